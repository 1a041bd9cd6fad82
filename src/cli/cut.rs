//! `solidsynth cut`: a planar cut of the solid as a PNG, optionally repeated through one warm
//! session to measure interactive latency.

use super::analyze::open_and_analyze;
use super::synth::SolidParams;
use crate::io::atomic;
use crate::lazy::cut::CutSpec;
use crate::Error;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
#[command(next_help_heading = "Cut")]
pub struct CutArgs {
    #[command(flatten)]
    pub solid: SolidParams,
    /// Centre of the cut, X,Y,Z in finest-level voxels.
    #[arg(help_heading = "Cut", long, allow_hyphen_values = true)]
    pub origin: String,
    /// Normal of the cut plane, NX,NY,NZ (any length but zero).
    #[arg(help_heading = "Cut", long, allow_hyphen_values = true)]
    pub normal: String,
    /// Up direction, projected onto the plane (default +y, or +z when the normal is along y).
    #[arg(help_heading = "Cut", long, allow_hyphen_values = true)]
    pub up: Option<String>,
    /// Pixels per side of the (square) cut.
    #[arg(help_heading = "Cut", long, default_value_t = 256, value_parser = super::whole_number_in::<1, { crate::lazy::cut::MAX_CUT_SIZE }>)]
    pub size: u32,
    /// Voxels per pixel.
    #[arg(
        help_heading = "Cut",
        long,
        default_value_t = 1.0,
        allow_hyphen_values = true
    )]
    pub spacing: f64,
    /// Run the cut K times, keeping the pipelines, level data and device buffers between cuts,
    /// and print the median and p95 latency of the warm cuts (all but the first, which is
    /// reported on its own).
    #[arg(help_heading = "Cut", long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub repeat: u32,
    /// Output PNG.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
    /// Time every kernel, waiting for the device after each (so each cut takes longer), and
    /// print each kernel's mean time per warm cut (the first is left out when repeating).
    #[arg(help_heading = "Performance", long)]
    pub profile: bool,
}

/// Parse `A,B,C` (finite numbers) for `flag`.
pub fn triple(text: &str, flag: &str) -> crate::Result<[f64; 3]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| Error::invalid(format!("{flag} {text}"), "expected three numbers A,B,C"))?;
    match v.as_slice() {
        [a, b, c] if v.iter().all(|x| x.is_finite()) => Ok([*a, *b, *c]),
        [_, _, _] => Err(Error::invalid(
            format!("{flag} {text}"),
            "numbers must be finite",
        )),
        _ => Err(Error::invalid(
            format!("{flag} {text}"),
            "expected three numbers A,B,C",
        )),
    }
}

pub fn run(args: CutArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_png_output(&args.output, "-o")?;
    let spec = CutSpec {
        origin: triple(&args.origin, "--origin")?,
        normal: triple(&args.normal, "--normal")?,
        up: args.up.as_deref().map(|u| triple(u, "--up")).transpose()?,
        size: args.size,
        spacing: args.spacing,
    };
    spec.frame()?;
    let params = args.solid.synth_params();
    params.validate()?;
    // The PNG beside the image: at most the image's 4 bytes a pixel again, and its encoder's.
    crate::solid::memory::check_cut_request(
        &spec,
        args.solid.max_group,
        args.solid.coarse_cache,
        8,
    )?;
    let (compute, analysis) = open_and_analyze(&args.solid.input, quiet || args.json)?;
    let mut session = args
        .solid
        .solid(&analysis, &compute, args.profile, None)?
        .into_cut_session();
    // The session keeps what it reads: the analysis is not held through the cuts.
    drop(analysis);
    let mut latencies = Vec::new();
    let mut image = None;
    for i in 0..args.repeat {
        if args.profile && i == 1 {
            // Kernel times of warm cuts only: restart the count after the first.
            session.synthesizer_mut().reset_kernel_times();
        }
        let start = Instant::now();
        image = Some(session.cut(&spec)?);
        latencies.push(start.elapsed().as_secs_f64() * 1000.0);
    }
    atomic::save_png(&args.output, &image.expect("repeat >= 1").to_rgba8())?;
    let times = super::output::Latencies::of(&latencies);
    let (median, p95) = (times.median_ms, times.p95_ms);
    // Per warm cut (all but the first, unless there is only one).
    let profiled = args.repeat.saturating_sub(1).max(1) as f64;
    let kernels: std::collections::BTreeMap<String, CutKernelTime> = session
        .synthesizer()
        .kernel_times()
        .map(|t| {
            t.iter()
                .map(|(k, (d, n))| {
                    let time = CutKernelTime {
                        ms_per_cut: d.as_secs_f64() * 1000.0 / profiled,
                        calls_per_cut: *n as f64 / profiled,
                    };
                    (k.to_string(), time)
                })
                .collect()
        })
        .unwrap_or_default();
    if args.json {
        super::output::print_summary(&CutSummary {
            output: &args.output,
            size: args.size,
            repeat: args.repeat,
            latencies: times,
            kernels,
            stats: session.synthesizer().last_stats(),
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
            backend: compute.describe(),
        });
    } else if !quiet {
        eprintln!(
            "cut {0}x{0} -> {1}: median {median:.1} ms, p95 {p95:.1} ms {2} (first {3:.1} ms)",
            args.size,
            args.output.display(),
            super::output::Latencies::over(args.repeat),
            latencies[0]
        );
        if let Some(st) = session.synthesizer().last_stats() {
            eprintln!(
                "  voxels synthesized per level (coarsest first): {:?}; peak state {:.1} MiB",
                st.voxels_per_level,
                st.peak_state_bytes as f64 / (1 << 20) as f64
            );
        }
        for (kernel, t) in &kernels {
            eprintln!(
                "  {kernel}: {:.1} ms per cut ({} calls)",
                t.ms_per_cut, t.calls_per_cut
            );
        }
    }
    Ok(())
}

/// `cut --json`.
#[derive(serde::Serialize)]
struct CutSummary<'a> {
    output: &'a std::path::Path,
    size: u32,
    repeat: u32,
    #[serde(flatten)]
    latencies: super::output::Latencies,
    /// Per kernel and warm cut, with `--profile`.
    kernels: std::collections::BTreeMap<String, CutKernelTime>,
    stats: Option<&'a crate::lazy::SynthStats>,
    peak_rss_bytes: Option<u64>,
    backend: String,
}

#[derive(serde::Serialize)]
struct CutKernelTime {
    ms_per_cut: f64,
    calls_per_cut: f64,
}
