//! Rendering a plain gradient solid to 8-bit values (what `gradient render` stores) on either
//! backend: kernel `tricubic_eval` in its 8-bit mode on the GPU, its reference on the CPU.

use super::GradientSolid;
use crate::backend::Compute;
use crate::contract::tricubic::Query;
use crate::error::Result;

/// `solid`'s channels at the points of `query`, rounded half up and clamped to 8 bits. On the
/// GPU a solid of at most 4 channels is quantized by the kernel (a quarter of the float output
/// to write and read back); wider solids are quantized on the host.
pub fn render_u8(solid: &GradientSolid, query: &Query, compute: &Compute) -> Result<Vec<u8>> {
    compute.tricubic_eval_u8(solid, query)
}

/// A deterministic random solid with an extent of `side` voxels per axis (side = 4 k + 1) and
/// colour-range values: the benchmark's input (smoothness does not change the work).
pub fn random_solid(side: u32, channels: u32, seed: u64) -> Result<GradientSolid> {
    let dims = (side.max(5) - 1).div_ceil(super::SPACING) + 1;
    let mut s = GradientSolid::new([dims; 3], channels)?;
    let mut rng = crate::util::hash::SeededRng::new(seed);
    for (i, v) in s.data.iter_mut().enumerate() {
        // Values in [0, 255], gradients in [-8, 8] per voxel.
        *v = if i % 4 == 0 {
            rng.below(25_600) as f32 / 100.0
        } else {
            rng.below(1_600) as f32 / 100.0 - 8.0
        };
    }
    Ok(s)
}
