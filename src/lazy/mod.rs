//! Lazy solid synthesis (paper section 5): any box of the infinite, spatially deterministic solid
//! defined by (analysis, seed, jitter, candidate mode, passes), on the GPU or the CPU with
//! byte-identical results.
//!
//! Per box: plan what each level must compute ([`plan`]); at l_start = L - 3 tile the candidate
//! slab warped by the jitter field (kernel `init`); then per level upsample (kernel `upsample`)
//! and run `passes` correction passes of 8 parity-class sub-passes (kernel `correct`); finally
//! average exemplar colours (kernel `colorize`). Large boxes are split into chunks, each
//! synthesized independently: determinism makes the seams invisible by construction.

pub mod balance;
mod brick_colors;
pub mod bricks;
mod coarse_cache;
pub mod color_match;
pub mod cut;
mod group;
mod group_plans;
pub mod grouping;
mod index_layout;
pub use crate::contract::jitter;
pub mod kernel_params;
mod level_triples;
pub mod memory;
mod options;
pub mod pack;
pub mod params;
pub mod plan;
mod request;
mod slabs;
mod tileable;

use crate::analysis::{Analysis, ANALYSED_LEVELS};
use crate::backend::synthesis as exec;
use crate::backend::Compute;
use crate::contract::uniforms::CorrectParams;
use crate::error::{Error, Result};
use crate::util::hash::hash32;
use crate::volume::Volume;
pub use balance::analyze;
pub use brick_colors::BrickColors;
pub use bricks::{Brick, BrickGrid, SparseLevel};
use index_layout::IndexLayout;
use level_triples::LevelTriples;
pub use memory::{group_cap, PADDING_ESTIMATE};
use options::RequestKind;
pub use options::{SynthOptions, MAX_GROUP_SIDES};
use pack::LevelPack;
use params::periods_below;
pub use params::{
    check_tileable_size, CandidateMode, ChannelSource, ChannelSources, ColorSource, PassSchedule, SynthParams,
    MAX_PASSES,
};
// The command line lists the coarse cache's valid sizes in its help.
#[cfg(feature = "cli")]
pub use params::{check_coarse_cache, COARSE_CACHE_PERIODS};
pub use plan::Box3;
use rayon::prelude::*;
pub use request::{Delivery, Region, Request};
use request::{Job, Periodic};
pub use slabs::Slab;
use slabs::SlabsJoined;

/// Order of the parity classes (bit 0 = x, 1 = y, 2 = z) within a pass. Sub-passes are
/// brick-local (`plan`), so the order does not change the dependency padding; it decides which
/// in-brick neighbours a class sees already updated, so another order gives a different solid.
pub const SUBPASS_ORDER: [usize; 8] = [0, 6, 5, 4, 3, 1, 2, 7];

/// Progress: (message, fraction of the whole job).
pub type Progress<'a> = &'a (dyn Fn(&str, f32) + Sync);

/// A synthesis session: packed exemplar data and kernels ready, any number of requests (boxes,
/// tileable solids, brick sets, sampled voxels), each taken through one path
/// (`request::for_each_group`) as a `request::Job`.
pub struct Synthesizer {
    pub params: SynthParams,
    /// How it runs (never what it computes).
    options: SynthOptions,
    /// Coarsest (l_start) first.
    packs: Vec<LevelPack>,
    border: u32,
    exec: exec::Executor,
    /// Whether the backend's memory is the host's (the CPU backend, a software or integrated
    /// GPU): the library's defaults for groups, shared coarse levels and overlapped reads
    /// depend on it.
    memory_is_hosts: bool,
    /// Per-kernel times when profiling (each kernel then waits for the device).
    times: Option<exec::KernelTimes>,
    last_stats: Option<SynthStats>,
    /// The coarse-level cache's triples on the backend, built and uploaded at its first use
    /// ([`Self::build_coarse_cache`]).
    cache_buf: Option<exec::IndexBuf>,
    /// When counting: per pack (coarsest first), per exemplar, how many stored voxels held each
    /// exemplar pixel after the level's correction (see [`Self::count_usage`]).
    usage: Option<Vec<[Vec<u64>; 3]>>,
    /// A plan made ahead (while deciding a request is one group, [`Self::planned_one_group`],
    /// or with the next groups' in parallel, [`Self::plan_ahead`]), with the group and exact
    /// part it is for: the group's synthesis takes it instead of planning again.
    next_plan: Option<(Vec<Brick>, Option<Box3>, Vec<SparseLevel>)>,
    /// Whether a request of several groups reads each group's colours back while the next
    /// group runs ([`SynthOptions::overlapped_reads`]): by default on a GPU whose memory is its
    /// own.
    overlap_reads: bool,
    /// Set while such a request runs: `synthesize_group` leaves its colours coming. (Each
    /// request of groups sets it before its first group; the other syntheses are of one group.)
    deferring: bool,
    /// Groups of the last request handed over while a later group ran (tests).
    overlapped_hand_overs: usize,
}

