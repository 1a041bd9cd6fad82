//! Lazy solid synthesis (paper section 5): any box of the infinite, spatially deterministic solid
//! defined by (analysis, seed, jitter, candidate mode, passes), on the GPU or the CPU with
//! byte-identical results.
//!
//! Per box: plan what each level must compute ([`plan`]); at l_start = L - 3 tile the candidate
//! slab warped by the jitter field (kernel `init`); then per level upsample (kernel `upsample`)
//! and run `passes` correction passes of 8 parity-class sub-passes (kernel `correct`); finally
//! average exemplar colours (kernel `colorize`). Large boxes are split into chunks, each
//! synthesized independently: determinism makes the seams invisible by construction.

pub mod bricks;
pub mod color_match;
pub mod cut;
pub mod exec;
mod group;
pub mod grouping;
mod index_layout;
pub mod jitter;
mod level_triples;
pub mod pack;
pub mod params;
pub mod plan;

use crate::analysis::{Analysis, ANALYSED_LEVELS};
use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::kernel_types::{ColorizeParams, CorrectParams, InitParams, UpsampleParams};
use crate::util::hash::hash32;
use crate::volume::Volume;
pub use bricks::{Brick, BrickGrid, SparseLevel};
use group::{FirstLevel, GroupResult};
use index_layout::IndexLayout;
use level_triples::LevelTriples;
use pack::LevelPack;
use params::periods_below;
pub use params::{
    check_tileable_size, CandidateMode, ChannelSource, ChannelSources, ColorSource, PassSchedule,
    SynthParams, MAX_PASSES,
};
pub use plan::Box3;
use rayon::prelude::*;

/// Order of the parity classes (bit 0 = x, 1 = y, 2 = z) within a pass. Chosen (exhaustively,
/// over all 8! orders) to minimize the dependency padding when every sub-pass read the latest
/// values (13 voxels per level for two passes, against 19 for the lexicographic order); since
/// sub-passes are brick-local (`plan`) the order no longer changes the padding, only which
/// in-brick neighbours a class sees updated.
pub const SUBPASS_ORDER: [usize; 8] = [0, 6, 5, 4, 3, 1, 2, 7];

/// Slabs of one volume (see [`Slab`]) joined back into the whole volume and its triples.
struct SlabsJoined {
    volume: Volume,
    triples: Vec<u32>,
}

impl SlabsJoined {
    fn new(size: [u32; 3], channels: u32, want_triples: bool) -> SlabsJoined {
        let voxels = size.iter().map(|&d| d as usize).product::<usize>();
        let mut volume = Volume::new(size[0], size[1], 0, channels);
        volume.data.reserve(voxels * channels as usize);
        let triples = Vec::with_capacity(if want_triples { voxels * 3 } else { 0 });
        SlabsJoined { volume, triples }
    }

    /// The next slab along z.
    fn push(&mut self, slab: Slab) -> Result<()> {
        self.volume.data.extend_from_slice(&slab.volume.data);
        self.volume.nz += slab.volume.nz;
        self.triples.extend_from_slice(slab.triples);
        Ok(())
    }

    fn finish(self) -> (Volume, Vec<u32>) {
        (self.volume, self.triples)
    }
}

/// Consecutive z slices of a synthesized box (see [`Synthesizer::synthesize_slabs`]).
pub struct Slab<'a> {
    /// First slice's z, relative to the box.
    pub z0: u32,
    /// The slices: the box's x and y extents, `volume.nz` slices.
    pub volume: &'a Volume,
    /// Their triples (3 packed coordinates per voxel, x fastest) when asked for, else empty.
    pub triples: &'a [u32],
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
    /// Whether several groups share their coarse levels (see
    /// [`Self::set_shared_coarse_levels`]); None: `shared_coarse_default`.
    shared_coarse: Option<bool>,
    /// Shared on the CPU backend and on GPUs that share the host's memory, not on GPUs with
    /// their own memory.
    shared_coarse_default: bool,
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
    /// A lower bound than the backend's on one level's state ([`Self::set_state_limit`]).
    state_limit: Option<u64>,
    /// Whether a request of several groups reads each group's colours back while the next
    /// group runs ([`Self::set_overlapped_reads`]): on a GPU whose memory is its own.
    overlap_reads: bool,
    /// Set while such a request runs: `synthesize_group` leaves its colours coming. (Each
    /// request of groups sets it before its first group; the other syntheses are of one group.)
    deferring: bool,
    /// Groups of the last request handed over while a later group ran (tests).
    overlapped_hand_overs: usize,
}

/// The smallest piece of per-voxel host work (a cut's lookups, points) handed to one thread.
pub const PARALLEL_PIECE: usize = 1 << 13;

/// At most this many plans of groups' every level are held at once ([`parents_of_groups`],
/// [`Synthesizer::plan_ahead`]).
const PLANS_AT_ONCE: usize = 4;

/// At most this many requested bricks (4^3 voxels each) are planned ahead together
/// ([`Synthesizer::plan_ahead`]): a plan holds its levels' brick lists and tables, tens of bytes
/// per brick, so a window of large groups would hold a lot.
const PLAN_AHEAD_BRICKS: usize = 1 << 17;

/// How a planned synthesis treats positions beyond a tileable solid's period.
#[derive(Clone, Copy)]
enum Periodic<'a> {
    /// The infinite solid.
    No,
    /// Per level, the period: each level stores exactly one period, and reads wrap around it.
    Wrapped(&'a [u32]),
    /// Per level, the period: the levels store a box of the periodic solid with its dependency
    /// padding, like any box request, and read it unwrapped. Only the initial level's tiling
    /// and jitter field wrap (they are periodic functions of position); the correction and
    /// upsampling of a periodic level give a periodic level, so every voxel of the box gets the
    /// value it has in the [`Periodic::Wrapped`] synthesis.
    Unwrapped(&'a [u32]),
}

impl Periodic<'_> {
    /// The period of the initial level's tiling and jitter field (0: none).
    fn init_period(self) -> u32 {
        match self {
            Periodic::No => 0,
            Periodic::Wrapped(p) | Periodic::Unwrapped(p) => p[0],
        }
    }

    /// The period around which level `l`'s reads wrap (0: none).
    fn read_period(self, l: usize) -> u32 {
        match self {
            Periodic::Wrapped(p) => p[l],
            Periodic::No | Periodic::Unwrapped(_) => 0,
        }
    }
}

