//! The resident state of the synthesis kernels `init`, `upsample`, `correct`, `colorize`, whose
//! dispatches live in `gpu/{init,upsample,correct,colorize}.rs` (CPU references in `src/cpu/`).
//! Level data stays resident; a level's state is one buffer, plus, during a
//! correction pass, a copy of the state as the pass began (`begin_pass`): brick-local sub-passes
//! read other bricks there, and their own brick's voxels of their own class, so that `correct`
//! writes its results straight into the state without any of its reads seeing them (see
//! `neighbour_word` in wgsl/correct.wgsl). Dispatches are recorded
//! into one command encoder and submitted together (`flush`: once per level, and before any
//! read) without waiting; the only wait is the bounded read-back of the colours.

use super::context::GpuContext;
use super::correct::{block_bricks, correct_constants, upload_tables};
pub use super::correct::WeightLayout;
use super::projection_weights::{projection_uniform, PROJECTION_VECTORS};
use crate::contract::level::LevelPack;
use crate::error::{Error, Result};
use std::sync::Arc;

pub struct GpuState {
    pub(super) current: wgpu::Buffer,
    /// A copy of the state as the current correction pass began (`begin_pass`): brick-local
    /// sub-passes read other bricks' voxels there.
    pub(super) pass_start: Option<wgpu::Buffer>,
    pub(super) words: u64,
    /// Where its buffers go when it is dropped, in a session that keeps them.
    pub(super) pool: Option<BufferPool>,
}

impl Drop for GpuState {
    fn drop(&mut self) {
        if let Some(pool) = &self.pool {
            pool.give(self.current.clone());
            if let Some(b) = self.pass_start.take() {
                pool.give(b);
            }
        }
    }
}

/// Device buffers a warm session keeps between its requests ([`GpuSynth::keep_buffers`]): a
/// request's states and colours come back here when it is done with them,
/// and the next request takes one of the same size instead of allocating (and having wgpu zero)
/// a new one. Every kernel writes the words it later reads (the kernels-tests run on poisoned
/// memory, and a test compares a warm session's repeated cuts with fresh ones), so what a buffer
/// held before does not matter. At most [`POOLED_BUFFERS`] and [`POOLED_BYTES`] are kept, the
/// oldest given back first.
#[derive(Clone, Default)]
pub(super) struct BufferPool(Arc<std::sync::Mutex<Vec<wgpu::Buffer>>>);

const POOLED_BUFFERS: usize = 8;
/// A 256^2 cut keeps under 45 MiB (a state, its pass-start copy, colours), an oblique 512^2 one
/// more; `serve` holds one pool per loaded solid, so the cap stays well below a device's memory.
const POOLED_BYTES: u64 = 256 << 20;

impl BufferPool {
    fn take(&self, bytes: u64) -> Option<wgpu::Buffer> {
        let mut kept = self.0.lock().unwrap();
        let i = kept.iter().position(|b| b.size() == bytes)?;
        Some(kept.remove(i))
    }

    pub(super) fn give(&self, buffer: wgpu::Buffer) {
        let mut kept = self.0.lock().unwrap();
        kept.push(buffer);
        while kept.len() > POOLED_BUFFERS
            || kept.iter().map(|b| b.size()).sum::<u64>() > POOLED_BYTES
        {
            kept.remove(0);
        }
    }
}

pub struct GpuSynth {
    pub(super) ctx: Arc<GpuContext>,
    pub(super) levels: Vec<wgpu::Buffer>,
    /// Per level, the `correct` kernel's projection weights ([`projection_uniform`]) and
    /// their layout.
    pub(super) projections: Vec<(wgpu::Buffer, WeightLayout)>,
    /// Per level, the `correct` kernel's candidate tables ([`candidate_tables`]) and their 3D
    /// slots per pixel; None once released ([`GpuSynth::release_coarse_tables`]) until a
    /// correction of the level needs them again (`GpuSynth::level_tables`).
    pub(super) candidates: std::sync::Mutex<Vec<Option<(wgpu::Buffer, u32)>>>,
    /// The levels' layouts (packs without their words), to build released tables again.
    pub(super) layouts: Vec<LevelPack>,
    /// Per level, the `correct` pipeline's constants ([`GpuSynth::correct_inputs`]).
    pub(super) correct_constants: Vec<Vec<(&'static str, f64)>>,
    /// Listed bricks per block of `correct`'s threads ([`block_bricks`]).
    pub(super) block_bricks: u32,
    pub(super) table: wgpu::Buffer,
    /// Dispatches recorded but not yet submitted, with their kernels' names: one submission
    /// per [`GpuSynth::flush`] (the executor flushes once per level, and every read flushes
    /// first) instead of one per dispatch.
    pub(super) pending: std::sync::Mutex<Option<Batch>>,
    /// The dispatches' parameters (uniform binding 0), one slice per dispatch of a batch: one
    /// upload per submission instead of a buffer per dispatch.
    pub(super) arena: wgpu::Buffer,
    /// Kept buffers, in a warm session ([`GpuSynth::keep_buffers`]).
    pub(super) pool: Option<BufferPool>,
}

/// Dispatches recorded and not yet submitted, with their kernels' names and parameters.
pub(super) struct Batch {
    pub(super) encoder: wgpu::CommandEncoder,
    pub(super) kernels: Vec<&'static str>,
    /// What [`GpuSynth::submit`] writes into the arena, each dispatch's at an aligned offset.
    pub(super) params: Vec<u8>,
}

/// Bytes of the parameter arena: 256 dispatches at the usual 256-byte offset alignment (a
/// level's batch has at most about 70); a fuller batch is submitted and a new one begun.
const ARENA_BYTES: usize = 64 << 10;

impl Batch {
    fn has_room(&self, bytes: usize, alignment: usize, capacity: u64) -> bool {
        (self.params.len().next_multiple_of(alignment) + bytes.next_multiple_of(16)) as u64
            <= capacity
    }

