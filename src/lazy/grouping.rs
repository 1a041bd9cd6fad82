//! Splitting a request's bricks into groups: cubes of bricks, each synthesized on its own with
//! its dependency padding, sized so that a group's state fits one buffer of the backend.

use super::bricks::{self, Brick, BRICK, BRICK_VOXELS};
use super::plan::{self, Box3};
use super::PADDING_ESTIMATE;
use std::collections::{BTreeMap, HashMap};

/// Bytes of one state over a box of `extent` finest-level voxels and its padding, each voxel a
/// triple and a value word (one word covers up to four channels; the estimate assumes that):
/// the memory estimates' rule of thumb, with [`PADDING_ESTIMATE`] for any schedule.
pub fn padded_state_bytes(extent: [u64; 3]) -> u64 {
    let pad = 2 * PADDING_ESTIMATE as u64;
    // (Saturating: an estimate of an absurd request must stay absurd, not wrap.)
    extent
        .iter()
        .fold(16u64, |bytes, e| bytes.saturating_mul(e.saturating_add(pad)))
}

/// An upper bound of the largest level state of a group whose bricks span a box of `extent`
/// finest-level voxels (brick-aligned), synthesized through one level per entry of `passes`
/// (coarsest first; `stride_bytes` per voxel at each): the dense plan of that box
/// ([`plan::plan`], whose storage holds every sparse plan's within the box), each level's
/// storage rounded out to whole bricks at any alignment. Exact in the schedule: more passes,
/// more padding.
pub fn planned_state_bytes(extent: [u64; 3], passes: &[usize], stride_bytes: &[u64]) -> u64 {
    let output = Box3::new([0; 3], extent.map(|e| e as i32));
    plan::plan(output, passes)
        .iter()
        .zip(stride_bytes)
        .map(|(level, stride)| {
            let s = level.storage;
            let bricks: u64 = (0..3)
                .map(|i| ((s.hi[i] - s.lo[i]) as u64).div_ceil(BRICK as u64) + 1)
                .product();
            bricks * BRICK_VOXELS as u64 * stride
        })
        .max()
        .unwrap_or(0)
}

/// The sides (voxels, per axis) of the boxes to split `all` into: cubes of `cap`, unless some
/// cube's state (`state_bytes` of its brick-aligned extent) would exceed `limit` bytes; then
/// cubes of the largest side that a dense cube's state fits (at least 8). Sides between the two
/// are tried by halving `cap`: a thin request (a cut, a flat box) fills little of a cube, and
/// each group's bounding box is what must fit. Fewer groups recompute less padding and make
/// fewer round trips (a 256^2 cut on lavapipe's 128 MiB buffers: one group instead of four).
/// Where the cap does not fit, the cubes are then evened out over the request (`even_sides`);
/// a sparse request's only where the even boxes still fit and are no more groups. Where it
/// fits, cubes of the cap, as asked; with `even_at_cap` evened too where that makes no more
/// groups (a shared coarse level: 512^3's parents in groups of 132, not 160 and 104, whose
/// larger group would hold 1.5 times the state).
pub fn group_sides(
    all: &[Brick],
    cap: u32,
    even_at_cap: bool,
    limit: u64,
    state_bytes: impl Fn([u64; 3]) -> u64,
) -> [u32; 3] {
    let mut dense = cap;
    while dense > 8 && state_bytes([dense as u64; 3]) > limit {
        dense -= 8;
    }
    let fits = |bounds: &[(Brick, Brick)]| {
        bounds.iter().all(|(lo, hi)| {
            let extent = [0, 1, 2].map(|i| ((hi[i] - lo[i] + 1) * BRICK) as u64);
            state_bytes(extent) <= limit
        })
    };
    let mut side = cap;
    while side > dense {
        let cubes = cube_bounds(all, [side; 3]);
        if fits(&cubes) {
            // A sparse request's cubes fit by their contents: smaller boxes need not, and
            // on a surface they may be more groups (each non-empty where a cube's corner was).
            let even = even_sides(all, side);
            let boxes = cube_bounds(all, even);
            return if fits(&boxes) && boxes.len() <= cubes.len() {
                even
            } else {
                [side; 3]
            };
        }
        side /= 2;
    }
    if dense == cap {
        // The cap fits: cubes of it, as asked (`--max-group`), or equal boxes within it.
        if even_at_cap {
            let even = even_sides(all, cap);
            if cube_bounds(all, even).len() <= cube_bounds(all, [cap; 3]).len() {
                return even;
            }
        }
        return [cap; 3];
    }
    // Any box within a dense cube fits.
    even_sides(all, dense)
}

