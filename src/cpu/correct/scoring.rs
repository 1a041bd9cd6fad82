//! The arithmetic of a correction: projections with AVX2 multiply-adds, squared distances, the
//! best candidate of a run, and cache prefetches for the runs about to be scored.

use super::*;

/// The first candidate of `run` whose scaled distance to `q` is below `best_d`, and then below
/// each one kept: (distance, coordinate) of the last kept.
#[inline(always)]
pub(super) fn best_2d_of_run<const P: usize>(
    run: &[Candidate2d<P>],
    q: &Projection,
    mut best_d: u32,
) -> Option<(u32, u32)> {
    // Branch-free selection (the comparisons are unpredictable; selects become cmovs).
    let mut best = usize::MAX;
    for (i, c) in run.iter().enumerate() {
        let d = squared_distance::<P>(q, &c.projection) * c.factor as u32;
        let better = d < best_d;
        best_d = if better { d } else { best_d };
        best = if better { i } else { best };
    }
    (best != usize::MAX).then(|| (best_d, run[best].coord))
}

/// The accumulators of one plane's projection (before [`Ctx::finish_projection`]) from its 25
/// state words, with 16-bit multiply-adds: each 32-bit lane adds the products of two channels,
/// so a pixel's 4 channels take 2 (BLOCKS = 1: 8 outputs) or 4 (16 outputs) instructions. The
/// products are exact (|value - mean| <= 255, |weight| < 2^15) and the i32 sums wrap as the
/// scalar loop's do, so the results are the same bit for bit.
///
/// # Safety
/// The CPU must support AVX2; `weights` and `means` come from [`PairWeights`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn project_plane_madd<const BLOCKS: usize>(
    words: &[u32; 25],
    weights: &[i16],
    means: &[i16],
) -> [i32; 16] {
    use std::arch::x86_64::*;
    assert!(weights.len() >= 25 * PAIR_WEIGHTS_PER_PIXEL && means.len() >= 25 * 4);
    let mut acc = [_mm256_setzero_si256(); 2];
    for (pixel, &word) in words.iter().enumerate() {
        // SAFETY (all loads): in bounds by the assertion above; unaligned loads.
        let values = _mm_cvtepu8_epi16(_mm_cvtsi32_si128(word as i32));
        let mean = unsafe { _mm_loadl_epi64(means.as_ptr().add(pixel * 4) as *const __m128i) };
        let centred = _mm_sub_epi16(values, mean);
        let pairs = [
            _mm256_broadcastd_epi32(centred),
            _mm256_broadcastd_epi32(_mm_srli_si128::<4>(centred)),
        ];
        let w = unsafe { weights.as_ptr().add(pixel * PAIR_WEIGHTS_PER_PIXEL) };
        for (pair, &values) in pairs.iter().enumerate() {
            for (block, acc) in acc.iter_mut().enumerate().take(BLOCKS) {
                let row =
                    unsafe { _mm256_loadu_si256(w.add((pair * 2 + block) * 16) as *const __m256i) };
                *acc = _mm256_add_epi32(*acc, _mm256_madd_epi16(values, row));
            }
        }
    }
    let mut out = [0i32; 16];
    // SAFETY: out holds 16 i32 = two 256-bit stores.
    unsafe {
        _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, acc[0]);
        _mm256_storeu_si256(out.as_mut_ptr().add(8) as *mut __m256i, acc[1]);
    }
    out
}

/// The first candidate of `run` whose scaled distance (`own` plus its two other planes') is
/// below `best_d`, and then below each one kept: (distance, triple) of the last kept.
#[inline(always)]
pub(super) fn best_of_run<const P: usize>(
    run: &[Candidate3d<P>],
    qb: &Projection,
    qc: &Projection,
    own: u32,
    mut best_d: u32,
) -> Option<(u32, [u32; 3])> {
    // Branch-free selection, as in [`best_2d_of_run`].
    let mut best = usize::MAX;
    for (i, e) in run.iter().enumerate() {
        let d = (own + squared_distance::<P>(qb, &e.next) + squared_distance::<P>(qc, &e.last))
            * e.factor;
        let better = d < best_d;
        best_d = if better { d } else { best_d };
        best = if better { i } else { best };
    }
    (best != usize::MAX).then(|| (best_d, run[best].triple))
}

