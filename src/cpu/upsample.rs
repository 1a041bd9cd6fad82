//! CPU reference of `wgsl/upsample.wgsl`: coordinate inheritance. Child (i, j, k) of parent
//! (i/2, j/2, k/2) (floor division) takes, for exemplar a, 2 * parent_a + (offset along axis a+1,
//! offset along axis a+2): Ex + (j%2, k%2), Ey + (k%2, i%2), Ez + (i%2, j%2). The child's value is
//! computed from the child level's exemplar pixels.

use super::synth_common::{brick_at, coord, pack_resolved, voxel_index, write_voxel};
use crate::contract::bricks::voxel_of;
use crate::contract::uniforms::UpsampleParams;
use rayon::prelude::*;

/// `level` is the child level's data (for the voxel values).
/// The child state (64 voxels per brick, list order) of the bricks of the list in `p`, from
/// the parent state; `bricks` is the child's brick index (holding a copy of the parent's table).
pub fn upsample(p: &UpsampleParams, level: &[u32], parent: &[u32], bricks: &[u32]) -> Vec<u32> {
    let stride = 3 + p.ex.pixel_words as usize;
    let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2];
    let mut out = vec![0u32; p.list_count as usize * 64 * stride];
    let plo = [p.parent_grid_lo_x, p.parent_grid_lo_y, p.parent_grid_lo_z];
    let pdims = [p.parent_grid_x, p.parent_grid_y, p.parent_grid_z];
    out.par_chunks_mut(64 * stride)
        .enumerate()
        .for_each(|(slot, dst)| {
            let brick = brick_at(bricks, p.list_offset, slot as u32);
            for x in 0..64usize {
                let c = voxel_of(brick, x as u32);
                let par = c.map(|v| v >> 1);
                let o = [c[0] - 2 * par[0], c[1] - 2 * par[1], c[2] - 2 * par[2]];
                // The plan stores every parent; a missing one (never expected) reads as 0.
                let pslot = voxel_index(bricks, par, plo, pdims, p.parent_table);
                let offsets = [(o[1], o[2]), (o[2], o[0]), (o[0], o[1])];
                let t: [u32; 3] = std::array::from_fn(|a| {
                    let (px, py) = coord(pslot.map_or(0, |s| parent[s * stride + a]));
                    pack_resolved(
                        2 * px + offsets[a].0,
                        2 * py + offsets[a].1,
                        p.ex.width,
                        p.ex.height,
                        p.ex.border,
                    )
                });
                let voxel = &mut dst[x * stride..(x + 1) * stride];
                write_voxel(
                    voxel,
                    level,
                    t,
                    pixels,
                    p.ex.width,
                    p.ex.pixel_words,
                    p.ex.channels,
                );
            }
        });
    out
}
