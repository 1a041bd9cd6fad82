//! The command line as a user meets it: outputs, and bad input (exit code 2, named input, nothing
//! left behind). The helpers are here; the tests are in one module per command family.

mod analysis;
#[path = "../common/mod.rs"]
mod common;
mod eval;
mod gradient;
mod gradient_edit;
mod lapped;
mod outputs;
mod surface;
mod synthesis;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    c.env("SOLIDSYNTH_LOG", "warn");
    // The same memory refusals on every machine, whatever it has free.
    c.env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "4096");
    c
}

fn fixture_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// The box [0, 16)^3 of the solid of `ssa` with `seed` (CPU), through `region`.
fn region16(ssa: &str, seed: &str, dir: &Path) -> solidsynth::volume::Volume {
    let vol = dir.join("r.nrrd");
    let o = run(&[
        "region",
        ssa,
        "--box",
        "0,0,0,16,16,16",
        "--seed",
        seed,
        "--backend",
        "cpu",
        "-o",
        vol.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    solidsynth::io::nrrd::load(&vol).unwrap()
}

/// Analyse the cells fixture (periodic, CPU) into `dir`/c.ssa.
fn analyze_cells(dir: &Path) -> PathBuf {
    let ssa = dir.join("c.ssa");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "--periodic",
        fixture_path("cells32.png").to_str().unwrap(),
        "-o",
        ssa.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    ssa
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

/// The command failed with exit code 2, mentioning `needle`, and `dir` holds only `allowed` files.
fn assert_user_error(out: &Output, needle: &str, dir: &Path, allowed: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(stderr.contains(needle), "expected '{needle}' in: {stderr}");
    // A system error reads as its description ("No such file or directory"), not its number.
    assert!(!stderr.contains("(os error"), "{stderr}");
    let mut left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| !allowed.contains(&n.as_str()))
        .collect();
    left.sort();
    assert!(left.is_empty(), "files left behind: {left:?}");
}