/// Ask the cache for the first `lines` 64-byte lines of `run` (no more than it holds): a hint
/// with no effect on results.
#[inline(always)]
pub(super) fn prefetch_lines<T>(run: &[T], lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let bytes = std::mem::size_of_val(run);
        let start = run.as_ptr() as *const i8;
        for line in 0..lines.min(bytes.div_ceil(64)) {
            // SAFETY: a prefetch never faults, and the address is inside `run` anyway.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(line * 64)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (run, lines);
}

/// Sum of squared differences of the first K projection bytes (|difference| <= 255).
#[inline(always)]
pub(super) fn squared_distance<const K: usize>(q: &Projection, stored: &[u8]) -> u32 {
    let stored: &[u8; K] = stored.try_into().unwrap();
    let mut d = 0i32;
    for j in 0..K {
        let diff = q[j] - stored[j] as i16;
        d += diff as i32 * diff as i32;
    }
    d as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::uniforms::ExemplarFields;

    /// The 16-bit multiply-add projection equals the scalar i32 sums, extreme values included.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn madd_projection_equals_the_scalar_sums() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut seed = 0x9E37_79B9u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for (channels, outputs) in [(3usize, 8usize), (4, 8), (3, 12), (4, 12), (4, 16)] {
            for round in 0..50 {
                let d = 25 * channels;
                // Row-major outputs x inputs, as the level data stores them; extremes first.
                let weights: Vec<i32> = (0..outputs * d)
                    .map(|i| match (round, i % 3) {
                        (0, _) => 32767,
                        (1, _) => -32768,
                        _ => (next() % 65536) as i32 - 32768,
                    })
                    .collect();
                let means: Vec<i32> = (0..d)
                    .map(|_| {
                        if round < 2 {
                            255
                        } else {
                            (next() % 256) as i32
                        }
                    })
                    .collect();
                let words: [u32; 25] = std::array::from_fn(|_| if round < 2 { 0 } else { next() });
                let mut level = Vec::new();
                level.extend(weights.iter().map(|&w| w as u32));
                level.extend(means.iter().map(|&m| m as u32));
                let p = CorrectParams {
                    ex: ExemplarFields {
                        channels: channels as u32,
                        pixel_words: 1,
                        ..Default::default()
                    },
                    pca_in: d as u32,
                    pca_out: outputs as u32,
                    weights0: 0,
                    weights1: 0,
                    weights2: 0,
                    mean0: (outputs * d) as u32,
                    mean1: (outputs * d) as u32,
                    mean2: (outputs * d) as u32,
                    ..Default::default()
                };
                let pairs = PairWeights::new(&p, &level).expect("16-bit weights");
                if round == 2 {
                    // A weight beyond 16 bits (an analysis older than revision 2) keeps the
                    // scalar path.
                    let mut wide = level.clone();
                    wide[d + 1] = 40_000;
                    assert!(PairWeights::new(&p, &wide).is_none());
                }
                // SAFETY: AVX2 detected above.
                let got = unsafe {
                    if outputs <= 8 {
                        project_plane_madd::<1>(&words, &pairs.weights[0], &pairs.means[0])
                    } else {
                        project_plane_madd::<2>(&words, &pairs.weights[0], &pairs.means[0])
                    }
                };
                for j in 0..outputs {
                    let mut want = 0i32;
                    for (pixel, &word) in words.iter().enumerate() {
                        for ch in 0..channels {
                            let i = pixel * channels + ch;
                            let value = ((word >> (ch * 8)) & 0xFF) as i32;
                            want = want
                                .wrapping_add((value - means[i]).wrapping_mul(weights[j * d + i]));
                        }
                    }
                    assert_eq!(
                        got[j], want,
                        "{channels} channels, {outputs} outputs, round {round}, output {j}"
                    );
                }
            }
        }
    }
}
