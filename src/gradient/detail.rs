//! The detail residual (paper 5.4, optional): the fitting error at each voxel, modelled as a
//! zero-mean Gaussian whose standard deviation sigma_c(x) = |original - fitted| is itself stored
//! as extra channels of the gradient solid (fitted with eq. 2 like the colours), and resampled at
//! render time from a position-determined noise, so fine grain comes back without storing it.
//!
//! The noise is value noise: a standard normal per integer lattice point and channel (Box-Muller
//! on hashed coordinates), interpolated trilinearly and divided by the root of the summed squared
//! weights, so it has unit variance everywhere and equals the lattice values at voxel centres.
//! Same position, same value: renders are deterministic and agree across subsets and backends
//! (the noise is added on the host after `tricubic_eval`).

use super::vectorize::{fit_point, point_position};
use super::GradientSolid;
use crate::backend::host_tricubic_eval as tricubic_eval;
use crate::contract::tricubic::Query;
use crate::error::{Error, Result};
use crate::util::hash::hash32;
use crate::volume::Volume;
use rayon::prelude::*;

/// A standard normal at lattice point `q`, channel `c`.
fn lattice_gaussian(q: [i32; 3], c: u32) -> f32 {
    let h = hash32(hash32(hash32(hash32(q[0] as u32) ^ q[1] as u32) ^ q[2] as u32) ^ c);
    let h2 = hash32(h ^ 0x9e37_79b9);
    let u1 = (h as f64 + 0.5) / 4_294_967_296.0;
    let u2 = (h2 as f64 + 0.5) / 4_294_967_296.0;
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// Unit-variance value noise at position `x`, channel `c`.
pub fn noise(x: [f32; 3], c: u32) -> f32 {
    let f = x.map(f32::floor);
    let t = [x[0] - f[0], x[1] - f[1], x[2] - f[2]];
    let base = f.map(|v| v as i32);
    let (mut sum, mut weights) = (0f32, 0f32);
    for corner in 0..8 {
        let mut w = 1.0;
        let mut q = base;
        for a in 0..3 {
            if (corner >> a) & 1 == 1 {
                w *= t[a];
                q[a] = q[a].wrapping_add(1);
            } else {
                w *= 1.0 - t[a];
            }
        }
        if w == 0.0 {
            continue;
        }
        sum += w * lattice_gaussian(q, c);
        weights += w * w;
    }
    sum / weights.sqrt()
}

/// `solid` (colours only) with sigma channels fitted to its residual against `v`.
pub fn with_detail(solid: &GradientSolid, v: &Volume) -> Result<GradientSolid> {
    solid.check()?;
    v.check("volume")?;
    if v.channels != solid.channels {
        return Err(Error::invalid(
            "volume",
            format!(
                "has {} channels; the gradient solid has {}",
                v.channels, solid.channels
            ),
        ));
    }
    let n = v.dims();
    let c = solid.channels as usize;
    let fitted = tricubic_eval(solid, &Query::volume(n));
    let residual: Vec<f32> = fitted
        .iter()
        .zip(&v.data)
        .map(|(f, &o)| (o as f32 - f).abs())
        .collect();
    let mut sigma = GradientSolid::new(solid.dims, solid.channels)?;
    let at = |x: u32, y: u32, z: u32| ((z * n[1] + y) * n[0] + x) as usize * c;
    sigma
        .data
        .par_chunks_mut(c * 4)
        .enumerate()
        .for_each(|(i, out)| {
            fit_point(point_position(solid.dims, i), n, out, &|x, y, z, px| {
                let r = &residual[at(x, y, z)..at(x, y, z) + c];
                for (o, &v) in px.iter_mut().zip(r) {
                    *o = v as f64;
                }
                true
            });
        });
    let mut out = GradientSolid::new(solid.dims, 2 * solid.channels)?;
    out.detail = solid.channels;
    (out.size, out.periodic) = (solid.size, solid.periodic);
    for (i, dst) in out.data.chunks_exact_mut(2 * c * 4).enumerate() {
        dst[..c * 4].copy_from_slice(&solid.data[i * c * 4..(i + 1) * c * 4]);
        dst[c * 4..].copy_from_slice(&sigma.data[i * c * 4..(i + 1) * c * 4]);
    }
    Ok(out)
}

/// Colours of a detail solid's evaluated `values` (all its channels per query point): with the
/// sampled residual added (`grain`), or the smooth part only.
pub fn colours(solid: &GradientSolid, query: &Query, values: &[f32], grain: bool) -> Vec<f32> {
    let all = solid.channels as usize;
    let c = all - solid.detail as usize;
    let mut out = vec![0f32; query.len() * c];
    out.par_chunks_mut(c).enumerate().for_each(|(k, dst)| {
        let v = &values[k * all..(k + 1) * all];
        let p = query.point(k);
        for ch in 0..c {
            dst[ch] = v[ch];
            if grain && solid.detail > 0 {
                dst[ch] += v[c + ch].max(0.0) * noise(p, ch as u32);
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient::vectorize::vectorize;

    #[test]
    fn noise_is_deterministic_with_unit_variance() {
        assert_eq!(noise([3.25, -7.5, 2.0], 1), noise([3.25, -7.5, 2.0], 1));
        assert_ne!(noise([3.25, -7.5, 2.0], 1), noise([3.25, -7.5, 2.0], 2));
        for offset in [0.0f32, 0.5, 0.25] {
            let samples: Vec<f64> = (0..20000)
                .map(|i| noise([(i % 97) as f32 + offset, (i / 97) as f32, 3.0 + offset], 0) as f64)
                .collect();
            let mean = samples.iter().sum::<f64>() / samples.len() as f64;
            let var =
                samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / samples.len() as f64;
            assert!(
                mean.abs() < 0.05 && (var - 1.0).abs() < 0.1,
                "offset {offset}: {mean} {var}"
            );
        }
    }

    #[test]
    fn sigma_tracks_the_residual_and_grain_restores_its_spread() {
        // Smooth ramp plus fine hashed grain of amplitude ~20: the fit keeps the ramp, sigma
        // the grain's size.
        let n = 24u32;
        let mut v = Volume::new(n, n, n, 1);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let grain = (hash32(x + 31 * y + 977 * z) % 41) as f32 - 20.0;
                    v.at_mut(x, y, z)[0] = (100.0 + 2.0 * x as f32 + grain) as u8;
                }
            }
        }
        let plain = vectorize(&v).unwrap();
        let d = with_detail(&plain, &v).unwrap();
        assert_eq!((d.channels, d.detail), (2, 1));
        let q = Query::volume([n; 3]);
        let values = tricubic_eval(&d, &q);
        let mean_sigma = values.chunks(2).map(|p| p[1] as f64).sum::<f64>() / q.len() as f64;
        // |uniform(-20, 20)| averages 10.
        assert!((mean_sigma - 10.0).abs() < 2.0, "{mean_sigma}");
        let smooth = colours(&d, &q, &values, false);
        let grainy = colours(&d, &q, &values, true);
        let spread = |a: &[f32]| {
            let diffs: Vec<f64> = a.iter().zip(&smooth).map(|(x, s)| (x - s) as f64).collect();
            (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64).sqrt()
        };
        assert_eq!(spread(&smooth), 0.0);
        let s = spread(&grainy);
        assert!(s > 6.0 && s < 16.0, "grain spread {s}");
    }
}
