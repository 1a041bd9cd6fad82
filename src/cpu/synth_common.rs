//! Helpers shared by the synthesis kernels' CPU references, one per WGSL helper function of the
//! same name (the shaders repeat them: WGSL has no includes).

use crate::analysis::frame::{pack, unpack};

/// Border::resolve with the kernels' code (0 wrap, 1 mirror).
#[inline]
pub fn resolve(c: i32, len: u32, border: u32) -> u32 {
    let n = len as i32;
    if border == 0 {
        return c.rem_euclid(n) as u32;
    }
    if n == 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let m = c.rem_euclid(period);
    (if m >= n { period - m } else { m }) as u32
}

/// Pack a coordinate after resolving it against the exemplar size.
#[inline]
pub fn pack_resolved(x: i32, y: i32, w: u32, h: u32, border: u32) -> u32 {
    pack(resolve(x, w, border), resolve(y, h, border))
}

#[inline]
pub fn coord(c: u32) -> (i32, i32) {
    let (x, y) = unpack(c);
    (x as i32, y as i32)
}

/// Box-local index of absolute voxel `p` in a box at `lo` of `size`.
#[inline]
pub fn box_index(p: [i32; 3], lo: [i32; 3], size: [u32; 3]) -> usize {
    ((((p[2] - lo[2]) as u32 * size[1]) + (p[1] - lo[1]) as u32) * size[0] + (p[0] - lo[0]) as u32)
        as usize
}

/// Byte `ch` of an exemplar pixel stored `pixel_words` words per pixel at word `base`.
#[inline]
pub fn pixel_byte(level: &[u32], base: u32, pixel_words: u32, width: u32, c: u32, ch: u32) -> u32 {
    let (x, y) = unpack(c);
    let word = level[(base + (y * width + x) * pixel_words + ch / 4) as usize];
    (word >> ((ch % 4) * 8)) & 0xFF
}

/// Word `w` of a voxel's value: channels 4w..4w+3 of the rounded mean of its three pixels.
#[inline]
pub fn value_word(
    level: &[u32],
    t: [u32; 3],
    w: u32,
    pixels: [u32; 3],
    width: u32,
    pixel_words: u32,
    channels: u32,
) -> u32 {
    let mut word = 0u32;
    for b in 0..4 {
        let ch = w * 4 + b;
        if ch < channels {
            let sum = pixel_byte(level, pixels[0], pixel_words, width, t[0], ch)
                + pixel_byte(level, pixels[1], pixel_words, width, t[1], ch)
                + pixel_byte(level, pixels[2], pixel_words, width, t[2], ch);
            word |= ((sum + 1) / 3) << (b * 8);
        }
    }
    word
}

/// Write a voxel (triple, then value words) into `dst` (stride 3 + pixel_words).
#[inline]
pub fn write_voxel(
    dst: &mut [u32],
    level: &[u32],
    t: [u32; 3],
    pixels: [u32; 3],
    width: u32,
    pixel_words: u32,
    channels: u32,
) {
    dst[..3].copy_from_slice(&t);
    for w in 0..pixel_words {
        dst[3 + w as usize] = value_word(level, t, w, pixels, width, pixel_words, channels);
    }
}
