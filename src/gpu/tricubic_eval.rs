//! Dispatch of `wgsl/tricubic_eval.wgsl` (CPU reference: `src/cpu/tricubic_eval.rs`).

use super::context::{chunk_ranges, dispatch_grid, GpuContext};
use crate::contract::tricubic::{GradientSolid, Query};
use crate::contract::uniforms::TricubicParams;
use crate::error::Result;
use rayon::prelude::*;

/// Written into the output before the kernel runs in debug builds (a NaN: never a result of
/// finite inputs).
const SENTINEL: u32 = 0x7FC0_DEAD;

/// Same result as [`crate::cpu::tricubic_eval::tricubic_eval`], within float tolerance.
pub fn tricubic_eval(gpu: &GpuContext, solid: &GradientSolid, query: &Query) -> Result<Vec<f32>> {
    let words = run(gpu, solid, query, false)?;
    Ok(words.into_iter().map(f32::from_bits).collect())
}

/// Same result as [`crate::cpu::tricubic_eval::tricubic_eval_u8`] (up to one level where a
/// value lies within the float tolerance of a rounding boundary): the kernel quantizes, so a
/// quarter of the float output is written and read back. At most 4 channels.
pub fn tricubic_eval_u8(gpu: &GpuContext, solid: &GradientSolid, query: &Query) -> Result<Vec<u8>> {
    let c = solid.channels as usize;
    if c > 4 {
        return Err(crate::error::Error::invalid(
            "tricubic_eval_u8",
            format!("8-bit output holds at most 4 channels, the solid has {c}"),
        ));
    }
    let words = run(gpu, solid, query, true)?;
    let mut out = vec![0u8; words.len() * c];
    out.par_chunks_mut(c)
        .zip(words.par_iter())
        .for_each(|(dst, w)| dst.copy_from_slice(&w.to_le_bytes()[..c]));
    Ok(out)
}

/// The kernel over `query` in dispatches of at most one binding: `channels` f32 bit patterns
/// per point, or one packed word per point with `quantize`.
fn run(gpu: &GpuContext, solid: &GradientSolid, query: &Query, quantize: bool) -> Result<Vec<u32>> {
    let c = if quantize { 1 } else { solid.channels as usize };
    let cells = cell_chunks(gpu, solid, query, c as u64 * 4);
    let pipeline = match cells {
        Some(_) => gpu.pipeline_with("tricubic_eval", &[("CELL_MODE", 1.0)])?,
        None => gpu.pipeline("tricubic_eval")?,
    };
    let control = gpu.storage_buffer("control points", bytemuck::cast_slice(&solid.data));
    let (mode, points, grid) = match query {
        Query::Points(p) => (1u32, bytemuck::cast_slice::<[f32; 3], u8>(p).to_vec(), None),
        Query::Grid { origin, a, b, c, n } => (0, vec![0u8; 16], Some((*origin, *a, *b, *c, *n))),
    };
    let points = gpu.storage_buffer(
        "points",
        if points.is_empty() {
            &[0u8; 16]
        } else {
            &points
        },
    );
    let bits = |v: [f32; 3]| v.map(f32::to_bits);
    let (o, a, b, cc, n) = grid.unwrap_or(([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], [1; 3]));
    let (o, a, b, cc) = (bits(o), bits(a), bits(b), bits(cc));
    let mut out = Vec::new();
    let ranges = match &cells {
        Some(chunks) => chunks.clone(),
        None => chunk_ranges(query.len(), c as u64 * 4, gpu.max_binding_bytes()),
    };
    for range in ranges {
        let count = range.len() as u32;
        // Cell mode: 4 threads per control cell of the chunk's layers, rounded up to whole
        // workgroups of 16 cells (the extra threads find no voxel).
        let threads = match cells {
            Some(_) => {
                let layer = n[0] as usize * n[1] as usize;
                let cell_layers = range.len().div_ceil(layer).div_ceil(4) as u32;
                (n[0].div_ceil(4) * n[1].div_ceil(4) * cell_layers).div_ceil(16) * 64
            }
            None => count,
        };
        let (gx, gy, grid_stride) = dispatch_grid(threads);
        let params = TricubicParams {
            dims_x: solid.dims[0],
            dims_y: solid.dims[1],
            dims_z: solid.dims[2],
            channels: solid.channels,
            mode,
            count,
            first: range.start as u32,
            grid_stride,
            n_x: n[0],
            n_y: n[1],
            origin_x: o[0],
            origin_y: o[1],
            origin_z: o[2],
            a_x: a[0],
            a_y: a[1],
            a_z: a[2],
            b_x: b[0],
            b_y: b[1],
            b_z: b[2],
            c_x: cc[0],
            c_y: cc[1],
            c_z: cc[2],
            quantize: quantize as u32,
            _pad1: 0,
        };
        let words = gpu.checked("tricubic_eval", || {
            let start = std::time::Instant::now();
            let uniform = gpu.uniform_buffer("tricubic params", &params);
            // Every point's words are written by the kernel. Debug builds (the tests) fill the
            // buffer with sentinels first, so a point the kernel skips shows as a NaN; release
            // builds do not fill and upload it from the host (64 MiB took 66 ms of a 256^3
            // render on lavapipe): wgpu zeroes it on the device.
            let output = if cfg!(debug_assertions) {
                gpu.output_buffer("values", count as usize * c, SENTINEL)
            } else {
                gpu.device_buffer("values", count as usize * c)
            };
            let allocated = start.elapsed();
            gpu.dispatch_and_wait(
                "tricubic_eval",
                &pipeline,
                &[&uniform, &control, &points, &output],
                (gx, gy),
            )?;
            let ran = start.elapsed();
            let words = gpu.read_words(&output, count as usize * c);
            tracing::debug!(
                "tricubic_eval: {count} points, buffers {:.3} s, kernel {:.3} s, read-back {:.3} s",
                allocated.as_secs_f64(),
                (ran - allocated).as_secs_f64(),
                (start.elapsed() - ran).as_secs_f64()
            );
            words
        })?;
        if out.is_empty() {
            out = words; // (no copy of a single dispatch's output)
        } else {
            out.extend(words);
        }
    }
    Ok(out)
}

/// When the kernel's cell mode applies ([`crate::cpu::tricubic_eval::cell_mode`]): the point
/// ranges of its dispatches, whole layers of control cells (4 z slices) each, within one storage
/// binding. `None`: the general path (also for layers too large for one binding, where the
/// result then matches the reference within the float tolerance only).
fn cell_chunks(
    gpu: &GpuContext,
    solid: &GradientSolid,
    query: &Query,
    bytes_per_point: u64,
) -> Option<Vec<std::ops::Range<usize>>> {
    let n = crate::cpu::tricubic_eval::cell_mode(solid, query)?;
    let layer = n[0] as u64 * n[1] as u64;
    let slices = (gpu.max_binding_bytes() / (layer * bytes_per_point)) / 4 * 4;
    if slices == 0 {
        return None;
    }
    let per = (slices * layer) as usize;
    let total = query.len();
    Some(
        (0..total.div_ceil(per))
            .map(|i| i * per..((i + 1) * per).min(total))
            .collect(),
    )
}
