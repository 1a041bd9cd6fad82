//! Sparse storage and planning of a synthesis in bricks of 4x4x4 voxels (paper 5.2: synthesize
//! only the voxels a request depends on, with storage proportional to them).
//!
//! A level's state is a list of bricks (its slots, sorted z, y, x), 64 voxels each, and a dense
//! table over their bounding box mapping a brick to its slot. Planning runs backwards from the
//! requested finest bricks: a level must deliver some bricks; each correction sub-pass computes
//! the bricks the plan of one brick (`plan::plan` of the box [0, 4)^3, translated) says it must,
//! and the level stores everything any of them reads. Bricks are aligned to multiples of 4, so
//! every translation keeps the parity classes, and the union of per-brick plans is a valid plan
//! of the union (dependencies only grow under union). The parent level delivers the parents of
//! the child's stored bricks.
//!
//! Kernels compute every voxel of their class in an active brick; voxels the plan does not need
//! may read absent neighbours (which read as zero), but nothing needed ever reads them.
//!
//! Length: about 670 lines (brick storage and the sparse, box, voxel-box and periodic
//! plans, which share the dilation); the tests are in `bricks/tests.rs`.

use super::plan::{plan, Box3};
use rayon::prelude::*;

pub use crate::contract::bricks::{
    brick_of, local_index, voxel_of, Brick, ABSENT, BRICK, BRICK_VOXELS,
};

/// The inclusive per-axis bounds of points (bricks or voxels); None when there are none.
pub fn bounds(points: &[[i32; 3]]) -> Option<([i32; 3], [i32; 3])> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), p| {
        (
            [0, 1, 2].map(|i| lo[i].min(p[i])),
            [0, 1, 2].map(|i| hi[i].max(p[i])),
        )
    }))
}

/// Sort (z, then y, then x) and remove duplicates.
pub fn normalize(bricks: &mut Vec<Brick>) {
    let key = |b: &Brick| (b[2], b[1], b[0]);
    // (Keys are the whole bricks: the order is the same however the sort runs. Parallel only
    // where it pays: a cut's or a group's tens of thousands of bricks.)
    if bricks.len() > 1 << 12 {
        bricks.par_sort_unstable_by_key(key);
    } else {
        bricks.sort_unstable_by_key(key);
    }
    bricks.dedup();
}

/// The bricks of voxels visited one by one, normalized at the end. Neighbouring voxels (atlas
/// texels) mostly share a brick: repeats of the previous brick are dropped on the way, so the
/// list stays near the brick count instead of one entry per voxel.
#[derive(Default)]
pub struct BrickSet(Vec<Brick>);

impl BrickSet {
    pub fn add(&mut self, voxel: [i32; 3]) {
        let b = brick_of(voxel);
        if self.0.last() != Some(&b) {
            self.0.push(b);
        }
    }

    pub fn finish(mut self) -> Vec<Brick> {
        normalize(&mut self.0);
        self.0.shrink_to_fit();
        self.0
    }
}

/// The bricks holding `voxels`, normalized.
pub fn bricks_of_voxels(voxels: &[[i32; 3]]) -> Vec<Brick> {
    let mut set = BrickSet::default();
    voxels.iter().for_each(|p| set.add(*p));
    set.finish()
}

/// The bricks covering a box.
pub fn bricks_of_box(b: Box3) -> Vec<Brick> {
    if b.is_empty() {
        return Vec::new();
    }
    let lo = brick_of(b.lo);
    let hi = brick_of(b.hi.map(|v| v - 1));
    let mut out = Vec::new();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                out.push([x, y, z]);
            }
        }
    }
    out
}

/// A dense table over the bounding box of a brick list: brick -> its slot (index in the list).
#[derive(Clone, Debug, PartialEq)]
pub struct BrickGrid {
    pub lo: Brick,
    pub dims: [u32; 3],
    pub table: Vec<u32>,
}

