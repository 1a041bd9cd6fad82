//! Dispatch of `wgsl/correct.wgsl` (CPU reference: `src/cpu/correct/`): the correction passes,
//! each a copy of the state as the pass begins (`begin_pass`) and one `correct` per parity-class
//! sub-pass, with the per-level tables the kernel binds (candidate tables, projection weights) and
//! its pipeline variants (override constants per level).

use super::candidate_tables::candidate_tables;
use super::context::GpuContext;
pub use super::projection_weights::WeightLayout;
use super::synth::{GpuState, GpuSynth};
use crate::contract::level::LevelPack;
use crate::contract::uniforms::CorrectParams;
use crate::error::{Error, Result};

/// The `correct` pipeline's override constants (see wgsl/correct.wgsl).
pub(super) fn correct_constants(
    channels: u32,
    pca_out: u32,
    k2d: u32,
    layout: WeightLayout,
    block_bricks: u32,
) -> Vec<(&'static str, f64)> {
    vec![
        ("CHANNELS", channels as f64),
        ("PCA_OUT", pca_out as f64),
        ("K2D", k2d as f64),
        ("WEIGHT_LAYOUT", layout.constant()),
        ("BLOCK_BRICKS", block_bricks as f64),
    ]
}

/// Environment variable choosing `correct`'s block of bricks (`block_bricks`), for timing
/// layouts on a device without rebuilding (32, an NVIDIA warp, timed the same as 8 on an H100).
pub const BLOCK_BRICKS_ENV: &str = "SOLIDSYNTH_BLOCK_BRICKS";

/// Listed bricks per block of `correct`'s k-major threads (`class_voxel` in
/// wgsl/lib/synth_common.wgsl): `SOLIDSYNTH_BLOCK_BRICKS` when it names a multiple of 8 up to 64;
/// else a CPU device's SIMD width where it is 16 (lavapipe at 512 bits on an AMD EPYC
/// development machine: the same bytes, `correct` 10% faster at 128^3 than blocks of 8,
/// BENCHMARKS.md), else 8, the layout measured on an NVIDIA H100 and on lavapipe at 256 bits.
pub(super) fn block_bricks(info: &wgpu::AdapterInfo) -> u32 {
    if let Ok(v) = std::env::var(BLOCK_BRICKS_ENV) {
        match v.parse::<u32>() {
            Ok(n) if (8..=64).contains(&n) && n % 8 == 0 => return n,
            _ => tracing::warn!("{BLOCK_BRICKS_ENV}={v} ignored: not 8, 16, ... 64"),
        }
    }
    if info.device_type == wgpu::DeviceType::Cpu && info.subgroup_max_size == 16 {
        16
    } else {
        8
    }
}

/// The grid of a `correct` dispatch over `bricks` listed bricks, in whole blocks of
/// `block_bricks`, and its rows' stride in threads (`CorrectParams::grid_stride`): both from the
/// one thread count, so that thread index gid.x + gid.y * stride is unique.
fn correct_dispatch(bricks: u32, block_bricks: u32) -> ((u32, u32, u32), u32) {
    let threads = bricks.div_ceil(block_bricks) as u64 * 8 * block_bricks as u64;
    let (x, y, stride) = super::context::dispatch_grid(threads as u32);
    ((x, y, 1), stride)
}

/// Level `level`'s candidate tables (of `levels`), built from its pack and uploaded, with their
/// 3D slots per pixel.
pub(super) fn upload_tables(
    ctx: &GpuContext,
    p: &LevelPack,
    level: usize,
    levels: usize,
) -> Result<(wgpu::Buffer, u32)> {
    let slots = p.k3d_used(level + 1 == levels);
    let started = std::time::Instant::now();
    let words = candidate_tables(p, slots);
    tracing::debug!(
        "level {level}: candidate tables of {} KiB built in {:.1} ms",
        words.len() / 256,
        started.elapsed().as_secs_f64() * 1e3
    );
    let bytes = words.len() as u64 * 4;
    if bytes > ctx.max_binding_bytes() {
        return Err(Error::invalid(
            "exemplar",
            format!(
                "its candidate tables need {bytes} bytes per level on the GPU, over the \
                 adapter's {}-byte binding limit; use a smaller exemplar or --backend cpu",
                ctx.max_binding_bytes()
            ),
        ));
    }
    let buffer = ctx.storage_buffer_in_pieces("candidate tables", bytemuck::cast_slice(&words))?;
    Ok((buffer, slots))
}

