//! `eval`: scores, the contact sheet, and its bad inputs.

use super::*;

#[test]
fn eval_scores_a_volume_and_writes_a_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let vol = solidsynth::exemplar::procedural::cells_3d(24, 30, 5);
    let nrrd = dir.path().join("v.nrrd");
    solidsynth::io::nrrd::save(&vol, &nrrd).unwrap();
    let ex = dir.path().join("ex.png");
    solidsynth::metrics::slices::slice(
        &solidsynth::exemplar::procedural::cells_3d(24, 30, 6),
        2,
        0,
    )
    .to_dynamic()
    .save(&ex)
    .unwrap();
    let sheet = dir.path().join("sheet.png");
    let o = run(&[
        "eval",
        ex.to_str().unwrap(),
        nrrd.to_str().unwrap(),
        "--json",
        "--sheet",
        sheet.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in ["per_axis", "worst_axis", "floor", "worst_ratio"] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert!(v["worst_axis"]["coherence"].as_f64().unwrap() > 0.0);
    assert!(image::open(&sheet).unwrap().width() > 3 * 24);
    let o = run(&["eval", ex.to_str().unwrap(), nrrd.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("completeness"));
    // Into a pipe whose reader has gone (`eval ... | head` after head quit): no panic, no
    // error message, ended by SIGPIPE like any Unix tool.
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = bin()
            .args([
                "eval",
                ex.to_str().unwrap(),
                nrrd.to_str().unwrap(),
                "--json",
            ])
            .stdout(writer)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(
            o.status.signal(),
            Some(libc::SIGPIPE),
            "{:?}: {stderr}",
            o.status
        );
    }
}

#[test]
fn eval_bad_inputs_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ex = fixture_path("cells32.png");
    let ex = ex.to_str().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        std::fs::write(d.join(name), bytes).unwrap();
        d.join(name).to_str().unwrap().to_string()
    };
    let short = write(
        "short.nrrd",
        b"NRRD0004\ntype: uint8\ndimension: 4\nsizes: 3 16 16 16\nencoding: raw\n\nabc",
    );
    let o = run(&["eval", ex, &short]);
    assert_user_error(&o, "short.nrrd", d, &["short.nrrd"]);
    let float = write(
        "float.nrrd",
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n12345678",
    );
    let o = run(&["eval", ex, &float]);
    assert_user_error(&o, "float", d, &["short.nrrd", "float.nrrd"]);
    let mut tiny_bytes =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
    tiny_bytes.extend_from_slice(&[0u8; 64]);
    let tiny = write("tiny.nrrd", &tiny_bytes);
    let sheet = d.join("s.png");
    let o = run(&["eval", ex, &tiny, "--sheet", sheet.to_str().unwrap()]);
    assert_user_error(
        &o,
        "tiny.nrrd",
        d,
        &["short.nrrd", "float.nrrd", "tiny.nrrd"],
    );
    // More slices than the volume has planes would score some twice.
    let mut small_bytes =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 16 16 16\nencoding: raw\n\n".to_vec();
    small_bytes.extend_from_slice(&[0u8; 4096]);
    let small = write("small.nrrd", &small_bytes);
    let o = run(&["eval", ex, &small, "--slices", "16"]);
    assert_user_error(
        &o,
        "--slices 16: must be 1..=15: the volume is 16x16x16",
        d,
        &["short.nrrd", "float.nrrd", "tiny.nrrd", "small.nrrd"],
    );
    let o = run(&["eval", ex, &small, "--slices", "15"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["eval", &d.join("missing.png").to_string_lossy(), &tiny]);
    assert_user_error(
        &o,
        "missing.png: No such file or directory",
        d,
        &["short.nrrd", "float.nrrd", "tiny.nrrd", "small.nrrd"],
    );
}