impl BrickGrid {
    pub fn new(bricks: &[Brick]) -> BrickGrid {
        let Some((lo, hi)) = bounds(bricks) else {
            return BrickGrid {
                lo: [0; 3],
                dims: [1; 3],
                table: vec![ABSENT],
            };
        };
        let dims = [0, 1, 2].map(|i| (hi[i] - lo[i] + 1) as u32);
        let mut table = vec![ABSENT; dims.iter().map(|&d| d as usize).product()];
        let mut grid = BrickGrid {
            lo,
            dims,
            table: Vec::new(),
        };
        for (slot, b) in bricks.iter().enumerate() {
            table[grid.cell(*b).unwrap()] = slot as u32;
        }
        grid.table = table;
        grid
    }

    fn cell(&self, b: Brick) -> Option<usize> {
        let d = [0, 1, 2].map(|i| b[i] - self.lo[i]);
        if (0..3).any(|i| d[i] < 0 || d[i] >= self.dims[i] as i32) {
            return None;
        }
        Some(
            ((d[2] as usize * self.dims[1] as usize) + d[1] as usize) * self.dims[0] as usize
                + d[0] as usize,
        )
    }

    pub fn slot(&self, b: Brick) -> Option<u32> {
        self.cell(b).map(|c| self.table[c]).filter(|&s| s != ABSENT)
    }

    /// Index of voxel `p` in a state of this grid's bricks.
    pub fn voxel_index(&self, p: [i32; 3]) -> Option<usize> {
        self.slot(brick_of(p))
            .map(|s| s as usize * BRICK_VOXELS as usize + local_index(p) as usize)
    }
}

/// Append a brick list (three i32 words per brick) to a brick index; returns its word offset.
pub fn push_list(words: &mut Vec<u32>, list: &[Brick]) -> u32 {
    let at = words.len() as u32;
    for b in list {
        words.extend(b.map(|v| v as u32));
    }
    at
}

/// Minkowski sum of a brick set with the brick offsets [lo, hi] (inclusive) per axis, through a
/// dense occupancy grid dilated one axis at a time. The offset ranges are a few bricks, so each
/// axis ORs a handful of shifted copies of whole rows, planes or the grid (contiguous bytes the
/// compiler vectorizes): an oblique cut's plan dilates a sparse sheet in a large bounding box
/// several times per level, and running sums along strided lines took most of its planning
/// (BENCHMARKS.md).
pub fn dilate(set: &[Brick], lo: [i32; 3], hi: [i32; 3]) -> Vec<Brick> {
    let Some((bmin, bmax)) = bounds(set) else {
        return Vec::new();
    };
    if (0..3).any(|i| hi[i] < lo[i]) {
        return Vec::new();
    }
    if lo == [0; 3] && hi == [0; 3] {
        // The set itself (an oblique cut's one-pass level asks for this 8 times).
        let mut out = set.to_vec();
        normalize(&mut out);
        return out;
    }
    // The grid covers the set and its image.
    let glo = [0, 1, 2].map(|i| bmin[i] + lo[i].min(0));
    let dims = [0, 1, 2].map(|i| (bmax[i] + hi[i].max(0) - glo[i] + 1) as usize);
    let idx = |p: [usize; 3]| (p[2] * dims[1] + p[1]) * dims[0] + p[0];
    let mut grid = vec![0u8; dims[0] * dims[1] * dims[2]];
    for b in set {
        grid[idx([0, 1, 2].map(|i| (b[i] - glo[i]) as usize))] = 1;
    }
    let mut before = Vec::new();
    for axis in 0..3 {
        // The grid as blocks of `n` cells along the axis, each cell `inner` contiguous bytes.
        let n = dims[axis];
        let inner: usize = dims[..axis].iter().product();
        for block in grid.chunks_exact_mut(n * inner) {
            before.clear();
            before.extend_from_slice(block);
            block.fill(0);
            // Cell k is set when some set cell k - d has d in [lo, hi].
            for d in lo[axis]..=hi[axis] {
                let shift = d.unsigned_abs() as usize;
                if shift >= n {
                    continue;
                }
                let (to, from) = if d >= 0 { (shift, 0) } else { (0, shift) };
                let len = (n - shift) * inner;
                for (out, cell) in block[to * inner..to * inner + len]
                    .iter_mut()
                    .zip(&before[from * inner..from * inner + len])
                {
                    *out |= cell;
                }
            }
        }
    }
    let mut out = Vec::new();
    for (i, _) in grid.iter().enumerate().filter(|(_, &cell)| cell != 0) {
        let (x, y, z) = (i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1]));
        out.push([glo[0] + x as i32, glo[1] + y as i32, glo[2] + z as i32]);
    }
    out
}

