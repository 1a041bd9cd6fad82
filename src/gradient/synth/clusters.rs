//! Colour quantization of the exemplar (paper 4.2.2, "Quantization"): k-means of its pixel
//! colours into N_T clusters, so a bucket can keep per-cluster counts instead of its samples and
//! average only the samples of its two dominant clusters (no blur across distinct colours).

use crate::exemplar::Image;

/// Lloyd iterations (the exemplar's colours converge quickly; the result only needs to separate
/// distinct colours, not be optimal).
const ITERATIONS: usize = 12;

/// Cluster id (0..k) of every pixel of `img`, row-major. Deterministic: the initial centres are
/// the pixels at evenly spaced ranks of luminance, so no seed is involved.
pub fn quantize(img: &Image, k: u32) -> Vec<u8> {
    let c = img.channels as usize;
    let pixels: Vec<&[u8]> = img.pixels.chunks_exact(c).collect();
    let k = (k as usize).clamp(1, 255).min(pixels.len());
    let luminance = |p: &[u8]| p.iter().map(|&v| v as u32).sum::<u32>();
    let mut by_luminance: Vec<usize> = (0..pixels.len()).collect();
    by_luminance.sort_by_key(|&i| (luminance(pixels[i]), i));
    let mut centres: Vec<Vec<f64>> = (0..k)
        .map(|j| {
            let rank = (2 * j + 1) * pixels.len() / (2 * k);
            pixels[by_luminance[rank]]
                .iter()
                .map(|&v| v as f64)
                .collect()
        })
        .collect();
    let nearest = |p: &[u8], centres: &[Vec<f64>]| -> usize {
        let mut best = (f64::INFINITY, 0);
        for (j, m) in centres.iter().enumerate() {
            let d: f64 = p.iter().zip(m).map(|(&v, m)| (v as f64 - m).powi(2)).sum();
            if d < best.0 {
                best = (d, j);
            }
        }
        best.1
    };
    let mut labels = vec![0u8; pixels.len()];
    for _ in 0..ITERATIONS {
        let mut sums = vec![vec![0f64; c]; k];
        let mut counts = vec![0usize; k];
        for (i, p) in pixels.iter().enumerate() {
            let j = nearest(p, &centres);
            labels[i] = j as u8;
            counts[j] += 1;
            for (s, &v) in sums[j].iter_mut().zip(p.iter()) {
                *s += v as f64;
            }
        }
        for j in 0..k {
            // An empty cluster keeps its centre (it may win pixels back later).
            if counts[j] > 0 {
                centres[j] = sums[j].iter().map(|s| s / counts[j] as f64).collect();
            }
        }
    }
    for (i, p) in pixels.iter().enumerate() {
        labels[i] = nearest(p, &centres) as u8;
    }
    labels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_distinct_colours() {
        // Three flat colours: three clusters, each colour in one of them.
        let mut img = Image::new(30, 1, 3);
        for x in 0..30u32 {
            let v = [[200, 10, 10], [10, 200, 10], [10, 10, 200]][(x / 10) as usize];
            img.pixels[(x * 3) as usize..(x * 3 + 3) as usize].copy_from_slice(&v);
        }
        let labels = quantize(&img, 3);
        for group in labels.chunks(10) {
            assert!(group.iter().all(|&l| l == group[0]), "{labels:?}");
        }
        assert_ne!(labels[0], labels[10]);
        assert_ne!(labels[10], labels[20]);
        assert_ne!(labels[0], labels[20]);
    }
}
