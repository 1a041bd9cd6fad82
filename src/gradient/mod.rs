//! Gradient solid textures (Zhang, Lai, Hu; section 3): a control grid of n^3 points at spacing
//! d = 4 voxels, each holding a feature vector f and its three gradients, interpolated
//! tricubically inside each cube.
//!
//! The paper's interpolant is Lekien-Marsden's with zero higher derivatives (cross derivatives
//! f_uv, f_uw, f_vw, f_uvw set to 0). Lekien-Marsden's 64x64 matrix is the tensor-product cubic
//! Hermite interpolant written in monomial form, so with those terms zero the value at local
//! parameters (u, v, w) in [0, 1]^3 of a cube is, over its 8 corners c:
//!   sum_c H_c(u) H_c(v) H_c(w) f_c + d G_c(u) H_c(v) H_c(w) f_x,c + (likewise for y, z)
//! with H_0 = 2t^3 - 3t^2 + 1, H_1 = 3t^2 - 2t^3, G_0 = t^3 - 2t^2 + t, G_1 = t^3 - t^2, and
//! gradients in per-voxel units (hence the factor d). These are the paper's 32 weights per sample.
//! C^1 across cubes and exact on linear fields (both tested).
//!
//! Control point (i, j, k) sits at voxel position d (i, j, k); a solid of n points per axis covers
//! positions [0, d (n - 1)]. Positions outside are clamped to the domain by the kernel; a
//! periodic solid's renders wrap them into its period first ([`file::GradientFile`]).

pub mod detail;
pub mod edit;
pub mod file;
pub mod format;
pub mod regions;
pub mod render;
pub mod synth;
pub mod vectorize;

pub use crate::contract::tricubic::{
    hermite_g, hermite_h, quantize, GradientSolid, Query, SPACING,
};
use crate::error::{Error, Result};

/// Sub-positions per cube edge of the weight table (the paper's 33: 1/8 voxel at d = 4).
pub const TABLE_SAMPLES: usize = 33;

impl GradientSolid {
    pub fn new(dims: [u32; 3], channels: u32) -> Result<GradientSolid> {
        if dims.iter().any(|&d| d < 2) || channels == 0 || channels > 16 {
            return Err(Error::invalid(
                "gradient solid",
                format!("needs at least 2 control points per axis and 1..=16 channels, got {dims:?} x {channels}"),
            ));
        }
        let n = dims.iter().map(|&d| d as usize).product::<usize>();
        Ok(GradientSolid {
            dims,
            channels,
            data: vec![0.0; n * channels as usize * 4],
            detail: 0,
            size: dims.map(|n| SPACING * (n - 1) + 1),
            periodic: false,
        })
    }

    /// The same control grid made periodic: period d (n - 1) per axis, the last face of points
    /// being the first's (as synthesis makes them).
    pub fn into_periodic(mut self) -> GradientSolid {
        self.size = self.dims.map(|n| SPACING * (n - 1));
        self.periodic = true;
        self
    }

    /// Voxels per axis covered: d (n - 1) + 1.
    pub fn extent(&self) -> [u32; 3] {
        self.dims.map(|n| SPACING * (n - 1) + 1)
    }

    pub fn point_index(&self, p: [u32; 3]) -> usize {
        ((p[2] as usize * self.dims[1] as usize) + p[1] as usize) * self.dims[0] as usize
            + p[0] as usize
    }

    /// The 4 values (f, fx, fy, fz) of channel `c` at control point `p`.
    pub fn at(&self, p: [u32; 3], c: u32) -> &[f32] {
        let i = (self.point_index(p) * self.channels as usize + c as usize) * 4;
        &self.data[i..i + 4]
    }

    pub fn at_mut(&mut self, p: [u32; 3], c: u32) -> &mut [f32] {
        let i = (self.point_index(p) * self.channels as usize + c as usize) * 4;
        &mut self.data[i..i + 4]
    }

    /// The cube containing position `x` (clamped to the domain) and the local parameters.
    pub fn locate(&self, x: [f32; 3]) -> ([u32; 3], [f32; 3]) {
        let mut cube = [0u32; 3];
        let mut t = [0f32; 3];
        for a in 0..3 {
            let max = (SPACING * (self.dims[a] - 1)) as f32;
            let s = x[a].clamp(0.0, max) / SPACING as f32;
            let c = (s.floor() as u32).min(self.dims[a] - 2);
            cube[a] = c;
            t[a] = s - c as f32;
        }
        (cube, t)
    }