/// The smallest piece of per-voxel host work (a cut's lookups, points) handed to one thread.
pub const PARALLEL_PIECE: usize = 1 << 13;

impl Synthesizer {
    /// A synthesizer with the library's default [`SynthOptions`].
    pub fn new(analysis: &Analysis, params: SynthParams, compute: &Compute) -> Result<Synthesizer> {
        Self::with_options(analysis, params, compute, SynthOptions::default())
    }

    /// A synthesizer of `analysis` and `params` on `compute`, run as `options` say.
    pub fn with_options(
        analysis: &Analysis,
        params: SynthParams,
        compute: &Compute,
        options: SynthOptions,
    ) -> Result<Synthesizer> {
        params.validate()?;
        options.validate()?;
        let mut packs: Vec<LevelPack> = (0..ANALYSED_LEVELS)
            .rev()
            .map(|l| LevelPack::new(analysis, l))
            .collect();
        if let ColorSource::PerChannel(list) = params.color {
            let channels = analysis.color_channels;
            if u32::from(list.len) != channels {
                return Err(Error::invalid(
                    format!("--color {}", params.color),
                    format!(
                        "names {} channel sources; the exemplars have {channels} colour channels",
                        list.len
                    ),
                ));
            }
        }
        if params.color.needs_matching() {
            let table = Self::matching_table(analysis, &params, compute)?;
            let finest = packs.last_mut().unwrap();
            let at = finest.offsets.color_match as usize;
            finest.words[at..at + table.len()].copy_from_slice(&table);
        }
        let table = jitter::table();
        let mut exec = exec::Executor::new(compute, &mut packs, &table)?;
        if options.keep_buffers {
            exec.keep_buffers();
        }
        let memory_is_hosts = compute.memory_is_hosts();
        let is_gpu = matches!(compute, Compute::Gpu(_));
        Ok(Synthesizer {
            overlap_reads: is_gpu && options.overlapped_reads.unwrap_or(!memory_is_hosts),
            memory_is_hosts,
            deferring: false,
            overlapped_hand_overs: 0,
            params,
            packs,
            border: analysis.border.code(),
            exec,
            next_plan: None,
            times: options.profile.then(Default::default),
            options,
            last_stats: None,
            cache_buf: None,
            usage: None,
        })
    }

    /// The `--color matched` table of this analysis and these parameters: the statistics of
    /// the mean colours of a tileable probe solid (same analysis and parameters) taken to the
    /// exemplars' (see [`color_match`]).
    fn matching_table(
        analysis: &Analysis,
        params: &SynthParams,
        compute: &Compute,
    ) -> Result<Vec<u32>> {
        // Tileable solids are synthesized whole, without the coarse-level cache; a cached
        // solid's colour statistics are those of the same texture, so its table is the same
        // estimate.
        let probe_params = SynthParams {
            color: ColorSource::Average,
            coarse_cache: None,
            ..params.clone()
        };
        let mut probe = Synthesizer::new(analysis, probe_params, compute)?;
        let finest = probe.packs.last().unwrap();
        let edge = color_match::probe_edge(finest.width);
        let colors = analysis.color_channels as usize;
        let mut target = vec![[0u64; 256]; colors.min(4)];
        for e in 0..if analysis.shared { 1 } else { 3 } {
            let image = &analysis.exemplar(e).levels[0].image;
            let h = color_match::histograms(&image.pixels, image.channels as usize, colors);
            for (t, h) in target.iter_mut().zip(h) {
                t.iter_mut().zip(h).for_each(|(a, b)| *a += b);
            }
        }
        let (volume, _) = probe.synthesize_tileable(edge, &|_, _| {}, false)?;
        let source = color_match::histograms(&volume.data, volume.channels as usize, colors);
        Ok(color_match::table(&source, &target))
    }

