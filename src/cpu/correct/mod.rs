//! CPU reference of `wgsl/correct.wgsl`: one correction sub-pass (paper 5.1) over the voxels of one
//! parity class in a box.
//!
//! Per voxel:
//! 1. Gather its 3-neighbourhood: for each exemplar a, the 5x5 plane through the voxel spanned by
//!    axes a+1 (columns) and a+2 (rows), each voxel's value being the mean of its three exemplar
//!    pixels (colour and feature channels). Project each plane with E_a's PCA basis exactly as
//!    kernel `project` projects exemplar neighbourhoods.
//! 2. Per exemplar a, the best k-coherent 2D candidate: from the 9 in-plane neighbours n = v +
//!    du e_{a+1} + dv e_{a+2}, the pixel (their E_a coordinate) - (du, dv), and its k2d 2D
//!    candidates, scored on plane a alone.
//! 3. 3D mode: among the current triple and the first k3d_used 3D candidates of the three best 2D
//!    pixels, the triple with the lowest summed distance over the three planes ("separation of the
//!    first candidate coordinate"). 2D mode (ablation): the three best 2D coordinates.
//!
//! Distances are integer sums of squared differences of 8-bit projections; ties keep the first
//! found in that enumeration order.
//!
//! Brick-local sub-passes: a voxel reads its neighbours in its own 4x4x4 brick as the pass's
//! earlier sub-passes left them and those in other bricks as they were when the pass began. A
//! pass's dependencies then stay within its bricks and 2 voxels around them, so a request plans
//! one dilation per pass, as the paper does (`lazy::plan`), instead of one per sub-pass, while
//! the sub-passes inside a brick keep their Gauss-Seidel convergence.
//!
//! Same results as the shader, organised for a CPU: a pass of whole bricks (what the planner
//! makes) runs brick by brick, a brick's eight sub-passes on a `Window` copied out of the
//! state, blocks of z layers at a time so that no copy of the state is needed (`pass`); other
//! sub-passes ([`correct_prepared`], what the kernels-tests compare sub-pass by sub-pass) return
//! their results, read against a pass-start copy. Candidates are scored from per-level tables
//! ([`Prepared`]) that hold their projections contiguously (`scoring`).
//!
//! Optimized paths and their oracles: the whole-brick in-place pass is held to the sub-pass by
//! sub-pass order (`correct_pass(.., false)`) by `kernels-tests/correct.rs` and
//! `tests/synthesis/correction.rs`; the AVX2 runs (16-bit multiply-adds, `scoring`, `pass`) to the
//! scalar i32 sums by `scoring`'s tests.
//!
//! The per-voxel correction (gather, 2D search, 3D search, write) reads top to bottom as
//! `wgsl/correct.wgsl` does; the plane projections, reads, tables, scoring and passes are
//! submodules.

mod neighbours;
mod pass;
mod prepared;
mod projection;
mod scoring;

pub use pass::correct_pass;
pub use prepared::Prepared;

use super::synth_common::{brick_at, coord, pack_resolved, voxel_index_wrapped, write_voxel};
use crate::contract::triple::rotate_from_shared;
use crate::contract::uniforms::CorrectParams;
use neighbours::*;
use pass::*;
use prepared::*;
use rayon::prelude::*;
use scoring::*;

/// Largest projection length (bytes) the kernels support.
pub const MAX_PCA_OUT: usize = 16;

/// A projected plane: bytes (0..=255) held as i16, so differences fit 16 bits and squared
/// distances become 16-bit multiply-adds.
type Projection = [i16; MAX_PCA_OUT];

#[derive(Clone, Copy)]
struct Ctx<'a> {
    p: &'a CorrectParams,
    level: &'a [u32],
    /// The level data as bytes (little-endian words), for reading projections directly.
    level_bytes: &'a [u8],
    /// The state as the sub-passes so far left it, and as it was when the pass began.
    state: &'a [u32],
    pass_start: &'a [u32],
    /// The level's brick index.
    bricks: &'a [u32],
    grid_lo: [i32; 3],
    grid_dims: [u32; 3],
    prepared: &'a Prepared,
}

