//! How a request is split and planned: groups of bricks sized to the backend
//! ([`grouping::group_sides`]), the whole request as one group where its sparse state fits,
//! the next groups' plans made ahead in parallel, and the shared coarse levels' triples
//! ([`LevelTriples`]) synthesized once for all groups.

use super::group::FirstLevel;
use super::request::Job;
use super::*;

/// At most this many plans of groups' every level are held at once ([`parents_of_groups`],
/// [`Synthesizer::plan_ahead`]).
pub(super) const PLANS_AT_ONCE: usize = 4;

/// At most this many requested bricks (4^3 voxels each) are planned ahead together
/// ([`Synthesizer::plan_ahead`]): a plan holds its levels' brick lists and tables, tens of bytes
/// per brick, so a window of large groups would hold a lot.
const PLAN_AHEAD_BRICKS: usize = 1 << 17;

impl Synthesizer {
    /// The most bytes one level's state of a group may take.
    pub(super) fn state_limit(&self) -> u64 {
        self.exec
            .max_state_bytes()
            .min(self.options.state_limit.unwrap_or(u64::MAX))
    }

    /// Split sorted bricks into groups (boxes of bricks) whose working set fits the backend
    /// ([`grouping::group_sides`]), each at most [`group_cap`] voxels on a side.
    /// `coarser_by`: how many levels above the finest the bricks are (a shared coarse level's);
    /// `max_group`: the request's group edge.
    pub(super) fn groups(
        &self,
        all: &[Brick],
        coarser_by: usize,
        max_group: Option<u32>,
    ) -> Vec<Vec<Brick>> {
        let whole_box = bricks::bounds(all).is_some_and(|(lo, hi)| {
            // (Saturating: bricks far apart span more cells than a u64 counts.)
            let cells = (0..3).fold(1u64, |n, i| n.saturating_mul((hi[i] - lo[i] + 1) as u64));
            cells == all.len() as u64
        });
        let cap = group_cap(max_group, coarser_by, whole_box);
        // The levels up to the bricks' own, with this schedule and these strides.
        let levels = ANALYSED_LEVELS - coarser_by;
        let passes = &self.params.passes.levels()[..levels];
        let strides: Vec<u64> = self.packs[..levels]
            .iter()
            .map(|p| (3 + p.pixel_words as u64) * 4)
            .collect();
        // The finest level also delivers what the output's colours read around it: a brick
        // more on every side for a sparse request (`plan_group`), which covers a box's reach.
        let grow = match coarser_by == 0 && self.params.color.reach() > 0 {
            true => 2 * bricks::BRICK as u64,
            false => 0,
        };
        let bound = |extent: [u64; 3]| {
            grouping::planned_state_bytes(extent.map(|e| e + grow), passes, &strides)
        };
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
    pub(super) fn planned_one_group(
        &self,
        all: &[Brick],
        exact: Option<Box3>,
        max_group: Option<u32>,
    ) -> Option<Vec<SparseLevel>> {
        let cap = max_group.unwrap_or(512).min(512);
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
        let levels = plan_group(all, exact, &passes[first..], self.params.color.reach());
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
    /// their time planning one after the other on an NVIDIA H100 (BENCHMARKS.md).
    /// The plans are of the levels from `first` (the finest only where a group reads the
    /// coarse cache or shared coarse levels).
    pub(super) fn plan_ahead(
        &self,
        groups: &[Vec<Brick>],
        exact: Option<Box3>,
        first: usize,
    ) -> std::collections::VecDeque<Vec<SparseLevel>> {
        let passes = &self.params.passes.levels()[first..];
        let reach = self.params.color.reach();
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
            .map(|g| plan_group(g, group_part(exact, g), passes, reach))
            .collect();
        tracing::debug!("planned {window} groups ahead in {:.1} ms", ms(timer));
        plans
    }

    /// The plan of `group` through the levels from `first`: the one made by
    /// [`Self::planned_one_group`] when it is for this group, else a new one.
    pub(super) fn plan_of(
        &mut self,
        group: &[Brick],
        exact: Option<Box3>,
        first: usize,
    ) -> Vec<SparseLevel> {
        if let Some((planned, planned_exact, levels)) = self.next_plan.take() {
            if planned == group && planned_exact == exact {
                return levels;
            }
        }
        let timer = std::time::Instant::now();
        let reach = self.params.color.reach();
        let levels = plan_group(group, exact, &self.params.passes.levels()[first..], reach);
        tracing::debug!("planned {} bricks in {:.1} ms", group.len(), ms(timer));
        levels
    }

    /// The triples of the level-`top` bricks `wanted` (sorted), synthesized group by group
    /// through levels l_start..=`top`. With several groups above l_start, their parent level
    /// is itself synthesized once for all of them (recursively), so no group recomputes the
    /// coarser levels' padding of its neighbours.
    pub(super) fn level_triples(
        &mut self,
        wanted: Vec<Brick>,
        top: usize,
        job: Job,
        stats: &mut SynthStats,
    ) -> Result<LevelTriples> {
        let progress = job.progress;
        let groups = self.groups(&wanted, ANALYSED_LEVELS - 1 - top, job.max_group);
        let passes = self.params.passes.levels();
        let plan_top = |group: &[Brick]| {
            bricks::plan_sparse(group, &passes[top..=top])
                .pop()
                .expect("one level")
        };
        let parents = if top > 0 && groups.len() > 1 {
            let below = parents_of_groups(&groups, plan_top);
            let below_progress = |m: &str, f| progress(m, 0.15 * f);
            Some(self.level_triples(below, top - 1, job.reporting(&below_progress), stats)?)
        } else {
            None
        };
        let mut out = LevelTriples::new(wanted, self.packs[top].width, self.packs[top].height);
        let stride = 3 + self.packs[top].pixel_words as usize;
        for (g, group) in groups.iter().enumerate() {
            self.check_cancelled()?;
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
            let level_job = Job {
                want_triples: false,
                ..job.reporting(&group_progress)
            };
            let state = self
                .synthesize_group(levels, first_pack, start, &[], level_job, stats)?
                .state;
            let timer = std::time::Instant::now();
            out.set_bricks(group, &grid, &state, stride)?;
            tracing::debug!("level {top}: group's triples stored in {:.1} ms", ms(timer));
        }
        Ok(out)
    }
}

/// The plan of a group of bricks: voxel-exact at the finest level when the request is the
/// box `exact` (see [`Synthesizer::for_each_group`]). `reach`: how far around an output voxel
/// its colour reads the finest level's final values ([`ColorSource::reach`]), which the finest
/// level then delivers too (the group's bricks and their neighbours where it is not a box).
pub(super) fn plan_group(
    group: &[Brick],
    exact: Option<Box3>,
    passes: &[usize],
    reach: i32,
) -> Vec<SparseLevel> {
    match (exact, reach) {
        (Some(b), _) => bricks::plan_voxel_box(b.dilate([-reach; 3], [reach; 3]), passes),
        (None, 0) => bricks::plan_sparse(group, passes),
        (None, _) => {
            // Within one brick of its own (reach <= 4): a correction pass computes whole
            // bricks anyway.
            debug_assert!(reach <= bricks::BRICK);
            bricks::plan_sparse(&bricks::dilate(group, [-1; 3], [1; 3]), passes)
        }
    }
}

/// The part of the exact box `exact` (see [`Synthesizer::for_each_group`]) that `group`'s
/// bricks cover.
pub(super) fn group_part(exact: Option<Box3>, group: &[Brick]) -> Option<Box3> {
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
pub(super) fn parents_of_groups(
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
pub(super) fn parent_level(level: &SparseLevel) -> SparseLevel {
    let mut parents: Vec<Brick> = level.bricks.iter().map(|b| b.map(|v| v >> 1)).collect();
    bricks::normalize(&mut parents);
    SparseLevel {
        grid: BrickGrid::new(&parents),
        deliver: parents.clone(),
        bricks: parents,
        subpasses: Vec::new(),
    }
}
