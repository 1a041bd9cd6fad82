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
    for (kernel, name, rust, size) in solidsynth::contract::uniforms::all_layouts() {
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

/// `SOLIDSYNTH_SHADER_DIR`: a kernel's file there replaces the embedded source. A broken file is
/// an error naming the kernel (not a panic, not the embedded kernel run silently); a copy of the
/// embedded source builds; kernels without a file there stay embedded.
#[test]
fn shader_dir_replaces_the_embedded_kernels_it_holds() {
    let _serial = crate::serial();
    let Some(_) = crate::gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("colorize.wgsl"), "this is not WGSL").unwrap();
    std::fs::write(dir.path().join("init.wgsl"), shaders::source("init")).unwrap();
    // Set under the serial lock, which every GPU test of this binary holds, and removed before
    // any check can fail (the contexts read it when they build a pipeline).
    std::env::set_var("SOLIDSYNTH_SHADER_DIR", dir.path());
    let ctx = crate::open(solidsynth::gpu::GpuOptions::from_env()).unwrap();
    let broken = ctx.pipeline("colorize").map(|_| ());
    let copied = ctx.pipeline("init").map(|_| ());
    let embedded = ctx.pipeline("upsample").map(|_| ());
    std::env::remove_var("SOLIDSYNTH_SHADER_DIR");
    let err = broken.expect_err("the broken file is used").to_string();
    assert!(err.contains("colorize"), "{err}");
    copied.unwrap();
    embedded.unwrap();
}
