//! `solidsynth bench ptm`: PTM synthesis with the projection-kernel and brute-force searches
//! (medians, ratio, and a check that the outputs are byte-identical), and relighting on the CPU
//! and the GPU.

use super::output::{self, BenchReport};
use crate::backend::{BackendChoice, Compute};
use crate::ptm::quilt::{self, QuiltParams, SearchMethod};
use crate::ptm::Lighting;
use crate::ptm::{capture, fit, Ptm, PtmFormat};
use clap::Args;
use std::time::Instant;

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchPtmArgs {
    /// Side of the synthetic source capture (and its fitted PTM).
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub source: u32,
    /// Side of the synthesized PTM.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub size: u32,
    #[arg(long, default_value_t = 32)]
    pub block: u32,
    #[arg(long, default_value_t = 6)]
    pub overlap: u32,
    /// PTM format of the source.
    #[arg(long, value_enum, default_value = "lrgb")]
    pub format: PtmFormat,
    /// Side of the PTM relit (the source tiled).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub relight_size: u32,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Skip the GPU relight.
    #[arg(long)]
    pub no_gpu: bool,
    /// Print the results as JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// One timed measurement of `bench ptm`.
#[derive(serde::Serialize)]
struct PtmRow {
    /// `synthesis` or `relight`.
    job: &'static str,
    /// The search method, or the relight backend and step.
    method: &'static str,
    /// Side of the synthesized or relit PTM.
    size: u32,
    median_ms: f64,
}

fn timed<T>(runs: u32, mut f: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<(f64, T)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        last = Some(f()?);
        times.push(t.elapsed().as_secs_f64());
    }
    Ok((output::median(&times), last.unwrap()))
}

/// `src` tiled to `size` x `size`.
fn tiled(src: &Ptm, size: u32) -> Ptm {
    let s = src.format.texel_bytes();
    let mut texels = Vec::with_capacity(size as usize * size as usize * s);
    for y in 0..size {
        for x in 0..size {
            texels.extend_from_slice(src.texel(x % src.width, y % src.height));
        }
    }
    Ptm {
        width: size,
        height: size,
        texels,
        ..src.clone()
    }
}

pub fn run(a: BenchPtmArgs) -> anyhow::Result<()> {
    let cap = capture::synthetic(a.source, 24, 0);
    let src = fit::fit(&cap, a.format, "synthetic capture")?;
    let mut out = BenchReport::new(
        "ptm",
        a.json,
        serde_json::json!({"source": a.source, "size": a.size, "block": a.block,
            "overlap": a.overlap, "format": a.format.header_name(),
            "relight_size": a.relight_size, "runs": a.runs,
            "threads": rayon::current_num_threads()}),
    );
    out.line(format!(
        "PTM benchmark: {0}x{0} {1} source (synthetic capture, 24 lights), median of {2} run(s), {3} rayon threads",
        a.source,
        a.format.header_name(),
        a.runs,
        rayon::current_num_threads()
    ));
    let mut params = QuiltParams::new(a.size);
    params.block = a.block;
    params.overlap = a.overlap;
    let mut run_search = |method: SearchMethod| {
        params.search = method;
        let p = params.clone();
        timed(a.runs, || Ok(quilt::synthesize(&src, &p, &mut |_, _| {})?))
    };
    let (t_proj, (out_proj, report)) = run_search(SearchMethod::ExactProjection)?;
    let (t_brute, (out_brute, _)) = run_search(SearchMethod::Brute)?;
    let st = &report.stats;
    out.line(format!(
        "synthesis {0}x{0}, blocks {1} overlap {2} ({3}x{4} blocks, {5} candidates per query):",
        a.size,
        a.block,
        a.overlap,
        report.blocks.0,
        report.blocks.1,
        st.candidates / st.queries.max(1)
    ));
    for (method, t) in [("exact-projection", t_proj), ("brute", t_brute)] {
        let row = PtmRow {
            job: "synthesis",
            method,
            size: a.size,
            median_ms: t * 1e3,
        };
        out.row(row, format!("  {method:<18} {t:>10.3} s"));
    }
    out.note(format!(
        "  brute/projection ratio {:.1}x; outputs byte-identical: {}",
        t_brute / t_proj,
        if out_proj == out_brute { "yes" } else { "NO" }
    ));
    out.note(format!(
        "  candidates left after projection stages ({:?} kernels): {}; exact distances per query: {:.1}",
        &crate::ptm::search::STAGES[..st.survivors.len()],
        st.survivors
            .iter()
            .map(|&s| format!("{:.2}%", 100.0 * s as f64 / st.candidates.max(1) as f64))
            .collect::<Vec<_>>()
            .join(", "),
        st.exact as f64 / st.queries.max(1) as f64
    ));
    if out_proj != out_brute {
        anyhow::bail!("the projection search and brute force disagree");
    }

    let big = tiled(&src, a.relight_size);
    let light = Lighting {
        lu: 0.4,
        lv: 0.3,
        specular: 0.0,
    };
    out.line(format!(
        "relight {0}x{0} (one light, no specular):",
        a.relight_size
    ));
    let (t_cpu, cpu) = timed(
        a.runs.max(5),
        || Ok(Compute::Cpu.ptm_relight(&big, &light)?),
    )?;
    let relight = |method, seconds: f64| PtmRow {
        job: "relight",
        method,
        size: a.relight_size,
        median_ms: seconds * 1e3,
    };
    out.row(
        relight("cpu", t_cpu),
        format!("  {:<34} {:>10.2} ms", "cpu", t_cpu * 1e3),
    );
    if !a.no_gpu {
        let gpu = Compute::open(BackendChoice::Gpu, &crate::gpu::GpuOptions::from_env())?;
        let (t_up, resident) = timed(a.runs, || Ok(gpu.resident_ptm(&big)))?;
        resident.relight(&light)?; // warm the pipeline
        let (t_gpu, relit) = timed(a.runs.max(5), || Ok(resident.relight(&light)?))?;
        let worst = cpu
            .iter()
            .zip(&relit)
            .map(|(c, g)| (c - g).abs())
            .fold(0f32, f32::max);
        out.note(format!("  adapter: {}", gpu.describe()));
        out.row(
            relight("gpu upload (once)", t_up),
            format!("  {:<34} {:>10.2} ms", "gpu upload (once)", t_up * 1e3),
        );
        out.row(
            relight("gpu relight (dispatch + readback)", t_gpu),
            format!(
                "  {:<34} {:>10.2} ms",
                "gpu relight (dispatch + readback)",
                t_gpu * 1e3
            ),
        );
        out.note(format!("  largest |gpu - cpu|: {worst:.2e}"));
    }
    out.finish();
    Ok(())
}
