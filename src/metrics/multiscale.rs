//! Multi-scale statistics of slices against their exemplar: the sliced Wasserstein distance
//! between 5x5 patch distributions at full, half and quarter resolution, and the distance between
//! radially averaged log power spectra. Both see what the patch-nearest-neighbour measures miss:
//! structure at the scale of several patches (brick courses, the spacing of grains) and its drift
//! across scales.

use crate::exemplar::Image;
use crate::util::hash::SeededRng;
use rustfft::num_complex::Complex;
use serde::Serialize;

/// Side of the patches whose distribution is compared.
pub const SWD_PATCH: u32 = 5;
/// Random projection directions (fixed: the same for every evaluation).
pub const SWD_DIRECTIONS: usize = 64;
/// Quantiles at which two projected distributions are compared.
const QUANTILES: usize = 256;
/// Patches drawn per set at most (on a regular stride over all of them).
const MAX_PATCHES: usize = 20_000;
/// Radial frequency bins of the power spectrum, over (0, 0.5] cycles per pixel.
pub const SPECTRUM_BINS: usize = 12;

/// The multi-scale distances (lower is better).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct MultiScale {
    /// Sliced Wasserstein distance (0..255 units along unit directions) between the
    /// distributions of mean-removed 5x5 patches at full, 1/2 and 1/4 resolution.
    pub swd: [f64; 3],
    /// RMS difference (decades) of radially averaged log10 power spectra of the luminance.
    pub spectrum: f64,
}

impl MultiScale {
    pub fn worst(a: &MultiScale, b: &MultiScale) -> MultiScale {
        MultiScale {
            swd: [0, 1, 2].map(|l| a.swd[l].max(b.swd[l])),
            spectrum: a.spectrum.max(b.spectrum),
        }
    }

    /// Each distance divided by its floor (floors clamped away from zero).
    pub fn ratio_to(&self, floor: &MultiScale) -> MultiScale {
        MultiScale {
            swd: [0, 1, 2].map(|l| self.swd[l] / floor.swd[l].max(0.5)),
            spectrum: self.spectrum / floor.spectrum.max(0.02),
        }
    }
}

/// The measures of `images` against `reference`.
pub fn score(images: &[Image], reference: &Image) -> MultiScale {
    let mut swd = [0.0; 3];
    let mut imgs: Vec<Image> = images.to_vec();
    let mut refr = reference.clone();
    for (level, slot) in swd.iter_mut().enumerate() {
        if level > 0 {
            imgs = imgs.iter().map(half_size).collect();
            refr = half_size(&refr);
        }
        *slot = sliced_wasserstein(&patches(&imgs), &patches(std::slice::from_ref(&refr)));
    }
    MultiScale {
        swd,
        spectrum: spectrum_distance(images, reference),
    }
}

/// `img` at half the size: each pixel the rounded mean of a 2x2 block (odd edges dropped).
pub fn half_size(img: &Image) -> Image {
    let (w, h, c) = (img.width / 2, img.height / 2, img.channels as usize);
    let mut out = Image::new(w.max(1), h.max(1), img.channels);
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|&(dx, dy)| img.at(2 * x + dx, 2 * y + dy)[ch] as u32)
                    .sum();
                out.pixels[(y * w + x) as usize * c + ch] = ((sum + 2) / 4) as u8;
            }
        }
    }
    out
}

/// Every 5x5 patch of the images (as 25 x C values, each channel's patch mean removed), on a
/// regular stride when there are more than [`MAX_PATCHES`]. Without the means, random
/// directions see mostly the patches' average colour (their projections' variance is the same
/// for noise and for structure); with them removed, what is compared is the patches' structure:
/// edges, flat areas, noise.
fn patches(images: &[Image]) -> Vec<Vec<f32>> {
    let p = SWD_PATCH;
    let total: usize = images
        .iter()
        .map(|i| (i.width.saturating_sub(p - 1) * i.height.saturating_sub(p - 1)) as usize)
        .sum();
    let stride = total.div_ceil(MAX_PATCHES).max(1);
    let mut out = Vec::new();
    let mut k = 0usize;
    for img in images {
        let c = img.channels as usize;
        for y in 0..img.height.saturating_sub(p - 1) {
            for x in 0..img.width.saturating_sub(p - 1) {
                k += 1;
                if !k.is_multiple_of(stride) {
                    continue;
                }
                let mut v = Vec::with_capacity((p * p) as usize * c);
                for dy in 0..p {
                    for dx in 0..p {
                        v.extend(img.at(x + dx, y + dy).iter().map(|&b| b as f32));
                    }
                }
                for ch in 0..c {
                    let mean = v.iter().skip(ch).step_by(c).sum::<f32>() / (p * p) as f32;
                    v.iter_mut()
                        .skip(ch)
                        .step_by(c)
                        .for_each(|value| *value -= mean);
                }
                out.push(v);
            }
        }
    }
    out
}

