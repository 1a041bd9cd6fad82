//! CPU reference of `wgsl/init.wgsl`: the l_start level as a tiling of exemplar 0's candidate slab
//! (5 voxels thick along x), warped by the jitter field.

use super::synth_common::{brick_at, coord, pack_resolved, write_voxel};
use crate::contract::bricks::voxel_of;
use crate::contract::jitter;
use crate::contract::triple::pack;
use crate::contract::uniforms::InitParams;
use crate::util::hash::hash32;
use rayon::prelude::*;

/// The state (triple and value per voxel, 64 voxels per brick in list order) of the bricks of
/// the list in `p` (brick index `bricks`). `cache`: the coarse-level cache's triples when
/// `p.cache_period` is set (3 words per voxel of the periodic cube, x fastest).
pub fn init(
    p: &InitParams,
    table: &[u32],
    level: &[u32],
    bricks: &[u32],
    cache: &[u32],
) -> Vec<u32> {
    assert!(
        p.cache_period == 0 || cache.len() >= (p.cache_period as usize).pow(3) * 3,
        "a coarse-level cache of the period's size"
    );
    let stride = 3 + p.ex.pixel_words as usize;
    let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2];
    let mut out = vec![0u32; p.list_count as usize * 64 * stride];
    out.par_chunks_mut(64 * stride)
        .enumerate()
        .for_each(|(slot, dst)| {
            let brick = brick_at(bricks, p.list_offset, slot as u32);
            // A brick is one jitter cell (both 4^3, aligned): its warps are computed together.
            let warps = (p.jitter_on != 0).then(|| {
                let cell = jitter::cell_of(brick_origin(brick));
                let sig2 = [p.sig0, p.sig1, p.sig2, p.sig3];
                let amps = [p.amp0, p.amp1, p.amp2, p.amp3];
                let gaussians = jitter::cell_gaussians(cell, p.seed_lo, p.seed_hi, p.period, sig2);
                jitter::cell_offsets(cell, &gaussians, amps, sig2, table)
            });
            for local in 0..64usize {
                let pos = voxel_of(brick, local as u32);
                let warp = warps.map_or([0; 3], |w| w[local]);
                let t = if p.cache_period != 0 {
                    cached_voxel(p, cache, pos, warp)
                } else {
                    init_voxel(p, level, pos, warp)
                };
                let voxel = &mut dst[local * stride..(local + 1) * stride];
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

const _: () = assert!(jitter::CELL == crate::contract::bricks::BRICK);

fn brick_origin(b: [i32; 3]) -> [i32; 3] {
    b.map(|v| v * crate::contract::bricks::BRICK)
}

/// The cached triple of voxel `pos`, warped by `warp`: the periodic cache read at the warped
/// position plus the tile offset (a hashed per-seed shift).
fn cached_voxel(p: &InitParams, cache: &[u32], pos: [i32; 3], warp: [i32; 3]) -> [u32; 3] {
    let n = p.cache_period as i32;
    let tile = [p.tile_x, p.tile_y, p.tile_z];
    let q = [0, 1, 2].map(|i| (pos[i] + warp[i] + tile[i] as i32).rem_euclid(n) as usize);
    let src = ((q[2] * n as usize + q[1]) * n as usize + q[0]) * 3;
    [cache[src], cache[src + 1], cache[src + 2]]
}

/// The initial triple of voxel `pos`, warped by `warp` (the jitter field there).
fn init_voxel(p: &InitParams, level: &[u32], pos: [i32; 3], warp: [i32; 3]) -> [u32; 3] {
    let mut q = [
        pos[0] + warp[0] + p.tile_x as i32,
        pos[1] + warp[1] + p.tile_y as i32,
        pos[2] + warp[2] + p.tile_z as i32,
    ];
    if p.period != 0 {
        q = q.map(|v| v.rem_euclid(p.period as i32));
    }
    let (w, h) = (p.ex.width, p.ex.height);
    // Each 5-voxel layer of slabs along x is shifted by its own hashed (y, z) offset, so the
    // tiling does not extrude exemplar 0 along x (a state the correction cannot leave: it
    // satisfies every x plane exactly).
    let layer = q[0].div_euclid(5);
    let shift = hash32(hash32(p.seed_lo ^ 0x5EED) ^ layer as u32);
    let u = (q[1] + (shift % w) as i32).rem_euclid(w as i32) as u32;
    let v = (q[2] + ((shift >> 16) % h) as i32).rem_euclid(h as i32) as u32;
    let depth = q[0].rem_euclid(5) - 2;
    let s = (p.slab_offset + (v * w + u) * 3) as usize;
    // Along x (the slab's normal): v in Ey, u in Ez (see analysis::frame).
    let (x1, y1) = coord(level[s + 1]);
    let (x2, y2) = coord(level[s + 2]);
    [
        pack(u, v),
        pack_resolved(x1, y1 + depth, w, h, p.ex.border),
        pack_resolved(x2 + depth, y2, w, h, p.ex.border),
    ]
}
