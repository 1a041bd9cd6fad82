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
//! Distances are integer sums of squared differences of 8-bit projections; ties keep the first
//! found in that enumeration order.
//!
//! Brick-local sub-passes: a voxel reads its neighbours in its own 4x4x4 brick from `state` (as the
//! pass's earlier sub-passes left them) and those in other bricks from `pass_start` (the state when
//! the pass began). A pass's dependencies then stay within its bricks and 2 voxels around them,
//! so a request plans one dilation per pass, as the paper does (`lazy::plan`), instead of one
//! per sub-pass, while the sub-passes inside a brick keep their Gauss-Seidel convergence.
//! Results are returned, not written in place, so a sub-pass never reads a value it produced.
//!
//! Same results as the shader, organised for a CPU: voxels are corrected a run of bricks at a
//! time from a `Window` copied out of the state, and candidates are scored from per-level
//! tables ([`Prepared`]) that hold their projections contiguously.

use super::synth_common::{brick_at, coord, pack_resolved, voxel_index, write_voxel};
use crate::analysis::frame::rotate_from_shared;
use crate::kernel_types::CorrectParams;
use rayon::prelude::*;

/// Largest projection length (bytes) the kernels support.
pub const MAX_PCA_OUT: usize = 16;

/// A projected plane: bytes (0..=255) held as i16, so differences fit 16 bits and squared
/// distances become 16-bit multiply-adds.
type Projection = [i16; MAX_PCA_OUT];

/// A 2D candidate and a copy of its stored projection: a source pixel's k2d candidates are then
/// scored from one contiguous run instead of k2d scattered reads of the exemplar's projections.
/// P bytes of projection: the level's kept dimensions (8 at the finest level: 16-byte entries,
/// so a pixel's k2d = 2 candidates share one cache line; 12 above).
#[derive(Clone, Copy)]
struct Candidate2d<const P: usize> {
    coord: u32,
    /// 16 + the pixel's usage penalty: its distance's scale.
    factor: u16,
    projection: [u8; P],
}

/// A level's [`Candidate2d`] tables, one per distinct (list, projections).
enum Tables2d {
    Short(Vec<Vec<Candidate2d<8>>>),
    Long(Vec<Vec<Candidate2d<12>>>),
}

/// The first candidate of `run` whose scaled distance to `q` is below `best_d`, and then below
/// each one kept: (distance, coordinate) of the last kept.
#[inline(always)]
fn best_2d_of_run<const P: usize>(
    run: &[Candidate2d<P>],
    q: &Projection,
    mut best_d: u32,
) -> Option<(u32, u32)> {
    // Branch-free selection (the comparisons are unpredictable; selects become cmovs).
    let mut best = usize::MAX;
    for (i, c) in run.iter().enumerate() {
        let d = squared_distance::<P>(q, &c.projection) * c.factor as u32;
        let better = d < best_d;
        best_d = if better { d } else { best_d };
        best = if better { i } else { best };
    }
    (best != usize::MAX).then(|| (best_d, run[best].coord))
}

/// A 3D candidate of a pixel of E_a (a triple whose a coordinate is that pixel) with copies of
/// the stored projections of its two other coordinates, E_{a+1}'s and E_{a+2}'s: what scoring
/// it needs besides the pixel's own distance, in one contiguous run per pixel.
/// P bytes per projection: the level's kept dimensions (8 at the finest level, so that its
/// entries are 32 bytes, two to a cache line; 12 above).
#[derive(Clone, Copy)]
struct Candidate3d<const P: usize> {
    triple: [u32; 3],
    /// 16 + the usage penalties of its three pixels: its distance's scale.
    factor: u32,
    next: [u8; P],
    last: [u8; P],
}

/// A level's [`Candidate3d`] tables (see [`Prepared::candidates_3d`]).
enum Tables3d {
    Short(Vec<Vec<Candidate3d<8>>>),
    Long(Vec<Vec<Candidate3d<12>>>),
}

impl Tables3d {
    fn has(&self, set: usize) -> bool {
        match self {
            Tables3d::Short(t) => set < t.len(),
            Tables3d::Long(t) => set < t.len(),
        }
    }
}

/// Largest candidate table (bytes) built for one level; beyond it (large exemplars) the
/// candidates are scored from the level data directly, with the same results. A 256^2 exemplar's
/// tables fit; three 512^2 exemplars' would add ~270 MB.
const MAX_TABLE_BYTES: usize = 32 << 20;

/// Where a voxel's correction reads its neighbours: the state through the brick index
/// ([`Ctx`]), or a [`Window`] copied from it around one brick. Voxels that are not stored read
/// as zero either way.
trait Neighbours {
    fn triple(&self, pos: [i32; 3]) -> [u32; 3];
    /// Value word `w` (of `pixel_words`).
    fn word(&self, pos: [i32; 3], w: usize) -> u32;

    /// Coordinate `a` of the triples of the 3x3 plane through `pos` spanned by axes `ua`
    /// (columns) and `va` (rows), row-major from (-1, -1).
    #[inline(always)]
    fn plane_coords(&self, pos: [i32; 3], ua: usize, va: usize, a: usize) -> [u32; 9] {
        let mut coords = [0u32; 9];
        for (i, c) in coords.iter_mut().enumerate() {
            let mut n = pos;
            n[ua] += i as i32 % 3 - 1;
            n[va] += i as i32 / 3 - 1;
            *c = self.triple(n)[a];
        }
        coords
    }

    /// Value word 0 of the 5x5 plane through `pos` spanned by axes `ua` (columns) and `va`
    /// (rows), row-major from (-2, -2).
    #[inline(always)]
    fn plane_words(&self, pos: [i32; 3], ua: usize, va: usize) -> [u32; 25] {
        let mut words = [0u32; 25];
        for (i, w) in words.iter_mut().enumerate() {
            let mut n = pos;
            n[ua] += i as i32 % 5 - 2;
            n[va] += i as i32 / 5 - 2;
            *w = self.word(n, 0);
        }
        words
    }
}

/// Edge of a [`Window`] along y and z: a brick (4) and the 2 voxels on each side that the
/// projection planes of its voxels reach.
const WINDOW: i32 = 8;
/// Most bricks in one window: a run of bricks consecutive along x shares one window, so the
/// voxels between them are copied once, not once per brick.
const MAX_RUN: i32 = 8;
/// The window's row length (x): the run's bricks and 2 voxels on each side.
const ROW: i32 = 4 * MAX_RUN + 4;
const WINDOW_VOXELS: usize = (WINDOW * WINDOW * ROW) as usize;

/// The triples and value words around a run of bricks along x, copied from the state a row
/// segment at a time: their voxels of a class then read their ~100 neighbours each without a
/// brick-index lookup. Only for one value word per voxel, and periods that are whole bricks.
struct Window {
    origin: [i32; 3],
    values: [u32; WINDOW_VOXELS],
    triples: [[u32; 3]; WINDOW_VOXELS],
}