/// Sides, each at most `largest` (in whole bricks), that split the request's bounding box into
/// as few boxes per axis as cubes of `largest` do, but of equal size: 512^3 in cubes of at most
/// 488 voxels becomes eight cubes of 256, not one of 488 and seven slivers of 24 that each
/// recompute a full padding, and 600 x 400 x 400 two boxes of 300 x 400 x 400. Equal groups
/// also let a GPU synthesize one while the host takes the previous one's colours (the NRRD's
/// slabs, a surface's atlas): on an NVIDIA H200, 512^3 took 1.71-1.74 s in groups of 256
/// against 2.0 s in the uneven ones, with shared coarse levels (BENCHMARKS.md).
fn even_sides(all: &[Brick], largest: u32) -> [u32; 3] {
    let most = cube_bricks(largest);
    let Some((lo, hi)) = bricks::bounds(all) else {
        return [largest; 3];
    };
    [0, 1, 2].map(|i| {
        let extent = (hi[i] - lo[i] + 1) as u32;
        let boxes = extent.div_ceil(most as u32);
        // (An axis in one box keeps the whole side: any side past its extent is the same.)
        let bricks = if boxes == 1 {
            most as u32
        } else {
            extent.div_ceil(boxes)
        };
        bricks * BRICK as u32
    })
}

/// `all` (sorted) split into boxes of `sides` voxels (each rounded down to whole bricks, at
/// least one), box keys in (z, y, x) order, each box's bricks in `all`'s order.
pub fn cubes(all: &[Brick], sides: [u32; 3]) -> Vec<Vec<Brick>> {
    if all.is_empty() {
        return Vec::new();
    }
    if is_one_cube(all, sides) {
        return vec![all.to_vec()];
    }
    let size = sides.map(cube_bricks);
    let origin = origin(all);
    let mut map: BTreeMap<[i32; 3], Vec<Brick>> = Default::default();
    for b in all {
        map.entry(cube_key(*b, origin, size)).or_default().push(*b);
    }
    map.into_values().collect()
}

/// Each box's bounding box of bricks (inclusive), as [`cubes`] would split `all`.
fn cube_bounds(all: &[Brick], sides: [u32; 3]) -> Vec<(Brick, Brick)> {
    let size = sides.map(cube_bricks);
    let Some((lo, hi)) = bricks::bounds(all) else {
        return Vec::new();
    };
    if in_one_cube(lo, hi, size) {
        return vec![(lo, hi)];
    }
    let mut map: HashMap<[i32; 3], (Brick, Brick)> = Default::default();
    for b in all {
        map.entry(cube_key(*b, lo, size))
            .and_modify(|(lo, hi)| {
                *lo = [0, 1, 2].map(|i| lo[i].min(b[i]));
                *hi = [0, 1, 2].map(|i| hi[i].max(b[i]));
            })
            .or_insert((*b, *b));
    }
    map.into_values().collect()
}

/// Whether bricks within [lo, hi] (inclusive) make one box of `size` bricks from `lo`: then
/// the splits need no per-brick key (a warm cut's request, a small box: grouping by keys in a
/// hash map took ~0.45 ms of a warm 256^2 cut's host time on the 2-core Intel Xeon development
/// machine).
fn in_one_cube(lo: Brick, hi: Brick, size: [i32; 3]) -> bool {
    (0..3).all(|i| hi[i] - lo[i] < size[i])
}

/// Whether `all` makes a single box of `sides` voxels ([`cubes`] would return one box).
pub fn is_one_cube(all: &[Brick], sides: [u32; 3]) -> bool {
    bricks::bounds(all).is_some_and(|(lo, hi)| in_one_cube(lo, hi, sides.map(cube_bricks)))
}

fn cube_bricks(side: u32) -> i32 {
    (side as i32 / BRICK).max(1)
}

/// Boxes start at the request's low corner, so a request that fits in one box is one group
/// wherever it lies.
fn origin(all: &[Brick]) -> Brick {
    bricks::bounds(all).map_or([0; 3], |(lo, _)| lo)
}

