//! Dispatch of the synthesis kernels `init`, `upsample`, `correct`, `colorize` (CPU references
//! in `src/cpu/`). Level data stays resident; a level's state is one buffer, plus, during a
//! correction pass, a copy of the state as the pass began (`begin_pass`): brick-local sub-passes
//! read other bricks there, and their own brick's voxels of their own class, so that `correct`
//! writes its results straight into the state without any of its reads seeing them (see
//! `neighbour_word` in wgsl/correct.wgsl). Dispatches are recorded
//! into one command encoder and submitted together (`flush`: once per level, and before any
//! read) without waiting; the only wait is the bounded read-back of the colours.

use super::candidate_tables::candidate_tables;
use super::context::{GpuContext, PendingRead};
pub use super::projection_weights::WeightLayout;
use super::projection_weights::{projection_uniform, PROJECTION_VECTORS};
use crate::error::{Error, Result};
use crate::kernel_types::{ColorizeParams, CorrectParams, InitParams, UpsampleParams};
use crate::lazy::pack::LevelPack;
use std::sync::Arc;

pub struct GpuState {
    current: wgpu::Buffer,
    /// A copy of the state as the current correction pass began (`begin_pass`): brick-local
    /// sub-passes read other bricks' voxels there.
    pass_start: Option<wgpu::Buffer>,
    words: u64,
    /// Where its buffers go when it is dropped, in a session that keeps them.
    pool: Option<BufferPool>,
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
struct BufferPool(Arc<std::sync::Mutex<Vec<wgpu::Buffer>>>);

const POOLED_BUFFERS: usize = 8;
/// A 256^2 cut keeps about 45 MiB (a state, its pass-start copy, colours; measured with
/// the correction records that session 27 removed, so less now), an oblique 512^2 one more;
/// `serve` holds one pool per loaded solid, so the cap stays well below a device's memory.
const POOLED_BYTES: u64 = 256 << 20;

impl BufferPool {
    fn take(&self, bytes: u64) -> Option<wgpu::Buffer> {
        let mut kept = self.0.lock().unwrap();
        let i = kept.iter().position(|b| b.size() == bytes)?;
        Some(kept.remove(i))
    }

