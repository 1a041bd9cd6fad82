//! The command line as a user meets it: outputs, and bad input (exit code 2, named input, nothing
//! left behind).

mod common;

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
    let mut left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| !allowed.contains(&n.as_str()))
        .collect();
    left.sort();
    assert!(left.is_empty(), "files left behind: {left:?}");
}

#[test]
fn analyze_and_inspect_fixture() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cells.ssa");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "--periodic",
        fixture_path("cells32.png").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let first = std::fs::read(&out).unwrap();
    // Same inputs, byte-identical file.
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "--periodic",
        fixture_path("cells32.png").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(std::fs::read(&out).unwrap() == first);

    let o = run(&["inspect", out.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // Four levels for each of the three exemplars one image becomes (`--frame paper`).
    assert_eq!(v["levels"].as_array().unwrap().len(), 3 * 4);
    assert_eq!(v["levels"][0]["width"], 32);
    let slab = dir.path().join("cells.slab.png");
    let img = image::open(&slab).unwrap();
    assert!(img.width() > 5 * 32 && img.height() > 4 * 32);
}

#[test]
fn analyze_three_exemplars_and_a_feature_mask() {
    let dir = tempfile::tempdir().unwrap();
    let mask = dir.path().join("mask.png");
    let mut m = image::GrayImage::new(32, 32);
    for (x, _, p) in m.enumerate_pixels_mut() {
        p.0[0] = if x < 16 { 255 } else { 0 };
    }
    m.save(&mask).unwrap();
    let out = dir.path().join("three.ssa");
    let (a, b) = (fixture_path("cells32.png"), fixture_path("marble32.png"));
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        a.to_str().unwrap(),
        "--ey",
        b.to_str().unwrap(),
        "--ez",
        a.to_str().unwrap(),
        "--feature-mask",
        mask.to_str().unwrap(),
        "--ey-feature-mask",
        mask.to_str().unwrap(),
        "--ez-feature-mask",
        mask.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = solidsynth::io::ssa::load(&out).unwrap();
    assert!(!a.shared && a.has_feature);
}

/// `--frame`: by default (the paper's frame) one image is analysed as three exemplars, the y
/// plane's transposed, and a given --ey is transposed too; `--frame cyclic` keeps one shared
/// image; an .ssa refuses the flag (its exemplars are fixed); `eval` takes the same frames.
#[test]
fn frames_orient_the_y_exemplar() {
    let dir = tempfile::tempdir().unwrap();
    let (stripes, cells) = (fixture_path("stripes32.png"), fixture_path("cells32.png"));
    let analyse = |extra: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut args = vec!["analyze", "--backend", "cpu", "--periodic"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out.to_str().unwrap()]);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        solidsynth::io::ssa::load(&out).unwrap()
    };
    let level0 =
        |a: &solidsynth::analysis::Analysis, e: usize| a.exemplar(e).levels[0].image.clone();
    // Colour and feature channels alike: y is x transposed, z is x.
    let paper = analyse(&[stripes.to_str().unwrap()], "paper.ssa");
    assert!(!paper.shared && paper.has_feature);
    let (x, y, z) = (level0(&paper, 0), level0(&paper, 1), level0(&paper, 2));
    assert_eq!(x.pixels, z.pixels);
    assert_ne!(x.pixels, y.pixels);
    assert_eq!(x.transposed().pixels, y.pixels);
    let cyclic = analyse(
        &[stripes.to_str().unwrap(), "--frame", "cyclic"],
        "cyclic.ssa",
    );
    assert!(cyclic.shared);
    assert_eq!(level0(&cyclic, 0).pixels, x.pixels);
    let three = analyse(
        &[
            stripes.to_str().unwrap(),
            "--ey",
            cells.to_str().unwrap(),
            "--ez",
            cells.to_str().unwrap(),
        ],
        "three.ssa",
    );
    assert_eq!(
        level0(&three, 1).transposed().pixels,
        level0(&three, 2).pixels
    );

    let volume = dir.path().join("v.nrrd");
    let paper_ssa = dir.path().join("paper.ssa");
    let o = run(&[
        "synth",
        paper_ssa.to_str().unwrap(),
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        volume.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for frame in ["paper", "cyclic"] {
        let o = run(&[
            "eval",
            stripes.to_str().unwrap(),
            volume.to_str().unwrap(),
            "--frame",
            frame,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // A non-square image: the paper's frame would transpose y to another size, so the default
    // is the cyclic frame, and an explicit --frame paper is refused.
    let wide = dir.path().join("wide.png");
    image::open(&cells)
        .unwrap()
        .crop_imm(0, 0, 32, 24)
        .save(&wide)
        .unwrap();
    assert!(analyse(&[wide.to_str().unwrap()], "wide.ssa").shared);
    let o = run(&[
        "analyze",
        wide.to_str().unwrap(),
        "--frame",
        "paper",
        "-o",
        dir.path().join("refused.ssa").to_str().unwrap(),
    ]);
    let kept = [
        "paper.ssa",
        "cyclic.ssa",
        "three.ssa",
        "v.nrrd",
        "wide.png",
        "wide.ssa",
    ];
    assert_user_error(&o, "--frame paper", dir.path(), &kept);
    let target = dir.path().join("w.nrrd");
    let o = run(&[
        "synth",
        paper_ssa.to_str().unwrap(),
        "--frame",
        "paper",
        "--size",
        "8",
        "-o",
        target.to_str().unwrap(),
    ]);
    assert_user_error(&o, "--frame", dir.path(), &kept);
}

#[test]
fn feature_channel_is_automatic_unless_turned_off() {
    let dir = tempfile::tempdir().unwrap();
    let cells = fixture_path("cells32.png");
    let analyse = |extra: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut args = vec!["analyze", "--backend", "cpu", cells.to_str().unwrap()];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out.to_str().unwrap()]);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        solidsynth::io::ssa::load(&out).unwrap()
    };
    // Default: the Otsu mask's feature channel, weighted 3 (the analysis records the weight).
    let auto = analyse(&[], "auto.ssa");
    assert!(auto.has_feature);
    assert_eq!(auto.exemplar(0).levels[0].image.channels, 4);
    assert_eq!(auto.params.feature_weight, 3.0);
    assert!(!analyse(&["--feature-mask", "none"], "none.ssa").has_feature);
    let edges = analyse(&["--feature-mask", "edges"], "edges.ssa");
    assert!(edges.has_feature);
    assert_ne!(
        edges.exemplar(0).levels[0].image.pixels,
        auto.exemplar(0).levels[0].image.pixels,
        "the edge mask's channel differs from the luminance mask's"
    );
    // Refused (exit 2, nothing written): a mask image for the y exemplar alone, analysis
    // options with an .ssa, and a feature weight without a feature channel.
    let (image, ssa) = (cells.to_str().unwrap(), dir.path().join("auto.ssa"));
    let refused: [(&str, &[&str], &str); 3] = [
        (image, &["--ey-feature-mask", image], "feature masks"),
        (
            ssa.to_str().unwrap(),
            &["--feature-mask", "none"],
            "--feature-mask",
        ),
        (
            image,
            &["--feature-mask", "none", "--feature-weight", "5"],
            "--feature-weight",
        ),
    ];
    let out = dir.path().join("v.nrrd");
    for (input, flags, needle) in refused {
        let mut args = vec!["synth", input, "--size", "8", "-o", out.to_str().unwrap()];
        args.extend_from_slice(flags);
        assert_user_error(
            &run(&args),
            needle,
            dir.path(),
            &["auto.ssa", "none.ssa", "edges.ssa"],
        );
    }
}

#[test]
fn bad_inputs_exit_2_naming_the_input_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.ssa");
    let out_s = out.to_str().unwrap();
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();

    // Missing file.
    let o = run(&["analyze", "--backend", "cpu", &p("nope.png"), "-o", out_s]);
    assert_user_error(&o, "nope.png", d, &[]);

    // Truncated / corrupt image.
    let png = std::fs::read(fixture_path("cells32.png")).unwrap();
    std::fs::write(d.join("trunc.png"), &png[..png.len() / 2]).unwrap();
    let o = run(&["analyze", "--backend", "cpu", &p("trunc.png"), "-o", out_s]);
    assert_user_error(&o, "trunc.png", d, &["trunc.png"]);
    std::fs::write(d.join("garbage.png"), b"this is not an image").unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        &p("garbage.png"),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "garbage.png", d, &["trunc.png", "garbage.png"]);
    let keep = [
        "trunc.png",
        "garbage.png",
        "tiny.png",
        "wide.png",
        "mask.png",
    ];

    // Tiny exemplar.
    image::RgbImage::new(8, 8).save(d.join("tiny.png")).unwrap();
    let o = run(&["analyze", "--backend", "cpu", &p("tiny.png"), "-o", out_s]);
    assert_user_error(&o, "at least 16", d, &keep);

    // Mismatched Ex/Ey/Ez sizes.
    image::RgbImage::new(40, 32)
        .save(d.join("wide.png"))
        .unwrap();
    let c = fixture_path("cells32.png");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "--ey",
        &p("wide.png"),
        "--ez",
        c.to_str().unwrap(),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "--ey", d, &keep);

    // A mask of another size.
    image::GrayImage::new(20, 20)
        .save(d.join("mask.png"))
        .unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "--feature-mask",
        &p("mask.png"),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "mask", d, &keep);

    // Output path is a directory, or in a missing directory.
    std::fs::create_dir(d.join("adir")).unwrap();
    let keep_dir = [&keep[..], &["adir"]].concat();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "-o",
        &p("adir"),
    ]);
    assert_user_error(&o, "is a directory", d, &keep_dir);
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "-o",
        &p("missing/out.ssa"),
    ]);
    assert_user_error(&o, "does not exist", d, &keep_dir);

    // A corrupt .ssa given to inspect.
    std::fs::write(d.join("bad.ssa"), b"SOLIDSSA garbage").unwrap();
    let keep_bad = [&keep_dir[..], &["bad.ssa"]].concat();
    let o = run(&["inspect", &p("bad.ssa")]);
    assert_user_error(&o, "bad.ssa", d, &keep_bad);

    // Bad flag values are clap's: also exit 2.
    let o = run(&[
        "analyze",
        "--backend",
        "quantum",
        c.to_str().unwrap(),
        "-o",
        out_s,
    ]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn existing_output_is_replaced_only_on_success() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.ssa");
    std::fs::write(&out, b"precious").unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "/nonexistent.png",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
}

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
    let o = run(&["eval", &d.join("missing.png").to_string_lossy(), &tiny]);
    assert_user_error(
        &o,
        "missing.png",
        d,
        &["short.nrrd", "float.nrrd", "tiny.nrrd"],
    );
}

