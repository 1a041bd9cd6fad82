//! Dispatch of `wgsl/project.wgsl` (CPU reference: `src/cpu/project.rs`).

use super::context::{chunk_ranges, dispatch_grid, GpuContext};
use crate::contract::pca::PcaBasis;
use crate::contract::uniforms::ProjectParams;
use crate::error::Result;
use crate::exemplar::{Border, Image};

/// Written into the output before the kernel runs; a quantized vector whose bytes are all 0xFF
/// can occur, so callers that test coverage look at words the kernel must zero-pad instead.
pub const SENTINEL: u32 = 0xDEAD_BEEF;

/// Project every pixel's neighbourhood on the GPU; same result as [`crate::cpu::project::project`].
pub fn project(gpu: &GpuContext, img: &Image, border: Border, pca: &PcaBasis) -> Result<Vec<u32>> {
    let pipeline = gpu.pipeline("project")?;
    let words = pca.words_per_vector();
    let total = img.pixel_count();
    let image = gpu.storage_buffer("exemplar", &img.pixels);
    let mean = gpu.storage_buffer("mean", bytemuck::cast_slice(&pca.mean));
    let weights = gpu.storage_buffer("weights", bytemuck::cast_slice(&pca.weights));
    let mut out = Vec::with_capacity(total * words as usize);
    for range in chunk_ranges(total, words as u64 * 4, gpu.max_binding_bytes()) {
        let count = range.len() as u32;
        let (gx, gy, grid_stride) = dispatch_grid(count);
        let params = ProjectParams {
            width: img.width,
            height: img.height,
            channels: img.channels,
            border: border.code(),
            input_dims: pca.input_dims,
            output_dims: pca.output_dims,
            shift: pca.shift,
            first_pixel: range.start as u32,
            pixel_count: count,
            words_per_vector: words,
            grid_stride,
            _pad: 0,
        };
        let chunk = gpu.checked("project", || {
            let uniform = gpu.uniform_buffer("project params", &params);
            let output = gpu.output_buffer("projected", count as usize * words as usize, SENTINEL);
            gpu.dispatch_and_wait(
                "project",
                &pipeline,
                &[&uniform, &image, &mean, &weights, &output],
                (gx, gy),
            )?;
            gpu.read_words(&output, count as usize * words as usize)
        })?;
        out.extend_from_slice(&chunk);
    }
    Ok(out)
}