impl Synthesizer {
    pub fn new(analysis: &Analysis, params: SynthParams, compute: &Compute) -> Result<Synthesizer> {
        params.validate()?;
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
        let exec = exec::Executor::new(compute, &mut packs, &table)?;
        let own_memory_gpu = matches!(compute, Compute::Gpu(_)) && !compute.memory_is_hosts();
        Ok(Synthesizer {
            overlap_reads: own_memory_gpu,
            shared_coarse_default: !own_memory_gpu,
            deferring: false,
            overlapped_hand_overs: 0,
            params,
            packs,
            border: analysis.border.code(),
            exec,
            max_chunk_side: None,
            shared_coarse: None,
            next_plan: None,
            state_limit: None,
            times: None,
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

    /// Bytes of working memory one chunk of `side`^3 needs at the finest level, at most: two
    /// state buffers of the padded box (the GPU's state and its pass-start copy; the CPU
    /// backend holds one), each voxel a triple and a value word (one word covers up to four
    /// channels; the estimate assumes that).
    pub fn chunk_bytes(side: u32) -> u64 {
        grouping::padded_state_bytes([side as u64; 3]) * 2
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
        let mut whole = SlabsJoined::new(size, self.color_channels(), want_triples);
        self.synthesize_slabs(out, progress, want_triples, |slab| whole.push(slab))?;
        Ok(whole.finish())
    }

    /// Synthesize the box `out` and hand it to `sink` in slabs along z, in order: each slab
    /// spans the box's full x and y and as many z slices as one group of the synthesis (the
    /// box whole when it fits one group). Only one slab is held at a time, so with groups
    /// bounded by [`Self::set_max_chunk_side`] a large box is written out (see
    /// [`crate::io::nrrd::SlabWriter`]) in bounded memory.
    pub fn synthesize_slabs(
        &mut self,
        out: Box3,
        progress: Progress,
        want_triples: bool,
        sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        self.synthesize_slabs_of(out, Periodic::No, progress, want_triples, sink)
    }

    /// [`Self::synthesize_slabs`] of the infinite solid ([`Periodic::No`]) or of a periodic one
    /// ([`Periodic::Unwrapped`]).
    fn synthesize_slabs_of(
        &mut self,
        out: Box3,
        periodic: Periodic,
        progress: Progress,
        want_triples: bool,
        mut sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        let size = out.size();
        let channels = self.color_channels() as usize;
        let mut all = bricks::bricks_of_box(out);
        bricks::normalize(&mut all);
        // The slab being filled: its z range in the box, its voxels and triples.
        let mut pending: Option<(std::ops::Range<i32>, Volume, Vec<u32>)> = None;
        let mut flush =
            |pending: &mut Option<(std::ops::Range<i32>, Volume, Vec<u32>)>| match pending.take() {
                Some((z, volume, triples)) => sink(Slab {
                    z0: (z.start - out.lo[2]) as u32,
                    volume: &volume,
                    triples: &triples,
                }),
                None => Ok(()),
            };
        // Groups come z-major (see `groups`): a group starting above the slab begins the next.
        self.for_each_group(
            &all,
            Some(out),
            periodic,
            progress,
            want_triples,
            |group, colors, group_triples| {
                let bz = group.iter().map(|b| b[2]).fold(i32::MAX, i32::min);
                let bz_end = group.iter().map(|b| b[2]).fold(i32::MIN, i32::max) + 1;
                let z =
                    (bz * bricks::BRICK).max(out.lo[2])..(bz_end * bricks::BRICK).min(out.hi[2]);
                if pending
                    .as_ref()
                    .is_some_and(|(range, ..)| z.start >= range.end)
                {
                    flush(&mut pending)?;
                }
                let (range, slab, slab_triples) = pending.get_or_insert_with(|| {
                    let depth = (z.end - z.start) as u32;
                    let voxels = size[0] as usize * size[1] as usize * depth as usize;
                    (
                        z.clone(),
                        Volume::new(size[0], size[1], depth, channels as u32),
                        vec![0; if want_triples { voxels * 3 } else { 0 }],
                    )
                });
                debug_assert!(z.start >= range.start && z.end <= range.end);
                let timer = std::time::Instant::now();
                place_group(
                    group,
                    colors,
                    group_triples,
                    out,
                    range.start,
                    slab,
                    want_triples.then_some(slab_triples),
                );
                tracing::debug!("group placed in its slab in {:.1} ms", ms(timer));
                Ok(())
            },
        )?;
        flush(&mut pending)
    }

    /// Synthesize every voxel of the finest-level bricks `requested` (4^3 voxels each, see
    /// [`bricks`]), computing only what they depend on. Large requests are split into groups of
    /// nearby bricks, each synthesized independently (determinism makes that invisible).
    pub fn synthesize_bricks(
        &mut self,
        requested: &[Brick],
        progress: Progress,
        want_triples: bool,
    ) -> Result<BrickColors> {
        self.synthesize_bricks_of(requested, None, progress, want_triples)
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
        let mut all = requested.to_vec();
        bricks::normalize(&mut all);
        self.for_each_group(&all, None, Periodic::No, progress, false, |group, c, _| {
            // (Groups keep the request's order: BrickColors' lookups need it.)
            debug_assert!(group
                .windows(2)
                .all(|w| (w[0][2], w[0][1], w[0][0]) < (w[1][2], w[1][1], w[1][0])));
            sink(BrickColors {
                bricks: group.to_vec(),
                grid: BrickColors::lookup(group),
                colors: c.to_vec(),
                triples: Vec::new(),
            })
        })
    }

    /// [`Self::synthesize_bricks`]; `exact`: the request is the voxels of this box (see
    /// [`Self::for_each_group`]; only they are meaningful in the result).
    fn synthesize_bricks_of(
        &mut self,
        requested: &[Brick],
        exact: Option<Box3>,
        progress: Progress,
        want_triples: bool,
    ) -> Result<BrickColors> {
        let mut all = requested.to_vec();
        bricks::normalize(&mut all);
        let grid = BrickColors::lookup(&all);
        let mut colors = vec![0u32; all.len() * 64];
        let mut triples = vec![0u32; if want_triples { all.len() * 64 * 3 } else { 0 }];
        self.for_each_group(
            &all,
            exact,
            Periodic::No,
            progress,
            want_triples,
            |group, c, t| {
                for (j, b) in group.iter().enumerate() {
                    let slot =
                        BrickColors::slot_in(&all, grid.as_ref(), *b).expect("requested brick");
                    colors[slot * 64..(slot + 1) * 64].copy_from_slice(&c[j * 64..(j + 1) * 64]);
                    if want_triples {
                        triples[slot * 192..(slot + 1) * 192]
                            .copy_from_slice(&t[j * 192..(j + 1) * 192]);
                    }
                }
                Ok(())
            },
        )?;
        Ok(BrickColors {
            bricks: all,
            grid,
            colors,
            triples,
        })
    }

    /// Synthesize the sorted bricks `all` group by group, handing each group's bricks, their
    /// colours (64 per brick, x fastest) and, when asked, their triples to `sink`.
    ///
    /// `exact`: the request is exactly the voxels of this box (`all` the bricks covering it):
    /// each group is then planned voxel-exactly at the finest level
    /// ([`bricks::plan_voxel_box`]), and only its voxels inside the box are meaningful.
    /// `periodic`: [`Periodic::No`], or [`Periodic::Unwrapped`] for a tileable solid's groups.
    fn for_each_group(
        &mut self,
        all: &[Brick],
        exact: Option<Box3>,
        periodic: Periodic,
        progress: Progress,
        want_triples: bool,
        mut sink: impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        let mut groups = self.groups(all, 0);
        self.next_plan = None;
        self.deferring = false;
        self.overlapped_hand_overs = 0;
        if groups.len() > 1 && matches!(periodic, Periodic::No) {
            let exact = group_part(exact, all);
            if let Some(levels) = self.planned_one_group(all, exact) {
                groups = vec![all.to_vec()];
                self.next_plan = Some((all.to_vec(), exact, levels));
            }
        }
        let mut stats = SynthStats {
            voxels_per_level: vec![0; ANALYSED_LEVELS],
            peak_state_bytes: 0,
            groups: groups.len(),
        };
        let exact_of_all = exact;
        // The cache replaces the infinite solid's coarse levels already.
        let cached = self.params.coarse_cache.is_some() && matches!(periodic, Periodic::No);
        let shared = self.shared_coarse.unwrap_or(self.shared_coarse_default);
        if groups.len() > 1 && shared && !cached {
            self.for_each_group_shared(
                &groups,
                exact,
                periodic,
                progress,
                want_triples,
                &mut stats,
                sink,
            )?;
            progress("done", 1.0);
            self.last_stats = Some(stats);
            return Ok(());
        }
        // The plans of the next few groups, made together (see `plan_ahead`).
        let mut ahead = std::collections::VecDeque::new();
        self.deferring = self.overlaps_reads(groups.len(), want_triples);
        let mut behind = None;
        for (g, group) in groups.iter().enumerate() {
            let base = g as f32 / groups.len() as f32;
            let scale = 1.0 / groups.len() as f32;
            let exact = group_part(exact, group);
            if groups.len() > 1 {
                if ahead.is_empty() {
                    let first = if cached { ANALYSED_LEVELS - 1 } else { 0 };
                    ahead = self.plan_ahead(&groups[g..], exact_of_all, first);
                }
                let levels = ahead.pop_front().expect("planned ahead");
                self.next_plan = Some((group.clone(), exact, levels));
            }
            let timer = std::time::Instant::now();
            let (c, t) = self.synthesize_group_of(
                group,
                exact,
                periodic,
                &|m, f| progress(m, base + scale * f),
                want_triples,
                &mut stats,
            )?;
            let done = GroupDone {
                group,
                colors: c,
                triples: t,
                synthesized_ms: ms(timer),
            };
            self.hand_over(done, &mut behind, &mut sink)?;
        }
        if let Some(last) = behind.take() {
            self.hand_over_now(last, &mut sink)?;
        }
        self.deferring = false;
        progress("done", 1.0);
        self.last_stats = Some(stats);
        Ok(())
    }

    /// [`Self::for_each_group`] with shared coarse levels (see
    /// [`Self::set_shared_coarse_levels`]): the parent level of every group's finest level is
    /// synthesized once ([`Self::level_triples`]), then each group uploads its parents and
    /// synthesizes only the finest level.
    #[allow(clippy::too_many_arguments)]
    fn for_each_group_shared(
        &mut self,
        groups: &[Vec<Brick>],
        exact: Option<Box3>,
        periodic: Periodic,
        progress: Progress,
        want_triples: bool,
        stats: &mut SynthStats,
        mut sink: impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        let finest = ANALYSED_LEVELS - 1;
        let passes = self.params.passes.levels();
        let plan_finest = |group: &[Brick]| {
            plan_group(group, group_part(exact, group), &passes[finest..])
                .pop()
                .expect("one level")
        };
        let wanted = parents_of_groups(groups, plan_finest);
        // The coarse levels hold about a seventh of the voxels.
        let coarse_share = 0.15;
        let parents = self.level_triples(
            wanted,
            finest - 1,
            periodic,
            &|m, f| progress(m, coarse_share * f),
            stats,
        )?;
        // (Not in a warm session, whose next request of several groups would build them again.)
        if !self.exec.keeps_buffers() {
            self.exec.release_coarse_pipelines(finest);
        }
        let mut ahead = std::collections::VecDeque::new();
        self.deferring = self.overlaps_reads(groups.len(), want_triples);
        let mut behind = None;
        for (g, group) in groups.iter().enumerate() {
            let base = coarse_share + (1.0 - coarse_share) * g as f32 / groups.len() as f32;
            let scale = (1.0 - coarse_share) / groups.len() as f32;
            if ahead.is_empty() {
                ahead = self.plan_ahead(&groups[g..], exact, finest);
            }
            let level = ahead
                .pop_front()
                .and_then(|mut levels| levels.pop())
                .expect("planned ahead");
            let parent = parent_level(&level);
            let start = self
                .exec
                .upload_state(parents.state_words(&parent, self.packs[finest - 1].pixel_words))?;
            let timer = std::time::Instant::now();
            let r = self.synthesize_group(
                vec![parent, level],
                finest - 1,
                FirstLevel::Given(start),
                group,
                periodic,
                &|m, f| progress(m, base + scale * f),
                want_triples,
                stats,
            )?;
            let done = GroupDone {
                group,
                colors: r.colors,
                triples: r.triples,
                synthesized_ms: ms(timer),
            };
            self.hand_over(done, &mut behind, &mut sink)?;
        }
        if let Some(last) = behind.take() {
            self.hand_over_now(last, &mut sink)?;
        }
        self.deferring = false;
        Ok(())
    }

    /// Whether a request of `groups` groups reads each group's colours back while the next one
    /// runs: on a GPU of its own memory (not when profiling, whose kernels each wait). Its
    /// host work (the next group's plan, brick indices and recording, then the caller's use of
    /// the colours) then overlaps the GPU's work instead of alternating with it; a group's colours and states are held a
    /// group longer, which a GPU sharing the host's memory (lavapipe: the bunny's 200 MB
    /// target) is better without.
    fn overlaps_reads(&self, groups: usize, want_triples: bool) -> bool {
        // (With triples, a group's colours are read at once: holding it back gains nothing.)
        self.overlap_reads && groups > 1 && self.times.is_none() && !want_triples
    }

    /// A group is synthesized: hand it to `sink` now, or, while reads overlap, hand over the
    /// group before it (whose colours have come back as this one ran) and keep it `behind`.
    fn hand_over<'g>(
        &mut self,
        done: GroupDone<'g>,
        behind: &mut Option<GroupDone<'g>>,
        sink: &mut impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        if !self.deferring {
            return self.hand_over_now(done, sink);
        }
        match behind.replace(done) {
            Some(previous) => {
                self.overlapped_hand_overs += 1;
                self.hand_over_now(previous, sink)
            }
            None => Ok(()),
        }
    }

    /// Wait for a group's colours if they are still coming and hand them to `sink`.
    fn hand_over_now(
        &mut self,
        done: GroupDone,
        sink: &mut impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        let timer = std::time::Instant::now();
        let colors = self.exec.finish_colors(done.colors)?;
        let waited = ms(timer);
        let timer = std::time::Instant::now();
        sink(done.group, &colors, &done.triples)?;
        tracing::debug!(
            "group of {} bricks: synthesized in {:.1} ms, its colours waited for {waited:.1} ms, \
             taken by the caller in {:.1} ms",
            done.group.len(),
            done.synthesized_ms,
            ms(timer)
        );
        self.return_free_heap();
        Ok(())
    }

    /// Between a request's groups: hand the heap's free pages back
    /// ([`crate::util::memory::return_free_heap`]), except in a warm session, whose next
    /// request would fault them in again (a warm 256^2 cut on the CPU backend: 81 -> 87 ms when
    /// trimmed after every group).
    fn return_free_heap(&self) {
        if !self.exec.keeps_buffers() {
            crate::util::memory::return_free_heap();
        }
    }

    /// The triples of the level-`top` bricks `wanted` (sorted), synthesized group by group
    /// through levels l_start..=`top`. With several groups above l_start, their parent level
    /// is itself synthesized once for all of them (recursively), so no group recomputes the
    /// coarser levels' padding of its neighbours.
    fn level_triples(
        &mut self,
        wanted: Vec<Brick>,
        top: usize,
        periodic: Periodic,
        progress: Progress,
        stats: &mut SynthStats,
    ) -> Result<LevelTriples> {
        let groups = self.groups(&wanted, ANALYSED_LEVELS - 1 - top);
        let passes = self.params.passes.levels();
        let plan_top = |group: &[Brick]| {
            bricks::plan_sparse(group, &passes[top..=top])
                .pop()
                .expect("one level")
        };
        let parents = if top > 0 && groups.len() > 1 {
            let below = parents_of_groups(&groups, plan_top);
            Some(self.level_triples(
                below,
                top - 1,
                periodic,
                &|m, f| progress(m, 0.15 * f),
                stats,
            )?)
        } else {
            None
        };
        let mut out = LevelTriples::new(wanted, self.packs[top].width, self.packs[top].height);
        let stride = 3 + self.packs[top].pixel_words as usize;
        for (g, group) in groups.iter().enumerate() {
            let f = g as f32 / groups.len() as f32;
            let group_progress = |m: &str, _: f32| progress(m, 0.15 + 0.85 * f);
            // From l_start, or from the shared parent level.
            let (levels, first_pack, start) = match &parents {
                None => (
                    bricks::plan_sparse(group, &passes[..=top]),
                    0,
                    FirstLevel::Init,
                ),
                Some(parents) => {
                    let level = plan_top(group);
                    let parent = parent_level(&level);
                    let timer = std::time::Instant::now();
                    let words = parents.state_words(&parent, self.packs[top - 1].pixel_words);
                    let start = self.exec.upload_state(words)?;
                    tracing::debug!(
                        "level {top}: shared parents uploaded in {:.1} ms",
                        ms(timer)
                    );
                    (vec![parent, level], top - 1, FirstLevel::Given(start))
                }
            };
            let grid = levels.last().expect("levels").grid.clone();
            let state = self
                .synthesize_group(
                    levels,
                    first_pack,
                    start,
                    &[],
                    periodic,
                    &group_progress,
                    false,
                    stats,
                )?
                .state;
            let timer = std::time::Instant::now();
            out.set_bricks(group, &grid, &state, stride)?;
            tracing::debug!("level {top}: group's triples stored in {:.1} ms", ms(timer));
        }
        Ok(out)
    }

    /// The packed colours of arbitrary voxels (any order, repeats allowed): only the bricks
    /// holding them are synthesized.
    pub fn sample(&mut self, voxels: &[[i32; 3]], progress: Progress) -> Result<Vec<u32>> {
        let timer = std::time::Instant::now();
        // An axis-aligned cut at unit spacing asks for a box of voxels (one voxel thick):
        // planned voxel-exactly, its dependency padding surrounds one layer, not four. Its
        // bricks are the box's (sorted as they come), not found voxel by voxel and sorted.
        let exact = voxel_box(voxels);
        let wanted = match exact {
            Some(b) => bricks::bricks_of_box(b),
            None => bricks::bricks_of_voxels(voxels),
        };
        tracing::debug!("sample: bricks of the voxels in {:.1} ms", ms(timer));
        let result = self.synthesize_bricks_of(&wanted, exact, progress, false)?;
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

    /// A warm session (`CutSession`): the GPU keeps its state and colour buffers from one
    /// request for the next ones of the same sizes (no allocation and zeroing per request),
    /// and neither backend hands free heap back between groups (the next request would fault
    /// the pages in again).
    pub fn keep_buffers(&mut self) {
        self.exec.keep_buffers();
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

    /// Tests: whether a request of several groups reads each group's colours back while the
    /// next one runs (on by default on a GPU whose memory is its own only). The same results
    /// either way.
    #[doc(hidden)]
    pub fn set_overlapped_reads(&mut self, on: bool) {
        self.overlap_reads = on && matches!(self.exec, exec::Executor::Gpu(_));
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

    /// Time every kernel (waiting for the device after each, so totals grow slightly).
    pub fn enable_profiling(&mut self) {
        self.times = Some(Default::default());
    }

    /// Kernel name -> (total time, calls), when profiling.
    pub fn kernel_times(&self) -> Option<&exec::KernelTimes> {
        self.times.as_ref()
    }

    /// Cap the group edge in voxels, rounded down to whole bricks (at least one); the result is
    /// the same whatever the grouping (tests prove it). Capped groups bound the working memory
    /// (the shared coarse levels' groups too, see [`Self::set_shared_coarse_levels`]).
    pub fn set_max_chunk_side(&mut self, side: u32) {
        self.max_chunk_side = Some(side.max(1));
    }

    /// Hold each level's state of a group within `bytes` (or the backend's buffer limit, when
    /// lower), which is what sizes the groups: for tests of the grouping on small requests.
    pub fn set_state_limit(&mut self, bytes: u64) {
        self.state_limit = Some(bytes);
    }

    /// The most bytes one level's state of a group may take.
    fn state_limit(&self) -> u64 {
        self.exec
            .max_state_bytes()
            .min(self.state_limit.unwrap_or(u64::MAX))
    }

    /// When a request takes several groups: whether the levels above the finest are
    /// synthesized once for all of them (level by level, each in groups of its own if it too
    /// is large) and their triples held on the host until every group has read its parents,
    /// instead of once per group with the group's padding. Shared levels save the coarse
    /// levels' repeated padding (a quarter of the time of a 256^3 box in eight groups on
    /// lavapipe) for about 0.9 bytes of host memory per finest-level voxel (1.7 for exemplars
    /// over 512 pixels), and each group's
    /// parent state built on the host. A shared level is itself split into groups of the
    /// finest groups' extent, so [`Self::set_max_chunk_side`] bounds its working memory too.
    /// Default: shared on the CPU backend and on GPUs that share the host's memory (since
    /// session 26 also when the groups are capped: a 256^3 box in 64-voxel groups on the CPU
    /// backend took 20.7 s with each group's own coarse levels, 15.3 s shared, for 6 MiB
    /// more); not shared on a GPU with its own memory, where reading the shared levels back
    /// and building each group's parents on the host cost more than the GPU's recomputed
    /// padding (session 32 on an H200: 512^3 in eight groups 1.71-1.74 s shared, 1.13-1.22 s
    /// not, 750 against 597 MiB; the bunny at 1024 in 16 groups 2.0 against 1.04-1.11 s).
    /// The result is the same either way.
    pub fn set_shared_coarse_levels(&mut self, shared: bool) {
        self.shared_coarse = Some(shared);
    }

    /// Bytes of a state holding one period `n`^3 of pack `pack`'s level.
    fn periodic_state_bytes(&self, n: u32, pack: usize) -> u64 {
        (n as u64).pow(3) * (3 + self.packs[pack].pixel_words as u64) * 4
    }

    /// Split sorted bricks into groups (boxes of bricks) whose working set fits the backend
    /// ([`grouping::group_sides`]), each at most [`group_cap`] voxels on a side.
    /// `coarser_by`: how many levels above the finest the bricks are (a shared coarse level's).
    fn groups(&self, all: &[Brick], coarser_by: usize) -> Vec<Vec<Brick>> {
        let whole_box = bricks::bounds(all).is_some_and(|(lo, hi)| {
            let bricks: usize = (0..3).map(|i| (hi[i] - lo[i] + 1) as usize).product();
            bricks == all.len()
        });
        let cap = group_cap(self.max_chunk_side, coarser_by, whole_box);
        // The levels up to the bricks' own, with this schedule and these strides.
        let levels = ANALYSED_LEVELS - coarser_by;
        let passes = &self.params.passes.levels()[..levels];
        let strides: Vec<u64> = self.packs[..levels]
            .iter()
            .map(|p| (3 + p.pixel_words as u64) * 4)
            .collect();
        let bound = |extent| grouping::planned_state_bytes(extent, passes, &strides);
        let sides = grouping::group_sides(all, cap, coarser_by > 0, self.state_limit(), bound);
        grouping::cubes(all, sides)
    }

    /// The plan of the whole request `all` as one group, when its sparse state fits the
    /// backend's buffers although the cubes' bounding boxes do not ([`Self::groups`] sizes
    /// groups by their dense padded bounding boxes): an oblique cut or a thin tilted shell
    /// fills little of its box. Only within one cube of the group cap (512 voxels or
    /// `--max-group`), so a user's cap still holds; None otherwise. One group computes no
    /// padding at the seams between groups (the oblique 256^2 cut on lavapipe: 2.35 M finest
    /// voxels instead of 2.64 M in five groups).
    fn planned_one_group(&self, all: &[Brick], exact: Option<Box3>) -> Option<Vec<SparseLevel>> {
        let cap = self.max_chunk_side.unwrap_or(512).min(512);
        if !grouping::is_one_cube(all, [cap; 3]) {
            return None;
        }
        let passes = self.params.passes.levels();
        // The levels a group synthesizes: with the cache, the finest only.
        let first = if self.params.coarse_cache.is_some() {
            ANALYSED_LEVELS - 1
        } else {
            0
        };
        let timer = std::time::Instant::now();
        let levels = plan_group(all, exact, &passes[first..]);
        tracing::debug!(
            "planned {} bricks as one group in {:.1} ms",
            all.len(),
            ms(timer)
        );
        let largest = levels
            .iter()
            .zip(&self.packs[first..])
            .map(|(level, pack)| level.voxels() * (3 + pack.pixel_words as u64) * 4)
            .max()
            .unwrap_or(0);
        (largest <= self.state_limit()).then_some(levels)
    }

    /// The plans of the first of `groups` (parts of the request whose exact box is `exact`)
    /// and of as many following ones as there are threads, within [`PLAN_AHEAD_BRICKS`]
    /// requested bricks, made in parallel: each group's plan is mostly serial work (its
    /// dilation and presence tables), and a surface's hundreds of small groups spent half
    /// their time planning one after the other on an H100 (BENCHMARKS.md, session 30).
    /// The plans are of the levels from `first` (the finest only where a group reads the
    /// coarse cache or shared coarse levels).
    fn plan_ahead(
        &self,
        groups: &[Vec<Brick>],
        exact: Option<Box3>,
        first: usize,
    ) -> std::collections::VecDeque<Vec<SparseLevel>> {
        let passes = &self.params.passes.levels()[first..];
        // Plans of every level are several times larger (the 2048 bunny's shared-level plans
        // held 0.65 GB more at 16 at once, `parents_of_groups`): at most 4 of those.
        let most = match first {
            0 => PLANS_AT_ONCE,
            _ => rayon::current_num_threads().max(1),
        };
        let mut bricks = 0;
        let window = groups
            .iter()
            .take(most)
            .take_while(|g| {
                bricks += g.len();
                bricks == g.len() || bricks <= PLAN_AHEAD_BRICKS
            })
            .count();
        let timer = std::time::Instant::now();
        let plans = groups[..window]
            .par_iter()
            .map(|g| plan_group(g, group_part(exact, g), passes))
            .collect();
        tracing::debug!("planned {window} groups ahead in {:.1} ms", ms(timer));
        plans
    }

    /// The plan of `group` through the levels from `first`: the one made by
    /// [`Self::planned_one_group`] when it is for this group, else a new one.
    fn plan_of(&mut self, group: &[Brick], exact: Option<Box3>, first: usize) -> Vec<SparseLevel> {
        if let Some((planned, planned_exact, levels)) = self.next_plan.take() {
            if planned == group && planned_exact == exact {
                return levels;
            }
        }
        let timer = std::time::Instant::now();
        let levels = plan_group(group, exact, &self.params.passes.levels()[first..]);
        tracing::debug!("planned {} bricks in {:.1} ms", group.len(), ms(timer));
        levels
    }

    /// A tileable solid: the `n`^3 volume of a solid periodic with period `n` along each axis
    /// (every level periodic with its own size), so copies of it tile space seamlessly. Its own
    /// deterministic definition (same analysis, seed, jitter), not a region of the infinite
    /// solid. `n` must be a multiple of 32 ([`check_tileable_size`]). Held whole: see
    /// [`Self::synthesize_tileable_slabs`] for large ones.
    pub fn synthesize_tileable(
        &mut self,
        n: u32,
        progress: Progress,
        want_triples: bool,
    ) -> Result<(Volume, Vec<u32>)> {
        let mut whole = SlabsJoined::new([n; 3], self.color_channels(), want_triples);
        self.synthesize_tileable_slabs(n, progress, want_triples, |slab| whole.push(slab))?;
        Ok(whole.finish())
    }

    /// [`Self::synthesize_tileable`], handed to `sink` in slabs along z like
    /// [`Self::synthesize_slabs`]. When the periodic state fits one buffer of the backend (and
    /// the group size, [`Self::set_max_chunk_side`]) it is synthesized in one piece, its reads
    /// wrapping around the period; otherwise as boxes of the periodic solid, group by group,
    /// each with its dependency padding (see [`Periodic::Unwrapped`]): the same voxels either
    /// way (tested), so 256^3 and larger tileable solids work within lavapipe's 128 MiB
    /// buffers. The coarse-level cache does not apply (it belongs to the infinite solid).
    pub fn synthesize_tileable_slabs(
        &mut self,
        n: u32,
        progress: Progress,
        want_triples: bool,
        mut sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        check_tileable_size(n)?;
        let periods = periods_below(n, ANALYSED_LEVELS);
        // One piece stores each level's period in whole bricks, which wrap (every period is
        // whole bricks: `check_tileable_size`); too large a period goes in groups.
        let one_piece = self.periodic_state_bytes(n, ANALYSED_LEVELS - 1) <= self.state_limit()
            && self.max_chunk_side.is_none_or(|side| side >= n);
        if !one_piece {
            if self.usage.is_some() {
                // Groups store padding voxels too, which would be counted.
                return Err(Error::Internal(
                    "usage counting needs a tileable solid synthesized in one piece".into(),
                ));
            }
            let whole = Box3::new([0; 3], [n as i32; 3]);
            let periodic = Periodic::Unwrapped(&periods);
            return self.synthesize_slabs_of(whole, periodic, progress, want_triples, sink);
        }
        let levels = bricks::plan_periodic(n, &self.params.passes.levels());
        let output = levels.last().unwrap().bricks.clone();
        let mut stats = SynthStats {
            voxels_per_level: vec![0; ANALYSED_LEVELS],
            peak_state_bytes: 0,
            groups: 1,
        };
        self.deferring = false;
        let GroupResult {
            colors, triples, ..
        } = self.synthesize_group(
            levels,
            0,
            FirstLevel::Init,
            &output,
            Periodic::Wrapped(&periods),
            progress,
            want_triples,
            &mut stats,
        )?;
        let colors = self.exec.finish_colors(colors)?;
        self.last_stats = Some(stats);
        let grid = BrickGrid::new(&output);
        let channels = self.color_channels() as usize;
        let mut volume = Volume::new(n, n, n, channels as u32);
        let mut out_triples = Vec::with_capacity(if want_triples {
            n as usize * n as usize * n as usize * 3
        } else {
            0
        });
        for z in 0..n as i32 {
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let i = grid.voxel_index([x, y, z]).expect("every brick is output");
                    volume
                        .at_mut(x as u32, y as u32, z as u32)
                        .copy_from_slice(&colors[i].to_le_bytes()[..channels]);
                    if want_triples {
                        out_triples.extend_from_slice(&triples[i * 3..i * 3 + 3]);
                    }
                }
            }
        }
        progress("done", 1.0);
        sink(Slab {
            z0: 0,
            volume: &volume,
            triples: &out_triples,
        })
    }

    /// Colours (64 per brick, `group` order) and, when asked, triples of one group of bricks.
    /// `exact`: see [`Self::for_each_group`].
    fn synthesize_group_of(
        &mut self,
        group: &[Brick],
        exact: Option<Box3>,
        periodic: Periodic,
        progress: Progress,
        want_triples: bool,
        stats: &mut SynthStats,
    ) -> Result<(exec::Colors, Vec<u32>)> {
        // The cache builds the infinite solid's levels; a tileable solid has its own.
        if self.params.coarse_cache.is_some() && matches!(periodic, Periodic::No) {
            return self.synthesize_group_cached(group, exact, progress, want_triples, stats);
        }
        let levels = self.plan_of(group, exact, 0);
        self.synthesize_group(
            levels,
            0,
            FirstLevel::Init,
            group,
            periodic,
            progress,
            want_triples,
            stats,
        )
        .map(|r| (r.colors, r.triples))
    }

    /// Level L-1 of the coarse cache: a tileable solid of period `coarse_cache / 2` there,
    /// synthesized through levels l_start..L-1 (once: the caller keeps it), its triples x
    /// fastest.
    fn build_coarse_cache(&mut self) -> Result<Vec<u32>> {
        let n = self.params.coarse_cache.expect("cache requested") / 2;
        let levels_above = ANALYSED_LEVELS - 1;
        // Built in one piece (its reads wrap around the period): one buffer must hold it.
        let state = self.periodic_state_bytes(n, levels_above - 1);
        if state > self.state_limit() {
            return Err(Error::invalid(
                format!("--coarse-cache {}", n * 2),
                format!(
                    "its periodic state ({} MiB) exceeds this backend's {} MiB per buffer: \
                     use a smaller period",
                    state >> 20,
                    self.state_limit() >> 20
                ),
            ));
        }
        let levels = bricks::plan_periodic(n, &self.params.passes.levels()[..levels_above]);
        let periods = periods_below(n, levels_above);
        let top = levels.last().unwrap().clone();
        let mut stats = SynthStats {
            voxels_per_level: vec![0; ANALYSED_LEVELS],
            ..Default::default()
        };
        let r = self.synthesize_group(
            levels,
            0,
            FirstLevel::Init,
            &[],
            Periodic::Wrapped(&periods),
            &|_, _| {},
            false,
            &mut stats,
        )?;
        let stride = 3 + self.packs[levels_above - 1].pixel_words as usize;
        let mut triples = Vec::with_capacity((n as usize).pow(3) * 3);
        for z in 0..n as i32 {
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let i = top.grid.voxel_index([x, y, z]).expect("whole period") * stride;
                    triples.extend_from_slice(&r.state[i..i + 3]);
                }
            }
        }
        drop(r);
        // Requests read the coarse levels from the cache from now on.
        self.exec.release_coarse_levels(levels_above);
        Ok(triples)
    }

    /// One group through the coarse cache: level L-1 read from the cache (warped, periodic),
    /// then only the finest level synthesized.
    fn synthesize_group_cached(
        &mut self,
        group: &[Brick],
        exact: Option<Box3>,
        progress: Progress,
        want_triples: bool,
        stats: &mut SynthStats,
    ) -> Result<(exec::Colors, Vec<u32>)> {
        let finest = self
            .plan_of(group, exact, ANALYSED_LEVELS - 1)
            .pop()
            .unwrap();
        let parent = parent_level(&finest);
        if self.cache_buf.is_none() {
            let triples = self.build_coarse_cache()?;
            self.cache_buf = Some(self.exec.upload_index(triples));
        }
        self.synthesize_group(
            vec![parent, finest],
            ANALYSED_LEVELS - 2,
            FirstLevel::Cached,
            group,
            Periodic::No,
            progress,
            want_triples,
            stats,
        )
        .map(|r| (r.colors, r.triples))
    }
}

/// A synthesized group of a request on its way to the caller ([`Synthesizer::hand_over`]).
struct GroupDone<'g> {
    group: &'g [Brick],
    colors: exec::Colors,
    triples: Vec<u32>,
    synthesized_ms: f64,
}

