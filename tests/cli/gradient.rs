//! `gradient synth`, `vectorize`, `render` and `edit`: files that round-trip, masks, and refused input.

use super::*;

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
    // By default the volume's own size comes back (its grid spans 17 voxels).
    let out = d.join("r.nrrd");
    let o = run(&[
        "gradient",
        "render",
        gs.to_str().unwrap(),
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
        "--json",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["size"], serde_json::json!([16, 16, 1]));
    assert_eq!(summary["output"], png.to_str().unwrap());
    let img = image::open(&png).unwrap().to_rgba8();
    for y in 0..16 {
        for x in 0..16 {
            assert_eq!(&img.get_pixel(x, y).0[..3], b.at(x, y, 5), "pixel {x},{y}");
        }
    }
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
    assert!(solid.periodic && solid.size == [20; 3]);
    // Rendered: one period by default, repeating past it, in volumes and in slices anywhere.
    let render = |args: &[&str], name: &str| -> std::path::PathBuf {
        let path = d.join(name);
        let mut all = vec![
            "gradient",
            "render",
            out.to_str().unwrap(),
            "--backend",
            "cpu",
        ];
        all.extend_from_slice(args);
        all.extend_from_slice(&["-o", path.to_str().unwrap()]);
        let o = run(&all);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        path
    };
    let period = solidsynth::io::nrrd::load(&render(&[], "p.nrrd")).unwrap();
    assert_eq!(period.dims(), [20; 3]);
    let twice = solidsynth::io::nrrd::load(&render(&["--size", "40"], "t.nrrd")).unwrap();
    for (x, y, z) in [(0, 0, 0), (25, 3, 39), (39, 39, 20), (20, 5, 7)] {
        assert_eq!(
            twice.at(x, y, z),
            period.at(x % 20, y % 20, z % 20),
            "{x},{y},{z}"
        );
    }
    let slice = |origin: &str, name: &str| {
        let path = render(
            &["--normal", "1,2,3", "--origin", origin, "--size", "24"],
            name,
        );
        image::open(path).unwrap().to_rgba8()
    };
    let near = slice("3,7,11", "near.png");
    assert_eq!(
        near,
        slice("-37,1007,-9", "far.png"),
        "shifted by whole periods"
    );
    let colours: std::collections::HashSet<_> = near.pixels().map(|p| p.0).collect();
    assert!(
        colours.len() > 50,
        "a textured slice: {} colours",
        colours.len()
    );

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
    // Over a small memory budget: refused before any work (the estimate is about 113 MiB).
    let o = bin()
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "64")
        .args([
            "gradient",
            "synth",
            "--size",
            "256",
            "--backend",
            "cpu",
            "-o",
            t,
        ])
        .output()
        .unwrap();
    assert_user_error(&o, "--size 256: needs about", b, &[]);
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
    // `gradient render` reads it: the volume is the solid's own exact rendering, one period.
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
        rs.render([16; 3], &solidsynth::backend::Compute::Cpu, Blend::Exact)
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
