//! Global statistics: value histograms and gradient orientations.

use crate::exemplar::Image;

/// Mean over channels of the 1D earth mover's distance between value distributions, / 255.
pub fn histogram_distance(images: &[Image], reference: &Image) -> f64 {
    let c = reference.channels as usize;
    let hist = |imgs: &[&Image], ch: usize| {
        let mut h = [0f64; 256];
        let mut n = 0f64;
        for img in imgs {
            for px in img.pixels.chunks_exact(c) {
                h[px[ch] as usize] += 1.0;
                n += 1.0;
            }
        }
        h.iter_mut().for_each(|v| *v /= n.max(1.0));
        h
    };
    let refs: Vec<&Image> = images.iter().collect();
    (0..c)
        .map(|ch| {
            let (a, b) = (hist(&refs, ch), hist(&[reference], ch));
            let (mut ca, mut cb, mut emd) = (0f64, 0f64, 0f64);
            for i in 0..256 {
                ca += a[i];
                cb += b[i];
                emd += (ca - cb).abs();
            }
            emd / 255.0
        })
        .sum::<f64>()
        / c as f64
}

/// Orientation bins over [0, pi).
pub const ORIENTATION_BINS: usize = 18;

/// Magnitude-weighted histogram of gradient orientations (Sobel on the mean of the colour
/// channels), normalized to sum 1, and the mean gradient magnitude. Orientation is taken modulo
/// pi (a gradient and its opposite describe the same edge direction).
pub fn orientation_histogram(images: &[&Image]) -> ([f64; ORIENTATION_BINS], f64) {
    let mut h = [0f64; ORIENTATION_BINS];
    let mut pixels = 0usize;
    for img in images {
        let c = img.channels.min(3) as usize;
        let lum = |x: u32, y: u32| -> f64 {
            let p = img.at(x, y);
            p[..c].iter().map(|&v| v as f64).sum::<f64>() / c as f64
        };
        for y in 1..img.height.saturating_sub(1) {
            for x in 1..img.width.saturating_sub(1) {
                pixels += 1;
                let gx = (lum(x + 1, y - 1) + 2.0 * lum(x + 1, y) + lum(x + 1, y + 1))
                    - (lum(x - 1, y - 1) + 2.0 * lum(x - 1, y) + lum(x - 1, y + 1));
                let gy = (lum(x - 1, y + 1) + 2.0 * lum(x, y + 1) + lum(x + 1, y + 1))
                    - (lum(x - 1, y - 1) + 2.0 * lum(x, y - 1) + lum(x + 1, y - 1));
                let mag = (gx * gx + gy * gy).sqrt();
                if mag < 1e-9 {
                    continue;
                }
                let mut angle = gy.atan2(gx);
                if angle < 0.0 {
                    angle += std::f64::consts::PI;
                }
                let bin = ((angle / std::f64::consts::PI) * ORIENTATION_BINS as f64) as usize;
                h[bin.min(ORIENTATION_BINS - 1)] += mag;
            }
        }
    }
    let total: f64 = h.iter().sum();
    if total > 0.0 {
        h.iter_mut().for_each(|v| *v /= total);
    }
    (h, total / pixels.max(1) as f64)
}

/// Total-variation distance between the orientation histograms of `images` and `reference`.
/// An image with no gradient at all (flat) scores 1 against a textured reference.
pub fn orientation_distance(images: &[Image], reference: &Image) -> f64 {
    let refs: Vec<&Image> = images.iter().collect();
    let (a, b) = (
        orientation_histogram(&refs).0,
        orientation_histogram(&[reference]).0,
    );
    let a_sum: f64 = a.iter().sum();
    let b_sum: f64 = b.iter().sum();
    if a_sum == 0.0 || b_sum == 0.0 {
        return if a_sum == b_sum { 0.0 } else { 1.0 };
    }
    0.5 * a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f64>()
}

/// |ln(mean gradient magnitude of `images` / that of `reference`)|: 0 when edges are as strong as
/// in the exemplar; grows with noise (too sharp) and with blur (too soft).
pub fn sharpness_distance(images: &[Image], reference: &Image) -> f64 {
    let refs: Vec<&Image> = images.iter().collect();
    let (a, b) = (
        orientation_histogram(&refs).1,
        orientation_histogram(&[reference]).1,
    );
    ((a + 1.0) / (b + 1.0)).ln().abs()
}
