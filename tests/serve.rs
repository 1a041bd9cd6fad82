//! The viewer's HTTP API as a script would use it: a server on a free loopback port (CPU
//! backend), a solid made from a small fixture, then cuts, volumes, uploads, bad requests and
//! concurrent requests through the minimal client.

mod common;

use solidsynth::backend::Compute;
use solidsynth::serve::client::{self, Reply};
use solidsynth::serve::jobs::Source;
use solidsynth::serve::{ServeConfig, Server};
use std::net::SocketAddr;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const PREVIEW: u32 = 16;
const MAX_UPLOAD: usize = 64 << 10;

/// One server for all tests of this binary (analysis is the slow part), and its first solid.
fn server() -> (SocketAddr, u64) {
    static SERVER: OnceLock<(SocketAddr, u64)> = OnceLock::new();
    *SERVER.get_or_init(|| {
        own_server(ServeConfig {
            port: 0,
            preview_size: PREVIEW,
            max_upload_bytes: MAX_UPLOAD,
            max_upload_side: 64,
            max_cut_size: 128,
            max_volume_size: 32,
            ..ServeConfig::default()
        })
    })
}

fn wait_job(addr: SocketAddr, id: u64) -> u64 {
    let start = Instant::now();
    loop {
        let r = get(addr, &format!("/api/jobs/{id}"));
        assert_eq!(r.status, 200);
        let j = r.json();
        match j["state"].as_str().unwrap() {
            "done" => return j["solid"].as_u64().unwrap(),
            "failed" => panic!("job failed: {j}"),
            _ => {
                let p = j["progress"].as_f64().unwrap();
                assert!((0.0..=1.0).contains(&p), "{j}");
            }
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "job {id} too slow"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn get(addr: SocketAddr, path: &str) -> Reply {
    client::get(addr, path).unwrap()
}

fn assert_error(r: &Reply, status: u16, needle: &str) {
    assert_eq!(r.status, status, "{}", String::from_utf8_lossy(&r.body));
    let message = r.json()["error"].as_str().unwrap_or_default().to_string();
    assert!(
        message.contains(needle),
        "expected {needle:?} in {message:?}"
    );
}

fn cut_path(solid: u64, query: &str) -> String {
    format!("/api/solids/{solid}/cut?{query}")
}

#[test]
fn a_cut_is_a_png_of_the_asked_size_and_deterministic() {
    let (addr, solid) = server();
    let q = "origin=8,8,5.5&normal=0.6,0,0.8&size=24";
    let a = get(addr, &cut_path(solid, q));
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    assert_eq!(a.header("content-type"), Some("image/png"));
    let img = image::load_from_memory(&a.body).unwrap();
    assert_eq!((img.width(), img.height()), (24, 24));
    let ms: f64 = a.header("x-synthesis-ms").unwrap().parse().unwrap();
    assert!(ms > 0.0);
    let frame: serde_json::Value = serde_json::from_str(a.header("x-cut-frame").unwrap()).unwrap();
    assert_eq!(frame["n"][2].as_f64().unwrap(), 0.8);
    // Same parameters, same bytes (percent-encoded commas are the same request).
    let b = get(
        addr,
        &cut_path(solid, "origin=8%2C8%2C5.5&normal=0.6,0,0.8&size=24"),
    );
    assert_eq!(a.body, b.body);
    // Another plane, another image.
    let c = get(
        addr,
        &cut_path(solid, "origin=8,8,9.5&normal=0.6,0,0.8&size=24"),
    );
    assert_eq!(c.status, 200);
    assert_ne!(a.body, c.body);
}

#[test]
fn an_axis_aligned_cut_is_a_slice_of_the_served_volume() {
    let (addr, solid) = server();
    let r = get(addr, &format!("/api/solids/{solid}/volume?format=raw"));
    assert_eq!(r.status, 200);
    let n = PREVIEW as usize;
    assert_eq!(r.body.len(), n * n * n * 4);
    let cut = get(
        addr,
        &cut_path(solid, "origin=8,8,5.5&normal=0,0,1&size=16"),
    );
    assert_eq!(cut.status, 200);
    let img = image::load_from_memory(&cut.body).unwrap().to_rgba8();
    for y in 0..n {
        for x in 0..n {
            let i = ((5 * n + y) * n + x) * 4;
            assert_eq!(
                img.get_pixel(x as u32, y as u32).0,
                r.body[i..i + 4],
                "({x}, {y})"
            );
        }
    }
}

#[test]
fn volumes_download_in_every_format_and_read_back_equal() {
    let (addr, solid) = server();
    let nrrd = get(addr, &format!("/api/solids/{solid}/volume?format=nrrd"));
    assert_eq!(nrrd.status, 200);
    let v = solidsynth::io::nrrd::parse(&nrrd.body).unwrap();
    assert_eq!(v.dims(), [PREVIEW; 3]);
    let vti = get(addr, &format!("/api/solids/{solid}/volume?format=vti"));
    assert_eq!(
        solidsynth::io::vti::from_bytes(&vti.body, "vti").unwrap(),
        v
    );
    let flip = get(addr, &format!("/api/solids/{solid}/volume?format=flipbook"));
    let img = image::load_from_memory(&flip.body).unwrap().to_rgba8();
    assert_eq!(
        solidsynth::io::flipbook::from_image(&img, PREVIEW, v.channels).unwrap(),
        v
    );
    // The command line's other writers: NumPy (its header, then the NRRD order), a TIFF stack
    // (read back by the tiff crate, page by page) and a KTX2 3D texture.
    let npy = get(addr, &format!("/api/solids/{solid}/volume?format=npy"));
    assert_eq!(npy.status, 200);
    assert!(npy.body.starts_with(b"\x93NUMPY"));
    assert_eq!(&npy.body[npy.body.len() - v.data.len()..], &v.data[..]);
    let tif = get(addr, &format!("/api/solids/{solid}/volume?format=tiff"));
    assert_eq!(tif.status, 200);
    let mut decoder = tiff::decoder::Decoder::new(std::io::Cursor::new(&tif.body)).unwrap();
    let mut pages = Vec::new();
    loop {
        match decoder.read_image().unwrap() {
            tiff::decoder::DecodingResult::U8(page) => pages.extend(page),
            _ => panic!("8-bit pages"),
        }
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().unwrap();
    }
    assert_eq!(pages, v.data);
    let ktx = get(addr, &format!("/api/solids/{solid}/volume?format=ktx2"));
    assert_eq!(ktx.status, 200);
    let reader = ktx2::Reader::new(&ktx.body[..]).unwrap();
    assert_eq!(reader.header().pixel_depth, PREVIEW);
    // Another size is synthesized on demand: the same solid, so the preview is its corner.
    let big = get(
        addr,
        &format!("/api/solids/{solid}/volume?format=nrrd&size=20"),
    );
    assert_eq!(big.status, 200);
    let big = solidsynth::io::nrrd::parse(&big.body).unwrap();
    assert_eq!(big.dims(), [20; 3]);
    assert_eq!(big.at(3, 7, 11), v.at(3, 7, 11));
    assert_error(
        &get(addr, &format!("/api/solids/{solid}/volume?size=33")),
        400,
        "size",
    );
    assert_error(
        &get(addr, &format!("/api/solids/{solid}/volume?format=obj")),
        400,
        "format",
    );
}

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
fn concurrent_cuts_queue_and_all_succeed() {
    let (addr, solid) = server();
    let results: Vec<(u16, Vec<u8>)> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..8)
            .map(|i| {
                s.spawn(move || {
                    let q = format!("origin=8,8,{}&normal=0,0.6,0.8&size=32", i % 4);
                    let r = get(addr, &cut_path(solid, &q));
                    (r.status, r.body)
                })
            })
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (i, (status, body)) in results.iter().enumerate() {
        assert_eq!(
            *status,
            200,
            "request {i}: {}",
            String::from_utf8_lossy(body)
        );
    }
    // Requests for the same plane got the same bytes, whatever the interleaving.
    assert_eq!(results[0].1, results[4].1);
    assert_ne!(results[0].1, results[1].1);
}

fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    c.env("SOLIDSYNTH_LOG", "warn");
    c
}

#[test]
fn the_serve_command_prints_its_address_and_answers() {
    use std::io::BufRead;
    let cache = tempfile::tempdir().unwrap();
    let mut child = bin()
        .args(["serve", "--port", "0", "--backend", "cpu"])
        .env("SOLIDSYNTH_CACHE_DIR", cache.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let line = lines
        .find_map(|l| l.ok().filter(|l| l.contains("solidsynth viewer: http://")))
        .expect("address line");
    let url = line
        .split("http://")
        .nth(1)
        .unwrap()
        .split('/')
        .next()
        .unwrap();
    let addr: SocketAddr = url.parse().unwrap();
    assert!(addr.ip().is_loopback(), "{line}");
    assert_eq!(get(addr, "/api/health").json()["ok"], true);
    assert_eq!(get(addr, "/").status, 200);
    // The startup job (built-in exemplar) is listed while it runs or once done.
    let state = get(addr, "/api/state").json();
    assert_eq!(state["jobs"][0]["name"], "cells", "{state}");
    assert_eq!(
        state["backend"].as_str().unwrap().split(' ').next(),
        Some("cpu")
    );
    // The port is taken now: a second server on it is refused with exit code 2.
    let o = bin()
        .args([
            "serve",
            "--port",
            &addr.port().to_string(),
            "--backend",
            "cpu",
        ])
        .env("SOLIDSYNTH_CACHE_DIR", cache.path())
        .output()
        .unwrap();
    child.kill().unwrap();
    let _ = child.wait();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("cannot listen"), "{stderr}");
}

#[test]
fn bad_serve_flags_exit_2_naming_the_flag() {
    for (args, needle) in [
        (&["serve", "--preview-size", "7"][..], "--preview-size 7"),
        (&["serve", "--port", "70000"][..], "--port"),
        (&["serve", "--bind", "nowhere"][..], "--bind"),
        (&["serve", "--max-cut-size", "5000"][..], "--max-cut-size"),
        (&["serve", "--jitter", "99"][..], "--jitter"),
        (&["bench", "serve", "--clients", "0"][..], "--clients"),
        (&["bench", "serve", "--mixed", "0"][..], "--mixed"),
        (
            &["bench", "serve", "--exemplar", "granite"][..],
            "--exemplar granite",
        ),
    ] {
        let o = bin().args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains(needle),
            "{args:?}: expected {needle:?} in {stderr}"
        );
    }
}

