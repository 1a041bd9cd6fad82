//! Dispatch of `wgsl/tricubic_eval.wgsl` (CPU reference: `src/cpu/tricubic_eval.rs`).

use super::context::{chunk_ranges, dispatch_grid, GpuContext};
use crate::cpu::tricubic_eval::Query;
use crate::error::Result;
use crate::gradient::GradientSolid;
use crate::kernel_types::TricubicParams;

/// Written into the output before the kernel runs (a NaN: never a result of finite inputs).
const SENTINEL: u32 = 0x7FC0_DEAD;

/// Same result as [`crate::cpu::tricubic_eval::tricubic_eval`], within float tolerance.
pub fn tricubic_eval(gpu: &GpuContext, solid: &GradientSolid, query: &Query) -> Result<Vec<f32>> {
    let pipeline = gpu.pipeline("tricubic_eval")?;
    let c = solid.channels as usize;
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
    let mut out = Vec::with_capacity(query.len() * c);
    for range in chunk_ranges(query.len(), c as u64 * 4, gpu.max_binding_bytes()) {
        let count = range.len() as u32;
        let (gx, gy, grid_stride) = dispatch_grid(count);
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
            _pad0: 0,
            _pad1: 0,
        };
        let words = gpu.checked("tricubic_eval", || {
            let uniform = gpu.uniform_buffer("tricubic params", &params);
            let output = gpu.output_buffer("values", count as usize * c, SENTINEL);
            gpu.dispatch_and_wait(
                "tricubic_eval",
                &pipeline,
                &[&uniform, &control, &points, &output],
                (gx, gy),
            )?;
            gpu.read_words(&output, count as usize * c)
        })?;
        out.extend(words.into_iter().map(f32::from_bits));
    }
    Ok(out)
}
