//! CPU reference of `wgsl/tricubic_eval.wgsl`: a gradient solid evaluated at the points of a
//! query, all channels per point, in f32 (the interpolant is derived in `gradient`).

use crate::contract::tricubic::{hermite_g, hermite_h, GradientSolid, SPACING};
pub use crate::contract::tricubic::{quantize, Query};
use rayon::prelude::*;

/// `channels` values per point of the query, in query order.
pub fn tricubic_eval(solid: &GradientSolid, query: &Query) -> Vec<f32> {
    if let Some(n) = cell_mode(solid, query) {
        return eval_cells(solid, n, |v| v);
    }
    let c = solid.channels as usize;
    let mut out = vec![0f32; query.len() * c];
    out.par_chunks_mut(c * 256)
        .enumerate()
        .for_each(|(chunk, dst)| {
            for (k, values) in dst.chunks_mut(c).enumerate() {
                solid.eval(query.point(chunk * 256 + k), values);
            }
        });
    out
}

/// [`tricubic_eval`] quantized to 8 bits per channel (reference of the kernel's `quantize`
/// mode: the same bytes wherever the float value is not within the float tolerance of a
/// rounding boundary).
pub fn tricubic_eval_u8(solid: &GradientSolid, query: &Query) -> Vec<u8> {
    // (A volume is quantized as it is evaluated: no float copy of it.)
    if let Some(n) = cell_mode(solid, query) {
        return eval_cells(solid, n, quantize);
    }
    tricubic_eval(solid, query)
        .into_iter()
        .map(quantize)
        .collect()
}

/// The volume side `n` when `query` is the box [0, n)^3 of integer voxels inside the solid's
/// domain (n <= extent per axis) and the solid has at most 4 channels: the case the kernel's cell
/// mode evaluates row by row (`wgsl/tricubic_eval.wgsl`), with its sums in another order than
/// a point's.
pub fn cell_mode(solid: &GradientSolid, query: &Query) -> Option<[u32; 3]> {
    let Query::Grid { n, .. } = query else {
        return None;
    };
    let inside = (0..3).all(|a| n[a] <= solid.extent()[a]);
    (*query == Query::volume(*n) && inside && solid.channels <= 4).then_some(*n)
}