/// Send raw bytes and hang up (write side), return the status code of the answer.
fn raw_status(addr: SocketAddr, bytes: &[u8]) -> u16 {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let _ = s.write_all(bytes);
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out);
    text.split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {text:?}"))
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

#[test]
fn a_gpu_server_cuts_the_same_bytes_as_the_cpu_one() {
    use solidsynth::backend::BackendChoice;
    let (cpu_addr, cpu_solid) = server();
    let compute = match Compute::open(BackendChoice::Gpu, &solidsynth::gpu::GpuOptions::from_env())
    {
        Ok(c) => c,
        Err(e) => {
            assert!(std::env::var_os("CI").is_none(), "no GPU in CI: {e}");
            eprintln!("SKIPPED the GPU server (no adapter, CI unset): {e}");
            return;
        }
    };
    let config = ServeConfig {
        port: 0,
        preview_size: PREVIEW,
        ..ServeConfig::default()
    };
    let (server, gpu_solid) = start_with_solid(config, compute);
    let addr = server.addr();
    assert!(get(addr, "/api/state").json()["backend"]
        .as_str()
        .unwrap()
        .starts_with("gpu"));
    let q = "origin=7,9,6.5&normal=0,0.6,0.8&size=20";
    let a = get(cpu_addr, &cut_path(cpu_solid, q));
    let b = get(addr, &cut_path(gpu_solid, q));
    assert_eq!((a.status, b.status), (200, 200));
    assert_eq!(a.body, b.body, "GPU and CPU cuts differ");
    server.shutdown();
}

