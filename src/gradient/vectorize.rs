//! Vectorization of a voxel volume into a gradient solid (paper 5.2): per control point, the
//! least-squares fit of eq. 2, f + grad . (x - p) ~ value(x), over the voxels of its
//! (2d + 1)^3 neighbourhood (clipped to the volume); then, optionally, the control-point
//! optimization of eq. 3: all control values at once, minimizing the squared difference between
//! the interpolated solid and every voxel (a sparse linear least-squares problem, solved by
//! conjugate gradients on the normal equations, starting from the eq. 2 fit).

use super::{GradientSolid, SPACING};
use crate::error::Result;
use crate::volume::Volume;
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

/// Control points per axis needed to cover `n` voxels.
pub fn grid_for(n: u32) -> u32 {
    (n.saturating_sub(1)).div_ceil(SPACING) + 1
}

pub fn vectorize(v: &Volume) -> Result<GradientSolid> {
    let dims = [
        grid_for(v.nx).max(2),
        grid_for(v.ny).max(2),
        grid_for(v.nz).max(2),
    ];
    let channels = v.channels;
    let mut solid = GradientSolid::new(dims, channels)?;
    solid.size = v.dims();
    let per_point = channels as usize * 4;
    solid
        .data
        .par_chunks_mut(per_point)
        .enumerate()
        .for_each(|(i, out)| {
            fit_point(point_position(dims, i), v.dims(), out, &|x, y, z, px| {
                for (o, &b) in px.iter_mut().zip(v.at(x, y, z)) {
                    *o = b as f64;
                }
                true
            });
        });
    Ok(solid)
}

/// Voxel position of control point `i` (x fastest).
pub(crate) fn point_position(dims: [u32; 3], i: usize) -> [i64; 3] {
    let d = SPACING as i64;
    [
        (i % dims[0] as usize) as i64 * d,
        ((i / dims[0] as usize) % dims[1] as usize) as i64 * d,
        (i / (dims[0] as usize * dims[1] as usize)) as i64 * d,
    ]
}

/// Eq. 2 at one control point at voxel position `p`: f + grad . (x - p) ~ value(x) in the least
/// squares over the voxels of its (2d + 1)^3 neighbourhood (clipped to the `n`-voxel volume) for
/// which `value` fills the channels and returns true. Writes (f, fx, fy, fz) per channel.
pub(crate) fn fit_point(
    p: [i64; 3],
    n: [u32; 3],
    out: &mut [f32],
    value: &dyn Fn(u32, u32, u32, &mut [f64]) -> bool,
) {
    let channels = out.len() / 4;
    let d = SPACING as i64;
    let range = |a: usize| (p[a] - d).max(0)..=(p[a] + d).min(n[a] as i64 - 1);
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = vec![Vector4::<f64>::zeros(); channels];
    let mut px = vec![0f64; channels];
    for z in range(2) {
        for y in range(1) {
            for x in range(0) {
                if !value(x as u32, y as u32, z as u32, &mut px) {
                    continue;
                }
                let row =
                    Vector4::new(1.0, (x - p[0]) as f64, (y - p[1]) as f64, (z - p[2]) as f64);
                ata += row * row.transpose();
                for c in 0..channels {
                    atb[c] += row * px[c];
                }
            }
        }
    }
    // A neighbourhood flat along an axis (a one-voxel-thick volume, or a region's samples on one
    // plane) leaves that gradient undetermined: the pseudo-inverse sets it to zero.
    let inv = ata
        .pseudo_inverse(1e-9)
        .unwrap_or_else(|_| Matrix4::zeros());
    for c in 0..channels {
        let sol = inv * atb[c];
        for k in 0..4 {
            out[c * 4 + k] = sol[k] as f32;
        }
    }
}

/// The voxels' interpolation stencils: per voxel (x fastest), its cube's first control point
/// index and the 32 weights.
fn stencils(s: &GradientSolid, n: [u32; 3]) -> Vec<(usize, [f32; 32])> {
    let mut out = Vec::with_capacity(n.iter().map(|&v| v as usize).product());
    for z in 0..n[2] {
        for y in 0..n[1] {
            for x in 0..n[0] {
                let (cube, t) = s.locate([x as f32, y as f32, z as f32]);
                out.push((s.point_index(cube), super::weights(t)));
            }
        }
    }
    out
}

/// Offsets (in points) of a cube's 8 corners from its first one, in weight order.
fn corner_offsets(s: &GradientSolid) -> [usize; 8] {
    let (dx, dy) = (s.dims[0] as usize, s.dims[0] as usize * s.dims[1] as usize);
    std::array::from_fn(|c| (c & 1) + ((c >> 1) & 1) * dx + (c >> 2) * dy)
}

/// y = A x: the interpolated values (per voxel, per channel) of control values `x`;
/// `point(voxel, p)` says which control point of `x` stands for grid point `p` at that voxel (the
/// identity, or a region solid's choice of feature set).
fn apply<F: Fn(usize, usize) -> usize + Sync>(
    st: &[(usize, [f32; 32])],
    corners: &[usize; 8],
    ch: usize,
    point: &F,
    x: &[f64],
    y: &mut [f64],
) {
    y.par_chunks_mut(ch)
        .zip(st)
        .enumerate()
        .for_each(|(vox, (out, (base, w)))| {
            for (c, o) in out.iter_mut().enumerate() {
                let mut acc = 0.0;
                for (k, off) in corners.iter().enumerate() {
                    let v = (point(vox, base + off) * ch + c) * 4;
                    for j in 0..4 {
                        acc += w[k * 4 + j] as f64 * x[v + j];
                    }
                }
                *o = acc;
            }
        });
}