    /// Exact evaluation of all channels at voxel-space position `x` into `out`.
    pub fn eval(&self, x: [f32; 3], out: &mut [f32]) {
        let (cube, t) = self.locate(x);
        self.eval_in(cube, t, out);
    }

    /// Evaluation inside a given cube at local parameters `t` (may be 0 or 1: a face).
    pub fn eval_in(&self, cube: [u32; 3], t: [f32; 3], out: &mut [f32]) {
        self.combine(cube, &weights(t), out);
    }

    /// Evaluation through a weight table (nearest tabulated sub-position).
    pub fn eval_table(&self, table: &WeightTable, x: [f32; 3], out: &mut [f32]) {
        let (cube, t) = self.locate(x);
        self.combine(cube, table.nearest(t), out);
    }

    /// sum over corners and (f, fx, fy, fz) of weight * value.
    fn combine(&self, cube: [u32; 3], w: &[f32; 32], out: &mut [f32]) {
        out.iter_mut().for_each(|o| *o = 0.0);
        for corner in 0..8u32 {
            let p = [
                cube[0] + (corner & 1),
                cube[1] + ((corner >> 1) & 1),
                cube[2] + (corner >> 2),
            ];
            let base = self.point_index(p) * self.channels as usize * 4;
            let cw = &w[corner as usize * 4..corner as usize * 4 + 4];
            for (c, o) in out.iter_mut().enumerate().take(self.channels as usize) {
                let v = &self.data[base + c * 4..base + c * 4 + 4];
                *o += cw[0] * v[0] + cw[1] * v[1] + cw[2] * v[2] + cw[3] * v[3];
            }
        }
    }
}

/// The 32 weights (corner-major: corner bit 0 = x, 1 = y, 2 = z; then f, fx, fy, fz) at local
/// parameters `t` in [0, 1]^3, gradients in per-voxel units.
pub fn weights(t: [f32; 3]) -> [f32; 32] {
    let (h, g) = (hermite_h, hermite_g);
    let mut w = [0f32; 32];
    for corner in 0..8u32 {
        let c = [corner & 1, (corner >> 1) & 1, corner >> 2];
        let hx = h(c[0], t[0]);
        let hy = h(c[1], t[1]);
        let hz = h(c[2], t[2]);
        let i = corner as usize * 4;
        w[i] = hx * hy * hz;
        w[i + 1] = g(c[0], t[0]) * hy * hz;
        w[i + 2] = hx * g(c[1], t[1]) * hz;
        w[i + 3] = hx * hy * g(c[2], t[2]);
    }
    w
}

/// The paper's precomputed weights at 33^3 sub-positions of a cube (4.6 MB of f32).
pub struct WeightTable {
    weights: Vec<[f32; 32]>,
}

impl Default for WeightTable {
    fn default() -> Self {
        Self::new()
    }
}