/// Brick offsets whose bricks intersect `b` (a voxel box relative to a brick at the origin).
fn offset_range(b: Box3) -> Option<([i32; 3], [i32; 3])> {
    if b.is_empty() {
        return None;
    }
    Some((
        b.lo.map(|v| v.div_euclid(BRICK)),
        b.hi.map(|v| (v + BRICK - 1).div_euclid(BRICK) - 1),
    ))
}

/// Answers "is any brick of a set inside this box of bricks?" in constant time (a 3D summed
/// area table over the set's bounding box).
struct Presence {
    lo: Brick,
    dims: [i32; 3],
    sat: Vec<u32>,
}

impl Presence {
    fn new(set: &[Brick]) -> Presence {
        let Some((lo, hi)) = bounds(set) else {
            return Presence {
                lo: [0; 3],
                dims: [1; 3],
                sat: vec![0; 8],
            };
        };
        let dims = [0, 1, 2].map(|i| hi[i] - lo[i] + 1);
        let [nx, ny, nz] = dims.map(|d| (d + 1) as usize);
        let mut sat = vec![0u32; nx * ny * nz];
        for b in set {
            let [x, y, z] = [0, 1, 2].map(|i| (b[i] - lo[i] + 1) as usize);
            sat[(z * ny + y) * nx + x] = 1;
        }
        // The table as three running sums, along x, then y, then z: one addition per cell
        // and axis instead of the seven-term recurrence with a brick lookup per cell (an
        // oblique 256^2 cut's bounding box is ~190k cells: building this was 15% of its
        // warm cut's main-thread CPU on lavapipe on the 2-core Intel Xeon development machine).
        for row in sat.chunks_exact_mut(nx) {
            for x in 1..nx {
                row[x] = row[x].wrapping_add(row[x - 1]);
            }
        }
        for plane in sat.chunks_exact_mut(nx * ny) {
            for y in 1..ny {
                let (before, rest) = plane.split_at_mut(y * nx);
                let previous = &before[(y - 1) * nx..];
                for (cell, &below) in rest[..nx].iter_mut().zip(previous) {
                    *cell = cell.wrapping_add(below);
                }
            }
        }
        for z in 1..nz {
            let (before, rest) = sat.split_at_mut(z * nx * ny);
            let previous = &before[(z - 1) * nx * ny..];
            for (cell, &below) in rest[..nx * ny].iter_mut().zip(previous) {
                *cell = cell.wrapping_add(below);
            }
        }
        Presence { lo, dims, sat }
    }

    /// Whether a brick of the set lies in [lo, hi] (inclusive).
    fn any(&self, lo: Brick, hi: Brick) -> bool {
        let a = [0, 1, 2].map(|i| (lo[i] - self.lo[i]).max(0));
        let b = [0, 1, 2].map(|i| (hi[i] - self.lo[i] + 1).min(self.dims[i]));
        if (0..3).any(|i| a[i] >= b[i]) {
            return false;
        }
        let n = |d: i32| (d + 1) as usize;
        let at = |x: i32, y: i32, z: i32| {
            self.sat[(z as usize * n(self.dims[1]) + y as usize) * n(self.dims[0]) + x as usize]
        };
        let sum = at(b[0], b[1], b[2])
            .wrapping_sub(at(a[0], b[1], b[2]))
            .wrapping_sub(at(b[0], a[1], b[2]))
            .wrapping_sub(at(b[0], b[1], a[2]))
            .wrapping_add(at(a[0], a[1], b[2]))
            .wrapping_add(at(a[0], b[1], a[2]))
            .wrapping_add(at(b[0], a[1], a[2]))
            .wrapping_sub(at(a[0], a[1], a[2]));
        sum != 0
    }
}