impl Window {
    fn new() -> Window {
        Window {
            origin: [0; 3],
            values: [0; WINDOW_VOXELS],
            triples: [[0; 3]; WINDOW_VOXELS],
        }
    }

    #[inline(always)]
    fn slot(&self, pos: [i32; 3]) -> usize {
        let d = [0, 1, 2].map(|i| pos[i] - self.origin[i]);
        debug_assert!(
            (0..ROW).contains(&d[0]) && (0..WINDOW).contains(&d[1]) && (0..WINDOW).contains(&d[2]),
            "{pos:?} outside"
        );
        ((d[2] * WINDOW + d[1]) * ROW + d[0]) as usize
    }

    /// Copy from the pass-start state what the corrections of the voxels of class `class` in the `n`
    /// bricks from `b` along x read, a row segment per index lookup (in a brick,
    /// x-consecutive voxels are consecutive in the state). The rest of the window is stale and
    /// never read.
    ///
    /// What is read (window coordinates; a brick's class voxels at c + 2 and c + 4 along each
    /// axis plus 4 per brick along x, c the class): values on the voxels' three planes within
    /// 2, triples within 1. So a row (y, z) is read along x from c_x to c_x + 4 (n - 1) + 6
    /// when y or z is a class coordinate (and the other within reach), only at the voxels'
    /// own x when both are merely within reach (copied from c_x + 2 to c_x + 4 (n - 1) + 4),
    /// else not at all; its triples where the same holds with reach 1.
    fn fill(&mut self, ctx: &Ctx, b: [i32; 3], n: i32, class: [i32; 3]) {
        debug_assert!((1..=MAX_RUN).contains(&n));
        self.origin = b.map(|v| v * 4 - 2);
        // A triple and one value word per voxel.
        const STRIDE: usize = 4;
        debug_assert_eq!(ctx.stride(), STRIDE);
        let on = |v: i32, c: i32| v == c + 2 || v == c + 4;
        let near = |v: i32, c: i32, reach: i32| (c + 2 - reach..=c + 4 + reach).contains(&v);
        let [cx, cy, cz] = class;
        let span = 4 * (n - 1);
        // Debug builds poison the window, so a read of a position not filled shows up as a
        // difference from the shader in the kernels-tests.
        #[cfg(debug_assertions)]
        {
            self.values.fill(0xA5A5_A5A5);
            self.triples.fill([0x0123_4567; 3]);
        }
        for z in 0..WINDOW {
            for y in 0..WINDOW {
                let reads = |reach| {
                    let full =
                        (on(y, cy) && near(z, cz, reach)) || (on(z, cz) && near(y, cy, reach));
                    (full, near(y, cy, reach) && near(z, cz, reach))
                };
                let (full, pair) = reads(2);
                let (full1, pair1) = reads(1);
                let xs = if full {
                    cx..cx + span + 7
                } else if pair {
                    cx + 2..cx + span + 5
                } else {
                    continue;
                };
                let with_triples = full1 || pair1;
                self.copy_row(ctx, y, z, xs, with_triples);
            }
        }
    }

    /// Copy every voxel of the window around the `n` bricks from `b` (all classes' reads) from
    /// the pass-start state: a whole pass's sub-passes then read it ([`correct_pass`]).
    fn fill_all(&mut self, ctx: &Ctx, b: [i32; 3], n: i32) {
        debug_assert!((1..=MAX_RUN).contains(&n));
        self.origin = b.map(|v| v * 4 - 2);
        for z in 0..WINDOW {
            for y in 0..WINDOW {
                self.copy_row(ctx, y, z, 0..4 * n + 4, true);
            }
        }
    }

    /// Copy window row (y, z) over `xs` from the pass-start state, a brick's segment per index
    /// lookup; triples too when asked.
    #[inline(always)]
    fn copy_row(
        &mut self,
        ctx: &Ctx,
        y: i32,
        z: i32,
        xs: std::ops::Range<i32>,
        with_triples: bool,
    ) {
        // A triple and one value word per voxel.
        const STRIDE: usize = 4;
        // Split at the brick edges (window x 2, 6, 10, ...).
        let mut x0 = xs.start;
        while x0 < xs.end {
            let edge = if x0 < 2 { 2 } else { x0 + 4 - (x0 - 2) % 4 };
            let x1 = xs.end.min(edge);
            let row = ((z * WINDOW + y) * ROW + x0) as usize;
            let len = (x1 - x0) as usize;
            let pos = [self.origin[0] + x0, self.origin[1] + y, self.origin[2] + z];
            match ctx.state_index(pos) {
                None => {
                    self.values[row..row + len].fill(0);
                    self.triples[row..row + len].fill([0; 3]);
                }
                Some(s) => {
                    let words = &ctx.pass_start[s * STRIDE..(s + len) * STRIDE];
                    for (i, v) in words.chunks_exact(STRIDE).enumerate() {
                        self.values[row + i] = v[3];
                        if with_triples {
                            self.triples[row + i] = [v[0], v[1], v[2]];
                        }
                    }
                }
            }
            x0 = x1;
        }
    }
}

/// The 64 voxels of one brick in a [`Window`]: values and triples.
struct BrickCopy {
    values: [u32; 64],
    triples: [[u32; 3]; 64],
}

impl BrickCopy {
    fn new() -> BrickCopy {
        BrickCopy {
            values: [0; 64],
            triples: [[0; 3]; 64],
        }
    }
}

impl Window {
    /// Window slot of local voxel `l` (x fastest) of brick `m` of the run.
    #[inline(always)]
    fn brick_slot(m: i32, l: usize) -> usize {
        let (x, y, z) = ((l & 3) as i32, ((l >> 2) & 3) as i32, (l >> 4) as i32);
        (((2 + z) * WINDOW + 2 + y) * ROW + 2 + 4 * m + x) as usize
    }

    /// Put brick `m`'s current voxels (`words`: its 64 state records of 4 words) in place of
    /// their pass-start copies, keeping those in `saved` for [`Window::restore`].
    fn overlay(&mut self, m: i32, words: &[u32], saved: &mut BrickCopy) {
        for (l, v) in words.chunks_exact(4).enumerate() {
            let s = Window::brick_slot(m, l);
            saved.values[l] = self.values[s];
            saved.triples[l] = self.triples[s];
            self.values[s] = v[3];
            self.triples[s] = [v[0], v[1], v[2]];
        }
    }

    /// Undo [`Window::overlay`] of brick `m`: the next brick of the run reads it as the pass began.
    fn restore(&mut self, m: i32, saved: &BrickCopy) {
        for l in 0..64 {
            let s = Window::brick_slot(m, l);
            self.values[s] = saved.values[l];
            self.triples[s] = saved.triples[l];
        }
    }
}

