//! Requests the server refuses or survives: bad parameters, unknown paths and methods, hostile and cross-origin requests, mutated requests, a mixed load.

use super::*;

#[test]
fn bad_parameters_get_400_with_a_message_and_the_server_goes_on() {
    let (addr, solid) = server();
    let cases = [
        ("origin=8,8,8&normal=0,0,0", "normal"),
        ("origin=8,8,8&normal=1,1,0", "unit vector"),
        ("origin=8,8,8&normal=nan,0,1", "normal"),
        ("origin=8,8,inf&normal=0,0,1", "origin"),
        ("origin=8,8&normal=0,0,1", "origin"),
        ("normal=0,0,1", "missing origin"),
        ("origin=8,8,8", "missing normal"),
        ("origin=8,8,8&normal=0,0,1&size=0", "size"),
        ("origin=8,8,8&normal=0,0,1&size=100000", "size"),
        ("origin=8,8,8&normal=0,0,1&size=-3", "size"),
        (
            "origin=8,8,8&normal=0,0,1&size=64&spacing=8",
            "spans at most",
        ),
        ("origin=8,8,8&normal=0,0,1&spacing=0", "spacing"),
        ("origin=1e300,0,0&normal=0,0,1", "origin"),
        ("origin=8,8,8&normal=0,0,1&up=0,0,1", "parallel"),
        ("origin=8,8,8&normal=0,0,1&colour=red", "unknown parameter"),
        ("origin=8,8,8&origin=1,1,1&normal=0,0,1", "twice"),
        ("origin=%zz&normal=0,0,1", "percent"),
    ];
    for (q, needle) in cases {
        assert_error(&get(addr, &cut_path(solid, q)), 400, needle);
    }
    let ok = get(addr, &cut_path(solid, "origin=8,8,8&normal=0,1,0&size=8"));
    assert_eq!(ok.status, 200);
}

#[test]
fn unknown_paths_methods_and_traversal_are_refused() {
    let (addr, solid) = server();
    assert_error(&get(addr, "/api/nothing"), 404, "no API endpoint");
    assert_error(
        &get(addr, "/api/solids/999999/cut?origin=0,0,0&normal=0,0,1"),
        404,
        "no solid",
    );
    assert_error(&get(addr, "/api/jobs/abc"), 404, "not an id");
    for p in [
        "/../Cargo.toml",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/assets/viewer/index.html",
        "/src/lib.rs",
    ] {
        assert_eq!(get(addr, p).status, 404, "{p}");
    }
    let post = client::request(
        addr,
        "POST",
        &cut_path(solid, "origin=0,0,0&normal=0,0,1"),
        None,
        b"",
    )
    .unwrap();
    assert_error(&post, 405, "not allowed");
    let page = get(addr, "/");
    assert_eq!(page.status, 200);
    assert!(String::from_utf8_lossy(&page.body).contains("solidsynth viewer"));
    assert!(get(addr, "/viewer.js").status == 200 && get(addr, "/viewer.css").status == 200);
    let state = get(addr, "/api/state").json();
    assert!(state["solids"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s["id"] == solid));
    let ex = get(addr, "/api/exemplars").json();
    assert!(ex.as_array().unwrap().len() >= 3);
    let png = get(addr, "/api/exemplars/marble.png");
    assert_eq!(png.header("content-type"), Some("image/png"));
    assert_eq!(get(addr, "/api/exemplars/..%2fmarble.png").status, 404);
}

#[test]
fn hostile_requests_are_refused_without_reading_or_allocating_them() {
    let (addr, _) = server();
    // A body claimed far beyond the memory of the machine: refused before reading it (an HTTP
    // crate tried first allocated the claimed size to skip the body and aborted the server).
    let huge = b"POST /api/solids HTTP/1.1\r\nHost: x\r\nContent-Length: 100000000000\r\n\r\nabc";
    assert_eq!(raw_status(addr, huge), 413);
    let mut head = b"GET / HTTP/1.1\r\nX-Long: ".to_vec();
    head.extend(std::iter::repeat_n(b'a', 40 << 10));
    head.extend_from_slice(b"\r\n\r\n");
    assert_eq!(raw_status(addr, &head), 431);
    // A head a little over the limit, arriving whole in one read, too.
    let mut head = b"GET / HTTP/1.1\r\nX-Long: ".to_vec();
    head.extend(std::iter::repeat_n(b'a', 20_000));
    head.extend_from_slice(b"\r\n\r\n");
    assert_eq!(raw_status(addr, &head), 431);
    // Two lengths that differ leave the body's end unknown.
    let lengths =
        b"POST /api/solids HTTP/1.1\r\nContent-Length: 5\r\nContent-Length: 10\r\n\r\nhello";
    assert_eq!(raw_status(addr, lengths), 400);
    // An endpoint without parameters refuses one (a typo would otherwise go unseen).
    let request = format!("GET /api/state?verbose=1 HTTP/1.1\nHost: {addr}\n\n");
    let (status, answer) = raw(addr, &request);
    assert_eq!(status, 400, "{answer}");
    assert!(answer.contains("takes no parameters"), "{answer}");
    assert_eq!(raw_status(addr, b"garbage\r\n\r\n"), 400);
    assert_eq!(raw_status(addr, b"GET http://x/ HTTP/1.1\r\n\r\n"), 400);
    let chunked =
        b"POST /api/solids HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n";
    assert_eq!(raw_status(addr, chunked), 411);
    // A client that sends half a body and hangs up.
    assert_eq!(
        raw_status(
            addr,
            b"POST /api/solids HTTP/1.1\r\nContent-Length: 10\r\n\r\nabc"
        ),
        400
    );
    // And the server still answers.
    assert_eq!(get(addr, "/api/health").json()["ok"], true);
}

