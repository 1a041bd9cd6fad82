//! `synth`, `region` and `cut`: the same solid whatever asks for it, in every volume format, and their bad inputs.

use super::*;

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
    // One solid, asked for with `more` arguments.
    let synth = |more: &[&str]| {
        let solid = [
            "synth",
            ssa.to_str().unwrap(),
            "--size",
            "12",
            "--seed",
            "3",
        ];
        let o = run(&[&solid[..], &["--backend", "cpu"], more].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    synth(&[
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
        synth(&[
            "--max-group",
            max_group,
            "-o",
            d.join(format!("{name}.nrrd")).to_str().unwrap(),
            "--triples",
            d.join(format!("{name}.bin")).to_str().unwrap(),
        ]);
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
    // The volume written as a PNG is the same picture, in the same bytes; an opaque solid's
    // PNGs are RGB.
    let as_png = d.join("v.png");
    synth(&["-o", as_png.to_str().unwrap()]);
    assert!(std::fs::read(&as_png).unwrap() == std::fs::read(&flip).unwrap());
    let slice = image::open(slices.join("slice_0005.png")).unwrap();
    assert_eq!(slice.color(), image::ColorType::Rgb8);
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
        "6",
        "-o",
        g.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("--max-group") && stderr.contains("a multiple of 4"),
        "{stderr}"
    );
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
    // The convention: `cut --origin 8,8,5 --normal 0,0,1 --size 16` is z-slice 5.
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