impl GpuSynth {
    /// Tests: `n` listed bricks per block of `correct`'s k-major threads instead of the
    /// adapter's choice ([`block_bricks`]; a multiple of 8). The same results either way.
    pub(crate) fn set_block_bricks(&mut self, n: u32) {
        assert!(n >= 8 && n.is_multiple_of(8), "blocks of {n} bricks");
        self.block_bricks = n;
        for constants in &mut self.correct_constants {
            for (name, value) in constants.iter_mut() {
                if *name == "BLOCK_BRICKS" {
                    *value = n as f64;
                }
            }
        }
    }

    /// Release the `correct` pipelines that only the levels above `level` use (their constants
    /// differ from every later level's): for when no coarser level will be corrected again (the
    /// coarse cache built, a request's shared coarse levels done). On lavapipe each compiled
    /// variant keeps its compiler's memory, ~14-22 MB of the peak on an AMD EPYC development
    /// machine (BENCHMARKS.md).
    pub fn release_coarse_pipelines(&self, level: usize) {
        let later = &self.correct_constants[level..];
        for (i, c) in self.correct_constants[..level].iter().enumerate() {
            let repeated = self.correct_constants[..i].contains(c);
            if !later.contains(c) && !repeated {
                self.ctx.release_pipeline("correct", c);
            }
        }
    }

    /// Drop the candidate tables of the levels above `level`, which requests of the infinite
    /// solid no longer correct once the coarse cache is built: 11 of the 19 MiB of tables of the
    /// built-in exemplar's analysis. A later correction of such a level (a tileable solid)
    /// builds them again from the level data on the device (and keeps them).
    pub fn release_coarse_tables(&mut self, level: usize) {
        for t in &mut self.candidates.get_mut().unwrap()[..level] {
            *t = None;
        }
    }

    /// Tests: per level, whether its candidate tables are held now.
    #[doc(hidden)]
    pub fn tables_held(&self) -> Vec<bool> {
        self.candidates
            .lock()
            .unwrap()
            .iter()
            .map(Option::is_some)
            .collect()
    }

    /// Level `level`'s candidate tables and their 3D slots per pixel, built again from the
    /// level data on the device if they were released.
    fn level_tables(&self, level: usize) -> Result<(wgpu::Buffer, u32)> {
        let mut candidates = self.candidates.lock().unwrap();
        if let Some(t) = &candidates[level] {
            return Ok(t.clone());
        }
        let layout = &self.layouts[level];
        let words = self.levels[level].size() as usize / 4;
        let pack = LevelPack {
            words: self.ctx.read_words(&self.levels[level], words)?,
            ..layout.clone_layout()
        };
        let t = upload_tables(&self.ctx, &pack, level, self.layouts.len())?;
        candidates[level] = Some(t.clone());
        Ok(t)
    }

    /// One correction pass: the sub-passes `ps` in order, a `correct` each, after a copy of the
    /// state as the pass begins (`begin_pass`).
    pub fn correct_pass(
        &mut self,
        level: usize,
        ps: &[CorrectParams],
        s: &mut GpuState,
        index: &wgpu::Buffer,
    ) -> Result<()> {
        // Each class at most once: `correct` reads a voxel of its sub-pass's class from the
        // pass-start copy, which holds its current value only until that class is corrected.
        let classes: Vec<_> = ps
            .iter()
            .map(|p| (p.class_x, p.class_y, p.class_z))
            .collect();
        if (1..classes.len()).any(|i| classes[..i].contains(&classes[i])) {
            return Err(Error::Internal(format!(
                "a correction pass lists a class twice: {classes:?}"
            )));
        }
        self.begin_pass(s)?;
        for p in ps {
            self.correct(level, p, s, index)?;
        }
        Ok(())
    }