impl WeightTable {
    pub fn new() -> WeightTable {
        let n = TABLE_SAMPLES;
        let step = 1.0 / (n - 1) as f32;
        let mut weights = Vec::with_capacity(n * n * n);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    weights.push(self::weights([
                        i as f32 * step,
                        j as f32 * step,
                        k as f32 * step,
                    ]));
                }
            }
        }
        WeightTable { weights }
    }

    fn nearest(&self, t: [f32; 3]) -> &[f32; 32] {
        let n = TABLE_SAMPLES;
        let idx = t.map(|v| ((v * (n - 1) as f32).round() as usize).min(n - 1));
        &self.weights[(idx[2] * n + idx[1]) * n + idx[0]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear_solid() -> (GradientSolid, [f32; 4]) {
        // f = 3 + 0.5 x - 2 y + 1.25 z, gradients constant.
        let coef = [3.0f32, 0.5, -2.0, 1.25];
        let mut s = GradientSolid::new([4, 3, 5], 1).unwrap();
        for k in 0..5 {
            for j in 0..3 {
                for i in 0..4 {
                    let x = [i, j, k].map(|v| (v * SPACING) as f32);
                    let v = s.at_mut([i, j, k], 0);
                    v[0] = coef[0] + coef[1] * x[0] + coef[2] * x[1] + coef[3] * x[2];
                    v[1] = coef[1];
                    v[2] = coef[2];
                    v[3] = coef[3];
                }
            }
        }
        (s, coef)
    }

    #[test]
    fn linear_fields_are_reproduced_exactly() {
        let (s, c) = linear_solid();
        let mut rng = crate::util::hash::SeededRng::new(2);
        let mut out = [0f32];
        for _ in 0..500 {
            let x = [12.0, 8.0, 16.0].map(|m: f32| rng.below(10_000) as f32 / 10_000.0 * m);
            s.eval(x, &mut out);
            let want = c[0] + c[1] * x[0] + c[2] * x[1] + c[3] * x[2];
            assert!((out[0] - want).abs() < 1e-4, "{x:?}: {} vs {want}", out[0]);
        }
    }

    #[test]
    fn interpolation_is_c1_across_cubes() {
        // Random control data: values and numerical gradients agree on both sides of a face.
        let mut s = GradientSolid::new([3, 3, 3], 1).unwrap();
        let mut rng = crate::util::hash::SeededRng::new(9);
        for v in s.data.iter_mut() {
            *v = rng.below(2000) as f32 / 100.0 - 10.0;
        }
        let f = |x: [f32; 3]| {
            let mut o = [0f32];
            s.eval(x, &mut o);
            o[0] as f64
        };
        let in_cube = |cube: [u32; 3], t: [f32; 3]| {
            let mut o = [0f32];
            s.eval_in(cube, t, &mut o);
            o[0] as f64
        };
        // The face x = 4 between cubes (0, cy, cz) and (1, cy, cz), seen from both sides: equal
        // values, and equal one-sided x derivatives (up to the O(h) of the differences).
        let h = 1e-2f32;
        for (cy, cz, ty, tz) in [(0, 0, 0.3f32, 0.7f32), (1, 1, 0.25, 0.5), (0, 1, 0.9, 0.1)] {
            let l = in_cube([0, cy, cz], [1.0, ty, tz]);
            let r = in_cube([1, cy, cz], [0.0, ty, tz]);
            assert!((l - r).abs() < 1e-4, "value jump {l} {r}");
            let gl = (l - in_cube([0, cy, cz], [1.0 - h, ty, tz])) / (h * SPACING as f32) as f64;
            let gr = (in_cube([1, cy, cz], [h, ty, tz]) - r) / (h * SPACING as f32) as f64;
            assert!((gl - gr).abs() < 0.2, "gradient jump {gl} {gr}");
        }
        // At a control point the value and gradient are the stored ones.
        let at = s.at([1, 1, 1], 0).to_vec();
        assert!((f([4.0, 4.0, 4.0]) - at[0] as f64).abs() < 1e-4);
        let e = 1e-2f32;
        let g = (f([4.0 + e, 4.0, 4.0]) - f([4.0 - e, 4.0, 4.0])) / (2.0 * e as f64);
        assert!((g - at[1] as f64).abs() < 0.02, "{g} vs {}", at[1]);
    }

    #[test]
    fn table_evaluation_is_close_to_exact() {
        let mut s = GradientSolid::new([3, 3, 3], 2).unwrap();
        let mut rng = crate::util::hash::SeededRng::new(4);
        for v in s.data.iter_mut() {
            *v = rng.below(256) as f32 - 128.0;
        }
        let table = WeightTable::new();
        let (mut a, mut b) = ([0f32; 2], [0f32; 2]);
        let mut worst = 0f32;
        for _ in 0..2000 {
            let x = [0; 3].map(|_| rng.below(8000) as f32 / 1000.0);
            s.eval(x, &mut a);
            s.eval_table(&table, x, &mut b);
            worst = worst.max((a[0] - b[0]).abs()).max((a[1] - b[1]).abs());
        }
        // Nearest of 33 sub-positions: within a few units on +-128 data; exact at the samples.
        assert!(worst < 20.0, "{worst}");
        s.eval([2.0, 1.0, 3.0], &mut a);
        s.eval_table(&table, [2.0, 1.0, 3.0], &mut b);
        assert!((a[0] - b[0]).abs() < 1e-3);
    }
}