    /// From now on, count after each level's correction how often every exemplar pixel is a
    /// coordinate of a stored voxel (the usage balancing's measurement, on tileable solids,
    /// whose stored voxels are exactly one period). Reading the counts back resets them.
    pub fn count_usage(&mut self) {
        self.usage = Some(
            self.packs
                .iter()
                .map(|p| std::array::from_fn(|_| vec![0; (p.width * p.height) as usize]))
                .collect(),
        );
    }

    /// The counts gathered since [`Self::count_usage`]: per pack (coarsest first), per exemplar
    /// (x, y, z), one count per exemplar pixel (row-major).
    pub fn take_usage(&mut self) -> Option<Vec<[Vec<u64>; 3]>> {
        let taken = self.usage.take();
        if taken.is_some() {
            self.count_usage();
        }
        taken
    }

    /// Colour channels of the volumes produced.
    pub fn color_channels(&self) -> u32 {
        self.packs[0].color_channels
    }

    /// Synthesize the box `out` (finest-level voxel coordinates, half-open).
    pub fn synthesize(&mut self, out: Box3, progress: Progress) -> Result<Volume> {
        Ok(self.synthesize_inner(out, progress, false)?.0)
    }

    /// [`Self::synthesize`] of a cut's box (one voxel thick): grouped as sampled voxels are
    /// (as few groups as the backend allows), not as a volume.
    pub(crate) fn synthesize_cut_box(&mut self, out: Box3) -> Result<Volume> {
        let mut whole = SlabsJoined::new(out.size(), self.color_channels(), false);
        let job = self.job(RequestKind::Voxels, false, &|_, _| {});
        self.synthesize_slabs_of(out, job, |slab| whole.push(slab))?;
        Ok(whole.finish().0)
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
        let mut whole = SlabsJoined::new(size, self.color_channels(), want_triples);
        self.synthesize_slabs(out, progress, want_triples, |slab| whole.push(slab))?;
        Ok(whole.finish())
    }

    /// Synthesize the box `out` and hand it to `sink` in slabs along z, in order: each slab
    /// spans the box's full x and y and as many z slices as one group of the synthesis (the
    /// box whole when it fits one group). Only one slab is held at a time, so with groups
    /// bounded ([`SynthOptions::max_group`]) a large box is written out (see
    /// [`crate::io::nrrd::SlabWriter`]) in bounded memory.
    pub fn synthesize_slabs(
        &mut self,
        out: Box3,
        progress: Progress,
        want_triples: bool,
        sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        let request = Request {
            region: Region::Box(out),
            want_triples,
            progress,
        };
        self.run(request, slabs_only(sink))
    }

    /// Synthesize every voxel of the finest-level bricks `requested` (4^3 voxels each, see
    /// `lazy::bricks`), computing only what they depend on. Large requests are split into
    /// groups of nearby bricks, each synthesized independently (determinism makes that
    /// invisible).
    pub fn synthesize_bricks(
        &mut self,
        requested: &[Brick],
        progress: Progress,
        want_triples: bool,
    ) -> Result<BrickColors> {
        let mut all = requested.to_vec();
        bricks::normalize(&mut all);
        let grid = BrickColors::lookup(&all);
        let mut colors = vec![0u32; all.len() * 64];
        let mut triples = vec![0u32; if want_triples { all.len() * 64 * 3 } else { 0 }];
        let request = Request {
            region: Region::Bricks(&all),
            want_triples,
            progress,
        };
        self.run(request, |delivery| {
            let Delivery::Bricks(group) = delivery else {
                unreachable!("bricks are delivered in groups")
            };
            for (j, b) in group.bricks.iter().enumerate() {
                let slot = BrickColors::slot_in(&all, grid.as_ref(), *b).expect("requested brick");
                colors[slot * 64..(slot + 1) * 64]
                    .copy_from_slice(&group.colors[j * 64..(j + 1) * 64]);
                if want_triples {
                    triples[slot * 192..(slot + 1) * 192]
                        .copy_from_slice(&group.triples[j * 192..(j + 1) * 192]);
                }
            }
            Ok(())
        })?;
        Ok(BrickColors {
            bricks: all,
            grid,
            colors,
            triples,
        })
    }