    fn give(&self, buffer: wgpu::Buffer) {
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
    ctx: Arc<GpuContext>,
    levels: Vec<wgpu::Buffer>,
    /// Per level, the `correct` kernel's projection weights ([`projection_uniform`]) and
    /// their layout.
    projections: Vec<(wgpu::Buffer, WeightLayout)>,
    /// Per level, the `correct` kernel's candidate tables ([`candidate_tables`]) and their 3D
    /// slots per pixel; None once released ([`GpuSynth::release_coarse_tables`]) until a
    /// correction of the level needs them again (`GpuSynth::level_tables`).
    candidates: std::sync::Mutex<Vec<Option<(wgpu::Buffer, u32)>>>,
    /// The levels' layouts (packs without their words), to build released tables again.
    layouts: Vec<LevelPack>,
    /// Per level, the `correct` pipeline's constants ([`GpuSynth::correct_inputs`]).
    correct_constants: Vec<Vec<(&'static str, f64)>>,
    /// Listed bricks per block of `correct`'s threads ([`block_bricks`]).
    block_bricks: u32,
    table: wgpu::Buffer,
    /// Dispatches recorded but not yet submitted, with their kernels' names: one submission
    /// per [`GpuSynth::flush`] (the executor flushes once per level, and every read flushes
    /// first) instead of one per dispatch.
    pending: std::sync::Mutex<Option<Batch>>,
    /// The dispatches' parameters (uniform binding 0), one slice per dispatch of a batch: one
    /// upload per submission instead of a buffer per dispatch.
    arena: wgpu::Buffer,
    /// Kept buffers, in a warm session ([`GpuSynth::keep_buffers`]).
    pool: Option<BufferPool>,
}

/// Dispatches recorded and not yet submitted, with their kernels' names and parameters.
struct Batch {
    encoder: wgpu::CommandEncoder,
    kernels: Vec<&'static str>,
    /// What [`GpuSynth::submit`] writes into the arena, each dispatch's at an aligned offset.
    params: Vec<u8>,
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

fn parameter_arena(ctx: &GpuContext, bytes: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("kernel parameters"),
        size: bytes,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The `correct` pipeline's override constants (see wgsl/correct.wgsl).
fn correct_constants(
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

/// Environment variable choosing `correct`'s block of bricks ([`block_bricks`]), for timing
/// layouts on a device without rebuilding (32, an NVIDIA warp, timed the same as 8 on an H100).
pub const BLOCK_BRICKS_ENV: &str = "SOLIDSYNTH_BLOCK_BRICKS";

/// Listed bricks per block of `correct`'s k-major threads (`class_voxel` in
/// wgsl/lib/synth_common.wgsl): `SOLIDSYNTH_BLOCK_BRICKS` when it names a multiple of 8 up to 64;
/// else a CPU device's SIMD width where it is 16 (lavapipe at 512 bits: the same bytes, `correct`
/// 10% faster at 128^3 than blocks of 8, BENCHMARKS.md session 29), else 8, the layout measured on
/// the H100 (session 24) and on lavapipe at 256 bits.
fn block_bricks(info: &wgpu::AdapterInfo) -> u32 {
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
fn groups(threads: u64) -> (u32, u32, u32) {
    let (x, y, _) = super::context::dispatch_grid(threads as u32);
    (x, y, 1)
}

/// Level `level`'s candidate tables (of `levels`), built from its pack and uploaded, with their
/// 3D slots per pixel.
fn upload_tables(
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
        // together held 18 MB more at once for no measurable gain (lavapipe, session 30).
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

    /// Tests: `n` listed bricks per block of `correct`'s k-major threads instead of the
    /// adapter's choice ([`block_bricks`]; a multiple of 8). The same results either way.
    pub(crate) fn set_block_bricks(&mut self, n: u32) {
        assert!(n >= 8 && n % 8 == 0, "blocks of {n} bricks");
        self.block_bricks = n;
        for constants in &mut self.correct_constants {
            for (name, value) in constants.iter_mut() {
                if *name == "BLOCK_BRICKS" {
                    *value = n as f64;
                }
            }
        }
    }

    /// Whether buffers are kept between requests (a warm session, [`Self::keep_buffers`]).
    pub fn keeps_buffers(&self) -> bool {
        self.pool.is_some()
    }

    /// Release the `correct` pipelines that only the levels above `level` use (their constants
    /// differ from every later level's): for when no coarser level will be corrected again (the
    /// coarse cache built, a request's shared coarse levels done). On lavapipe each compiled
    /// variant keeps its compiler's memory, ~14-22 MB of the peak (BENCHMARKS.md, session 27).
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

    /// Shrink the parameter arena to `bytes` (after a flush), so that batches are submitted
    /// after a few dispatches: the kernels-tests take the path of a full arena that way.
    #[doc(hidden)]
    pub fn set_parameter_arena_bytes(&mut self, bytes: u64) -> Result<()> {
        // Room for the largest parameters (`CorrectParams`) at any offset alignment.
        if bytes < 512 || bytes % 16 != 0 {
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
    fn scratch_buffer(&self, label: &str, words: u64) -> wgpu::Buffer {
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
    fn run<T: bytemuck::Pod>(
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

    fn new_batch(&self) -> Batch {
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
    fn fill_state<T: bytemuck::Pod>(
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

    /// `cache`: the coarse-level cache's triples when `p.cache_period` is set.
    pub fn init(
        &mut self,
        level: usize,
        p: &InitParams,
        index: &wgpu::Buffer,
        cache: Option<&wgpu::Buffer>,
    ) -> Result<GpuState> {
        if p.cache_period != 0 && cache.is_none() {
            return Err(Error::Gpu(
                "init from the coarse cache without its buffer".into(),
            ));
        }
        // (Binding 5 is declared whether or not the cache is read: the table stands in.)
        self.fill_state(
            "init",
            p,
            level,
            &self.table,
            index,
            Some(cache.unwrap_or(&self.table)),
            p.list_count,
            p.pixel_words,
            &[],
        )
    }

    /// `level`: the child level.
    pub fn upsample(
        &mut self,
        level: usize,
        p: &UpsampleParams,
        parent: GpuState,
        index: &wgpu::Buffer,
    ) -> Result<GpuState> {
        self.fill_state(
            "upsample",
            p,
            level,
            &parent.current,
            index,
            None,
            p.list_count,
            p.pixel_words,
            &[],
        )
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
        let constants = correct_constants(p.channels, p.pca_out, p.k2d, *layout, self.block_bricks);
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

    /// Record and submit `colorize` and begin reading its colours back; they come with
    /// [`Self::finish_read`].
    pub fn colorize(
        &mut self,
        level: usize,
        p: &ColorizeParams,
        s: &GpuState,
        index: &wgpu::Buffer,
    ) -> Result<PendingRead> {
        let n = p.list_count as usize * 64;
        // (`colorize` writes a colour per listed voxel.)
        let out = self.scratch_buffer("colours", n as u64);
        self.run(
            "colorize",
            &[],
            p,
            &[
                (1, &self.levels[level]),
                (2, &s.current),
                (3, &out),
                (4, index),
            ],
            groups(n as u64),
        )?;
        self.flush()?;
        let colours = self.ctx.start_read(&out, n);
        // (Reusable at once: whatever writes it next is queued after this copy.)
        if let Some(pool) = &self.pool {
            pool.give(out);
        }
        Ok(colours)
    }

    /// The words of a read begun here (a group's colours).
    pub fn finish_read(&self, read: PendingRead) -> Result<Vec<u32>> {
        self.ctx.finish_read(read)
    }
}

impl GpuSynth {
    /// Read a state back (tests and debugging).
    pub fn read_state(&self, s: &GpuState) -> Result<Vec<u32>> {
        self.flush()?;
        self.ctx.read_words(&s.current, s.words as usize)
    }
}

impl GpuSynth {
    /// Wait until all submitted kernels finished (for per-kernel timing).
    pub fn finish(&self) -> Result<()> {
        self.flush()?;
        self.ctx.wait_idle()
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
