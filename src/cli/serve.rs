//! `solidsynth serve`: the interactive viewer (a local web page and its HTTP API), and
//! `solidsynth bench serve`, its load test.

use super::analyze::load_or_analyze;
use super::synth::SolidParams;
use clap::Args;
use solidsynth::serve::jobs::{self, Source};
use solidsynth::serve::{client, ServeConfig, Server};
use solidsynth::Error;
use std::net::IpAddr;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Port to listen on (0: any free port; the address is printed).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to bind. The default answers this machine only; anything else exposes the
    /// viewer (and its CPU/GPU time) to the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// A host name (optionally NAME:PORT) requests may name in their Host header besides the
    /// bound address (and `localhost` on a loopback address); repeatable. Requests naming any
    /// other host are refused (421): a web page cannot reach the server through a name it
    /// controls (DNS rebinding).
    #[arg(long = "allow-host", value_name = "NAME")]
    pub allow_hosts: Vec<String>,
    /// Edge of the volume synthesized with every solid (the page's 3D texture), a multiple of 4.
    #[arg(long, default_value_t = 64)]
    pub preview_size: u32,
    /// Largest cut accepted (pixels per side, and voxels spanned per side).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=1024))]
    pub max_cut_size: u32,
    /// Synthesize every level for each request instead of reading the coarse levels from the
    /// coarse-level cache (period 64) that `serve` uses by default: cuts then cost 3-5x more
    /// (measured in BENCHMARKS.md), and the solid is the one `synth` makes without
    /// `--coarse-cache`.
    #[arg(long, conflicts_with = "coarse_cache")]
    pub full_levels: bool,
    /// The solid: INPUT (image or .ssa; default the built-in exemplar) and its flags, as for
    /// `synth`. `--seed` is the first solid's; the page picks others.
    #[command(flatten)]
    pub solid: SolidParams,
}

/// Coarse-level cache period `serve` uses unless told otherwise: interactive cuts are 3x cheaper.
pub const DEFAULT_COARSE_CACHE: u32 = 64;

fn config(args: &ServeArgs) -> ServeConfig {
    let mut params = args.solid.synth_params();
    if !args.full_levels && params.coarse_cache.is_none() {
        params.coarse_cache = Some(DEFAULT_COARSE_CACHE);
    }
    ServeConfig {
        bind: args.bind,
        port: args.port,
        preview_size: args.preview_size,
        max_cut_size: args.max_cut_size,
        params,
        allow_hosts: args.allow_hosts.clone(),
        cache: solidsynth::solid::AnalysisCache::user_default(),
        ..ServeConfig::default()
    }
}

pub fn run(args: ServeArgs, quiet: bool) -> anyhow::Result<()> {
    let config = config(&args);
    config.validate()?;
    if let solidsynth::lazy::ColorSource::PerChannel(_) = config.params.color {
        // Uploads may have 1, 3 or 4 colour channels: one list cannot fit them all.
        return Err(Error::invalid(
            format!("--color {}", config.params.color),
            "serve takes one colour source for every solid (average, matched, x, y or z), \
             not one per channel",
        )
        .into());
    }
    let compute = args.solid.input.backend.open()?;
    // An INPUT is analysed (or loaded, or taken from the analysis cache) before listening, with
    // the terminal's progress bar; without one the built-in exemplar is analysed in a job the
    // page shows progress for.
    let source = match &args.solid.input.input {
        Some(p) => Source::Analysis {
            name: p
                .file_name()
                .map_or("input".into(), |n| n.to_string_lossy().to_string()),
            analysis: load_or_analyze(&args.solid.input, &compute, quiet)?,
        },
        None => {
            if args.solid.input.ey.is_some() || args.solid.input.feature_mask_given() {
                return Err(Error::invalid("--ey/--feature-mask", "need an INPUT image").into());
            }
            let b = jobs::builtin("cells").expect("built-in");
            Source::Image {
                name: b.name.into(),
                image: b.image(),
                periodic: true,
            }
        }
    };
    let server = Server::start(config, compute)?;
    let addr = server.addr();
    if !args.bind.is_loopback() {
        tracing::warn!("listening on {addr}, reachable from other machines");
    }
    server
        .state()
        .start_job(source, args.solid.seed)
        .map_err(|jobs::Busy(m)| anyhow::anyhow!(m))?;
    // Scripts (and the tests) read this line to learn the port.
    eprintln!(
        "solidsynth viewer: http://{addr}/  (backend {})",
        server.state().compute.describe()
    );
    server.join();
    Ok(())
}

#[derive(Args, Debug)]
pub struct BenchServeArgs {
    /// Concurrent clients.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=12))]
    pub clients: u32,
    /// Cut requests per client.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub requests: u32,
    /// Cut size (pixels per side).
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=512))]
    pub size: u32,
    /// Built-in exemplar of the solid.
    #[arg(long, default_value = "cells")]
    pub exemplar: String,
    /// Print a JSON summary instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub backend: super::BackendArgs,
    /// Coarse-level cache period for the solid (as `serve`, default 64).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_COARSE_CACHE)]
    pub coarse_cache: u32,
    /// No coarse-level cache (as `serve --full-levels`).
    #[arg(long)]
    pub full_levels: bool,
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
    let pct = |mut v: Vec<f64>, p: f64| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[((v.len() as f64 * p).ceil() as usize).clamp(1, v.len()) - 1]
    };
    let rt: Vec<f64> = ok.iter().map(|r| r.1).collect();
    let synth: Vec<f64> = ok.iter().map(|r| r.2).collect();
    let summary = serde_json::json!({
        "clients": args.clients, "requests_per_client": args.requests, "cut_size": size,
        "exemplar": args.exemplar, "backend": backend, "coarse_cache": config_cache,
        "setup_seconds": setup_s, "wall_seconds": wall,
        "ok": ok.len(), "failed": failed,
        "throughput_per_s": ok.len() as f64 / wall,
        "latency_p50_ms": pct(rt.clone(), 0.5), "latency_p95_ms": pct(rt, 0.95),
        "synthesis_p50_ms": pct(synth.clone(), 0.5), "synthesis_p95_ms": pct(synth, 0.95),
    });
    if args.json {
        println!("{summary}");
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
            summary["throughput_per_s"].as_f64().unwrap_or(0.0)
        );
        println!(
            "  round trip p50 {:.0} ms, p95 {:.0} ms; synthesis p50 {:.0} ms, p95 {:.0} ms",
            summary["latency_p50_ms"].as_f64().unwrap_or(f64::NAN),
            summary["latency_p95_ms"].as_f64().unwrap_or(f64::NAN),
            summary["synthesis_p50_ms"].as_f64().unwrap_or(f64::NAN),
            summary["synthesis_p95_ms"].as_f64().unwrap_or(f64::NAN)
        );
    }
    if failed > 0 {
        anyhow::bail!("{failed} request(s) failed");
    }
    Ok(())
}
