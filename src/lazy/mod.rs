//! Lazy solid synthesis (paper section 5): any box of the infinite, spatially deterministic solid
//! defined by (analysis, seed, jitter, candidate mode, passes), on the GPU or the CPU with
//! byte-identical results.
//!
//! Per box: plan what each level must compute ([`plan`]); at l_start = L - 3 tile the candidate
//! slab warped by the jitter field (kernel `init`); then per level upsample (kernel `upsample`)
//! and run `passes` correction passes of 8 parity-class sub-passes (kernel `correct`); finally
//! average exemplar colours (kernel `colorize`). Large boxes are split into chunks, each
//! synthesized independently: determinism makes the seams invisible by construction.

pub mod cut;
pub mod exec;
pub mod jitter;
pub mod pack;
pub mod plan;

use crate::analysis::{Analysis, ANALYSED_LEVELS};
use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::kernel_types::{ColorizeParams, CorrectParams, InitParams, UpsampleParams};
use crate::util::hash::hash32;
use crate::volume::Volume;
use pack::LevelPack;
pub use plan::Box3;

/// Order of the parity classes (bit 0 = x, 1 = y, 2 = z) within a pass. Chosen (exhaustively,
/// over all 8! orders) to minimize the dependency padding: 13 voxels per level for two passes,
/// against 19 for the lexicographic order.
pub const SUBPASS_ORDER: [usize; 8] = [0, 6, 5, 4, 3, 1, 2, 7];

/// Which candidates the correction searches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum CandidateMode {
    /// Precomputed 3D candidates, two-step search (the paper's method).
    #[value(name = "3d")]
    ThreeD,
    /// Standard k-coherent 2D candidates, each direction searched independently (ablation).
    #[value(name = "2d")]
    TwoD,
}

/// Where an output voxel's colour comes from (the solid itself, its triples, is the same).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum ColorSource {
    /// The mean of the voxel's three exemplar pixels (the paper's rule).
    #[default]
    Average,
    /// The pixel of Ex (resp. Ey, Ez) at the voxel's coordinate in it: sharper, but only as
    /// consistent across axes as the synthesis made the triple.
    X,
    Y,
    Z,
}

/// What defines the solid besides the analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthParams {
    pub seed: u64,
    /// Jitter magnitude (0 disables; 1 is the default warp).
    pub jitter: f32,
    pub candidates: CandidateMode,
    /// Correction passes per level (the paper uses 2).
    pub passes: u32,
    /// Output colour rule.
    pub color: ColorSource,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            seed: 0,
            jitter: 1.0,
            candidates: CandidateMode::ThreeD,
            passes: 2,
            color: ColorSource::Average,
        }
    }
}

impl SynthParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.jitter.is_finite() && (0.0..=jitter::MAX_JITTER).contains(&self.jitter)) {
            return Err(Error::invalid(
                format!("--jitter {}", self.jitter),
                format!("must be a number in 0..={}", jitter::MAX_JITTER),
            ));
        }
        if self.passes > 8 {
            return Err(Error::invalid(
                format!("--passes {}", self.passes),
                "must be 0..=8 (0 shows the initialization)",
            ));
        }
        Ok(())
    }
}

/// Progress: (message, fraction of the whole job).
pub type Progress<'a> = &'a (dyn Fn(&str, f32) + Sync);

/// A synthesis session: packed exemplar data and kernels ready, any number of boxes.
pub struct Synthesizer {
    pub params: SynthParams,
    /// Coarsest (l_start) first.
    packs: Vec<LevelPack>,
    border: u32,
    exec: exec::Executor,
    /// Upper bound on chunk edges (None: as large as the backend allows).
    max_chunk_side: Option<u32>,
    /// Per-kernel times when profiling (each kernel then waits for the device).
    times: Option<exec::KernelTimes>,
}

impl Synthesizer {
    pub fn new(analysis: &Analysis, params: SynthParams, compute: &Compute) -> Result<Synthesizer> {
        params.validate()?;
        let packs: Vec<LevelPack> = (0..ANALYSED_LEVELS)
            .rev()
            .map(|l| LevelPack::new(analysis, l))
            .collect();
        let table = jitter::table();
        let exec = exec::Executor::new(compute, &packs, &table)?;
        Ok(Synthesizer {
            params,
            packs,
            border: analysis.border.code(),
            exec,
            max_chunk_side: None,
            times: None,
        })
    }

