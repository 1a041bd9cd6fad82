//! PCA of neighbourhood vectors and its exact fixed-point form.
//!
//! The projection that synthesis compares neighbourhoods with must be bit-identical on the GPU and
//! the CPU, so it is integer arithmetic: for a neighbourhood x (u8 values),
//!   acc_j = sum_i (x_i - mean_i) * weight_ji          (i32; never overflows, see `choose_shift`)
//!   q_j   = clamp(((acc_j + 2^(F-1)) >> F) + 128, 0, 255)
//! where weight_ji = round(B_ji * w_i * s * 2^F): B is the orthonormal PCA basis, w_i the channel
//! weight (feature channel), s one scale for all kept dimensions (so distances stay isotropic:
//! squared distances between q vectors approximate s^2 times the weighted squared L2 distance of
//! the neighbourhoods) chosen so the exemplar's projections fill the 8-bit range.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, SymmetricEigen};

pub use crate::contract::pca::PcaBasis;

impl PcaBasis {
    /// Fraction of the variance captured by the kept dimensions.
    pub fn energy_kept(&self) -> f64 {
        let total: f64 = self.eigenvalues.iter().map(|&v| v.max(0.0) as f64).sum();
        if total <= 0.0 {
            return 1.0;
        }
        let kept: f64 = self.eigenvalues[..self.output_dims as usize]
            .iter()
            .map(|&v| v.max(0.0) as f64)
            .sum();
        kept / total
    }

    /// Bytes per projected vector rounded up to whole u32 words (the GPU packing).
    pub fn words_per_vector(&self) -> u32 {
        self.output_dims.div_ceil(4)
    }

    /// Structural sanity (used when loading a file).
    pub fn validate(&self) -> std::result::Result<(), String> {
        let (d, k) = (self.input_dims as usize, self.output_dims as usize);
        if !(1..=16).contains(&k) || d == 0 || d > 25 * 8 || k > d {
            return Err(format!("PCA dims {k} of {d} out of range"));
        }
        if self.mean.len() != d || self.weights.len() != d * k || self.eigenvalues.len() != d {
            return Err("PCA array lengths do not match its dimensions".into());
        }
        if !(1..=24).contains(&self.shift) {
            return Err(format!("PCA shift {} out of range", self.shift));
        }
        let bound = max_abs_accumulator(&self.weights, d, k);
        if bound > i32::MAX as i64 {
            return Err("PCA weights could overflow the i32 accumulator".into());
        }
        Ok(())
    }
}

/// Largest |acc_j| possible for inputs in 0..=255 and means in 0..=255.
fn max_abs_accumulator(weights: &[i32], d: usize, k: usize) -> i64 {
    (0..k)
        .map(|j| {
            weights[j * d..(j + 1) * d]
                .iter()
                .map(|&w| (w as i64).abs() * 255)
                .sum::<i64>()
        })
        .max()
        .unwrap_or(0)
}

/// Fit a PCA basis to `vectors` (each `dims` u8 values; at most `max_samples` of them used,
/// evenly strided), keeping `keep` dimensions. `channel_weight[i]` scales input i.
pub fn fit(
    vectors: &[u8],
    dims: usize,
    keep: usize,
    channel_weight: &[f32],
    max_samples: usize,
) -> Result<PcaBasis> {
    assert_eq!(channel_weight.len(), dims);
    let count = vectors.len() / dims;
    if count == 0 {
        return Err(Error::invalid("exemplar", "no neighbourhoods to analyse"));
    }
    let keep = keep.min(dims);
    let stride = count.div_ceil(max_samples.max(1)).max(1);
    let samples: Vec<&[u8]> = vectors.chunks_exact(dims).step_by(stride).collect();
    let n = samples.len() as f64;

    let mut mean = vec![0f64; dims];
    for s in &samples {
        for (m, &v) in mean.iter_mut().zip(s.iter()) {
            *m += v as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mean_int: Vec<i32> = mean.iter().map(|m| m.round() as i32).collect();

    // Weighted, centred (on the integer mean, as the kernel does) covariance.
    let mut cov = DMatrix::<f64>::zeros(dims, dims);
    let mut centred = vec![0f64; dims];
    for s in &samples {
        for i in 0..dims {
            centred[i] = (s[i] as f64 - mean_int[i] as f64) * channel_weight[i] as f64;
        }
        for i in 0..dims {
            let ci = centred[i];
            if ci == 0.0 {
                continue;
            }
            for j in i..dims {
                cov[(i, j)] += ci * centred[j];
            }
        }
    }
    for i in 0..dims {
        for j in i..dims {
            let v = cov[(i, j)] / n;
            cov[(i, j)] = v;
            cov[(j, i)] = v;
        }
    }
    let eig = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..dims).collect();
    order.sort_by(|&a, &b| {
        eig.eigenvalues[b]
            .partial_cmp(&eig.eigenvalues[a])
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.cmp(&b))
    });
    // Basis rows with a fixed sign convention (largest component positive) for reproducibility.
    let mut basis = vec![0f64; keep * dims];
    for (j, &col) in order.iter().take(keep).enumerate() {
        let v = eig.eigenvectors.column(col);
        let big = v
            .iter()
            .cloned()
            .fold(0f64, |acc, x| if x.abs() > acc.abs() { x } else { acc });
        let sign = if big < 0.0 { -1.0 } else { 1.0 };
        for i in 0..dims {
            basis[j * dims + i] = sign * v[i] * channel_weight[i] as f64;
        }
    }
    // One scale for all kept dimensions so the largest projection maps to +-127.
    let mut max_abs = 0f64;
    for s in &samples {
        for j in 0..keep {
            let mut y = 0f64;
            for i in 0..dims {
                y += (s[i] as f64 - mean_int[i] as f64) * basis[j * dims + i];
            }
            max_abs = max_abs.max(y.abs());
        }
    }
    let scale = if max_abs > 0.0 { 127.0 / max_abs } else { 1.0 };
    let (shift, weights) = choose_shift(&basis, dims, keep, scale);
    let eigenvalues = order.iter().map(|&c| eig.eigenvalues[c] as f32).collect();
    Ok(PcaBasis {
        input_dims: dims as u32,
        output_dims: keep as u32,
        shift,
        mean: mean_int,
        weights,
        eigenvalues,
    })
}