/// The cell mode of the kernel, in its order of operations (lavapipe, which does not fuse
/// multiply-adds, then gives the same bits): per z plane of a cube, its 4 corner columns are
/// reduced along z (value, x and y derivative terms); per row, those along y to the 4
/// coefficients of the cubic along x (a0, a1, b0, b1: value and derivative terms of its two x
/// faces); per voxel, that cubic is evaluated at the voxel's fraction.
/// Each value goes through `store` (the identity, or the 8-bit quantization).
fn eval_cells<T: Copy + Default + Send>(
    solid: &GradientSolid,
    n: [u32; 3],
    store: impl Fn(f32) -> T + Sync,
) -> Vec<T> {
    type V4 = [f32; 4];
    let c = solid.channels as usize;
    let d = SPACING;
    let (nx, ny) = (n[0] as usize, n[1] as usize);
    let mut out = vec![T::default(); nx * ny * n[2] as usize * c];
    // [f, gx, gy, gz] of channels 0..3 (0 past the solid's channels).
    let load = |p: [u32; 3]| -> [V4; 4] {
        let mut k = [[0f32; 4]; 4];
        let base = solid.point_index(p) * c * 4;
        for ch in 0..c {
            for (j, row) in k.iter_mut().enumerate() {
                row[ch] = solid.data[base + ch * 4 + j];
            }
        }
        k
    };
    let lanes = |f: &dyn Fn(usize) -> f32| -> V4 { [0, 1, 2, 3].map(f) };
    // (f, gx, gy) of the corner column at (x, y), reduced along z at fraction tz.
    let column = |x: u32, y: u32, z: u32, tz: f32| -> [V4; 3] {
        let (k0, k1) = (load([x, y, z]), load([x, y, z + 1]));
        let (h0, h1) = (hermite_h(0, tz), hermite_h(1, tz));
        let (g0, g1) = (hermite_g(0, tz), hermite_g(1, tz));
        [
            lanes(&|i| k0[0][i] * h0 + k1[0][i] * h1 + k0[3][i] * g0 + k1[3][i] * g1),
            lanes(&|i| k0[1][i] * h0 + k1[1][i] * h1),
            lanes(&|i| k0[2][i] * h0 + k1[2][i] * h1),
        ]
    };
    out.par_chunks_mut(nx * ny * c)
        .enumerate()
        .for_each(|(z, plane)| {
            let z = z as u32;
            let cz = (z / d).min(solid.dims[2] - 2);
            let tz = (z % d) as f32 / d as f32 + (z / d - cz) as f32;
            for cell_y in 0..n[1].div_ceil(d) {
                let cy = cell_y.min(solid.dims[1] - 2);
                for cell_x in 0..n[0].div_ceil(d) {
                    let cx = cell_x.min(solid.dims[0] - 2);
                    let c00 = column(cx, cy, cz, tz);
                    let c10 = column(cx + 1, cy, cz, tz);
                    let c01 = column(cx, cy + 1, cz, tz);
                    let c11 = column(cx + 1, cy + 1, cz, tz);
                    for ly in 0..d {
                        let y = cell_y * d + ly;
                        if y >= n[1] {
                            break;
                        }
                        let ty = ly as f32 / d as f32 + (cell_y - cy) as f32;
                        let (hy0, hy1) = (hermite_h(0, ty), hermite_h(1, ty));
                        let (gy0, gy1) = (hermite_g(0, ty), hermite_g(1, ty));
                        let a0 = lanes(&|i| {
                            c00[0][i] * hy0 + c01[0][i] * hy1 + c00[2][i] * gy0 + c01[2][i] * gy1
                        });
                        let a1 = lanes(&|i| {
                            c10[0][i] * hy0 + c11[0][i] * hy1 + c10[2][i] * gy0 + c11[2][i] * gy1
                        });
                        let b0 = lanes(&|i| c00[1][i] * hy0 + c01[1][i] * hy1);
                        let b1 = lanes(&|i| c10[1][i] * hy0 + c11[1][i] * hy1);
                        for lx in 0..d {
                            let x = cell_x * d + lx;
                            if x >= n[0] {
                                break;
                            }
                            let t = lx as f32 / d as f32 + (cell_x - cx) as f32;
                            let (h0, h1) = (hermite_h(0, t), hermite_h(1, t));
                            let (g0, g1) = (hermite_g(0, t), hermite_g(1, t));
                            let o = (y as usize * nx + x as usize) * c;
                            for ch in 0..c {
                                plane[o + ch] =
                                    store(a0[ch] * h0 + a1[ch] * h1 + b0[ch] * g0 + b1[ch] * g1);
                            }
                        }
                    }
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::hash::SeededRng;

    fn solid(dims: [u32; 3], channels: u32) -> GradientSolid {
        let mut s = GradientSolid::new(dims, channels).unwrap();
        let mut rng = SeededRng::new(5);
        for v in s.data.iter_mut() {
            *v = rng.below(40_000) as f32 / 100.0 - 200.0;
        }
        s
    }

    /// The row-by-row cell mode evaluates the same interpolant as the per-point path, on whole
    /// and partial cells and on the grid's far face.
    #[test]
    fn cell_mode_equals_the_point_evaluation() {
        for (dims, channels, n) in [
            ([5, 4, 6], 3, [17, 13, 21]),
            ([5, 4, 6], 1, [10, 7, 15]),
            ([3, 3, 3], 4, [9, 9, 9]),
            ([4, 5, 3], 2, [1, 2, 3]),
        ] {
            let s = solid(dims, channels);
            let q = Query::volume(n);
            assert_eq!(cell_mode(&s, &q), Some(n));
            let cells = tricubic_eval(&s, &q);
            let mut point = vec![0f32; channels as usize];
            let scale = 1.0 + 4.0 * s.data.iter().fold(0f32, |m, v| m.max(v.abs()));
            for idx in 0..q.len() {
                s.eval(q.point(idx), &mut point);
                for (ch, p) in point.iter().enumerate() {
                    let got = cells[idx * channels as usize + ch];
                    assert!(
                        (got - p).abs() <= 1e-5 * scale,
                        "{dims:?} {n:?} point {idx} channel {ch}: {got} vs {p}"
                    );
                }
            }
        }
        // Outside the domain, more than 4 channels, or not a unit volume: the general path.
        let s = solid([5, 4, 6], 3);
        assert_eq!(cell_mode(&s, &Query::volume([18, 13, 21])), None);
        assert_eq!(cell_mode(&solid([3; 3], 5), &Query::volume([8; 3])), None);
        let slice = Query::Grid {
            origin: [0.5, 0.0, 0.0],
            a: [1.0, 0.0, 0.0],
            b: [0.0, 1.0, 0.0],
            c: [0.0, 0.0, 1.0],
            n: [8, 8, 8],
        };
        assert_eq!(cell_mode(&s, &slice), None);
    }
}
