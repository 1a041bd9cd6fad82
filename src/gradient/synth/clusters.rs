//! Colour quantization of the exemplar (paper 4.2.2, "Quantization"): k-means of its pixel
//! colours into N_T clusters, so a bucket can keep per-cluster counts instead of its samples and
//! average only the samples of its two dominant clusters (no blur across distinct colours).
//!
//! With a binary mask ([`quantize_regions`]) the clusters are allocated per region, as the paper
//! describes: one cluster for each region to start with, then each further cluster goes to the
//! region with the largest average quantization error, until all N_T are allocated; k-means runs
//! within each region, so every cluster holds the pixels of one region only.

use crate::exemplar::Image;

/// Lloyd iterations (the exemplar's colours converge quickly; the result only needs to separate
/// distinct colours, not be optimal).
const ITERATIONS: usize = 12;

/// Cluster id (0..k) of every pixel of `img`, row-major. Deterministic: the initial centres are
/// the pixels at evenly spaced ranks of luminance, so no seed is involved.
pub fn quantize(img: &Image, k: u32) -> Vec<u8> {
    let c = img.channels as usize;
    let pixels: Vec<&[u8]> = img.pixels.chunks_exact(c).collect();
    kmeans(&pixels, k as usize).0
}

/// K-means of `pixels` (deterministic, see [`quantize`]): the label of every pixel and the mean
/// squared distance of the pixels to their centres (the average quantization error).
fn kmeans(pixels: &[&[u8]], k: usize) -> (Vec<u8>, f64) {
    if pixels.is_empty() {
        return (Vec::new(), 0.0);
    }
    let c = pixels[0].len();
    let k = k.clamp(1, 255).min(pixels.len());
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
    let mut error = 0.0;
    for (i, p) in pixels.iter().enumerate() {
        let j = nearest(p, &centres);
        labels[i] = j as u8;
        error += p
            .iter()
            .zip(&centres[j])
            .map(|(&v, m)| (v as f64 - m).powi(2))
            .sum::<f64>();
    }
    (labels, error / pixels.len() as f64)
}

/// Mask-aware quantization (paper 4.2.2): `k` clusters of the first `colour_channels` channels
/// of `img`, each holding pixels of one region only (`positive[pixel]`). Starts from one cluster
/// per region; each further cluster goes to the region whose average quantization error is the
/// largest (ties: the positive region), which is then re-clustered with one more. A region
/// never gets more clusters than it has pixels. Returns the label of every pixel and, per
/// cluster, whether it belongs to the positive region (negative clusters come first).
pub fn quantize_regions(
    img: &Image,
    colour_channels: usize,
    positive: &[bool],
    k: u32,
) -> (Vec<u8>, Vec<bool>) {
    let c = img.channels as usize;
    let colours: Vec<&[u8]> = img
        .pixels
        .chunks_exact(c)
        .map(|p| &p[..colour_channels.min(c)])
        .collect();
    // Region 0: negative, region 1: positive.
    let members: [Vec<usize>; 2] = [false, true].map(|side| {
        (0..colours.len())
            .filter(|&i| positive[i] == side)
            .collect()
    });
    let pixels: [Vec<&[u8]>; 2] = [0, 1].map(|r| members[r].iter().map(|&i| colours[i]).collect());
    let present = |r: usize| !pixels[r].is_empty();
    let mut count = [present(0) as usize, present(1) as usize];
    let mut fits = [0, 1].map(|r| kmeans(&pixels[r], count[r]));
    let total = (k as usize).clamp(count[0] + count[1], 255);
    while count[0] + count[1] < total {
        let can_grow = |r: usize| count[r] > 0 && count[r] < pixels[r].len();
        let r = match (can_grow(0), can_grow(1)) {
            (false, false) => break,
            (true, false) => 0,
            (false, true) => 1,
            (true, true) => {
                if fits[0].1 > fits[1].1 {
                    0
                } else {
                    1
                }
            }
        };
        count[r] += 1;
        fits[r] = kmeans(&pixels[r], count[r]);
    }
    let mut labels = vec![0u8; colours.len()];
    for r in 0..2 {
        let offset = if r == 1 { count[0] } else { 0 };
        for (&i, &l) in members[r].iter().zip(&fits[r].0) {
            labels[i] = (offset + l as usize) as u8;
        }
    }
    let regions = (0..count[0] + count[1]).map(|j| j >= count[0]).collect();
    (labels, regions)
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
    #[test]
    fn mask_aware_clusters_are_region_pure_and_go_to_the_worse_region() {
        // Negative region (x < 20): one flat grey. Positive region: four distinct colours, one
        // of them equal to the grey (k-means over all pixels would merge the two greys).
        let (w, h) = (40u32, 8u32);
        let mut img = Image::new(w, h, 4);
        let mut positive = vec![false; (w * h) as usize];
        let palette = [[120, 120, 120], [250, 10, 10], [10, 250, 10], [10, 10, 250]];
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                positive[i] = x >= 20;
                let rgb = if x < 20 {
                    [120, 120, 120]
                } else {
                    palette[((x - 20) / 5) as usize]
                };
                img.pixels[i * 4..i * 4 + 3].copy_from_slice(&rgb);
                // A distance-like fourth channel that the clustering must ignore.
                img.pixels[i * 4 + 3] = (x * 6) as u8;
            }
        }
        let (labels, regions) = quantize_regions(&img, 3, &positive, 5);
        // One cluster is enough for the flat region: the other four go to the positive one.
        assert_eq!(regions, vec![false, true, true, true, true]);
        for (i, &l) in labels.iter().enumerate() {
            assert_eq!(regions[l as usize], positive[i], "pixel {i}");
        }
        // Each positive colour has its own cluster.
        let label_at = |x: u32| labels[x as usize];
        let distinct: std::collections::BTreeSet<u8> =
            [20, 25, 30, 35].into_iter().map(label_at).collect();
        assert_eq!(distinct.len(), 4);
        assert!((0..20).all(|x| label_at(x) == 0));
        // Swapped regions: the allocation follows the error, not the side.
        let flipped: Vec<bool> = positive.iter().map(|&p| !p).collect();
        let (labels, regions) = quantize_regions(&img, 3, &flipped, 5);
        assert_eq!(regions, vec![false, false, false, false, true]);
        for (i, &l) in labels.iter().enumerate() {
            assert_eq!(regions[l as usize], flipped[i], "pixel {i}");
        }
        // More clusters than a flat region can use still allocates all of them elsewhere, and a
        // region never gets more clusters than pixels.
        let (_, regions) = quantize_regions(&img, 3, &positive, 12);
        assert_eq!(regions.len(), 12);
    }
}
