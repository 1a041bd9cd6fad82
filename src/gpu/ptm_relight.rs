//! Dispatch of `wgsl/ptm_relight.wgsl` (CPU reference: `src/cpu/ptm_relight.rs`). The texels
//! stay on the GPU ([`GpuPtm`]) so relighting under a new light costs one dispatch and a readback.

use super::context::{dispatch_grid, GpuContext};
use crate::cpu::ptm_relight::Lighting;
use crate::error::Result;
use crate::kernel_types::PtmRelightParams;
use crate::ptm::{Ptm, PtmFormat};
use std::ops::Range;

/// Written into the output before the kernel runs (a NaN: never a result of finite inputs).
const SENTINEL: u32 = 0x7FC0_DEAD;

/// A PTM's texels uploaded in chunks that respect the storage-binding limit.
pub struct GpuPtm {
    format: PtmFormat,
    scale: [f32; 6],
    bias: [i32; 6],
    chunks: Vec<(Range<usize>, wgpu::Buffer)>,
}

impl GpuPtm {
    /// Upload `ptm`'s texels. Chunks hold a multiple of 4 pixels, so each starts on a word.
    pub fn upload(gpu: &GpuContext, ptm: &Ptm) -> GpuPtm {
        let s = ptm.format.texel_bytes();
        // Per pixel the larger of its input bytes and its 12 output bytes must fit a binding.
        let per = (gpu.max_binding_bytes() / s.max(12) as u64) as usize / 4 * 4;
        let per = per.max(4);
        let total = ptm.pixels();
        let chunks = (0..total.div_ceil(per))
            .map(|i| {
                let r = i * per..((i + 1) * per).min(total);
                let buf = gpu.storage_buffer("ptm texels", &ptm.texels[r.start * s..r.end * s]);
                (r, buf)
            })
            .collect();
        GpuPtm {
            format: ptm.format,
            scale: ptm.scale,
            bias: ptm.bias,
            chunks,
        }
    }

    /// r, g, b per pixel under `light`: same as [`crate::cpu::ptm_relight::ptm_relight`] within
    /// float tolerance.
    pub fn relight(&self, gpu: &GpuContext, light: &Lighting) -> Result<Vec<f32>> {
        let pipeline = gpu.pipeline("ptm_relight")?;
        let total: usize = self.chunks.iter().map(|c| c.0.len()).sum();
        let mut out = Vec::with_capacity(total * 3);
        for (range, texels) in &self.chunks {
            let count = range.len() as u32;
            let (gx, gy, grid_stride) = dispatch_grid(count);
            let [s0, s1, s2, s3, s4, s5] = self.scale.map(f32::to_bits);
            let [b0, b1, b2, b3, b4, b5] = self.bias.map(|b| b as u32);
            let params = PtmRelightParams {
                width: 0,
                count,
                first: range.start as u32,
                grid_stride,
                format: match self.format {
                    PtmFormat::Rgb => 0,
                    PtmFormat::Lrgb => 1,
                },
                texel_bytes: self.format.texel_bytes() as u32,
                light_u: light.lu.to_bits(),
                light_v: light.lv.to_bits(),
                light_w: light.lw().to_bits(),
                specular: light.specular.to_bits(),
                scale0: s0,
                scale1: s1,
                scale2: s2,
                scale3: s3,
                scale4: s4,
                scale5: s5,
                bias0: b0,
                bias1: b1,
                bias2: b2,
                bias3: b3,
                bias4: b4,
                bias5: b5,
                _pad0: 0,
                _pad1: 0,
            };
            let words = gpu.checked("ptm_relight", || {
                let uniform = gpu.uniform_buffer("ptm relight params", &params);
                let output = gpu.output_buffer("relit rgb", count as usize * 3, SENTINEL);
                gpu.dispatch_and_wait(
                    "ptm_relight",
                    &pipeline,
                    &[&uniform, texels, &output],
                    (gx, gy),
                )?;
                gpu.read_words(&output, count as usize * 3)
            })?;
            out.extend(words.into_iter().map(f32::from_bits));
        }
        Ok(out)
    }
}

/// Upload and relight once.
pub fn ptm_relight(gpu: &GpuContext, ptm: &Ptm, light: &Lighting) -> Result<Vec<f32>> {
    GpuPtm::upload(gpu, ptm).relight(gpu, light)
}
