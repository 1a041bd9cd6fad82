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
}
