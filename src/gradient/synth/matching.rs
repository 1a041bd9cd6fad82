//! Finding matched patches (paper 4.2.1): check points, their three slices of the current solid,
//! and the exemplar patches that best match them.

use super::crossbar::{CrossbarSets, MAX_SET};
use super::frame::{Frame, SliceAxes};
use super::ivf::lane_distance;
use super::patches::{LevelPatches, Line};
use super::pca::KEPT;
use super::{GradientSynthParams, PeriodicSolid, SliceSearch};
use crate::gradient::SPACING;
use crate::util::hash::mix64;
use glam::DVec3;
use rayon::prelude::*;

/// What one iteration of one level needs to place and match check points.
pub struct MatchContext<'a> {
    pub params: &'a GradientSynthParams,
    pub level: u32,
    pub iteration: u32,
    pub patches: &'a LevelPatches,
    /// The crossbar-consistent sets of [`SliceSearch::Crossbar`] (built per level).
    pub sets: Option<&'a CrossbarSets>,
}

impl MatchContext<'_> {
    /// Check point `k` of cube `cube` (wrapped cube coordinates): a seeded position inside the
    /// cube, whole voxels.
    pub fn check_point(&self, cube: [u32; 3], k: u32) -> [i64; 3] {
        let tag = ((self.level as u64) << 56)
            ^ ((self.iteration as u64) << 48)
            ^ ((k as u64) << 40)
            ^ ((cube[2] as u64) << 26)
            ^ ((cube[1] as u64) << 13)
            ^ cube[0] as u64;
        let h = mix64(mix64(self.params.seed) ^ tag);
        let d = SPACING as u64;
        std::array::from_fn(|a| (cube[a] * SPACING) as i64 + ((h >> (8 * a)) % d) as i64)
    }

    /// The slice frame at check point `p`.
    pub fn frame(&self, p: [i64; 3], period: i64) -> Frame {
        let centre = DVec3::splat(period as f64 / 2.0);
        self.params
            .field
            .frame([p[0] as i32, p[1] as i32, p[2] as i32], centre)
    }

    /// Voxel of sample (a, b) of the slice orthogonal to local axis `o` at `p`.
    #[inline]
    pub fn sample_position(
        &self,
        p: [i64; 3],
        frame: &Frame,
        o: usize,
        a: u32,
        b: u32,
    ) -> [i64; 3] {
        let s = self.patches.spacing as i64;
        let h = (self.patches.size / 2) as i64;
        let (da, db) = (s * (a as i64 - h), s * (b as i64 - h));
        if frame.is_identity() {
            let (u, v) = self.params.slice_axes().of(o);
            let mut q = p;
            q[u] += da;
            q[v] += db;
            return q;
        }
        let (u, v) = frame.slice_axes(self.params.slice_axes(), o);
        let off = u * da as f64 + v * db as f64;
        [
            p[0] + off.x.round() as i64,
            p[1] + off.y.round() as i64,
            p[2] + off.z.round() as i64,
        ]
    }
}

/// Matched candidate indices of one check point: one per slice (x, y, z); [`UNMATCHED`] for a
/// slice left free.
pub type Match = [u32; 3];

pub const UNMATCHED: u32 = u32::MAX;

/// Every check point's voxel, in order (cube index, then k): computed once per iteration, for
/// the matching and for every bucket tile that visits it. Coordinates lie in [0, P), P <= 4096.
pub fn check_points(m: u32, ctx: &MatchContext) -> Vec<[u16; 3]> {
    let m = m as usize;
    let nc = ctx.params.check_points as usize;
    (0..m * m * m * nc)
        .into_par_iter()
        .map(|i| {
            let cube = i / nc;
            let cube = [cube % m, (cube / m) % m, cube / (m * m)].map(|c| c as u32);
            ctx.check_point(cube, (i % nc) as u32).map(|v| v as u16)
        })
        .collect()
}

/// One thread's working memory for matching check points.
pub struct Scratch {
    /// The samples of one slice (a direction field's slices are projected from it).
    buffer: Vec<f32>,
    /// Per candidate, the last check point (`epoch`) whose E_z pool took it: a pool drops
    /// the second copy of a candidate in both of its sets.
    pooled: Vec<u32>,
    epoch: u32,
    /// E_z's pool: (crossbar cost, candidate) keys.
    pool: Vec<u64>,
}

impl Scratch {
    pub fn new(patches: &LevelPatches) -> Scratch {
        Scratch {
            buffer: vec![0.0; patches.dims()],
            pooled: vec![u32::MAX; patches.candidates()],
            epoch: 0,
            pool: Vec::new(),
        }
    }
}

/// The matches of `points` ([`check_points`]), in their order.
pub fn match_all(solid: &PeriodicSolid, ctx: &MatchContext, points: &[[u16; 3]]) -> Vec<Match> {
    points
        .par_iter()
        .map_init(
            || Scratch::new(ctx.patches),
            |scratch, p| match_check_point_dispatch(solid, ctx, p.map(i64::from), scratch),
        )
        .collect()
}