    /// Colour channels of the volumes produced.
    pub fn color_channels(&self) -> u32 {
        self.packs[0].color_channels
    }

    /// Bytes of working memory one chunk of `side`^3 needs at the finest level: two state
    /// buffers of the padded box, each voxel a triple and a value word (one word covers up to
    /// four channels; the estimate assumes that).
    pub fn chunk_bytes(side: u32) -> u64 {
        let padded = (side + 2 * PADDING_ESTIMATE) as u64;
        padded * padded * padded * 16 * 2
    }

    /// Synthesize the box `out` (finest-level voxel coordinates, half-open).
    pub fn synthesize(&mut self, out: Box3, progress: Progress) -> Result<Volume> {
        Ok(self.synthesize_inner(out, progress, false)?.0)
    }

    /// Like [`Self::synthesize`], also returning the finest-level triples of the box: 3 packed
    /// coordinates (x | y << 16, in Ex, Ey, Ez) per voxel, x fastest.
    pub fn synthesize_with_triples(
        &mut self,
        out: Box3,
        progress: Progress,
    ) -> Result<(Volume, Vec<u32>)> {
        self.synthesize_inner(out, progress, true)
    }

    fn synthesize_inner(
        &mut self,
        out: Box3,
        progress: Progress,
        want_triples: bool,
    ) -> Result<(Volume, Vec<u32>)> {
        let size = out.size();
        let mut triples = if want_triples {
            vec![0u32; out.voxels() as usize * 3]
        } else {
            Vec::new()
        };
        let channels = self.color_channels();
        let mut volume = Volume::new(size[0], size[1], size[2], channels);
        let chunks = self.chunks(out);
        for (i, chunk) in chunks.iter().enumerate() {
            let base = i as f32 / chunks.len() as f32;
            let scale = 1.0 / chunks.len() as f32;
            let (colors, chunk_triples) =
                self.synthesize_chunk(*chunk, &|m, f| progress(m, base + scale * f), want_triples)?;
            let cs = chunk.size();
            for z in 0..cs[2] {
                for y in 0..cs[1] {
                    for x in 0..cs[0] {
                        let word = colors[((z * cs[1] + y) * cs[0] + x) as usize].to_le_bytes();
                        let (vx, vy, vz) = (
                            (chunk.lo[0] - out.lo[0]) as u32 + x,
                            (chunk.lo[1] - out.lo[1]) as u32 + y,
                            (chunk.lo[2] - out.lo[2]) as u32 + z,
                        );
                        volume
                            .at_mut(vx, vy, vz)
                            .copy_from_slice(&word[..channels as usize]);
                        if want_triples {
                            let src = ((z * cs[1] + y) * cs[0] + x) as usize * 3;
                            let dst = ((vz * size[1] + vy) * size[0] + vx) as usize * 3;
                            triples[dst..dst + 3].copy_from_slice(&chunk_triples[src..src + 3]);
                        }
                    }
                }
            }
        }
        progress("done", 1.0);
        Ok((volume, triples))
    }

    /// Time every kernel (waiting for the device after each, so totals grow slightly).
    pub fn enable_profiling(&mut self) {
        self.times = Some(Default::default());
    }

    /// Kernel name -> (total time, calls), when profiling.
    pub fn kernel_times(&self) -> Option<&exec::KernelTimes> {
        self.times.as_ref()
    }

    /// Cap the chunk edge (the result is the same whatever the chunking; tests prove it).
    pub fn set_max_chunk_side(&mut self, side: u32) {
        self.max_chunk_side = Some(side.max(1));
    }

    /// Split `out` into cubes whose finest-level working set fits the backend's limit.
    fn chunks(&self, out: Box3) -> Vec<Box3> {
        let limit = self.exec.max_state_bytes();
        let mut side = self.max_chunk_side.unwrap_or(512).min(512);
        while side > 8 && Self::chunk_bytes(side) / 2 > limit {
            side -= 8;
        }
        let mut chunks = Vec::new();
        let mut z = out.lo[2];
        while z < out.hi[2] {
            let z1 = (z + side as i32).min(out.hi[2]);
            let mut y = out.lo[1];
            while y < out.hi[1] {
                let y1 = (y + side as i32).min(out.hi[1]);
                let mut x = out.lo[0];
                while x < out.hi[0] {
                    let x1 = (x + side as i32).min(out.hi[0]);
                    chunks.push(Box3::new([x, y, z], [x1, y1, z1]));
                    x = x1;
                }
                y = y1;
            }
            z = z1;
        }
        chunks
    }

