//! `solidsynth lapped`: fill, cut, view and bake from the command line, and their bad inputs
//! (exit 2, nothing written).

use super::run;
use crate::common::assert_refused;
use solidsynth::io::nrrd;
use solidsynth::lapped::shapes;
use solidsynth::volume::Volume;
use std::path::{Path, PathBuf};
use std::process::Command;

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

struct Fixtures {
    dir: tempfile::TempDir,
    mesh: PathBuf,
    exemplar: PathBuf,
}

fn fixtures() -> Fixtures {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("sphere.obj");
    std::fs::write(&mesh, shapes::obj_text(&shapes::sphere(24, 12))).unwrap();
    let exemplar = dir.path().join("e.nrrd");
    nrrd::save(&crate::common::lapped_exemplar_volume(), &exemplar).unwrap();
    Fixtures {
        dir,
        mesh,
        exemplar,
    }
}

#[test]
fn cli_fill_cut_bake() {
    let f = fixtures();
    let model = f.dir.path().join("m.lst");
    let fill = |threads: &str, out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_solidsynth"))
            .env("SOLIDSYNTH_LOG", "warn")
            .env("RAYON_NUM_THREADS", threads)
            .args([
                "lapped",
                "fill",
                "--mesh",
                p(&f.mesh),
                "--exemplar",
                p(&f.exemplar),
                "--resolution",
                "6",
                "--seed",
                "3",
                "--json",
                "-o",
                p(out),
            ])
            .output()
            .unwrap()
    };
    let out = fill("2", &model);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(summary["tets"].as_u64().unwrap() > 100);
    assert_eq!(summary["inverted_tets"], 0);
    assert!(summary["min_dihedral_degrees"].as_f64().unwrap() > 5.0);
    assert!(summary["patches"].as_u64().unwrap() > 5);
    // Same seed, one thread: byte-identical model.
    let again = f.dir.path().join("m1.lst");
    assert!(fill("1", &again).status.success());
    assert_eq!(
        std::fs::read(&model).unwrap(),
        std::fs::read(&again).unwrap()
    );

    let cut = f.dir.path().join("cut.png");
    let out = run(&[
        "lapped",
        "cut",
        p(&model),
        "--origin",
        "0,0,0",
        "--normal",
        "0,0,1",
        "--size",
        "64",
        "--extent",
        "2.5",
        "--repeat",
        "2",
        "--json",
        "-o",
        p(&cut),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&cut).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (64, 64));
    assert_eq!(img.get_pixel(32, 32)[3], 255);
    assert_eq!(img.get_pixel(1, 1)[3], 0);

    // The GPU render (lavapipe in CI; skipped only without an adapter and without CI).
    let view = f.dir.path().join("view.png");
    let out = run(&[
        "lapped",
        "render",
        p(&model),
        "--camera",
        "20,15",
        "--size",
        "64",
        "--backend",
        "gpu",
        "-o",
        p(&view),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    if out.status.success() {
        let img = image::open(&view).unwrap().to_rgba8();
        assert_eq!(img.dimensions(), (64, 64));
        assert_eq!(
            img.get_pixel(32, 32)[3],
            255,
            "the sphere covers the centre"
        );
        assert_eq!(img.get_pixel(0, 0)[3], 0, "background is transparent");
        // `bench lapped --render` starts the render as a child process, which must choose its
        // own llvmpipe width rather than inherit the 512 bits the bench set for itself (which
        // the render refuses).
        let kiwi = f.dir.path().join("kiwi.nrrd");
        let out = run(&["lapped", "exemplar", "--kind", "kiwi", "-o", p(&kiwi)]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = run(&[
            "bench",
            "lapped",
            "--resolution",
            "4",
            "--exemplar",
            p(&kiwi),
            "--runs",
            "1",
            "--cuts",
            "1",
            "--render",
        ]);
        let printed = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && printed.contains("render 1024x1024"),
            "{printed}{}",
            String::from_utf8_lossy(&out.stderr)
        );
    } else {
        assert!(
            std::env::var_os("CI").is_none() && err.contains("no Vulkan adapter"),
            "render failed: {err}"
        );
        eprintln!("SKIPPED render (no GPU adapter, CI unset)");
    }

    let glb = f.dir.path().join("m.glb");
    let out = run(&["lapped", "bake", p(&model), "--texels", "4", "-o", p(&glb)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(&std::fs::read(&glb).unwrap()[..4], b"glTF");
}

#[test]
fn cli_refuses_bad_input() {
    let f = fixtures();
    let d = f.dir.path();
    let out = d.join("out.lst");
    let fill = |mesh: &Path, exemplar: &Path, field: Option<&Path>| {
        let mut args = vec![
            "lapped".to_string(),
            "fill".into(),
            "--mesh".into(),
            p(mesh).into(),
            "--exemplar".into(),
            p(exemplar).into(),
            "--resolution".into(),
            "5".into(),
            "-o".into(),
            p(&out).into(),
        ];
        if let Some(fl) = field {
            args.push("--field".into());
            args.push(p(fl).into());
        }
        Command::new(env!("CARGO_BIN_EXE_solidsynth"))
            .env("SOLIDSYNTH_LOG", "warn")
            .args(&args)
            .output()
            .unwrap()
    };
    let write = |name: &str, text: &str| {
        let path = d.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    // Meshes: empty, NaN, flat.
    let empty = write("empty.obj", "# nothing\n");
    assert_refused(&fill(&empty, &f.exemplar, None), "empty.obj", &out);
    let nan = write(
        "nan.obj",
        "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n",
    );
    assert_refused(&fill(&nan, &f.exemplar, None), "non-finite", &out);
    let flat = write("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_refused(&fill(&flat, &f.exemplar, None), "no volume", &out);
    // Exemplars: not a cube, not a volume.
    let slab = d.join("slab.nrrd");
    nrrd::save(&Volume::new(8, 8, 4, 3), &slab).unwrap();
    assert_refused(&fill(&f.mesh, &slab, None), "cube", &out);
    let junk = write("junk.nrrd", "NRRD0004\nsizes: 0\n\n");
    assert_refused(&fill(&f.mesh, &junk, None), "junk.nrrd", &out);
    // Constraint files: unknown type, missing field, unknown field, point outside the mesh.
    for (name, text, needle) in [
        ("type.json", r#"{"type": "9"}"#, "unknown texture type"),
        ("missing.json", r#"{"scale": 0.5}"#, "missing field `type`"),
        (
            "unknown.json",
            r#"{"type": "0", "speed": 1}"#,
            "unknown field `speed`",
        ),
        ("nostrokes.json", r#"{"type": "1-a"}"#, "needs \"strokes\""),
        (
            "outside.json",
            r#"{"type": "0", "scales": [{"at": [3, 0, 0], "scale": 1}]}"#,
            "outside the mesh",
        ),
        (
            "huge.json",
            r#"{"type": "0", "scale": 1e30}"#,
            "times the mesh's longest side",
        ),
    ] {
        let field = write(name, text);
        assert_refused(&fill(&f.mesh, &f.exemplar, Some(&field)), needle, &out);
        let err =
            String::from_utf8_lossy(&fill(&f.mesh, &f.exemplar, Some(&field)).stderr).to_string();
        assert!(err.contains(name), "{err}");
    }
    // Cut and render arguments.
    let model = d.join("m.lst");
    assert!(fill(&f.mesh, &f.exemplar, None).status.success());
    std::fs::rename(&out, &model).unwrap();
    let png = d.join("c.png");
    let cut = |origin: &str, normal: &str| {
        run(&[
            "lapped",
            "cut",
            p(&model),
            "--origin",
            origin,
            "--normal",
            normal,
            "-o",
            p(&png),
        ])
    };
    assert_refused(&cut("0,0,0", "0,0,0"), "--normal", &png);
    assert_refused(&cut("0,nan,0", "0,0,1"), "--origin", &png);
    for (camera, problem) in [
        ("0,95", "strictly between -90 and 90"),
        ("0,90", "strictly between -90 and 90"),
        ("0,20,0.5", "over 1 bounding radius"),
        ("0,inf", "finite"),
        ("0", "expected AZ,EL"),
    ] {
        let camera = format!("--camera={camera}");
        let o = run(&["lapped", "render", p(&model), &camera, "-o", p(&png)]);
        assert_refused(&o, problem, &png);
    }
    let damaged = write("bad.lst", "SSLST001 and then nothing useful");
    let o = run(&[
        "lapped",
        "cut",
        p(&damaged),
        "--origin",
        "0,0,0",
        "--normal",
        "0,0,1",
        "-o",
        p(&png),
    ]);
    assert_refused(&o, "bad.lst", &png);
    let o = run(&["lapped", "bake", p(&model), "-o", p(&d.join("m.obj"))]);
    assert_refused(&o, ".glb", &d.join("m.obj"));
}