impl Window {
    /// The slot of the corner (-reach, -reach) of the plane through `pos` spanned by axes `ua`
    /// and `va`, and the slot strides along them.
    #[inline(always)]
    fn plane_slots(
        &self,
        pos: [i32; 3],
        ua: usize,
        va: usize,
        reach: i32,
    ) -> (isize, isize, isize) {
        const STRIDES: [isize; 3] = [1, ROW as isize, (WINDOW * ROW) as isize];
        let mut corner = pos;
        corner[ua] -= reach;
        corner[va] -= reach;
        (self.slot(corner) as isize, STRIDES[ua], STRIDES[va])
    }
}

impl Neighbours for Window {
    #[inline(always)]
    fn triple(&self, pos: [i32; 3]) -> [u32; 3] {
        self.triples[self.slot(pos)]
    }

    #[inline(always)]
    fn word(&self, pos: [i32; 3], w: usize) -> u32 {
        debug_assert_eq!(w, 0);
        self.values[self.slot(pos)]
    }

    /// As [`Window::plane_words`].
    #[inline(always)]
    fn plane_coords(&self, pos: [i32; 3], ua: usize, va: usize, a: usize) -> [u32; 9] {
        let (first, su, sv) = self.plane_slots(pos, ua, va, 1);
        let mut coords = [0u32; 9];
        for v in 0..3 {
            let row = first + v as isize * sv;
            for u in 0..3 {
                coords[v * 3 + u] = self.triples[(row + u as isize * su) as usize][a];
            }
        }
        coords
    }

    /// From the corner's slot and the two axes' strides: no position arithmetic per read.
    #[inline(always)]
    fn plane_words(&self, pos: [i32; 3], ua: usize, va: usize) -> [u32; 25] {
        let (first, su, sv) = self.plane_slots(pos, ua, va, 2);
        let mut words = [0u32; 25];
        for v in 0..5 {
            let row = first + v as isize * sv;
            for u in 0..5 {
                words[v * 5 + u] = self.values[(row + u as isize * su) as usize];
            }
        }
        words
    }
}

/// A voxel's reads in a brick-local sub-pass: its own brick from the current state, the rest from
/// `outer` (the pass-start state, through the index or a [`Window`] copied from it).
struct BrickLocal<'r, R: Neighbours> {
    outer: &'r R,
    state: &'r [u32],
    stride: usize,
    /// The own brick's first voxel (position) and state index.
    origin: [i32; 3],
    base: usize,
}

impl<R: Neighbours> BrickLocal<'_, R> {
    /// The state index of `pos` when it lies in the own brick (by position: in a periodic state
    /// the copy of the brick one period away is another brick).
    #[inline(always)]
    fn own(&self, pos: [i32; 3]) -> Option<usize> {
        let d = [0, 1, 2].map(|i| pos[i] - self.origin[i]);
        d.iter()
            .all(|&v| (0..4).contains(&v))
            .then(|| self.base + (d[2] * 16 + d[1] * 4 + d[0]) as usize)
    }
}