/// DNS rebinding and cross-site requests: only the bound address (and localhost) as Host, no
/// state change from another origin, uploads only as images; HEAD answers like GET.
#[test]
fn requests_from_elsewhere_are_refused() {
    let (addr, _) = server();
    let port = addr.port();
    let (code, text) = raw(addr, "GET /api/health HTTP/1.1\nHost: evil.example\n\n");
    assert_eq!(code, 421, "{text}");
    assert!(
        text.contains("evil.example") && text.contains("\"error\""),
        "{text}"
    );
    assert_eq!(
        raw(
            addr,
            &format!("GET /api/health HTTP/1.1\nHost: evil.example:{port}\n\n")
        )
        .0,
        421
    );
    assert_eq!(raw(addr, "GET /api/health HTTP/1.1\n\n").0, 400);
    for host in [
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        format!("LOCALHOST:{port}"),
    ] {
        assert_eq!(
            raw(addr, &format!("GET /api/health HTTP/1.1\nHost: {host}\n\n")).0,
            200,
            "{host}"
        );
    }
    // A page elsewhere posting a "simple" (no preflight) request with an image body.
    let png = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/marble32.png"
    ))
    .unwrap();
    let post = |origin: &str, content_type: &str| {
        use std::io::{Read, Write};
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let head = format!(
            "POST /api/solids?seed=1 HTTP/1.1\r\nHost: {addr}\r\n{origin}Content-Type: {content_type}\r\nContent-Length: {}\r\n\r\n",
            png.len()
        );
        s.write_all(head.as_bytes()).unwrap();
        let _ = s.write_all(&png);
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        String::from_utf8_lossy(&out)
            .split_whitespace()
            .nth(1)
            .and_then(|c| c.parse::<u16>().ok())
            .unwrap()
    };
    assert_eq!(post("Origin: http://evil.example\r\n", "text/plain"), 403);
    assert_eq!(post("Origin: http://evil.example\r\n", "image/png"), 403);
    assert_eq!(
        post(&format!("Origin: http://{addr}x\r\n"), "image/png"),
        403
    );
    assert_eq!(post("", "text/plain"), 415);
    assert_eq!(post("", "application/octet-stream"), 415);
    // HEAD: GET's status and length, no body.
    let (code, text) = raw(addr, &format!("HEAD / HTTP/1.1\nHost: {addr}\n\n"));
    assert_eq!(code, 200, "{text}");
    let page = get(addr, "/");
    assert!(
        text.contains(&format!("Content-Length: {}", page.body.len())),
        "{text}"
    );
    assert!(
        text.ends_with("\r\n\r\n"),
        "a HEAD answer has no body: {text}"
    );
    assert_eq!(
        raw(
            addr,
            &format!("HEAD /api/health HTTP/1.1\nHost: {addr}\n\n")
        )
        .0,
        200
    );
}

/// The request reader and the query parser under the fuzz tests' structured mutations
/// (`common::mutate`) of valid requests: every answer is a status line the server means, and
/// it goes on answering. `SOLIDSYNTH_FUZZ_CASES` cases (default 300: each is a connection).
#[test]
fn mutated_requests_get_clean_answers() {
    let (addr, solid) = server();
    let cases: usize = std::env::var("SOLIDSYNTH_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1500)
        / 5;
    let valid = [
        format!(
            "GET /api/solids/{solid}/cut.png?origin=1,2,3&normal=0,1,1&size=32&spacing=1 HTTP/1.1\r\nHost: {addr}\r\n\r\n"
        ),
        format!("GET /api/volume/{solid}.nrrd?size=16 HTTP/1.1\r\nHost: {addr}\r\n\r\n"),
        format!(
            "POST /api/solids?seed=3&periodic=1 HTTP/1.1\r\nHost: {addr}\r\nOrigin: http://{addr}\r\nContent-Type: image/png\r\nContent-Length: 4\r\n\r\nXPNG"
        ),
    ];
    let meant = [
        200, 202, 400, 403, 404, 405, 408, 411, 413, 415, 421, 431, 503,
    ];
    let mut rng = solidsynth::util::hash::SeededRng::new(0x4771);
    for case in 0..cases {
        let request = common::mutate(valid[case % valid.len()].as_bytes(), &mut rng);
        use std::io::{Read, Write};
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let _ = s.write_all(&request);
        let _ = s.shutdown(std::net::Shutdown::Write);
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        let text = String::from_utf8_lossy(&out);
        let code: u16 = text
            .split_whitespace()
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        assert!(
            text.starts_with("HTTP/1.1 ") && meant.contains(&code),
            "case {case}: {:?} -> {:?}",
            String::from_utf8_lossy(&request),
            &text[..text.len().min(200)]
        );
    }
    assert_eq!(get(addr, "/api/health").json()["ok"], true);
}

/// `bench serve --mixed`: a short run of mixed and hostile traffic in which every answer is the
/// one its request should get (the command exits 1 otherwise).
#[test]
fn the_mixed_load_test_runs_and_every_answer_is_as_expected() {
    let o = bin()
        .args([
            "bench",
            "serve",
            "--mixed",
            "2",
            "--idle",
            "1",
            "--clients",
            "1",
            "--size",
            "16",
            "--backend",
            "cpu",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let kinds = report["kinds"].as_array().unwrap();
    assert!(
        kinds
            .iter()
            .any(|k| k["kind"] == "cut" && k["as_expected"].as_u64().unwrap() > 0),
        "{report}"
    );
    assert!(
        kinds.iter().any(|k| k["kind"] == "hostile: bad Host"),
        "{report}"
    );
    assert!(
        kinds
            .iter()
            .all(|k| k["unexpected"].as_array().unwrap().is_empty()),
        "{report}"
    );
}