    /// Colours of `out` (one packed word per voxel) and, when asked, its triples.
    fn synthesize_chunk(
        &mut self,
        out: Box3,
        progress: Progress,
        want_triples: bool,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        let plans = plan::plan(out, ANALYSED_LEVELS, self.params.passes as usize);
        let seed_lo = self.params.seed as u32;
        let seed_hi = (self.params.seed >> 32) as u32;
        let coarse = &self.packs[0];
        let amps = jitter::amplitudes(self.params.jitter);
        let sig = jitter::sigma2_fixed();
        let s0 = plans[0].storage;
        let init = InitParams {
            lo_x: s0.lo[0],
            lo_y: s0.lo[1],
            lo_z: s0.lo[2],
            size_x: s0.size()[0],
            size_y: s0.size()[1],
            size_z: s0.size()[2],
            ex_width: coarse.width,
            ex_height: coarse.height,
            border: self.border,
            seed_lo,
            seed_hi,
            jitter_on: (self.params.jitter > 0.0) as u32,
            tile_x: hash32(seed_lo ^ 0x51) % 5,
            tile_y: hash32(seed_hi ^ 0x52) % coarse.width,
            tile_z: hash32(seed_lo ^ seed_hi ^ 0x53) % coarse.height,
            slab_offset: coarse.offsets.slab,
            amp0: amps[0],
            amp1: amps[1],
            amp2: amps[2],
            amp3: amps[3],
            sig0: sig[0],
            sig1: sig[1],
            sig2: sig[2],
            sig3: sig[3],
            channels: coarse.channels,
            pixel_words: coarse.pixel_words,
            pixels0: coarse.offsets.pixels[0],
            pixels1: coarse.offsets.pixels[1],
            pixels2: coarse.offsets.pixels[2],
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        };
        progress("level 0: init", 0.0);
        let mut state = exec::timed(&mut self.exec, &mut self.times, "init", |e| {
            e.init(0, &init)
        })?;
        for (level, lp) in plans.iter().enumerate() {
            let pack = &self.packs[level];
            if level > 0 {
                let parent = plans[level - 1].storage;
                let child = lp.storage;
                let up = UpsampleParams {
                    parent_lo_x: parent.lo[0],
                    parent_lo_y: parent.lo[1],
                    parent_lo_z: parent.lo[2],
                    parent_size_x: parent.size()[0],
                    parent_size_y: parent.size()[1],
                    parent_size_z: parent.size()[2],
                    child_lo_x: child.lo[0],
                    child_lo_y: child.lo[1],
                    child_lo_z: child.lo[2],
                    child_size_x: child.size()[0],
                    child_size_y: child.size()[1],
                    child_size_z: child.size()[2],
                    ex_width: pack.width,
                    ex_height: pack.height,
                    border: self.border,
                    channels: pack.channels,
                    pixel_words: pack.pixel_words,
                    pixels0: pack.offsets.pixels[0],
                    pixels1: pack.offsets.pixels[1],
                    pixels2: pack.offsets.pixels[2],
                };
                state = exec::timed(&mut self.exec, &mut self.times, "upsample", |e| {
                    e.upsample(level, &up, state)
                })?;
            }
            progress(
                &format!("level {level}: correction"),
                (level as f32 + 0.1) / plans.len() as f32,
            );
            // The paper's reduced search at the finest level: 4 of the 3D candidates.
            let k3d_used = if level + 1 == plans.len() {
                4
            } else {
                pack.k3d_stride
            }
            .min(pack.k3d_stride);
            for (class, b) in &lp.subpasses {
                if b.is_empty() {
                    continue;
                }
                let par = [class & 1, (class >> 1) & 1, (class >> 2) & 1].map(|v| v as i32);
                let first = [0, 1, 2].map(|i| b.lo[i] + (par[i] - b.lo[i]).rem_euclid(2));
                let count = [0, 1, 2].map(|i| ((b.hi[i] - first[i]).max(0) as u32).div_ceil(2));
                if count.contains(&0) {
                    continue;
                }
                let mode = self.params.candidates;
                let p = correct_params(pack, lp.storage, first, count, k3d_used, self.border, mode);
                exec::timed(&mut self.exec, &mut self.times, "correct", |e| {
                    e.correct(level, &p, &mut state)
                })?;
            }
        }
        let finest = plans.last().unwrap();
        let pack = self.packs.last().unwrap();
        let c = ColorizeParams {
            lo_x: finest.storage.lo[0],
            lo_y: finest.storage.lo[1],
            lo_z: finest.storage.lo[2],
            size_x: finest.storage.size()[0],
            size_y: finest.storage.size()[1],
            size_z: finest.storage.size()[2],
            out_lo_x: out.lo[0],
            out_lo_y: out.lo[1],
            out_lo_z: out.lo[2],
            out_size_x: out.size()[0],
            out_size_y: out.size()[1],
            out_size_z: out.size()[2],
            color_channels: pack.color_channels,
            pixel_words: pack.pixel_words,
            source: self.params.color as u32,
            ex_width: pack.width,
            pixels0: pack.offsets.pixels[0],
            pixels1: pack.offsets.pixels[1],
            pixels2: pack.offsets.pixels[2],
            _pad: 0,
        };
        let colors = exec::timed(&mut self.exec, &mut self.times, "colorize", |e| {
            e.colorize(plans.len() - 1, &c, &state)
        })?;
        let mut triples = Vec::new();
        if want_triples {
            let words = self.exec.read_state(&state)?;
            let stride = 3 + pack.pixel_words as usize;
            triples.reserve(out.voxels() as usize * 3);
            for z in out.lo[2]..out.hi[2] {
                for y in out.lo[1]..out.hi[1] {
                    for x in out.lo[0]..out.hi[0] {
                        let i = finest.storage.index([x, y, z]) * stride;
                        triples.extend_from_slice(&words[i..i + 3]);
                    }
                }
            }
        }
        Ok((colors, triples))
    }
}

