//! `solidsynth bench ...`: benchmark tables (the numbers recorded in BENCHMARKS.md).

use super::bench_child::run_json;
use super::output::{self, BenchReport};
use crate::exemplar::{self, procedural, Image};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Analysis wall time and peak memory per exemplar size (each size in a fresh process).
    #[command(after_help = super::help::BENCH_ANALYZE)]
    Analyze(BenchAnalyzeArgs),
    /// Synthesis (after analysis) per volume size and backend: median wall time, peak memory,
    /// and per-kernel times with the CPU/GPU ratio (each run in a fresh process).
    #[command(after_help = super::help::BENCH_SYNTH)]
    Synth(BenchSynthArgs),
    /// Direct gradient-solid synthesis per size and backend: median wall time, peak memory,
    /// per-level match/update times (each run in a fresh process).
    #[command(after_help = super::help::BENCH_GRADIENT_SYNTH)]
    GradientSynth(BenchGradientArgs),
    /// Gradient-solid rendering (kernel `tricubic_eval`, 8-bit volumes as `gradient render`
    /// writes them) per size and backend, in one warm process: median time, CPU/GPU ratio, and
    /// whether the backends' bytes agree.
    #[command(after_help = super::help::BENCH_GRADIENT_RENDER)]
    GradientRender(BenchRenderArgs),
    /// PTM synthesis (projection vs brute-force search, identical output) and relighting (CPU vs
    /// GPU) on a synthetic capture.
    #[command(after_help = super::help::BENCH_PTM)]
    Ptm(super::ptm_bench::BenchPtmArgs),
    /// Lapped solid textures: fill time and memory (fresh processes), warm 512^2 cut latency,
    /// optionally the GPU render.
    #[command(after_help = super::help::BENCH_LAPPED)]
    Lapped(super::lapped_bench::BenchLappedArgs),
    /// Load test of `serve`: concurrent cut requests on loopback; throughput, p50/p95 latency,
    /// failures.
    #[command(after_help = super::help::BENCH_SERVE)]
    Serve(super::serve_bench::BenchServeArgs),
    /// The same jobs (a volume, warm cuts, a surface) on the CPU backend and on every GPU adapter
    /// present, software ones labelled: medians, CPU/GPU ratios and a same-bytes check, as
    /// Markdown or JSON.
    #[command(after_help = super::help::BENCH_COMPARE)]
    Compare(super::bench_compare::BenchCompareArgs),
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchGradientArgs {
    /// Exemplar image (default: the built-in exemplar).
    pub input: Option<PathBuf>,
    /// Solid periods, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![64u32, 128],
          value_parser = clap::value_parser!(u32).range(16..=crate::gradient::synth::MAX_SIZE as i64))]
    pub sizes: Vec<u32>,
    /// Backends to compare, comma-separated (gpu: the bucket kernel on the GPU).
    #[arg(long, value_delimiter = ',', default_values_t = vec!["cpu".to_string()],
          value_parser = ["cpu", "gpu"])]
    pub backends: Vec<String>,
    /// Runs per size and backend; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Print the results as JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchRenderArgs {
    /// Rendered volume edges (each from a random 3-channel solid of that extent).
    #[arg(long, value_delimiter = ',', default_values_t = vec![128u32, 256],
          value_parser = clap::value_parser!(u32).range(4..=1024))]
    pub sizes: Vec<u32>,
    /// Timed renders per size and backend, after one untimed warm-up; the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Skip the GPU backend (CPU times only).
    #[arg(long)]
    pub no_gpu: bool,
    /// Use the adapter whose name contains this (case-insensitive).
    #[arg(long, env = "SOLIDSYNTH_ADAPTER")]
    pub adapter: Option<String>,
    /// Print the results as JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchSynthArgs {
    /// Exemplar image or .ssa (default: the built-in exemplar).
    pub input: Option<PathBuf>,
    /// Volume edges, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![64u32, 128],
          value_parser = clap::value_parser!(u32).range(8..=super::synth::MAX_SIZE as i64))]
    pub sizes: Vec<u32>,
    /// Backends to compare, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec!["cpu".to_string(), "gpu".to_string()],
          value_parser = ["cpu", "gpu"])]
    pub backends: Vec<String>,
    /// Runs per size and backend; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Treat the input exemplar as periodic.
    #[arg(long)]
    pub periodic: bool,
    /// The analysis' feature channel, as `synth --feature-mask` (auto, edges or none).
    #[arg(long, default_value = "auto", value_parser = ["auto", "edges", "none"])]
    pub feature_mask: String,
    /// Correction passes, as `synth --passes` (one count, or one per level, coarsest first).
    #[arg(long, default_value = "2", value_name = "N|N,N,N,N")]
    pub passes: crate::lazy::PassSchedule,
    /// Largest group, as `synth --max-group`.
    #[arg(long, value_name = "VOXELS", value_parser = super::synth::parse_max_group)]
    pub max_group: Option<u32>,
    /// Print the results as JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchAnalyzeArgs {
    /// Exemplar sizes (square, 16 to 2048), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![64u32, 128, 256, 512],
          value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub sizes: Vec<u32>,
    /// Crop the exemplars from this image (top-left corner; it must be at least as large as the
    /// biggest size). Default: procedural cobblestones generated at each size.
    #[arg(help_heading = "Benchmark", long)]
    pub exemplar: Option<PathBuf>,
    /// Runs per size; the median is reported.
    #[arg(help_heading = "Benchmark", long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Usage-balancing rounds of each analysis (see `analyze --balance-rounds`; 0 times the
    /// paper's precomputation alone).
    #[arg(help_heading = "Benchmark", long, default_value_t = crate::analysis::balance::DEFAULT_ROUNDS, value_parser = super::whole_number_in::<0, { crate::analysis::balance::MAX_ROUNDS }>)]
    pub balance_rounds: u32,
    /// The feature channel, as `analyze --feature-mask` (auto, edges or none).
    #[arg(long, default_value = "auto", value_parser = ["auto", "edges", "none"])]
    pub feature_mask: String,
    /// The frame, as `analyze --frame` (`paper`: three exemplars, about twice the time of
    /// `cyclic`'s one shared image).
    #[arg(long, default_value = "paper", value_parser = ["paper", "cyclic"])]
    pub frame: String,
    /// Print JSON lines instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
    #[command(flatten)]
    pub backend: super::BackendArgs,
}

