//! PCA of exemplar patch vectors in floating point, for the nearest-patch search of gradient
//! solid synthesis (paper 4.2.1: "a PCA projection of the matching vectors ... reduces
//! dimensions from hundreds to 10-20").
//!
//! Patch vectors have up to 21 x 21 x 3 = 1323 dimensions, too many for a dense eigen
//! decomposition per level, and only the leading components are wanted: block subspace
//! iteration on a strided subsample, then a Rayleigh-Ritz step to order the components.
//! Everything is seeded and sequential in its reductions, so the basis is the same on every run.

use crate::util::hash::SeededRng;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// Kept dimensions: the dimensionality of the nearest-patch search.
pub const KEPT: usize = 16;
/// Patches used to fit the basis (evenly strided over all of them).
pub const MAX_SAMPLES: usize = 1500;
/// Subspace iterations (the spectrum of image patches decays fast: a handful converge).
const ITERATIONS: usize = 8;

/// `x q`, its two halves of rows on two threads (the fit's products are its whole cost, and
/// otherwise serial).
fn product(x: &DMatrix<f64>, q: &DMatrix<f64>) -> DMatrix<f64> {
    let half = x.nrows() / 2;
    let (top, bottom) = rayon::join(
        || x.rows(0, half) * q,
        || x.rows(half, x.nrows() - half) * q,
    );
    DMatrix::from_fn(x.nrows(), q.ncols(), |i, j| {
        if i < half {
            top[(i, j)]
        } else {
            bottom[(i - half, j)]
        }
    })
}

/// `x^T z` without transposing `x`, its two halves of columns on two threads.
fn transposed_product(x: &DMatrix<f64>, z: &DMatrix<f64>) -> DMatrix<f64> {
    let half = x.ncols() / 2;
    let (top, bottom) = rayon::join(
        || x.columns(0, half).tr_mul(z),
        || x.columns(half, x.ncols() - half).tr_mul(z),
    );
    DMatrix::from_fn(x.ncols(), z.ncols(), |i, j| {
        if i < half {
            top[(i, j)]
        } else {
            bottom[(i - half, j)]
        }
    })
}

/// A fitted projection: `mean` and `KEPT` orthonormal rows of `dims` values.
#[derive(Clone, Debug)]
pub struct PatchPca {
    pub dims: usize,
    pub mean: Vec<f32>,
    /// KEPT x dims, row-major, rows by decreasing variance.
    pub basis: Vec<f32>,
    /// Fraction of the sample variance the kept rows capture.
    pub energy_kept: f64,
    /// The basis transposed (dims x KEPT) and B mean: what `project` reads.
    basis_t: Vec<f32>,
    bias: [f32; KEPT],
}

impl PatchPca {
    /// Fit to `vectors` (`dims` values each).
    pub fn fit(vectors: &[f32], dims: usize, seed: u64) -> PatchPca {
        let count = vectors.len() / dims;
        assert!(count > 0, "no patch vectors");
        let stride = count.div_ceil(MAX_SAMPLES).max(1);
        let rows: Vec<&[f32]> = vectors.chunks_exact(dims).step_by(stride).collect();
        let mut mean = vec![0f64; dims];
        for r in &rows {
            for (m, &v) in mean.iter_mut().zip(r.iter()) {
                *m += v as f64;
            }
        }
        mean.iter_mut().for_each(|m| *m /= rows.len() as f64);
        let x = DMatrix::<f64>::from_fn(rows.len(), dims, |i, j| rows[i][j] as f64 - mean[j]);
        let total: f64 = x.iter().map(|v| v * v).sum();
        let keep = KEPT.min(dims).min(rows.len());

        let mut rng = SeededRng::new(seed);
        let mut q = DMatrix::<f64>::from_fn(dims, keep, |_, _| {
            (rng.below(1 << 20) as f64 / (1 << 19) as f64) - 1.0
        });
        for _ in 0..ITERATIONS {
            let z = product(&x, &q);
            q = transposed_product(&x, &z);
            q = q.qr().q();
        }
        // Rayleigh-Ritz: order (and rotate) the subspace's directions by variance.
        let xq = &x * &q;
        let small = xq.transpose() * &xq;
        let eig = SymmetricEigen::new(small);
        let mut order: Vec<usize> = (0..keep).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let kept_variance: f64 = eig.eigenvalues.iter().map(|v| v.max(0.0)).sum();
        let rotated = &q * &eig.eigenvectors;
        let mut basis = vec![0f32; KEPT * dims];
        for (row, &k) in order.iter().enumerate() {
            for j in 0..dims {
                basis[row * dims + j] = rotated[(j, k)] as f32;
            }
        }
        let mean: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
        let basis_t = (0..dims * KEPT)
            .map(|i| basis[(i % KEPT) * dims + i / KEPT])
            .collect();
        let bias = std::array::from_fn(|k| {
            let row = &basis[k * dims..(k + 1) * dims];
            row.iter().zip(&mean).map(|(w, m)| w * m).sum()
        });
        PatchPca {
            dims,
            mean,
            basis,
            energy_kept: if total > 0.0 {
                (kept_variance / total).min(1.0)
            } else {
                1.0
            },
            basis_t,
            bias,
        }
    }

