//! The kernel layer's rules, checked on the source tree: each WGSL kernel K has its CPU reference
//! (`src/cpu/K.rs` or `src/cpu/K/`), its dispatch (`src/gpu/K.rs`) and its isolated test
//! (`kernels-tests/K.rs`); and the kernel layer (`cpu/`, `gpu/`, `contract/`) imports no domain,
//! nor analysis any synthesis.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// What is missing for kernel `name` under `root`.
fn missing_files(root: &Path, name: &str) -> Vec<String> {
    let cpu = root.join(format!("src/cpu/{name}.rs")).exists()
        || root.join(format!("src/cpu/{name}/mod.rs")).exists();
    let mut missing = Vec::new();
    if !cpu {
        missing.push(format!("src/cpu/{name}.rs"));
    }
    for file in [
        format!("src/gpu/{name}.rs"),
        format!("kernels-tests/{name}.rs"),
    ] {
        if !root.join(&file).exists() {
            missing.push(file);
        }
    }
    missing
}

fn kernels(root: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(root.join("wgsl"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn every_wgsl_kernel_has_its_reference_dispatch_and_test() {
    let root = root();
    let names = kernels(&root);
    assert!(names.len() >= 9, "kernels found: {names:?}");
    let missing: Vec<String> = names.iter().flat_map(|k| missing_files(&root, k)).collect();
    assert!(
        missing.is_empty(),
        "kernels without their files: {missing:?}"
    );
}

#[test]
fn the_file_check_fails_for_a_kernel_without_its_files() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("src/cpu/blur")).unwrap();
    std::fs::write(dir.path().join("src/cpu/blur/mod.rs"), "").unwrap();
    assert_eq!(
        missing_files(dir.path(), "blur"),
        ["src/gpu/blur.rs", "kernels-tests/blur.rs"]
    );
    assert_eq!(missing_files(&root(), "correct"), Vec::<String>::new());
}

/// `use crate::X` or `crate::X::` lines of the Rust files under `dir` naming one of `rooms`.
fn imports_of(dir: &Path, rooms: &[&str]) -> Vec<String> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                for (n, line) in text.lines().enumerate() {
                    let code = line.split("//").next().unwrap_or("");
                    if rooms.iter().any(|r| code.contains(&format!("crate::{r}"))) {
                        found.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
                    }
                }
            }
        }
    }
    found
}

#[test]
fn the_kernel_layer_imports_no_domain() {
    let root = root();
    let domains = [
        "lazy", "gradient", "ptm", "lapped", "analysis", "mesh", "serve", "cli",
    ];
    for layer in ["src/cpu", "src/gpu", "src/contract"] {
        let up = imports_of(&root.join(layer), &domains);
        assert!(up.is_empty(), "{layer} reaches up: {up:#?}");
    }
    let up = imports_of(&root.join("src/analysis"), &["lazy"]);
    assert!(up.is_empty(), "analysis imports synthesis: {up:#?}");
    // The domains reach the kernels through the backend's door only.
    for domain in [
        "src/lazy",
        "src/gradient",
        "src/ptm",
        "src/lapped",
        "src/mesh",
    ] {
        let direct = imports_of(&root.join(domain), &["cpu::", "gpu::"]);
        assert!(
            direct.is_empty(),
            "{domain} calls kernels directly: {direct:#?}"
        );
    }
}

#[test]
fn the_import_check_sees_an_upward_import() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("k.rs"),
        "use crate::lazy::Box3;\n// crate::ptm in a comment\n",
    )
    .unwrap();
    let found = imports_of(dir.path(), &["lazy", "ptm"]);
    assert_eq!(found.len(), 1, "{found:?}");
}
