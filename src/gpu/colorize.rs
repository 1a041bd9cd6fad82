//! Dispatch of `wgsl/colorize.wgsl` (CPU reference: `src/cpu/colorize.rs`): the colours of a
//! group's output voxels, read back without waiting (the only read of a synthesis).

use super::context::PendingRead;
use super::synth::{groups, GpuState, GpuSynth};
use crate::contract::uniforms::ColorizeParams;
use crate::error::Result;

impl GpuSynth {
    /// Record and submit `colorize` and begin reading its colours back; they come with
    /// [`Self::finish_read`].
    pub fn colorize(
        &mut self,
        level: usize,
        p: &ColorizeParams,
        s: &GpuState,
        index: &wgpu::Buffer,
    ) -> Result<PendingRead> {
        let n = p.list_count as usize * 64;
        // The grid's row stride is the dispatch's to choose (a thread per listed voxel).
        let p = &ColorizeParams {
            grid_stride: super::context::dispatch_grid(n as u32).2,
            ..*p
        };
        // (`colorize` writes a colour per listed voxel.)
        let out = self.scratch_buffer("colours", n as u64);
        self.run(
            "colorize",
            &[],
            p,
            &[
                (1, &self.levels[level]),
                (2, &s.current),
                (3, &out),
                (4, index),
            ],
            groups(n as u64),
        )?;
        self.flush()?;
        let colours = self.ctx.start_read(&out, n);
        // (Reusable at once: whatever writes it next is queued after this copy.)
        if let Some(pool) = &self.pool {
            pool.give(out);
        }
        Ok(colours)
    }

    /// The words of a read begun here (a group's colours).
    pub fn finish_read(&self, read: PendingRead) -> Result<Vec<u32>> {
        self.ctx.finish_read(read)
    }
}