#[test]
fn synth_writes_nrrd_flipbook_slices_and_sheet_from_an_ssa() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ssa = d.join("m.ssa");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "--periodic",
        fixture_path("marble32.png").to_str().unwrap(),
        "-o",
        ssa.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let out = d.join("v.nrrd");
    let (flip, sheet, slices) = (d.join("f.png"), d.join("s.png"), d.join("slices"));
    let o = run(&[
        "synth",
        ssa.to_str().unwrap(),
        "--size",
        "12",
        "--seed",
        "3",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
        "--flipbook",
        flip.to_str().unwrap(),
        "--sheet",
        sheet.to_str().unwrap(),
        "--slices",
        slices.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = solidsynth::io::nrrd::load(&out).unwrap();
    assert_eq!((v.nx, v.ny, v.nz, v.channels), (12, 12, 12, 3));
    let header = String::from_utf8_lossy(&std::fs::read(&out).unwrap()[..80]).to_string();
    assert!(
        header.starts_with("NRRD0004\n") && header.contains("sizes: 3 12 12 12"),
        "{header}"
    );
    let f = image::open(&flip).unwrap();
    assert_eq!((f.width(), f.height()), (4 * 12, 3 * 12));
    assert_eq!(std::fs::read_dir(&slices).unwrap().count(), 12);
    assert!(image::open(&sheet).is_ok());
    // Triples of the same run: header (8-byte magic, 6 u32) then 3 u32 per voxel. Streamed in
    // slabs of small groups, the volume and its triples are the same bytes.
    let with_triples = |name: &str, max_group: &str| {
        let o = run(&[
            "synth",
            ssa.to_str().unwrap(),
            "--size",
            "12",
            "--seed",
            "3",
            "--backend",
            "cpu",
            "--max-group",
            max_group,
            "-o",
            d.join(format!("{name}.nrrd")).to_str().unwrap(),
            "--triples",
            d.join(format!("{name}.bin")).to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let volume = std::fs::read(d.join(format!("{name}.nrrd"))).unwrap();
        assert!(
            volume == std::fs::read(&out).unwrap(),
            "{name}: another volume"
        );
        std::fs::read(d.join(format!("{name}.bin"))).unwrap()
    };
    let t = with_triples("whole", "512");
    assert_eq!(&t[..8], b"SSTRIPLE");
    assert_eq!(t.len(), 32 + 12 * 12 * 12 * 12);
    assert!(with_triples("grouped", "4") == t);
    // The flipbook tile of slice z = 5 is the NRRD's z = 5 slice.
    let f = f.to_rgba8();
    for (x, y) in [(0u32, 0u32), (7, 3), (11, 11)] {
        let p = f.get_pixel(12 + x, 12 + y);
        assert_eq!(&p.0[..3], v.at(x, y, 5));
    }
    // And the whole flipbook reads back as the volume (round trip).
    assert_eq!(solidsynth::io::flipbook::from_image(&f, 12, 3).unwrap(), v);
}

/// An interrupt (Ctrl-C) while the volume is being streamed to its file deletes the partial file.
#[test]
#[cfg(unix)]
fn an_interrupted_synthesis_leaves_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = tempfile::tempdir().unwrap();
    let mut child = bin()
        .env("SOLIDSYNTH_CACHE_DIR", cache.path())
        .args(["synth", "--size", "256", "--backend", "cpu", "-q", "-o"])
        .arg(d.join("v.nrrd"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let partial = loop {
        let names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .collect();
        if let Some(n) = names.iter().find(|n| n.ends_with(".partial")) {
            break n.clone();
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "exited before writing: {names:?}"
        );
        assert!(
            started.elapsed().as_secs() < 120,
            "no partial output appeared"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    let left: Vec<_> = std::fs::read_dir(d).unwrap().collect();
    assert!(left.is_empty(), "{partial} interrupted, left {left:?}");
}

#[test]
fn synth_bad_inputs_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("v.nrrd");
    let out_s = out.to_str().unwrap();
    let o = run(&["synth", "--size", "0", "-o", out_s]);
    assert_user_error(&o, "--size 0", d, &[]);
    let o = run(&["synth", "--size", "2048", "-o", out_s]);
    assert_user_error(&o, "--size 2048", d, &[]);
    let o = run(&["synth", "--size", "16", "--jitter", "nan", "-o", out_s]);
    assert_user_error(&o, "--jitter", d, &[]);
    for passes in ["2,2", "9", "2,2,9,2"] {
        let o = run(&["synth", "--size", "16", "--passes", passes, "-o", out_s]);
        assert_user_error(&o, "--passes", d, &[]);
    }
    let o = run(&["synth", "--size", "16", "--jitter", "100", "-o", out_s]);
    assert_user_error(&o, "--jitter", d, &[]);
    // A colour source per channel: as many as the exemplar's colour channels (3), known names.
    let o = run(&[
        "synth",
        "--size",
        "16",
        "--backend",
        "cpu",
        "--color",
        "x,y",
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "--color x,y", d, &[]);
    let o = run(&["synth", "--size", "16", "--color", "x,red,z", "-o", out_s]);
    assert_user_error(&o, "--color", d, &[]);
    // serve takes uploads of any channel count: one source only, refused before listening.
    let o = run(&["serve", "--port", "0", "--color", "x,y,z"]);
    assert_user_error(&o, "--color x,y,z", d, &[]);
    std::fs::write(d.join("bad.ssa"), b"SOLIDSSA\x01\x00\x00\x00").unwrap();
    let o = run(&[
        "synth",
        d.join("bad.ssa").to_str().unwrap(),
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "bad.ssa", d, &["bad.ssa"]);
    // A version from the future is named as such.
    let mut future = solidsynth::io::ssa::to_bytes(&common::analyze(
        vec![common::fixture("cells32.png")],
        solidsynth::exemplar::Border::Wrap,
    ));
    future[8] = 9;
    std::fs::write(d.join("future.ssa"), &future).unwrap();
    let o = run(&[
        "synth",
        d.join("future.ssa").to_str().unwrap(),
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "version 9", d, &["bad.ssa", "future.ssa"]);
    // Unwritable output locations.
    let o = run(&[
        "synth",
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        d.join("no/such/dir/v.nrrd").to_str().unwrap(),
    ]);
    assert_user_error(&o, "does not exist", d, &["bad.ssa", "future.ssa"]);
    std::fs::create_dir(d.join("full")).unwrap();
    std::fs::write(d.join("full/keep.png"), b"x").unwrap();
    // `synth --size 16` into v.nrrd with one more output.
    let with_output = |flag: &str, path: &str| {
        run(&[
            "synth",
            "--size",
            "16",
            "--backend",
            "cpu",
            "-o",
            out_s,
            flag,
            path,
        ])
    };
    let kept = ["bad.ssa", "future.ssa", "full"];
    let o = with_output("--slices", d.join("full").to_str().unwrap());
    assert_user_error(&o, "not an empty directory", d, &kept);
    assert_eq!(std::fs::read(d.join("full/keep.png")).unwrap(), b"x");
    // A directory no output can be written in (even by root) is refused before any work,
    // named by its flag, and the other outputs are not written either.
    #[cfg(target_os = "linux")]
    {
        let o = with_output("--flipbook", "/proc/f.png");
        assert_user_error(&o, "--flipbook /proc/f.png", d, &kept);
    }
    // An output that is also an input, or two outputs on one path: refused, nothing touched.
    let exemplar = d.join("ex.png");
    std::fs::copy(fixture_path("cells32.png"), &exemplar).unwrap();
    let before = std::fs::read(&exemplar).unwrap();
    let ex = exemplar.to_str().unwrap();
    let o = run(&["synth", ex, "--size", "16", "--backend", "cpu", "-o", ex]);
    assert_user_error(
        &o,
        "is also given as an input",
        d,
        &["bad.ssa", "future.ssa", "full", "ex.png"],
    );
    assert_eq!(std::fs::read(&exemplar).unwrap(), before);
    std::fs::remove_file(&exemplar).unwrap();
    let o = with_output("--vti", out_s);
    assert_user_error(&o, "is also given as an input or another output", d, &kept);
    // A slices directory whose parent is missing: refused before any work, by its flag.
    let o = with_output("--slices", d.join("no/such").to_str().unwrap());
    assert_user_error(&o, "--slices", d, &kept);
    // The coarse cache belongs to the infinite solid, not to a tileable one.
    let o = run(&[
        "synth",
        "--size",
        "32",
        "--tileable",
        "--coarse-cache",
        "64",
        "-o",
        out_s,
    ]);
    assert_user_error(
        &o,
        "--coarse-cache with --tileable",
        d,
        &["bad.ssa", "future.ssa", "full"],
    );
    // A period the pyramid cannot halve down to a coarsest period of whole 4-voxel bricks.
    let o = run(&["synth", "--size", "40", "--tileable", "-o", out_s]);
    assert_user_error(
        &o,
        "--size 40 with --tileable",
        d,
        &["bad.ssa", "future.ssa", "full"],
    );
}

#[test]
fn region_is_the_same_solid_as_synth_and_checks_its_box() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ssa = analyze_cells(d);
    let (a, b) = (d.join("a.nrrd"), d.join("b.nrrd"));
    let o = run(&[
        "synth",
        ssa.to_str().unwrap(),
        "--size",
        "10",
        "--seed",
        "2",
        "--backend",
        "cpu",
        "-o",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&[
        "region",
        ssa.to_str().unwrap(),
        "--box",
        "0,0,0,10,10,10",
        "--seed",
        "2",
        "--backend",
        "cpu",
        "-o",
        b.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "synth --size N != region --box 0,0,0,N,N,N"
    );
    // A box with negative coordinates holds the same voxels where it overlaps.
    let c = d.join("c.nrrd");
    let o = run(&[
        "region",
        ssa.to_str().unwrap(),
        "--box",
        "-4,3,5,6,9,12",
        "--seed",
        "2",
        "--backend",
        "cpu",
        "-o",
        c.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let (va, vc) = (
        solidsynth::io::nrrd::load(&a).unwrap(),
        solidsynth::io::nrrd::load(&c).unwrap(),
    );
    for (x, y, z) in [(0u32, 3u32, 5u32), (5, 8, 9), (3, 4, 9)] {
        assert_eq!(va.at(x, y, z), vc.at(x + 4, y - 3, z - 5));
    }
    // Small groups (cubes of 8 voxels: 8 of them here) give the same bytes.
    let g = d.join("g.nrrd");
    let o = run(&[
        "region",
        ssa.to_str().unwrap(),
        "--box",
        "0,0,0,10,10,10",
        "--seed",
        "2",
        "--max-group",
        "8",
        "--backend",
        "cpu",
        "-o",
        g.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&g).unwrap());
    std::fs::remove_file(&g).unwrap();
    let o = run(&[
        "region",
        ssa.to_str().unwrap(),
        "--box",
        "0,0,0,10,10,10",
        "--max-group",
        "2",
        "-o",
        g.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--max-group"));
    let keep = ["c.ssa", "a.nrrd", "b.nrrd", "c.nrrd"];
    for (bad, needle) in [
        ("1,1,1,1,2,2", "X1 must be greater"),
        ("0,0,0,5,5", "six integers"),
        ("0,0,0,5,5,x", "six integers"),
        ("0,0,0,9000,1,1", "at most"),
    ] {
        let o = run(&[
            "region",
            ssa.to_str().unwrap(),
            "--box",
            bad,
            "--backend",
            "cpu",
            "-o",
            d.join("bad.nrrd").to_str().unwrap(),
        ]);
        assert_user_error(&o, needle, d, &keep);
    }
}

#[test]
fn cuts_equal_the_same_voxels_of_a_region() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ssa = analyze_cells(d);
    let s = ssa.to_str().unwrap();
    let v = region16(s, "7", d);
    // The issue's convention: `cut --origin 8,8,5 --normal 0,0,1 --size 16` is z-slice 5.
    let png = d.join("cut.png");
    let o = run(&[
        "cut",
        s,
        "--origin",
        "8,8,5",
        "--normal",
        "0,0,1",
        "--size",
        "16",
        "--seed",
        "7",
        "--backend",
        "cpu",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&png).unwrap().to_rgba8();
    for y in 0..16 {
        for x in 0..16 {
            assert_eq!(&img.get_pixel(x, y).0[..3], v.at(x, y, 5), "pixel {x},{y}");
        }
    }
    // An oblique cut inside the box samples the box's voxels.
    let spec = solidsynth::lazy::cut::CutSpec {
        origin: [8.0, 7.5, 8.2],
        normal: [1.0, 2.0, -0.7],
        up: Some([0.0, 0.0, 1.0]),
        size: 8,
        spacing: 1.3,
    };
    let o = run(&[
        "cut",
        s,
        "--origin",
        "8,7.5,8.2",
        "--normal",
        "1,2,-0.7",
        "--up",
        "0,0,1",
        "--size",
        "8",
        "--spacing",
        "1.3",
        "--seed",
        "7",
        "--backend",
        "cpu",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&png).unwrap().to_rgba8();
    for (k, p) in spec.voxels().unwrap().into_iter().enumerate() {
        let (x, y) = (k as u32 % 8, k as u32 / 8);
        assert_eq!(
            &img.get_pixel(x, y).0[..3],
            v.at(p[0] as u32, p[1] as u32, p[2] as u32)
        );
    }
    let keep = ["c.ssa", "r.nrrd", "cut.png"];
    for (args, needle) in [
        (vec!["--normal", "0,0,0"], "--normal"),
        (vec!["--normal", "0,0,1", "--up", "0,0,2"], "parallel"),
        (vec!["--normal", "0,x,1"], "three numbers"),
        (vec!["--normal", "0,0,1", "--spacing", "0"], "--spacing"),
        // Over the memory budget (4 GiB in these tests): refused before any synthesis.
        (
            vec!["--normal", "0,0,1", "--coarse-cache", "1024"],
            "needs about",
        ),
    ] {
        let mut a = vec![
            "cut",
            s,
            "--origin",
            "1,2,3",
            "--size",
            "8",
            "--backend",
            "cpu",
            "-o",
        ];
        let out = d.join("bad.png");
        a.push(out.to_str().unwrap());
        a.extend(args);
        assert_user_error(&run(&a), needle, d, &keep);
    }
    let o = run(&[
        "cut",
        s,
        "--origin",
        "1,2,3",
        "--normal",
        "1,1,1",
        "--size",
        "4096",
        "--spacing",
        "8",
        "-o",
        d.join("bad.png").to_str().unwrap(),
    ]);
    assert_user_error(&o, "cut --size 4096 --spacing 8: needs about", d, &keep);
}

#[test]
fn surface_bakes_the_solid_at_each_texel_and_refuses_bad_meshes() {
    use solidsynth::mesh::{bake::Atlas, Placement};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj_text = "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let mesh_path = d.join("tetra.obj");
    std::fs::write(&mesh_path, obj_text).unwrap();
    let ssa = analyze_cells(d);
    let s = ssa.to_str().unwrap();
    let common = [
        "--seed",
        "3",
        "--backend",
        "cpu",
        "--resolution",
        "16",
        "--texels",
        "5",
    ];
    let out = d.join("baked.obj");
    let mut args = vec!["surface", s, "--mesh", mesh_path.to_str().unwrap()];
    args.extend_from_slice(&common);
    args.extend_from_slice(&["-o", out.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read_to_string(d.join("baked.mtl"))
        .unwrap()
        .contains("map_Kd baked.png"));
    // Every texel is the solid's voxel at its 3D point: compare with a region holding the mesh.
    // The atlas is RGB for a solid of three channels, RGBA for four (below).
    let v = region16(s, "3", d);
    let texels_of = |v: &solidsynth::volume::Volume, png: &str, mesh_text: &str| {
        let img = image::open(d.join(png)).unwrap();
        let color = match v.channels {
            3 => image::ColorType::Rgb8,
            4 => image::ColorType::Rgba8,
            n => panic!("a {n}-channel solid"),
        };
        assert_eq!(img.color(), color, "{png}");
        let img = img.to_rgba8();
        let mesh = solidsynth::mesh::parse_obj(mesh_text.as_bytes(), "t").unwrap();
        let atlas = Atlas::new(mesh.triangles.len(), 5, 0).unwrap();
        assert_eq!((img.width(), img.height()), (atlas.width, atlas.height));
        let voxels = atlas.texel_voxels(&mesh, &Placement::fit(&mesh, 16));
        for (k, p) in voxels.iter().enumerate() {
            let (x, y) = (k as u32 % atlas.width, k as u32 / atlas.width);
            let want = v.at(p[0] as u32, p[1] as u32, p[2] as u32);
            assert_eq!(
                &img.get_pixel(x, y).0[..want.len()],
                want,
                "{png}: texel {x},{y} voxel {p:?}"
            );
        }
    };
    let texels_are_the_solid = |png: &str, mesh_text: &str| texels_of(&v, png, mesh_text);
    texels_are_the_solid("baked.png", obj_text);
    // A solid of four channels (an RGBA exemplar, its alpha varying) keeps its fourth in the
    // atlas.
    let cells = image::open(fixture_path("cells32.png")).unwrap().to_rgba8();
    let rgba = image::RgbaImage::from_fn(32, 32, |x, y| {
        let [r, g, b, _] = cells.get_pixel(x, y).0;
        image::Rgba([r, g, b, (x * 8) as u8])
    });
    let rgba_path = d.join("rgba-exemplar.png");
    rgba.save(&rgba_path).unwrap();
    let rgba_ssa = d.join("rgba.ssa");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "--periodic",
        rgba_path.to_str().unwrap(),
        "-o",
        rgba_ssa.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = rgba_ssa.to_str().unwrap();
    let out = d.join("rgba.obj");
    let mut args = vec!["surface", r, "--mesh", mesh_path.to_str().unwrap()];
    args.extend_from_slice(&common);
    args.extend_from_slice(&["-o", out.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v4 = region16(r, "3", d);
    assert_eq!(v4.channels, 4);
    texels_of(&v4, "rgba.png", obj_text);
    // The same in groups of one brick (each group's texels placed as it finishes), and an open
    // mesh of three triangles, whose atlas has a cell no triangle owns (its texels take the
    // voxel of the first triangle's first corner): every texel is still the solid at its voxel.
    let open_text = "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\n";
    let open_path = d.join("open.obj");
    std::fs::write(&open_path, open_text).unwrap();
    for (text, path) in [(obj_text, &mesh_path), (open_text, &open_path)] {
        let out = d.join("grouped.obj");
        let mut args = vec!["surface", s, "--mesh", path.to_str().unwrap()];
        args.extend_from_slice(&common);
        args.extend_from_slice(&["--max-group", "4", "-o", out.to_str().unwrap()]);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        texels_are_the_solid("grouped.png", text);
    }
    // Binary glTF.
    let glb = d.join("baked.glb");
    let mut args = vec!["surface", s, "--mesh", mesh_path.to_str().unwrap()];
    args.extend_from_slice(&common);
    args.extend_from_slice(&["-o", glb.to_str().unwrap()]);
    assert!(run(&args).status.success());
    let bytes = std::fs::read(&glb).unwrap();
    assert_eq!(&bytes[..4], b"glTF");

    // The default layout: cells fitted to the triangles at one voxel per texel.
    let fitted = d.join("fitted.obj");
    let o = run(&[
        "surface",
        s,
        "--mesh",
        mesh_path.to_str().unwrap(),
        "--seed",
        "3",
        "--backend",
        "cpu",
        "--resolution",
        "16",
        "--json",
        "-o",
        fitted.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["texel_size"], 1.0);
    let mesh = solidsynth::mesh::parse_obj(obj_text.as_bytes(), "t").unwrap();
    let place = Placement::fit(&mesh, 16);
    let atlas = Atlas::fitted(&mesh, &place, 1.0, 0).unwrap();
    let img = image::open(d.join("fitted.png")).unwrap().to_rgba8();
    assert_eq!(
        summary["atlas"],
        serde_json::json!([atlas.width, atlas.height])
    );
    assert_eq!((img.width(), img.height()), (atlas.width, atlas.height));
    for (k, p) in atlas.texel_voxels(&mesh, &place).iter().enumerate() {
        let (x, y) = (k as u32 % atlas.width, k as u32 / atlas.width);
        let want = v.at(p[0] as u32, p[1] as u32, p[2] as u32);
        assert_eq!(&img.get_pixel(x, y).0[..3], want, "fitted texel {x},{y}");
    }
    // Its cells follow the triangles: the right-angled faces' 16-voxel legs get 17 texels, the
    // slanted face's 22.6-voxel edges 24.
    let sides: Vec<_> = atlas.cells().iter().map(|c| (c.width, c.height)).collect();
    assert_eq!(sides, [(17, 17), (17, 17), (17, 17), (24, 24)]);
    for (flags, needle) in [
        (vec!["--texel-size", "0"], "--texel-size 0"),
        (vec!["--texel-size", "inf"], "--texel-size inf"),
        (
            vec!["--texel-size", "2", "--texels", "4"],
            "cannot be used with",
        ),
    ] {
        let mut args = vec!["surface", s, "--mesh", mesh_path.to_str().unwrap()];
        args.extend_from_slice(&flags);
        let bad_out = d.join("bad.glb");
        args.extend_from_slice(&["--backend", "cpu", "-o", bad_out.to_str().unwrap()]);
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{flags:?}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(needle),
            "{flags:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!bad_out.exists());
    }

    // Bad input: non-finite coordinates, an empty mesh, an unknown output type.
    let bad = tempfile::tempdir().unwrap();
    let b = bad.path();
    std::fs::write(b.join("nan.obj"), "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(b.join("empty.obj"), "v 0 0 0\n").unwrap();
    for (mesh, output, needle) in [
        ("nan.obj", "o.glb", "non-finite"),
        ("empty.obj", "o.glb", "no triangles"),
        ("missing.ply", "o.glb", "missing.ply"),
        ("nan.obj", "o.txt", ".glb or .obj"),
    ] {
        let o = run(&[
            "surface",
            s,
            "--mesh",
            b.join(mesh).to_str().unwrap(),
            "--backend",
            "cpu",
            "-o",
            b.join(output).to_str().unwrap(),
        ]);
        assert_user_error(&o, needle, b, &["nan.obj", "empty.obj"]);
    }
    // Over the memory budget: the bricks holding the surface's texel positions, counted before
    // any synthesis (a one-triangle mesh scaled into a 2^20 box: a brick per texel, ~33 K for
    // its 256 x 256 texels, ~9 MB of colours and bookkeeping against a 5 MiB budget).
    std::fs::write(b.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let o = bin()
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "5")
        .args([
            "surface",
            s,
            "--mesh",
            b.join("tri.obj").to_str().unwrap(),
            "--resolution",
            "1048576",
            "--texels",
            "256",
            "--backend",
            "cpu",
            "-o",
            b.join("o.glb").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_user_error(
        &o,
        "surface --resolution 1048576: needs about",
        b,
        &["nan.obj", "empty.obj", "tri.obj"],
    );
}

#[test]
fn gradient_vectorize_and_render_round_trip_and_refuse_corrupt_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let vol = d.join("v.nrrd");
    let o = run(&[
        "synth",
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        vol.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gs = d.join("v.gsolid");
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--json",
        "-o",
        gs.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["grid"], serde_json::json!([5, 5, 5]));
    // The rendering is an approximation of the volume: bounded error, well below random.
    let rms = summary["rms"].as_f64().unwrap();
    assert!(rms > 0.0 && rms < 40.0, "rms {rms}");
    let out = d.join("r.nrrd");
    let o = run(&[
        "gradient",
        "render",
        gs.to_str().unwrap(),
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (
        solidsynth::io::nrrd::load(&vol).unwrap(),
        solidsynth::io::nrrd::load(&out).unwrap(),
    );
    let measured = solidsynth::gradient::vectorize::rms(&a, &b);
    assert!((measured - rms).abs() < 1e-9, "{measured} vs {rms}");
    // A slice with the cut conventions: centred at (7.5, 7.5, 5) with unit spacing, its pixels
    // sample the integer positions of z-slice 5 of the rendered volume.
    let png = d.join("slice.png");
    let o = run(&[
        "gradient",
        "render",
        gs.to_str().unwrap(),
        "--normal",
        "0,0,1",
        "--origin",
        "7.5,7.5,5",
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&png).unwrap().to_rgba8();
    for y in 0..16 {
        for x in 0..16 {
            assert_eq!(&img.get_pixel(x, y).0[..3], b.at(x, y, 5), "pixel {x},{y}");
        }
    }
    // Editing: strokes recolour, bad strokes are refused.
    let strokes = d.join("s.json");
    std::fs::write(
        &strokes,
        r#"{"strokes": [{"position": [8, 8, 8], "strength": 1.0}]}"#,
    )
    .unwrap();
    let edited = d.join("e.gsolid");
    let o = run(&[
        "gradient",
        "edit",
        gs.to_str().unwrap(),
        "--strokes",
        strokes.to_str().unwrap(),
        "--color",
        "255,0,255",
        "-o",
        edited.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e =
        solidsynth::gradient::format::from_bytes(&std::fs::read(&edited).unwrap(), "e").unwrap();
    let mut at_stroke = [0f32; 3];
    e.eval([8.0, 8.0, 8.0], &mut at_stroke);
    assert!(
        at_stroke[0] > 200.0 && at_stroke[2] > 200.0 && at_stroke[1] < 60.0,
        "{at_stroke:?}"
    );
    std::fs::write(&strokes, r#"{"strokes": []}"#).unwrap();
    let o = run(&[
        "gradient",
        "edit",
        gs.to_str().unwrap(),
        "--strokes",
        strokes.to_str().unwrap(),
        "--color",
        "255,0,255",
        "-o",
        d.join("x.gsolid").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no strokes"));
    assert!(!d.join("x.gsolid").exists());
    // A corrupt file: exit 2 naming it, nothing written.
    let mut bytes = std::fs::read(&gs).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x10;
    let bad = tempfile::tempdir().unwrap();
    let b = bad.path();
    std::fs::write(b.join("bad.gsolid"), &bytes).unwrap();
    let o = run(&[
        "gradient",
        "render",
        b.join("bad.gsolid").to_str().unwrap(),
        "--backend",
        "cpu",
        "-o",
        b.join("o.nrrd").to_str().unwrap(),
    ]);
    assert_user_error(&o, "bad.gsolid", b, &["bad.gsolid"]);
    // A volume over the kernels' 32-bit indices (and this machine's memory): refused before
    // anything is allocated.
    let o = run(&[
        "gradient",
        "render",
        gs.to_str().unwrap(),
        "--size",
        "2048",
        "--backend",
        "cpu",
        "-o",
        b.join("o.nrrd").to_str().unwrap(),
    ]);
    assert_user_error(&o, "--size 2048", b, &["bad.gsolid"]);
}

#[test]
fn synth_writes_a_vti_equal_to_its_nrrd() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (nrrd, vti) = (d.join("v.nrrd"), d.join("v.vti"));
    let o = run(&[
        "synth",
        "--size",
        "12",
        "--backend",
        "cpu",
        "--vti",
        vti.to_str().unwrap(),
        "-o",
        nrrd.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = solidsynth::io::nrrd::load(&nrrd).unwrap();
    let b = solidsynth::io::vti::from_bytes(&std::fs::read(&vti).unwrap(), "v.vti").unwrap();
    assert_eq!(a, b);
}

#[test]
fn gradient_synth_writes_a_tileable_solid_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("s.gsolid");
    let o = run(&[
        "gradient",
        "synth",
        fixture_path("cc0_gravel64.png").to_str().unwrap(),
        "--size",
        "18",
        "--iterations",
        "1",
        "--seed",
        "4",
        "--backend",
        "cpu",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["period"], 20, "{summary}");
    assert_eq!(summary["levels"].as_array().unwrap().len(), 3);
    let solid =
        solidsynth::gradient::format::from_bytes(&std::fs::read(&out).unwrap(), "s").unwrap();
    assert_eq!(solid.dims, [6, 6, 6]);

    let bad = tempfile::tempdir().unwrap();
    let b = bad.path();
    let target = b.join("o.gsolid");
    let t = target.to_str().unwrap();
    let cells = fixture_path("cells32.png");
    let cases: [(&[&str], &str); 4] = [
        (&["--size", "32", "--field", "spiral:1,0,0"], "--field"),
        (&["--size", "32", "--field", "constant:0,0,0"], "--field"),
        (&["--size", "4"], "--size 4"),
        // 32x32 is smaller than the coarse level's 33-pixel patches.
        (&[cells.to_str().unwrap(), "--size", "32"], "cells32.png"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["gradient", "synth", "--backend", "cpu", "-o", t];
        all.extend_from_slice(args);
        assert_user_error(&run(&all), needle, b, &[]);
    }
}

#[test]
fn gradient_synth_with_a_mask_writes_a_region_solid_and_refuses_bad_masks() {
    use solidsynth::gradient::regions::{Blend, RegionSolid};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (img, mask) = solidsynth::exemplar::procedural::discs(40, 7, 6.0, 5);
    let (ex, mk) = (d.join("discs.png"), d.join("mask.png"));
    img.to_dynamic().save(&ex).unwrap();
    mask.to_dynamic().save(&mk).unwrap();
    let out = d.join("r.gsolid");
    let o = run(&[
        "gradient",
        "synth",
        ex.to_str().unwrap(),
        "--mask",
        mk.to_str().unwrap(),
        "--size",
        "16",
        "--iterations",
        "1",
        "--backend",
        "cpu",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["period"], 16, "{summary}");
    assert!(
        summary["regions"]["split_points"].as_u64().unwrap() > 0,
        "{summary}"
    );
    let rs = RegionSolid::from_bytes(&std::fs::read(&out).unwrap(), "r").unwrap();
    assert_eq!(rs.positive.dims, [5, 5, 5]);
    // `gradient render` reads it: the volume is the solid's own exact rendering.
    let vol = d.join("r.nrrd");
    let o = run(&[
        "gradient",
        "render",
        out.to_str().unwrap(),
        "--no-antialias",
        "--backend",
        "cpu",
        "-o",
        vol.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rendered = solidsynth::io::nrrd::load(&vol).unwrap();
    assert_eq!(
        rendered,
        rs.render([17; 3], &solidsynth::backend::Compute::Cpu, Blend::Exact)
            .unwrap()
    );

    // Refused with exit code 2, nothing written.
    let bad = tempfile::tempdir().unwrap();
    let b = bad.path();
    let small = d.join("small.png");
    solidsynth::exemplar::Image::new(32, 40, 1)
        .to_dynamic()
        .save(&small)
        .unwrap();
    let empty = d.join("empty.png");
    solidsynth::exemplar::Image::new(40, 40, 1)
        .to_dynamic()
        .save(&empty)
        .unwrap();
    let text = d.join("mask.txt");
    std::fs::write(&text, "not an image").unwrap();
    let missing = d.join("missing.png");
    let target = b.join("o.gsolid");
    let cases: [(&Path, &str, &str); 5] = [
        (&small, "16", "32x40"),
        (&empty, "16", "all inside or all outside"),
        (&text, "16", "cannot decode"),
        (&missing, "16", "cannot read"),
        (&mk, "300", "--mask with --size 300"),
    ];
    for (mask, size, needle) in cases {
        let o = run(&[
            "gradient",
            "synth",
            ex.to_str().unwrap(),
            "--mask",
            mask.to_str().unwrap(),
            "--size",
            size,
            "--backend",
            "cpu",
            "-o",
            target.to_str().unwrap(),
        ]);
        assert_user_error(&o, needle, b, &[]);
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("--mask"),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // The region refinement has a lower size limit than the separation.
    let o = run(&[
        "gradient",
        "synth",
        ex.to_str().unwrap(),
        "--mask",
        mk.to_str().unwrap(),
        "--size",
        "200",
        "--optimize",
        "-o",
        target.to_str().unwrap(),
    ]);
    assert_user_error(&o, "--mask --optimize with --size 200", b, &[]);
}

#[test]
fn gradient_vectorize_with_a_mask_separates_regions() {
    use solidsynth::volume::Volume;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 21u32;
    let (mut v, mut m) = (Volume::new(n, n, n, 3), Volume::new(n, n, n, 1));
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let inside = x + y / 2 < 14;
                m.at_mut(x, y, z)[0] = if inside { 255 } else { 0 };
                v.at_mut(x, y, z).copy_from_slice(if inside {
                    &[230, 40, 20]
                } else {
                    &[20, 60, 210]
                });
            }
        }
    }
    let (vol, mask) = (d.join("v.nrrd"), d.join("m.nrrd"));
    solidsynth::io::nrrd::save(&v, &vol).unwrap();
    solidsynth::io::nrrd::save(&m, &mask).unwrap();
    let gs = d.join("r.gsolid");
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--mask",
        mask.to_str().unwrap(),
        "--json",
        "-o",
        gs.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (with, without) = (
        s["rms"].as_f64().unwrap(),
        s["rms_without_regions"].as_f64().unwrap(),
    );
    // (A stair-stepped oblique boundary: about half the error remains at its steps.)
    assert!(
        with < 0.6 * without,
        "with regions {with}, without {without}"
    );
    assert!(s["split_points"].as_u64().unwrap() > 0);
    // Rendering a region file, both blends; the exact one reproduces the reported error.
    let out = d.join("r.nrrd");
    let o = run(&[
        "gradient",
        "render",
        gs.to_str().unwrap(),
        "--no-antialias",
        "--backend",
        "cpu",
        "--size",
        "21",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = solidsynth::io::nrrd::load(&out).unwrap();
    let measured = solidsynth::gradient::vectorize::rms(&r, &v);
    assert!((measured - with).abs() < 1e-9, "{measured} vs {with}");
    // --optimize (eq. 3 over both feature sets) lowers the error further.
    let opt = d.join("opt.gsolid");
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--mask",
        mask.to_str().unwrap(),
        "--optimize",
        "--json",
        "-o",
        opt.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let so: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(so["rms"].as_f64().unwrap() < with, "{so}");
    // Detail residual: sigma channels stored, grain added at render time (or not).
    let dg = d.join("detail.gsolid");
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--detail",
        "-o",
        dg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let solid =
        solidsynth::gradient::format::from_bytes(&std::fs::read(&dg).unwrap(), "d").unwrap();
    assert_eq!((solid.channels, solid.detail), (6, 3));
    let render = |extra: &[&str], name: &str| {
        let out = d.join(name);
        let mut args = vec![
            "gradient",
            "render",
            dg.to_str().unwrap(),
            "--backend",
            "cpu",
            "--size",
            "21",
        ];
        args.extend(extra);
        args.extend(["-o", out.to_str().unwrap()]);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        solidsynth::io::nrrd::load(&out).unwrap()
    };
    let (grain, smooth) = (render(&[], "g.nrrd"), render(&["--no-detail"], "s.nrrd"));
    assert_eq!((grain.channels, smooth.channels), (3, 3));
    assert_eq!(
        smooth,
        solidsynth::gradient::vectorize::render(&solid, [21; 3])
    );
    assert_ne!(grain, smooth);
    assert_eq!(grain, render(&[], "g2.nrrd"), "grain is deterministic");
    // Refused, nothing written: a mask of another size, editing.
    let small = d.join("small.nrrd");
    solidsynth::io::nrrd::save(&Volume::new(8, 8, 8, 1), &small).unwrap();
    let no = d.join("no.gsolid");
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--mask",
        small.to_str().unwrap(),
        "-o",
        no.to_str().unwrap(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!no.exists());
    let strokes = d.join("s.json");
    std::fs::write(
        &strokes,
        r#"{"strokes": [{"position": [8, 8, 8], "strength": 1.0}]}"#,
    )
    .unwrap();
    // Editing takes plain solids only.
    for (input, needle) in [(&gs, "region-separated"), (&dg, "detail channels")] {
        let o = run(&[
            "gradient",
            "edit",
            input.to_str().unwrap(),
            "--strokes",
            strokes.to_str().unwrap(),
            "--color",
            "255,0,255",
            "-o",
            no.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&o.stderr).contains(needle));
    }
    let o = run(&[
        "gradient",
        "vectorize",
        vol.to_str().unwrap(),
        "--mask",
        mask.to_str().unwrap(),
        "--detail",
        "-o",
        no.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!no.exists());
}

/// llvmpipe runs 16 lanes wide on an AVX-512 host unless the user chose a width: the process
/// sets `LP_NATIVE_VECTOR_WIDTH=512` only when it is unset (`adapters` names the width). Under
/// `CI` lavapipe is the project's Vulkan device (.ci/run installs it), so its absence fails.
#[test]
fn lavapipe_runs_at_the_host_vector_width_unless_the_user_chose_one() {
    let adapters = |width: Option<&str>| {
        let mut c = bin();
        c.arg("adapters");
        match width {
            Some(w) => c.env("LP_NATIVE_VECTOR_WIDTH", w),
            None => c.env_remove("LP_NATIVE_VECTOR_WIDTH"),
        };
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let listed = adapters(None);
    if !listed.contains("llvmpipe") {
        assert!(
            std::env::var_os("CI").is_none(),
            "no lavapipe adapter under CI: {listed}"
        );
        return;
    }
    #[cfg(target_arch = "x86_64")]
    let wide = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512vl");
    #[cfg(not(target_arch = "x86_64"))]
    let wide = false;
    if wide {
        assert!(listed.contains("512 bits"), "{listed}");
    }
    let chosen = adapters(Some("256"));
    assert!(chosen.contains("256 bits"), "{chosen}");
}

/// A subcommand's name is not a path: `ptm capture -o capture` writes ./capture (the check that
/// no output is also an input reads the command's arguments only). An output that is an input
/// is still refused.
#[test]
fn an_output_named_like_its_subcommand_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let o = bin()
        .current_dir(dir.path())
        .args([
            "ptm", "capture", "--size", "40", "--lights", "12", "-o", "capture",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("capture").is_dir());
    let image = dir.path().join("e.png");
    std::fs::copy(fixture_path("cells32.png"), &image).unwrap();
    let p = image.to_str().unwrap();
    let o = run(&["analyze", p, "--backend", "cpu", "-o", p]);
    assert_user_error(
        &o,
        "is also given as an input",
        dir.path(),
        &["capture", "e.png"],
    );
}