/// Copy a group's colours (64 per brick, `group` order) and, when given, triples into the slab
/// of box `out` whose first z slice is `slab_z0`: the parts of the bricks inside the box. Brick
/// layers (4 z slices) are disjoint parts of the slab, filled in parallel.
fn place_group(
    group: &[Brick],
    colors: &[u32],
    group_triples: &[u32],
    out: Box3,
    slab_z0: i32,
    slab: &mut Volume,
    slab_triples: Option<&mut Vec<u32>>,
) {
    let channels = slab.channels as usize;
    let (sx, sy) = (slab.nx as usize, slab.ny as usize);
    let slice = sx * sy;
    let slab_z1 = slab_z0 + slab.nz as i32;
    // The group's bricks by layer: (brick z, index in the group), z ascending.
    let mut order: Vec<(i32, usize)> = group.iter().enumerate().map(|(j, b)| (b[2], j)).collect();
    order.sort_unstable();
    // Each layer's slices within the slab, then its part of the colours and triples.
    let mut layers = Vec::new();
    let (mut data, mut triples) = (
        &mut slab.data[..],
        slab_triples.map_or(&mut [][..], |t| &mut t[..]),
    );
    let mut consumed = slab_z0;
    for run in order.chunk_by(|a, b| a.0 == b.0) {
        let bz = run[0].0;
        let z0 = (bz * bricks::BRICK).max(out.lo[2]).max(slab_z0);
        let z1 = ((bz + 1) * bricks::BRICK).min(out.hi[2]).min(slab_z1);
        if z0 >= z1 {
            continue;
        }
        let skip = (z0 - consumed) as usize * slice;
        let take = (z1 - z0) as usize * slice;
        let rest = std::mem::take(&mut data);
        let (layer, rest) = rest[skip * channels..].split_at_mut(take * channels);
        data = rest;
        let (layer_triples, rest_triples) = if triples.is_empty() {
            (&mut [][..], &mut [][..])
        } else {
            let rest = std::mem::take(&mut triples);
            rest[skip * 3..].split_at_mut(take * 3)
        };
        triples = rest_triples;
        consumed = z1;
        layers.push((z0, z1, run, layer, layer_triples));
    }
    layers
        .into_par_iter()
        .for_each(|(z0, z1, run, layer, layer_triples)| {
            let with_triples = !layer_triples.is_empty();
            for &(_, j) in run {
                // The brick clipped to the box and to the layer: rows of consecutive voxels
                // along x, copied whole (a brick inside the box is 16 rows of 4).
                let lo = group[j].map(|v| v * bricks::BRICK);
                let from = [lo[0].max(out.lo[0]), lo[1].max(out.lo[1]), lo[2].max(z0)];
                let end = [out.hi[0], out.hi[1], z1];
                let to = [0, 1, 2].map(|i| (lo[i] + bricks::BRICK).min(end[i]));
                let run_len = (to[0] - from[0]).max(0) as usize;
                for z in from[2]..to[2] {
                    for y in from[1]..to[1] {
                        let first = ((z - z0) as usize * sy + (y - out.lo[1]) as usize) * sx
                            + (from[0] - out.lo[0]) as usize;
                        let src = j * 64
                            + ((z - lo[2]) * 16 + (y - lo[1]) * 4 + (from[0] - lo[0])) as usize;
                        let dst = &mut layer[first * channels..(first + run_len) * channels];
                        write_colors(dst, &colors[src..src + run_len], channels);
                        if with_triples {
                            layer_triples[first * 3..(first + run_len) * 3]
                                .copy_from_slice(&group_triples[src * 3..(src + run_len) * 3]);
                        }
                    }
                }
            }
        });
}

