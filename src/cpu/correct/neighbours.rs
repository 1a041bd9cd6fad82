//! Where a voxel's correction reads its neighbours: the [`Neighbours`] reads, a [`Window`] copied
//! from the state around a run of bricks, and [`BrickLocal`] (a voxel's own brick from the
//! current state, the rest as the pass began).

use super::*;

/// Where a voxel's correction reads its neighbours: the state through the brick index
/// ([`Ctx`]), or a [`Window`] copied from it around one brick. Voxels that are not stored read
/// as zero either way.
pub(super) trait Neighbours {
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
pub(super) const WINDOW: i32 = 8;
/// Most bricks in one window: a run of bricks consecutive along x shares one window, so the
/// voxels between them are copied once, not once per brick.
pub(super) const MAX_RUN: i32 = 8;
/// The window's row length (x): the run's bricks and 2 voxels on each side.
pub(super) const ROW: i32 = 4 * MAX_RUN + 4;
pub(super) const WINDOW_VOXELS: usize = (WINDOW * WINDOW * ROW) as usize;

/// The triples and value words around a run of bricks along x, copied from the state a row
/// segment at a time: their voxels of a class then read their ~100 neighbours each without a
/// brick-index lookup. Only for one value word per voxel, and periods that are whole bricks.
pub(super) struct Window {
    pub(super) origin: [i32; 3],
    pub(super) values: [u32; WINDOW_VOXELS],
    pub(super) triples: [[u32; 3]; WINDOW_VOXELS],
}

impl Window {
    pub(super) fn new() -> Window {
        Window {
            origin: [0; 3],
            values: [0; WINDOW_VOXELS],
            triples: [[0; 3]; WINDOW_VOXELS],
        }
    }

    #[inline(always)]
    pub(super) fn slot(&self, pos: [i32; 3]) -> usize {
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
    pub(super) fn fill(&mut self, ctx: &Ctx, b: [i32; 3], n: i32, class: [i32; 3]) {
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
    pub(super) fn fill_all(&mut self, ctx: &Ctx, b: [i32; 3], n: i32) {
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
    pub(super) fn copy_row(
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
pub(super) struct BrickCopy {
    pub(super) values: [u32; 64],
    pub(super) triples: [[u32; 3]; 64],
}

impl BrickCopy {
    pub(super) fn new() -> BrickCopy {
        BrickCopy {
            values: [0; 64],
            triples: [[0; 3]; 64],
        }
    }
}

impl Window {
    /// Window slot of local voxel `l` (x fastest) of brick `m` of the run.
    #[inline(always)]
    pub(super) fn brick_slot(m: i32, l: usize) -> usize {
        let (x, y, z) = ((l & 3) as i32, ((l >> 2) & 3) as i32, (l >> 4) as i32);
        (((2 + z) * WINDOW + 2 + y) * ROW + 2 + 4 * m + x) as usize
    }

    /// Put brick `m`'s current voxels (`words`: its 64 state records of 4 words) in place of
    /// their pass-start copies, keeping those in `saved` for [`Window::restore`].
    pub(super) fn overlay(&mut self, m: i32, words: &[u32], saved: &mut BrickCopy) {
        for (l, v) in words.chunks_exact(4).enumerate() {
            let s = Window::brick_slot(m, l);
            saved.values[l] = self.values[s];
            saved.triples[l] = self.triples[s];
            self.values[s] = v[3];
            self.triples[s] = [v[0], v[1], v[2]];
        }
    }

    /// Undo [`Window::overlay`] of brick `m`: the next brick of the run reads it as the pass began.
    pub(super) fn restore(&mut self, m: i32, saved: &BrickCopy) {
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
    pub(super) fn plane_slots(
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
pub(super) struct BrickLocal<'r, R: Neighbours> {
    pub(super) outer: &'r R,
    pub(super) state: &'r [u32],
    pub(super) stride: usize,
    /// The own brick's first voxel (position) and state index.
    pub(super) origin: [i32; 3],
    pub(super) base: usize,
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
