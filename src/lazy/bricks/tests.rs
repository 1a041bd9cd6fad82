use super::plans::*;
use super::*;
use std::collections::HashSet;

fn brute_dilate(set: &[Brick], lo: [i32; 3], hi: [i32; 3]) -> Vec<Brick> {
    let mut out = HashSet::new();
    for b in set {
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    out.insert([b[0] + x, b[1] + y, b[2] + z]);
                }
            }
        }
    }
    let mut v: Vec<Brick> = out.into_iter().collect();
    normalize(&mut v);
    v
}

#[test]
fn dilation_equals_brute_force() {
    let set = vec![[0, 0, 0], [5, -3, 2], [-7, 1, 1], [6, -3, 2]];
    for (lo, hi) in [
        ([-1, -2, 0], [1, 0, 3]),
        ([0, 0, 0], [0, 0, 0]),
        ([-4, -4, -4], [4, 4, 4]),
        ([1, 2, -3], [2, 2, -1]),
    ] {
        assert_eq!(
            dilate(&set, lo, hi),
            brute_dilate(&set, lo, hi),
            "{lo:?} {hi:?}"
        );
    }
    // Random sets and ranges (seeded), ranges beside zero and wider than the set included.
    let mut rng = crate::util::hash::SeededRng::new(36);
    for _ in 0..200 {
        let count = 1 + rng.below(30) as usize;
        let set: Vec<Brick> = (0..count)
            .map(|_| [0; 3].map(|_: i32| rng.below(12) as i32 - 6))
            .collect();
        let a = [0; 3].map(|_: i32| rng.below(9) as i32 - 4);
        let b = [0; 3].map(|_: i32| rng.below(9) as i32 - 4);
        let (lo, hi) = (
            [0, 1, 2].map(|i| a[i].min(b[i])),
            [0, 1, 2].map(|i| a[i].max(b[i])),
        );
        assert_eq!(
            dilate(&set, lo, hi),
            brute_dilate(&set, lo, hi),
            "{set:?} {lo:?} {hi:?}"
        );
    }
}

#[test]
fn voxel_indices_are_unique_and_round_trip() {
    let bricks = vec![[0, 0, 0], [-1, 2, 3], [4, -5, 0]];
    let grid = BrickGrid::new(&bricks);
    let mut seen = HashSet::new();
    for (slot, &b) in bricks.iter().enumerate() {
        for l in 0..BRICK_VOXELS {
            let p = voxel_of(b, l);
            assert_eq!(brick_of(p), b);
            assert_eq!(local_index(p), l);
            let i = grid.voxel_index(p).unwrap();
            assert_eq!(i / 64, slot);
            assert!(seen.insert(i));
        }
    }
    assert_eq!(grid.voxel_index([100, 0, 0]), None);
    assert_eq!(grid.voxel_index([4, 0, 0]), None);
}

fn same_plans(a: &[SparseLevel], b: &[SparseLevel]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.bricks, y.bricks);
        assert_eq!(x.grid, y.grid);
        assert_eq!(x.deliver, y.deliver);
        assert_eq!(x.subpasses.len(), y.subpasses.len());
        for (p, q) in x.subpasses.iter().zip(&y.subpasses) {
            assert_eq!(p.class, q.class);
            assert_eq!(p.active(&x.bricks), q.active(&y.bricks));
        }
    }
}

#[test]
fn box_plans_equal_the_general_planner() {
    for (lo, hi) in [
        ([0, 0, 0], [0, 0, 0]),
        ([0, 0, 0], [3, 3, 3]),
        ([-3, 2, -7], [1, 2, -5]),
        ([5, -1, 0], [9, 6, 2]),
    ] {
        let output = bricks_of_box(Box3::new(
            lo.map(|v| v * BRICK),
            hi.map(|v| (v + 1) * BRICK),
        ));
        assert_eq!(brick_box(&output), Some((lo, hi)));
        for passes in [[2, 2, 2, 2], [2, 2, 2, 1], [1, 3, 0, 2]] {
            same_plans(
                &plan_sparse(&output, &passes),
                &plan_general(output.clone(), &passes),
            );
        }
    }
    // Not a box: one brick missing.
    let mut holed = bricks_of_box(Box3::new([0; 3], [12; 3]));
    holed.remove(13);
    assert_eq!(brick_box(&holed), None);
}

#[test]
fn voxel_exact_boxes_compute_a_subset_of_the_brick_plan() {
    let bits = |p: &SparseLevel| -> u32 {
        p.subpasses
            .iter()
            .flat_map(|sp| sp.active(&p.bricks))
            .map(|(_, m)| m.count_ones())
            .sum()
    };
    for (out, thin) in [
        (Box3::new([-5, 3, 7], [30, 21, 8]), true),
        (Box3::new([0, 0, 0], [16, 16, 16]), false),
        (Box3::new([-9, -1, 2], [3, 14, 13]), false),
    ] {
        for passes in [[2, 2, 2, 2], [2, 2, 2, 1]] {
            let exact = plan_voxel_box(out, &passes);
            let bricks = plan_sparse(&bricks_of_box(out), &passes);
            let (e, b) = (exact.last().unwrap(), bricks.last().unwrap());
            assert_eq!(e.deliver, b.deliver);
            for (se, sb) in e.subpasses.iter().zip(&b.subpasses) {
                let wide: std::collections::HashMap<Brick, u8> =
                    sb.active(&b.bricks).into_iter().collect();
                for (brick, m) in se.active(&e.bricks) {
                    assert_eq!(m & !wide[&brick], 0, "{out:?} {brick:?}");
                }
            }
            if thin {
                // Passes compute whole bricks (brick-local sub-passes, `plan`): a thin box
                // computes what its bricks do.
                assert_eq!(bits(e), bits(b));
            }
        }
    }
}

