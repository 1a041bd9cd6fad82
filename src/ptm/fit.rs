//! Least-squares PTM fit (the paper's section V): per pixel, the six coefficients minimizing
//! sum_i (L(lu_i, lv_i) - L_i)^2. The design matrix depends only on the lights, so its
//! pseudo-inverse is computed once (SVD, which also detects rank-deficient light sets) and applied
//! to every pixel.

use super::capture::{Capture, Light};
use super::{quantize, Ptm, PtmFormat, COEFFS};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Singular values below this fraction of the largest count as zero: such a light set cannot
/// separate the six basis functions (e.g. one elevation: lu^2 + lv^2 is constant, so the lu^2,
/// lv^2 and 1 columns are dependent); a fit would amplify noise without bound.
pub const RANK_TOLERANCE: f64 = 1e-3;

/// The PTM basis at a light: [lu^2, lv^2, lu lv, lu, lv, 1].
pub fn basis(l: Light) -> [f64; COEFFS] {
    [l.lu * l.lu, l.lv * l.lv, l.lu * l.lv, l.lu, l.lv, 1.0]
}

/// The 6 x N pseudo-inverse of the design matrix, row-major; an error naming `what` (the light
/// file) when the lights are fewer than 6 or rank-deficient.
pub fn pseudo_inverse(lights: &[Light], what: &str) -> Result<Vec<f64>> {
    let n = lights.len();
    if n < COEFFS {
        return Err(Error::invalid(
            what,
            format!("{n} lights; a PTM fit needs at least {COEFFS}"),
        ));
    }
    let a = DMatrix::from_fn(n, COEFFS, |r, c| basis(lights[r])[c]);
    let svd = a.svd(true, true);
    let max = svd.singular_values.max();
    let rank = svd
        .singular_values
        .iter()
        .filter(|&&s| s > max * RANK_TOLERANCE)
        .count();
    if rank < COEFFS {
        return Err(Error::invalid(
            what,
            format!(
                "degenerate light set: the {n} directions determine only {rank} of the 6 PTM \
                 basis functions (e.g. lights all at one elevation make lu^2 + lv^2 constant, \
                 lights on one line make lu and lv dependent); spread the lights over several \
                 elevations and azimuths"
            ),
        ));
    }
    let pinv = svd
        .pseudo_inverse(0.0)
        .map_err(|e| Error::invalid(what, format!("least squares failed: {e}")))?;
    Ok((0..COEFFS)
        .flat_map(|r| (0..n).map(move |c| (r, c)))
        .map(|(r, c)| pinv[(r, c)])
        .collect())
}

/// Fit a PTM to a capture. LRGB: the polynomial fits the luminance (mean of R, G, B) and each
/// pixel keeps a colour c (least squares of C_i ~ c Y_i over the images), normalized so its
/// largest channel is 1 (the polynomial absorbs the factor). RGB: one polynomial per channel.
pub fn fit(capture: &Capture, format: PtmFormat, what: &str) -> Result<Ptm> {
    capture.validate(what)?;
    let pinv = pseudo_inverse(&capture.lights, what)?;
    let n = capture.images.len();
    let (w, h) = (capture.width(), capture.height());
    let pixels = w as usize * h as usize;
    let planes = format.planes();
    // Unit-intensity coefficients, planes x 6 per pixel, and the LRGB colours.
    let mut coeffs = vec![0f32; pixels * planes * COEFFS];
    let mut colours = vec![[0f32; 3]; pixels];
    coeffs
        .par_chunks_mut(planes * COEFFS)
        .zip(colours.par_iter_mut())
        .enumerate()
        .for_each(|(p, (out, colour))| {
            let (x, y) = ((p % w as usize) as u32, (p / w as usize) as u32);
            let samples: Vec<[f64; 3]> = capture
                .images
                .iter()
                .map(|img| img.get_pixel(x, y).0.map(|v| v as f64 / 255.0))
                .collect();
            let solve = |value: &dyn Fn(&[f64; 3]) -> f64| -> [f64; COEFFS] {
                let mut a = [0f64; COEFFS];
                for (r, ar) in a.iter_mut().enumerate() {
                    *ar = (0..n).map(|i| pinv[r * n + i] * value(&samples[i])).sum();
                }
                a
            };
            match format {
                PtmFormat::Rgb => {
                    for c in 0..3 {
                        let a = solve(&|s| s[c]);
                        for i in 0..COEFFS {
                            out[c * COEFFS + i] = a[i] as f32;
                        }
                    }
                }
                PtmFormat::Lrgb => {
                    let lum = |s: &[f64; 3]| (s[0] + s[1] + s[2]) / 3.0;
                    let yy: f64 = samples.iter().map(|s| lum(s) * lum(s)).sum();
                    let chroma = if yy > 1e-12 {
                        [0, 1, 2].map(|c| samples.iter().map(|s| s[c] * lum(s)).sum::<f64>() / yy)
                    } else {
                        [1.0; 3]
                    };
                    let m = chroma.iter().cloned().fold(0.0, f64::max).max(1e-6);
                    let a = solve(&lum);
                    for i in 0..COEFFS {
                        out[i] = (a[i] * m) as f32;
                    }
                    *colour = chroma.map(|c| (c / m) as f32);
                }
            }
        });
    let (scale, bias, bytes) = quantize(&coeffs);
    let s = format.texel_bytes();
    let mut texels = vec![0u8; pixels * s];
    for p in 0..pixels {
        let t = &mut texels[p * s..(p + 1) * s];
        t[..planes * COEFFS]
            .copy_from_slice(&bytes[p * planes * COEFFS..(p + 1) * planes * COEFFS]);
        if format == PtmFormat::Lrgb {
            for c in 0..3 {
                t[COEFFS + c] = (colours[p][c] * 255.0).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    Ok(Ptm {
        format,
        width: w,
        height: h,
        scale,
        bias,
        texels,
    })
}

/// RMS difference (in 8-bit levels) between the capture's images and the PTM shaded at each
/// image's light: how well the biquadratic model (plus quantization) explains the capture.
pub fn rms_error(capture: &Capture, ptm: &Ptm) -> f64 {
    let mut sum = 0f64;
    let mut count = 0usize;
    for (img, light) in capture.images.iter().zip(&capture.lights) {
        for (x, y, p) in img.enumerate_pixels() {
            let c = ptm.shade(x, y, light.lu as f32, light.lv as f32);
            for (&v, &q) in c.iter().zip(&p.0) {
                let d = (v * 255.0).clamp(0.0, 255.0) as f64 - q as f64;
                sum += d * d;
                count += 1;
            }
        }
    }
    (sum / count.max(1) as f64).sqrt()
}