fn crop(img: &Image, size: u32) -> Image {
    let mut out = Image::new(size, size, img.channels);
    for y in 0..size {
        let src = &img.pixels[((y * img.width) * img.channels) as usize..]
            [..(size * img.channels) as usize];
        out.pixels[(y * size * img.channels) as usize..][..src.len()].copy_from_slice(src);
    }
    out
}

pub fn run(cmd: BenchCommand) -> anyhow::Result<()> {
    match cmd {
        BenchCommand::Analyze(args) => bench_analyze(args),
        BenchCommand::Synth(args) => bench_synth(args),
        BenchCommand::GradientSynth(args) => bench_gradient_synth(args),
        BenchCommand::GradientRender(args) => bench_gradient_render(args),
        BenchCommand::Ptm(args) => super::ptm_bench::run(args),
        BenchCommand::Lapped(args) => super::lapped_bench::run(args),
        BenchCommand::Serve(args) => super::serve_bench::bench(args),
        BenchCommand::Compare(args) => super::bench_compare::run(args),
    }
}

fn bench_gradient_synth(args: BenchGradientArgs) -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let exe = std::env::current_exe()?;
    let mut report = BenchReport::new(
        "gradient-synth",
        args.json,
        serde_json::json!({"input": args.input, "sizes": args.sizes, "backends": args.backends,
            "runs": args.runs}),
    );
    report.line(format!(
        "gradient synthesis benchmark: median of {} run(s) per size and backend",
        args.runs
    ));
    report.line(format!(
        "{:>6} {:>8} {:>10} {:>13} {:>28}",
        "size", "backend", "median s", "peak RSS MiB", "match / update s (median run)"
    ));
    for &size in &args.sizes {
        for backend in &args.backends {
            let mut runs = Vec::new();
            for _ in 0..args.runs.max(1) {
                let mut cmd = Command::new(&exe);
                cmd.args(["--quiet", "gradient", "synth"]);
                if let Some(input) = &args.input {
                    cmd.arg(input);
                }
                cmd.args([
                    "--size",
                    &size.to_string(),
                    "--backend",
                    backend,
                    "--json",
                    "-o",
                ])
                .arg(dir.path().join("bench.gsolid"));
                let job = format!("gradient synth --size {size} --backend {backend}");
                runs.push(run_json(&mut cmd, &job)?);
            }
            let seconds = |v: &serde_json::Value| v["seconds"].as_f64().unwrap_or(f64::NAN);
            runs.sort_by(|a, b| seconds(a).total_cmp(&seconds(b)));
            let median = &runs[runs.len() / 2];
            let sum = |key: &str| -> f64 {
                median["levels"]
                    .as_array()
                    .map(|l| l.iter().filter_map(|x| x[key].as_f64()).sum())
                    .unwrap_or(0.0)
            };
            let row = GradientSynthRow {
                size,
                backend: backend.clone(),
                median_s: seconds(median),
                peak_rss_mib: median["peak_rss_bytes"].as_f64().unwrap_or(f64::NAN)
                    / (1 << 20) as f64,
                match_s: sum("match_seconds"),
                update_s: sum("update_seconds"),
            };
            let text = format!(
                "{:>6} {:>8} {:>10.2} {:>13.1} {:>28}",
                row.size,
                row.backend,
                row.median_s,
                row.peak_rss_mib,
                format!("{:.2} / {:.2}", row.match_s, row.update_s),
            );
            report.row(row, text);
        }
    }
    report.finish();
    Ok(())
}