    /// basis . mean, which [`Self::project`] subtracts.
    pub fn bias(&self) -> &[f32; KEPT] {
        &self.bias
    }

    /// The KEPT coordinates of `v` (rows beyond the fitted ones, for tiny inputs, stay 0).
    /// Written as sum_j v_j B_j - B mean with B transposed so the inner loop runs over the 16
    /// output lanes (vectorizes; this is the hot loop of the patch search).
    #[inline(always)]
    pub fn project(&self, v: &[f32]) -> [f32; KEPT] {
        let mut acc = [0f32; KEPT];
        for (x, column) in v.iter().zip(self.basis_t.chunks_exact(KEPT)) {
            for (a, w) in acc.iter_mut().zip(column) {
                *a += w * x;
            }
        }
        std::array::from_fn(|k| acc[k] - self.bias[k])
    }

    /// The projections of `count` vectors that `fill(i, buffer)` writes one at a time (none is
    /// kept: 62 MB for the finest level's patches), in parallel and compiled for AVX2 when the
    /// CPU has it (the same operations in the same order either way, so the same floats).
    pub fn project_each(
        &self,
        count: usize,
        fill: impl Fn(usize, &mut Vec<f32>) + Sync,
    ) -> Vec<[f32; KEPT]> {
        #[inline(always)]
        fn run(
            pca: &PatchPca,
            range: std::ops::Range<usize>,
            fill: &(impl Fn(usize, &mut Vec<f32>) + Sync),
        ) -> Vec<[f32; KEPT]> {
            let mut buffer = Vec::with_capacity(pca.dims);
            range
                .map(|i| {
                    buffer.clear();
                    fill(i, &mut buffer);
                    pca.project(&buffer)
                })
                .collect()
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        fn run_avx2(
            pca: &PatchPca,
            range: std::ops::Range<usize>,
            fill: &(impl Fn(usize, &mut Vec<f32>) + Sync),
        ) -> Vec<[f32; KEPT]> {
            run(pca, range, fill)
        }
        const CHUNK: usize = 64;
        (0..count.div_ceil(CHUNK))
            .into_par_iter()
            .flat_map_iter(|c| {
                let range = c * CHUNK..((c + 1) * CHUNK).min(count);
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2 (checked just above).
                    return unsafe { run_avx2(self, range, &fill) };
                }
                run(self, range, &fill)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_dominant_directions_of_low_rank_data() {
        // Points on a 3D subspace of R^40 plus tiny noise: 3 components carry the energy, and
        // projection preserves distances between points of the subspace.
        let dims = 40;
        let mut rng = SeededRng::new(7);
        let dirs: Vec<Vec<f32>> = (0..3)
            .map(|_| (0..dims).map(|_| rng.below(200) as f32 - 100.0).collect())
            .collect();
        let mut data = Vec::new();
        for _ in 0..500 {
            let c: Vec<f32> = (0..3).map(|_| rng.below(100) as f32 / 50.0 - 1.0).collect();
            for j in 0..dims {
                data.push(5.0 + (0..3).map(|k| c[k] * dirs[k][j]).sum::<f32>());
            }
        }
        let pca = PatchPca::fit(&data, dims, 1);
        assert!(pca.energy_kept > 0.999, "{}", pca.energy_kept);
        let (a, b) = (&data[0..dims], &data[dims..2 * dims]);
        let full: f32 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
        let (pa, pb) = (pca.project(a), pca.project(b));
        let reduced: f32 = pa.iter().zip(&pb).map(|(x, y)| (x - y).powi(2)).sum();
        assert!((full - reduced).abs() < 1e-3 * full, "{full} vs {reduced}");
    }
}