/// x = A^T y (sequential: a deterministic order of accumulation).
fn apply_t<F: Fn(usize, usize) -> usize>(
    st: &[(usize, [f32; 32])],
    corners: &[usize; 8],
    ch: usize,
    point: &F,
    y: &[f64],
    x: &mut [f64],
) {
    x.iter_mut().for_each(|v| *v = 0.0);
    for (vox, (base, w)) in st.iter().enumerate() {
        for c in 0..ch {
            let r = y[vox * ch + c];
            for (k, off) in corners.iter().enumerate() {
                let v = (point(vox, base + off) * ch + c) * 4;
                for j in 0..4 {
                    x[v + j] += w[k * 4 + j] as f64 * r;
                }
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Eq. 3: refine all control values so the interpolated solid fits every voxel of `v` in the
/// least-squares sense (CGNR, `iterations` steps). Returns the RMS error after each step.
pub fn optimize(s: &mut GradientSolid, v: &Volume, iterations: usize) -> Vec<f64> {
    let mut x: Vec<f64> = s.data.iter().map(|&d| d as f64).collect();
    let history = cgnr(s, v, &|_, p| p, &mut x, iterations);
    s.data = x.into_iter().map(|v| v as f32).collect();
    history
}

/// CGNR on the interpolation operator of `grid` (its stencils over `v`'s voxels) with control
/// points mapped by `point`, from and into `x`. Returns the RMS error after each step.
pub(crate) fn cgnr<F: Fn(usize, usize) -> usize + Sync>(
    grid: &GradientSolid,
    v: &Volume,
    point: &F,
    x: &mut [f64],
    iterations: usize,
) -> Vec<f64> {
    let n = [v.nx, v.ny, v.nz];
    let ch = grid.channels as usize;
    let st = stencils(grid, n);
    let corners = corner_offsets(grid);
    let b: Vec<f64> = v.data.iter().map(|&x| x as f64).collect();
    let mut ax = vec![0f64; b.len()];
    apply(&st, &corners, ch, point, x, &mut ax);
    let mut resid: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut r = vec![0f64; x.len()];
    apply_t(&st, &corners, ch, point, &resid, &mut r);
    let mut p = r.clone();
    let mut rs = dot(&r, &r);
    let mut q = vec![0f64; b.len()];
    let mut history = Vec::new();
    for _ in 0..iterations {
        if rs <= 1e-18 {
            break;
        }
        apply(&st, &corners, ch, point, &p, &mut q);
        let alpha = rs / dot(&q, &q).max(f64::MIN_POSITIVE);
        x.iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
        resid.iter_mut().zip(&q).for_each(|(r, q)| *r -= alpha * q);
        history.push((dot(&resid, &resid) / resid.len() as f64).sqrt());
        apply_t(&st, &corners, ch, point, &resid, &mut r);
        let rs_new = dot(&r, &r);
        let beta = rs_new / rs;
        p.iter_mut().zip(&r).for_each(|(p, r)| *p = r + beta * *p);
        rs = rs_new;
    }
    history
}

/// Render every voxel of an `n`-sized box from the origin (exact evaluation), rounded to 8 bits:
/// the colour channels (a detail solid's smooth part, without grain).
pub fn render(s: &GradientSolid, n: [u32; 3]) -> Volume {
    let c = (s.channels - s.detail) as usize;
    let mut v = Volume::new(n[0], n[1], n[2], c as u32);
    let row = n[0] as usize * c;
    v.data.par_chunks_mut(row).enumerate().for_each(|(r, dst)| {
        let (y, z) = ((r % n[1] as usize) as f32, (r / n[1] as usize) as f32);
        let mut out = vec![0f32; s.channels as usize];
        for x in 0..n[0] as usize {
            s.eval([x as f32, y, z], &mut out);
            for k in 0..c {
                dst[x * c + k] = out[k].round().clamp(0.0, 255.0) as u8;
            }
        }
    });
    v
}

/// RMS difference (0..255 units) between two volumes of the same shape.
pub fn rms(a: &Volume, b: &Volume) -> f64 {
    let sum: f64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
        .sum();
    (sum / a.data.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_volume_vectorizes_exactly_and_a_textured_one_closely() {
        let mut v = Volume::new(17, 13, 9, 1);
        for z in 0..9 {
            for y in 0..13 {
                for x in 0..17 {
                    v.at_mut(x, y, z)[0] = (20 + 3 * x + 2 * y + 5 * z) as u8;
                }
            }
        }
        let s = vectorize(&v).unwrap();
        assert_eq!(rms(&render(&s, [17, 13, 9]), &v), 0.0);
        // A smooth non-linear field: small error.
        for z in 0..9 {
            for y in 0..13 {
                for x in 0..17 {
                    let f = 128.0
                        + 60.0 * ((x as f64) * 0.15).sin() * ((y as f64 + z as f64) * 0.1).cos();
                    v.at_mut(x, y, z)[0] = f.round() as u8;
                }
            }
        }
        let mut s = vectorize(&v).unwrap();
        let e = rms(&render(&s, [17, 13, 9]), &v);
        assert!(e < 4.0, "rms {e}");
        // Eq. 3 lowers the error further, monotonically (CG on the normal equations).
        let history = optimize(&mut s, &v, 30);
        assert!(
            history.windows(2).all(|w| w[1] <= w[0] + 1e-9),
            "{history:?}"
        );
        let e2 = rms(&render(&s, [17, 13, 9]), &v);
        assert!(e2 < 0.7 * e, "optimized rms {e2} vs {e}");
    }
}
