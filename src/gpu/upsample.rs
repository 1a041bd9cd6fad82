//! Dispatch of `wgsl/upsample.wgsl` (CPU reference: `src/cpu/upsample.rs`): a child level's
//! state inherited from its parent's coordinates.

use super::synth::{GpuState, GpuSynth};
use crate::contract::uniforms::UpsampleParams;
use crate::error::Result;

impl GpuSynth {
    /// `level`: the child level.
    pub fn upsample(
        &mut self,
        level: usize,
        p: &UpsampleParams,
        parent: GpuState,
        index: &wgpu::Buffer,
    ) -> Result<GpuState> {
        // The grid's row stride is the dispatch's to choose (`fill_state`: a thread per voxel).
        let p = &UpsampleParams {
            grid_stride: super::context::dispatch_grid(p.list_count * 64).2,
            ..*p
        };
        self.fill_state(
            "upsample",
            p,
            level,
            &parent.current,
            index,
            None,
            p.list_count,
            p.ex.pixel_words,
            &[],
        )
    }
}