/// One correction sub-pass of a sparse level.
#[derive(Clone, Debug)]
pub struct SubpassPlan {
    /// Parity class (bit 0 x, 1 y, 2 z) of the voxels updated.
    pub class: usize,
    /// Bricks with at least one needed voxel of the class (empty when `over_storage`).
    pub bricks: Vec<Brick>,
    /// Per brick of `bricks`, bit k: whether its class voxel k (offset 2 * (k & 1, k >> 1 & 1,
    /// k >> 2)) is needed. Voxel-exact, so bricks cost only the voxels the plan needs. When
    /// `over_storage`: one mask per stored brick, in slot order, 0 for the bricks skipped.
    pub masks: Vec<u8>,
    /// Masks over the level's stored bricks instead of a list (a sub-pass covering most of
    /// a box: 1 byte per stored brick instead of 13 per listed one).
    pub over_storage: bool,
}

impl SubpassPlan {
    fn listed(class: usize) -> SubpassPlan {
        SubpassPlan {
            class,
            bricks: Vec::new(),
            masks: Vec::new(),
            over_storage: false,
        }
    }

    /// Whether the sub-pass computes nothing.
    pub fn is_empty(&self) -> bool {
        self.masks.is_empty()
    }

    /// The bricks it computes, with their masks (`stored`: the level's bricks).
    #[cfg(any(test, feature = "internals"))]
    pub fn active<'a>(&'a self, stored: &'a [Brick]) -> Vec<(Brick, u8)> {
        if self.over_storage {
            stored
                .iter()
                .zip(&self.masks)
                .filter(|(_, &m)| m != 0)
                .map(|(b, &m)| (*b, m))
                .collect()
        } else {
            self.bricks
                .iter()
                .copied()
                .zip(self.masks.iter().copied())
                .collect()
        }
    }
}

/// The needed class voxels of the bricks near the delivered ones (`presence`) for a sub-pass
/// whose per-brick plan box is `needed` (relative to a brick at the origin): voxel v is needed
/// when some delivered brick b has v - 4b inside the box. `candidates`: the delivered bricks
/// dilated by the brick offsets of `needed` ([`offset_range`]), the bricks that may hold one.
fn subpass_plan(
    class: usize,
    needed: Box3,
    candidates: &[Brick],
    presence: &Presence,
) -> SubpassPlan {
    let mut plan = SubpassPlan::listed(class);
    let c = [
        (class & 1) as i32,
        ((class >> 1) & 1) as i32,
        ((class >> 2) & 1) as i32,
    ];
    // Class voxel k of brick a lies at v = 4a + c + 2 (k's bit per axis). The delivered bricks
    // that need it span [ceil((v - needed.hi + 1) / 4), floor((v - needed.lo) / 4)] per axis,
    // which is a plus an offset range fixed by the axis and k's bit along it (4a divides out).
    let ranges: [[(i32, i32); 2]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|bit| {
            let t = c[i] + 2 * bit as i32;
            (
                (t - needed.hi[i] + BRICK).div_euclid(BRICK),
                (t - needed.lo[i]).div_euclid(BRICK),
            )
        })
    });
    // Class voxels whose ranges are the same (usually several) share one query.
    let first_alike: [usize; 8] = std::array::from_fn(|k| {
        let key = |k: usize| [0, 1, 2].map(|i| ranges[i][(k >> i) & 1]);
        (0..k).find(|&j| key(j) == key(k)).unwrap_or(k)
    });
    for &a in candidates {
        let mut mask = 0u8;
        for k in 0..8 {
            let j = first_alike[k];
            let needed_here = if j < k {
                mask & (1 << j) != 0
            } else {
                let blo = [0, 1, 2].map(|i| a[i] + ranges[i][(k >> i) & 1].0);
                let bhi = [0, 1, 2].map(|i| a[i] + ranges[i][(k >> i) & 1].1);
                presence.any(blo, bhi)
            };
            if needed_here {
                mask |= 1 << k;
            }
        }
        if mask != 0 {
            plan.bricks.push(a);
            plan.masks.push(mask);
        }
    }
    plan
}