/// Packed colours (little-endian bytes) written as `channels` bytes each. The common channel
/// counts get fixed-size copies: with the count only known at run time each voxel's copy was a
/// `memcpy` call (place_group was 12% of a warm 256^2 cut's main-thread CPU, session 37).
fn write_colors(dst: &mut [u8], colors: &[u32], channels: usize) {
    fn each<const N: usize>(dst: &mut [u8], colors: &[u32]) {
        for (pixel, color) in dst.chunks_exact_mut(N).zip(colors) {
            let bytes: [u8; 4] = color.to_le_bytes();
            pixel.copy_from_slice(&bytes[..N]);
        }
    }
    match channels {
        1 => each::<1>(dst, colors),
        2 => each::<2>(dst, colors),
        3 => each::<3>(dst, colors),
        4 => each::<4>(dst, colors),
        _ => unreachable!("{channels} colour channels"),
    }
}

/// The plan of a group of bricks: voxel-exact at the finest level when the request is the
/// box `exact` (see [`Synthesizer::for_each_group`]).
fn plan_group(group: &[Brick], exact: Option<Box3>, passes: &[usize]) -> Vec<SparseLevel> {
    match exact {
        Some(b) => bricks::plan_voxel_box(b, passes),
        None => bricks::plan_sparse(group, passes),
    }
}

