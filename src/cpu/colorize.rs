//! CPU reference of `wgsl/colorize.wgsl`: the colour channels of each output voxel, packed into
//! one u32: its cached value (the rounded mean of its three exemplar pixels), or, on request, the
//! pixel of one exemplar at the voxel's coordinate in it.

use super::synth_common::box_index;
use crate::kernel_types::ColorizeParams;
use rayon::prelude::*;

pub fn colorize(p: &ColorizeParams, level: &[u32], state: &[u32]) -> Vec<u32> {
    let (sx, sy, sz) = (
        p.out_size_x as usize,
        p.out_size_y as usize,
        p.out_size_z as usize,
    );
    let lo = [p.lo_x, p.lo_y, p.lo_z];
    let size = [p.size_x, p.size_y, p.size_z];
    let stride = 3 + p.pixel_words as usize;
    let mask = if p.color_channels < 4 {
        (1u32 << (p.color_channels * 8)) - 1
    } else {
        u32::MAX
    };
    let mut out = vec![0u32; sx * sy * sz];
    out.par_chunks_mut(sx).enumerate().for_each(|(row, dst)| {
        let (y, z) = ((row % sy) as i32, (row / sy) as i32);
        for (x, word) in dst.iter_mut().enumerate() {
            let pos = [p.out_lo_x + x as i32, p.out_lo_y + y, p.out_lo_z + z];
            let i = box_index(pos, lo, size) * stride;
            let value = if p.source == 0 {
                state[i + 3]
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