/// Voxels outside the stored bricks read as zero (only voxels the plan does not need read them).
impl Neighbours for Ctx<'_> {
    #[inline(always)]
    fn triple(&self, pos: [i32; 3]) -> [u32; 3] {
        let Some(s) = self.state_index(pos) else {
            return [0; 3];
        };
        let i = s * self.stride();
        [self.state[i], self.state[i + 1], self.state[i + 2]]
    }

    #[inline(always)]
    fn word(&self, pos: [i32; 3], w: usize) -> u32 {
        self.state_index(pos)
            .map_or(0, |s| self.state[s * self.stride() + 3 + w])
    }
}

impl Ctx<'_> {
    fn stride(&self) -> usize {
        3 + self.p.ex.pixel_words as usize
    }

    #[inline(always)]
    fn state_index(&self, pos: [i32; 3]) -> Option<usize> {
        voxel_index_wrapped(
            self.bricks,
            pos,
            self.grid_lo,
            self.grid_dims,
            self.p.table_offset,
            self.p.period,
        )
    }

    /// Squared distance between a plane projection and E_a's stored projection at pixel `c`.
    #[inline(always)]
    fn distance(&self, q: &Projection, a: usize, c: u32) -> u32 {
        let p = self.p;
        let (x, y) = coord(c);
        let base = ([p.proj0, p.proj1, p.proj2][a]
            + (y as u32 * p.ex.width + x as u32) * p.proj_words) as usize
            * 4;
        let stored = &self.level_bytes[base..base + p.pca_out as usize];
        // Fixed lengths for the usual kept dimensions, so the loop vectorizes.
        match stored.len() {
            8 => squared_distance::<8>(q, stored),
            12 => squared_distance::<12>(q, stored),
            _ => q
                .iter()
                .zip(stored)
                .map(|(&qj, &b)| (qj as i32 - b as i32).pow(2) as u32)
                .sum(),
        }
    }

    /// Best k-coherent 2D candidate of exemplar `a` for the voxel at `pos`.
    #[inline(always)]
    fn best_2d(&self, r: &impl Neighbours, pos: [i32; 3], a: usize, q: &Projection) -> u32 {
        let p = self.p;
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let cand2d = [p.cand2d0, p.cand2d1, p.cand2d2][a];
        let (mut best, mut best_d) = (0u32, u32::MAX);
        // Neighbours of a coherent patch all propose the same source pixel: its candidates
        // are scored once (a repeat could not win: ties keep the first found). All sources
        // first, their candidate runs asked of the cache, then scored: the (mostly missing)
        // reads overlap.
        let mut seen = [u32::MAX; 9];
        let mut seen_count = 0;
        let coords = r.plane_coords(pos, ua, va, a);
        for dv in -1..=1 {
            for du in -1..=1 {
                let (cx, cy) = coord(coords[(3 * (dv + 1) + du + 1) as usize]);
                let (sx, sy) = (cx - du, cy - dv);
                if p.ex.border != 0
                    && (sx < 0 || sy < 0 || sx >= p.ex.width as i32 || sy >= p.ex.height as i32)
                {
                    continue;
                }
                let src = pack_resolved(sx, sy, p.ex.width, p.ex.height, p.ex.border);
                if seen[..seen_count].contains(&src) {
                    continue;
                }
                seen[seen_count] = src;
                seen_count += 1;
                if let Some(table) = self.prepared.candidates_2d_of[a] {
                    let (px, py) = coord(src);
                    let at = (py as u32 * p.ex.width + px as u32) as usize * p.k2d as usize;
                    match &self.prepared.candidates_2d {
                        Tables2d::Short(t) => prefetch_lines(&t[table][at..], 1),
                        Tables2d::Long(t) => prefetch_lines(&t[table][at..], 1),
                    }
                }
            }
        }
        for &src in &seen[..seen_count] {
            let (px, py) = coord(src);
            let pixel = py as u32 * p.ex.width + px as u32;
            if let Some(table) = self.prepared.candidates_2d_of[a] {
                let k = p.k2d as usize;
                let range = pixel as usize * k..(pixel as usize + 1) * k;
                let found = match &self.prepared.candidates_2d {
                    Tables2d::Short(t) => best_2d_of_run(&t[table][range], q, best_d),
                    Tables2d::Long(t) => best_2d_of_run(&t[table][range], q, best_d),
                };
                if let Some((d, c)) = found {
                    best_d = d;
                    best = c;
                }
                continue;
            }
            let list = cand2d + pixel * p.k2d;
            for j in 0..p.k2d {
                let c = self.level[(list + j) as usize];
                let d = self.distance(q, a, c) * (16 + self.penalty(a, c));
                if d < best_d {
                    best_d = d;
                    best = c;
                }
            }
        }
        best
    }

    /// Ask the cache for the [`Tables3d`] run of pixel `c` of exemplar `a` (its first two
    /// lines: the four candidates of the finest level, the first ones above).
    #[inline(always)]
    fn prefetch_3d(&self, a: usize, c: u32) {
        let p = self.p;
        let set = if p.shared_sets != 0 { 0 } else { a };
        let (x, y) = coord(c);
        let at = (y as u32 * p.ex.width + x as u32) as usize * p.k3d_used as usize;
        match &self.prepared.candidates_3d {
            Tables3d::Short(t) if set < t.len() => prefetch_lines(&t[set][at..], 2),
            Tables3d::Long(t) if set < t.len() => prefetch_lines(&t[set][at..], 2),
            _ => {}
        }
    }

    #[inline(always)]
    fn penalty(&self, a: usize, c: u32) -> u32 {
        penalty(self.p, self.level, a, c)
    }

    /// The scale of a triple's distance: 16 + the penalties of its three pixels.
    #[inline(always)]
    fn factor(&self, t: [u32; 3]) -> u32 {
        16 + self.penalty(0, t[0]) + self.penalty(1, t[1]) + self.penalty(2, t[2])
    }

    /// A triple's distance to the voxel's three plane projections, scaled by its usage
    /// penalties (at most 3 x 12 x 255^2 x (16 + 3 x 255) < 2^32).
    #[inline(always)]
    fn total_distance(&self, q: &[Projection; 3], t: [u32; 3]) -> u32 {
        (self.distance(&q[0], 0, t[0])
            + self.distance(&q[1], 1, t[1])
            + self.distance(&q[2], 2, t[2]))
            * self.factor(t)
    }

    #[inline(always)]
    fn correct_voxel<const MADD: bool>(&self, r: &impl Neighbours, pos: [i32; 3]) -> [u32; 3] {
        let p = self.p;
        let q = [
            self.project_plane::<MADD>(r, pos, 0),
            self.project_plane::<MADD>(r, pos, 1),
            self.project_plane::<MADD>(r, pos, 2),
        ];
        // Each plane's 3D candidates are fetched as soon as its best 2D pixel is known, so the
        // (mostly cache-missing) reads overlap the other planes' 2D searches.
        // (Unrolled: a loop over the planes is 20% slower, each call no longer specialized.)
        let prefetch = p.mode != 1;
        let best0 = self.best_2d(r, pos, 0, &q[0]);
        if prefetch {
            self.prefetch_3d(0, best0);
        }
        let best1 = self.best_2d(r, pos, 1, &q[1]);
        if prefetch {
            self.prefetch_3d(1, best1);
        }
        let best2 = self.best_2d(r, pos, 2, &q[2]);
        if prefetch {
            self.prefetch_3d(2, best2);
        }
        let best2d = [best0, best1, best2];
        if p.mode == 1 {
            return best2d;
        }
        let mut best = r.triple(pos);
        let mut best_d = self.total_distance(&q, best);
        for a in 0..3 {
            let set = if p.shared_sets != 0 { 0 } else { a };
            // Every 3D candidate of pixel best2d[a] has that pixel as its a coordinate (the
            // .ssa reader checks it): its distance on plane a is scored once.
            let own = self.distance(&q[a], a, best2d[a]);
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            let (x, y) = coord(best2d[a]);
            let pixel = y as u32 * p.ex.width + x as u32;
            let count = self.level[([p.counts0, p.counts1, p.counts2][set] + pixel) as usize]
                .min(p.k3d_used);
            if self.prepared.candidates_3d.has(set) {
                // The same scores from the table: the triple's coordinates after the own one
                // (rotated into place for a shared set) are those of `next` and `last`.
                let used = p.k3d_used as usize;
                let range = pixel as usize * used..pixel as usize * used + count as usize;
                let found = match &self.prepared.candidates_3d {
                    Tables3d::Short(t) => best_of_run(&t[set][range], &q[b], &q[c], own, best_d),
                    Tables3d::Long(t) => best_of_run(&t[set][range], &q[b], &q[c], own, best_d),
                };
                if let Some((d, t)) = found {
                    best_d = d;
                    best = if p.shared_sets != 0 {
                        rotate_from_shared(t, a)
                    } else {
                        t
                    };
                }
                continue;
            }
            let list = [p.cand3d0, p.cand3d1, p.cand3d2][set] + pixel * p.k3d_stride * 3;
            for j in 0..count {
                let e = (list + j * 3) as usize;
                let mut t = [self.level[e], self.level[e + 1], self.level[e + 2]];
                if p.shared_sets != 0 {
                    t = rotate_from_shared(t, a);
                }
                let d = (own + self.distance(&q[b], b, t[b]) + self.distance(&q[c], c, t[c]))
                    * self.factor(t);
                if d < best_d {
                    best_d = d;
                    best = t;
                }
            }
        }
        best
    }
}