impl<R: Neighbours> Neighbours for BrickLocal<'_, R> {
    #[inline(always)]
    fn triple(&self, pos: [i32; 3]) -> [u32; 3] {
        match self.own(pos) {
            Some(s) => {
                let i = s * self.stride;
                [self.state[i], self.state[i + 1], self.state[i + 2]]
            }
            None => self.outer.triple(pos),
        }
    }

    #[inline(always)]
    fn word(&self, pos: [i32; 3], w: usize) -> u32 {
        match self.own(pos) {
            Some(s) => self.state[s * self.stride + 3 + w],
            None => self.outer.word(pos, w),
        }
    }
}

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
        3 + self.p.pixel_words as usize
    }

    #[inline(always)]
    fn state_index(&self, pos: [i32; 3]) -> Option<usize> {
        let pos = match self.p.period {
            0 => pos,
            // (No division for the positions already inside the period: nearly all.)
            n => {
                let n = n as i32;
                let wrap = |v: i32| {
                    if (0..n).contains(&v) {
                        v
                    } else if (-n..0).contains(&v) {
                        v + n
                    } else {
                        v.rem_euclid(n)
                    }
                };
                [wrap(pos[0]), wrap(pos[1]), wrap(pos[2])]
            }
        };
        voxel_index(
            self.bricks,
            pos,
            self.grid_lo,
            self.grid_dims,
            self.p.table_offset,
        )
    }

    /// Projection of the plane of exemplar `a` through voxel `pos`.
    #[inline(always)]
    fn project_plane<const MADD: bool>(
        &self,
        r: &impl Neighbours,
        pos: [i32; 3],
        a: usize,
    ) -> Projection {
        #[cfg(target_arch = "x86_64")]
        if MADD {
            if let Some(pairs) = &self.prepared.pair_weights {
                let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
                let words = r.plane_words(pos, ua, va);
                // SAFETY: MADD is only set on the AVX2 path (`correct_run_avx2`), entered after
                // detecting AVX2.
                let acc = unsafe {
                    if self.p.pca_out as usize <= 8 {
                        project_plane_madd::<1>(&words, &pairs.weights[a], &pairs.means[a])
                    } else {
                        project_plane_madd::<2>(&words, &pairs.weights[a], &pairs.means[a])
                    }
                };
                return self.finish_projection(&acc);
            }
        }
        // Accumulate only the kept dimensions (8 at the finest level, 12 above): the unused
        // weights are zero, so the result is the same; the loop is just shorter. With the
        // channel count a constant too, the compiler unrolls the channels and vectorizes the K
        // multiply-adds (integer sums: same result in any order).
        match (self.p.pca_out, self.p.channels) {
            (0..=8, 3) => self.project_plane_k::<8, 3>(r, pos, a),
            (0..=8, 4) => self.project_plane_k::<8, 4>(r, pos, a),
            (9..=12, 3) => self.project_plane_k::<12, 3>(r, pos, a),
            (9..=12, 4) => self.project_plane_k::<12, 4>(r, pos, a),
            _ => self.project_plane_any(r, pos, a),
        }
    }

    /// [`Ctx::project_plane`] for K kept dimensions and C <= 4 channels (one state word).
    #[inline(always)]
    fn project_plane_k<const K: usize, const C: usize>(
        &self,
        r: &impl Neighbours,
        pos: [i32; 3],
        a: usize,
    ) -> Projection {
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let (wt, mean) = (&self.prepared.weights_t[a], &self.prepared.means[a]);
        let mut acc = [0i32; K];
        let mut i = 0usize;
        for dv in -2..=2 {
            for du in -2..=2 {
                let mut n = pos;
                n[ua] += du;
                n[va] += dv;
                let word = r.word(n, 0);
                for ch in 0..C {
                    let centred = ((word >> (ch * 8)) & 0xFF) as i32 - mean[i];
                    let row: &[i32; K] =
                        wt[i * MAX_PCA_OUT..i * MAX_PCA_OUT + K].try_into().unwrap();
                    for j in 0..K {
                        acc[j] = acc[j].wrapping_add(centred.wrapping_mul(row[j]));
                    }
                    i += 1;
                }
            }
        }
        self.finish_projection(&acc)
    }

    /// [`Ctx::project_plane`] for any channel count.
    fn project_plane_any(&self, r: &impl Neighbours, pos: [i32; 3], a: usize) -> Projection {
        let p = self.p;
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let (wt, mean) = (&self.prepared.weights_t[a], &self.prepared.means[a]);
        let mut acc = [0i32; MAX_PCA_OUT];
        let mut i = 0usize;
        for dv in -2..=2 {
            for du in -2..=2 {
                let mut n = pos;
                n[ua] += du;
                n[va] += dv;
                for ch in 0..p.channels {
                    let byte = (r.word(n, ch as usize / 4) >> ((ch % 4) * 8)) & 0xFF;
                    let centred = byte as i32 - mean[i];
                    let row = &wt[i * MAX_PCA_OUT..(i + 1) * MAX_PCA_OUT];
                    for j in 0..MAX_PCA_OUT {
                        acc[j] = acc[j].wrapping_add(centred.wrapping_mul(row[j]));
                    }
                    i += 1;
                }
            }
        }
        self.finish_projection(&acc)
    }

    /// Rounds, shifts and clamps the accumulated projection to bytes (as the shader does).
    #[inline(always)]
    fn finish_projection(&self, acc: &[i32]) -> Projection {
        let p = self.p;
        let round = 1i32 << (p.shift - 1);
        let mut q = [0i16; MAX_PCA_OUT];
        for (j, &a) in acc.iter().enumerate().take(p.pca_out as usize) {
            q[j] = ((a.wrapping_add(round) >> p.shift) + 128).clamp(0, 255) as i16;
        }
        q
    }

    /// Squared distance between a plane projection and E_a's stored projection at pixel `c`.
    #[inline(always)]
    fn distance(&self, q: &Projection, a: usize, c: u32) -> u32 {
        let p = self.p;
        let (x, y) = coord(c);
        let base = ([p.proj0, p.proj1, p.proj2][a]
            + (y as u32 * p.ex_width + x as u32) * p.proj_words) as usize
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
                if p.border != 0
                    && (sx < 0 || sy < 0 || sx >= p.ex_width as i32 || sy >= p.ex_height as i32)
                {
                    continue;
                }
                let src = pack_resolved(sx, sy, p.ex_width, p.ex_height, p.border);
                if seen[..seen_count].contains(&src) {
                    continue;
                }
                seen[seen_count] = src;
                seen_count += 1;
                if let Some(table) = self.prepared.candidates_2d_of[a] {
                    let (px, py) = coord(src);
                    let at = (py as u32 * p.ex_width + px as u32) as usize * p.k2d as usize;
                    match &self.prepared.candidates_2d {
                        Tables2d::Short(t) => prefetch_lines(&t[table][at..], 1),
                        Tables2d::Long(t) => prefetch_lines(&t[table][at..], 1),
                    }
                }
            }
        }
        for &src in &seen[..seen_count] {
            let (px, py) = coord(src);
            let pixel = py as u32 * p.ex_width + px as u32;
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
        let at = (y as u32 * p.ex_width + x as u32) as usize * p.k3d_used as usize;
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
            let pixel = y as u32 * p.ex_width + x as u32;
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
            p.pixel_words == 1 && p.period % 4 == 0 && (n > 1 || self.mask(i).count_ones() >= 3);
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

/// PCA weights laid out for [`project_plane_madd`]: per neighbourhood pixel (25), per channel
/// pair (0-1, 2-3), per block of 8 outputs (BLOCKS of 2), 16 i16 weights interleaved as
/// (channel 2q, output j), (channel 2q + 1, output j) for the block's 8 outputs j. Channels past
/// the exemplar's (3 colours without a feature channel) get zero weights and means.
struct PairWeights {
    weights: [Vec<i16>; 3],
    /// Per pixel, the 4 channels' means.
    means: [Vec<i16>; 3],
}

const PAIR_WEIGHTS_PER_PIXEL: usize = 2 * 2 * 16;

impl PairWeights {
    /// For one state word per voxel (3 or 4 channels), 25-pixel neighbourhoods, at most 16
    /// outputs, and weights that fit 16 bits (every analysis since revision 2); else None.
    fn new(p: &CorrectParams, level: &[u32]) -> Option<PairWeights> {
        let channels = p.channels as usize;
        let (d, k) = (p.pca_in as usize, p.pca_out as usize);
        if !(3..=4).contains(&channels) || d != 25 * channels || k > 16 || p.pixel_words != 1 {
            return None;
        }
        let layout = |a: usize| -> Option<(Vec<i16>, Vec<i16>)> {
            let (w0, m0) = (
                [p.weights0, p.weights1, p.weights2][a] as usize,
                [p.mean0, p.mean1, p.mean2][a] as usize,
            );
            let mut weights = vec![0i16; 25 * PAIR_WEIGHTS_PER_PIXEL];
            let mut means = vec![0i16; 25 * 4];
            for pixel in 0..25 {
                for ch in 0..channels {
                    let input = pixel * channels + ch;
                    means[pixel * 4 + ch] = i16::try_from(level[m0 + input] as i32).ok()?;
                    let (pair, lane) = (ch / 2, ch % 2);
                    for j in 0..k {
                        let w = i16::try_from(level[w0 + j * d + input] as i32).ok()?;
                        let slot = pixel * PAIR_WEIGHTS_PER_PIXEL + (pair * 2 + j / 8) * 16;
                        weights[slot + (j % 8) * 2 + lane] = w;
                    }
                }
            }
            Some((weights, means))
        };
        let (w0, m0) = layout(0)?;
        let (w1, m1) = layout(1)?;
        let (w2, m2) = layout(2)?;
        Some(PairWeights {
            weights: [w0, w1, w2],
            means: [m0, m1, m2],
        })
    }
}

/// The accumulators of one plane's projection (before [`Ctx::finish_projection`]) from its 25
/// state words, with 16-bit multiply-adds: each 32-bit lane adds the products of two channels,
/// so a pixel's 4 channels take 2 (BLOCKS = 1: 8 outputs) or 4 (16 outputs) instructions. The
/// products are exact (|value - mean| <= 255, |weight| < 2^15) and the i32 sums wrap as the
/// scalar loop's do, so the results are the same bit for bit.
///
/// # Safety
/// The CPU must support AVX2; `weights` and `means` come from [`PairWeights`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn project_plane_madd<const BLOCKS: usize>(
    words: &[u32; 25],
    weights: &[i16],
    means: &[i16],
) -> [i32; 16] {
    use std::arch::x86_64::*;
    assert!(weights.len() >= 25 * PAIR_WEIGHTS_PER_PIXEL && means.len() >= 25 * 4);
    let mut acc = [_mm256_setzero_si256(); 2];
    for (pixel, &word) in words.iter().enumerate() {
        // SAFETY (all loads): in bounds by the assertion above; unaligned loads.
        let values = _mm_cvtepu8_epi16(_mm_cvtsi32_si128(word as i32));
        let mean = unsafe { _mm_loadl_epi64(means.as_ptr().add(pixel * 4) as *const __m128i) };
        let centred = _mm_sub_epi16(values, mean);
        let pairs = [
            _mm256_broadcastd_epi32(centred),
            _mm256_broadcastd_epi32(_mm_srli_si128::<4>(centred)),
        ];
        let w = unsafe { weights.as_ptr().add(pixel * PAIR_WEIGHTS_PER_PIXEL) };
        for (pair, &values) in pairs.iter().enumerate() {
            for (block, acc) in acc.iter_mut().enumerate().take(BLOCKS) {
                let row =
                    unsafe { _mm256_loadu_si256(w.add((pair * 2 + block) * 16) as *const __m256i) };
                *acc = _mm256_add_epi32(*acc, _mm256_madd_epi16(values, row));
            }
        }
    }
    let mut out = [0i32; 16];
    // SAFETY: out holds 16 i32 = two 256-bit stores.
    unsafe {
        _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, acc[0]);
        _mm256_storeu_si256(out.as_mut_ptr().add(8) as *mut __m256i, acc[1]);
    }
    out
}

