//! `solidsynth bench serve`: the viewer's server under load, cuts or mixed traffic (hostile
//! requests and slow connections included), every answer checked.

use super::output::percentile;
use crate::serve::jobs::{self, Source};
use crate::serve::{client, ServeConfig, Server};
use crate::Error;
use clap::Args;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
#[command(next_help_heading = "Load")]
pub struct BenchServeArgs {
    /// Concurrent clients.
    #[arg(help_heading = "Load", long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=12))]
    pub clients: u32,
    /// Cut requests per client.
    #[arg(help_heading = "Load", long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub requests: u32,
    /// Cut size (pixels per side).
    #[arg(help_heading = "Load", long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=512))]
    pub size: u32,
    /// Built-in exemplar of the solid.
    #[arg(help_heading = "Load", long, default_value = "cells")]
    pub exemplar: String,
    /// Print a JSON summary instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
    #[command(flatten)]
    pub backend: super::BackendArgs,
    /// Coarse-level cache period for the solid (as `serve`, default 64).
    #[arg(
        help_heading = "Load",
        long,
        value_name = "N",
        default_value_t = super::serve::DEFAULT_COARSE_CACHE,
        value_parser = super::synth::parse_coarse_cache,
        allow_hyphen_values = true
    )]
    pub coarse_cache: u32,
    /// No coarse-level cache (as `serve --full-levels`).
    #[arg(help_heading = "Load", long)]
    pub full_levels: bool,
    /// Mixed traffic for this many seconds instead of `--requests` cuts: the clients send cuts,
    /// volume downloads and good uploads; one more sends hostile requests (random bodies as
    /// PNG, claimed gigabytes, bad Host and Origin, text uploads, garbage); `--idle` more hold
    /// slow connections open (a byte a second). Every answer is checked against what it should
    /// be; failures of valid requests must be 0.
    #[arg(help_heading = "Load", long, value_name = "SECONDS", value_parser = clap::value_parser!(u32).range(1..=600))]
    pub mixed: Option<u32>,
    /// Slow ("slowloris") connections held open during `--mixed`.
    #[arg(help_heading = "Load", long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(0..=12))]
    pub idle: u32,
}

