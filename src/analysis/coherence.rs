//! The coherence filter (paper 4.2): keep a triple of pixel p in E_a only if, for each of the two
//! other exemplars, some neighbouring pixel's candidate continues it there.
//!
//! The paper writes the test as |C[p + d]_y - c_y| = 1 for some unit offset d. We use its exact
//! geometric meaning: the volume axis shared by the planes of E_a and E_{a+1} is a+2, which is v
//! in E_a and u in E_{a+1}; so the neighbour p + (0, s) (s = +-1) must hold a candidate whose
//! E_{a+1} coordinate is c_{a+1} + (s, 0). Likewise the neighbour p + (s, 0) must hold one whose
//! E_{a+2} coordinate is c_{a+2} + (0, s). Sets shrink each round (neighbours lose candidates
//! too), until every pixel has at most `max_kept` or nothing changes; then the lowest-CB
//! `max_kept` remain. A pixel may end with none (cf. the paper's Fig. 13); inspect reports them.

use super::crossbar::RankedTriple;
use crate::exemplar::Border;
use rayon::prelude::*;

/// Size of one exemplar (for neighbour and coordinate arithmetic).
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    pub width: u32,
    pub height: u32,
}

impl Grid {
    /// Index of (x + dx, y + dy), or None when it leaves a non-tiling exemplar.
    fn offset(&self, index: u32, dx: i32, dy: i32, border: Border) -> Option<u32> {
        let (x, y) = (
            (index % self.width) as i32 + dx,
            (index / self.width) as i32 + dy,
        );
        let (w, h) = (self.width as i32, self.height as i32);
        match border {
            Border::Wrap => Some((y.rem_euclid(h) * w + x.rem_euclid(w)) as u32),
            Border::Mirror => {
                if x < 0 || y < 0 || x >= w || y >= h {
                    None
                } else {
                    Some((y * w + x) as u32)
                }
            }
        }
    }
}

/// Filter the ranked (ascending CB) sets of E_a in place, as the paper does: rounds run while some
/// pixel still has more than `max_kept` triples (at least one round, at most `max_rounds`, and
/// only while a round removes something); then the lowest-CB `max_kept` remain. Every triple kept
/// passed the test of the last round against its neighbours' sets as they were at that round's
/// start. `grids` = sizes of E_a, E_{a+1}, E_{a+2}. Returns the number of rounds run.
pub fn filter(
    sets: &mut [Vec<RankedTriple>],
    grids: [Grid; 3],
    border: Border,
    max_kept: usize,
    max_rounds: usize,
) -> usize {
    let mut rounds = 0;
    while rounds < max_rounds.max(1) {
        rounds += 1;
        let changed = filter_round(sets, grids, border);
        if !changed || !sets.iter().any(|s| s.len() > max_kept) {
            break;
        }
    }
    sets.iter_mut().for_each(|s| s.truncate(max_kept));
    rounds
}

/// One Jacobi round: every set is filtered against the sets as they were at the round's start.
/// Returns whether anything was removed.
fn filter_round(sets: &mut [Vec<RankedTriple>], grids: [Grid; 3], border: Border) -> bool {
    // Sorted coordinate lists of every pixel's current set, for binary search.
    let keys: Vec<(Vec<u32>, Vec<u32>)> = sets
        .par_iter()
        .map(|s| {
            let mut n1: Vec<u32> = s.iter().map(|t| t.next1).collect();
            let mut n2: Vec<u32> = s.iter().map(|t| t.next2).collect();
            n1.sort_unstable();
            n2.sort_unstable();
            (n1, n2)
        })
        .collect();
    sets.par_iter_mut()
        .enumerate()
        .map(|(p, set)| {
            let before = set.len();
            set.retain(|t| supported(p as u32, t, &keys, grids, border));
            set.len() != before
        })
        .reduce(|| false, |a, b| a || b)
}

/// Whether triple `t` of pixel `p` is continued by a neighbour in both other exemplars.
pub fn is_coherent(
    p: u32,
    t: &RankedTriple,
    sets: &[Vec<RankedTriple>],
    grids: [Grid; 3],
    border: Border,
) -> bool {
    let has = |np: u32, f: &dyn Fn(&RankedTriple) -> bool| sets[np as usize].iter().any(f);
    let in_next1 = [-1i32, 1].iter().any(|&s| {
        match (
            grids[0].offset(p, 0, s, border),
            grids[1].offset(t.next1, s, 0, border),
        ) {
            (Some(np), Some(want)) => has(np, &|c| c.next1 == want),
            _ => false,
        }
    });
    in_next1
        && [-1i32, 1].iter().any(|&s| {
            match (
                grids[0].offset(p, s, 0, border),
                grids[2].offset(t.next2, 0, s, border),
            ) {
                (Some(np), Some(want)) => has(np, &|c| c.next2 == want),
                _ => false,
            }
        })
}

fn supported(
    p: u32,
    t: &RankedTriple,
    keys: &[(Vec<u32>, Vec<u32>)],
    grids: [Grid; 3],
    border: Border,
) -> bool {
    let in_next1 = [-1i32, 1].iter().any(|&s| {
        match (
            grids[0].offset(p, 0, s, border),
            grids[1].offset(t.next1, s, 0, border),
        ) {
            (Some(np), Some(want)) => keys[np as usize].0.binary_search(&want).is_ok(),
            _ => false,
        }
    });
    in_next1
        && [-1i32, 1].iter().any(|&s| {
            match (
                grids[0].offset(p, s, 0, border),
                grids[2].offset(t.next2, 0, s, border),
            ) {
                (Some(np), Some(want)) => keys[np as usize].1.binary_search(&want).is_ok(),
                _ => false,
            }
        })
}