    /// Append `bytes` (zero-padded to 16) at the next aligned offset; returns the offset.
    fn push_params(&mut self, bytes: &[u8], alignment: usize) -> u64 {
        let offset = self.params.len().next_multiple_of(alignment);
        self.params.resize(offset, 0);
        self.params.extend_from_slice(bytes);
        self.params
            .resize(offset + bytes.len().next_multiple_of(16), 0);
        offset as u64
    }
}

pub(super) fn parameter_arena(ctx: &GpuContext, bytes: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("kernel parameters"),
        size: bytes,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn entries<'a>(buffers: &[(u32, &'a wgpu::Buffer)]) -> Vec<wgpu::BindGroupEntry<'a>> {
    buffers
        .iter()
        .map(|&(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect()
}

/// Workgroups for `threads` threads of a 64-wide kernel (the params carry the grid stride).
pub(super) fn groups(threads: u64) -> (u32, u32, u32) {
    let (x, y, _) = super::context::dispatch_grid(threads as u32);
    (x, y, 1)
}

impl GpuSynth {
    pub fn new(ctx: Arc<GpuContext>, packs: &[LevelPack], table: &[u32]) -> Result<GpuSynth> {
        for p in packs {
            let bytes = p.words.len() as u64 * 4;
            if bytes > ctx.max_binding_bytes() {
                return Err(Error::invalid(
                    "exemplar",
                    format!(
                        "its analysis needs {bytes} bytes per level on the GPU, over the adapter's \
                         {}-byte binding limit; use a smaller exemplar or --backend cpu",
                        ctx.max_binding_bytes()
                    ),
                ));
            }
        }
        let uniform_bytes = (PROJECTION_VECTORS * 16) as u64;
        if ctx.limits.max_uniform_buffer_binding_size < uniform_bytes {
            return Err(Error::Gpu(format!(
                "the adapter's uniform bindings hold {} bytes; the correction kernel needs \
                 {uniform_bytes}; use --backend cpu",
                ctx.limits.max_uniform_buffer_binding_size
            )));
        }
        let mut projections = Vec::with_capacity(packs.len());
        let preferred = if ctx.byte_weights {
            WeightLayout::Bytes
        } else {
            WeightLayout::Halves
        };
        for p in packs {
            let layout = projection_uniform(p, preferred).ok_or_else(|| {
                Error::invalid(
                    "exemplar",
                    format!(
                        "its PCA ({} inputs, {} outputs) is too large for the GPU correction \
                         kernel's weights; use --backend cpu",
                        p.pca_in, p.pca_out
                    ),
                )
            })?;
            use wgpu::util::DeviceExt;
            let buffer = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("projection weights"),
                    contents: bytemuck::cast_slice(&layout.vectors),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            projections.push((buffer, layout.layout));
        }
        let levels = packs
            .iter()
            .map(|p| ctx.storage_buffer_in_pieces("level data", bytemuck::cast_slice(&p.words)))
            .collect::<Result<_>>()?;
        let candidates = packs
            .iter()
            .enumerate()
            .map(|(i, p)| upload_tables(&ctx, p, i, packs.len()).map(Some))
            .collect::<Result<Vec<_>>>()?;
        let layouts = packs.iter().map(LevelPack::clone_layout).collect();
        let table = ctx.storage_buffer("jitter table", bytemuck::cast_slice(table));
        let arena = parameter_arena(&ctx, ARENA_BYTES as u64);
        let block_bricks = block_bricks(&ctx.info);
        tracing::debug!(
            "correct: blocks of {block_bricks} bricks (subgroups of {}-{} lanes)",
            ctx.info.subgroup_min_size,
            ctx.info.subgroup_max_size
        );
        let correct_constants: Vec<_> = packs
            .iter()
            .zip(&projections)
            .map(|(p, (_, layout))| {
                correct_constants(p.channels, p.pca_out, p.k2d, *layout, block_bricks)
            })
            .collect();
        // The kernels built before the synthesis starts, together. On a hardware GPU every
        // kernel a synthesis runs, `correct`'s variants (the long compiles) first. On a CPU
        // device `correct` is built at its first dispatch of each level, as the previous
        // levels run: its compiler shares the cores with them, and building the variants
        // together held 18 MB more at once for no measurable gain (lavapipe on an AMD EPYC
        // development machine).
        let mut kernels = Vec::new();
        if ctx.info.device_type != wgpu::DeviceType::Cpu {
            kernels.extend(correct_constants.iter().map(|c| ("correct", c.clone())));
        }
        kernels.extend(["init", "upsample", "colorize"].map(|k| (k, Vec::new())));
        ctx.prebuild_pipelines(&kernels)?;
        Ok(GpuSynth {
            ctx,
            levels,
            projections,
            candidates: std::sync::Mutex::new(candidates),
            layouts,
            table,
            pending: std::sync::Mutex::new(None),
            arena,
            pool: None,
            correct_constants,
            block_bricks,
        })
    }

    /// Whether buffers are kept between requests (a warm session, [`Self::keep_buffers`]).
    pub fn keeps_buffers(&self) -> bool {
        self.pool.is_some()
    }

    /// Shrink the parameter arena to `bytes` (after a flush), so that batches are submitted
    /// after a few dispatches: the kernels-tests take the path of a full arena that way.
    #[doc(hidden)]
    pub fn set_parameter_arena_bytes(&mut self, bytes: u64) -> Result<()> {
        // Room for the largest parameters (`CorrectParams`) at any offset alignment.
        if bytes < 512 || !bytes.is_multiple_of(16) {
            return Err(Error::invalid(
                "parameter arena",
                format!("{bytes} bytes; it needs a multiple of 16, at least 512"),
            ));
        }
        self.flush()?;
        self.arena = parameter_arena(&self.ctx, bytes);
        Ok(())
    }

    /// Keep the buffers of finished requests for the next ones (a warm session: `CutSession`,
    /// `serve`). Off by default: a one-off synthesis would only hold memory longer.
    pub fn keep_buffers(&mut self) {
        self.pool.get_or_insert_with(BufferPool::default);
    }

    /// A storage buffer of `words` words that a kernel fills before anything reads it: a kept one
    /// of that size when there is one.
    pub(super) fn scratch_buffer(&self, label: &str, words: u64) -> wgpu::Buffer {
        let bytes = words.max(1) * 4;
        self.pool
            .as_ref()
            .and_then(|p| p.take(bytes))
            .unwrap_or_else(|| self.ctx.device_buffer(label, words as usize))
    }

    pub fn max_state_bytes(&self) -> u64 {
        self.ctx.max_binding_bytes()
    }

    /// A state: `init` and `upsample` write every word of theirs, a correction's scratch is a
    /// copy of the state before its kernel runs.
    fn state_buffer(&self, words: u64) -> wgpu::Buffer {
        self.scratch_buffer("triples", words)
    }

    /// Record one dispatch of `kernel`: its parameters at binding 0 (a slice of the batch's
    /// parameter arena), `buffers` at the other bindings.
    pub(super) fn run<T: bytemuck::Pod>(
        &self,
        kernel: &'static str,
        constants: &[(&str, f64)],
        params: &T,
        buffers: &[(u32, &wgpu::Buffer)],
        grid: (u32, u32, u32),
    ) -> Result<()> {
        let pipeline = self.ctx.pipeline_with(kernel, constants)?;
        let bytes = bytemuck::bytes_of(params);
        let mut pending = self.pending.lock().unwrap();
        if pending
            .as_ref()
            .is_some_and(|b| !b.has_room(bytes.len(), self.arena_alignment(), self.arena.size()))
        {
            let full = pending.take().unwrap();
            self.submit(full)?;
        }
        let recorded = self.ctx.checked(kernel, || {
            let batch = pending.get_or_insert_with(|| self.new_batch());
            let offset = batch.push_params(bytes, self.arena_alignment());
            let mut entries = entries(buffers);
            entries.push(wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &self.arena,
                    offset,
                    size: std::num::NonZeroU64::new(bytes.len().next_multiple_of(16) as u64),
                }),
            });
            let bind = self
                .ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(kernel),
                    layout: &pipeline.get_bind_group_layout(0),
                    entries: &entries,
                });
            // One pass per dispatch: wgpu orders the passes' buffer accesses with barriers, as
            // separate submissions were ordered.
            let mut pass = batch
                .encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(kernel),
                    ..Default::default()
                });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(grid.0, grid.1, grid.2);
            batch.kernels.push(kernel);
            Ok(())
        });
        if recorded.is_err() {
            // The request fails; its batch (whose encoder may be invalid now) must not be
            // submitted with the next request's work.
            pending.take();
        }
        recorded
    }

    pub(super) fn new_batch(&self) -> Batch {
        Batch {
            encoder: self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("synthesis kernels"),
                }),
            kernels: Vec::new(),
            params: Vec::new(),
        }
    }

    fn arena_alignment(&self) -> usize {
        (self.ctx.limits.min_uniform_buffer_offset_alignment as usize).max(16)
    }

    /// Submit the recorded dispatches (errors found in them name their kernels).
    pub fn flush(&self) -> Result<()> {
        let batch = self.pending.lock().unwrap().take();
        match batch {
            Some(b) => self.submit(b),
            None => Ok(()),
        }
    }

    /// Upload a batch's parameters into the arena and submit its commands. The arena is reused
    /// by the next batch: the queue writes it after the work submitted before has run.
    fn submit(&self, batch: Batch) -> Result<()> {
        let mut names = batch.kernels;
        names.sort_unstable();
        names.dedup();
        self.ctx
            .checked(&format!("kernels {}", names.join(", ")), || {
                self.ctx.queue.write_buffer(&self.arena, 0, &batch.params);
                self.ctx.queue.submit(Some(batch.encoder.finish()));
                if tracing::enabled!(tracing::Level::DEBUG) {
                    if let Some(r) = self.ctx.device.generate_allocator_report() {
                        tracing::debug!(
                            "device memory after submitting {}: {:.1} MiB in {} buffers, {:.1} MiB \
                             of blocks",
                            names.join(", "),
                            r.total_allocated_bytes as f64 / (1 << 20) as f64,
                            r.allocations.len(),
                            r.total_reserved_bytes as f64 / (1 << 20) as f64
                        );
                    }
                }
                Ok(())
            })
    }

    /// A state built on the host.
    pub fn upload_state(&self, words: &[u32]) -> GpuState {
        use wgpu::util::DeviceExt;
        // Usable like any state (corrections copy it to and from their scratch buffer).
        let current = self
            .ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("uploaded state"),
                contents: bytemuck::cast_slice(words),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            });
        GpuState {
            current,
            pass_start: None,
            words: words.len() as u64,
            pool: self.pool.clone(),
        }
    }

    /// A brick index (tables and brick lists) on the device.
    pub fn upload_index(&self, words: &[u32]) -> wgpu::Buffer {
        self.ctx
            .storage_buffer("brick index", bytemuck::cast_slice(words))
    }

    /// Run a kernel that fills a fresh state of `bricks` bricks: uniform at binding 0, level data
    /// at 1, `input` at 2, the new state at 3, the brick index at 4, `extra` at 5 when given
    /// (`init` and `upsample`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fill_state<T: bytemuck::Pod>(
        &self,
        kernel: &'static str,
        params: &T,
        level: usize,
        input: &wgpu::Buffer,
        index: &wgpu::Buffer,
        extra: Option<&wgpu::Buffer>,
        bricks: u32,
        pixel_words: u32,
        constants: &[(&str, f64)],
    ) -> Result<GpuState> {
        let voxels = bricks as u64 * 64;
        let words = voxels * (3 + pixel_words as u64);
        let out = self.state_buffer(words);
        let mut buffers = vec![(1, &self.levels[level]), (2, input), (3, &out), (4, index)];
        buffers.extend(extra.map(|b| (5, b)));
        self.run(kernel, constants, params, &buffers, groups(voxels))?;
        Ok(GpuState {
            current: out,
            pass_start: None,
            words,
            pool: self.pool.clone(),
        })
    }

    /// Read a state back (tests and debugging).
    pub fn read_state(&self, s: &GpuState) -> Result<Vec<u32>> {
        self.flush()?;
        self.ctx.read_words(&s.current, s.words as usize)
    }

    /// Wait until all submitted kernels finished (for per-kernel timing).
    pub fn finish(&self) -> Result<()> {
        self.flush()?;
        self.ctx.wait_idle()
    }
}
