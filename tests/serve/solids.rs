//! Solids made by the server: uploads checked and analysed in a job, the page's parameters validated as the command line does.

use super::*;

#[test]
fn uploads_are_bounded_checked_and_analysed_in_a_job() {
    let (addr, _) = server();
    let post = |query: &str, body: &[u8]| {
        client::request(
            addr,
            "POST",
            &format!("/api/solids{query}"),
            Some("image/png"),
            body,
        )
        .unwrap()
    };
    assert_error(&post("", &vec![0u8; MAX_UPLOAD + 1]), 413, "larger than");
    assert_error(&post("", b"not an image"), 400, "upload");
    let mut big = Vec::new();
    image::RgbImage::new(100, 80)
        .write_to(&mut std::io::Cursor::new(&mut big), image::ImageFormat::Png)
        .unwrap();
    assert_error(&post("", &big), 400, "at most 64");
    assert_error(&post("?exemplar=granite", b""), 400, "built-ins are");
    assert_error(&post("", b""), 400, "give ?exemplar");
    assert_error(&post("?seed=-1&exemplar=cells", b""), 400, "seed");
    // A real upload: a job, progress, then a solid that cuts.
    let png = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/marble32.png"),
    )
    .unwrap();
    let r = post("?seed=5&periodic=1", &png);
    assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
    let solid = wait_job(addr, r.json()["id"].as_u64().unwrap());
    let info = get(addr, &format!("/api/solids/{solid}")).json();
    assert_eq!(info["seed"], 5);
    assert_eq!(info["name"], "upload");
    let cut = get(addr, &cut_path(solid, "origin=4,4,4&normal=1,0,0&size=12"));
    assert_eq!(cut.status, 200);
}

#[test]
fn new_solids_take_the_pages_parameters_validated_as_the_command_line_does() {
    let (addr, _) = own_server(ServeConfig {
        port: 0,
        preview_size: PREVIEW,
        ..ServeConfig::default()
    });
    let png = std::fs::read(common::fixture_path("marble32.png")).unwrap();
    let post = |query: &str| {
        client::request(
            addr,
            "POST",
            &format!("/api/solids?{query}"),
            Some("image/png"),
            &png,
        )
        .unwrap()
    };
    for (query, needle) in [
        ("jitter=9", "jitter"),
        ("passes=9", "passes"),
        ("passes=1,2", "passes"),
        ("color=x,y,z", "one source"),
        ("color=purple", "color"),
        ("feature=blob", "feature"),
        ("coarse_cache=100", "coarse-cache"),
    ] {
        assert_error(&post(query), 400, needle);
    }
    let r =
        post("periodic=1&seed=2&jitter=0.5&passes=2,2,2,1&color=x&feature=none&coarse_cache=64");
    assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
    let solid = wait_job(addr, r.json()["id"].as_u64().unwrap());
    let info = get(addr, &format!("/api/solids/{solid}")).json();
    assert_eq!(info["seed"], 2);
    assert_eq!(info["params"]["jitter"], 0.5);
    assert_eq!(info["params"]["passes"], "2,2,2,1");
    assert_eq!(info["params"]["color"], "x");
    assert_eq!(info["params"]["coarse_cache"], 64);
    let cut = get(
        addr,
        &cut_path(solid, "origin=-300,70,5&normal=0,0,1&size=8"),
    );
    assert_eq!(cut.status, 200);
}
