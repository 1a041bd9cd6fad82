//! The feature-distance channel (Lefebvre-Hoppe 2006, Kopf et al. 2007): the signed Euclidean
//! distance of each pixel to the boundary of a user mask, stored as one more 8-bit channel so
//! neighbourhood matching preserves the shapes the mask outlines.

use super::{Border, Image};
use crate::error::{Error, Result};

/// Distance in pixels (at the finest level) that maps to the full 8-bit range on each side.
pub const FEATURE_RANGE_PX: f32 = 12.0;

/// Squared distance transform of a 1D sampled function (Felzenszwalb-Huttenlocher 2012): `out`
/// gets min over p of (q - p)^2 + f(p); `v` and `z` are scratch of `f.len()` and `f.len() + 1`.
pub(crate) fn edt_1d(f: &[f32], out: &mut [f32], v: &mut [usize], z: &mut [f32]) {
    let n = f.len();
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f32::NEG_INFINITY;
    z[1] = f32::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f32) - (f[p] + (p * p) as f32)) / (2.0 * (q - p) as f32);
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0 and the parabola at q dominates from -inf.
                v[0] = q;
                z[0] = f32::NEG_INFINITY;
                z[1] = f32::INFINITY;
                break;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f32::INFINITY;
            break;
        }
    }
    k = 0;
    for q in 0..n {
        while z[k + 1] < q as f32 {
            k += 1;
        }
        let d = q as f32 - v[k] as f32;
        out[q] = d * d + f[v[k]];
    }
}

/// Squared Euclidean distance from every pixel to the nearest pixel where `seed` is true.
fn squared_distance_to(seed: &[bool], w: usize, h: usize) -> Vec<f32> {
    const FAR: f32 = 1e12;
    let mut grid: Vec<f32> = seed.iter().map(|&s| if s { 0.0 } else { FAR }).collect();
    let n = w.max(h);
    let (mut f, mut out, mut v, mut z) = (
        vec![0f32; n],
        vec![0f32; n],
        vec![0usize; n],
        vec![0f32; n + 1],
    );
    for x in 0..w {
        for y in 0..h {
            f[y] = grid[y * w + x];
        }
        edt_1d(&f[..h], &mut out[..h], &mut v, &mut z);
        for y in 0..h {
            grid[y * w + x] = out[y];
        }
    }
    for y in 0..h {
        f[..w].copy_from_slice(&grid[y * w..(y + 1) * w]);
        edt_1d(&f[..w], &mut out[..w], &mut v, &mut z);
        grid[y * w..(y + 1) * w].copy_from_slice(&out[..w]);
    }
    grid
}

/// Build the feature channel from a mask image (any channels; a pixel is "inside" when its first
/// channel is >= 128). Inside pixels get 128 + distance to the outside, outside pixels 128 -
/// distance to the inside, scaled so [`FEATURE_RANGE_PX`] spans 127 levels. The distance
/// transform ignores `border` wrap-around: distances are measured within the image.
pub fn feature_channel(
    mask: &Image,
    exemplar: &Image,
    what: &str,
    _border: Border,
) -> Result<Image> {
    mask.check(what)?;
    if (mask.width, mask.height) != (exemplar.width, exemplar.height) {
        return Err(Error::invalid(
            what,
            format!(
                "mask is {}x{} but the exemplar is {}x{}",
                mask.width, mask.height, exemplar.width, exemplar.height
            ),
        ));
    }
    let (w, h) = (mask.width as usize, mask.height as usize);
    let inside: Vec<bool> = mask
        .pixels
        .chunks_exact(mask.channels as usize)
        .map(|p| p[0] >= 128)
        .collect();
    if inside.iter().all(|&b| b) || inside.iter().all(|&b| !b) {
        return Err(Error::invalid(
            what,
            "mask has no boundary: it is all inside or all outside (threshold 128)",
        ));
    }
    let outside: Vec<bool> = inside.iter().map(|&b| !b).collect();
    let d_to_outside = squared_distance_to(&outside, w, h);
    let d_to_inside = squared_distance_to(&inside, w, h);
    let scale = 127.0 / FEATURE_RANGE_PX;
    let mut out = Image::new(mask.width, mask.height, 1);
    for i in 0..w * h {
        let signed = if inside[i] {
            d_to_outside[i].sqrt() - 0.5
        } else {
            0.5 - d_to_inside[i].sqrt()
        };
        out.pixels[i] = (128.0 + signed * scale).round().clamp(0.0, 255.0) as u8;
    }
    Ok(out)
}

