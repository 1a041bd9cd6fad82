//! CPU reference of `wgsl/upsample.wgsl`: coordinate inheritance. Child (i, j, k) of parent
//! (i/2, j/2, k/2) (floor division) takes, for exemplar a, 2 * parent_a + (offset along axis a+1,
//! offset along axis a+2): Ex + (j%2, k%2), Ey + (k%2, i%2), Ez + (i%2, j%2). The child's value is
//! computed from the child level's exemplar pixels.

use super::synth_common::{box_index, coord, pack_resolved, write_voxel};
use crate::kernel_types::UpsampleParams;
use rayon::prelude::*;

/// `level` is the child level's data (for the voxel values).
pub fn upsample(p: &UpsampleParams, level: &[u32], parent: &[u32]) -> Vec<u32> {
    let (sx, sy, sz) = (
        p.child_size_x as usize,
        p.child_size_y as usize,
        p.child_size_z as usize,
    );
    let stride = 3 + p.pixel_words as usize;
    let pixels = [p.pixels0, p.pixels1, p.pixels2];
    let mut out = vec![0u32; sx * sy * sz * stride];
    let plo = [p.parent_lo_x, p.parent_lo_y, p.parent_lo_z];
    let psize = [p.parent_size_x, p.parent_size_y, p.parent_size_z];
    out.par_chunks_mut(sx * stride)
        .enumerate()
        .for_each(|(row, dst)| {
            let (y, z) = ((row % sy) as i32, (row / sy) as i32);
            for x in 0..sx {
                let c = [p.child_lo_x + x as i32, p.child_lo_y + y, p.child_lo_z + z];
                let par = c.map(|v| v >> 1);
                let o = [c[0] - 2 * par[0], c[1] - 2 * par[1], c[2] - 2 * par[2]];
                let i = box_index(par, plo, psize) * stride;
                let offsets = [(o[1], o[2]), (o[2], o[0]), (o[0], o[1])];
                let t: [u32; 3] = std::array::from_fn(|a| {
                    let (px, py) = coord(parent[i + a]);
                    pack_resolved(
                        2 * px + offsets[a].0,
                        2 * py + offsets[a].1,
                        p.ex_width,
                        p.ex_height,
                        p.border,
                    )
                });
                let voxel = &mut dst[x * stride..(x + 1) * stride];
                write_voxel(
                    voxel,
                    level,
                    t,
                    pixels,
                    p.ex_width,
                    p.pixel_words,
                    p.channels,
                );
            }
        });
    out
}