    /// [`Self::synthesize_bricks`] group by group: `sink` gets each group's requested bricks and
    /// their colours as soon as the group is done, so a caller that consumes them as they come
    /// (a surface's atlas) never holds the whole request's colours.
    pub fn synthesize_bricks_by_group(
        &mut self,
        requested: &[Brick],
        progress: Progress,
        mut sink: impl FnMut(BrickColors) -> Result<()>,
    ) -> Result<()> {
        let request = Request {
            region: Region::Bricks(requested),
            want_triples: false,
            progress,
        };
        self.run(request, |delivery| match delivery {
            Delivery::Bricks(group) => sink(group),
            _ => unreachable!("bricks are delivered in groups"),
        })
    }

    /// The packed colours of arbitrary voxels (any order, repeats allowed): only the bricks
    /// holding them are synthesized.
    pub fn sample(&mut self, voxels: &[[i32; 3]], progress: Progress) -> Result<Vec<u32>> {
        let limit = plan::COORDINATE_LIMIT;
        if let Some((i, v)) = voxels
            .iter()
            .enumerate()
            .find(|(_, v)| v.iter().any(|&c| (c as i64).abs() > limit))
        {
            return Err(Error::invalid(
                "voxels",
                format!("voxel {i} ({}, {}, {}) lies beyond +-{limit}", v[0], v[1], v[2]),
            ));
        }
        let mut colors = Vec::new();
        let request = Request {
            region: Region::Voxels(voxels),
            want_triples: false,
            progress,
        };
        self.run(request, |delivery| match delivery {
            Delivery::Colors(c) => {
                colors = c;
                Ok(())
            }
            _ => unreachable!("voxels are delivered as one list"),
        })?;
        Ok(colors)
    }

    /// [`Self::sample`]'s work ([`Region::Voxels`]).
    fn sample_voxels(&mut self, voxels: &[[i32; 3]], progress: Progress) -> Result<Vec<u32>> {
        let timer = std::time::Instant::now();
        // An axis-aligned cut at unit spacing asks for a box of voxels (one voxel thick):
        // planned voxel-exactly, its dependency padding surrounds one layer, not four. Its
        // bricks are the box's (sorted as they come), not found voxel by voxel and sorted.
        let exact = bricks::voxel_box(voxels);
        let wanted = match exact {
            Some(b) => bricks::bricks_of_box(b),
            None => bricks::bricks_of_voxels(voxels),
        };
        tracing::debug!("sample: bricks of the voxels in {:.1} ms", ms(timer));
        let job = Job {
            exact,
            ..self.job(RequestKind::Voxels, false, progress)
        };
        let result = self.synthesize_bricks_of(&wanted, job)?;
        let timer = std::time::Instant::now();
        // (Pieces of thousands of lookups: a warm cut's 65536 would otherwise be split into
        // as many tasks as the pool likes, whose wake-ups cost more than the lookups. Within a
        // piece, a run of voxels in one brick, as a cut's rows have, finds the brick once.)
        let result = &result;
        let colors = voxels
            .par_chunks(PARALLEL_PIECE)
            .flat_map_iter(|piece| {
                let mut last = None;
                piece
                    .iter()
                    .map(move |p| result.color_near(*p, &mut last).expect("requested voxel"))
            })
            .collect();
        tracing::debug!("sample: voxels' colours gathered in {:.1} ms", ms(timer));
        Ok(colors)
    }

    /// Voxels synthesized per level and peak state memory of the last synthesis.
    pub fn last_stats(&self) -> Option<&SynthStats> {
        self.last_stats.as_ref()
    }

    /// Tests: per level (coarsest first), whether the correction's derived tables are held
    /// now (released once the coarse cache is built, built again when needed).
    #[doc(hidden)]
    pub fn tables_held(&self) -> Vec<bool> {
        self.exec.tables_held()
    }

    /// Tests: `n` listed bricks (a multiple of 8) per block of the GPU `correct` kernel's
    /// k-major threads instead of the adapter's choice (8, or 16 on lavapipe at 512 bits). The
    /// same results either way.
    #[doc(hidden)]
    pub fn set_block_bricks(&mut self, n: u32) {
        self.exec.set_block_bricks(n);
    }

    /// Tests: on the CPU backend, every correction pass sub-pass by sub-pass against a copy of
    /// the state as the pass began (the reference of the brick-by-brick passes; same results).
    #[doc(hidden)]
    pub fn set_sub_pass_reference(&mut self, on: bool) {
        self.exec.set_sub_pass_reference(on);
    }