/// The first candidate of `run` whose scaled distance (`own` plus its two other planes') is
/// below `best_d`, and then below each one kept: (distance, triple) of the last kept.
#[inline(always)]
fn best_of_run<const P: usize>(
    run: &[Candidate3d<P>],
    qb: &Projection,
    qc: &Projection,
    own: u32,
    mut best_d: u32,
) -> Option<(u32, [u32; 3])> {
    // Branch-free selection, as in [`best_2d_of_run`].
    let mut best = usize::MAX;
    for (i, e) in run.iter().enumerate() {
        let d = (own + squared_distance::<P>(qb, &e.next) + squared_distance::<P>(qc, &e.last))
            * e.factor;
        let better = d < best_d;
        best_d = if better { d } else { best_d };
        best = if better { i } else { best };
    }
    (best != usize::MAX).then(|| (best_d, run[best].triple))
}

/// Ask the cache for the first `lines` 64-byte lines of `run` (no more than it holds): a hint
/// with no effect on results.
#[inline(always)]
fn prefetch_lines<T>(run: &[T], lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let bytes = std::mem::size_of_val(run);
        let start = run.as_ptr() as *const i8;
        for line in 0..lines.min(bytes.div_ceil(64)) {
            // SAFETY: a prefetch never faults, and the address is inside `run` anyway.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(line * 64)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (run, lines);
}

/// Sum of squared differences of the first K projection bytes (|difference| <= 255).
#[inline(always)]
fn squared_distance<const K: usize>(q: &Projection, stored: &[u8]) -> u32 {
    let stored: &[u8; K] = stored.try_into().unwrap();
    let mut d = 0i32;
    for j in 0..K {
        let diff = q[j] - stored[j] as i16;
        d += diff as i32 * diff as i32;
    }
    d as u32
}

/// A sub-pass's results: (state voxel index, new triple), kept in the parts the workers produced
/// (a sub-pass of a large box updates tens of millions of voxels: no concatenating copy).
pub struct Updates(Vec<Vec<(u32, [u32; 3])>>);

impl Updates {
    pub fn len(&self) -> usize {
        self.0.iter().map(Vec::len).sum()
    }

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
    let pixels = [p.pixels0, p.pixels1, p.pixels2][a];
    let table = pixels + p.ex_width * p.ex_height * p.pixel_words;
    level[(table + y as u32 * p.ex_width + x as u32) as usize]
}

/// Run one sub-pass: returns (state index, new triple) for every voxel of the class in the
/// bricks of the list in `p`. `pass_start`: the state when its pass began (the same words as
/// `state` in the pass's first sub-pass).
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

/// What a correction derives from a level's data alone: the PCA weights transposed, the means,
/// and the 2D candidate tables. The same for every sub-pass of a level, so an executor builds
/// it once per level ([`correct_prepared`]).
pub struct Prepared {
    /// The parameters it was built from (the level-data offsets and sizes it depends on).
    key: [u32; 29],
    /// Per exemplar: the PCA weights transposed to input-major (input_dims x MAX_PCA_OUT, zero
    /// padded) and the mean, so the inner loop is contiguous. Integer sums do not depend on the
    /// order of accumulation, so the results equal the shader's bit for bit.
    weights_t: [Vec<i32>; 3],
    means: [Vec<i32>; 3],
    /// The same weights for the AVX2 path's 16-bit multiply-adds, when they fit.
    pair_weights: Option<PairWeights>,
    /// Per exemplar, an index into `candidates_2d` (exemplars sharing their lists share a table),
    /// or None when the projections are too long for [`Candidate2d`] or the tables too large.
    candidates_2d_of: [Option<usize>; 3],
    /// `k2d` [`Candidate2d`] per exemplar pixel, row-major.
    candidates_2d: Tables2d,
    /// Per candidate set (one when shared), `k3d_used` [`Candidate3d`] per pixel (slots past
    /// the pixel's count unused); empty when the projections are too long, or a shared set's
    /// exemplars do not share their projections.
    candidates_3d: Tables3d,
}

impl Prepared {
    fn key(p: &CorrectParams) -> [u32; 29] {
        [
            p.weights0,
            p.weights1,
            p.weights2,
            p.mean0,
            p.mean1,
            p.mean2,
            p.cand2d0,
            p.cand2d1,
            p.cand2d2,
            p.proj0,
            p.proj1,
            p.proj2,
            p.pca_in,
            p.pca_out,
            p.k2d,
            p.ex_width,
            p.ex_height,
            p.proj_words,
            p.counts0,
            p.counts1,
            p.counts2,
            p.cand3d0,
            p.cand3d1,
            p.cand3d2,
            p.k3d_used ^ (p.k3d_stride << 8) ^ (p.shared_sets << 16),
            // The penalties follow the pixels (the candidate tables hold them).
            p.pixels0,
            p.pixels1,
            p.pixels2,
            p.pixel_words,
        ]
    }

    /// The [`Candidate3d`] tables (see the field).
    fn candidates_3d<const P: usize>(p: &CorrectParams, level: &[u32]) -> Vec<Vec<Candidate3d<P>>> {
        let k = p.pca_out as usize;
        let proj = [p.proj0, p.proj1, p.proj2];
        let sets = if p.shared_sets != 0 { 1 } else { 3 };
        let bytes = sets
            * (p.ex_width * p.ex_height * p.k3d_used) as usize
            * std::mem::size_of::<Candidate3d<P>>();
        if k != P
            || bytes > MAX_TABLE_BYTES
            || (p.shared_sets != 0 && (proj[1] != proj[0] || proj[2] != proj[0]))
        {
            return Vec::new();
        }
        let level_bytes: &[u8] = bytemuck::cast_slice(level);
        let projection = |e: usize, c: u32| {
            let (x, y) = coord(c);
            let base = (proj[e] + (y as u32 * p.ex_width + x as u32) * p.proj_words) as usize * 4;
            let mut out = [0u8; P];
            out[..k].copy_from_slice(&level_bytes[base..base + k]);
            out
        };
        let used = p.k3d_used as usize;
        (0..sets)
            .map(|set| {
                let counts = [p.counts0, p.counts1, p.counts2][set] as usize;
                let list = [p.cand3d0, p.cand3d1, p.cand3d2][set] as usize;
                let (next, last) = ((set + 1) % 3, (set + 2) % 3);
                (0..(p.ex_width * p.ex_height) as usize)
                    .into_par_iter()
                    .flat_map_iter(|pixel| {
                        let count = (level[counts + pixel] as usize).min(used);
                        (0..used).map(move |j| {
                            if j >= count {
                                return Candidate3d {
                                    triple: [0; 3],
                                    factor: 0,
                                    next: [0; P],
                                    last: [0; P],
                                };
                            }
                            let e = list + (pixel * p.k3d_stride as usize + j) * 3;
                            let triple = [level[e], level[e + 1], level[e + 2]];
                            Candidate3d {
                                triple,
                                factor: 16
                                    + (0..3).map(|e| penalty(p, level, e, triple[e])).sum::<u32>(),
                                next: projection(next, triple[next]),
                                last: projection(last, triple[last]),
                            }
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// The [`Candidate2d`] tables (see the fields), empty when the projections are not P long
    /// or the tables too large.
    #[allow(clippy::type_complexity)]
    fn candidates_2d<const P: usize>(
        p: &CorrectParams,
        level: &[u32],
    ) -> ([Option<usize>; 3], Vec<Vec<Candidate2d<P>>>) {
        let level_bytes: &[u8] = bytemuck::cast_slice(level);
        let mut candidates_2d: Vec<Vec<Candidate2d<P>>> = Vec::new();
        let mut candidates_2d_of = [None; 3];
        let mut built: Vec<(u32, u32, u32)> = Vec::new();
        let k = p.pca_out as usize;
        let table_bytes =
            (p.ex_width * p.ex_height * p.k2d) as usize * std::mem::size_of::<Candidate2d<P>>();
        if k == P && 3 * table_bytes <= MAX_TABLE_BYTES {
            for a in 0..3 {
                let (list, proj) = (
                    [p.cand2d0, p.cand2d1, p.cand2d2][a],
                    [p.proj0, p.proj1, p.proj2][a],
                );
                let pixels = [p.pixels0, p.pixels1, p.pixels2][a];
                if let Some(i) = built.iter().position(|&b| b == (list, proj, pixels)) {
                    candidates_2d_of[a] = Some(i);
                    continue;
                }
                let n = (p.ex_width * p.ex_height * p.k2d) as usize;
                let table = level[list as usize..list as usize + n]
                    .par_iter()
                    .map(|&c| {
                        let (x, y) = coord(c);
                        let base =
                            (proj + (y as u32 * p.ex_width + x as u32) * p.proj_words) as usize * 4;
                        let mut projection = [0u8; P];
                        projection[..k].copy_from_slice(&level_bytes[base..base + k]);
                        Candidate2d {
                            coord: c,
                            factor: (16 + penalty(p, level, a, c)) as u16,
                            projection,
                        }
                    })
                    .collect();
                candidates_2d_of[a] = Some(candidates_2d.len());
                candidates_2d.push(table);
                built.push((list, proj, pixels));
            }
        }
        (candidates_2d_of, candidates_2d)
    }

    pub fn new(p: &CorrectParams, level: &[u32]) -> Prepared {
        let transpose = |a: usize| {
            let (w0, m0) = (
                [p.weights0, p.weights1, p.weights2][a] as usize,
                [p.mean0, p.mean1, p.mean2][a] as usize,
            );
            let (d, k) = (p.pca_in as usize, p.pca_out as usize);
            let mut t = vec![0i32; d * MAX_PCA_OUT];
            for i in 0..d {
                for j in 0..k {
                    t[i * MAX_PCA_OUT + j] = level[w0 + j * d + i] as i32;
                }
            }
            (
                t,
                level[m0..m0 + d]
                    .iter()
                    .map(|&m| m as i32)
                    .collect::<Vec<i32>>(),
            )
        };
        let (t0, m0) = transpose(0);
        let (t1, m1) = transpose(1);
        let (t2, m2) = transpose(2);
        let (candidates_2d_of, candidates_2d) = match p.pca_out {
            8 => {
                let (of, t) = Self::candidates_2d::<8>(p, level);
                (of, Tables2d::Short(t))
            }
            _ => {
                let (of, t) = Self::candidates_2d::<12>(p, level);
                (of, Tables2d::Long(t))
            }
        };
        Prepared {
            key: Self::key(p),
            weights_t: [t0, t1, t2],
            means: [m0, m1, m2],
            pair_weights: PairWeights::new(p, level),
            candidates_2d_of,
            candidates_2d,
            candidates_3d: match p.pca_out {
                8 => Tables3d::Short(Self::candidates_3d::<8>(p, level)),
                _ => Tables3d::Long(Self::candidates_3d::<12>(p, level)),
            },
        }
    }

    /// Without the candidate tables: every candidate scored from the level data directly, as
    /// for exemplars too large for the tables (the same results; tests compare the two).
    pub fn without_tables(mut self) -> Prepared {
        self.candidates_2d_of = [None; 3];
        self.candidates_2d = Tables2d::Short(Vec::new());
        self.candidates_3d = Tables3d::Short(Vec::new());
        self
    }

    /// Whether it was built for a level laid out as `p` says.
    pub fn fits(&self, p: &CorrectParams) -> bool {
        self.key == Self::key(p)
    }
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
        state.len() / (3 + p.pixel_words as usize) <= u32::MAX as usize,
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

/// The list's entries with a class voxel to correct, as runs (first entry, count) of up to
/// [`MAX_RUN`] bricks consecutive along x, in list order.
fn runs_of(ctx: &Ctx) -> Vec<(u32, u32)> {
    let p = ctx.p;
    let mut runs: Vec<(u32, u32)> = Vec::new();
    let mut i = 0;
    while i < p.list_count {
        if ctx.mask(i) == 0 {
            i += 1;
            continue;
        }
        let first = brick_at(ctx.bricks, p.list_offset, i);
        let mut n = 1;
        while n < MAX_RUN as u32
            && i + n < p.list_count
            && ctx.mask(i + n) != 0
            && brick_at(ctx.bricks, p.list_offset, i + n)
                == [first[0] + n as i32, first[1], first[2]]
        {
            n += 1;
        }
        runs.push((i, n));
        i += n;
    }
    runs
}

/// `f` over `runs` in parallel, each thread with a window of its own; the outputs of each
/// thread's share, in order.
fn in_parallel<T: Send>(
    runs: &[(u32, u32)],
    f: impl Fn(&mut Window, u32, u32, &mut Vec<T>) + Sync,
) -> Vec<Vec<T>> {
    runs.par_iter()
        .fold(
            || (Box::new(Window::new()), Vec::new()),
            |(mut window, mut out), &(i, n)| {
                f(&mut window, i, n, &mut out);
                (window, out)
            },
        )
        .map(|(_, out)| out)
        .collect()
}

/// [`runs_of`] `ctx`'s list, `f` over them in parallel ([`in_parallel`]).
fn over_runs<T: Send>(
    ctx: &Ctx,
    f: impl Fn(&mut Window, u32, u32, &mut Vec<T>) + Sync,
) -> Vec<Vec<T>> {
    in_parallel(&runs_of(ctx), f)
}

/// One correction pass: its sub-passes `ps` in order, each [`correct_prepared`] of the state
/// as the earlier ones left it, with `pass_start` (overwritten) the state as the pass began.
/// When every sub-pass lists the same whole bricks (the planner's passes do) and voxels hold
/// one value word, brick by brick instead: a brick's eight sub-passes read one window copied
/// from the pass-start state, with the brick's own voxels updated in it as they go (the same
/// results: a brick's sub-passes see only its own voxels' updates), so a pass copies each
/// window once instead of once per sub-pass. That path needs no pass-start copy either
/// ([`whole_brick_pass_in_place`]); `pass_start` is then left empty.
pub fn correct_pass(
    prepared: &Prepared,
    ps: &[CorrectParams],
    level: &[u32],
    state: &mut [u32],
    pass_start: &mut Vec<u32>,
    bricks: &[u32],
) {
    if whole_brick_pass(ps, bricks) {
        assert!(prepared.fits(&ps[0]), "prepared for another level layout");
        pass_start.clear();
        pass_start.shrink_to_fit();
        whole_brick_pass_in_place(prepared, ps, level, state, bricks);
        return;
    }
    pass_start.clear();
    pass_start.extend_from_slice(state);
    for p in ps {
        let updates = correct_prepared(prepared, p, level, state, pass_start, bricks);
        apply(p, level, state, &updates);
    }
}

/// A whole-brick pass without a copy of the state: bricks are corrected a block of z layers of
/// bricks at a time (the block's runs in parallel), and a block's results are held back until
/// the next block is done. A voxel's reads reach 2 voxels, so the bricks of a layer read the
/// layers beside it only: when a block is corrected, it and the block before it still hold
/// their pass-start values in `state` (their results are held), and the block before can then
/// be written, no block left to read it. A periodic state's first block is read by its last
/// (the wrap), so its results wait for the end. Memory: two blocks' results instead of two
/// whole states. A block is one layer, or as many as it takes to give every thread a few runs
/// (a thin shell's groups have few bricks per layer, and each block ends with a wait).
fn whole_brick_pass_in_place(
    prepared: &Prepared,
    ps: &[CorrectParams],
    level: &[u32],
    state: &mut [u32],
    bricks: &[u32],
) {
    // The runs, by z layer of bricks (ascending; list order within a layer).
    let mut layers: std::collections::BTreeMap<i32, Vec<(u32, u32)>> = Default::default();
    {
        let ctxs = sub_pass_contexts(prepared, ps, level, state, bricks);
        for (i, n) in runs_of(&ctxs[0]) {
            let z = brick_at(bricks, ps[0].list_offset, i)[2];
            layers.entry(z).or_default().push((i, n));
        }
    }
    let min_runs = 8 * rayon::current_num_threads();
    let mut blocks: Vec<Vec<(u32, u32)>> = Vec::new();
    for runs in layers.into_values() {
        match blocks.last_mut() {
            Some(block) if block.len() < min_runs => block.extend(runs),
            _ => blocks.push(runs),
        }
    }
    let periodic = ps[0].period != 0;
    type Results = Vec<Vec<(usize, [u32; 256])>>;
    let mut previous: Option<Results> = None;
    let mut first: Option<Results> = None;
    for (k, runs) in blocks.iter().enumerate() {
        let results = {
            let ctxs = sub_pass_contexts(prepared, ps, level, state, bricks);
            in_parallel(runs, |window, i, n, out| {
                fused_run_dispatch(&ctxs, window, i, n, out)
            })
        };
        // The block below has no reader left.
        if let Some(below) = previous.take() {
            write_bricks(state, &below);
        }
        if periodic && k == 0 {
            first = Some(results);
        } else {
            previous = Some(results);
        }
    }
    for results in [previous, first].into_iter().flatten() {
        write_bricks(state, &results);
    }
}

/// The sub-passes' contexts, reading the state `state` (also as the pass-start state).
fn sub_pass_contexts<'a>(
    prepared: &'a Prepared,
    ps: &'a [CorrectParams],
    level: &'a [u32],
    state: &'a [u32],
    bricks: &'a [u32],
) -> Vec<Ctx<'a>> {
    ps.iter()
        .map(|p| Ctx {
            p,
            level,
            level_bytes: bytemuck::cast_slice(level),
            prepared,
            state,
            pass_start: state,
            bricks,
            grid_lo: [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z],
            grid_dims: [p.grid_x, p.grid_y, p.grid_z],
        })
        .collect()
}

/// Write corrected bricks (their first state index and 64 voxels' words) into the state.
fn write_bricks(state: &mut [u32], results: &[Vec<(usize, [u32; 256])>]) {
    for (base, words) in results.iter().flatten() {
        state[base * 4..(base + 64) * 4].copy_from_slice(words);
    }
}

/// Whether the sub-passes of a pass all list the same bricks, each whole (mask 0xFF) or not at
/// all, each class once, with one value word per voxel and whole-brick periods: what the
/// brick-by-brick pass needs.
pub(crate) fn whole_brick_pass(ps: &[CorrectParams], bricks: &[u32]) -> bool {
    let Some(p0) = ps.first() else { return false };
    let mut classes = 0u32;
    for p in ps {
        classes |= 1 << (p.class_x | p.class_y << 1 | p.class_z << 2);
    }
    let mask = |p: &CorrectParams, i: u32| {
        (bricks[(p.mask_offset + i / 4) as usize] >> ((i % 4) * 8)) & 0xFF
    };
    classes.count_ones() as usize == ps.len()
        && ps.iter().all(|p| {
            p.pixel_words == 1
                && p.period % 4 == 0
                && p.list_count == p0.list_count
                && (0..p.list_count).all(|i| {
                    let m = mask(p, i);
                    (m == 0 || m == 0xFF)
                        && m == mask(p0, i)
                        && brick_at(bricks, p.list_offset, i) == brick_at(bricks, p0.list_offset, i)
                })
        })
}

/// [`fused_run`], with AVX2 when the CPU has it (as [`Ctx::correct_run_dispatch`]).
fn fused_run_dispatch(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { fused_run_avx2(ctxs, window, i, n, out) };
    }
    fused_run::<false>(ctxs, window, i, n, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn fused_run_avx2(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    fused_run::<true>(ctxs, window, i, n, out)
}

/// A pass over the run of `n` bricks from list entry `i`: per brick, its sub-passes in order
/// on the window, then its 64 voxels (state records) appended to `out` with their first index.
#[inline(always)]
fn fused_run<const MADD: bool>(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    let first_ctx = &ctxs[0];
    let p0 = first_ctx.p;
    let first = brick_at(first_ctx.bricks, p0.list_offset, i);
    window.fill_all(first_ctx, first, n as i32);
    let pixels = [p0.pixels0, p0.pixels1, p0.pixels2];
    let mut saved = BrickCopy::new();
    for m in 0..n as i32 {
        let b = [first[0] + m, first[1], first[2]];
        let base = first_ctx
            .state_index(b.map(|v| v * 4))
            .expect("active bricks are stored");
        // The brick's pass-start voxels, for the next bricks' reads.
        for l in 0..64 {
            let s = Window::brick_slot(m, l);
            saved.values[l] = window.values[s];
            saved.triples[l] = window.triples[s];
        }
        for ctx in ctxs {
            let p = ctx.p;
            let class = [p.class_x as i32, p.class_y as i32, p.class_z as i32];
            // A sub-pass's voxels read each other's values from before it: all eight first.
            let mut found = [(0usize, [0u32; 3]); 8];
            for (k, f) in found.iter_mut().enumerate() {
                let local = [
                    class[0] + 2 * (k as i32 & 1),
                    class[1] + 2 * ((k as i32 >> 1) & 1),
                    class[2] + 2 * (k as i32 >> 2),
                ];
                let pos = [0, 1, 2].map(|a| b[a] * 4 + local[a]);
                let l = (local[2] * 16 + local[1] * 4 + local[0]) as usize;
                *f = (l, ctx.correct_voxel::<MADD>(&*window, pos));
            }
            for (l, t) in found {
                let s = Window::brick_slot(m, l);
                let mut record = [0u32; 4];
                write_voxel(&mut record, ctx.level, t, pixels, p.ex_width, 1, p.channels);
                window.triples[s] = t;
                window.values[s] = record[3];
            }
        }
        let mut words = [0u32; 256];
        for (l, w) in words.chunks_exact_mut(4).enumerate() {
            let s = Window::brick_slot(m, l);
            let t = window.triples[s];
            w.copy_from_slice(&[t[0], t[1], t[2], window.values[s]]);
            window.values[s] = saved.values[l];
            window.triples[s] = saved.triples[l];
        }
        out.push((base, words));
    }
}

/// Apply a sub-pass's results to the state: each voxel's new triple and its value.
pub fn apply(p: &CorrectParams, level: &[u32], state: &mut [u32], updates: &Updates) {
    let stride = 3 + p.pixel_words as usize;
    let pixels = [p.pixels0, p.pixels1, p.pixels2];
    for (i, t) in updates.iter() {
        write_voxel(
            &mut state[i * stride..(i + 1) * stride],
            level,
            t,
            pixels,
            p.ex_width,
            p.pixel_words,
            p.channels,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 16-bit multiply-add projection equals the scalar i32 sums, extreme values included.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn madd_projection_equals_the_scalar_sums() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut seed = 0x9E37_79B9u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for (channels, outputs) in [(3usize, 8usize), (4, 8), (3, 12), (4, 12), (4, 16)] {
            for round in 0..50 {
                let d = 25 * channels;
                // Row-major outputs x inputs, as the level data stores them; extremes first.
                let weights: Vec<i32> = (0..outputs * d)
                    .map(|i| match (round, i % 3) {
                        (0, _) => 32767,
                        (1, _) => -32768,
                        _ => (next() % 65536) as i32 - 32768,
                    })
                    .collect();
                let means: Vec<i32> = (0..d)
                    .map(|_| {
                        if round < 2 {
                            255
                        } else {
                            (next() % 256) as i32
                        }
                    })
                    .collect();
                let words: [u32; 25] = std::array::from_fn(|_| if round < 2 { 0 } else { next() });
                let mut level = Vec::new();
                level.extend(weights.iter().map(|&w| w as u32));
                level.extend(means.iter().map(|&m| m as u32));
                let p = CorrectParams {
                    channels: channels as u32,
                    pixel_words: 1,
                    pca_in: d as u32,
                    pca_out: outputs as u32,
                    weights0: 0,
                    weights1: 0,
                    weights2: 0,
                    mean0: (outputs * d) as u32,
                    mean1: (outputs * d) as u32,
                    mean2: (outputs * d) as u32,
                    ..Default::default()
                };
                let pairs = PairWeights::new(&p, &level).expect("16-bit weights");
                if round == 2 {
                    // A weight beyond 16 bits (an analysis older than revision 2) keeps the
                    // scalar path.
                    let mut wide = level.clone();
                    wide[d + 1] = 40_000;
                    assert!(PairWeights::new(&p, &wide).is_none());
                }
                // SAFETY: AVX2 detected above.
                let got = unsafe {
                    if outputs <= 8 {
                        project_plane_madd::<1>(&words, &pairs.weights[0], &pairs.means[0])
                    } else {
                        project_plane_madd::<2>(&words, &pairs.weights[0], &pairs.means[0])
                    }
                };
                for j in 0..outputs {
                    let mut want = 0i32;
                    for (pixel, &word) in words.iter().enumerate() {
                        for ch in 0..channels {
                            let i = pixel * channels + ch;
                            let value = ((word >> (ch * 8)) & 0xFF) as i32;
                            want = want
                                .wrapping_add((value - means[i]).wrapping_mul(weights[j * d + i]));
                        }
                    }
                    assert_eq!(
                        got[j], want,
                        "{channels} channels, {outputs} outputs, round {round}, output {j}"
                    );
                }
            }
        }
    }
}