/// The part of the exact box `exact` (see [`Synthesizer::for_each_group`]) that `group`'s
/// bricks cover.
fn group_part(exact: Option<Box3>, group: &[Brick]) -> Option<Box3> {
    exact.map(|b| {
        let (lo, hi) = bricks::bounds(group).expect("groups hold bricks");
        Box3::new(
            [0, 1, 2].map(|i| b.lo[i].max(lo[i] * bricks::BRICK)),
            [0, 1, 2].map(|i| b.hi[i].min((hi[i] + 1) * bricks::BRICK)),
        )
    })
}

/// The parent bricks that the levels `plan` gives `groups` read, all groups together (sorted
/// once per group and once at the end, not once per group over the growing whole).
fn parents_of_groups(
    groups: &[Vec<Brick>],
    plan: impl Fn(&[Brick]) -> SparseLevel + Sync,
) -> Vec<Brick> {
    // A few groups planned at a time, in parallel (a plan is a pure function of its group; the
    // union is normalized, so the order they finish in does not matter). Not all at once: a
    // plan can take tens of MB, and the bunny at 2048 on 16 cores held 0.65 GB more so.
    let mut all: Vec<Brick> = Vec::new();
    for some in groups.chunks(PLANS_AT_ONCE) {
        let parents: Vec<Vec<Brick>> = some
            .par_iter()
            .map(|group| parent_level(&plan(group)).bricks)
            .collect();
        all.extend(parents.into_iter().flatten());
    }
    bricks::normalize(&mut all);
    all
}

