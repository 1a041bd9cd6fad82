//! The one path of a request: a [`Request`] (a region of the solid, whether triples come back,
//! where progress goes) becomes a [`Job`] (what the request asks of each of its groups), taken
//! group by group, with shared coarse levels where they pay, the next groups' plans made ahead,
//! and each group's colours handed to the caller's sink (on a GPU of its own memory while the
//! next group runs) as [`Delivery`] pieces.

use super::group::FirstLevel;
use super::group_plans::{group_part, parent_level, parents_of_groups, plan_group};
use super::*;

/// What a request asks for.
#[derive(Clone, Copy, Debug)]
pub enum Region<'a> {
    /// The voxels of a box of the infinite solid (finest-level coordinates, half-open),
    /// delivered in slabs along z ([`Delivery::Slab`]).
    Box(Box3),
    /// The n^3 volume of the solid periodic with period n (a multiple of 32, its own solid:
    /// [`Synthesizer::synthesize_tileable`]), delivered in slabs along z.
    Tileable(u32),
    /// Whole finest-level bricks of the infinite solid (a surface's shell), delivered group by
    /// group ([`Delivery::Bricks`]).
    Bricks(&'a [Brick]),
    /// Voxels in any order, repeats allowed (a cut's pixels), delivered as their colours in
    /// that order ([`Delivery::Colors`]).
    Voxels(&'a [[i32; 3]]),
}

/// One request of a [`Synthesizer`]: its region, whether the finest level's triples come back
/// (boxes, tileable solids, bricks), and where progress goes.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    pub region: Region<'a>,
    pub want_triples: bool,
    pub progress: Progress<'a>,
}

fn no_progress(_: &str, _: f32) {}

impl<'a> Request<'a> {
    /// The colours of `region`, no triples, no progress reports.
    pub fn new(region: Region<'a>) -> Request<'a> {
        Request {
            region,
            want_triples: false,
            progress: &no_progress,
        }
    }
}

/// A piece of a request's result, in order.
pub enum Delivery<'a> {
    /// Consecutive z slices of a box or a tileable solid.
    Slab(Slab<'a>),
    /// A group of requested bricks with their colours (and triples when asked), sorted.
    Bricks(BrickColors),
    /// The colours of requested voxels, in their order.
    Colors(Vec<u32>),
}

/// One request as its groups see it: the same for every group of the request.
#[derive(Clone, Copy)]
pub(super) struct Job<'a> {
    /// The request is exactly the voxels of this box (its bricks are the bricks covering it):
    /// each group is then planned voxel-exactly at the finest level
    /// ([`bricks::plan_voxel_box`]), and only its voxels inside the box are meaningful. None: the
    /// requested bricks whole.
    pub(super) exact: Option<Box3>,
    /// [`Periodic::No`] for the infinite solid; a tileable solid's groups or whole period.
    pub(super) periodic: Periodic<'a>,
    /// Whether the finest level's triples come back with the colours.
    pub(super) want_triples: bool,
    /// The largest group edge in voxels (None: as large as the backend allows).
    pub(super) max_group: Option<u32>,
    pub(super) progress: Progress<'a>,
}

impl<'a> Job<'a> {
    /// The same job reporting to `progress` (a part of the request's progress).
    pub(super) fn reporting<'b>(self, progress: Progress<'b>) -> Job<'b>
    where
        'a: 'b,
    {
        Job {
            exact: self.exact,
            periodic: self.periodic,
            want_triples: self.want_triples,
            max_group: self.max_group,
            progress,
        }
    }
}

/// How a planned synthesis treats positions beyond a tileable solid's period.
#[derive(Clone, Copy)]
pub(super) enum Periodic<'a> {
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
    pub(super) fn init_period(self) -> u32 {
        match self {
            Periodic::No => 0,
            Periodic::Wrapped(p) | Periodic::Unwrapped(p) => p[0],
        }
    }

    /// The period around which level `l`'s reads wrap (0: none).
    pub(super) fn read_period(self, l: usize) -> u32 {
        match self {
            Periodic::Wrapped(p) => p[l],
            Periodic::No | Periodic::Unwrapped(_) => 0,
        }
    }
}