impl Ctx<'_> {
    /// Correct the voxels the sub-pass's masks mark (bit k: class voxel k) in the run of `n`
    /// bricks from entry `i` of its list (consecutive along x), appending (state index, new
    /// triple).
    #[inline(always)]
    fn correct_run<const MADD: bool>(
        &self,
        window: &mut Window,
        i: u32,
        n: u32,
        out: &mut Vec<(u32, [u32; 3])>,
    ) {
        let p = self.p;
        let first = brick_at(self.bricks, p.list_offset, i);
        // A window costs ~100 index lookups and a few KiB copied per brick; a voxel read through
        // the index ~100 lookups. (The same values either way.)
        let windowed =
            p.ex.pixel_words == 1 && p.period.is_multiple_of(4) && (n > 1 || self.mask(i).count_ones() >= 3);
        let class = [p.class_x as i32, p.class_y as i32, p.class_z as i32];
        if windowed {
            window.fill(self, first, n as i32, class);
        }
        // Reads outside the own brick through the index see the pass-start state.
        let start = Ctx {
            state: self.pass_start,
            ..*self
        };
        let stride = self.stride();
        let mut saved = BrickCopy::new();
        for m in 0..n {
            let mask = self.mask(i + m);
            let b = [first[0] + m as i32, first[1], first[2]];
            let origin = b.map(|v| v * 4);
            let base = self.state_index(origin).expect("active bricks are stored");
            if windowed {
                // The brick's own voxels as the pass's sub-passes left them, in place of their
                // pass-start copies while its voxels are corrected.
                let words = &self.state[base * stride..(base + 64) * stride];
                window.overlay(m as i32, words, &mut saved);
            }
            for k in 0..8 {
                if (mask >> k) & 1 == 0 {
                    continue;
                }
                let pos = [
                    b[0] * 4 + class[0] + 2 * (k & 1),
                    b[1] * 4 + class[1] + 2 * ((k >> 1) & 1),
                    b[2] * 4 + class[2] + 2 * (k >> 2),
                ];
                let index = self.state_index(pos).expect("active bricks are stored");
                let t = if windowed {
                    self.correct_voxel::<MADD>(&*window, pos)
                } else {
                    let r = BrickLocal {
                        outer: &start,
                        state: self.state,
                        stride,
                        origin,
                        base,
                    };
                    self.correct_voxel::<MADD>(&r, pos)
                };
                out.push((index as u32, t));
            }
            if windowed {
                window.restore(m as i32, &saved);
            }
        }
    }

    /// The sub-pass's mask of list entry `i`: bit k for class voxel k.
    #[inline(always)]
    fn mask(&self, i: u32) -> u32 {
        (self.bricks[(self.p.mask_offset + i / 4) as usize] >> ((i % 4) * 8)) & 0xFF
    }

    /// [`Ctx::correct_run`], compiled for AVX2 when the CPU has it (detected at run time):
    /// the projections' 8-wide integer multiply-adds then take one instruction. Integer
    /// arithmetic: the same result either way.
    fn correct_run_dispatch(
        &self,
        window: &mut Window,
        i: u32,
        n: u32,
        out: &mut Vec<(u32, [u32; 3])>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.correct_run_avx2(window, i, n, out) };
        }
        self.correct_run::<false>(window, i, n, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn correct_run_avx2(
        &self,
        window: &mut Window,
        i: u32,
        n: u32,
        out: &mut Vec<(u32, [u32; 3])>,
    ) {
        self.correct_run::<true>(window, i, n, out)
    }
}

