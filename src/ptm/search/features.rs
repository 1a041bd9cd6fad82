//! The searches' features: per pixel, the quantized orthonormal (Legendre) coefficients of its
//! reflectance functions, and the exact squared distance between runs of them.

use super::super::{legendre, Ptm, COEFFS};
use rayon::prelude::*;

/// Legendre coefficients (unit intensity) are stored as round(b * FEATURE_SCALE), clamped to
/// i16 range (|b| <= 16): 1/2048 of full intensity is an eighth of an 8-bit level. With |f| <
/// 2^15 a difference squared fits a u32, which keeps the inner loop narrow.
pub const FEATURE_SCALE: f64 = 2048.0;

/// Per pixel, the quantized orthonormal coefficients of its reflectance functions: 6 for LRGB
/// (the luminance polynomial), 18 for RGB (the three channels stacked).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FeatureImage {
    pub width: u32,
    pub height: u32,
    pub dims: usize,
    pub data: Vec<i32>,
}

impl FeatureImage {
    pub fn new(width: u32, height: u32, dims: usize) -> Self {
        FeatureImage {
            width,
            height,
            dims,
            data: vec![0; width as usize * height as usize * dims],
        }
    }

    /// The values of `len` pixels of row y starting at column x.
    #[inline]
    pub fn run(&self, x: u32, y: u32, len: u32) -> &[i32] {
        let i = (y as usize * self.width as usize + x as usize) * self.dims;
        &self.data[i..i + len as usize * self.dims]
    }

    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [i32] {
        let i = (y as usize * self.width as usize + x as usize) * self.dims;
        &mut self.data[i..i + self.dims]
    }
}

/// Feature dimensions of a PTM's format.
pub fn feature_dims(ptm: &Ptm) -> usize {
    ptm.format.planes() * COEFFS
}

/// The features of one texel of `ptm` into `out` (`feature_dims` values).
pub fn texel_features(ptm: &Ptm, texel: &[u8], out: &mut [i32]) {
    for p in 0..ptm.format.planes() {
        let a: [f64; COEFFS] = std::array::from_fn(|i| ptm.decode(i, texel[p * COEFFS + i]) as f64);
        let b = legendre::to_legendre(&a);
        for i in 0..COEFFS {
            out[p * COEFFS + i] = (b[i] * FEATURE_SCALE).round().clamp(-32767.0, 32767.0) as i32;
        }
    }
}

/// The feature image of a whole PTM.
pub fn features(ptm: &Ptm) -> FeatureImage {
    let mut f = FeatureImage::new(ptm.width, ptm.height, feature_dims(ptm));
    let d = f.dims;
    let s = ptm.format.texel_bytes();
    f.data
        .par_chunks_mut(d)
        .zip(ptm.texels.par_chunks(s))
        .for_each(|(out, t)| texel_features(ptm, t, out));
    f
}

/// Sum of squared differences of two equal-length runs. |values| < 2^15, so each square fits a
/// u32; the sum is exact in u64 whatever the order.
#[inline]
pub fn squared_difference(a: &[i32], b: &[i32]) -> u64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = (x - y).unsigned_abs();
            (d * d) as u64
        })
        .sum()
}