/// The parent level that `level`'s upsampling reads, as a level given whole (no corrections):
/// the parents of its stored bricks.
fn parent_level(level: &SparseLevel) -> SparseLevel {
    let mut parents: Vec<Brick> = level.bricks.iter().map(|b| b.map(|v| v >> 1)).collect();
    bricks::normalize(&mut parents);
    SparseLevel {
        grid: BrickGrid::new(&parents),
        deliver: parents.clone(),
        bricks: parents,
        subpasses: Vec::new(),
    }
}

/// The box `voxels` fill exactly (each of its voxels once, in any order), if they do.
fn voxel_box(voxels: &[[i32; 3]]) -> Option<Box3> {
    let (lo, hi) = bricks::bounds(voxels)?;
    let b = Box3::new(lo, hi.map(|v| v.saturating_add(1)));
    if b.voxels() != voxels.len() as u64 {
        return None;
    }
    // (Outside only at the edge of i32, where the box saturated.)
    if !voxels.iter().all(|p| b.contains(*p)) {
        return None;
    }
    // A z cut lists its box in storage order: no voxel can repeat then.
    if voxels.iter().enumerate().all(|(i, p)| b.index(*p) == i) {
        return Some(b);
    }
    let mut seen = vec![0u64; voxels.len().div_ceil(64)];
    for p in voxels {
        let i = b.index(*p);
        if seen[i / 64] & (1 << (i % 64)) != 0 {
            return None;
        }
        seen[i / 64] |= 1 << (i % 64);
    }
    Some(b)
}

