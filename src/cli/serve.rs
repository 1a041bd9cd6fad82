//! `solidsynth serve`: the interactive viewer (a local web page and its HTTP API); its load
//! test, `bench serve`, is in [`super::serve_bench`].

use super::analyze::load_or_analyze;
use super::synth::SolidParams;
use crate::serve::jobs::{self, Source};
use crate::serve::{ServeConfig, Server};
use crate::Error;
use clap::Args;
use std::net::IpAddr;

#[derive(Args, Debug)]
#[command(next_help_heading = "Server")]
pub struct ServeArgs {
    /// Port to listen on (0: any free port; the address is printed).
    #[arg(help_heading = "Server", long, default_value_t = 8080)]
    pub port: u16,
    /// Address to bind. The default answers this machine only; anything else exposes the
    /// viewer (and its CPU/GPU time) to the network.
    #[arg(help_heading = "Server", long, default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// A host name (optionally NAME:PORT) requests may name in their Host header besides the
    /// bound address (and `localhost` on a loopback address); repeatable. Requests naming any
    /// other host are refused (421): a web page cannot reach the server through a name it
    /// controls (DNS rebinding).
    #[arg(help_heading = "Server", long = "allow-host", value_name = "NAME")]
    pub allow_hosts: Vec<String>,
    /// Edge of the volume synthesized with every solid (the page's 3D texture), a multiple of 4.
    #[arg(help_heading = "Server", long, default_value_t = 64)]
    pub preview_size: u32,
    /// Largest cut accepted (pixels per side, and voxels spanned per side).
    #[arg(help_heading = "Server", long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=1024))]
    pub max_cut_size: u32,
    /// Largest surface bake the page may ask for: voxels across the mesh's longest side.
    #[arg(help_heading = "Server", long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub max_surface_resolution: u32,
    /// Synthesize every level for each request instead of reading the coarse levels from the
    /// coarse-level cache (period 64) that `serve` uses by default: cuts then cost 2.5-4.6x more
    /// (256 to 64 pixels a side, CPU backend of an AMD EPYC machine; BENCHMARKS.md), and the
    /// solid is the one `synth` makes without `--coarse-cache`.
    #[arg(help_heading = "Server", long, conflicts_with = "coarse_cache")]
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
        max_surface_resolution: args.max_surface_resolution,
        params,
        allow_hosts: args.allow_hosts.clone(),
        cache: crate::solid::AnalysisCache::user_default(),
        ..ServeConfig::default()
    }
}

pub fn run(args: ServeArgs, quiet: bool) -> anyhow::Result<()> {
    let config = config(&args);
    config.validate()?;
    if let crate::lazy::ColorSource::PerChannel(_) = config.params.color {
        // Uploads may have 1, 3 or 4 colour channels: one list cannot fit them all.
        return Err(Error::invalid(
            format!("--color {}", config.params.color),
            "serve takes one colour source for every solid (average, fitted, matched, x, y or z), \
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
            let given = args.solid.input.analysis_flags_given();
            if !given.is_empty() {
                return Err(Error::invalid(
                    given.join(" "),
                    "analysis settings need an INPUT image; without one the built-in exemplar is \
                     analysed as the page's exemplars are",
                )
                .into());
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