/// A sub-pass's results: (state voxel index, new triple), kept in the parts the workers produced
/// (a sub-pass of a large box updates tens of millions of voxels: no concatenating copy).
pub struct Updates(Vec<Vec<(u32, [u32; 3])>>);

impl Updates {
    #[cfg(any(test, feature = "internals"))]
    pub fn len(&self) -> usize {
        self.0.iter().map(Vec::len).sum()
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn iter(&self) -> impl Iterator<Item = (usize, [u32; 3])> + '_ {
        self.0.iter().flatten().map(|&(i, t)| (i as usize, t))
    }
}

/// Usage penalty of pixel `c` of E_a (see `analysis::balance`), in sixteenths: the level data
/// holds one word per pixel right after E_a's pixels (see `lazy::pack`).
#[inline(always)]
fn penalty(p: &CorrectParams, level: &[u32], a: usize, c: u32) -> u32 {
    let (x, y) = coord(c);
    let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2][a];
    let table = pixels + p.ex.width * p.ex.height * p.ex.pixel_words;
    level[(table + y as u32 * p.ex.width + x as u32) as usize]
}

/// Run one sub-pass: returns (state index, new triple) for every voxel of the class in the
/// bricks of the list in `p`. `pass_start`: the state when its pass began (the same words as
/// `state` in the pass's first sub-pass).
#[cfg(any(test, feature = "internals"))]
pub fn correct(
    p: &CorrectParams,
    level: &[u32],
    state: &[u32],
    pass_start: &[u32],
    bricks: &[u32],
) -> Updates {
    correct_prepared(
        &Prepared::new(p, level),
        p,
        level,
        state,
        pass_start,
        bricks,
    )
}