impl Synthesizer {
    /// Synthesize what `request` asks for, handing the result to `sink` piece by piece: the
    /// one path of every request (the other request methods are this with a sink of their
    /// own). Only the voxels a request depends on are computed; a voxel's value does not depend
    /// on the request it came in (except a tileable solid's, which is its own solid).
    pub fn run(
        &mut self,
        request: Request,
        mut sink: impl FnMut(Delivery) -> Result<()>,
    ) -> Result<()> {
        let Request {
            region,
            want_triples,
            progress,
        } = request;
        match region {
            Region::Box(out) => {
                let job = self.job(RequestKind::Volume, want_triples, progress);
                self.synthesize_slabs_of(out, job, |slab| sink(Delivery::Slab(slab)))
            }
            Region::Tileable(n) => {
                self.tileable_slabs(n, progress, want_triples, |slab| sink(Delivery::Slab(slab)))
            }
            Region::Bricks(requested) => {
                let mut all = requested.to_vec();
                bricks::normalize(&mut all);
                let job = self.job(RequestKind::Bricks, want_triples, progress);
                self.for_each_group(&all, job, |group, colors, triples| {
                    // (Groups keep the request's order: BrickColors' lookups need it.)
                    debug_assert!(group
                        .windows(2)
                        .all(|w| (w[0][2], w[0][1], w[0][0]) < (w[1][2], w[1][1], w[1][0])));
                    sink(Delivery::Bricks(BrickColors {
                        bricks: group.to_vec(),
                        grid: BrickColors::lookup(group),
                        colors: colors.to_vec(),
                        triples: triples.to_vec(),
                    }))
                })
            }
            Region::Voxels(voxels) => {
                let colors = self.sample_voxels(voxels, progress)?;
                sink(Delivery::Colors(colors))
            }
        }
    }

    /// Synthesize the sorted bricks `all` group by group, handing each group's bricks, their
    /// colours (64 per brick, x fastest) and, when asked, their triples to `sink`.
    ///
    /// `job` says how (see [`Job`]): the one path of every request of the infinite solid and of
    /// a tileable solid's groups.
    pub(super) fn for_each_group(
        &mut self,
        all: &[Brick],
        job: Job,
        mut sink: impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        let Job {
            exact,
            periodic,
            progress,
            want_triples,
            ..
        } = job;
        let mut groups = self.groups(all, 0, job.max_group);
        self.next_plan = None;
        self.deferring = false;
        self.overlapped_hand_overs = 0;
        if groups.len() > 1 && matches!(periodic, Periodic::No) {
            let exact = group_part(exact, all);
            if let Some(levels) = self.planned_one_group(all, exact, job.max_group) {
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
        let shared = self.shares_coarse_levels();
        if groups.len() > 1 && shared && !cached {
            self.for_each_group_shared(&groups, job, &mut stats, sink)?;
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
            self.check_cancelled()?;
            let timer = std::time::Instant::now();
            let scaled = |m: &str, f| progress(m, base + scale * f);
            let group_job = Job {
                exact,
                ..job.reporting(&scaled)
            };
            let (c, t) = self.synthesize_group_of(group, group_job, &mut stats)?;
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
    /// [`SynthOptions::shared_coarse_levels`]): the parent level of every group's finest level is
    /// synthesized once ([`Self::level_triples`]), then each group uploads its parents and
    /// synthesizes only the finest level.
    fn for_each_group_shared(
        &mut self,
        groups: &[Vec<Brick>],
        job: Job,
        stats: &mut SynthStats,
        mut sink: impl FnMut(&[Brick], &[u32], &[u32]) -> Result<()>,
    ) -> Result<()> {
        let Job {
            exact,
            progress,
            want_triples,
            ..
        } = job;
        let finest = ANALYSED_LEVELS - 1;
        let passes = self.params.passes.levels();
        let reach = self.params.color.reach();
        let plan_finest = |group: &[Brick]| {
            plan_group(group, group_part(exact, group), &passes[finest..], reach)
                .pop()
                .expect("one level")
        };
        let wanted = parents_of_groups(groups, plan_finest);
        // The coarse levels hold about a seventh of the voxels.
        let coarse_share = 0.15;
        let coarse_progress = |m: &str, f| progress(m, coarse_share * f);
        let parents =
            self.level_triples(wanted, finest - 1, job.reporting(&coarse_progress), stats)?;
        // (Not in a warm session, whose next request of several groups would build them again.)
        if !self.exec.keeps_buffers() {
            self.exec.release_coarse_pipelines(finest);
        }
        let mut ahead = std::collections::VecDeque::new();
        self.deferring = self.overlaps_reads(groups.len(), want_triples);
        let mut behind = None;
        for (g, group) in groups.iter().enumerate() {
            self.check_cancelled()?;
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
            let scaled = |m: &str, f| progress(m, base + scale * f);
            let r = self.synthesize_group(
                vec![parent, level],
                finest - 1,
                FirstLevel::Given(start),
                group,
                job.reporting(&scaled),
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

    /// Colours (64 per brick, `group` order) and, when asked, triples of one group of bricks.
    /// `job.exact`: the part of the request's box this group covers.
    fn synthesize_group_of(
        &mut self,
        group: &[Brick],
        job: Job,
        stats: &mut SynthStats,
    ) -> Result<(exec::Colors, Vec<u32>)> {
        // The cache builds the infinite solid's levels; a tileable solid has its own.
        if self.params.coarse_cache.is_some() && matches!(job.periodic, Periodic::No) {
            return self.synthesize_group_cached(group, job, stats);
        }
        let levels = self.plan_of(group, job.exact, 0);
        self.synthesize_group(levels, 0, FirstLevel::Init, group, job, stats)
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
