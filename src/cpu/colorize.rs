//! CPU reference of `wgsl/colorize.wgsl`: the colour channels of each output voxel, packed into
//! one u32, channel c from the source in bits 4c..4c+3 of `source`: 0 its cached value (the
//! rounded mean of its three exemplar pixels), a + 1 the pixel of exemplar a at the voxel's
//! coordinate in it, 4 the cached value mapped through the `--color matched` table
//! (`lazy::color_match`), 5 the fitted weighting of the three pixels ([`fitted`]).

use super::synth_common::{brick_at, resolve, voxel_index_wrapped};
use crate::contract::bricks::voxel_of;
use crate::contract::uniforms::{ColorizeParams, FITTED_REACH};
use rayon::prelude::*;

/// Colours of the bricks of the list in `p`: 64 per brick (x fastest), list order.
pub fn colorize(p: &ColorizeParams, level: &[u32], state: &[u32], bricks: &[u32]) -> Vec<u32> {
    let stride = 3 + p.ex.pixel_words as usize;
    let mask = color_mask(p.color_channels);
    let wants_fitted = (0..4).any(|c| (p.source >> (4 * c)) & 0xF == 5);
    let mut out = vec![0u32; p.list_count as usize * 64];
    out.par_chunks_mut(64).enumerate().for_each(|(b, dst)| {
        let brick = brick_at(bricks, p.list_offset, b as u32);
        for (local, word) in dst.iter_mut().enumerate() {
            let pos = voxel_of(brick, local as u32);
            let Some(slot) = state_slot(p, bricks, pos) else {
                *word = 0; // never expected: output bricks are stored
                continue;
            };
            let i = slot * stride;
            let value = state[i + 3];
            let pixel = |a: usize| {
                let (x, y) = crate::contract::triple::unpack(state[i + a]);
                exemplar_word(p, level, a, x as i32, y as i32)
            };
            let fitted = match wants_fitted {
                true => fitted(p, level, state, bricks, pos, [0, 1, 2].map(|a| state[i + a])),
                false => 0,
            };
            let value = (0..4).fold(0, |out, c| {
                let from = match (p.source >> (4 * c)) & 0xF {
                    0 => value,
                    4 => level[(p.match_table + ((value >> (c * 8)) & 0xFF)) as usize],
                    5 => fitted,
                    code => pixel(code as usize - 1),
                };
                out | (from & (0xFF << (c * 8)))
            });
            *word = value & mask;
        }
    });
    out
}

/// The bytes of a value word that hold colour channels.
fn color_mask(color_channels: u32) -> u32 {
    match color_channels < 4 {
        true => (1u32 << (color_channels * 8)) - 1,
        false => u32::MAX,
    }
}

/// Index of voxel `pos` in the finest level's state (wrapped into the period of a tileable
/// solid); None when its brick is not stored.
fn state_slot(p: &ColorizeParams, bricks: &[u32], pos: [i32; 3]) -> Option<usize> {
    let lo = [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z];
    let dims = [p.grid_x, p.grid_y, p.grid_z];
    voxel_index_wrapped(bricks, pos, lo, dims, p.table_offset, p.period)
}

/// Word 0 of exemplar `a`'s pixel at (x, y), resolved against its border.
fn exemplar_word(p: &ColorizeParams, level: &[u32], a: usize, x: i32, y: i32) -> u32 {
    let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2][a];
    let x = resolve(x, p.ex.width, p.ex.border);
    let y = resolve(y, p.ex.height, p.ex.border);
    level[(pixels + (y * p.ex.width + x) * p.ex.pixel_words) as usize]
}

/// Squared distance between the colour channels of two value words.
fn color_distance(a: u32, b: u32, color_channels: u32) -> u32 {
    (0..color_channels.min(4))
        .map(|c| {
            let d = ((a >> (8 * c)) & 0xFF) as i32 - ((b >> (8 * c)) & 0xFF) as i32;
            (d * d) as u32
        })
        .sum()
}

/// The fitted colour of the voxel at `pos` with coordinates `triple`: its three exemplar pixels
/// weighted by how well each plane fits. Plane a's misfit D_a is the squared distance between
/// the mean colours of the 5x5 plane through the voxel (columns along axis a + 1, rows along
/// a + 2, as the correction reads them) and exemplar a's 5x5 window around the voxel's
/// coordinate in it. Weights in integers, so every backend gives the same bytes: q_a =
/// 256 (D_min + 1) / (D_a + 1) (at most 256, for the best plane), w_a = q_a^2, and each colour
/// channel is the rounded mean sum(w_a pixel_a) / sum(w_a). A plane whose neighbourhood does not
/// look like its exemplar there (a pixel that continues no structure of the solid) then counts
/// less than in the paper's plain mean; planes that fit equally keep the mean.
fn fitted(
    p: &ColorizeParams,
    level: &[u32],
    state: &[u32],
    bricks: &[u32],
    pos: [i32; 3],
    triple: [u32; 3],
) -> u32 {
    let stride = 3 + p.ex.pixel_words as usize;
    let mean_at = |n: [i32; 3]| state_slot(p, bricks, n).map_or(0, |s| state[s * stride + 3]);
    let mut misfit = [0u32; 3];
    let mut pixels = [0u32; 3];
    for a in 0..3 {
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let (x, y) = crate::contract::triple::unpack(triple[a]);
        let (x, y) = (x as i32, y as i32);
        pixels[a] = exemplar_word(p, level, a, x, y);
        for dv in -FITTED_REACH..=FITTED_REACH {
            for du in -FITTED_REACH..=FITTED_REACH {
                let mut n = pos;
                n[ua] += du;
                n[va] += dv;
                let exemplar = exemplar_word(p, level, a, x + du, y + dv);
                misfit[a] += color_distance(mean_at(n), exemplar, p.color_channels);
            }
        }
    }
    let best = *misfit.iter().min().expect("three planes");
    let weights = misfit.map(|d| {
        let q = ((best + 1) << 8) / (d + 1);
        q * q
    });
    let total: u32 = weights.iter().sum();
    (0..p.color_channels.min(4)).fold(0, |out, c| {
        let sum: u32 = (0..3)
            .map(|a| weights[a] * ((pixels[a] >> (8 * c)) & 0xFF))
            .sum();
        out | ((sum + total / 2) / total) << (8 * c)
    })
}
