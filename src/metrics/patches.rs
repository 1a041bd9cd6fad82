//! Patch-level measures: exact nearest-neighbour RMS distances between 7x7 patches.

use super::PATCH;
use crate::exemplar::Image;
use crate::util::hash::SeededRng;
use rayon::prelude::*;

/// All patches of `img` whose top-left corners lie on a grid of `stride`, flattened.
fn patch_table(img: &Image, stride: u32) -> Vec<u8> {
    let c = img.channels as usize;
    let mut out = Vec::new();
    for y in (0..=img.height - PATCH).step_by(stride as usize) {
        for x in (0..=img.width - PATCH).step_by(stride as usize) {
            for dy in 0..PATCH {
                let row = ((y + dy) * img.width + x) as usize * c;
                out.extend_from_slice(&img.pixels[row..row + PATCH as usize * c]);
            }
        }
    }
    out
}

fn patch_at(img: &Image, x: u32, y: u32, out: &mut Vec<u8>) {
    let c = img.channels as usize;
    out.clear();
    for dy in 0..PATCH {
        let row = ((y + dy) * img.width + x) as usize * c;
        out.extend_from_slice(&img.pixels[row..row + PATCH as usize * c]);
    }
}

/// Smallest SSD from `query` to any patch of `table` (exact, with early exit per patch row).
fn nearest_ssd(query: &[u8], table: &[u8]) -> u64 {
    let len = query.len();
    let row = len / PATCH as usize;
    let mut best = u64::MAX;
    for cand in table.chunks_exact(len) {
        let mut d = 0u64;
        for r in 0..PATCH as usize {
            let (q, k) = (
                &query[r * row..(r + 1) * row],
                &cand[r * row..(r + 1) * row],
            );
            d += q
                .iter()
                .zip(k)
                .map(|(&a, &b)| ((a as i32 - b as i32) * (a as i32 - b as i32)) as u32)
                .sum::<u32>() as u64;
            if d >= best {
                break;
            }
        }
        best = best.min(d);
    }
    best
}

fn rms(ssd_sum: u64, count: usize, patch_len: usize) -> f64 {
    (ssd_sum as f64 / (count.max(1) * patch_len) as f64).sqrt()
}

/// Grid stride that keeps at most `cap` patches of an image.
fn stride_for(img: &Image, cap: u32) -> u32 {
    let n = ((img.width - PATCH + 1) as u64) * ((img.height - PATCH + 1) as u64);
    ((n as f64 / cap.max(1) as f64).sqrt().ceil() as u32).max(1)
}

/// For `samples` random patches of each image: RMS distance to the nearest reference patch.
pub fn coherence(
    images: &[Image],
    reference: &Image,
    samples: u32,
    max_reference: u32,
    seed: u64,
) -> f64 {
    let table = patch_table(reference, stride_for(reference, max_reference));
    let mut rng = SeededRng::new(seed);
    let mut queries = Vec::new();
    for img in images {
        for _ in 0..samples {
            let x = rng.below((img.width - PATCH + 1) as u64) as u32;
            let y = rng.below((img.height - PATCH + 1) as u64) as u32;
            queries.push((img, x, y));
        }
    }
    let total: u64 = queries
        .par_iter()
        .map_init(Vec::new, |buf, &(img, x, y)| {
            patch_at(img, x, y, buf);
            nearest_ssd(buf, &table)
        })
        .sum();
    rms(
        total,
        queries.len(),
        (PATCH * PATCH * reference.channels) as usize,
    )
}

/// For `samples` random reference patches: RMS distance to the nearest patch of any image (every
/// image patch, or a regular grid of them when there are more than `max_image_patches`).
pub fn completeness(
    images: &[Image],
    reference: &Image,
    samples: u32,
    max_image_patches: u32,
    seed: u64,
) -> f64 {
    let per_image = max_image_patches / images.len().max(1) as u32;
    let table: Vec<u8> = images
        .iter()
        .flat_map(|img| patch_table(img, stride_for(img, per_image)))
        .collect();
    let mut rng = SeededRng::new(seed);
    let queries: Vec<(u32, u32)> = (0..samples)
        .map(|_| {
            (
                rng.below((reference.width - PATCH + 1) as u64) as u32,
                rng.below((reference.height - PATCH + 1) as u64) as u32,
            )
        })
        .collect();
    let total: u64 = queries
        .par_iter()
        .map_init(Vec::new, |buf, &(x, y)| {
            patch_at(reference, x, y, buf);
            nearest_ssd(buf, &table)
        })
        .sum();
    rms(
        total,
        queries.len(),
        (PATCH * PATCH * reference.channels) as usize,
    )
}
