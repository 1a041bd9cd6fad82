//! CPU reference of `wgsl/scatter.wgsl`: a correction sub-pass's records (one per listed class
//! voxel, list order, stride words each) written into the state at the voxels the sub-pass
//! updated. The CPU backend itself keeps its updates in the workers' parts and does not need it;
//! the GPU backend's correction writes records so that it needs no second full state.

use super::synth_common::{brick_at, voxel_index};
use crate::kernel_types::ScatterParams;

pub fn scatter(p: &ScatterParams, updates: &[u32], state: &mut [u32], bricks: &[u32]) {
    let stride = p.stride as usize;
    let lo = [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z];
    let dims = [p.grid_x, p.grid_y, p.grid_z];
    let class = [p.class_x as i32, p.class_y as i32, p.class_z as i32];
    for tid in 0..p.list_count * 8 {
        let (b, k) = (tid / 8, tid % 8);
        let mask = bricks[(p.mask_offset + b / 4) as usize] >> ((b % 4) * 8 + k);
        if mask & 1 == 0 {
            continue; // not updated in this sub-pass
        }
        let brick = brick_at(bricks, p.list_offset, b);
        let bits = [k & 1, (k >> 1) & 1, k >> 2];
        let pos: [i32; 3] = std::array::from_fn(|a| brick[a] * 4 + class[a] + 2 * bits[a] as i32);
        let Some(slot) = voxel_index(bricks, pos, lo, dims, p.table_offset) else {
            continue; // never expected: updated voxels are stored
        };
        let (to, from) = (slot * stride, tid as usize * stride);
        state[to..to + stride].copy_from_slice(&updates[from..from + stride]);
    }
}
