//! Dispatch of `wgsl/ptm_relight.wgsl` (CPU reference: `src/cpu/ptm_relight.rs`). The texels
//! stay on the GPU ([`GpuPtm`]) so relighting under a new light costs one dispatch and a readback.

use super::context::{dispatch_grid, GpuContext};
use crate::contract::ptm::{Lighting, Ptm, PtmFormat};
use crate::contract::uniforms::PtmRelightParams;
use crate::error::Result;
use std::ops::Range;

/// Written into a new output buffer, and before every relight in debug builds (a NaN: never a
/// result of finite inputs).
const SENTINEL: u32 = 0x7FC0_DEAD;

/// A PTM's texels uploaded in chunks that respect the storage-binding limit, each texel padded
/// to whole words (LRGB: 9 bytes in 3 words, RGB: 18 in 5) so the kernel's byte extraction uses
/// constant shifts.
pub struct GpuPtm {
    format: PtmFormat,
    step: [f32; 6],
    bias: [i32; 6],
    /// Per chunk: its pixels, its texels, and its output buffer (kept between relights).
    chunks: Vec<(Range<usize>, wgpu::Buffer, wgpu::Buffer)>,
}

/// Words per padded texel.
fn texel_words(format: PtmFormat) -> usize {
    format.texel_bytes().div_ceil(4)
}

impl GpuPtm {
    /// Upload `ptm`'s texels.
    pub fn upload(gpu: &GpuContext, ptm: &Ptm) -> GpuPtm {
        let s = ptm.format.texel_bytes();
        let words = texel_words(ptm.format);
        // Per pixel the larger of its input bytes and its 12 output bytes must fit a binding.
        let per = ((gpu.max_binding_bytes() / (4 * words).max(12) as u64) as usize).max(1);
        let total = ptm.pixels();
        let chunks = (0..total.div_ceil(per))
            .map(|i| {
                let r = i * per..((i + 1) * per).min(total);
                let mut padded = vec![0u8; r.len() * 4 * words];
                for (dst, src) in padded
                    .chunks_exact_mut(4 * words)
                    .zip(ptm.texels[r.start * s..r.end * s].chunks_exact(s))
                {
                    dst[..s].copy_from_slice(src);
                }
                let out = gpu.output_buffer("relit rgb", r.len() * 3, SENTINEL);
                (r, gpu.storage_buffer("ptm texels", &padded), out)
            })
            .collect();
        GpuPtm {
            format: ptm.format,
            step: std::array::from_fn(|i| ptm.step(i)),
            bias: ptm.bias,
            chunks,
        }
    }

    /// r, g, b per pixel under `light`: same as [`crate::cpu::ptm_relight::ptm_relight`] within
    /// float tolerance.
    pub fn relight(&self, gpu: &GpuContext, light: &Lighting) -> Result<Vec<f32>> {
        let pipeline = gpu.pipeline("ptm_relight")?;
        let mut out = Vec::new();
        for (range, texels, output) in &self.chunks {
            let count = range.len() as u32;
            let (gx, gy, grid_stride) = dispatch_grid(count);
            let [s0, s1, s2, s3, s4, s5] = self.step.map(f32::to_bits);
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
                texel_words: texel_words(self.format) as u32,
                light_u: light.lu.to_bits(),
                light_v: light.lv.to_bits(),
                light_w: light.lw().to_bits(),
                specular: light.specular.to_bits(),
                step0: s0,
                step1: s1,
                step2: s2,
                step3: s3,
                step4: s4,
                step5: s5,
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
                // The kernel writes every pixel. Debug builds (the tests) refill the output
                // with sentinels before each relight, so a skipped pixel shows as a NaN;
                // release builds do not (a 12 MiB upload per 1024^2 relight).
                if cfg!(debug_assertions) {
                    let sentinels = vec![SENTINEL; count as usize * 3];
                    gpu.queue
                        .write_buffer(output, 0, bytemuck::cast_slice(&sentinels));
                }
                gpu.dispatch_and_wait(
                    "ptm_relight",
                    &pipeline,
                    &[&uniform, texels, output],
                    (gx, gy),
                )?;
                gpu.read_words(output, count as usize * 3)
            })?;
            if out.is_empty() {
                // In place (same size and alignment): no copy of a single chunk's output.
                out = words.into_iter().map(f32::from_bits).collect();
            } else {
                out.extend(words.into_iter().map(f32::from_bits));
            }
        }
        Ok(out)
    }
}

/// Upload and relight once.
pub fn ptm_relight(gpu: &GpuContext, ptm: &Ptm, light: &Lighting) -> Result<Vec<f32>> {
    GpuPtm::upload(gpu, ptm).relight(gpu, light)
}