/// [`match_check_point`], compiled for AVX2 when the CPU has it (detected at run time): the
/// slices' evaluation and projection then run 8 lanes wide. The same IEEE operations in the
/// same order (Rust never contracts them into FMAs): the same matches either way.
fn match_check_point_dispatch(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    scratch: &mut Scratch,
) -> Match {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { match_check_point_avx2(solid, ctx, p, scratch) };
    }
    match_check_point(solid, ctx, p, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn match_check_point_avx2(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    scratch: &mut Scratch,
) -> Match {
    match_check_point(solid, ctx, p, scratch)
}

/// The three slices at `p`, projected.
#[inline(always)]
fn project_slices(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    buffer: &mut [f32],
) -> [[f32; KEPT]; 3] {
    let frame = ctx.frame(p, solid.period());
    let (n, c) = (ctx.patches.size, solid.channels);
    // A loop, not `std::array::from_fn`: its closure would be compiled apart from the caller,
    // without the caller's AVX2 (half the projection's speed).
    let mut projections = [[0.0; KEPT]; 3];
    for (o, out) in projections.iter_mut().enumerate() {
        if o as u32 >= ctx.params.matched_slices {
            continue; // a slice left free is never searched
        }
        if frame.is_identity() {
            // Axis-aligned slices: whole-voxel steps along two axes, projected straight from
            // the control points their samples are nearest to.
            let (u, v) = ctx.params.slice_axes().of(o);
            *out = ctx.patches.folded().project(solid, p, u, v);
            continue;
        }
        // A direction field: each sample located on its own.
        for b in 0..n {
            for a in 0..n {
                let q = ctx.sample_position(p, &frame, o, a, b);
                let at = ((b * n + a) as usize) * c;
                solid.taylor(q, &mut buffer[at..at + c]);
            }
        }
        *out = ctx.patches.pca().project(buffer);
    }
    projections
}

/// Index of the candidate with the smallest `cost` (ties: the nearer in appearance, i.e. the
/// earlier in `ranked`).
fn most_consistent(ranked: &[(f32, u32)], cost: impl Fn(u32) -> u32) -> u32 {
    let mut best = (u32::MAX, ranked[0].1);
    for &(_, c) in ranked {
        let e = cost(c);
        if e < best.0 {
            best = (e, c);
        }
    }
    best.1
}

/// The candidate of `set` nearest to the projected slice `q` (ties: the lower index). A plain
/// loop (a closure would be compiled without the caller's AVX2).
#[inline(always)]
fn nearest_in(patches: &LevelPatches, q: &[f32; KEPT], set: &[u32]) -> u32 {
    let mut best = u64::MAX;
    for &c in set {
        let d = lane_distance(q, patches.point(c));
        best = best.min(((d.to_bits() as u64) << 32) | c as u64);
    }
    best as u32
}

/// The matches of the check point at `p`.
///
/// Crossbars (Fig. 3) are the lines two slices share; which patch line each is depends on the
/// slice axes ([`SliceAxes`]). Cyclic: the line along z is the centre column of s_x and the
/// centre row of s_y; along y, the column of s_z and the row of s_x; along x, the column of s_y
/// and the row of s_z. Upright: along z, the centre columns of s_x and s_y (only two slices are
/// matched then).
///
/// [`SliceSearch::Crossbar`] is the paper's search: E_x is the nearest patch to s_x; E_y the
/// nearest to s_y among the N_1 patches most consistent with E_x on their crossbar (sets
/// precomputed, [`super::crossbar`]); E_z the nearest to s_z among the N_2 most consistent with
/// both, ranked by the sum of the two line distances over the union of E_x's and E_y's
/// precomputed sets. [`SliceSearch::CrossbarNearest`] swaps the roles: the N_1 nearest patches
/// to s_y, then the most consistent of them.
#[inline(always)]
pub fn match_check_point(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    scratch: &mut Scratch,
) -> Match {
    let q = project_slices(solid, ctx, p, &mut scratch.buffer);
    let patches = ctx.patches;
    let probes = ctx.params.probes.map(|p| p as usize);
    let three = ctx.params.matched_slices == 3;
    match ctx.params.search {
        SliceSearch::Independent => {
            let mut m = q.map(|q| patches.nearest(&q, 1, probes)[0].1);
            if !three {
                m[2] = UNMATCHED;
            }
            m
        }
        SliceSearch::Crossbar { n1, n2 } => {
            let sets = ctx.sets.expect("crossbar sets built for the level");
            let ex = patches.nearest(&q[0], 1, probes)[0].1;
            let for_ey = sets.for_ey.of(ex);
            let ey = nearest_in(patches, &q[1], &for_ey[..for_ey.len().min(n1 as usize)]);
            let Some(for_ez) = &sets.for_ez else {
                return [ex, ey, UNMATCHED];
            };
            // Three slices (cyclic axes): E_z's column against E_x's row, its row against E_y's
            // column. The pool is both lines' precomputed sets (each already knows its own
            // line's distance), ranked by the summed distance.
            scratch.epoch = scratch.epoch.wrapping_add(1);
            let (epoch, pooled, pool) = (scratch.epoch, &mut scratch.pooled, &mut scratch.pool);
            pool.clear();
            for (&c, &d) in for_ez.of(ex).iter().zip(for_ez.distances(ex)) {
                pooled[c as usize] = epoch;
                let cost = d + patches.line_distance(ey, Line::Column, c, Line::Row);
                pool.push(((cost as u64) << 32) | c as u64);
            }
            for (&c, &d) in sets.for_ey.of(ey).iter().zip(sets.for_ey.distances(ey)) {
                if pooled[c as usize] != epoch {
                    let cost = patches.line_distance(ex, Line::Row, c, Line::Column) + d;
                    pool.push(((cost as u64) << 32) | c as u64);
                }
            }
            let n2 = (n2 as usize).min(pool.len());
            pool.select_nth_unstable(n2 - 1);
            let mut set = [0u32; 2 * MAX_SET];
            for (s, &key) in set.iter_mut().zip(&pool[..n2]) {
                *s = key as u32;
            }
            let ez = nearest_in(patches, &q[2], &set[..n2]);
            [ex, ey, ez]
        }
        SliceSearch::CrossbarNearest { n1, n2 } => {
            let ex = patches.nearest(&q[0], 1, probes)[0].1;
            let ey_line = match ctx.params.slice_axes() {
                SliceAxes::Cyclic => Line::Row,
                SliceAxes::Upright => Line::Column,
            };
            let ey = most_consistent(&patches.nearest(&q[1], n1 as usize, probes), |c| {
                patches.line_distance(ex, Line::Column, c, ey_line)
            });
            if !three {
                return [ex, ey, UNMATCHED];
            }
            // Three slices: cyclic axes.
            let ez = most_consistent(&patches.nearest(&q[2], n2 as usize, probes), |c| {
                patches.line_distance(ex, Line::Row, c, Line::Column)
                    + patches.line_distance(ey, Line::Column, c, Line::Row)
            });
            [ex, ey, ez]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient::synth::{LevelSpec, DEFAULT_PROBES};

    #[test]
    fn crossbar_matches_come_from_the_consistent_sets() {
        let img = crate::exemplar::default_exemplar()
            .with_channels(3)
            .crop(0, 0, 64, 64);
        let spec = LevelSpec {
            spacing: 1,
            size: 9,
        };
        let patches = LevelPatches::build(&img, spec.spacing, spec.size, None, None, 3).unwrap();
        let (n1, n2) = (20, 50);
        let sets = CrossbarSets::build(&patches, true, n2, 4);
        let params = GradientSynthParams {
            size: 32,
            levels: vec![spec],
            search: SliceSearch::Crossbar { n1, n2: n2 as u32 },
            ..Default::default()
        };
        let ctx = MatchContext {
            params: &params,
            level: 0,
            iteration: 0,
            patches: &patches,
            sets: Some(&sets),
        };
        let solid = PeriodicSolid::random(8, &img, 1);
        let mut scratch = Scratch::new(&patches);
        for p in check_points(8, &ctx).iter().step_by(7) {
            let p = p.map(i64::from);
            let [ex, ey, ez] = match_check_point(&solid, &ctx, p, &mut scratch);
            let q = project_slices(&solid, &ctx, p, &mut scratch.buffer);
            assert_eq!(
                ex,
                patches.nearest(&q[0], 1, Some(DEFAULT_PROBES as usize))[0].1
            );
            // E_y: the nearest to s_y of E_x's N_1 most consistent.
            let for_ey = &sets.for_ey.of(ex)[..n1 as usize];
            assert_eq!(ey, nearest_in(&patches, &q[1], for_ey));
            // E_z: of the union of the two sets, among the N_2 of lowest summed crossbar
            // distance, and the nearest to s_z of those.
            let cost = |c: u32| {
                patches.line_distance(ex, Line::Row, c, Line::Column)
                    + patches.line_distance(ey, Line::Column, c, Line::Row)
            };
            let for_ez = sets.for_ez.as_ref().unwrap();
            let mut pool: Vec<(u32, u32)> = for_ez
                .of(ex)
                .iter()
                .chain(sets.for_ey.of(ey))
                .map(|&c| (cost(c), c))
                .collect();
            pool.sort_unstable();
            pool.dedup();
            let kept: Vec<u32> = pool[..n2].iter().map(|&(_, c)| c).collect();
            assert_eq!(ez, nearest_in(&patches, &q[2], &kept));
        }
    }
}
