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
//! Brick storage is here; the sparse, box, voxel-box and periodic plans are in `bricks/plans.rs`,
//! the tests in `bricks/tests.rs`.

use super::plan::{plan, Box3};
use rayon::prelude::*;

mod plans;
pub use plans::{plan_periodic, plan_sparse, plan_voxel_box, SparseLevel, SubpassPlan};

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

/// The box `voxels` fill exactly (each of its voxels once, in any order), if they do.
pub(super) fn voxel_box(voxels: &[[i32; 3]]) -> Option<Box3> {
    let (lo, hi) = bounds(voxels)?;
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
mod tests;
