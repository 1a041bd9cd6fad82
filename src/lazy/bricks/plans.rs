//! Planning a level in bricks: per correction sub-pass, the bricks (and class voxels) it must
//! compute, for sparse requests, boxes of bricks, voxel-exact boxes and periodic solids; and
//! the stored bricks every step reads.

use super::*;

/// Brick offsets whose bricks intersect `b` (a voxel box relative to a brick at the origin).
pub(super) fn offset_range(b: Box3) -> Option<([i32; 3], [i32; 3])> {
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
pub(super) struct Presence {
    lo: Brick,
    dims: [i32; 3],
    sat: Vec<u32>,
}

impl Presence {
    pub(super) fn new(set: &[Brick]) -> Presence {
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
    pub(super) fn any(&self, lo: Brick, hi: Brick) -> bool {
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
pub(super) fn subpass_plan(
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
pub(super) fn brick_box(sorted: &[Brick]) -> Option<(Brick, Brick)> {
    let (lo, hi) = bounds(sorted)?;
    let cells = (0..3).fold(1u64, |n, i| n.saturating_mul((hi[i] - lo[i] + 1) as u64));
    // Sorted and deduplicated: as many bricks as cells means every cell.
    (cells == sorted.len() as u64).then_some((lo, hi))
}

/// [`plan_sparse`] of the full brick box [lo, hi] (inclusive), with every set a box: the same
/// plan as [`plan_general`]'s, in time proportional to the bricks (a large box spent most of a
/// second in the general planner's per-voxel presence queries, which a GPU run cannot hide).
pub(super) fn plan_box(mut lo: Brick, mut hi: Brick, passes: &[usize]) -> Vec<SparseLevel> {
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
pub(super) fn subpass_in_box(class: usize, needed: Box3, storage: (Brick, [usize; 3])) -> SubpassPlan {
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
pub(super) fn plan_general(mut deliver: Vec<Brick>, passes: &[usize]) -> Vec<SparseLevel> {
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
                .flat_map(|_| crate::lazy::SUBPASS_ORDER)
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
