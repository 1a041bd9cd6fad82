//! Finding matched patches (paper 4.2.1): check points, their three slices of the current solid,
//! and the exemplar patches that best match them.

use super::frame::{Frame, SliceAxes};
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

/// The matches of `points` ([`check_points`]), in their order.
pub fn match_all(solid: &PeriodicSolid, ctx: &MatchContext, points: &[[u16; 3]]) -> Vec<Match> {
    points
        .par_iter()
        .map_init(
            || vec![0f32; ctx.patches.dims()],
            |buffer, p| match_check_point_dispatch(solid, ctx, p.map(i64::from), buffer),
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
    buffer: &mut [f32],
) -> Match {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { match_check_point_avx2(solid, ctx, p, buffer) };
    }
    match_check_point(solid, ctx, p, buffer)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn match_check_point_avx2(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    buffer: &mut [f32],
) -> Match {
    match_check_point(solid, ctx, p, buffer)
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

/// The matches of the check point at `p`.
///
/// Crossbars (Fig. 3) are the lines two slices share; which patch line each is depends on the
/// slice axes ([`SliceAxes`]). Cyclic: the line along z is the centre column of s_x and the
/// centre row of s_y; along y, the column of s_z and the row of s_x; along x, the column of s_y
/// and the row of s_z. Upright: along z, the centre columns of s_x and s_y (only two slices are
/// matched then). The paper chooses E_y "from a set of N_1 candidates with the most consistent
/// crossbar voxels as E_x"; we read the set as the N_1 nearest patches to s_y (what the search
/// gives cheaply) and pick the one whose crossbar agrees best with E_x.
#[inline(always)]
pub fn match_check_point(
    solid: &PeriodicSolid,
    ctx: &MatchContext,
    p: [i64; 3],
    buffer: &mut [f32],
) -> Match {
    let q = project_slices(solid, ctx, p, buffer);
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
