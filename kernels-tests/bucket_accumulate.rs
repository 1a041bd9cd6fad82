//! `bucket_accumulate`: GPU equals the CPU reference bit for bit, in any sample order.

use crate::compare::words_equal;
use solidsynth::cpu::bucket_accumulate::{bucket_accumulate, dominant};
use solidsynth::util::hash::SeededRng;

fn samples(seed: u64, n: usize, voxels: u32, clusters: u32, channels: u32) -> Vec<u32> {
    let mut rng = SeededRng::new(seed);
    let mut out = Vec::new();
    for _ in 0..n {
        out.push(rng.below(voxels as u64) as u32);
        // Skewed clusters, so dominance and ties both occur.
        out.push(
            (rng.below(clusters as u64) * rng.below(clusters as u64) / clusters as u64) as u32,
        );
        for _ in 0..channels {
            out.push(rng.below(256) as u32);
        }
    }
    out
}

#[test]
fn bucket_accumulate_matches_its_reference_in_any_order() {
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    let (voxels, clusters, channels) = (500usize, 12u32, 3u32);
    let s = samples(4, 20_000, voxels as u32, clusters, channels);
    let cpu = bucket_accumulate(&s, voxels, clusters, channels);
    let out =
        solidsynth::gpu::bucket_accumulate::bucket_accumulate(gpu, &s, voxels, clusters, channels)
            .unwrap();
    words_equal("counts", &cpu.counts, &out.counts).unwrap();
    words_equal("sums", &cpu.sums, &out.sums).unwrap();
    // Reversed sample order: the same buckets (integer atomics commute).
    let stride = 2 + channels as usize;
    let reversed: Vec<u32> = s.chunks_exact(stride).rev().flatten().copied().collect();
    let again = solidsynth::gpu::bucket_accumulate::bucket_accumulate(
        gpu, &reversed, voxels, clusters, channels,
    )
    .unwrap();
    assert_eq!(again, out);
    // The sums hold exactly the dominant clusters' samples (checked by brute force on voxel 7).
    let d = dominant(&cpu.counts[7 * 12..8 * 12]);
    let mut want = [0u32; 8];
    for smp in s.chunks_exact(stride).filter(|x| x[0] == 7) {
        if let Some(slot) = d.iter().position(|&c| c == smp[1]) {
            want[slot * 4] += 1;
            for c in 0..3 {
                want[slot * 4 + 1 + c] += smp[2 + c] << 8;
            }
        }
    }
    assert_eq!(&cpu.sums[7 * 8..8 * 8], &want);
}

/// Gradient-solid synthesis with its bucket step on the GPU (tiles' samples listed and
/// dispatched a batch at a time) gives the same solid, bit for bit, as the CPU's streamed
/// buckets; also when a small storage binding makes every tile its own dispatch and splits its
/// samples over several buffers.
#[test]
fn gradient_synthesis_buckets_bit_exact_on_gpu_and_cpu() {
    let _serial = crate::serial();
    use solidsynth::backend::{BackendChoice, Compute};
    use solidsynth::gpu::GpuOptions;
    use solidsynth::gradient::synth::{synthesize, GradientSynthParams};
    let Some(_) = crate::gpu() else { return };
    let gpu = Compute::open(BackendChoice::Gpu, &GpuOptions::from_env()).unwrap();
    let small_binding = GpuOptions {
        // A tile's counts (1728 voxels x 12 clusters) fit, two tiles' do not.
        max_binding_bytes: Some(128 << 10),
        ..GpuOptions::from_env()
    };
    let narrow = Compute::open(BackendChoice::Gpu, &small_binding).unwrap();
    let exemplar = solidsynth::exemplar::procedural::cobblestone(48, 9, 3);
    // 24^3: 6^3 control points, eight tiles of 3^3.
    let params = GradientSynthParams {
        seed: 5,
        size: 24,
        iterations: 1,
        check_points: 2,
        ..Default::default()
    };
    let (cpu, _) = synthesize(&exemplar, &params, &Compute::Cpu, &|_, _| {}).unwrap();
    let bits = |s: &solidsynth::gradient::synth::PeriodicSolid| -> Vec<u32> {
        s.data.iter().map(|v| v.to_bits()).collect()
    };
    for (name, compute) in [("batched", &gpu), ("one tile per dispatch", &narrow)] {
        let (on_gpu, _) = synthesize(&exemplar, &params, compute, &|_, _| {}).unwrap();
        words_equal(name, &bits(&cpu), &bits(&on_gpu)).unwrap();
    }
}

/// Synthesis with a mask (region separation): the bucket step on the GPU gives the same region
/// solid file, byte for byte, as on the CPU.
#[test]
fn masked_gradient_synthesis_same_file_on_gpu_and_cpu() {
    let _serial = crate::serial();
    use solidsynth::backend::{BackendChoice, Compute};
    use solidsynth::gpu::GpuOptions;
    use solidsynth::gradient::format::Encoding;
    use solidsynth::gradient::synth::{synthesize_regions, GradientSynthParams, MaskedExemplar};
    let Some(_) = crate::gpu() else { return };
    let gpu = Compute::open(BackendChoice::Gpu, &GpuOptions::from_env()).unwrap();
    let (img, mask) = solidsynth::exemplar::procedural::discs(40, 7, 6.0, 5);
    let masked = MaskedExemplar::new(&img, &mask, "mask").unwrap();
    let params = GradientSynthParams {
        seed: 5,
        size: 16,
        iterations: 1,
        check_points: 2,
        ..Default::default()
    };
    let file = |c: &Compute| {
        let (rs, _) = synthesize_regions(&masked, &params, c, &|_, _| {}).unwrap();
        rs.to_bytes(Encoding::F32)
    };
    let (cpu, on_gpu) = (file(&Compute::Cpu), file(&gpu));
    let words = |b: &[u8]| -> Vec<u32> { b.iter().map(|&x| x as u32).collect() };
    words_equal("region solid file", &words(&cpu), &words(&on_gpu)).unwrap();
}
