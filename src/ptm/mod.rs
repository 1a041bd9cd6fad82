//! Relightable texture synthesis with polynomial texture maps (Hel-Or, Malzbender, Gelb,
//! "Synthesis and Rendering of 3D Textures"): per-pixel biquadratic reflectance functions of the
//! light direction, fitted to a capture, synthesized by image quilting over their coefficients
//! with an exact projection-kernel search, and relit on the GPU.
//!
//! - [`capture`]: a synthetic capture (procedural height field + albedo, Lambertian, cast shadows).
//! - [`fit`]: least-squares PTM fit of a capture (LRGB or RGB), rank-deficient light sets refused.
//! - `format`: the HP `.ptm` file format (PTM_1.2, PTM_FORMAT_RGB / PTM_FORMAT_LRGB).
//! - [`legendre`]: the orthonormal Legendre basis of section VI (distances = function distances).
//! - [`search`]: block neighbourhood search, brute force and the exact projection-kernel scheme.
//! - [`quilt`]: block-based synthesis (section IV) with minimum-error cuts or alpha blending.
//! - [`relight`]: rendering under any light (kernel `ptm_relight`), contact sheets.

pub mod capture;
pub mod fit;
pub mod format;
pub mod legendre;
pub mod quilt;
pub mod relight;
pub mod search;

pub use crate::contract::ptm::{Lighting, Ptm, PtmFormat, COEFFS};

/// Evaluate a biquadratic PTM polynomial at light (lu, lv).
#[inline]
pub fn eval_poly(a: &[f32], lu: f32, lv: f32) -> f32 {
    a[0] * lu * lu + a[1] * lv * lv + a[2] * lu * lv + a[3] * lu + a[4] * lv + a[5]
}

impl Ptm {
    /// Pixels in the map.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The bytes of pixel (x, y).
    pub fn texel(&self, x: u32, y: u32) -> &[u8] {
        let s = self.format.texel_bytes();
        let i = (y as usize * self.width as usize + x as usize) * s;
        &self.texels[i..i + s]
    }

    /// The unit-intensity value of one quantization step of coefficient i: scale / 255.
    #[inline]
    pub fn step(&self, i: usize) -> f32 {
        self.scale[i] / 255.0
    }

    /// Coefficient i of a stored byte, in unit intensity (1.0 = full intensity). The relight
    /// kernel decodes with the same expression.
    #[inline]
    pub fn decode(&self, i: usize, q: u8) -> f32 {
        (q as i32 - self.bias[i]) as f32 * self.step(i)
    }

    /// The decoded polynomials of one texel in unit intensity (`planes` x 6 values) and, for
    /// LRGB, its colour in [0, 1].
    pub fn decode_texel(&self, texel: &[u8]) -> ([[f32; COEFFS]; 3], [f32; 3]) {
        let mut polys = [[0f32; COEFFS]; 3];
        for (p, poly) in polys.iter_mut().enumerate().take(self.format.planes()) {
            for (i, a) in poly.iter_mut().enumerate() {
                *a = self.decode(i, texel[p * COEFFS + i]);
            }
        }
        let rgb = match self.format {
            PtmFormat::Lrgb => [6, 7, 8].map(|k| texel[k] as f32 / 255.0),
            PtmFormat::Rgb => [1.0; 3],
        };
        (polys, rgb)
    }

    /// The colour of pixel (x, y) under light (lu, lv), unclamped, unit intensity (no specular).
    pub fn shade(&self, x: u32, y: u32, lu: f32, lv: f32) -> [f32; 3] {
        let (polys, rgb) = self.decode_texel(self.texel(x, y));
        match self.format {
            PtmFormat::Lrgb => {
                let l = eval_poly(&polys[0], lu, lv);
                rgb.map(|c| l * c)
            }
            PtmFormat::Rgb => [0, 1, 2].map(|p| eval_poly(&polys[p], lu, lv)),
        }
    }
}

/// Unit-intensity coefficients quantized to the file's bytes: per coefficient index, a scale and
/// integer bias spanning that coefficient's range over all pixels and planes.
/// `coeffs` holds `count` polynomials of 6 values each; returns (scale, bias, bytes).
pub fn quantize(coeffs: &[f32]) -> ([f32; COEFFS], [i32; COEFFS], Vec<u8>) {
    let mut lo = [f32::INFINITY; COEFFS];
    let mut hi = [f32::NEG_INFINITY; COEFFS];
    for poly in coeffs.chunks_exact(COEFFS) {
        for i in 0..COEFFS {
            let v = poly[i] * 255.0;
            lo[i] = lo[i].min(v);
            hi[i] = hi[i].max(v);
        }
    }
    let mut scale = [1f32; COEFFS];
    let mut bias = [0i32; COEFFS];
    for i in 0..COEFFS {
        if coeffs.is_empty() {
            break;
        }
        // 254 steps rather than 255: the rounded bias can shift the range by half a step, and the
        // full range must still fit in 0..=255. A constant coefficient gets a unit step.
        let range = hi[i] - lo[i];
        scale[i] = if range > 1e-6 { range / 254.0 } else { 1.0 };
        bias[i] = (-lo[i] / scale[i]).round() as i32;
    }
    let bytes = coeffs
        .chunks_exact(COEFFS)
        .flat_map(|poly| {
            (0..COEFFS).map(move |i| {
                ((poly[i] * 255.0 / scale[i]).round() + bias[i] as f32).clamp(0.0, 255.0) as u8
            })
        })
        .collect();
    (scale, bias, bytes)
}