/// One size and backend of `bench gradient-synth` (the median run).
#[derive(serde::Serialize)]
struct GradientSynthRow {
    size: u32,
    backend: String,
    median_s: f64,
    peak_rss_mib: f64,
    match_s: f64,
    update_s: f64,
}

fn bench_gradient_render(args: BenchRenderArgs) -> anyhow::Result<()> {
    use crate::backend::Compute;
    use crate::gradient::render::{random_solid, render_u8};
    use crate::gradient::Query;
    let mut report = BenchReport::new(
        "gradient-render",
        args.json,
        serde_json::json!({"sizes": args.sizes, "runs": args.runs, "gpu": !args.no_gpu}),
    );
    let mut backends = vec![("cpu", Compute::Cpu)];
    if !args.no_gpu {
        let mut opts = crate::gpu::GpuOptions::from_env();
        opts.adapter_filter = args.adapter.clone().or(opts.adapter_filter);
        let ctx = crate::gpu::GpuContext::new(&opts)?;
        report.note(format!("adapter: {}", ctx.describe()));
        backends.push(("gpu", Compute::Gpu(std::sync::Arc::new(ctx))));
    }
    report.line(format!(
        "gradient render benchmark (3 channels, 8-bit output, read-back included): median of {} \
         warm run(s)",
        args.runs
    ));
    report.line(format!(
        "{:>6} {:>8} {:>10} {:>10}",
        "size", "backend", "median s", "Mvoxel/s"
    ));
    for &size in &args.sizes {
        let solid = random_solid(size, 3, u64::from(size))?;
        let query = Query::volume([size; 3]);
        let mut medians = Vec::new();
        let mut outputs = Vec::new();
        for (name, compute) in &backends {
            let mut out = render_u8(&solid, &query, compute)?;
            let mut times = Vec::new();
            for _ in 0..args.runs.max(1) {
                let start = Instant::now();
                out = render_u8(&solid, &query, compute)?;
                times.push(start.elapsed().as_secs_f64());
            }
            let median = output::median(&times);
            let row = GradientRenderRow {
                size,
                backend: name.to_string(),
                median_s: median,
                mvoxels_per_s: query.len() as f64 / median / 1e6,
            };
            let text = format!(
                "{:>6} {:>8} {:>10.4} {:>10.1}",
                size, name, median, row.mvoxels_per_s
            );
            report.row(row, text);
            medians.push(median);
            outputs.push(out);
        }
        if let [cpu, gpu] = &medians[..] {
            let differing = outputs[0]
                .iter()
                .zip(&outputs[1])
                .filter(|(a, b)| a != b)
                .count();
            report.note(format!(
                "{size:>6}  cpu/gpu ratio {:.2}; bytes differing between the backends: {differing} of {}",
                cpu / gpu,
                outputs[0].len()
            ));
        }
    }
    report.finish();
    Ok(())
}