/// What one level of a sparse synthesis computes.
#[derive(Clone, Debug)]
pub struct SparseLevel {
    /// Stored bricks, in slot order.
    pub bricks: Vec<Brick>,
    pub grid: BrickGrid,
    /// The correction sub-passes in execution order.
    pub subpasses: Vec<SubpassPlan>,
    /// Bricks whose values this level delivers (to the finer level, or as output): the plan's
    /// own record, which the tests check against the requests.
    #[cfg_attr(not(any(test, feature = "internals")), allow(dead_code))]
    pub deliver: Vec<Brick>,
}

impl SparseLevel {
    pub fn voxels(&self) -> u64 {
        self.bricks.len() as u64 * BRICK_VOXELS as u64
    }
}

/// Plan the synthesis of the finest-level bricks `output` through one level per entry of
/// `passes` (that level's correction passes, coarsest first); coarsest level first.
pub fn plan_sparse(output: &[Brick], passes: &[usize]) -> Vec<SparseLevel> {
    let mut deliver = output.to_vec();
    normalize(&mut deliver);
    match brick_box(&deliver) {
        Some((lo, hi)) => plan_box(lo, hi, passes),
        None => plan_general(deliver, passes),
    }
}

/// The inclusive brick range of `sorted` bricks when they fill it exactly (a box request).
fn brick_box(sorted: &[Brick]) -> Option<(Brick, Brick)> {
    let (lo, hi) = bounds(sorted)?;
    let cells: u64 = (0..3).map(|i| (hi[i] - lo[i] + 1) as u64).product();
    // Sorted and deduplicated: as many bricks as cells means every cell.
    (cells == sorted.len() as u64).then_some((lo, hi))
}

/// [`plan_sparse`] of the full brick box [lo, hi] (inclusive), with every set a box: the same
/// plan as [`plan_general`]'s, in time proportional to the bricks (a large box spent most of a
/// second in the general planner's per-voxel presence queries, which a GPU run cannot hide).
fn plan_box(mut lo: Brick, mut hi: Brick, passes: &[usize]) -> Vec<SparseLevel> {
    let mut out = Vec::new();
    for &level_passes in passes.iter().rev() {
        let one = &plan(Box3::new([0; 3], [BRICK; 3]), &[level_passes])[0];
        let (slo, shi) = offset_range(one.storage).expect("storage holds the brick");
        let range = |a: Brick, b: Brick| {
            bricks_of_box(Box3::new(
                [0, 1, 2].map(|i| a[i] * BRICK),
                [0, 1, 2].map(|i| (b[i] + 1) * BRICK),
            ))
        };
        let s0 = [0, 1, 2].map(|i| lo[i] + slo[i]);
        let s1 = [0, 1, 2].map(|i| hi[i] + shi[i]);
        let sdims = [0, 1, 2].map(|i| (s1[i] - s0[i] + 1) as usize);
        let bricks = range(s0, s1);
        let storage = (s0, sdims);
        let subpasses = one
            .subpasses
            .par_iter()
            .map(|&(class, needed)| {
                if needed.is_empty() {
                    return SubpassPlan::listed(class);
                }
                // The union of the translates 4b + needed (b in the box) is one voxel box: the
                // brick plan boxes grow from the brick by dilations, so their sides are at
                // least 4 long and consecutive translates touch.
                let union = Box3::new(
                    [0, 1, 2].map(|i| lo[i] * BRICK + needed.lo[i]),
                    [0, 1, 2].map(|i| hi[i] * BRICK + needed.hi[i]),
                );
                subpass_in_box(class, union, storage)
            })
            .collect();
        let deliver = range(lo, hi);
        let grid = BrickGrid::new(&bricks);
        out.push(SparseLevel {
            bricks,
            grid,
            subpasses,
            deliver,
        });
        // The parents of the stored box: a box.
        lo = [0, 1, 2].map(|i| (lo[i] + slo[i]) >> 1);
        hi = [0, 1, 2].map(|i| (hi[i] + shi[i]) >> 1);
    }
    out.reverse();
    out
}