#[cfg(test)]
mod voxel_box_tests {
    use super::*;

    #[test]
    fn voxel_box_recognizes_exactly_the_boxes() {
        let mut slice: Vec<[i32; 3]> = (0..6)
            .flat_map(|y| (0..5).map(move |x| [x - 2, y, 7]))
            .collect();
        slice.reverse();
        assert_eq!(voxel_box(&slice), Some(Box3::new([-2, 0, 7], [3, 6, 8])));
        // A repeat in place of a voxel: as many voxels as the box, not the box.
        let mut repeated = slice.clone();
        repeated[3] = repeated[4];
        assert_eq!(voxel_box(&repeated), None);
        assert_eq!(voxel_box(&slice[1..]), None);
        // In storage order (x fastest), as a z cut lists them, and with a repeat there.
        let mut ordered = slice.clone();
        ordered.reverse();
        assert_eq!(voxel_box(&ordered), Some(Box3::new([-2, 0, 7], [3, 6, 8])));
        ordered[3] = ordered[4];
        assert_eq!(voxel_box(&ordered), None);
        assert_eq!(voxel_box(&[]), None);
        assert_eq!(voxel_box(&[[i32::MAX, 0, 0]]), None);
    }
}

/// Milliseconds since `timer` started (for debug logs).
fn ms(timer: std::time::Instant) -> f64 {
    timer.elapsed().as_secs_f64() * 1e3
}

