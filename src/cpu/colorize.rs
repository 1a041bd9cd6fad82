//! CPU reference of `wgsl/colorize.wgsl`: the colour channels of each output voxel, packed into
//! one u32, channel c from the source in bits 4c..4c+3 of `source`: 0 its cached value (the
//! rounded mean of its three exemplar pixels), a + 1 the pixel of exemplar a at the voxel's
//! coordinate in it, 4 the cached value mapped through the `--color matched` table
//! (`lazy::color_match`).

use super::synth_common::{brick_at, voxel_index};
use crate::contract::bricks::voxel_of;
use crate::contract::uniforms::ColorizeParams;
use rayon::prelude::*;

/// Colours of the bricks of the list in `p`: 64 per brick (x fastest), list order.
pub fn colorize(p: &ColorizeParams, level: &[u32], state: &[u32], bricks: &[u32]) -> Vec<u32> {
    let lo = [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z];
    let dims = [p.grid_x, p.grid_y, p.grid_z];
    let stride = 3 + p.ex.pixel_words as usize;
    let mask = if p.color_channels < 4 {
        (1u32 << (p.color_channels * 8)) - 1
    } else {
        u32::MAX
    };
    let mut out = vec![0u32; p.list_count as usize * 64];
    out.par_chunks_mut(64).enumerate().for_each(|(b, dst)| {
        let brick = brick_at(bricks, p.list_offset, b as u32);
        for (local, word) in dst.iter_mut().enumerate() {
            let pos = voxel_of(brick, local as u32);
            let Some(slot) = voxel_index(bricks, pos, lo, dims, p.table_offset) else {
                *word = 0; // never expected: output bricks are stored
                continue;
            };
            let i = slot * stride;
            let value = state[i + 3];
            let pixel = |a: usize| {
                let (x, y) = crate::contract::triple::unpack(state[i + a]);
                let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2][a];
                level[(pixels + (y * p.ex.width + x) * p.ex.pixel_words) as usize]
            };
            let value = (0..4).fold(0, |out, c| {
                let from = match (p.source >> (4 * c)) & 0xF {
                    0 => value,
                    4 => level[(p.match_table + ((value >> (c * 8)) & 0xFF)) as usize],
                    code => pixel(code as usize - 1),
                };
                out | (from & (0xFF << (c * 8)))
            });
            *word = value & mask;
        }
    });
    out
}
