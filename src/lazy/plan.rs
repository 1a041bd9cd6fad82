//! Which voxels each step of a box synthesis must compute, so that the box holds exactly the
//! values of the infinite solid (spatial determinism, paper 5.2).
//!
//! A correction sub-pass updates the voxels of one parity class (x, y, z mod 2) and reads, for
//! each, the three 5x5 planes through it (its 3-neighbourhood and its k-coherent sources). Planning
//! runs backwards from the requested box: per class, the box of voxels whose values are still
//! needed; a sub-pass must compute its class's needed box, and every voxel it reads becomes needed
//! before it. At the start of a level, the union of needed boxes is what upsampling (or the
//! initialization) must provide, and half of it (rounded out) is what the coarser level must
//! deliver. Boxes make this slightly conservative but never short.

use super::SUBPASS_ORDER;

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
    pub fn voxels(&self) -> u64 {
        self.size().iter().map(|&s| s as u64).product()
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

/// Offsets a correction reads: the three 5x5 planes through the voxel.
pub fn footprint() -> Vec<[i32; 3]> {
    let mut d = Vec::new();
    for z in -2..=2 {
        for y in -2..=2 {
            for x in -2..=2i32 {
                if x == 0 || y == 0 || z == 0 {
                    d.push([x, y, z]);
                }
            }
        }
    }
    d
}

fn class_of(c: usize) -> [i32; 3] {
    [(c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32]
}

/// For reader class `c` and read class `k`: the per-axis extent of footprint offsets from a
/// class-c voxel landing on a class-k voxel (None when no offset does).
fn extents() -> [[Option<([i32; 3], [i32; 3])>; 8]; 8] {
    let mut out = [[None; 8]; 8];
    for c in 0..8 {
        let pc = class_of(c);
        for d in footprint() {
            let k = (0..3)
                .map(|i| (((pc[i] + d[i]).rem_euclid(2)) as usize) << i)
                .sum::<usize>();
            let e = out[c][k].get_or_insert((d, d));
            for i in 0..3 {
                e.0[i] = e.0[i].min(d[i]);
                e.1[i] = e.1[i].max(d[i]);
            }
        }
    }
    out
}

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
    let ext = extents();
    let mut plans = Vec::new();
    let mut deliver = output;
    for &level_passes in passes.iter().rev() {
        let mut need = [deliver; 8];
        let mut subpasses = Vec::new();
        for _ in 0..level_passes {
            for &c in SUBPASS_ORDER.iter().rev() {
                // Only the class's own voxels are computed: reads are dilated from their hull
                // (a thin box may hold none of a class).
                let computed = need[c].snapped_to_class(c);
                subpasses.push((c, computed));
                if computed.is_empty() {
                    continue;
                }
                // Voxel c is overwritten here: before it, class c is needed only where read.
                need[c] = Box3::new([0; 3], [0; 3]);
                for k in 0..8 {
                    if let Some((lo, hi)) = ext[c][k] {
                        need[k] = need[k].hull(&computed.dilate(lo, hi));
                    }
                }
            }
        }
        subpasses.reverse();
        let storage = need.iter().fold(deliver, |acc, b| acc.hull(b));
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
        // The padding of the finest level stays small (13 voxels with the chosen order).
        let f = &plans[3];
        assert!(
            f.storage.lo[0] >= out.lo[0] - 13 && f.storage.hi[2] <= out.hi[2] + 13,
            "{:?}",
            f.storage
        );
    }

    #[test]
    fn parent_box_covers_children_with_negative_coordinates() {
        let b = Box3::new([-5, -4, 3], [-1, 4, 8]);
        let p = b.parent();
        // Children -5..=-2 have parents -3..=-1 (floor division), so the exclusive bound is 0.
        assert_eq!(p, Box3::new([-3, -2, 1], [0, 2, 4]));
    }
}