/// One size and backend of `bench gradient-render`.
#[derive(serde::Serialize)]
struct GradientRenderRow {
    size: u32,
    backend: String,
    median_s: f64,
    mvoxels_per_s: f64,
}

fn bench_synth(args: BenchSynthArgs) -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let exe = std::env::current_exe()?;
    let child = |size: u32, backend: &str, profile: bool| -> anyhow::Result<serde_json::Value> {
        let mut cmd = Command::new(&exe);
        cmd.env("SOLIDSYNTH_CACHE_DIR", dir.path().join("cache"))
            .args([
                "--quiet",
                "synth",
                "--json",
                "--size",
                &size.to_string(),
                "--backend",
                backend,
                "-o",
            ])
            .arg(dir.path().join("v.nrrd"));
        if let Some(i) = &args.input {
            cmd.arg(i);
        }
        if args.periodic {
            cmd.arg("--periodic");
        }
        // (An .ssa input with `none` is refused by synth: the file holds its channel.)
        cmd.args(["--feature-mask", &args.feature_mask]);
        cmd.args(["--passes", &args.passes.to_string()]);
        if let Some(g) = args.max_group {
            cmd.args(["--max-group", &g.to_string()]);
        }
        if profile {
            cmd.arg("--profile");
        }
        run_json(
            &mut cmd,
            &format!("synth --size {size} --backend {backend}"),
        )
    };
    // Warm the analysis cache so the runs time synthesis only.
    child(16, "cpu", false)?;
    let mut report = BenchReport::new(
        "synth",
        args.json,
        serde_json::json!({"input": args.input, "sizes": args.sizes, "backends": args.backends,
            "runs": args.runs, "passes": args.passes, "feature_mask": args.feature_mask,
            "max_group": args.max_group, "periodic": args.periodic}),
    );
    report.line(format!("synthesis benchmark: median of {} run(s), analysis excluded; per-kernel times from one --profile run", args.runs));
    report.line(format!(
        "{:>6}  {:>8}  {:>10}  {:>12}  kernels (s): init / upsample / correct / colorize",
        "size", "backend", "median s", "peak RSS MiB"
    ));
    for &size in &args.sizes {
        let mut per_backend = Vec::new();
        for backend in &args.backends {
            let mut times = Vec::new();
            let mut peak = 0u64;
            for _ in 0..args.runs.max(1) {
                let v = child(size, backend, false)?;
                times.push(v["synthesis_seconds"].as_f64().unwrap_or(f64::NAN));
                peak = peak.max(v["peak_rss_bytes"].as_u64().unwrap_or(0));
            }
            let median = output::median(&times);
            let prof = child(size, backend, true)?;
            let k = |name: &str| {
                prof["kernels"][name]["seconds"]
                    .as_f64()
                    .unwrap_or(f64::NAN)
            };
            let kernels = KernelSeconds {
                init: k("init"),
                upsample: k("upsample"),
                correct: k("correct"),
                colorize: k("colorize"),
            };
            let text = format!(
                "{:>6}  {:>8}  {:>10.3}  {:>12.1}  {:.3} / {:.3} / {:.3} / {:.3}",
                size,
                backend,
                median,
                peak as f64 / (1 << 20) as f64,
                kernels.init,
                kernels.upsample,
                kernels.correct,
                kernels.colorize
            );
            let row = SynthRow {
                size,
                backend: backend.clone(),
                median_s: median,
                peak_rss_mib: peak as f64 / (1 << 20) as f64,
                kernels,
            };
            report.row(&row, text);
            per_backend.push(row);
        }
        if let [a, b] = per_backend.as_slice() {
            let (ka, kb) = (&a.kernels, &b.kernels);
            report.note(format!(
                "{:>6}  {}/{} ratio: end-to-end {:.2}; kernels {:.2} / {:.2} / {:.2} / {:.2}",
                size,
                a.backend,
                b.backend,
                a.median_s / b.median_s,
                ka.init / kb.init,
                ka.upsample / kb.upsample,
                ka.correct / kb.correct,
                ka.colorize / kb.colorize
            ));
        }
    }
    report.finish();
    Ok(())
}