/// Mean over [`SWD_DIRECTIONS`] fixed unit directions of the 1D Wasserstein-1 distance between
/// the two sets projected on it (compared at [`QUANTILES`] quantiles).
fn sliced_wasserstein(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return f64::NAN;
    }
    let dims = a[0].len();
    let mut rng = SeededRng::new(0x0051_1CED);
    let mut total = 0.0;
    for _ in 0..SWD_DIRECTIONS {
        // A uniformly random unit direction: normalized Gaussian components (Box-Muller).
        let mut dir: Vec<f64> = (0..dims)
            .map(|_| {
                let u1 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            })
            .collect();
        let norm = dir.iter().map(|d| d * d).sum::<f64>().sqrt().max(1e-12);
        dir.iter_mut().for_each(|d| *d /= norm);
        let project = |set: &[Vec<f32>]| {
            let mut p: Vec<f64> = set
                .iter()
                .map(|v| v.iter().zip(&dir).map(|(&x, d)| x as f64 * d).sum())
                .collect();
            p.sort_by(f64::total_cmp);
            p
        };
        let (pa, pb) = (project(a), project(b));
        let quantile = |p: &[f64], q: f64| p[((q * p.len() as f64) as usize).min(p.len() - 1)];
        total += (0..QUANTILES)
            .map(|i| {
                let q = (i as f64 + 0.5) / QUANTILES as f64;
                (quantile(&pa, q) - quantile(&pb, q)).abs()
            })
            .sum::<f64>()
            / QUANTILES as f64;
    }
    total / SWD_DIRECTIONS as f64
}

/// Radially averaged power spectrum of the images' luminance (mean of the colour channels,
/// mean removed, Hann-windowed), per [`SPECTRUM_BINS`] bins, averaged over the images.
pub fn radial_power(images: &[Image]) -> [f64; SPECTRUM_BINS] {
    let mut sums = [0.0f64; SPECTRUM_BINS];
    let mut counts = [0u64; SPECTRUM_BINS];
    let mut planner = rustfft::FftPlanner::<f64>::new();
    for img in images {
        let (w, h) = (img.width as usize, img.height as usize);
        let colour = (img.channels as usize).clamp(1, 3);
        let mut lum: Vec<f64> = (0..w * h)
            .map(|i| {
                let px = &img.pixels[i * img.channels as usize..];
                px[..colour].iter().map(|&b| b as f64).sum::<f64>() / colour as f64
            })
            .collect();
        let mean = lum.iter().sum::<f64>() / lum.len().max(1) as f64;
        let hann = |i: usize, n: usize| {
            0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n.max(2) as f64).cos()
        };
        let mut data: Vec<Complex<f64>> = lum
            .iter_mut()
            .enumerate()
            .map(|(i, v)| Complex::new((*v - mean) * hann(i % w, w) * hann(i / w, h), 0.0))
            .collect();
        let rows = planner.plan_fft_forward(w);
        for row in data.chunks_exact_mut(w) {
            rows.process(row);
        }
        let cols = planner.plan_fft_forward(h);
        let mut column = vec![Complex::new(0.0, 0.0); h];
        for x in 0..w {
            for y in 0..h {
                column[y] = data[y * w + x];
            }
            cols.process(&mut column);
            for y in 0..h {
                data[y * w + x] = column[y];
            }
        }
        for y in 0..h {
            for x in 0..w {
                let fx = (if x <= w / 2 {
                    x as f64
                } else {
                    x as f64 - w as f64
                }) / w as f64;
                let fy = (if y <= h / 2 {
                    y as f64
                } else {
                    y as f64 - h as f64
                }) / h as f64;
                let r = (fx * fx + fy * fy).sqrt();
                if r == 0.0 || r > 0.5 {
                    continue;
                }
                let bin = ((r / 0.5 * SPECTRUM_BINS as f64) as usize).min(SPECTRUM_BINS - 1);
                sums[bin] += data[y * w + x].norm_sqr() / (w * h) as f64;
                counts[bin] += 1;
            }
        }
    }
    std::array::from_fn(|i| sums[i] / counts[i].max(1) as f64)
}

/// RMS difference of the log10 radial power spectra of `images` and `reference`.
pub fn spectrum_distance(images: &[Image], reference: &Image) -> f64 {
    let (a, b) = (
        radial_power(images),
        radial_power(std::slice::from_ref(reference)),
    );
    let squares: f64 = a
        .iter()
        .zip(&b)
        .map(|(p, q)| ((p + 1e-6).log10() - (q + 1e-6).log10()).powi(2))
        .sum();
    (squares / SPECTRUM_BINS as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: u32, h: u32, seed: u64) -> Image {
        let mut img = Image::new(w, h, 1);
        let mut rng = SeededRng::new(seed);
        img.pixels
            .iter_mut()
            .for_each(|p| *p = rng.below(256) as u8);
        img
    }

    #[test]
    fn identical_distributions_score_near_zero_and_shifted_ones_do_not() {
        let a = noise(48, 48, 1);
        let b = noise(48, 48, 2);
        let same = score(std::slice::from_ref(&b), &a);
        assert!(same.swd[0] < 5.0, "{same:?}");
        assert!(same.spectrum < 0.2, "{same:?}");
        let mut dark = b.clone();
        dark.pixels.iter_mut().for_each(|p| *p /= 4);
        let far = score(&[dark], &a);
        assert!(
            far.swd[0] > 10.0 * same.swd[0].max(1.0),
            "{far:?} vs {same:?}"
        );
    }

    #[test]
    fn half_size_averages_blocks() {
        let mut img = Image::new(4, 2, 1);
        img.pixels = vec![0, 10, 20, 30, 40, 50, 60, 70];
        let half = half_size(&img);
        assert_eq!((half.width, half.height), (2, 1));
        assert_eq!(half.pixels, vec![25, 45]);
    }
}
