//! What the tool prints when its output is not a terminal: no ANSI colour, a line per stage
//! instead of a progress bar, and `--json` summaries carrying their schema version.

use std::process::Command;

/// Run `solidsynth` with `command_line`'s words as arguments in `dir`.
fn solidsynth(command_line: &str, dir: &std::path::Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_solidsynth"))
        .args(command_line.split_whitespace())
        .current_dir(dir)
        .env("SOLIDSYNTH_CACHE_DIR", dir.join("cache"))
        .env_remove("NO_COLOR")
        .output()
        .unwrap()
}

#[test]
fn redirected_logs_have_no_colour_and_a_line_per_stage() {
    let dir = tempfile::tempdir().unwrap();
    let out = solidsynth("synth --size 16 --backend cpu -o a.nrrd", dir.path());
    assert!(out.status.success());
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(
        !log.contains('\u{1b}'),
        "ANSI escapes in a redirected log:\n{log}"
    );
    // Stage lines: seconds, then the stage ("level 2: correction").
    let stages: Vec<&str> = log.lines().filter(|l| l.contains(" s  ")).collect();
    assert!(stages.len() >= 2, "no stage lines in:\n{log}");
    assert!(
        !log.contains('\r'),
        "a progress bar was drawn into a file:\n{log}"
    );
}

#[test]
fn json_summaries_carry_their_schema() {
    let dir = tempfile::tempdir().unwrap();
    for command_line in [
        "synth --size 16 --backend cpu -o a.nrrd --json",
        "ptm capture --size 16 --lights 6 -o cap --json",
        "lapped exemplar --size 16 -o kiwi.nrrd --json",
        "adapters --json",
    ] {
        let out = solidsynth(command_line, dir.path());
        assert!(
            out.status.success(),
            "{command_line}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        let value: serde_json::Value = serde_json::from_str(text.trim())
            .unwrap_or_else(|e| panic!("{command_line} printed no JSON ({e}): {text}"));
        assert_eq!(value["schema"], 1, "{command_line}: {text}");
    }
    // Values are spelled as the flags spell them.
    let out = solidsynth(
        "synth --size 16 --backend cpu --passes 2,2,2,1 -o b.nrrd --json",
        dir.path(),
    );
    let value: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(value["candidates"], "3d");
    assert_eq!(value["passes"], "2,2,2,1");
    assert_eq!(value["color"], "average");
}

#[test]
fn completions_and_man_pages_are_generated() {
    let dir = tempfile::tempdir().unwrap();
    let out = solidsynth("completions bash", dir.path());
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("solidsynth"));
    let out = solidsynth("man -o man", dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = std::fs::read_to_string(dir.path().join("man/solidsynth.1")).unwrap();
    assert!(page.contains(".TH"));
    assert!(dir.path().join("man/solidsynth-synth.1").exists());
}
