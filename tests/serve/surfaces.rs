//! Meshes and surfaces: the bunny served, uploaded meshes baked on demand equal to the command line's.

use super::*;

#[test]
fn the_bunny_mesh_is_served_and_its_size_matches_its_header() {
    let (addr, _) = server();
    let r = get(addr, "/api/meshes/bunny/geometry");
    assert_eq!(r.status, 200);
    assert_eq!(r.header("content-type"), Some("application/octet-stream"));
    let b = &r.body;
    let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
    let (vertices, triangles) = (u32_at(0), u32_at(4));
    // The Stanford bunny of assets/meshes/bunny.obj.
    assert_eq!((vertices, triangles), (1839, 3674));
    assert_eq!(b.len(), 8 + 12 * vertices + 12 * triangles);
    // Positions fit [-0.5, 0.5]^3 and the longest side spans it; indices name vertices.
    let positions: Vec<f32> = b[8..8 + 12 * vertices]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert!(positions.iter().all(|p| p.abs() <= 0.5 + 1e-6));
    let span = |k: usize| {
        let axis = positions.iter().skip(k).step_by(3);
        let (lo, hi) = axis.fold((f32::MAX, f32::MIN), |(l, h), &p| (l.min(p), h.max(p)));
        hi - lo
    };
    assert!((span(0).max(span(1)).max(span(2)) - 1.0).abs() < 1e-5);
    assert!((0..3 * triangles).all(|k| u32_at(8 + 12 * vertices + 4 * k) < vertices));
}

#[test]
fn surfaces_bake_on_demand_onto_uploaded_meshes_and_equal_the_command_line() {
    let (addr, solid) = own_server(ServeConfig {
        port: 0,
        preview_size: PREVIEW,
        max_surface_resolution: 128,
        ..ServeConfig::default()
    });
    let post = |path: &str, content_type: &str, body: &[u8]| {
        client::request(addr, "POST", path, Some(content_type), body).unwrap()
    };
    let cube_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/uv-cube.obj");
    let cube = std::fs::read(&cube_path).unwrap();
    // An upload: kept, listed, its geometry centred in the unit box.
    let r = post("/api/meshes?format=obj&name=cube", "model/obj", &cube);
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let mesh = r.json();
    assert_eq!(
        (mesh["vertices"].as_u64(), mesh["triangles"].as_u64()),
        (Some(8), Some(12))
    );
    assert_eq!(mesh["has_uvs"], true);
    let id = mesh["id"].as_str().unwrap().to_string();
    let list = get(addr, "/api/meshes").json();
    assert!(list.as_array().unwrap().iter().any(|m| m["id"] == "bunny"));
    assert!(list
        .as_array()
        .unwrap()
        .iter()
        .any(|m| m["id"] == id.as_str()));
    let geometry = get(addr, &format!("/api/meshes/{id}/geometry")).body;
    assert_eq!(geometry.len(), 8 + 8 * 12 + 12 * 12);
    let coords: Vec<f32> = geometry[8..8 + 8 * 12]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert!(coords.iter().all(|c| c.abs() == 0.5), "{coords:?}");
    // Bad meshes and requests.
    assert_error(
        &post("/api/meshes?format=obj", "model/obj", b"garbage"),
        400,
        "line 1 begins with \"garbage\", which is not an OBJ statement",
    );
    assert_error(
        &post("/api/meshes?format=obj", "model/obj", b"# nothing\n"),
        400,
        "no triangles",
    );
    assert_error(
        &post("/api/meshes?format=stl", "model/stl", &cube),
        400,
        "format",
    );
    assert_error(
        &post("/api/meshes?format=obj", "text/plain", &cube),
        415,
        "mesh",
    );
    assert_error(
        &post("/api/meshes", "model/obj", &cube),
        400,
        "missing format",
    );
    let surface = |query: &str| {
        post(
            &format!("/api/solids/{solid}/surface?{query}"),
            "model/obj",
            b"",
        )
    };
    assert_error(&surface("resolution=4096"), 400, "resolution");
    assert_error(&surface("mesh=77"), 404, "no mesh");
    assert_error(&surface("tiles=3"), 400, "unknown parameter");

    // A bake: a job, then a .glb equal byte for byte to the command line's.
    let r = surface(&format!("mesh={id}&resolution=16"));
    assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.json()["kind"], "surface");
    let done = wait_state(addr, r.json()["id"].as_u64().unwrap(), "done");
    let baked = done["surface"].as_u64().unwrap();
    let glb = get(addr, &format!("/api/surfaces/{baked}.glb"));
    assert_eq!(glb.header("content-type"), Some("model/gltf-binary"));
    assert!(glb.header("content-disposition").unwrap().contains(".glb"));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cube.glb");
    let o = bin()
        .args([
            "surface",
            common::fixture_path("cells32.png").to_str().unwrap(),
            "--periodic",
        ])
        .args([
            "--seed",
            "3",
            "--backend",
            "cpu",
            "--resolution",
            "16",
            "--mesh",
        ])
        .arg(&cube_path)
        .arg("-o")
        .arg(&out)
        .env("SOLIDSYNTH_CACHE_DIR", dir.path().join("cache"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        glb.body == std::fs::read(&out).unwrap(),
        "the server's .glb differs from surface's"
    );
    let info = get(addr, &format!("/api/surfaces/{baked}")).json();
    assert_eq!(
        (info["mesh"].as_str(), info["resolution"].as_u64()),
        (Some(id.as_str()), Some(16))
    );
    assert_error(&get(addr, "/api/surfaces/999.glb"), 404, "no surface");

    // Cancelling a running bake ends it "cancelled"; a second cancel is a conflict.
    let r = surface("resolution=128");
    let job = r.json()["id"].as_u64().unwrap();
    let c = post(&format!("/api/jobs/{job}/cancel"), "model/obj", b"");
    assert_eq!(c.status, 200, "{}", String::from_utf8_lossy(&c.body));
    let ended = wait_state(addr, job, "cancelled");
    assert!(ended["surface"].is_null());
    assert_error(
        &post(&format!("/api/jobs/{job}/cancel"), "model/obj", b""),
        409,
        "already ended",
    );
    assert_error(
        &post("/api/jobs/12345/cancel", "model/obj", b""),
        404,
        "no job",
    );
    // The solid still cuts after its bake was cancelled.
    let cut = get(addr, &cut_path(solid, "origin=4,4,4&normal=0,0,1&size=8"));
    assert_eq!(cut.status, 200);
}
