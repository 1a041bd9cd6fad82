//! `analyze`, `inspect` and the feature channel: the .ssa a user gets, from one or three exemplars.

use super::*;

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