/// A sub-pass's masks: class voxel v is needed exactly when some delivered brick b has
/// v - 4b inside the per-brick box, checked voxel by voxel for seeded random scattered sets
/// and boxes. (The planner's own boxes are whole bricks grown by whole bricks, whose masks
/// are all or nothing: random boxes also cut bricks in two.)
/// `Presence::any` against a scan of the set, for random sets (empty, repeated bricks,
/// negative coordinates) and random boxes reaching past the set's bounds on every side.
#[test]
fn presence_answers_as_a_scan_does() {
    let mut rng = crate::util::hash::SeededRng::new(31);
    for case in 0..300 {
        let count = rng.below(20) as usize * (case % 5).min(1);
        let spread = 1 + rng.below(9) as i32;
        let set: Vec<Brick> = (0..count)
            .map(|_| [0; 3].map(|_: i32| rng.below(spread as u64) as i32 - spread / 2))
            .collect();
        let presence = Presence::new(&set);
        for _ in 0..40 {
            let lo = [0; 3].map(|_: i32| rng.below(14) as i32 - 8);
            let hi = lo.map(|v| v + rng.below(6) as i32 - 1);
            let scan = set
                .iter()
                .any(|b| (0..3).all(|i| lo[i] <= b[i] && b[i] <= hi[i]));
            assert_eq!(
                presence.any(lo, hi),
                scan,
                "case {case}: {lo:?}..={hi:?} in {set:?}"
            );
        }
    }
}

#[test]
fn sub_pass_masks_equal_brute_force() {
    let mut rng = crate::util::hash::SeededRng::new(7);
    for _ in 0..40 {
        let count = 1 + rng.below(12) as usize;
        let mut deliver: Vec<Brick> = (0..count)
            .map(|_| [0; 3].map(|_: i32| rng.below(10) as i32 - 5))
            .collect();
        normalize(&mut deliver);
        deliver.dedup();
        let lo = [0; 3].map(|_: i32| rng.below(9) as i32 - 6);
        let needed = Box3::new(lo, lo.map(|v| v + 1 + rng.below(10) as i32));
        let class = rng.below(8) as usize;
        let (rlo, rhi) = offset_range(needed).unwrap();
        let candidates = dilate(&deliver, rlo, rhi);
        let sp = subpass_plan(class, needed, &candidates, &Presence::new(&deliver));
        let got: std::collections::HashMap<Brick, u8> = sp
            .bricks
            .iter()
            .copied()
            .zip(sp.masks.iter().copied())
            .collect();
        let c = [0, 1, 2].map(|i| ((class >> i) & 1) as i32);
        for a in dilate(&deliver, [-4; 3], [4; 3]) {
            let mut want = 0u8;
            for k in 0..8 {
                let v = [0, 1, 2].map(|i| a[i] * BRICK + c[i] + 2 * ((k >> i) & 1));
                if deliver
                    .iter()
                    .any(|b| needed.contains([0, 1, 2].map(|i| v[i] - b[i] * BRICK)))
                {
                    want |= 1 << k;
                }
            }
            let have = got.get(&a).copied().unwrap_or(0);
            assert_eq!(
                have, want,
                "{deliver:?} {needed:?} class {class} brick {a:?}"
            );
        }
    }
}

#[test]
fn sparse_plan_reads_stay_inside_storage() {
    // Every voxel a needed sub-pass voxel reads is stored, at every level.
    let output = vec![[0, 0, 0], [3, 1, -2], [-5, 0, 0]];
    let levels = plan_sparse(&output, &[2; 4]);
    for l in &levels {
        for sp in &l.subpasses {
            let set = &sp.bricks;
            let reads = dilate(set, [-1; 3], [1; 3]);
            // Reads of a 2-voxel footprint stay within one brick of the active brick, but only
            // needed voxels must be covered: check the per-brick needed boxes directly.
            let _ = reads;
            for b in set {
                assert!(l.grid.slot(*b).is_some(), "active brick {b:?} not stored");
            }
        }
    }
    for w in levels.windows(2) {
        for b in &w[1].bricks {
            assert!(w[0].grid.slot(b.map(|v| v >> 1)).is_some());
        }
    }
    assert_eq!(levels.last().unwrap().deliver.len(), 3);
}

    #[test]
    fn voxel_box_recognizes_exactly_the_boxes() {
        let mut slice: Vec<[i32; 3]> = (0..6)
            .flat_map(|y| (0..5).map(move |x| [x - 2, y, 7]))
            .collect();
        slice.reverse();
        assert_eq!(voxel_box(&slice), Some(Box3::new([-2, 0, 7], [3, 6, 8])));
        // A repeat in place of a voxel: as many voxels as the box, not the box.
        let mut repeated = slice.clone();
        repeated[3] = repeated[4];
        assert_eq!(voxel_box(&repeated), None);
        assert_eq!(voxel_box(&slice[1..]), None);
        // In storage order (x fastest), as a z cut lists them, and with a repeat there.
        let mut ordered = slice.clone();
        ordered.reverse();
        assert_eq!(voxel_box(&ordered), Some(Box3::new([-2, 0, 7], [3, 6, 8])));
        ordered[3] = ordered[4];
        assert_eq!(voxel_box(&ordered), None);
        assert_eq!(voxel_box(&[]), None);
        assert_eq!(voxel_box(&[[i32::MAX, 0, 0]]), None);
    }
