//! CPU reference of `wgsl/ptm_relight.wgsl`: a PTM rendered under one light (unit-intensity RGB
//! per pixel, unclamped), with an optional Blinn-Phong highlight (exponent 32) around the normal
//! that maximizes the luminance polynomial. Same order of operations as the shader; rayon over
//! rows.

pub use crate::contract::ptm::Lighting;
use crate::contract::ptm::{Ptm, PtmFormat, COEFFS};
use rayon::prelude::*;

/// 1/255 rounded to f32; colours are byte * INV_255 on both backends.
pub const INV_255: f32 = 1.0 / 255.0;

/// Highlight exponent (applied as five squarings, no `pow`).
#[cfg(any(test, feature = "internals"))]
pub const SHININESS: u32 = 32;

fn poly(a: &[f32; COEFFS], lu: f32, lv: f32) -> f32 {
    a[0] * lu * lu + a[1] * lv * lv + a[2] * lu * lv + a[3] * lu + a[4] * lv + a[5]
}

/// The normal of a luminance polynomial (see the shader's `normal_of`).
pub fn normal_of(a: &[f32; COEFFS]) -> [f32; 3] {
    let (mut u, mut v) = (0f32, 0f32);
    let det = 4.0 * a[0] * a[1] - a[2] * a[2];
    if a[0] < 0.0 && det > 0.0 {
        u = (a[2] * a[4] - 2.0 * a[1] * a[3]) / det;
        v = (a[2] * a[3] - 2.0 * a[0] * a[4]) / det;
    } else if a[5] > 1e-6 {
        u = a[3] / a[5];
        v = a[4] / a[5];
    }
    let r2 = u * u + v * v;
    if r2 > 1.0 {
        let k = 1.0 / r2.sqrt();
        u *= k;
        v *= k;
    }
    [u, v, (1.0 - u * u - v * v).max(0.0).sqrt()]
}

/// One texel under `light`.
pub fn relight_texel(ptm: &Ptm, texel: &[u8], light: &Lighting) -> [f32; 3] {
    let decode = |p: usize| -> [f32; COEFFS] {
        std::array::from_fn(|i| (texel[p * COEFFS + i] as i32 - ptm.bias[i]) as f32 * ptm.step(i))
    };
    let (lu, lv) = (light.lu, light.lv);
    let (mut rgb, lum) = match ptm.format {
        PtmFormat::Lrgb => {
            let a = decode(0);
            let l = poly(&a, lu, lv);
            ([6, 7, 8].map(|k| l * (texel[k] as f32 * INV_255)), a)
        }
        PtmFormat::Rgb => {
            let (r, g, b) = (decode(0), decode(1), decode(2));
            (
                [poly(&r, lu, lv), poly(&g, lu, lv), poly(&b, lu, lv)],
                std::array::from_fn(|i| (r[i] + g[i] + b[i]) / 3.0),
            )
        }
    };
    if light.specular > 0.0 {
        let n = normal_of(&lum);
        let h0 = [lu, lv, light.lw() + 1.0];
        let len = (h0[0] * h0[0] + h0[1] * h0[1] + h0[2] * h0[2]).sqrt();
        let h = h0.map(|c| c / len);
        let mut s = (n[0] * h[0] + n[1] * h[1] + n[2] * h[2]).max(0.0);
        for _ in 0..5 {
            s *= s;
        }
        for c in rgb.iter_mut() {
            *c += light.specular * s;
        }
    }
    rgb
}

/// Every pixel of `ptm` under `light`: r, g, b per pixel, rows top to bottom.
pub fn ptm_relight(ptm: &Ptm, light: &Lighting) -> Vec<f32> {
    let s = ptm.format.texel_bytes();
    let mut out = vec![0f32; ptm.pixels() * 3];
    out.par_chunks_mut(3 * 256)
        .zip(ptm.texels.par_chunks(s * 256))
        .for_each(|(dst, src)| {
            for (o, t) in dst.chunks_exact_mut(3).zip(src.chunks_exact(s)) {
                o.copy_from_slice(&relight_texel(ptm, t, light));
            }
        });
    out
}