/// One size and backend of `bench synth`.
#[derive(serde::Serialize)]
struct SynthRow {
    size: u32,
    backend: String,
    median_s: f64,
    peak_rss_mib: f64,
    /// From one `--profile` run.
    kernels: KernelSeconds,
}

#[derive(serde::Serialize)]
struct KernelSeconds {
    init: f64,
    upsample: f64,
    correct: f64,
    colorize: f64,
}

fn bench_analyze(args: BenchAnalyzeArgs) -> anyhow::Result<()> {
    let source = match &args.exemplar {
        Some(p) => Some(exemplar::load_image(p, "--exemplar")?),
        None => None,
    };
    if let Some(src) = &source {
        let biggest = args.sizes.iter().copied().max().unwrap_or(0);
        if src.width < biggest || src.height < biggest {
            anyhow::bail!(crate::Error::invalid(
                "--exemplar",
                format!(
                    "is {}x{}, smaller than --sizes {biggest}",
                    src.width, src.height
                )
            ));
        }
    }
    let dir = tempfile::tempdir()?;
    let exe = std::env::current_exe()?;
    if !args.json {
        println!(
            "analysis benchmark: backend {:?}, {} run(s) per size, {} balancing round(s), median reported",
            args.backend.backend, args.runs, args.balance_rounds
        );
        println!(
            "{:>6}  {:>10}  {:>10}  {:>12}  {:>10}",
            "size", "median s", "min s", "peak RSS MiB", "file MiB"
        );
    }
    for &size in &args.sizes {
        let img = match &source {
            Some(src) => crop(src, size),
            None => procedural::cobblestone(size, (size / 8).max(8), 7),
        };
        let input = dir.path().join(format!("ex{size}.png"));
        img.to_dynamic().save(&input)?;
        let output = dir.path().join(format!("ex{size}.ssa"));
        let mut times = Vec::new();
        let mut peak = 0u64;
        for _ in 0..args.runs.max(1) {
            let start = Instant::now();
            let mut cmd = Command::new(&exe);
            cmd.args(["--quiet", "analyze", "--json", "--backend"])
                .arg(format!("{:?}", args.backend.backend).to_lowercase())
                .arg("--balance-rounds")
                .arg(args.balance_rounds.to_string())
                .args(["--feature-mask", &args.feature_mask])
                .args(["--frame", &args.frame])
                .arg(&input)
                .arg("-o")
                .arg(&output);
            if let Some(a) = &args.backend.adapter {
                cmd.args(["--adapter", a]);
            }
            let summary = run_json(&mut cmd, &format!("analyze at size {size}"))?;
            let secs = start.elapsed().as_secs_f64();
            peak = peak.max(summary["peak_rss_bytes"].as_u64().unwrap_or(0));
            times.push(secs);
        }
        let median = output::median(&times);
        let min = times.iter().copied().fold(f64::INFINITY, f64::min);
        let file_mib = std::fs::metadata(&output)?.len() as f64 / (1 << 20) as f64;
        if args.json {
            println!(
                "{}",
                serde_json::to_value(AnalyzeRow {
                    schema: super::output::SUMMARY_SCHEMA,
                    size,
                    median_s: median,
                    min_s: min,
                    peak_rss_bytes: peak,
                    file_bytes: std::fs::metadata(&output)?.len(),
                })?
            );
        } else {
            println!(
                "{:>6}  {:>10.3}  {:>10.3}  {:>12.1}  {:>10.1}",
                size,
                median,
                min,
                peak as f64 / (1 << 20) as f64,
                file_mib
            );
        }
    }
    Ok(())
}

/// One exemplar size of `bench analyze --json` (a JSON line per size).
#[derive(serde::Serialize)]
struct AnalyzeRow {
    schema: u32,
    size: u32,
    median_s: f64,
    min_s: f64,
    peak_rss_bytes: u64,
    file_bytes: u64,
}
