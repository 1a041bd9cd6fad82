//! CPU reference of `wgsl/colorize.wgsl`: the colour channels of each output voxel, packed into
//! one u32: its cached value (the rounded mean of its three exemplar pixels), or, on request, the
//! pixel of one exemplar at the voxel's coordinate in it, or the cached value mapped channel by
//! channel through the `--color matched` table (`lazy::color_match`).

use super::synth_common::{brick_at, voxel_index};
use crate::kernel_types::ColorizeParams;
use crate::lazy::bricks::voxel_of;
use rayon::prelude::*;

/// Colours of the bricks of the list in `p`: 64 per brick (x fastest), list order.
pub fn colorize(p: &ColorizeParams, level: &[u32], state: &[u32], bricks: &[u32]) -> Vec<u32> {
    let lo = [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z];
    let dims = [p.grid_x, p.grid_y, p.grid_z];
    let stride = 3 + p.pixel_words as usize;
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
            let value = if p.source == 0 {
                state[i + 3]
            } else if p.source == 4 {
                let value = state[i + 3];
                (0..4).fold(0, |mapped, c| {
                    let k = (value >> (c * 8)) & 0xFF;
                    mapped | (level[(p.match_table + k) as usize] & (0xFF << (c * 8)))
                })
            } else {
                let a = (p.source - 1) as usize;
                let (x, y) = crate::analysis::frame::unpack(state[i + a]);
                let pixels = [p.pixels0, p.pixels1, p.pixels2][a];
                level[(pixels + (y * p.ex_width + x) * p.pixel_words) as usize]
            };
            *word = value & mask;
        }
    });
    out
}
