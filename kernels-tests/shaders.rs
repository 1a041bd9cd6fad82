//! Every `.wgsl` parses and validates with naga, is registered, and shares its struct layouts
//! with the Rust `#[repr(C)]` types.

use solidsynth::gpu::shaders;

#[test]
fn every_wgsl_file_validates_and_is_registered() {
    let _serial = crate::serial();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("wgsl");
    let mut on_disk = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            let src = std::fs::read_to_string(&path).unwrap();
            let full = shaders::source(&name);
            assert!(
                full.ends_with(&src),
                "{name}.wgsl differs from the embedded copy"
            );
            shaders::validate(&name, full).unwrap_or_else(|e| panic!("{e}"));
            on_disk.push(name);
        }
    }
    on_disk.sort();
    let mut registered: Vec<String> = shaders::KERNELS
        .iter()
        .map(|(n, _)| n.to_string())
        .collect();
    registered.sort();
    assert_eq!(on_disk, registered);
}

#[test]
fn validation_rejects_a_broken_shader() {
    let _serial = crate::serial();
    let broken =
        shaders::source("project").replace("acc[j] += centred", "acc[j] += undefined_name");
    assert!(shaders::validate("broken", &broken).is_err());
}

#[test]
fn shared_struct_layouts_match_wgsl() {
    let _serial = crate::serial();
    for (kernel, name, rust, size) in solidsynth::kernel_types::all_layouts() {
        let (module, _) = shaders::validate(kernel, shaders::source(kernel)).unwrap();
        let (members, span) = shaders::struct_layout(&module, name)
            .unwrap_or_else(|| panic!("{name} not in {kernel}.wgsl"));
        let wgsl: Vec<(String, usize)> =
            members.into_iter().map(|(n, o)| (n, o as usize)).collect();
        let rust: Vec<(String, usize)> =
            rust.into_iter().map(|(n, o)| (n.to_string(), o)).collect();
        assert_eq!(wgsl, rust, "{name}");
        assert_eq!(span as usize, size, "{name}");
    }
}