/// Integer luminance (BT.601 weights) of a pixel: gray and gray+alpha images use their first
/// channel, colour images the weighted sum of the first three; alpha is ignored.
fn luminance(pixel: &[u8]) -> u8 {
    match pixel.len() {
        1 | 2 => pixel[0],
        _ => {
            ((77 * pixel[0] as u32 + 150 * pixel[1] as u32 + 29 * pixel[2] as u32 + 128) >> 8) as u8
        }
    }
}

/// Otsu's threshold of a 256-bin histogram: the t maximizing the between-class variance of
/// {< t} and {>= t} (the first such t; `None` when no t leaves both classes non-empty).
fn otsu_threshold(histogram: &[u64; 256]) -> Option<u8> {
    let total: u64 = histogram.iter().sum();
    let weighted: f64 = histogram
        .iter()
        .enumerate()
        .map(|(v, &n)| v as f64 * n as f64)
        .sum();
    let (mut below, mut below_weighted) = (0u64, 0f64);
    let mut best: Option<(f64, u8)> = None;
    for t in 1..256usize {
        below += histogram[t - 1];
        below_weighted += (t - 1) as f64 * histogram[t - 1] as f64;
        let above = total - below;
        if below == 0 || above == 0 {
            continue;
        }
        let mean_below = below_weighted / below as f64;
        let mean_above = (weighted - below_weighted) / above as f64;
        let spread = below as f64 * above as f64 * (mean_below - mean_above).powi(2);
        if best.is_none_or(|(b, _)| spread > b) {
            best = Some((spread, t as u8));
        }
    }
    best.map(|(_, t)| t)
}

/// `values` (one byte per pixel, row-major) split in two by Otsu's threshold: 255 where a value
/// is at or above it (`inside_above`) or below it (otherwise), else 0. `None` when all values
/// are equal.
fn otsu_mask(width: u32, height: u32, values: &[u8], inside_above: bool) -> Option<Image> {
    let mut histogram = [0u64; 256];
    for &v in values {
        histogram[v as usize] += 1;
    }
    let threshold = otsu_threshold(&histogram)?;
    let mut mask = Image::new(width, height, 1);
    for (m, &v) in mask.pixels.iter_mut().zip(values) {
        *m = if (v >= threshold) == inside_above {
            255
        } else {
            0
        };
    }
    Some(mask)
}

/// The automatic feature mask of an exemplar: its luminance thresholded by Otsu's method
/// (255 where the luminance is at or above the threshold). Lefebvre and Hoppe 2006 and Kopf et
/// al. 2007 take the feature distance from a binary mask of the exemplar's structure (mortar
/// against bricks, gaps against stones); a two-class split of the luminance is the simplest
/// such mask and needs no user input. `None` for an exemplar with a single luminance value.
pub fn auto_mask(exemplar: &Image) -> Option<Image> {
    let channels = exemplar.channels as usize;
    let values: Vec<u8> = exemplar
        .pixels
        .chunks_exact(channels)
        .map(luminance)
        .collect();
    otsu_mask(exemplar.width, exemplar.height, &values, true)
}

/// The edge feature mask of an exemplar: 0 on its strong edges, 255 elsewhere. The luminance
/// gradient's magnitude (central differences, `border` past the edges), scaled so its maximum
/// is 255, is thresholded by Otsu's method. The feature channel is then the distance to the
/// nearest strong edge: suited to cells, mortar grids and cracks whose regions differ in colour
/// but not in luminance. `None` for an exemplar without any gradient.
pub fn edge_mask(exemplar: &Image, border: Border) -> Option<Image> {
    let (w, h) = (exemplar.width as i32, exemplar.height as i32);
    let lum = |x: i32, y: i32| luminance(exemplar.at_border(x, y, border)) as i32;
    let squared: Vec<i32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            (lum(x + 1, y) - lum(x - 1, y)).pow(2) + (lum(x, y + 1) - lum(x, y - 1)).pow(2)
        })
        .collect();
    let magnitude: Vec<u32> = squared.iter().map(|&g| (g as u32).isqrt()).collect();
    let max = *magnitude.iter().max()?;
    if max == 0 {
        return None;
    }
    let values: Vec<u8> = magnitude.iter().map(|&g| (g * 255 / max) as u8).collect();
    otsu_mask(exemplar.width, exemplar.height, &values, false)
}

