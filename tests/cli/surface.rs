//! `surface`: the solid baked at each texel, and the meshes it refuses.

use super::*;

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
    std::fs::write(b.join("point.obj"), "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n").unwrap();
    for (mesh, output, needle) in [
        ("nan.obj", "o.glb", "non-finite"),
        ("empty.obj", "o.glb", "no triangles"),
        ("point.obj", "o.glb", "every triangle has zero area"),
        ("missing.ply", "o.glb", "missing.ply"),
        ("nan.obj", "o.txt", ".glb or .obj"),
        ("nan.obj", "my mesh.obj", "may not contain spaces"),
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
        assert_user_error(&o, needle, b, &["nan.obj", "empty.obj", "point.obj"]);
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
        &["nan.obj", "empty.obj", "point.obj", "tri.obj"],
    );
}
