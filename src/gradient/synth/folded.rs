//! The PCA projection of an axis-aligned slice, folded over the solid's control points.
//!
//! A slice sample's value is the first-order Taylor evaluation about its nearest control point c
//! (4.2.4): f_c + grad f_c . (q - c). The projection is linear in the samples, so it is linear in
//! the control points' values and gradients: y = sum over the control points c the slice's
//! samples fall nearest to, over channels k, of
//!   (f_ck + t_w df_ck/dw) G0 + (df_ck/du) Gu + (df_ck/dv) Gv,
//! minus the PCA bias, where u and v are the slice's axes, w its normal (t_w, the check point's
//! offset from c along w, is the same for every sample), and G0, Gu, Gv are the sums, over the
//! samples nearest to c, of the basis rows of sample channel k weighted by 1, t_u and t_v. Which
//! samples are nearest to which point, and their offsets, depend only on the check point's
//! position in its control cell along u and v (4 x 4 patterns), so the sums are tabulated once
//! per level. A 21 x 21 slice (the finest level) then costs 7 x 7 points x 3 terms instead of
//! 441 samples' evaluation and projection: a third of the multiply-adds.
//!
//! The sums are the same as the sample-by-sample projection's, added in another order, so the
//! projections agree to float rounding (tested), not bit for bit. Where the samples lie exactly
//! one control spacing apart (the coarsest level) every point holds one sample and folding
//! saves nothing: there the samples are evaluated and projected one by one, without tables
//! (the same floats as the sample-by-sample projection, tested).

use super::pca::{PatchPca, KEPT};
use super::{PeriodicSolid, SPACING};

/// Tabulated sums for one level (patch size, sample spacing, channel count).
pub struct FoldedProjection {
    size: i64,
    spacing: i64,
    channels: usize,
    /// Control points per slice axis that some pattern's samples reach.
    slots: usize,
    /// Per pattern (cell position along u, then v: 16), per slot (v-major), per channel: the
    /// sums G0, Gu, Gv.
    sums: Vec<[[f32; KEPT]; 3]>,
    /// Samples exactly one control spacing apart (the coarsest level): each is nearest to a
    /// point of its own, at the same offset as every other, so folding saves nothing and its
    /// tables (three rows per sample and pattern, ~750 KB) only cost cache bandwidth. Then
    /// no tables: the basis column of every input (what `pca.project` reads, ~16 KB).
    columns: Option<Vec<[f32; KEPT]>>,
    bias: [f32; KEPT],
}

/// The control point a sample at voxel coordinate `q` is nearest to along one axis, and the
/// sample's offset from it (as [`PeriodicSolid::nearest_point`]).
fn nearest(q: i64) -> (i64, i64) {
    let d = SPACING as i64;
    let c = (q + d / 2).div_euclid(d);
    (c, q - c * d)
}

impl FoldedProjection {
    /// Tables for `size` x `size` slices of `channels` values per sample, `spacing` voxels
    /// apart, projected with `pca` (whose input is the samples row by row, channel fastest).
    pub fn new(pca: &PatchPca, size: u32, spacing: u32, channels: usize) -> FoldedProjection {
        let (n, s) = (size as i64, spacing as i64);
        let h = n / 2;
        let d = SPACING as i64;
        let first = |r: i64| nearest(r - s * h).0;
        let slots = (0..d)
            .map(|r| (nearest(r + s * h).0 - first(r) + 1) as usize)
            .max()
            .unwrap_or(1);
        let dims = (n * n) as usize * channels;
        assert_eq!(pca.dims, dims, "PCA input is the slice's samples");
        if s == d {
            let basis = |k: usize, input: usize| pca.basis.get(k * dims + input).copied();
            return FoldedProjection {
                size: n,
                spacing: s,
                channels,
                slots,
                sums: Vec::new(),
                columns: Some(
                    (0..dims)
                        .map(|input| std::array::from_fn(|k| basis(k, input).unwrap_or(0.0)))
                        .collect(),
                ),
                bias: *pca.bias(),
            };
        }
        let per_pattern = slots * slots * channels;
        let mut sums = vec![[[0f64; KEPT]; 3]; (d * d) as usize * per_pattern];
        for rv in 0..d {
            for ru in 0..d {
                let pattern = (rv * d + ru) as usize;
                for b in 0..n {
                    let (cv, tv) = nearest(rv + s * (b - h));
                    let j = (cv - first(rv)) as usize;
                    for a in 0..n {
                        let (cu, tu) = nearest(ru + s * (a - h));
                        let i = (cu - first(ru)) as usize;
                        for k in 0..channels {
                            let input = ((b * n + a) as usize) * channels + k;
                            let cell =
                                &mut sums[pattern * per_pattern + (j * slots + i) * channels + k];
                            for (out, row) in pca.basis.chunks_exact(dims).enumerate().take(KEPT) {
                                let w = row[input] as f64;
                                cell[0][out] += w;
                                cell[1][out] += w * tu as f64;
                                cell[2][out] += w * tv as f64;
                            }
                        }
                    }
                }
            }
        }
        FoldedProjection {
            size: n,
            spacing: s,
            channels,
            slots,
            sums: sums
                .iter()
                .map(|g| g.map(|row| row.map(|x| x as f32)))
                .collect(),
            columns: None,
            bias: *pca.bias(),
        }
    }