    /// What every `correct` dispatch of `level` binds besides the states (its candidate tables
    /// and projection weights) and its pipeline constants; an error when `p` scores more 3D
    /// candidates than the tables hold.
    fn correct_inputs(
        &self,
        level: usize,
        p: &CorrectParams,
    ) -> Result<(wgpu::Buffer, &wgpu::Buffer, Vec<(&'static str, f64)>)> {
        let (candidates, slots) = self.level_tables(level)?;
        if p.mode == 0 && p.k3d_used > slots {
            return Err(Error::Gpu(format!(
                "the correction scores {} 3D candidates per pixel; level {level}'s tables hold {slots}",
                p.k3d_used
            )));
        }
        let (projection, layout) = &self.projections[level];
        let constants =
            correct_constants(p.ex.channels, p.pca_out, p.k2d, *layout, self.block_bricks);
        Ok((candidates, projection, constants))
    }

    /// Begin a correction pass: record a copy of the state as it is now, which the pass's
    /// sub-passes read for voxels outside their own bricks.
    fn begin_pass(&mut self, s: &mut GpuState) -> Result<()> {
        if s.pass_start.is_none() {
            s.pass_start = Some(self.scratch_buffer("pass-start state", s.words));
        }
        let copy = s.pass_start.as_ref().unwrap();
        let mut pending = self.pending.lock().unwrap();
        let batch = pending.get_or_insert_with(|| self.new_batch());
        batch
            .encoder
            .copy_buffer_to_buffer(&s.current, 0, copy, 0, Some(s.words * 4));
        Ok(())
    }

    /// One correction sub-pass: `correct` corrects the listed class voxels in place (inside a
    /// pass, after [`Self::begin_pass`]).
    fn correct(
        &mut self,
        level: usize,
        p: &CorrectParams,
        s: &mut GpuState,
        index: &wgpu::Buffer,
    ) -> Result<()> {
        let (candidates, projection, constants) = self.correct_inputs(level, p)?;
        let start = s
            .pass_start
            .as_ref()
            .expect("a correction runs inside a pass (begin_pass)");
        let (grid, stride) = correct_dispatch(p.list_count, self.block_bricks);
        let p = CorrectParams {
            grid_stride: stride,
            ..*p
        };
        self.run(
            "correct",
            &constants,
            &p,
            &[
                (1, &self.levels[level]),
                (3, &s.current),
                (4, index),
                (5, projection),
                (6, &candidates),
                (7, start),
            ],
            grid,
        )
    }
}

#[cfg(test)]
mod tests {
    /// Every (listed brick, class voxel) of a `correct` dispatch is one thread's,
    /// and no thread's twice, for blocks of 8 to 64 bricks and list counts around the grid's
    /// second row (65535 workgroups of 64 threads), where a stride from another thread count
    /// gave two threads the same voxel. Mirrors `class_voxel` (wgsl/lib/synth_common.wgsl).
    #[test]
    fn correct_threads_cover_each_class_voxel_once() {
        let row_bricks = 65535 * 64 / 8;
        for block in [8u32, 16, 32, 64] {
            for bricks in [
                1,
                7,
                17,
                1000,
                row_bricks - 40,
                row_bricks - 3,
                row_bricks + 5,
            ] {
                let ((x, y, _), stride) = super::correct_dispatch(bricks, block);
                assert_eq!(stride, x * 64);
                let mut seen = vec![0u8; bricks as usize * 8];
                for gy in 0..y {
                    for gx in 0..x * 64 {
                        let t = gx + gy * stride;
                        let b = (t / (8 * block)) * block + t % block;
                        let k = (t / block) % 8;
                        if b < bricks {
                            seen[(b * 8 + k) as usize] += 1;
                        }
                    }
                }
                assert!(
                    seen.iter().all(|&n| n == 1),
                    "blocks of {block}, {bricks} bricks"
                );
            }
        }
    }
}
