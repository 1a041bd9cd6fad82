//! The synthesis kernels' uniforms, built from a level's pack and the request's plan: one
//! function per kernel, each starting from the level's [`ExemplarFields`], built once by
//! `ExemplarFields::of`. `grid_stride` (the dispatch grid's row stride) is left 0 here: the GPU
//! dispatch sets it from the grid it chooses, and the CPU references do not read it.

use super::bricks::BrickGrid;
use super::params::CandidateMode;
use crate::contract::jitter;
use crate::contract::level::LevelPack;
use crate::contract::uniforms::{
    ColorizeParams, CorrectParams, ExemplarFields, InitParams, UpsampleParams,
};
use crate::util::hash::hash32;

/// The uniforms of one `correct` sub-pass: the class voxels of the bricks of the list at word
/// `list.0` (`list.1` bricks) of a level's brick index, whose table (offset 0) describes `grid`.
pub fn correct_params(
    pack: &LevelPack,
    grid: &BrickGrid,
    list: (u32, u32),
    class: usize,
    k3d_used: u32,
    border: u32,
    mode: CandidateMode,
) -> CorrectParams {
    let o = &pack.offsets;
    CorrectParams {
        ex: ExemplarFields::of(pack, border),
        grid_lo_x: grid.lo[0],
        grid_lo_y: grid.lo[1],
        grid_lo_z: grid.lo[2],
        grid_x: grid.dims[0],
        grid_y: grid.dims[1],
        grid_z: grid.dims[2],
        table_offset: 0,
        list_offset: list.0,
        list_count: list.1,
        class_x: (class & 1) as u32,
        class_y: ((class >> 1) & 1) as u32,
        class_z: ((class >> 2) & 1) as u32,
        pca_in: pack.pca_in,
        pca_out: pack.pca_out,
        shift: pack.shift,
        proj_words: pack.proj_words,
        k2d: pack.k2d,
        k3d_used,
        k3d_stride: pack.k3d_stride,
        mode: (mode == CandidateMode::TwoD) as u32,
        shared_sets: pack.shared as u32,
        proj0: o.projected[0],
        proj1: o.projected[1],
        proj2: o.projected[2],
        mean0: o.mean[0],
        mean1: o.mean[1],
        mean2: o.mean[2],
        weights0: o.weights[0],
        weights1: o.weights[1],
        weights2: o.weights[2],
        cand2d0: o.cand2d[0],
        cand2d1: o.cand2d[1],
        cand2d2: o.cand2d[2],
        cand3d0: o.cand3d[0],
        cand3d1: o.cand3d[1],
        cand3d2: o.cand3d[2],
        counts0: o.counts[0],
        counts1: o.counts[1],
        counts2: o.counts[2],
        // Set by the dispatch, which chooses the grid (`gpu::correct`).
        grid_stride: 0,
        // The caller points this at the list's voxel masks.
        mask_offset: 0,
        period: 0,
        _r0: 0,
        _r1: 0,
    }
}

/// The uniforms of `init` over the bricks of the list `list` (word offset, count) of a level's
/// brick index: the warped tiling of exemplar 0's candidate slab, periodic with `period` (0:
/// the infinite solid), for `seed` and `jitter`. Reading the coarse cache instead sets
/// `cache_period` and the tile offset on this.
pub fn init_params(
    pack: &LevelPack,
    border: u32,
    list: (u32, u32),
    period: u32,
    seed: u64,
    jitter: f32,
) -> InitParams {
    let seed_lo = seed as u32;
    let seed_hi = (seed >> 32) as u32;
    let amps = jitter::amplitudes(jitter);
    let sig = jitter::sigma2_fixed();
    InitParams {
        ex: ExemplarFields::of(pack, border),
        list_offset: list.0,
        list_count: list.1,
        grid_stride: 0,
        period,
        cache_period: 0,
        seed_lo,
        seed_hi,
        jitter_on: (jitter > 0.0) as u32,
        tile_x: hash32(seed_lo ^ 0x51) % 5,
        tile_y: hash32(seed_hi ^ 0x52) % pack.width,
        tile_z: hash32(seed_lo ^ seed_hi ^ 0x53) % pack.height,
        slab_offset: pack.offsets.slab,
        amp0: amps[0],
        amp1: amps[1],
        amp2: amps[2],
        amp3: amps[3],
        sig0: sig[0],
        sig1: sig[1],
        sig2: sig[2],
        sig3: sig[3],
    }
}

/// The uniforms of `upsample` of the child bricks of the list `list` of a level's brick index,
/// whose parent level's table (over `parent`) was copied there at word `parent_table`.
pub fn upsample_params(
    pack: &LevelPack,
    border: u32,
    parent: &BrickGrid,
    parent_table: u32,
    list: (u32, u32),
) -> UpsampleParams {
    UpsampleParams {
        ex: ExemplarFields::of(pack, border),
        parent_grid_lo_x: parent.lo[0],
        parent_grid_lo_y: parent.lo[1],
        parent_grid_lo_z: parent.lo[2],
        parent_grid_x: parent.dims[0],
        parent_grid_y: parent.dims[1],
        parent_grid_z: parent.dims[2],
        parent_table,
        list_offset: list.0,
        list_count: list.1,
        grid_stride: 0,
        _r0: 0,
        _r1: 0,
    }
}

/// The uniforms of `colorize` of the output bricks of the list `list` of the finest level's
/// brick index (whose table, at word 0, describes `grid`), channel sources `source`
/// ([`super::ColorSource::kernel_code`]), in a tileable solid of period `period` (0 for none).
pub fn colorize_params(
    pack: &LevelPack,
    border: u32,
    grid: &BrickGrid,
    list: (u32, u32),
    source: u32,
    period: u32,
) -> ColorizeParams {
    ColorizeParams {
        ex: ExemplarFields::of(pack, border),
        grid_lo_x: grid.lo[0],
        grid_lo_y: grid.lo[1],
        grid_lo_z: grid.lo[2],
        grid_x: grid.dims[0],
        grid_y: grid.dims[1],
        grid_z: grid.dims[2],
        table_offset: 0,
        list_offset: list.0,
        list_count: list.1,
        grid_stride: 0,
        match_table: pack.offsets.color_match,
        color_channels: pack.color_channels,
        source,
        period,
        _r1: 0,
        _r2: 0,
    }
}