    /// The projection of the slice spanned by axes `u` (samples along a row) and `v` (rows)
    /// centred on voxel `p` of `solid`: what `pca.project` returns for the slice's samples,
    /// to float rounding.
    #[inline(always)]
    pub fn project(&self, solid: &PeriodicSolid, p: [i64; 3], u: usize, v: usize) -> [f32; KEPT] {
        debug_assert_eq!(solid.channels, self.channels);
        let w = 3 - u - v;
        let d = SPACING as i64;
        let h = self.size / 2;
        if let Some(columns) = &self.columns {
            return self.project_spaced(columns, solid, p, u, v);
        }
        let (cu0, _) = nearest(p[u] - self.spacing * h);
        let (cv0, _) = nearest(p[v] - self.spacing * h);
        let (cw, tw) = nearest(p[w]);
        let tw = tw as f32;
        let pattern = (p[v].rem_euclid(d) * d + p[u].rem_euclid(d)) as usize;
        let per_pattern = self.slots * self.slots * self.channels;
        let sums = &self.sums[pattern * per_pattern..(pattern + 1) * per_pattern];
        let mut acc = self.bias.map(|b| -b);
        let mut point = [0i64; 3];
        point[w] = cw;
        for j in 0..self.slots {
            point[v] = cv0 + j as i64;
            for i in 0..self.slots {
                point[u] = cu0 + i as i64;
                let base = solid.offset(point);
                for k in 0..self.channels {
                    let f = &solid.data[base + k * 4..base + k * 4 + 4];
                    let terms = [f[0] + f[1 + w] * tw, f[1 + u], f[1 + v]];
                    let g = &sums[(j * self.slots + i) * self.channels + k];
                    for (term, row) in terms.iter().zip(g) {
                        for (a, &x) in acc.iter_mut().zip(row) {
                            *a += term * x;
                        }
                    }
                }
            }
        }
        acc
    }

    /// [`Self::project`] for samples one control spacing apart: sample (a, b) is nearest to
    /// point (first + a, first + b) at the same offset t as the first, so each is evaluated
    /// there (as [`PeriodicSolid::taylor`] does, the same operations in the same order) and
    /// projected as `pca.project` does: the same floats as the sample-by-sample projection.
    #[inline(always)]
    fn project_spaced(
        &self,
        columns: &[[f32; KEPT]],
        solid: &PeriodicSolid,
        p: [i64; 3],
        u: usize,
        v: usize,
    ) -> [f32; KEPT] {
        let w = 3 - u - v;
        let h = self.size / 2;
        let mut first = [0i64; 3];
        let mut t = [0f32; 3];
        for (axis, start) in [
            (u, p[u] - self.spacing * h),
            (v, p[v] - self.spacing * h),
            (w, p[w]),
        ] {
            let (c, offset) = nearest(start);
            first[axis] = c;
            t[axis] = offset as f32;
        }
        let mut acc = [0f32; KEPT];
        let mut point = first;
        let mut column = columns.iter();
        for b in 0..self.size {
            point[v] = first[v] + b;
            for a in 0..self.size {
                point[u] = first[u] + a;
                let base = solid.offset(point);
                for k in 0..self.channels {
                    let f = &solid.data[base + k * 4..base + k * 4 + 4];
                    let value = f[0] + f[1] * t[0] + f[2] * t[1] + f[3] * t[2];
                    let weights = column.next().expect("a column per input");
                    for (sum, weight) in acc.iter_mut().zip(weights) {
                        *sum += weight * value;
                    }
                }
            }
        }
        std::array::from_fn(|k| acc[k] - self.bias[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folded projection equals sample-by-sample evaluation and projection, for every
    /// cell position, axis pair and level geometry, across the solid's wrap.
    #[test]
    fn folded_projection_equals_the_sample_by_sample_one() {
        let mut seed = 12345u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
        };
        let channels = 3;
        let m = 8u32;
        let solid = PeriodicSolid {
            m,
            channels,
            data: (0..(m * m * m) as usize * channels * 4)
                .map(|i| {
                    if i % 4 == 0 {
                        128.0 + 100.0 * rand()
                    } else {
                        20.0 * rand()
                    }
                })
                .collect(),
        };
        for (size, spacing) in [(21u32, 1u32), (11, 2), (9, 4), (5, 3)] {
            let dims = (size * size) as usize * channels;
            let vectors: Vec<f32> = (0..dims * 40).map(|_| 128.0 + 60.0 * rand()).collect();
            let pca = PatchPca::fit(&vectors, dims, 3);
            let folded = FoldedProjection::new(&pca, size, spacing, channels);
            let n = size as i64;
            let h = n / 2;
            let mut buffer = vec![0f32; dims];
            for (u, v) in [(1usize, 2usize), (2, 0), (0, 1)] {
                for pu in -5..9i64 {
                    for pv in [-3i64, 0, 2, 7, 31] {
                        let mut p = [3i64, 17, -6];
                        p[u] = pu;
                        p[v] = pv;
                        for b in 0..n {
                            for a in 0..n {
                                let mut q = p;
                                q[u] += spacing as i64 * (a - h);
                                q[v] += spacing as i64 * (b - h);
                                let at = ((b * n + a) as usize) * channels;
                                solid.taylor(q, &mut buffer[at..at + channels]);
                            }
                        }
                        let want = pca.project(&buffer);
                        assert!(want.iter().any(|x| x.abs() > 1.0), "a trivial projection");
                        let got = folded.project(&solid, p, u, v);
                        if spacing == SPACING {
                            // No folding at this spacing: the very same floats.
                            assert_eq!(got, want, "spacing {spacing} axes {u},{v} p {p:?}");
                        }
                        for k in 0..KEPT {
                            let tolerance = 1e-3 * (1.0 + want[k].abs());
                            assert!(
                                (got[k] - want[k]).abs() <= tolerance,
                                "size {size} spacing {spacing} axes {u},{v} p {p:?} dim {k}: {} vs {}",
                                got[k],
                                want[k]
                            );
                        }
                    }
                }
            }
        }
    }
}