/// The uniforms of one `correct` sub-pass: the class voxels `first + 2 * (0..count)` of a level
/// whose state covers `storage`.
pub fn correct_params(
    pack: &LevelPack,
    storage: Box3,
    first: [i32; 3],
    count: [u32; 3],
    k3d_used: u32,
    border: u32,
    mode: CandidateMode,
) -> CorrectParams {
    let o = &pack.offsets;
    CorrectParams {
        lo_x: storage.lo[0],
        lo_y: storage.lo[1],
        lo_z: storage.lo[2],
        size_x: storage.size()[0],
        size_y: storage.size()[1],
        size_z: storage.size()[2],
        first_x: first[0],
        first_y: first[1],
        first_z: first[2],
        count_x: count[0],
        count_y: count[1],
        count_z: count[2],
        ex_width: pack.width,
        ex_height: pack.height,
        channels: pack.channels,
        pixel_words: pack.pixel_words,
        pca_in: pack.pca_in,
        pca_out: pack.pca_out,
        shift: pack.shift,
        proj_words: pack.proj_words,
        k2d: pack.k2d,
        k3d_used,
        k3d_stride: pack.k3d_stride,
        border: border,
        mode: (mode == CandidateMode::TwoD) as u32,
        shared_sets: pack.shared as u32,
        pixels0: o.pixels[0],
        pixels1: o.pixels[1],
        pixels2: o.pixels[2],
        proj0: o.projected[0],
        proj1: o.projected[1],
        proj2: o.projected[2],
        mean0: o.mean[0],
        mean1: o.mean[1],
        mean2: o.mean[2],
        weights0: o.weights[0],
        weights1: o.weights[1],
        weights2: o.weights[2],
        cand2d0: o.cand2d[0],
        cand2d1: o.cand2d[1],
        cand2d2: o.cand2d[2],
        cand3d0: o.cand3d[0],
        cand3d1: o.cand3d[1],
        cand3d2: o.cand3d[2],
        counts0: o.counts[0],
        counts1: o.counts[1],
        counts2: o.counts[2],
        _pad0: 0,
        _pad1: 0,
        _pad2: 0,
        _pad3: 0,
        _pad4: 0,
    }
}

/// Padding per side assumed when sizing chunks (the plan's exact padding is at most this).
pub const PADDING_ESTIMATE: u32 = 14;
