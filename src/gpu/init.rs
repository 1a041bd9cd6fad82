//! Dispatch of `wgsl/init.wgsl` (CPU reference: `src/cpu/init.rs`): a level's first state, the
//! warped tiling of the candidate slab or the coarse-level cache.

use super::synth::{GpuState, GpuSynth};
use crate::contract::uniforms::InitParams;
use crate::error::{Error, Result};

impl GpuSynth {
    /// `cache`: the coarse-level cache's triples when `p.cache_period` is set.
    pub fn init(
        &mut self,
        level: usize,
        p: &InitParams,
        index: &wgpu::Buffer,
        cache: Option<&wgpu::Buffer>,
    ) -> Result<GpuState> {
        if p.cache_period != 0 && cache.is_none() {
            return Err(Error::Gpu(
                "init from the coarse cache without its buffer".into(),
            ));
        }
        // The grid's row stride is the dispatch's to choose (`fill_state`: a thread per voxel).
        let p = &InitParams {
            grid_stride: super::context::dispatch_grid(p.list_count * 64).2,
            ..*p
        };
        // (Binding 5 is declared whether or not the cache is read: the table stands in.)
        self.fill_state(
            "init",
            p,
            level,
            &self.table,
            index,
            Some(cache.unwrap_or(&self.table)),
            p.list_count,
            p.ex.pixel_words,
            &[],
        )
    }
}
