//! The `solidsynth ptm` commands, and their bad input: exit 2, nothing written.

use super::*;

#[test]
fn cli_capture_fit_synth_relight() {
    let dir = tempfile::tempdir().unwrap();
    let cap = dir.path().join("cap");
    let o = run(&[
        "ptm",
        "capture",
        "--size",
        "40",
        "--lights",
        "12",
        "-o",
        p(&cap),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_dir(&cap).unwrap().count(), 13);
    let tex = dir.path().join("t.ptm");
    let o = run(&[
        "ptm",
        "fit",
        p(&cap),
        "--format",
        "rgb",
        "--json",
        "-o",
        p(&tex),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["rms_error_levels"].as_f64().unwrap() < 16.0);
    // The same synthesis with both searches.
    let synth = |search: &str, out: &Path| {
        run(&[
            "ptm",
            "synth",
            p(&tex),
            "--size",
            "72",
            "--block",
            "16",
            "--overlap",
            "4",
            "--seed",
            "2",
            "--search",
            search,
            "-o",
            p(out),
        ])
    };
    let big = dir.path().join("big.ptm");
    let o = synth("exact-projection", &big);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let brute = dir.path().join("brute.ptm");
    let o = synth("brute", &brute);
    assert!(o.status.success());
    assert_eq!(std::fs::read(&big).unwrap(), std::fs::read(&brute).unwrap());
    let ptm = format::load(&big).unwrap();
    assert_eq!(
        (ptm.width, ptm.height, ptm.format),
        (72, 72, PtmFormat::Rgb)
    );
    let relight = |backend: &str, out: &Path| {
        run(&[
            "ptm",
            "relight",
            p(&big),
            "--light",
            "0.5,-0.2",
            "--specular",
            "0.3",
            "--backend",
            backend,
            "-o",
            p(out),
        ])
    };
    let png = dir.path().join("lit.png");
    let o = relight("cpu", &png);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::open(&png).unwrap().width(), 72);
    // The GPU (lavapipe in CI) renders the same image, within one 8-bit level.
    let gpu_png = dir.path().join("lit-gpu.png");
    let o = relight("gpu", &gpu_png);
    if o.status.success() {
        let (a, b) = (
            image::open(&png).unwrap().to_rgba8(),
            image::open(&gpu_png).unwrap().to_rgba8(),
        );
        assert!(a
            .pixels()
            .zip(b.pixels())
            .all(|(x, y)| (0..4).all(|c| x.0[c].abs_diff(y.0[c]) <= 1)));
    } else {
        assert!(
            std::env::var_os("CI").is_none(),
            "no GPU in CI: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        eprintln!("SKIPPED the GPU relight (no adapter, CI unset)");
    }
    let sheet = dir.path().join("sheet.png");
    let o = run(&[
        "ptm",
        "relight",
        p(&big),
        "--sweep",
        "6",
        "--backend",
        "cpu",
        "-o",
        p(&sheet),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = image::open(&sheet).unwrap();
    assert_eq!((s.width(), s.height()), (3 * 76 + 4, 2 * 76 + 4));
}

#[test]
fn cli_bad_ptm_inputs_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cap = d.join("cap");
    assert!(run(&[
        "ptm",
        "capture",
        "--size",
        "24",
        "--lights",
        "8",
        "-o",
        p(&cap)
    ])
    .status
    .success());
    let out = d.join("o.ptm");
    // Capture into a non-empty directory; too few lights.
    assert_refused(
        &run(&["ptm", "capture", "--size", "24", "-o", p(&cap)]),
        "not an empty directory",
        &d.join("cap/lights.json"),
    );
    assert_refused(
        &run(&["ptm", "capture", "--lights", "5", "-o", p(&d.join("c5"))]),
        "--lights 5",
        &d.join("c5"),
    );
    // Light file that does not match the images: an extra image, then a missing one.
    std::fs::copy(cap.join("img_000.png"), cap.join("zzz.png")).unwrap();
    assert_refused(
        &run(&["ptm", "fit", p(&cap), "-o", p(&out)]),
        "lists 8 images but",
        &out,
    );
    std::fs::remove_file(cap.join("zzz.png")).unwrap();
    // The capture's own files are inputs: an output over one of them is refused, the files kept.
    for own in ["img_000.png", "lights.lp"] {
        let target = cap.join(own);
        let before = std::fs::read(&target).unwrap();
        let o = run(&["ptm", "fit", p(&cap), "-o", p(&target)]);
        assert_eq!(o.status.code(), Some(2), "{own}");
        assert!(String::from_utf8_lossy(&o.stderr).contains("a file this command reads"));
        assert_eq!(std::fs::read(&target).unwrap(), before, "{own} rewritten");
    }
    // A light file that lists one image twice (and so leaves another out).
    let twice = d.join("twice");
    copy_capture(&cap, &twice);
    let lp = std::fs::read_to_string(twice.join("lights.lp")).unwrap();
    let second = lp
        .lines()
        .nth(2)
        .unwrap()
        .replace("img_001.png", "img_000.png");
    let lp: Vec<String> = lp
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 2 {
                second.clone()
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(twice.join("lights.lp"), lp.join("\n") + "\n").unwrap();
    assert_refused(
        &run(&["ptm", "fit", p(&twice), "-o", p(&out)]),
        "lists img_000.png twice",
        &out,
    );
    // Fewer than 6 images.
    let few = d.join("few");
    std::fs::create_dir(&few).unwrap();
    let mut lp = String::from("5\n");
    for i in 0..5 {
        std::fs::copy(
            cap.join(format!("img_00{i}.png")),
            few.join(format!("img_00{i}.png")),
        )
        .unwrap();
        lp.push_str(&format!("img_00{i}.png 0.{i} 0.3 0.8\n"));
    }
    std::fs::write(few.join("lights.lp"), &lp).unwrap();
    assert_refused(
        &run(&["ptm", "fit", p(&few), "-o", p(&out)]),
        "at least 6",
        &out,
    );
    // Images of different sizes.
    let mixed = d.join("mixed");
    copy_capture(&cap, &mixed);
    image::RgbImage::new(24, 20)
        .save(mixed.join("img_004.png"))
        .unwrap();
    assert_refused(
        &run(&["ptm", "fit", p(&mixed), "-o", p(&out)]),
        "one size",
        &out,
    );
    // Degenerate lights: all at one elevation.
    let ring = d.join("ring");
    std::fs::create_dir(&ring).unwrap();
    let mut lp = String::from("8\n");
    for i in 0..8 {
        std::fs::copy(
            cap.join(format!("img_00{i}.png")),
            ring.join(format!("img_00{i}.png")),
        )
        .unwrap();
        let a = i as f64 * std::f64::consts::TAU / 8.0;
        lp.push_str(&format!(
            "img_00{i}.png {} {} 0.8\n",
            a.cos() * 0.6,
            a.sin() * 0.6
        ));
    }
    std::fs::write(ring.join("lights.lp"), &lp).unwrap();
    assert_refused(
        &run(&["ptm", "fit", p(&ring), "-o", p(&out)]),
        "degenerate light set",
        &out,
    );
    // Corrupt and truncated .ptm files, for synth and relight.
    let tex = d.join("t.ptm");
    assert!(run(&["ptm", "fit", p(&cap), "-o", p(&tex)])
        .status
        .success());
    let bytes = std::fs::read(&tex).unwrap();
    let trunc = d.join("trunc.ptm");
    std::fs::write(&trunc, &bytes[..bytes.len() - 10]).unwrap();
    let garbage = d.join("garbage.ptm");
    std::fs::write(&garbage, b"PTM_1.2\nPTM_FORMAT_LRGB\n24 x\n").unwrap();
    let png = d.join("o.png");
    assert_refused(
        &run(&[
            "ptm",
            "synth",
            p(&trunc),
            "--size",
            "32",
            "--block",
            "8",
            "--overlap",
            "2",
            "-o",
            p(&out),
        ]),
        "truncated",
        &out,
    );
    assert_refused(
        &run(&[
            "ptm",
            "relight",
            p(&garbage),
            "--light",
            "0,0",
            "--backend",
            "cpu",
            "-o",
            p(&png),
        ]),
        "garbage.ptm",
        &png,
    );
    // Bad flags.
    assert_refused(
        &run(&["ptm", "synth", p(&tex), "--block", "64", "-o", p(&out)]),
        "--block 64",
        &out,
    );
    let named_png = d.join("synth.png");
    assert_refused(
        &run(&["ptm", "synth", p(&tex), "-o", p(&named_png)]),
        "is written as a PTM: give a name ending in .ptm",
        &named_png,
    );
    // The largest output over a small memory budget: refused before any work, naming both.
    let o = bin()
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "64")
        .args([
            "ptm",
            "synth",
            p(&tex),
            "--size",
            "4096",
            "--block",
            "8",
            "--overlap",
            "2",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_refused(&o, "--size 4096x4096: needs about", &out);
    assert_refused(&o, "64.0 MiB is available", &out);
    // Relights refused: --elevation belongs to --sweep (it was ignored beside --light), and a
    // light outside the unit disk.
    let relit = d.join("relit.png");
    let refusals: [(&str, &[&str], &str, &Path); 2] = [
        (
            "0,0",
            &["--elevation", "10"],
            "give --sweep N with it",
            &relit,
        ),
        ("0.9,0.9", &["--backend", "cpu"], "--light", &png),
    ];
    for (light, more, needle, out) in refusals {
        let relight = ["ptm", "relight", p(&tex), "--light", light];
        assert_refused(
            &run(&[&relight[..], more, &["-o", p(out)]].concat()),
            needle,
            out,
        );
    }
    // A light given both ways is ambiguous (the direction used to win).
    let both = r#"{"lights": [{"file": "a.png", "direction": [0, 0, 1], "lu": 0.1, "lv": 0.1}]}"#;
    let e = capture::parse_lights(both, "lights.json", true).unwrap_err();
    assert!(e.to_string().contains("gives both"), "{e}");
    // The input is never overwritten.
    let o = run(&[
        "ptm",
        "synth",
        p(&tex),
        "--size",
        "32",
        "--block",
        "8",
        "--overlap",
        "2",
        "-o",
        p(&tex),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&tex).unwrap(), bytes);
}

/// A copy of the capture directory `from` at `to` (a new directory).
fn copy_capture(from: &Path, to: &Path) {
    std::fs::create_dir(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}
