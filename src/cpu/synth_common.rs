//! Helpers shared by the synthesis kernels' CPU references, one per WGSL helper function of the
//! same name (the shaders repeat them: WGSL has no includes).

use crate::contract::triple::{pack, unpack};

/// Border::resolve with the kernels' code (0 wrap, 1 mirror).
#[inline]
pub fn resolve(c: i32, len: u32, border: u32) -> u32 {
    let n = len as i32;
    // Inside the exemplar (nearly always): no division.
    if (0..n).contains(&c) {
        return c as u32;
    }
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

/// Brick `i` of the list starting at word `list` of a brick index (`brick_at` in WGSL).
#[inline]
pub fn brick_at(bricks: &[u32], list: u32, i: u32) -> [i32; 3] {
    let e = (list + 3 * i) as usize;
    [bricks[e] as i32, bricks[e + 1] as i32, bricks[e + 2] as i32]
}

/// Index of voxel `p` in a state whose brick table (over the bricks `grid_lo + [0, dims)`)
/// starts at word `table`; None when its brick is not stored (`voxel_index` in WGSL).
#[inline]
pub fn voxel_index(
    bricks: &[u32],
    p: [i32; 3],
    grid_lo: [i32; 3],
    dims: [u32; 3],
    table: u32,
) -> Option<usize> {
    let d = [
        (p[0] >> 2) - grid_lo[0],
        (p[1] >> 2) - grid_lo[1],
        (p[2] >> 2) - grid_lo[2],
    ];
    // (Negative values wrap to large u32s: one comparison per axis.)
    if d[0] as u32 >= dims[0] || d[1] as u32 >= dims[1] || d[2] as u32 >= dims[2] {
        return None;
    }
    let cell = (d[2] as u32 * dims[1] + d[1] as u32) * dims[0] + d[0] as u32;
    let slot = bricks[(table + cell) as usize];
    (slot != crate::contract::bricks::ABSENT)
        .then(|| slot as usize * 64 + crate::contract::bricks::local_index(p) as usize)
}

/// [`voxel_index`] of `p` wrapped into a periodic state's period `period` (0: not periodic)
/// (`voxel_index_wrapped` in WGSL).
#[inline(always)]
pub fn voxel_index_wrapped(
    bricks: &[u32],
    p: [i32; 3],
    grid_lo: [i32; 3],
    dims: [u32; 3],
    table: u32,
    period: u32,
) -> Option<usize> {
    let p = match period {
        0 => p,
        n => {
            let n = n as i32;
            // (No division for the positions already inside the period: nearly all.)
            p.map(|v| {
                if (0..n).contains(&v) {
                    v
                } else if (-n..0).contains(&v) {
                    v + n
                } else {
                    v.rem_euclid(n)
                }
            })
        }
    };
    voxel_index(bricks, p, grid_lo, dims, table)
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