/// The sub-pass of class `class` computing the class voxels inside the voxel box `needed`, on
/// a level storing the full brick box at `storage.0` with `storage.1` bricks per axis.
fn subpass_in_box(class: usize, needed: Box3, storage: (Brick, [usize; 3])) -> SubpassPlan {
    let (s0, sdims) = storage;
    let stored: usize = sdims.iter().product();
    let mut sp = SubpassPlan::listed(class);
    if needed.is_empty() {
        return sp;
    }
    let c = [0, 1, 2].map(|i| ((class >> i) & 1) as i32);
    // Per axis and brick coordinate: which of the 8 class voxels of the brick lie inside along
    // that axis, as mask bits (bricks with none left out).
    let bits: [Vec<(i32, u8)>; 3] = std::array::from_fn(|i| {
        (needed.lo[i].div_euclid(BRICK)..=(needed.hi[i] - 1).div_euclid(BRICK))
            .map(|a| {
                let mut bits = 0u8;
                for k in 0..8 {
                    let v = a * BRICK + c[i] + 2 * ((k >> i) & 1);
                    if v >= needed.lo[i] && v < needed.hi[i] {
                        bits |= 1 << k;
                    }
                }
                (a, bits)
            })
            .filter(|&(_, m)| m != 0)
            .collect()
    });
    // (Every combination is nonzero: the three axes' bits each hold a choice along their axis,
    // and their product is a class voxel inside.)
    let count: usize = bits.iter().map(Vec::len).product();
    if count == 0 {
        return sp;
    }
    if 2 * count >= stored {
        sp.over_storage = true;
        sp.masks = vec![0; stored];
        for &(z, mz) in &bits[2] {
            for &(y, my) in &bits[1] {
                let row = ((z - s0[2]) as usize * sdims[1] + (y - s0[1]) as usize) * sdims[0];
                for &(x, mx) in &bits[0] {
                    sp.masks[row + (x - s0[0]) as usize] = mz & my & mx;
                }
            }
        }
        return sp;
    }
    sp.bricks.reserve_exact(count);
    sp.masks.reserve_exact(count);
    for &(z, mz) in &bits[2] {
        for &(y, my) in &bits[1] {
            for &(x, mx) in &bits[0] {
                sp.bricks.push([x, y, z]);
                sp.masks.push(mz & my & mx);
            }
        }
    }
    sp
}

