//! The door of the four synthesis kernels (`init`, `upsample`, `correct`, `colorize`) on the
//! chosen backend: the CPU executor calls the references in `cpu/`; the GPU executor
//! (`gpu::synth`) keeps the level data resident. The GPU keeps, during a correction
//! pass, a copy of the state as the pass began (`begin_pass`); the CPU only for passes that are
//! not whole bricks (its whole-brick passes hold back blocks of results instead,
//! `cpu::correct::correct_pass`).

use super::Compute;
use crate::contract::level::LevelPack;
use crate::contract::uniforms::{ColorizeParams, CorrectParams, InitParams, UpsampleParams};
use crate::error::Result;
use crate::gpu::synth::GpuSynth;

/// A level's brick index (tables and brick lists, `lazy::bricks`) on the backend.
pub enum IndexBuf {
    Cpu(Vec<u32>),
    Gpu(wgpu::Buffer),
}

impl IndexBuf {
    fn cpu(&self) -> &[u32] {
        match self {
            IndexBuf::Cpu(v) => v,
            IndexBuf::Gpu(_) => unreachable!("index from another backend"),
        }
    }
    fn gpu(&self) -> &wgpu::Buffer {
        match self {
            IndexBuf::Gpu(b) => b,
            IndexBuf::Cpu(_) => unreachable!("index from another backend"),
        }
    }
}

/// A level's triples on the backend. The CPU's holds its words and, during a correction pass
/// that is not of whole bricks, a copy of them as the pass began (brick-local sub-passes read
/// other bricks there; empty otherwise).
pub enum State {
    Cpu(Vec<u32>, Vec<u32>),
    Gpu(crate::gpu::synth::GpuState),
}

pub enum Executor {
    Cpu {
        levels: Vec<Vec<u32>>,
        table: Vec<u32>,
        /// Per level, the correction's derived tables, built at the level's first sub-pass and
        /// kept (a warm cut session reuses them) until the coarse cache is built
        /// ([`Executor::release_coarse_levels`]); built again if needed after that.
        prepared: Vec<std::sync::OnceLock<crate::cpu::correct::Prepared>>,
        /// Tests: every pass sub-pass by sub-pass against a pass-start copy (the reference the
        /// brick-by-brick passes must equal), see [`Executor::set_sub_pass_reference`].
        sub_pass_reference: bool,
        /// A warm session ([`Executor::keep_buffers`]): its states are plain vectors, but its
        /// requests keep the heap as it is between them.
        warm: bool,
    },
    Gpu(Box<GpuSynth>),
}

impl Executor {
    /// Takes the packs' level data ([`LevelPack::words`], left empty): the CPU keeps it, the
    /// GPU uploads it. The caller keeps the layouts, which is all the planning reads, so the
    /// level data is held once (14 MiB for the built-in exemplar), not twice.
    pub fn new(compute: &Compute, packs: &mut [LevelPack], table: &[u32]) -> Result<Executor> {
        let exec = match compute {
            Compute::Cpu => Executor::Cpu {
                levels: packs
                    .iter_mut()
                    .map(|p| std::mem::take(&mut p.words))
                    .collect(),
                table: table.to_vec(),
                prepared: packs.iter().map(|_| Default::default()).collect(),
                sub_pass_reference: false,
                warm: false,
            },
            Compute::Gpu(ctx) => Executor::Gpu(Box::new(GpuSynth::new(ctx.clone(), packs, table)?)),
        };
        for p in packs.iter_mut() {
            p.words = Vec::new();
        }
        Ok(exec)
    }

    /// Largest state (one triple buffer) a chunk may use.
    /// The state's words (triples and values), copied to the host.
    pub fn read_state(&self, state: &State) -> Result<Vec<u32>> {
        match (self, state) {
            (Executor::Cpu { .. }, State::Cpu(v, _)) => Ok(v.clone()),
            (Executor::Gpu(g), State::Gpu(s)) => g.read_state(s),
            _ => unreachable!("state from another backend"),
        }
    }

    /// Submit the work recorded so far (the GPU records a level's dispatches and submits them
    /// together; the CPU runs each kernel as it is called).
    pub fn flush(&self) -> Result<()> {
        match self {
            Executor::Cpu { .. } => Ok(()),
            Executor::Gpu(g) => g.flush(),
        }
    }

    /// Whether this is a warm session ([`Self::keep_buffers`]).
    pub fn keeps_buffers(&self) -> bool {
        match self {
            Executor::Cpu { warm, .. } => *warm,
            Executor::Gpu(g) => g.keeps_buffers(),
        }
    }