/// One feature mask per exemplar from `mask_of`, or none at all when one of them has no mask
/// (the feature channel is all or nothing).
fn masks_of(exemplars: &[Image], mask_of: impl Fn(&Image) -> Option<Image>) -> Vec<Image> {
    exemplars
        .iter()
        .map(mask_of)
        .collect::<Option<Vec<_>>>()
        .unwrap_or_default()
}

/// [`auto_mask`] of each exemplar (or none, see `masks_of`).
pub fn auto_masks(exemplars: &[Image]) -> Vec<Image> {
    masks_of(exemplars, auto_mask)
}

/// [`edge_mask`] of each exemplar (or none, see `masks_of`).
pub fn edge_masks(exemplars: &[Image], border: Border) -> Vec<Image> {
    masks_of(exemplars, |e| edge_mask(e, border))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_matches_brute_force() {
        let (w, h) = (23usize, 17usize);
        let seed: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 31 == 0).collect();
        let fast = squared_distance_to(&seed, w, h);
        for y in 0..h {
            for x in 0..w {
                let mut best = f32::INFINITY;
                for sy in 0..h {
                    for sx in 0..w {
                        if seed[sy * w + sx] {
                            let d =
                                ((x as f32 - sx as f32).powi(2)) + (y as f32 - sy as f32).powi(2);
                            best = best.min(d);
                        }
                    }
                }
                assert_eq!(fast[y * w + x], best, "at {x},{y}");
            }
        }
    }

    #[test]
    fn feature_channel_is_signed_around_128() {
        let mut mask = Image::new(32, 32, 1);
        for y in 8..24 {
            for x in 8..24 {
                mask.pixels[y * 32 + x] = 255;
            }
        }
        let ex = Image::new(32, 32, 3);
        let f = feature_channel(&mask, &ex, "--feature-mask", Border::Mirror).unwrap();
        assert!(f.at(16, 16)[0] > 128 + 40);
        assert!(f.at(0, 0)[0] < 128 - 40);
        assert!(f.at(8, 16)[0] >= 128 && f.at(7, 16)[0] < 128);
        let wrong = Image::new(31, 32, 1);
        assert!(feature_channel(&wrong, &ex, "--feature-mask", Border::Mirror).is_err());
    }
    #[test]
    fn otsu_splits_two_clusters_between_them() {
        let mut h = [0u64; 256];
        h[40] = 100;
        h[200] = 50;
        let t = otsu_threshold(&h).unwrap();
        assert!((41..=200).contains(&t), "threshold {t}");
        let mut flat = [0u64; 256];
        flat[90] = 10;
        assert_eq!(otsu_threshold(&flat), None);
    }

    #[test]
    fn auto_mask_separates_dark_lines_from_bright_blocks() {
        // Bright 12x12 blocks with a dark 4-pixel joint: the joint is outside, blocks inside.
        let mut ex = Image::new(32, 32, 3);
        for y in 0..32u32 {
            for x in 0..32u32 {
                let joint = x % 16 < 4 || y % 16 < 4;
                let v = if joint {
                    30
                } else {
                    180 + ((x * 7 + y * 3) % 20) as u8
                };
                let i = ((y * 32 + x) * 3) as usize;
                ex.pixels[i..i + 3].copy_from_slice(&[v, v / 2, v / 3]);
            }
        }
        let m = auto_mask(&ex).unwrap();
        assert_eq!(m.at(1, 8)[0], 0);
        assert_eq!(m.at(8, 8)[0], 255);
        assert!(feature_channel(&m, &ex, "auto", Border::Wrap).is_ok());
        let flat = Image::new(8, 8, 3);
        assert!(auto_mask(&flat).is_none());
        assert!(auto_masks(&[ex.clone(), flat.clone()]).is_empty());
        assert_eq!(auto_masks(&[ex.clone(), ex.clone()]).len(), 2);
        // The edge mask: the joint's two sides are edges (0), the joint's and the blocks'
        // middles are not (the blocks' texture is faint against the joint's step).
        let e = edge_mask(&ex, Border::Wrap).unwrap();
        assert_eq!(e.at(4, 8)[0], 0);
        assert_eq!(e.at(15, 8)[0], 0);
        assert_eq!(e.at(10, 10)[0], 255);
        assert_eq!(e.at(1, 1)[0], 255);
        assert!(edge_mask(&flat, Border::Wrap).is_none());
        assert!(edge_masks(&[ex.clone(), flat], Border::Wrap).is_empty());
        assert_eq!(edge_masks(&[ex], Border::Mirror).len(), 1);
    }
}
