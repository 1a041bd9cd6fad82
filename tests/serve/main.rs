//! The viewer's HTTP API as a script would use it: a server on a free loopback port (CPU
//! backend), a solid made from a small fixture, then cuts, volumes, uploads, bad requests and
//! concurrent requests through the minimal client. The helpers are here, the tests in one module
//! per part of the API.

mod command;
#[path = "../common/mod.rs"]
mod common;
mod cuts;
mod requests;
mod solids;
mod surfaces;

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

fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    c.env("SOLIDSYNTH_LOG", "warn");
    c
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
