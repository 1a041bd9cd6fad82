//! CPU reference of `wgsl/colorize.wgsl`: the colour of each voxel of the output box (the mean of
//! its three exemplar pixels), colour channels packed into one u32 per voxel.

use super::synth_common::{box_index, voxel_channel};
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
    let pixels = [p.pixels0, p.pixels1, p.pixels2];
    let mut out = vec![0u32; sx * sy * sz];
    out.par_chunks_mut(sx).enumerate().for_each(|(row, dst)| {
        let (y, z) = ((row % sy) as i32, (row / sy) as i32);
        for (x, word) in dst.iter_mut().enumerate() {
            let pos = [p.out_lo_x + x as i32, p.out_lo_y + y, p.out_lo_z + z];
            let i = box_index(pos, lo, size) * 3;
            let t = [state[i], state[i + 1], state[i + 2]];
            let mut packed = 0u32;
            for ch in 0..p.color_channels {
                packed |=
                    voxel_channel(level, pixels, p.pixel_words, p.ex_width, t, ch) << (ch * 8);
            }
            *word = packed;
        }
    });
    out
}
