//! `solidsynth bench ptm`: PTM synthesis with the projection-kernel and brute-force searches
//! (medians, ratio, and a check that the outputs are byte-identical), and relighting on the CPU
//! and the GPU.

use crate::backend::{BackendChoice, Compute};
use crate::ptm::quilt::{self, QuiltParams, SearchMethod};
use crate::ptm::Lighting;
use crate::ptm::{capture, fit, Ptm, PtmFormat};
use clap::Args;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BenchPtmArgs {
    /// Side of the synthetic source capture (and its fitted PTM).
    #[arg(long, default_value_t = 128)]
    pub source: u32,
    /// Side of the synthesized PTM.
    #[arg(long, default_value_t = 512)]
    pub size: u32,
    #[arg(long, default_value_t = 32)]
    pub block: u32,
    #[arg(long, default_value_t = 6)]
    pub overlap: u32,
    /// PTM format of the source.
    #[arg(long, value_enum, default_value = "lrgb")]
    pub format: PtmFormat,
    /// Side of the PTM relit (the source tiled).
    #[arg(long, default_value_t = 1024)]
    pub relight_size: u32,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub runs: u32,
    /// Skip the GPU relight.
    #[arg(long)]
    pub no_gpu: bool,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn timed<T>(runs: u32, mut f: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<(f64, T)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        last = Some(f()?);
        times.push(t.elapsed().as_secs_f64());
    }
    Ok((median(times), last.unwrap()))
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
    println!(
        "PTM benchmark: {0}x{0} {1} source (synthetic capture, 24 lights), median of {2} run(s), {3} rayon threads",
        a.source,
        a.format.header_name(),
        a.runs,
        rayon::current_num_threads()
    );
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
    println!(
        "synthesis {0}x{0}, blocks {1} overlap {2} ({3}x{4} blocks, {5} candidates per query):",
        a.size,
        a.block,
        a.overlap,
        report.blocks.0,
        report.blocks.1,
        st.candidates / st.queries.max(1)
    );
    println!("  {:<18} {:>10.3} s", "exact-projection", t_proj);
    println!("  {:<18} {:>10.3} s", "brute", t_brute);
    println!(
        "  brute/projection ratio {:.1}x; outputs byte-identical: {}",
        t_brute / t_proj,
        if out_proj == out_brute { "yes" } else { "NO" }
    );
    println!(
        "  candidates left after projection stages ({:?} kernels): {}; exact distances per query: {:.1}",
        &crate::ptm::search::STAGES[..st.survivors.len()],
        st.survivors
            .iter()
            .map(|&s| format!("{:.2}%", 100.0 * s as f64 / st.candidates.max(1) as f64))
            .collect::<Vec<_>>()
            .join(", "),
        st.exact as f64 / st.queries.max(1) as f64
    );
    if out_proj != out_brute {
        anyhow::bail!("the projection search and brute force disagree");
    }

    let big = tiled(&src, a.relight_size);
    let light = Lighting {
        lu: 0.4,
        lv: 0.3,
        specular: 0.0,
    };
    println!("relight {0}x{0} (one light, no specular):", a.relight_size);
    let (t_cpu, cpu) = timed(
        a.runs.max(5),
        || Ok(Compute::Cpu.ptm_relight(&big, &light)?),
    )?;
    println!("  {:<34} {:>10.2} ms", "cpu", t_cpu * 1e3);
    if !a.no_gpu {
        let gpu = Compute::open(BackendChoice::Gpu, &crate::gpu::GpuOptions::from_env())?;
        let (t_up, resident) = timed(a.runs, || Ok(gpu.resident_ptm(&big)))?;
        resident.relight(&light)?; // warm the pipeline
        let (t_gpu, out) = timed(a.runs.max(5), || Ok(resident.relight(&light)?))?;
        let worst = cpu
            .iter()
            .zip(&out)
            .map(|(c, g)| (c - g).abs())
            .fold(0f32, f32::max);
        println!("  adapter: {}", gpu.describe());
        println!("  {:<34} {:>10.2} ms", "gpu upload (once)", t_up * 1e3);
        println!(
            "  {:<34} {:>10.2} ms",
            "gpu relight (dispatch + readback)",
            t_gpu * 1e3
        );
        println!("  largest |gpu - cpu|: {worst:.2e}");
    }
    Ok(())
}