    /// Tests: how many groups of the last request were handed over while a later group ran
    /// ([`Self::set_overlapped_reads`]).
    #[doc(hidden)]
    pub fn overlapped_hand_overs(&self) -> usize {
        self.overlapped_hand_overs
    }

    /// Tests: a GPU parameter arena of `bytes`, so that batches fill up (see
    /// `GpuSynth::set_parameter_arena_bytes`).
    #[doc(hidden)]
    pub fn set_parameter_arena_bytes(&mut self, bytes: u64) -> Result<()> {
        self.exec.set_parameter_arena_bytes(bytes)
    }

    /// `Err(Error::Cancelled)` once the options' token is cancelled.
    fn check_cancelled(&self) -> Result<()> {
        self.options.cancel.as_ref().map_or(Ok(()), |t| t.check())
    }

    /// The options it runs with.
    pub fn options(&self) -> &SynthOptions {
        &self.options
    }

    /// Replace the cancellation token its requests check (None: they run to the end).
    pub fn set_cancel(&mut self, token: Option<crate::util::cancel::CancelToken>) {
        self.options.cancel = token;
    }

    /// A warm session (`CutSession`): the GPU keeps its state and colour buffers from one
    /// request for the next ones of the same sizes (no allocation and zeroing per request),
    /// and neither backend hands free heap back between groups (the next request would fault
    /// the pages in again).
    pub(crate) fn keep_buffers(&mut self) {
        self.options.keep_buffers = true;
        self.exec.keep_buffers();
    }

    /// Restart the kernel times (when profiling: [`SynthOptions::profile`]), e.g. to time warm
    /// requests only.
    pub fn reset_kernel_times(&mut self) {
        if let Some(t) = self.times.as_mut() {
            t.clear();
        }
    }

    /// The job of a request of `kind` of the infinite solid.
    fn job<'a>(&self, kind: RequestKind, want_triples: bool, progress: Progress<'a>) -> Job<'a> {
        Job {
            exact: None,
            periodic: Periodic::No,
            want_triples,
            max_group: self.group_limit(kind),
            progress,
        }
    }

    /// The largest group edge of a box or tileable request (None: as large as the backend
    /// allows): what a box's memory estimate assumes.
    pub fn volume_group_limit(&self) -> Option<u32> {
        self.group_limit(RequestKind::Volume)
    }

    /// The largest group edge of a request of `kind`: the options' `max_group`, else the
    /// library's default ([`SynthOptions::max_group`]).
    fn group_limit(&self, kind: RequestKind) -> Option<u32> {
        let user = self.options.max_group.map(|side| side.max(1));
        user.or_else(|| {
            (self.memory_is_hosts && kind != RequestKind::Voxels)
                .then_some(memory::HOST_MEMORY_GROUP)
        })
    }

    /// Whether a request's groups share their coarse levels ([`SynthOptions::shared_coarse_levels`]).
    fn shares_coarse_levels(&self) -> bool {
        self.options
            .shared_coarse_levels
            .unwrap_or(self.memory_is_hosts)
    }

    /// Kernel name -> (total time, calls), when profiling.
    pub fn kernel_times(&self) -> Option<&exec::KernelTimes> {
        self.times.as_ref()
    }
}



/// Milliseconds since `timer` started (for debug logs).
fn ms(timer: std::time::Instant) -> f64 {
    timer.elapsed().as_secs_f64() * 1e3
}

/// Voxels synthesized per level (coarsest first) and the peak state memory of one synthesis.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SynthStats {
    pub voxels_per_level: Vec<u64>,
    /// Largest state of one level with its pass-start copy where the backend keeps one (the
    /// GPU; the CPU only where voxels hold more than one value word), bytes.
    pub peak_state_bytes: u64,
    /// Groups of bricks synthesized independently.
    pub groups: usize,
}

/// A sink of [`Delivery`] pieces that takes slabs only (boxes, tileable solids).
fn slabs_only<'s>(
    mut sink: impl FnMut(Slab) -> Result<()> + 's,
) -> impl FnMut(Delivery) -> Result<()> + 's {
    move |delivery| match delivery {
        Delivery::Slab(slab) => sink(slab),
        _ => unreachable!("volumes are delivered in slabs"),
    }
}
