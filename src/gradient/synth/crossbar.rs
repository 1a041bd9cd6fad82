//! Crossbar-consistent candidate sets (paper 4.2.1).
//!
//! "We then search for the patch E_y that best matches s_y from a set of N_1 candidates with
//! the most consistent crossbar voxels as E_x": the set depends on E_x alone, not on the slice,
//! so it is computed once per level for every candidate that can be E_x. A [`ConsistentSets`]
//! holds, for every candidate c, the K candidates whose `to` line (row or column through the
//! centre) is nearest to c's `from` line by the exact sum of squared differences of the
//! crossbar voxels ([`LevelPatches::line_distance`]; ties by index). The per check point work
//! is then a few dozen distances in PCA space instead of a k-nearest search (see
//! [`super::matching::match_check_point`]).
//!
//! The sets are found approximately: the `to` lines are PCA-projected and indexed like the
//! patches ([`IvfIndex`]); each `from` line takes the `PRESELECT` x K nearest there, which are
//! then ranked by their exact line distance. Deterministic like everything else here.

use super::ivf::IvfIndex;
use super::patches::{LevelPatches, Line};
use super::pca::PatchPca;
use rayon::prelude::*;

/// Lists the approximate search of the lines scans.
const PROBES: usize = 4;
/// Preselected candidates per kept one, ranked by the exact line distance. 1: the PCA's nearest
/// K are kept, only reordered (in the unit test 4 lists and 1x keep 98% of the exact sets;
/// 8 lists and 2x, 100%, for 40% more building time and eval ratios within noise).
const PRESELECT: usize = 1;

/// Largest set size (N_1 and N_2 are at most this).
pub const MAX_SET: usize = 256;

/// Per candidate, the `k` candidates most crossbar-consistent with it for one pair of lines.
pub struct ConsistentSets {
    k: usize,
    sets: Vec<u32>,
    /// The line distance of every set member to its candidate (what ranked it).
    distances: Vec<u32>,
}

impl ConsistentSets {
    /// For every candidate c, the `k` candidates whose `to` line is nearest to c's `from` line.
    pub fn build(patches: &LevelPatches, from: Line, to: Line, k: usize, seed: u64) -> Self {
        let n = patches.candidates();
        let k = k.clamp(1, n.min(MAX_SET));
        let dims = patches.line_len();
        let as_floats = |i: u32, line: Line| patches.line(i, line).iter().map(|&v| v as f32);
        let targets: Vec<f32> = (0..n as u32).flat_map(|i| as_floats(i, to)).collect();
        let pca = PatchPca::fit(&targets, dims, seed);
        let points = pca.project_each(n, |i, buffer| buffer.extend(as_floats(i as u32, to)));
        let index = IvfIndex::build(&points);
        let ranked: Vec<(u32, u32)> = (0..n as u32)
            .into_par_iter()
            .flat_map_iter(|c| {
                let query: Vec<f32> = as_floats(c, from).collect();
                let near = index.nearest(&pca.project(&query), PRESELECT * k, Some(PROBES));
                let mut ranked: Vec<(u32, u32)> = near
                    .iter()
                    .map(|&(_, j)| (patches.line_distance(c, from, j, to), j))
                    .collect();
                ranked.sort_unstable();
                ranked.truncate(k);
                ranked
            })
            .collect();
        ConsistentSets {
            k,
            sets: ranked.iter().map(|&(_, j)| j).collect(),
            distances: ranked.iter().map(|&(d, _)| d).collect(),
        }
    }

    /// Candidates per set.
    pub fn set_size(&self) -> usize {
        self.k
    }

    /// The candidates most consistent with `c`, most consistent first.
    #[inline(always)]
    pub fn of(&self, c: u32) -> &[u32] {
        &self.sets[c as usize * self.k..(c as usize + 1) * self.k]
    }

    /// The line distances of [`Self::of`]`(c)` to `c`.
    #[inline(always)]
    pub fn distances(&self, c: u32) -> &[u32] {
        &self.distances[c as usize * self.k..(c as usize + 1) * self.k]
    }
}

/// The sets a check point's search reads: E_y's (by E_x's line) and, with three slices, E_z's
/// by E_x's other line (its set by E_y's line is `for_ey` again: the same pair of lines).
pub struct CrossbarSets {
    pub for_ey: ConsistentSets,
    pub for_ez: Option<ConsistentSets>,
}

impl CrossbarSets {
    /// The sets of the cyclic axes (three slices: E_y's row against E_x's column, E_z's column
    /// against E_x's row) or the upright ones (two slices: E_y's column against E_x's column),
    /// `k` per candidate.
    pub fn build(patches: &LevelPatches, three: bool, k: usize, seed: u64) -> Self {
        if three {
            CrossbarSets {
                for_ey: ConsistentSets::build(patches, Line::Column, Line::Row, k, seed),
                for_ez: Some(ConsistentSets::build(
                    patches,
                    Line::Row,
                    Line::Column,
                    k,
                    seed ^ 1,
                )),
            }
        } else {
            CrossbarSets {
                for_ey: ConsistentSets::build(patches, Line::Column, Line::Column, k, seed),
                for_ez: None,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_hold_mostly_the_exactly_most_consistent_candidates() {
        let img = crate::exemplar::default_exemplar().crop(0, 0, 64, 64);
        let patches = LevelPatches::build(&img, 1, 9, None, None, 3).unwrap();
        let k = 20;
        let sets = ConsistentSets::build(&patches, Line::Column, Line::Row, k, 5);
        let n = patches.candidates() as u32;
        let mut recall = 0.0;
        let tested: Vec<u32> = (0..n).step_by(37).collect();
        for &c in &tested {
            let mut exact: Vec<(u32, u32)> = (0..n)
                .map(|j| (patches.line_distance(c, Line::Column, j, Line::Row), j))
                .collect();
            exact.sort_unstable();
            let exact: Vec<u32> = exact[..k].iter().map(|&(_, j)| j).collect();
            let set = sets.of(c);
            assert_eq!(set.len(), k);
            // Most consistent first, distinct.
            let d = |j: u32| patches.line_distance(c, Line::Column, j, Line::Row);
            assert!(set.windows(2).all(|w| (d(w[0]), w[0]) < (d(w[1]), w[1])));
            let stored: Vec<u32> = set.iter().map(|&j| d(j)).collect();
            assert_eq!(sets.distances(c), stored);
            recall += set.iter().filter(|j| exact.contains(j)).count() as f64 / k as f64;
        }
        let recall = recall / tested.len() as f64;
        assert!(recall >= 0.85, "recall of the exact sets {recall:.3}");
        // Deterministic.
        let again = ConsistentSets::build(&patches, Line::Column, Line::Row, k, 5);
        assert_eq!(again.sets, sets.sets);
    }
}
