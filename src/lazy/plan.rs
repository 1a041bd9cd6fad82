//! Which voxels each step of a box synthesis must compute, so that the box holds exactly the
//! values of the infinite solid (spatial determinism, paper 5.2).
//!
//! A correction sub-pass updates the voxels of one parity class (x, y, z mod 2) and reads, for
//! each, the three 5x5 planes through it (its 3-neighbourhood and its k-coherent sources). It
//! reads a neighbour in its own 4x4x4 brick as the earlier sub-passes of the pass left it, and a
//! neighbour in another brick as it was when the pass began (`cpu::correct`, brick-local
//! sub-passes). So a pass's dependencies stay within its bricks plus 2 voxels: planning runs
//! backwards from the requested box, a pass computes every voxel of the bricks covering what
//! must be correct after it, and needs, when it begins, those bricks and 2 voxels around them.
//! The paper plans one dilation by the neighbourhood per pass in the same way (its Fig. 7); with
//! every read taking the latest value, sub-pass after sub-pass, the dependencies would chain
//! through the eight sub-passes (13 voxels of padding per level for two passes instead of 6 to 9
//! here; BENCHMARKS.md). At the start of a level, the union of needed boxes is what upsampling
//! (or the initialization) must provide, and half of it (rounded out) is what the coarser level
//! must deliver. Boxes make this slightly conservative but never short.

use super::SUBPASS_ORDER;

/// Requests stay within +-2^28 voxels of the origin (boxes, cut samples): every level's
/// coordinates and brick indices then fit the engine's 32-bit arithmetic.
pub const COORDINATE_LIMIT: i64 = 1 << 28;

/// A half-open box of integer voxel coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Box3 {
    pub lo: [i32; 3],
    pub hi: [i32; 3],
}

impl Box3 {
    pub fn new(lo: [i32; 3], hi: [i32; 3]) -> Box3 {
        Box3 { lo, hi }
    }
    pub fn size(&self) -> [u32; 3] {
        [0, 1, 2].map(|i| (self.hi[i] - self.lo[i]).max(0) as u32)
    }
    /// Voxels in the box (saturating: a box spanning the whole coordinate range holds more
    /// than a u64 counts).
    pub fn voxels(&self) -> u64 {
        self.size()
            .iter()
            .fold(1u64, |n, &s| n.saturating_mul(s as u64))
    }
    pub fn is_empty(&self) -> bool {
        (0..3).any(|i| self.hi[i] <= self.lo[i])
    }
    pub fn contains(&self, p: [i32; 3]) -> bool {
        (0..3).all(|i| p[i] >= self.lo[i] && p[i] < self.hi[i])
    }
    pub fn contains_box(&self, other: &Box3) -> bool {
        other.is_empty() || (0..3).all(|i| other.lo[i] >= self.lo[i] && other.hi[i] <= self.hi[i])
    }
    pub fn hull(&self, other: &Box3) -> Box3 {
        if self.is_empty() {
            return *other;
        }
        if other.is_empty() {
            return *self;
        }
        Box3 {
            lo: [0, 1, 2].map(|i| self.lo[i].min(other.lo[i])),
            hi: [0, 1, 2].map(|i| self.hi[i].max(other.hi[i])),
        }
    }
    /// Minkowski sum with the offsets [lo, hi] (inclusive) per axis.
    pub fn dilate(&self, lo: [i32; 3], hi: [i32; 3]) -> Box3 {
        Box3 {
            lo: [0, 1, 2].map(|i| self.lo[i] + lo[i]),
            hi: [0, 1, 2].map(|i| self.hi[i] + hi[i]),
        }
    }
    /// The smallest box holding every voxel of parity class `class` (bit i: parity along axis
    /// i) inside this one (empty when there is none, e.g. a one-voxel-thick box of the other
    /// parity).
    pub fn snapped_to_class(&self, class: usize) -> Box3 {
        let c = [0, 1, 2].map(|i| ((class >> i) & 1) as i32);
        Box3 {
            // First voxel >= lo, and one past the last voxel < hi, of parity c.
            lo: [0, 1, 2].map(|i| self.lo[i] + (self.lo[i] - c[i]).rem_euclid(2)),
            hi: [0, 1, 2].map(|i| self.hi[i] - (self.hi[i] - 1 - c[i]).rem_euclid(2)),
        }
    }
    /// The smallest box of whole bricks (multiples of 4) holding this one.
    pub fn snapped_to_bricks(&self) -> Box3 {
        if self.is_empty() {
            return *self;
        }
        Box3 {
            lo: self.lo.map(|v| v.div_euclid(BRICK) * BRICK),
            hi: self.hi.map(|v| (v - 1).div_euclid(BRICK) * BRICK + BRICK),
        }
    }

    /// The coarser-level box whose children cover this one.
    pub fn parent(&self) -> Box3 {
        Box3 {
            lo: self.lo.map(|v| v >> 1),
            hi: self.hi.map(|v| ((v - 1) >> 1) + 1),
        }
    }
    /// Row-major (x fastest) index of `p` inside this box.
    pub fn index(&self, p: [i32; 3]) -> usize {
        let s = self.size();
        (((p[2] - self.lo[2]) as usize * s[1] as usize) + (p[1] - self.lo[1]) as usize)
            * s[0] as usize
            + (p[0] - self.lo[0]) as usize
    }
}