/// Raw request `text` (CRLF line ends added), its status line's code and its whole answer.
fn raw(addr: SocketAddr, text: &str) -> (u16, String) {
    let bytes = text.replace('\n', "\r\n");
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    s.write_all(bytes.as_bytes()).unwrap();
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out).to_string();
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, text)
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

/// The server keeps its analyses in the command line's disk cache: a second server (a restart)
/// reads them instead of analysing again.
#[test]
fn a_restarted_server_reads_its_analyses_from_the_disk_cache() {
    let dir = tempfile::tempdir().unwrap();
    let start = || {
        let config = ServeConfig {
            port: 0,
            preview_size: 16,
            cache: Some(solidsynth::solid::AnalysisCache::at(dir.path())),
            ..ServeConfig::default()
        };
        Server::start(config, Compute::Cpu).unwrap()
    };
    let source = || Source::Image {
        name: "marble32".into(),
        image: common::fixture("marble32.png"),
        periodic: false,
    };
    let first = start();
    let job = first.state().start_job(source(), 1).unwrap();
    wait_job(first.addr(), job.id);
    first.shutdown();
    let cached: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(cached.len(), 1, "one analysis cached");
    let written = std::fs::metadata(&cached[0]).unwrap().modified().unwrap();
    let bytes = std::fs::read(&cached[0]).unwrap();
    // A damaged copy would be analysed again and replaced; this one is read as it is.
    let second = start();
    let job = second.state().start_job(source(), 1).unwrap();
    wait_job(second.addr(), job.id);
    second.shutdown();
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    assert_eq!(
        std::fs::metadata(&cached[0]).unwrap().modified().unwrap(),
        written,
        "not rewritten"
    );
    assert_eq!(std::fs::read(&cached[0]).unwrap(), bytes);
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

/// A server on a loopback port, its first solid made from the cells fixture with seed 3. (Tests
/// that bake surfaces or make solids start their own: they would crowd the shared one's solids
/// and jobs.) The server lives as long as the test process.
fn own_server(config: ServeConfig) -> (SocketAddr, u64) {
    let (server, solid) = start_with_solid(config, Compute::Cpu);
    let addr = server.addr();
    std::mem::forget(server);
    (addr, solid)
}

/// A server on `compute` and the id of its first solid, made from the cells fixture with seed 3.
fn start_with_solid(config: ServeConfig, compute: Compute) -> (Server, u64) {
    let server = Server::start(config, compute).unwrap();
    let addr = server.addr();
    assert!(addr.ip().is_loopback());
    let job = server
        .state()
        .start_job(
            Source::Image {
                name: "cells32".into(),
                image: common::fixture("cells32.png"),
                periodic: true,
            },
            3,
        )
        .unwrap();
    let solid = wait_job(addr, job.id);
    (server, solid)
}

/// Wait for job `id` to reach `state` ("done", "cancelled"); its status.
fn wait_state(addr: SocketAddr, id: u64, state: &str) -> serde_json::Value {
    let start = Instant::now();
    loop {
        let j = get(addr, &format!("/api/jobs/{id}")).json();
        let now = j["state"].as_str().unwrap().to_string();
        if now == state {
            return j;
        }
        assert!(
            matches!(now.as_str(), "queued" | "running"),
            "job {id} ended {now}, not {state}: {j}"
        );
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "job {id} too slow"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
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
