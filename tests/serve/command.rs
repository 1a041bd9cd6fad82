//! The `serve` command: its address, its flags, and a restart reading the analysis cache.

use super::*;

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
        // Without INPUT the built-in exemplar is analysed the page's way: analysis flags are
        // refused by name, not ignored.
        (
            &["serve", "--port", "0", "--frame", "cyclic", "--periodic"][..],
            "invalid --frame --periodic: analysis settings need an INPUT image",
        ),
        (
            &["serve", "--port", "0", "--feature-weight", "5"][..],
            "invalid --feature-weight:",
        ),
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