/// Start a server on a free loopback port, make one solid, then fire `clients` x `requests`
/// cuts (each client on its own connection per request, different planes) and report
/// throughput, latency percentiles and failures.
pub fn bench(args: BenchServeArgs) -> anyhow::Result<()> {
    let b = jobs::builtin(&args.exemplar).ok_or_else(|| {
        Error::invalid(
            format!("--exemplar {}", args.exemplar),
            "not a built-in exemplar",
        )
    })?;
    let mut config = ServeConfig {
        port: 0,
        ..ServeConfig::default()
    };
    config.params.coarse_cache = (!args.full_levels).then_some(args.coarse_cache);
    config.validate()?;
    let config_cache = config.params.coarse_cache;
    let compute = args.backend.open()?;
    let backend = compute.describe();
    let server = Server::start(config, compute)?;
    let addr = server.addr();
    let job = server
        .state()
        .start_job(
            Source::Image {
                name: b.name.into(),
                image: b.image(),
                periodic: true,
            },
            0,
        )
        .map_err(|jobs::Busy(m)| anyhow::anyhow!(m))?;
    let setup = Instant::now();
    let solid = loop {
        let status = client::get(addr, &format!("/api/jobs/{}", job.id))?.json();
        match status["state"].as_str() {
            Some("done") => break status["solid"].as_u64().unwrap_or(0),
            Some("failed") => anyhow::bail!("the solid failed: {}", status["error"]),
            _ => std::thread::sleep(Duration::from_millis(200)),
        }
    };
    let setup_s = setup.elapsed().as_secs_f64();
    if let Some(seconds) = args.mixed {
        let result = mixed_traffic(addr, solid, &args, seconds);
        server.shutdown();
        let table = result?;
        let unexpected: usize = table.iter().map(|(_, r)| r.unexpected.len()).sum();
        print_mixed(&args, &backend, setup_s, seconds, &table);
        if unexpected > 0 {
            anyhow::bail!("{unexpected} answer(s) were not what the request should get");
        }
        return Ok(());
    }
    let size = args.size;
    let start = Instant::now();
    let results: Vec<(bool, f64, f64)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..args.clients)
            .map(|c| {
                s.spawn(move || {
                    (0..args.requests)
                        .map(|r| {
                            // A different oblique plane per request, through the preview box.
                            let k = (c * args.requests + r) as f64;
                            let (a, e) = (0.37 * k, 0.6 + 0.05 * (k % 7.0));
                            let n = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
                            let path = format!(
                                "/api/solids/{solid}/cut?origin=32,32,{}&normal={},{},{}&size={size}",
                                16.0 + k % 32.0,
                                n[0],
                                n[1],
                                n[2]
                            );
                            let t = Instant::now();
                            let reply = client::get(addr, &path);
                            let ms = t.elapsed().as_secs_f64() * 1e3;
                            match reply {
                                Ok(r) if r.status == 200 => {
                                    let synth = r
                                        .header("x-synthesis-ms")
                                        .and_then(|v| v.parse().ok())
                                        .unwrap_or(f64::NAN);
                                    (true, ms, synth)
                                }
                                Ok(r) => {
                                    tracing::warn!("HTTP {}: {}", r.status, String::from_utf8_lossy(&r.body));
                                    (false, ms, f64::NAN)
                                }
                                Err(e) => {
                                    tracing::warn!("request failed: {e}");
                                    (false, ms, f64::NAN)
                                }
                            }
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("client thread"))
            .collect()
    });
    let wall = start.elapsed().as_secs_f64();
    server.shutdown();
    let ok: Vec<&(bool, f64, f64)> = results.iter().filter(|r| r.0).collect();
    let failed = results.len() - ok.len();
    let rt: Vec<f64> = ok.iter().map(|r| r.1).collect();
    let synth: Vec<f64> = ok.iter().map(|r| r.2).collect();
    let summary = LoadSummary {
        clients: args.clients,
        requests_per_client: args.requests,
        cut_size: size,
        exemplar: &args.exemplar,
        backend: &backend,
        coarse_cache: config_cache,
        setup_seconds: setup_s,
        wall_seconds: wall,
        ok: ok.len(),
        failed,
        throughput_per_s: ok.len() as f64 / wall,
        latency_p50_ms: percentile(&rt, 0.5),
        latency_p95_ms: percentile(&rt, 0.95),
        synthesis_p50_ms: percentile(&synth, 0.5),
        synthesis_p95_ms: percentile(&synth, 0.95),
    };
    if args.json {
        super::output::print_summary(&summary);
    } else {
        println!(
            "serve load test: {} clients x {} cuts of {size}x{size} ({}), backend {backend}",
            args.clients, args.requests, args.exemplar
        );
        println!(
            "  setup (analysis + {}^3 preview): {setup_s:.1} s",
            ServeConfig::default().preview_size
        );
        println!(
            "  {} ok, {failed} failed in {wall:.1} s: {:.2} cuts/s",
            ok.len(),
            summary.throughput_per_s
        );
        println!(
            "  round trip p50 {:.0} ms, p95 {:.0} ms; synthesis p50 {:.0} ms, p95 {:.0} ms",
            summary.latency_p50_ms,
            summary.latency_p95_ms,
            summary.synthesis_p50_ms,
            summary.synthesis_p95_ms
        );
    }
    if failed > 0 {
        anyhow::bail!("{failed} request(s) failed");
    }
    Ok(())
}

/// What one kind of request got during `bench serve --mixed`: round trips of the answers that
/// were as expected, and the unexpected ones.
#[derive(Default)]
struct KindResults {
    latencies_ms: Vec<f64>,
    unexpected: Vec<String>,
}

/// One request `raw` (a whole HTTP request) on a new connection: its status and round trip.
fn raw_request(addr: std::net::SocketAddr, raw: &[u8]) -> (u16, f64) {
    use std::io::{Read, Write};
    let t = Instant::now();
    let Ok(mut s) = std::net::TcpStream::connect(addr) else {
        return (0, 0.0);
    };
    let _ = s.set_read_timeout(Some(Duration::from_secs(120)));
    let _ = s.write_all(raw);
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let code = String::from_utf8_lossy(&out[..out.len().min(64)])
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, t.elapsed().as_secs_f64() * 1e3)
}

/// The mixed load of `bench serve --mixed`: per kind of request, the results.
fn mixed_traffic(
    addr: std::net::SocketAddr,
    solid: u64,
    args: &BenchServeArgs,
    seconds: u32,
) -> anyhow::Result<Vec<(&'static str, KindResults)>> {
    use crate::util::hash::SeededRng;
    let deadline = Instant::now() + Duration::from_secs(seconds as u64);
    let png = crate::io::atomic::png_bytes(
        &jobs::builtin("marble")
            .expect("built in")
            .image()
            .to_rgba8(),
    )?;
    let host = format!("Host: {addr}\r\n");
    let results =
        std::sync::Mutex::new(std::collections::BTreeMap::<&'static str, KindResults>::new());
    let record = |kind: &'static str, code: u16, ms: f64, expected: &[u16]| {
        let mut r = results.lock().unwrap();
        let entry = r.entry(kind).or_default();
        if expected.contains(&code) {
            entry.latencies_ms.push(ms);
        } else {
            entry.unexpected.push(format!("HTTP {code}"));
        }
    };
    let (record, host, png) = (&record, &host, &png);
    std::thread::scope(|s| {
        for c in 0..args.clients {
            s.spawn(move || {
                let mut k = 0u32;
                while Instant::now() < deadline {
                    k += 1;
                    let a = 0.37 * (c * 1000 + k) as f64;
                    match k % 8 {
                        // A volume download now and then, an upload rarely (an analysis job: 202,
                        // or 503 while the job slots are full, the documented back-pressure).
                        3 => {
                            let req = format!("GET /api/solids/{solid}/volume?format=nrrd HTTP/1.1\r\n{host}\r\n");
                            let (code, ms) = raw_request(addr, req.as_bytes());
                            record("volume download", code, ms, &[200]);
                        }
                        7 if k % 64 == 7 => {
                            let head = format!(
                                "POST /api/solids?seed={k} HTTP/1.1\r\n{host}Origin: http://{addr}\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n",
                                png.len()
                            );
                            let mut req = head.into_bytes();
                            req.extend_from_slice(png);
                            let (code, ms) = raw_request(addr, &req);
                            record("upload (good PNG)", code, ms, &[202, 503]);
                        }
                        _ => {
                            // A unit normal, a different oblique plane each time.
                            let e = 0.6 + 0.05 * (k % 7) as f64;
                            let req = format!(
                                "GET /api/solids/{solid}/cut?origin=32,32,{}&normal={},{},{}&size={} HTTP/1.1\r\n{host}\r\n",
                                16 + k % 32,
                                e.cos() * a.cos(),
                                e.cos() * a.sin(),
                                e.sin(),
                                args.size
                            );
                            let (code, ms) = raw_request(addr, req.as_bytes());
                            record("cut", code, ms, &[200]);
                        }
                    }
                }
            });
        }
        // Hostile requests, each with the answer it must get.
        s.spawn(move || {
            let mut rng = SeededRng::new(0xBAD);
            let mut k = 0u64;
            while Instant::now() < deadline {
                k += 1;
                let junk: Vec<u8> = (0..1 + rng.below(4096)).map(|_| rng.below(256) as u8).collect();
                let (kind, req, expected): (&'static str, Vec<u8>, &[u16]) = match k % 6 {
                    0 => {
                        let mut r = format!("POST /api/solids?seed=1 HTTP/1.1\r\n{host}Content-Type: image/png\r\nContent-Length: {}\r\n\r\n", junk.len()).into_bytes();
                        r.extend_from_slice(&junk);
                        ("hostile: random body as PNG", r, &[400])
                    }
                    1 => ("hostile: claimed 100 GB body", format!("POST /api/solids HTTP/1.1\r\n{host}Content-Type: image/png\r\nContent-Length: 100000000000\r\n\r\nabc").into_bytes(), &[413]),
                    2 => ("hostile: bad Host", b"GET /api/state HTTP/1.1\r\nHost: evil.example\r\n\r\n".to_vec(), &[421]),
                    3 => {
                        let mut r = format!("POST /api/solids HTTP/1.1\r\n{host}Origin: http://evil.example\r\nContent-Type: text/plain\r\nContent-Length: {}\r\n\r\n", junk.len()).into_bytes();
                        r.extend_from_slice(&junk);
                        ("hostile: cross-site POST", r, &[403])
                    }
                    4 => {
                        let mut r = format!("POST /api/solids HTTP/1.1\r\n{host}Content-Type: text/plain\r\nContent-Length: {}\r\n\r\n", junk.len()).into_bytes();
                        r.extend_from_slice(&junk);
                        ("hostile: text upload", r, &[415])
                    }
                    _ => {
                        let mut r = junk.clone();
                        r.extend_from_slice(b"\r\n\r\n");
                        ("hostile: garbage", r, &[400, 431])
                    }
                };
                let (code, ms) = raw_request(addr, &req);
                record(kind, code, ms, expected);
            }
        });
        // Slow connections: a byte of a request head a second until the server hangs up.
        for _ in 0..args.idle {
            s.spawn(move || {
                use std::io::{Read, Write};
                let t = Instant::now();
                let Ok(mut conn) = std::net::TcpStream::connect(addr) else {
                    record("slow connection (held open, or 408)", 1, 0.0, &[0, 408]);
                    return;
                };
                let _ = conn.set_read_timeout(Some(Duration::from_millis(50)));
                let head = format!("GET /api/state HTTP/1.1\r\n{host}X-Slow: ");
                let mut out = Vec::new();
                for byte in head.bytes().chain(std::iter::repeat(b'a')) {
                    if Instant::now() >= deadline || conn.write_all(&[byte]).is_err() {
                        break;
                    }
                    let mut buf = [0u8; 512];
                    if let Ok(n) = conn.read(&mut buf) {
                        out.extend_from_slice(&buf[..n]);
                        if n == 0 || !out.is_empty() {
                            break;
                        }
                    }
                    std::thread::sleep(Duration::from_secs(1));
                }
                let code = String::from_utf8_lossy(&out)
                    .split_whitespace()
                    .nth(1)
                    .and_then(|c| c.parse().ok())
                    .unwrap_or(0);
                // Held open to the end of the test (0), or timed out by the server (408).
                let ms = t.elapsed().as_secs_f64() * 1e3;
                record("slow connection (held open, or 408)", code, ms, &[0, 408]);
            });
        }
    });
    Ok(results.into_inner().unwrap().into_iter().collect())
}

fn print_mixed(
    args: &BenchServeArgs,
    backend: &str,
    setup_s: f64,
    seconds: u32,
    table: &[(&'static str, KindResults)],
) {
    let rss = crate::util::memory::peak_rss_bytes().unwrap_or(0) as f64 / (1 << 20) as f64;
    if args.json {
        let rows: Vec<_> = table
            .iter()
            .map(|(kind, r)| MixedKindSummary {
                kind,
                as_expected: r.latencies_ms.len(),
                unexpected: r.unexpected.clone(),
                per_s: r.latencies_ms.len() as f64 / seconds as f64,
                p50_ms: percentile(&r.latencies_ms, 0.5),
                p95_ms: percentile(&r.latencies_ms, 0.95),
                p99_ms: percentile(&r.latencies_ms, 0.99),
            })
            .collect();
        super::output::print_summary(&MixedSummary {
            seconds,
            clients: args.clients,
            idle: args.idle,
            backend,
            setup_seconds: setup_s,
            peak_rss_mib: rss,
            kinds: rows,
        });
        return;
    }
    println!(
        "serve mixed load: {} clients, 1 hostile, {} slow connections, {seconds} s; backend {backend}; setup {setup_s:.1} s",
        args.clients, args.idle
    );
    println!("| request | as expected | unexpected | per s | p50 ms | p95 ms | p99 ms |");
    println!("|---|---|---|---|---|---|---|");
    for (kind, r) in table {
        let l = &r.latencies_ms;
        println!(
            "| {kind} | {} | {} | {:.2} | {:.0} | {:.0} | {:.0} |",
            l.len(),
            r.unexpected.len(),
            l.len() as f64 / seconds as f64,
            percentile(l, 0.5),
            percentile(l, 0.95),
            percentile(l, 0.99)
        );
    }
    for (kind, r) in table {
        if let Some(first) = r.unexpected.first() {
            println!("{kind}: unexpected answers, the first {first}");
        }
    }
    println!("peak RSS of the process (server and clients): {rss:.0} MiB");
}

/// `bench serve --json`.
#[derive(serde::Serialize)]
struct LoadSummary<'a> {
    clients: u32,
    requests_per_client: u32,
    cut_size: u32,
    exemplar: &'a str,
    backend: &'a str,
    coarse_cache: Option<u32>,
    setup_seconds: f64,
    wall_seconds: f64,
    ok: usize,
    failed: usize,
    throughput_per_s: f64,
    latency_p50_ms: f64,
    latency_p95_ms: f64,
    synthesis_p50_ms: f64,
    synthesis_p95_ms: f64,
}

/// `bench serve --mixed SECONDS --json`.
#[derive(serde::Serialize)]
struct MixedSummary<'a> {
    seconds: u32,
    clients: u32,
    idle: u32,
    backend: &'a str,
    setup_seconds: f64,
    peak_rss_mib: f64,
    kinds: Vec<MixedKindSummary>,
}

/// One kind of request in [`MixedSummary`].
#[derive(serde::Serialize)]
struct MixedKindSummary {
    kind: &'static str,
    as_expected: usize,
    /// What each unexpected answer was.
    unexpected: Vec<String>,
    per_s: f64,
    p50_ms: f64,
    p95_ms: f64,
    p99_ms: f64,
}
