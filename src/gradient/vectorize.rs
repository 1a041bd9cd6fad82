//! Vectorization of a voxel volume into a gradient solid (paper 5.2): per control point, the
//! least-squares fit of eq. 2, f + grad . (x - p) ~ value(x), over the voxels of its
//! (2d + 1)^3 neighbourhood (clipped to the volume). Control-point optimization (eq. 3) is not
//! implemented.

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
    let per_point = channels as usize * 4;
    let d = SPACING as i64;
    solid
        .data
        .par_chunks_mut(per_point)
        .enumerate()
        .for_each(|(i, out)| {
            let p = [
                (i % dims[0] as usize) as i64 * d,
                ((i / dims[0] as usize) % dims[1] as usize) as i64 * d,
                (i / (dims[0] as usize * dims[1] as usize)) as i64 * d,
            ];
            let range = |a: usize, n: u32| (p[a] - d).max(0)..=(p[a] + d).min(n as i64 - 1);
            let mut ata = Matrix4::<f64>::zeros();
            let mut atb = vec![Vector4::<f64>::zeros(); channels as usize];
            for z in range(2, v.nz) {
                for y in range(1, v.ny) {
                    for x in range(0, v.nx) {
                        let row = Vector4::new(
                            1.0,
                            (x - p[0]) as f64,
                            (y - p[1]) as f64,
                            (z - p[2]) as f64,
                        );
                        ata += row * row.transpose();
                        let px = v.at(x as u32, y as u32, z as u32);
                        for c in 0..channels as usize {
                            atb[c] += row * px[c] as f64;
                        }
                    }
                }
            }
            // A neighbourhood flat along an axis (a one-voxel-thick volume) leaves that gradient
            // undetermined: the pseudo-inverse sets it to zero.
            let inv = ata
                .pseudo_inverse(1e-9)
                .unwrap_or_else(|_| Matrix4::zeros());
            for c in 0..channels as usize {
                let sol = inv * atb[c];
                for k in 0..4 {
                    out[c * 4 + k] = sol[k] as f32;
                }
            }
        });
    Ok(solid)
}

/// Render every voxel of an `n`-sized box from the origin (exact evaluation), rounded to 8 bits.
pub fn render(s: &GradientSolid, n: [u32; 3]) -> Volume {
    let mut v = Volume::new(n[0], n[1], n[2], s.channels);
    let c = s.channels as usize;
    let row = n[0] as usize * c;
    v.data.par_chunks_mut(row).enumerate().for_each(|(r, dst)| {
        let (y, z) = ((r % n[1] as usize) as f32, (r / n[1] as usize) as f32);
        let mut out = vec![0f32; c];
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
        let s = vectorize(&v).unwrap();
        let e = rms(&render(&s, [17, 13, 9]), &v);
        assert!(e < 4.0, "rms {e}");
    }
}