/// [`correct`] with the level's [`Prepared`] data (built from the same level and layout).
pub fn correct_prepared(
    prepared: &Prepared,
    p: &CorrectParams,
    level: &[u32],
    state: &[u32],
    pass_start: &[u32],
    bricks: &[u32],
) -> Updates {
    assert!(prepared.fits(p), "prepared for another level layout");
    assert_eq!(
        state.len(),
        pass_start.len(),
        "pass-start state of another size"
    );
    assert!(
        state.len() / (3 + p.ex.pixel_words as usize) <= u32::MAX as usize,
        "state indices fit 32 bits"
    );
    let ctx = Ctx {
        p,
        level,
        level_bytes: bytemuck::cast_slice(level),
        prepared,
        state,
        pass_start,
        bricks,
        grid_lo: [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z],
        grid_dims: [p.grid_x, p.grid_y, p.grid_z],
    };
    Updates(over_runs(&ctx, |window, i, n, out| {
        ctx.correct_run_dispatch(window, i, n, out)
    }))
}

/// Apply a sub-pass's results to the state: each voxel's new triple and its value.
pub fn apply(p: &CorrectParams, level: &[u32], state: &mut [u32], updates: &Updates) {
    let stride = 3 + p.ex.pixel_words as usize;
    let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2];
    for (i, t) in updates.iter() {
        write_voxel(
            &mut state[i * stride..(i + 1) * stride],
            level,
            t,
            pixels,
            p.ex.width,
            p.ex.pixel_words,
            p.ex.channels,
        );
    }
}