/// Threads per row of the 2D dispatch grid for `threads` threads (see `gpu::context`).
fn stride_for(threads: u64) -> u32 {
    crate::gpu::context::dispatch_grid(threads as u32).2
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

/// The colours (and, when asked, triples) of a set of finest-level bricks.
pub struct BrickColors {
    /// The bricks, sorted as [`bricks::normalize`] sorts them (z, then y, then x).
    pub bricks: Vec<Brick>,
    /// A dense brick -> position table when the bricks fill their bounding box well enough (a
    /// box); `None` for a sparse request (a surface's shell), whose bounding box would cost more
    /// than the bricks: positions are then found by binary search.
    pub grid: Option<BrickGrid>,
    /// 64 packed colours per brick (x fastest inside the brick).
    pub colors: Vec<u32>,
    /// 3 packed coordinates per voxel, when asked.
    pub triples: Vec<u32>,
}

impl BrickColors {
    /// The dense table for `sorted` bricks, when it holds at most 8 cells per brick.
    fn lookup(sorted: &[Brick]) -> Option<BrickGrid> {
        let (lo, hi) = bricks::bounds(sorted).unwrap_or_default();
        let cells: u64 = (0..3).map(|i| (hi[i] - lo[i] + 1) as u64).product();
        (cells <= 8 * sorted.len().max(1) as u64).then(|| BrickGrid::new(sorted))
    }

    /// Position of brick `b` in `sorted`, through `grid` when there is one.
    fn slot_in(sorted: &[Brick], grid: Option<&BrickGrid>, b: Brick) -> Option<usize> {
        match grid {
            Some(g) => g.slot(b).map(|s| s as usize),
            None => sorted
                .binary_search_by_key(&(b[2], b[1], b[0]), |x| (x[2], x[1], x[0]))
                .ok(),
        }
    }

    /// Position of voxel `p` in `colors` (None when its brick was not requested).
    pub fn index(&self, p: [i32; 3]) -> Option<usize> {
        Self::slot_in(&self.bricks, self.grid.as_ref(), bricks::brick_of(p))
            .map(|s| s * bricks::BRICK_VOXELS as usize + bricks::local_index(p) as usize)
    }

    /// Packed colour of voxel `p`.
    pub fn color(&self, p: [i32; 3]) -> Option<u32> {
        self.index(p).map(|i| self.colors[i])
    }

    /// [`Self::color`] for voxels visited in a coherent order (an atlas' texels): `last`
    /// remembers the previous voxel's brick and slot, so a run of voxels in one brick costs
    /// one search (without a dense table, a search is a binary search over every brick).
    pub fn color_near(&self, p: [i32; 3], last: &mut Option<(Brick, usize)>) -> Option<u32> {
        let b = bricks::brick_of(p);
        let slot = match *last {
            Some((lb, slot)) if lb == b => slot,
            _ => {
                let slot = Self::slot_in(&self.bricks, self.grid.as_ref(), b)?;
                *last = Some((b, slot));
                slot
            }
        };
        Some(self.colors[slot * bricks::BRICK_VOXELS as usize + bricks::local_index(p) as usize])
    }
}

/// The uniforms of one `correct` sub-pass: the class voxels of the bricks of the list at word
/// `list.0` (`list.1` bricks) of a level's brick index, whose table (offset 0) describes `grid`.
pub fn correct_params(
    pack: &LevelPack,
    grid: &BrickGrid,
    list: (u32, u32),
    class: usize,
    k3d_used: u32,
    border: u32,
    mode: CandidateMode,
) -> CorrectParams {
    let o = &pack.offsets;
    CorrectParams {
        grid_lo_x: grid.lo[0],
        grid_lo_y: grid.lo[1],
        grid_lo_z: grid.lo[2],
        grid_x: grid.dims[0],
        grid_y: grid.dims[1],
        grid_z: grid.dims[2],
        table_offset: 0,
        list_offset: list.0,
        list_count: list.1,
        class_x: (class & 1) as u32,
        class_y: ((class >> 1) & 1) as u32,
        class_z: ((class >> 2) & 1) as u32,
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
        border,
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
        grid_stride: stride_for(list.1 as u64 * 8),
        // The caller points this at the list's voxel masks.
        mask_offset: 0,
        period: 0,
        _r0: 0,
        _r1: 0,
    }
}

/// Padding per side assumed when sizing chunks (the plan's exact padding is at most this).
pub const PADDING_ESTIMATE: u32 = 14;

/// The largest group side, in its own level's voxels, at `coarser_by` levels above the finest,
/// given the finest level's cap `max_chunk_side` (`--max-group`; None: 512); `whole_box`: the
/// level's request is every brick of a box.
///
/// Without a cap, a coarse level's 512 halves per level, so that its groups span the same space
/// as the finest level's. With one, a shared coarse level's groups take the cap in their own
/// voxels (twice the space per level, an eighth of the voxels), and a box's a quarter more, in
/// whole bricks: a box's coarse level is the finest groups' parents with their padding, a
/// little more than the cap whenever the finest groups are (256^3 in groups of 128: 136 voxels
/// at the level above). Cut at exactly the cap, that request took one group of 128 and seven
/// slivers of 8, each recomputing a whole padding: 1.35 times the voxels of one group of 136
/// (lavapipe, 256^3: 20.4 / 21.1 / 19.8 s against 22.5 / 22.5 / 21.6 s, the largest state
/// 107 against 91 MiB; BENCHMARKS.md, session 34). A surface's coarse levels keep the cap:
/// their cubes are not slivers, and larger ones held the bunny's 1024 at 430 MB against 367.
pub fn group_cap(max_chunk_side: Option<u32>, coarser_by: usize, whole_box: bool) -> u32 {
    match max_chunk_side {
        None => 512 >> coarser_by,
        Some(side) if coarser_by == 0 || !whole_box => side.min(512),
        Some(side) => ((side + side / 4) / 4 * 4).max(side).min(512),
    }
}

#[cfg(test)]
mod tileable_tests {
    use super::*;
    use crate::analysis::{analyze, AnalysisInput, AnalysisParams};
    use crate::exemplar::Border;

    /// A tileable solid is exactly periodic: a box of the periodic solid shifted by part of a
    /// period holds the tileable volume's voxels rolled by that shift, for a period in one
    /// piece (64) and the smallest (32).
    #[test]
    fn tileable_solids_repeat_exactly_with_their_period() {
        let input = AnalysisInput {
            exemplars: vec![crate::exemplar::procedural::cobblestone(32, 5, 2)],
            masks: vec![],
            border: Border::Wrap,
            names: vec!["cobblestone".into()],
        };
        let params = AnalysisParams {
            balance_rounds: 0,
            ..Default::default()
        };
        let analysis = analyze(&input, &params, &Compute::Cpu, &|_, _| {}).unwrap();
        for n in [32i32, 64] {
            let mut s = Synthesizer::new(&analysis, SynthParams::default(), &Compute::Cpu).unwrap();
            let (whole, _) = s.synthesize_tileable(n as u32, &|_, _| {}, false).unwrap();
            let periods = periods_below(n as u32, ANALYSED_LEVELS);
            let shift = [n / 2 + 3, -n + 5, 2 * n - 7];
            let out = Box3::new(shift, shift.map(|v| v + 20));
            let mut shifted = Vec::new();
            s.synthesize_slabs_of(
                out,
                Periodic::Unwrapped(&periods),
                &|_, _| {},
                false,
                |slab| {
                    shifted.extend_from_slice(&slab.volume.data);
                    Ok(())
                },
            )
            .unwrap();
            let c = whole.channels as usize;
            let mut i = 0;
            for z in 0..20 {
                for y in 0..20 {
                    for x in 0..20 {
                        let p = [x + shift[0], y + shift[1], z + shift[2]].map(|v| v.rem_euclid(n));
                        let want = whole.at(p[0] as u32, p[1] as u32, p[2] as u32);
                        assert_eq!(&shifted[i..i + c], want, "period {n}, voxel {x},{y},{z}");
                        i += c;
                    }
                }
            }
        }
    }
}