/// The largest shift F <= 20 whose fixed-point weights fit 16 bits and cannot overflow an i32
/// accumulator. 16-bit weights let the CPU backend project with 16-bit multiply-adds (two
/// products per 32-bit lane, the same exact sums); they still carry 15 bits of precision for
/// 8-bit projections.
fn choose_shift(basis: &[f64], dims: usize, keep: usize, scale: f64) -> (u32, Vec<i32>) {
    for shift in (1..=20u32).rev() {
        let f = scale * (1u64 << shift) as f64;
        let weights: Vec<i32> = basis
            .iter()
            .map(|&b| (b * f).round().clamp(i32::MIN as f64, i32::MAX as f64) as i32)
            .collect();
        let fits_16_bits = weights.iter().all(|&w| i16::try_from(w).is_ok());
        if fits_16_bits
            && max_abs_accumulator(&weights, dims, keep) + (1 << shift) <= i32::MAX as i64
        {
            return (shift, weights);
        }
    }
    let weights = basis
        .iter()
        .map(|&b| (b * scale * 2.0).round() as i32)
        .collect();
    (1, weights)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::project::project_vector;
    use crate::util::hash::SeededRng;

    #[test]
    fn quantized_distances_track_true_distances() {
        // Vectors on a 3-dimensional subspace of a 20-dim space: PCA with 3 dims loses nothing,
        // so quantized squared distances must be proportional to the true ones (up to rounding).
        let mut rng = SeededRng::new(5);
        let dims = 20;
        let dirs: Vec<Vec<f64>> = (0..3)
            .map(|_| {
                (0..dims)
                    .map(|_| (rng.below(200) as f64 - 100.0) / 100.0)
                    .collect()
            })
            .collect();
        let mut data = Vec::new();
        for _ in 0..500 {
            let c: Vec<f64> = (0..3).map(|_| rng.below(60) as f64 - 30.0).collect();
            for i in 0..dims {
                let v = 128.0 + (0..3).map(|k| c[k] * dirs[k][i]).sum::<f64>();
                data.push(v.round().clamp(0.0, 255.0) as u8);
            }
        }
        let pca = fit(&data, dims, 3, &vec![1.0; dims], 10_000).unwrap();
        assert!(pca.energy_kept() > 0.99, "energy {}", pca.energy_kept());
        let proj: Vec<[u8; 3]> = data
            .chunks_exact(dims)
            .map(|x| {
                let mut o = [0u8; 3];
                project_vector(&pca, x, &mut o);
                o
            })
            .collect();
        let mut ratios = Vec::new();
        for i in 0..100 {
            let (a, b) = (i, 499 - i);
            let t: f64 = (0..dims)
                .map(|k| (data[a * dims + k] as f64 - data[b * dims + k] as f64).powi(2))
                .sum();
            let q: f64 = (0..3)
                .map(|k| (proj[a][k] as f64 - proj[b][k] as f64).powi(2))
                .sum();
            if t > 2000.0 {
                ratios.push(q / t);
            }
        }
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        for r in &ratios {
            assert!((r / mean - 1.0).abs() < 0.2, "ratio {r} vs mean {mean}");
        }
    }
}