    /// No level above `level` will be corrected again: the GPU releases their `correct`
    /// pipelines ([`crate::gpu::synth::GpuSynth::release_coarse_pipelines`]).
    pub fn release_coarse_pipelines(&self, level: usize) {
        if let Executor::Gpu(g) = self {
            g.release_coarse_pipelines(level);
            crate::util::memory::return_free_heap();
        }
    }

    /// The coarse cache is built: no level above `level` will be corrected again by a request
    /// of the infinite solid. Release their `correct` pipelines and derived tables: the GPU
    /// its candidate tables ([`GpuSynth::release_coarse_tables`]), the CPU its prepared
    /// tables. A tileable synthesis, which corrects those levels again, builds them again (the
    /// GPU's from the level data on the device).
    pub fn release_coarse_levels(&mut self, level: usize) {
        match self {
            Executor::Cpu { prepared, .. } => {
                for p in &mut prepared[..level] {
                    p.take();
                }
            }
            Executor::Gpu(g) => {
                g.release_coarse_pipelines(level);
                g.release_coarse_tables(level);
            }
        }
        crate::util::memory::return_free_heap();
    }

    /// Tests: per level, whether its correction's derived tables are held now (the GPU's
    /// candidate tables, the CPU's prepared tables, built at a level's first correction).
    pub fn tables_held(&self) -> Vec<bool> {
        match self {
            Executor::Cpu { prepared, .. } => prepared.iter().map(|p| p.get().is_some()).collect(),
            Executor::Gpu(g) => g.tables_held(),
        }
    }

    /// A warm session: the GPU keeps device buffers from one request to the next (the CPU
    /// backend's states are plain vectors), and neither hands free heap back between groups.
    pub fn keep_buffers(&mut self) {
        match self {
            Executor::Cpu { warm, .. } => *warm = true,
            Executor::Gpu(g) => g.keep_buffers(),
        }
    }

    /// See `GpuSynth::set_block_bricks` (nothing on the CPU backend).
    pub fn set_block_bricks(&mut self, n: u32) {
        if let Executor::Gpu(g) = self {
            g.set_block_bricks(n);
        }
    }

    /// Tests: the CPU backend runs every correction pass sub-pass by sub-pass against a copy of
    /// the state as the pass began, never brick by brick in place (the same results; the GPU
    /// is unaffected).
    pub fn set_sub_pass_reference(&mut self, on: bool) {
        if let Executor::Cpu {
            sub_pass_reference, ..
        } = self
        {
            *sub_pass_reference = on;
        }
    }

    /// See [`GpuSynth::set_parameter_arena_bytes`] (the CPU backend has no arena).
    pub fn set_parameter_arena_bytes(&mut self, bytes: u64) -> Result<()> {
        match self {
            Executor::Gpu(g) => g.set_parameter_arena_bytes(bytes),
            Executor::Cpu { .. } => Ok(()),
        }
    }

    /// Copies of a level's state a correction pass holds: the GPU's state and its pass-start
    /// copy; on the CPU the state alone (a pass of whole bricks holds back two blocks of z
    /// layers of corrected bricks instead, at most about a quarter of a state,
    /// `cpu::correct::correct_pass`), two where voxels hold more than one value word (a
    /// pass-start copy).
    pub fn state_copies(&self, pixel_words: u32) -> u64 {
        match self {
            Executor::Cpu { .. } if pixel_words == 1 => 1,
            _ => 2,
        }
    }

    pub fn max_state_bytes(&self) -> u64 {
        match self {
            Executor::Cpu { .. } => 1 << 31,
            Executor::Gpu(g) => g.max_state_bytes(),
        }
    }

    /// A state built on the host (e.g. from the coarse-level cache).
    pub fn upload_state(&self, words: Vec<u32>) -> Result<State> {
        match self {
            Executor::Cpu { .. } => Ok(State::Cpu(words, Vec::new())),
            Executor::Gpu(g) => Ok(State::Gpu(g.upload_state(&words))),
        }
    }

    pub fn upload_index(&self, words: Vec<u32>) -> IndexBuf {
        match self {
            Executor::Cpu { .. } => IndexBuf::Cpu(words),
            Executor::Gpu(g) => IndexBuf::Gpu(g.upload_index(&words)),
        }
    }

    /// `cache`: the coarse-level cache's triples (uploaded with [`Self::upload_index`]) when
    /// `p.cache_period` is set.
    pub fn init(
        &mut self,
        level: usize,
        p: &InitParams,
        index: &IndexBuf,
        cache: Option<&IndexBuf>,
    ) -> Result<State> {
        match self {
            Executor::Cpu { levels, table, .. } => Ok(State::Cpu(
                crate::cpu::init::init(
                    p,
                    table,
                    &levels[level],
                    index.cpu(),
                    cache.map_or(&[][..], |c| c.cpu()),
                ),
                Vec::new(),
            )),
            Executor::Gpu(g) => Ok(State::Gpu(g.init(
                level,
                p,
                index.gpu(),
                cache.map(|c| c.gpu()),
            )?)),
        }
    }