/// How far a correction reads from its voxel along any axis: the 5x5 planes reach 2 (its
/// k-coherent sources, the 3x3 in-plane neighbours, are among them).
pub const READ_REACH: i32 = 2;

/// Brick edge (`bricks::BRICK`): a pass's sub-passes see each other's updates within a brick.
const BRICK: i32 = 4;

/// What one level of a box synthesis computes.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelPlan {
    /// Voxels stored at this level (everything any step reads or writes).
    pub storage: Box3,
    /// The box whose values the level must deliver (to the finer level, or as output).
    pub deliver: Box3,
    /// Per correction sub-pass in execution order (passes x SUBPASS_ORDER): the parity class
    /// and the box of its voxels to compute (possibly empty).
    pub subpasses: Vec<(usize, Box3)>,
}

/// Plan a synthesis of `output` (finest-level voxels) through one level per entry of `passes`,
/// each with that many correction passes (coarsest level first). Returned coarsest level first.
pub fn plan(output: Box3, passes: &[usize]) -> Vec<LevelPlan> {
    let mut plans = Vec::new();
    let mut deliver = output;
    for &level_passes in passes.iter().rev() {
        // What must hold its solid values after the pass being planned (the last one first).
        let mut need = deliver;
        let mut subpasses = Vec::new();
        for _ in 0..level_passes {
            // Every voxel of the bricks covering it: a voxel depends on the earlier sub-passes'
            // results in its own brick.
            let computed = need.snapped_to_bricks();
            if computed.is_empty() {
                // Nothing needed: no pass computes anything (the padding must not grow from
                // an empty box).
                subpasses.extend(SUBPASS_ORDER.iter().map(|&c| (c, computed)));
                continue;
            }
            for &c in SUBPASS_ORDER.iter().rev() {
                subpasses.push((c, computed.snapped_to_class(c)));
            }
            need = computed.dilate([-READ_REACH; 3], [READ_REACH; 3]);
        }
        subpasses.reverse();
        let storage = need.hull(&deliver);
        plans.push(LevelPlan {
            storage,
            deliver,
            subpasses,
        });
        deliver = storage.parent();
    }
    plans.reverse();
    plans
}

#[cfg(test)]
mod tests {
    use super::*;

    fn class_of(c: usize) -> [i32; 3] {
        [(c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32]
    }

    #[test]
    fn snapping_keeps_exactly_the_class_voxels() {
        for b in [
            Box3::new([0, 0, 0], [4, 4, 4]),
            Box3::new([-3, 2, 5], [4, 3, 6]),
            Box3::new([1, -1, 0], [2, 5, 7]),
        ] {
            for class in 0..8 {
                let s = b.snapped_to_class(class);
                let c = [0, 1, 2].map(|i| ((class >> i) & 1) as i32);
                let mut inside = Vec::new();
                for z in b.lo[2]..b.hi[2] {
                    for y in b.lo[1]..b.hi[1] {
                        for x in b.lo[0]..b.hi[0] {
                            let p = [x, y, z];
                            if (0..3).all(|i| p[i].rem_euclid(2) == c[i]) {
                                inside.push(p);
                                assert!(s.contains(p), "{b:?} {class} {p:?}");
                            }
                        }
                    }
                }
                assert_eq!(s.is_empty(), inside.is_empty(), "{b:?} {class}");
                if !s.is_empty() {
                    // Tight: its corners are class voxels of the box.
                    assert!(inside.contains(&s.lo));
                    assert!(inside.contains(&s.hi.map(|v| v - 1)));
                }
            }
        }
    }

    #[test]
    fn plan_reads_stay_inside_storage_and_shrink_to_the_output() {
        let out = Box3::new([-3, 5, 0], [20, 9, 16]);
        let plans = plan(out, &[2; 4]);
        assert_eq!(plans.last().unwrap().deliver, out);
        for (i, p) in plans.iter().enumerate() {
            for (_, b) in &p.subpasses {
                assert!(p.storage.contains_box(&b.dilate([-2; 3], [2; 3])));
            }
            if i + 1 < plans.len() {
                assert_eq!(plans[i + 1].storage.parent(), p.deliver);
            }
        }
        // The padding of the finest level: its bricks (out.lo[0] = -3 rounds to -4), one more
        // brick for the first pass, and 2 voxels around.
        let f = &plans[3];
        assert_eq!(f.storage, Box3::new([-10, -2, -6], [26, 18, 22]));
        // Every pass computes whole bricks, all of their voxels.
        for (class, b) in &f.subpasses {
            assert_eq!(b.lo.map(|v| v.rem_euclid(4)), class_of(*class), "{b:?}");
        }
    }

    #[test]
    fn parent_box_covers_children_with_negative_coordinates() {
        let b = Box3::new([-5, -4, 3], [-1, 4, 8]);
        let p = b.parent();
        // Children -5..=-2 have parents -3..=-1 (floor division), so the exclusive bound is 0.
        assert_eq!(p, Box3::new([-3, -2, 1], [0, 2, 4]));
    }
}