fn cube_key(b: Brick, origin: Brick, size: [i32; 3]) -> [i32; 3] {
    let key = [0, 1, 2].map(|i| (b[i] - origin[i]).div_euclid(size[i]));
    [key[2], key[1], key[0]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slab(x: i32, y: i32, z: i32) -> Vec<Brick> {
        let mut out = Vec::new();
        for k in 0..z {
            for j in 0..y {
                for i in 0..x {
                    out.push([i, j, k]);
                }
            }
        }
        out
    }

    /// The default schedule's bound: two passes at each of four levels, 16 bytes a voxel.
    fn two_passes(extent: [u64; 3]) -> u64 {
        planned_state_bytes(extent, &[2; 4], &[16; 4])
    }

    #[test]
    fn a_thin_request_takes_a_cube_larger_than_a_dense_one() {
        let limit = 128 << 20;
        // A dense 184^3 cube with its padding is the largest that fits 128 MiB; 512 voxels
        // take three of those a side, evened out to 172.
        assert!(two_passes([184; 3]) <= limit && two_passes([192; 3]) > limit);
        assert_eq!(
            group_sides(&slab(128, 128, 128), 512, false, limit, two_passes),
            [172; 3]
        );
        // A 256^2 cut one brick thick: its padded box fits.
        let cut = slab(64, 64, 1);
        assert_eq!(group_sides(&cut, 512, false, limit, two_passes), [512; 3]);
        assert_eq!(cubes(&cut, [512; 3]).len(), 1);
        // 512 wide and 16 thick does not fit whole; its 256 x 256 quarters do.
        let wide = slab(128, 128, 4);
        assert!(two_passes([512, 512, 16]) > limit);
        assert_eq!(group_sides(&wide, 512, false, limit, two_passes), [256; 3]);
        assert_eq!(cubes(&wide, [256; 3]).len(), 4);
    }

    #[test]
    fn the_bound_follows_the_schedule_and_covers_the_padding() {
        // Two passes at the finest level pad a brick-aligned box by 6 voxels a side (its
        // bricks, one more brick for the first pass, 2 voxels of reads); whole bricks at any
        // alignment add at most one brick a side.
        let b = two_passes([64, 64, 64]);
        assert!(b >= 76u64.pow(3) * 16 && b <= 80u64.pow(3) * 16, "{b}");
        // More passes, more padding: the dense side shrinks.
        let four = |e: [u64; 3]| planned_state_bytes(e, &[2, 2, 2, 4], &[16; 4]);
        assert!(four([64; 3]) > b);
        let limit = 128 << 20;
        assert!(group_sides(&slab(128, 128, 128), 512, false, limit, four)[0] < 172);
        // No passes: the storage is the box itself (plus the brick rounding).
        let none = planned_state_bytes([64; 3], &[0; 4], &[16; 4]);
        assert_eq!(none, 17u64.pow(3) * 64 * 16);
    }

    #[test]
    fn a_shared_coarse_level_just_over_the_cap_is_one_group() {
        use crate::lazy::group_cap;
        let limit = 128 << 20;
        // A box's level above the finest, with finest groups of 128.
        let coarse_sides = |bricks: &[Brick], even_at_cap: bool| {
            group_sides(
                bricks,
                group_cap(Some(128), 1, true),
                even_at_cap,
                limit,
                two_passes,
            )
        };
        // 256^3 in finest groups of 128 asks the level above for its 128^3 parents and their
        // padding: 136 voxels (34 bricks) a side. One group, not one of 128 and seven slivers.
        let parents = slab(34, 34, 34);
        assert_eq!(group_cap(Some(128), 1, true), 160);
        assert_eq!(cubes(&parents, coarse_sides(&parents, true)).len(), 1);
        assert_eq!(cubes(&parents, [128; 3]).len(), 8);
        // 512^3's parents (264 a side): two equal groups per axis, not 128 + 128 + 8, nor the
        // cap's 160 + 104 (evened at the cap), nor more groups for a sparse request.
        let parents = slab(66, 66, 66);
        assert_eq!(coarse_sides(&parents, true), [132; 3]);
        assert_eq!(coarse_sides(&parents, false), [160; 3]);
        // Three bricks: in two cubes of 160 (40 bricks), in three of the even boxes of 84.
        let scattered = vec![[0, 0, 0], [25, 0, 0], [41, 41, 0]];
        assert_eq!(even_sides(&scattered, 160), [84, 84, 160]);
        assert_eq!(
            group_sides(&scattered, 160, true, limit, two_passes),
            [160; 3]
        );
        // The finest level and a sparse request's coarse levels keep the cap as given;
        // without one, levels halve 512.
        assert_eq!(group_cap(Some(128), 0, true), 128);
        assert_eq!(group_cap(Some(128), 1, false), 128);
        assert_eq!(group_cap(None, 2, true), 128);
        assert_eq!(group_cap(Some(12), 1, true), 12);
        assert_eq!(group_cap(Some(500), 1, true), 512);
    }

    #[test]
    fn a_box_too_large_for_one_cube_splits_into_equal_cubes() {
        // 512^3 where cubes of at most 488 fit: eight of 256, not one of 488 and seven slivers.
        let fits_488 = |e: [u64; 3]| e.iter().product::<u64>();
        let limit = 488u64.pow(3);
        let all = slab(128, 128, 128);
        assert_eq!(group_sides(&all, 512, false, limit, fits_488), [256; 3]);
        let groups = cubes(&all, [256; 3]);
        assert_eq!(groups.len(), 8);
        assert!(groups.iter().all(|g| g.len() == 64 * 64 * 64));
        // Uneven extents (whose cubes of 512 fit: 512 x 400 x 400 and a slab): each axis split
        // as few times as the cubes split it, into equal parts.
        let long = slab(150, 100, 100);
        let sides = group_sides(&long, 512, false, limit, fits_488);
        assert_eq!(sides, [300, 512, 512], "600 in two of 300, 400 in one");
        let groups = cubes(&long, sides);
        assert_eq!(groups.len(), 2);
        assert!(groups.iter().all(|g| g.len() == 75 * 100 * 100));
        // A thin request whose cubes fit by their contents (a dense cube of 128 at most): its
        // 512-voxel cubes evened out too.
        let thin = slab(150, 150, 2);
        let limit = 512 * 512 * 8 + 1;
        assert!(fits_488([136; 3]) > limit);
        assert_eq!(
            group_sides(&thin, 512, false, limit, fits_488),
            [300, 300, 512]
        );
        assert_eq!(cubes(&thin, [300, 300, 512]).len(), 4);
        // Not where the even boxes would be more groups: an L of bricks in a 600^2 square is
        // three cubes of 512 (the far corner's is empty) but four boxes of 300.
        let mut corner: Vec<Brick> = slab(150, 150, 1)
            .into_iter()
            .filter(|b| b[0] < 128 || b[1] < 128)
            .collect();
        corner.sort_by_key(|b| (b[2], b[1], b[0]));
        let sides = group_sides(&corner, 512, false, limit, fits_488);
        assert_eq!(cubes(&corner, sides).len(), 3, "{sides:?}");
    }

    #[test]
    fn the_cap_and_the_smallest_side_hold() {
        // A user's cap is never exceeded, even when a larger cube would fit.
        assert_eq!(
            group_sides(&slab(8, 8, 1), 64, false, 128 << 20, two_passes),
            [64; 3]
        );
        // A limit too small for anything still gives whole bricks.
        assert_eq!(
            group_sides(&slab(8, 8, 8), 512, false, 1, two_passes),
            [8; 3]
        );
        assert_eq!(cubes(&slab(8, 8, 8), [8; 3]).len(), 8 * 8 * 8 / 8);
    }

    #[test]
    fn cubes_keep_every_brick_once_in_z_y_x_order() {
        let all = slab(10, 6, 3);
        let groups = cubes(&all, [16; 3]);
        let mut seen: Vec<Brick> = groups.concat();
        assert_eq!(seen.len(), all.len());
        seen.sort_by_key(|b| (b[2], b[1], b[0]));
        assert_eq!(seen, all);
        // The first cube holds the origin, the last the far corner.
        assert!(groups[0].contains(&[0, 0, 0]));
        assert!(groups.last().unwrap().contains(&[9, 5, 2]));
        assert!(groups.iter().all(|g| g.len() <= 64));
    }

    /// The bounds and boxes of random scattered brick sets, from within one box (the fast
    /// path) to spread over many, against a plain grouping by each brick's box.
    #[test]
    fn cube_bounds_and_cubes_agree_with_grouping_by_key() {
        let mut seed = 11u32;
        let mut next = |n: i32| {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as i32 % n
        };
        for case in 0..200 {
            let spread = [1, 3, 4, 5, 9, 40][case % 6];
            let side = [8u32, 16, 20, 64][case / 6 % 4];
            let origin = [next(50) - 25, next(50) - 25, next(50) - 25];
            let mut all: Vec<Brick> = (0..1 + next(60))
                .map(|_| [0, 1, 2].map(|i| origin[i] + next(spread)))
                .collect();
            all.sort_by_key(|b| (b[2], b[1], b[0]));
            all.dedup();
            let size = cube_bricks(side);
            let lo = bricks::bounds(&all).unwrap().0;
            let mut expected: BTreeMap<[i32; 3], Vec<Brick>> = Default::default();
            for b in &all {
                expected
                    .entry(cube_key(*b, lo, [size; 3]))
                    .or_default()
                    .push(*b);
            }
            let groups: Vec<Vec<Brick>> = expected.into_values().collect();
            assert_eq!(cubes(&all, [side; 3]), groups, "case {case}");
            assert_eq!(
                is_one_cube(&all, [side; 3]),
                groups.len() == 1,
                "case {case}"
            );
            let mut bounds = cube_bounds(&all, [side; 3]);
            let mut want: Vec<(Brick, Brick)> =
                groups.iter().map(|g| bricks::bounds(g).unwrap()).collect();
            bounds.sort();
            want.sort();
            assert_eq!(bounds, want, "case {case}");
        }
    }
}