    /// `level` is the child level, `index` its brick index.
    pub fn upsample(
        &mut self,
        level: usize,
        p: &UpsampleParams,
        parent: State,
        index: &IndexBuf,
    ) -> Result<State> {
        match (self, parent) {
            (Executor::Cpu { levels, .. }, State::Cpu(v, _)) => Ok(State::Cpu(
                crate::cpu::upsample::upsample(p, &levels[level], &v, index.cpu()),
                Vec::new(),
            )),
            (Executor::Gpu(g), State::Gpu(s)) => {
                Ok(State::Gpu(g.upsample(level, p, s, index.gpu())?))
            }
            _ => unreachable!("state from another backend"),
        }
    }

    /// One correction pass: the sub-passes `ps` in order. Each reads a neighbour in its own
    /// brick as the earlier sub-passes left it and one in another brick as it was when the pass
    /// began (brick-local sub-passes, `plan`).
    pub fn correct_pass(
        &mut self,
        level: usize,
        ps: &[CorrectParams],
        state: &mut State,
        index: &IndexBuf,
    ) -> Result<()> {
        let Some(p0) = ps.first() else { return Ok(()) };
        match (self, state) {
            (
                Executor::Cpu {
                    levels,
                    prepared,
                    sub_pass_reference,
                    ..
                },
                State::Cpu(v, pass_start),
            ) => {
                use crate::cpu::correct::{correct_pass, Prepared};
                let data = &levels[level];
                let mut prep = prepared[level].get_or_init(|| Prepared::new(p0, data));
                // (A pack's layout does not change between sub-passes; rebuilt if it ever did.)
                let rebuilt;
                if !prep.fits(p0) {
                    rebuilt = Prepared::new(p0, data);
                    prep = &rebuilt;
                }
                correct_pass(
                    prep,
                    ps,
                    data,
                    v,
                    pass_start,
                    index.cpu(),
                    !*sub_pass_reference,
                );
                Ok(())
            }
            (Executor::Gpu(g), State::Gpu(s)) => g.correct_pass(level, ps, s, index.gpu()),
            _ => unreachable!("state from another backend"),
        }
    }

    /// The colours of the voxels `p` lists: on the GPU still coming back (the kernel and the
    /// copy submitted), to be taken with [`Self::finish_colors`].
    pub fn colorize(
        &mut self,
        level: usize,
        p: &ColorizeParams,
        state: &State,
        index: &IndexBuf,
    ) -> Result<Colors> {
        match (self, state) {
            (Executor::Cpu { levels, .. }, State::Cpu(v, _)) => Ok(Colors::Ready(
                crate::cpu::colorize::colorize(p, &levels[level], v, index.cpu()),
            )),
            (Executor::Gpu(g), State::Gpu(s)) => {
                g.colorize(level, p, s, index.gpu()).map(Colors::Coming)
            }
            _ => unreachable!("state from another backend"),
        }
    }

    /// The colours of [`Self::colorize`], waiting for them if they are still coming.
    pub fn finish_colors(&self, colors: Colors) -> Result<Vec<u32>> {
        match (self, colors) {
            (_, Colors::Ready(v)) => Ok(v),
            (Executor::Gpu(g), Colors::Coming(read)) => g.finish_read(read),
            (Executor::Cpu { .. }, Colors::Coming(_)) => unreachable!("a read of another backend"),
        }
    }
}

/// A group's colours (64 per brick), ready or still being read back from the GPU.
pub enum Colors {
    Ready(Vec<u32>),
    Coming(crate::gpu::context::PendingRead),
}

/// Wall time and calls per kernel, when profiling.
pub type KernelTimes = std::collections::BTreeMap<&'static str, (std::time::Duration, u32)>;

/// Runs `f`, waiting for the GPU afterwards when profiling, and adds its time to `times[kernel]`.
pub fn timed<T>(
    exec: &mut Executor,
    times: &mut Option<KernelTimes>,
    kernel: &'static str,
    f: impl FnOnce(&mut Executor) -> Result<T>,
) -> Result<T> {
    let Some(t) = times else { return f(exec) };
    let start = std::time::Instant::now();
    let out = f(exec)?;
    if let Executor::Gpu(g) = exec {
        g.finish()?;
    }
    let elapsed = start.elapsed();
    tracing::trace!("kernel {kernel}: {:.1} ms", elapsed.as_secs_f64() * 1e3);
    let e = t.entry(kernel).or_default();
    e.0 += elapsed;
    e.1 += 1;
    Ok(out)
}
