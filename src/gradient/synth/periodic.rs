//! The solid being synthesized: m^3 control points of a periodic gradient solid, their
//! wrapped addressing and the first-order evaluation the slices are sampled with.

use super::super::{GradientSolid, SPACING};
use crate::error::Result;
use crate::exemplar::Image;
use crate::util::hash::{mix64, SeededRng};

/// `v` modulo `period` in [0, period): `rem_euclid` without its division for the values within
/// one period of the domain (nearly all: slices reach a few voxels beyond it). Hot: every
/// sample of every slice goes through it.
#[inline(always)]
pub fn wrap(v: i64, period: i64) -> i64 {
    if (0..period).contains(&v) {
        v
    } else if (-period..0).contains(&v) {
        v + period
    } else if (period..2 * period).contains(&v) {
        v - period
    } else {
        v.rem_euclid(period)
    }
}

/// The solid being synthesized: m^3 control points, periodic (point m is point 0).
#[derive(Clone, Debug, PartialEq)]
pub struct PeriodicSolid {
    pub m: u32,
    pub channels: usize,
    /// Per point (x fastest), per channel: f, df/dx, df/dy, df/dz (per voxel).
    pub data: Vec<f32>,
}

impl PeriodicSolid {
    /// Period in voxels.
    pub fn period(&self) -> i64 {
        (SPACING * self.m) as i64
    }

    /// Offset of the values of control point `p` (any integers: wrapped).
    #[inline(always)]
    pub fn offset(&self, p: [i64; 3]) -> usize {
        let m = self.m as i64;
        // Not `p.map(..)`: its closure is compiled out of line, without the caller's AVX2.
        let (x, y, z) = (wrap(p[0], m), wrap(p[1], m), wrap(p[2], m));
        ((z * m + y) * m + x) as usize * self.channels * 4
    }

    /// The control point nearest to voxel `q` (ties, at half spacing, to the upper one: the
    /// nearest point's voxels are offsets -2..=1 from it) and the offset of `q` from it.
    pub fn nearest_point(q: [i64; 3]) -> ([i64; 3], [i64; 3]) {
        let d = SPACING as i64;
        let c = q.map(|v| (v + d / 2).div_euclid(d));
        (c, std::array::from_fn(|a| q[a] - c[a] * d))
    }

    /// First-order Taylor evaluation at voxel `q` (4.2.4): f_c + grad f_c . (q - c) about the
    /// nearest control point c.
    pub fn taylor(&self, q: [i64; 3], out: &mut [f32]) {
        let (c, delta) = Self::nearest_point(q);
        let base = self.offset(c);
        let t = delta.map(|v| v as f32);
        for (k, o) in out.iter_mut().enumerate().take(self.channels) {
            let v = &self.data[base + k * 4..base + k * 4 + 4];
            *o = v[0] + v[1] * t[0] + v[2] * t[1] + v[3] * t[2];
        }
    }

    /// Standard deviation of the point values (all channels): a collapse to a flat solid shows.
    pub fn value_spread(&self) -> f64 {
        let values: Vec<f64> = self.data.iter().step_by(4).map(|&v| v as f64).collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt()
    }

    /// Histogram matching of the point values, per channel, to `target` (per channel, sorted
    /// ascending): the point of rank r takes the target's quantile (r + 0.5) / n. Gradients are
    /// scaled by the slope of that monotone map around the point's rank, so the interpolated
    /// solid keeps its shape. Ties rank by point index (deterministic).
    pub fn match_histogram(&mut self, target: &[Vec<u8>]) {
        let n = (self.m as usize).pow(3);
        let per = self.channels * 4;
        for (c, target) in target.iter().enumerate().take(self.channels) {
            if target.is_empty() {
                continue;
            }
            let value = |i: usize| self.data[i * per + c * 4];
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&a, &b| value(a).total_cmp(&value(b)).then(a.cmp(&b)));
            let quantile = |r: usize| {
                let t = ((r as f64 + 0.5) / n as f64 * target.len() as f64) as usize;
                target[t.min(target.len() - 1)] as f32
            };
            let k = (n / 64).max(1);
            let mapped: Vec<(f32, f32)> = (0..n)
                .map(|r| {
                    let (lo, hi) = (r.saturating_sub(k), (r + k).min(n - 1));
                    let run = value(order[hi]) - value(order[lo]);
                    let slope = if run > 1e-3 {
                        ((quantile(hi) - quantile(lo)) / run).clamp(0.0, 4.0)
                    } else {
                        1.0
                    };
                    (quantile(r), slope)
                })
                .collect();
            for (r, &i) in order.iter().enumerate() {
                let v = &mut self.data[i * per + c * 4..i * per + c * 4 + 4];
                v[0] = mapped[r].0;
                for g in &mut v[1..4] {
                    *g *= mapped[r].1;
                }
            }
        }
    }

    /// Random initialization (4.1): each point takes a random exemplar pixel, gradients zero.
    pub fn random(m: u32, exemplar: &Image, seed: u64) -> PeriodicSolid {
        let channels = exemplar.channels as usize;
        let mut rng = SeededRng::new(mix64(seed ^ 0x1a17_0000));
        let n = (m as usize).pow(3);
        let mut data = vec![0f32; n * channels * 4];
        for point in data.chunks_exact_mut(channels * 4) {
            let p = rng.below(exemplar.pixel_count() as u64) as usize;
            for k in 0..channels {
                point[k * 4] = exemplar.pixels[p * channels + k] as f32;
            }
        }
        PeriodicSolid { m, channels, data }
    }

    /// The gradient solid with m + 1 points per axis (last face = first): covers [0, P]^3 and
    /// tiles with period P.
    pub fn to_gradient_solid(&self) -> Result<GradientSolid> {
        let n = self.m + 1;
        let mut out = GradientSolid::new([n; 3], self.channels as u32)?;
        let per = self.channels * 4;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let src = self.offset([x as i64, y as i64, z as i64]);
                    let dst = out.point_index([x, y, z]) * per;
                    out.data[dst..dst + per].copy_from_slice(&self.data[src..src + per]);
                }
            }
        }
        Ok(out.into_periodic())
    }
}
