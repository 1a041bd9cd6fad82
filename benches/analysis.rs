//! `cargo bench`: kernel `project` on the CPU reference vs the GPU adapter, the whole analysis, and
//! end-to-end synthesis on both backends, and kernel `tricubic_eval` (gradient solids).
//! Wall-clock tables per exemplar size with peak memory come from `solidsynth bench analyze`.

use criterion::{criterion_group, criterion_main, Criterion};
use solidsynth::analysis::{neighbourhood::gather, pca, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::exemplar::{procedural, Border};
use solidsynth::gpu::{GpuContext, GpuOptions};

fn project_kernel(c: &mut Criterion) {
    let gpu = GpuContext::new(&GpuOptions::from_env()).ok();
    match &gpu {
        Some(g) => eprintln!("GPU adapter: {}", g.describe()),
        None => eprintln!("no GPU adapter: GPU rows skipped"),
    }
    for size in [128u32, 256] {
        let img = procedural::cobblestone(size, size / 8, 7);
        let mut vectors = Vec::new();
        for y in 0..size {
            for x in 0..size {
                gather(&img, Border::Wrap, x, y, &mut vectors);
            }
        }
        let basis = pca::fit(&vectors, 75, 12, &[1.0; 75], 1 << 16).unwrap();
        let mut group = c.benchmark_group(format!("project/{size}x{size}"));
        group.sample_size(10);
        group.bench_function("cpu", |b| {
            b.iter(|| solidsynth::cpu::project::project(&img, Border::Wrap, &basis))
        });
        if let Some(g) = &gpu {
            group.bench_function("gpu", |b| {
                b.iter(|| solidsynth::gpu::project::project(g, &img, Border::Wrap, &basis).unwrap())
            });
        }
        group.finish();
    }
}

fn whole_analysis(c: &mut Criterion) {
    let mut group = c.benchmark_group("analyze");
    group.sample_size(10);
    for size in [64u32, 128] {
        let input = AnalysisInput {
            exemplars: vec![procedural::cobblestone(size, size / 8, 7)],
            masks: vec![],
            border: Border::Wrap,
            names: vec!["cobblestone".into()],
        };
        group.bench_function(format!("{size}x{size} cpu"), |b| {
            b.iter(|| {
                solidsynth::lazy::analyze(
                    &input,
                    &AnalysisParams::default(),
                    &Compute::Cpu,
                    &|_, _| {},
                )
                .unwrap()
            })
        });
    }
    group.finish();
}

/// End-to-end synthesis of a 24^3 box (every kernel) on the CPU backend and on the GPU adapter,
/// then each kernel's share of it ("synthesis kernels 24^3/KERNEL BACKEND": the kernel's total
/// time per synthesis, from the synthesizer's profiling, which waits for the device after every
/// kernel). `solidsynth bench synth` prints the same
/// split with CPU/GPU ratios for larger volumes.
fn synthesis(c: &mut Criterion) {
    use solidsynth::lazy::{Box3, SynthParams, Synthesizer};
    let input = AnalysisInput {
        exemplars: vec![procedural::cobblestone(64, 8, 7)],
        masks: vec![],
        border: Border::Wrap,
        names: vec!["cobblestone".into()],
    };
    let a = solidsynth::lazy::analyze(
        &input,
        &AnalysisParams::default(),
        &Compute::Cpu,
        &|_, _| {},
    )
    .unwrap();
    let b = Box3::new([0; 3], [24; 3]);
    let mut group = c.benchmark_group("synthesize 24^3");
    group.sample_size(10);
    let profiled = solidsynth::lazy::SynthOptions {
        profile: true,
        ..Default::default()
    };
    let mut cpu =
        Synthesizer::with_options(&a, SynthParams::default(), &Compute::Cpu, profiled.clone())
            .unwrap();
    group.bench_function("cpu", |bench| {
        bench.iter(|| cpu.synthesize(b, &|_, _| {}).unwrap())
    });
    if let Ok(gpu) = Compute::open(
        solidsynth::backend::BackendChoice::Gpu,
        &GpuOptions::from_env(),
    ) {
        let mut g =
            Synthesizer::with_options(&a, SynthParams::default(), &gpu, profiled.clone()).unwrap();
        group.bench_function("gpu", |bench| {
            bench.iter(|| g.synthesize(b, &|_, _| {}).unwrap())
        });
        group.finish();
        per_kernel(c, b, [("cpu", &mut cpu), ("gpu", &mut g)]);
    } else {
        group.finish();
        per_kernel(c, b, [("cpu", &mut cpu)]);
    }
}

/// Each synthesis kernel's time per synthesis of box `b`, per backend.
fn per_kernel<const N: usize>(
    c: &mut Criterion,
    b: solidsynth::lazy::Box3,
    synths: [(&str, &mut solidsynth::lazy::Synthesizer); N],
) {
    let mut group = c.benchmark_group("synthesis kernels 24^3");
    group.sample_size(10);
    for (backend, s) in synths {
        for kernel in ["init", "upsample", "correct", "colorize"] {
            group.bench_function(format!("{kernel} {backend}"), |bench| {
                bench.iter_custom(|iterations| {
                    let mut total = std::time::Duration::ZERO;
                    for _ in 0..iterations {
                        s.reset_kernel_times();
                        s.synthesize(b, &|_, _| {}).unwrap();
                        // A kernel that did not run (none here) adds nothing.
                        total += s
                            .kernel_times()
                            .unwrap()
                            .get(kernel)
                            .map_or(std::time::Duration::ZERO, |&(time, _)| time);
                    }
                    total
                })
            });
        }
    }
    group.finish();
}

/// Kernel `tricubic_eval`: a 64^3 volume from a random 17^3 x 3-channel gradient solid.
fn tricubic(c: &mut Criterion) {
    use solidsynth::cpu::tricubic_eval::{tricubic_eval, Query};
    let mut solid = solidsynth::gradient::GradientSolid::new([17, 17, 17], 3).unwrap();
    let mut rng = solidsynth::util::hash::SeededRng::new(1);
    for v in solid.data.iter_mut() {
        *v = rng.below(256) as f32;
    }
    let query = Query::volume([64, 64, 64]);
    let gpu = GpuContext::new(&GpuOptions::from_env()).ok();
    let mut group = c.benchmark_group("tricubic_eval/64^3");
    group.sample_size(10);
    group.bench_function("cpu", |b| b.iter(|| tricubic_eval(&solid, &query)));
    if let Some(g) = &gpu {
        group.bench_function("gpu", |b| {
            b.iter(|| solidsynth::gpu::tricubic_eval::tricubic_eval(g, &solid, &query).unwrap())
        });
    }
    group.finish();
}

/// A warm 128^2 oblique cut through the facade (`Solid::into_cut_session`) against the engine's
/// own path (`CutSession` over a `Synthesizer`), on the CPU backend, the same analysis and
/// parameters: the facade must add nothing measurable.
fn facade_cut(c: &mut Criterion) {
    use solidsynth::lazy::cut::{CutSession, CutSpec};
    use solidsynth::lazy::{SynthParams, Synthesizer};
    let a = solidsynth::Solid::builder().cpu().analyze().unwrap();
    let params = SynthParams {
        coarse_cache: Some(64),
        ..Default::default()
    };
    let spec = CutSpec {
        origin: [3.0, -4.0, 11.0],
        normal: [1.0, 2.0, 3.0],
        up: None,
        size: 128,
        spacing: 1.0,
    };
    let mut engine = CutSession::new(Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap());
    let mut facade = solidsynth::Solid::builder()
        .shared_analysis(a)
        .params(params)
        .cpu()
        .build()
        .unwrap()
        .into_cut_session();
    assert_eq!(engine.cut(&spec).unwrap(), facade.cut(&spec).unwrap());
    let mut group = c.benchmark_group("warm cut 128^2 oblique, coarse cache 64, cpu");
    group.sample_size(20);
    group.bench_function("engine CutSession", |b| {
        b.iter(|| engine.cut(&spec).unwrap())
    });
    group.bench_function("facade Solid", |b| b.iter(|| facade.cut(&spec).unwrap()));
    group.finish();
}

criterion_group!(
    benches,
    project_kernel,
    whole_analysis,
    synthesis,
    tricubic,
    facade_cut
);
criterion_main!(benches);