/// The synthesis of exactly the voxels of the box `out` (voxel units, not necessarily
/// aligned to bricks) through one level per entry of `passes` (coarsest first); coarsest level
/// first. The finest level: the dense planner's boxes (`plan::plan` of `out`), stored in the
/// bricks covering them; the coarser levels as for the box of those bricks' parents. Since
/// passes compute whole bricks (brick-local sub-passes) this computes what the brick plan of
/// `out`'s bricks does: a one-voxel slice gains nothing here, its padding surrounds its bricks'
/// four voxel layers either way. Delivers `out`'s voxels.
pub fn plan_voxel_box(out: Box3, passes: &[usize]) -> Vec<SparseLevel> {
    let (&finest, coarser) = passes.split_last().expect("at least one level");
    let dense = &plan(out, &[finest])[0];
    let s0 = brick_of(dense.storage.lo);
    let s1 = brick_of(dense.storage.hi.map(|v| v - 1));
    let sdims = [0, 1, 2].map(|i| (s1[i] - s0[i] + 1) as usize);
    let bricks = bricks_of_box(Box3::new(
        s0.map(|v| v * BRICK),
        s1.map(|v| (v + 1) * BRICK),
    ));
    let subpasses = dense
        .subpasses
        .par_iter()
        .map(|&(class, needed)| subpass_in_box(class, needed, (s0, sdims)))
        .collect();
    let mut levels = match coarser.is_empty() {
        true => Vec::new(),
        false => plan_box(s0.map(|v| v >> 1), s1.map(|v| v >> 1), coarser),
    };
    levels.push(SparseLevel {
        grid: BrickGrid::new(&bricks),
        bricks,
        subpasses,
        deliver: bricks_of_box(out),
    });
    levels
}

/// [`plan_sparse`] of any set of bricks (`deliver`, normalized).
fn plan_general(mut deliver: Vec<Brick>, passes: &[usize]) -> Vec<SparseLevel> {
    let mut out = Vec::new();
    for &level_passes in passes.iter().rev() {
        let one = &plan(Box3::new([0; 3], [BRICK; 3]), &[level_passes])[0];
        let storage_range = offset_range(one.storage).expect("storage holds the brick");
        let bricks = dilate(&deliver, storage_range.0, storage_range.1);
        let presence = Presence::new(&deliver);
        // The sub-passes' candidate bricks: `deliver` dilated by each one's brick offsets,
        // once per distinct range (the eight classes of a pass usually share one).
        let mut ranges: Vec<([i32; 3], [i32; 3])> = one
            .subpasses
            .iter()
            .filter_map(|(_, needed)| offset_range(*needed))
            .collect();
        ranges.sort_unstable();
        ranges.dedup();
        let dilated: Vec<Vec<Brick>> = ranges
            .par_iter()
            .map(|&(lo, hi)| dilate(&deliver, lo, hi))
            .collect();
        // (Independent of each other: planned in parallel.)
        let subpasses = one
            .subpasses
            .par_iter()
            .map(|&(class, needed)| {
                let candidates = offset_range(needed).map_or(&[][..], |range| {
                    &dilated[ranges.binary_search(&range).expect("range listed")]
                });
                subpass_plan(class, needed, candidates, &presence)
            })
            .collect();
        let grid = BrickGrid::new(&bricks);
        let mut parent: Vec<Brick> = bricks.iter().map(|b| b.map(|v| v >> 1)).collect();
        normalize(&mut parent);
        out.push(SparseLevel {
            bricks,
            grid,
            subpasses,
            deliver,
        });
        deliver = parent;
    }
    out.reverse();
    out
}

/// The plan of a tileable solid of period `n` (finest level) through one level per entry of
/// `passes` (coarsest first): level l stores every brick of its period box [0, n >> (levels -
/// 1 - l))^3 and every sub-pass computes all of them (reads wrap around the period, so no
/// padding is needed).
pub fn plan_periodic(n: u32, passes: &[usize]) -> Vec<SparseLevel> {
    let levels = passes.len();
    passes
        .iter()
        .enumerate()
        .map(|(l, &level_passes)| {
            let p = (n >> (levels - 1 - l)) as i32;
            let bricks = bricks_of_box(Box3::new([0; 3], [p; 3]));
            let subpasses = (0..level_passes)
                .flat_map(|_| super::SUBPASS_ORDER)
                .map(|class| SubpassPlan {
                    class,
                    bricks: Vec::new(),
                    masks: vec![0xFF; bricks.len()],
                    over_storage: true,
                })
                .collect();
            SparseLevel {
                grid: BrickGrid::new(&bricks),
                deliver: bricks.clone(),
                bricks,
                subpasses,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
