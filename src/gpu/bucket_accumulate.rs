//! Dispatch of `wgsl/bucket_accumulate.wgsl` (CPU reference: `src/cpu/bucket_accumulate.rs`).

use super::context::{dispatch_grid, GpuContext};
use crate::cpu::bucket_accumulate::Buckets;
use crate::error::{Error, Result};
use crate::kernel_types::BucketParams;

/// Same result as [`crate::cpu::bucket_accumulate::bucket_accumulate`], bit for bit.
pub fn bucket_accumulate(
    gpu: &GpuContext,
    samples: &[u32],
    voxels: usize,
    clusters: u32,
    channels: u32,
) -> Result<Buckets> {
    if clusters == 0 || clusters > 32 {
        return Err(Error::invalid("clusters", "must be 1..=32"));
    }
    let pipeline = gpu.pipeline("bucket_accumulate")?;
    let n = samples.len() / (2 + channels as usize);
    let (gx, gy, grid_stride) = dispatch_grid(n as u32);
    let input = gpu.storage_buffer("samples", bytemuck::cast_slice(samples));
    let counts = gpu.output_buffer("bucket counts", voxels * clusters as usize, 0);
    let sum_words = voxels * 2 * (1 + channels as usize);
    let sums = gpu.output_buffer("bucket sums", sum_words, 0);
    for pass in 0..2 {
        let params = BucketParams {
            samples: n as u32,
            clusters,
            channels,
            pass_index: pass,
            grid_stride,
            ..Default::default()
        };
        gpu.checked("bucket_accumulate", || {
            let uniform = gpu.uniform_buffer("bucket params", &params);
            gpu.dispatch_and_wait(
                "bucket_accumulate",
                &pipeline,
                &[&uniform, &input, &counts, &sums],
                (gx, gy),
            )
        })?;
    }
    Ok(Buckets {
        counts: gpu.read_words(&counts, voxels * clusters as usize)?,
        sums: gpu.read_words(&sums, sum_words)?,
    })
}
