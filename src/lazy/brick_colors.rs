//! The colours (and triples) of a set of finest-level bricks, with their lookup by voxel.

use super::request::Job;
use super::*;

/// The colours (and, when asked, triples) of a set of finest-level bricks.
pub struct BrickColors {
    /// The bricks, sorted as [`bricks::normalize`] sorts them (z, then y, then x).
    pub bricks: Vec<Brick>,
    /// A dense brick -> position table when the bricks fill their bounding box well enough (a
    /// box); `None` for a sparse request (a surface's shell), whose bounding box would cost more
    /// than the bricks: positions are then found by binary search.
    pub grid: Option<BrickGrid>,
    /// 64 packed colours per brick (x fastest inside the brick).
    pub colors: Vec<u32>,
    /// 3 packed coordinates per voxel, when asked.
    pub triples: Vec<u32>,
}

impl BrickColors {
    /// The dense table for `sorted` bricks, when it holds at most 8 cells per brick.
    pub(super) fn lookup(sorted: &[Brick]) -> Option<BrickGrid> {
        let (lo, hi) = bricks::bounds(sorted).unwrap_or_default();
        let cells = (0..3).fold(1u64, |n, i| n.saturating_mul((hi[i] - lo[i] + 1) as u64));
        (cells <= 8 * sorted.len().max(1) as u64).then(|| BrickGrid::new(sorted))
    }

    /// Position of brick `b` in `sorted`, through `grid` when there is one.
    pub(super) fn slot_in(sorted: &[Brick], grid: Option<&BrickGrid>, b: Brick) -> Option<usize> {
        match grid {
            Some(g) => g.slot(b).map(|s| s as usize),
            None => sorted
                .binary_search_by_key(&(b[2], b[1], b[0]), |x| (x[2], x[1], x[0]))
                .ok(),
        }
    }

    /// Position of voxel `p` in `colors` (None when its brick was not requested).
    pub fn index(&self, p: [i32; 3]) -> Option<usize> {
        Self::slot_in(&self.bricks, self.grid.as_ref(), bricks::brick_of(p))
            .map(|s| s * bricks::BRICK_VOXELS as usize + bricks::local_index(p) as usize)
    }

    /// Packed colour of voxel `p`.
    pub fn color(&self, p: [i32; 3]) -> Option<u32> {
        self.index(p).map(|i| self.colors[i])
    }

    /// [`Self::color`] for voxels visited in a coherent order (an atlas' texels): `last`
    /// remembers the previous voxel's brick and slot, so a run of voxels in one brick costs
    /// one search (without a dense table, a search is a binary search over every brick).
    pub fn color_near(&self, p: [i32; 3], last: &mut Option<(Brick, usize)>) -> Option<u32> {
        let b = bricks::brick_of(p);
        let slot = match *last {
            Some((lb, slot)) if lb == b => slot,
            _ => {
                let slot = Self::slot_in(&self.bricks, self.grid.as_ref(), b)?;
                *last = Some((b, slot));
                slot
            }
        };
        Some(self.colors[slot * bricks::BRICK_VOXELS as usize + bricks::local_index(p) as usize])
    }
}

impl Synthesizer {
    /// [`Self::synthesize_bricks`] as `job` says (with `job.exact`, only the voxels of that box
    /// are meaningful in the result).
    pub(super) fn synthesize_bricks_of(
        &mut self,
        requested: &[Brick],
        job: Job,
    ) -> Result<BrickColors> {
        let want_triples = job.want_triples;
        let mut all = requested.to_vec();
        bricks::normalize(&mut all);
        let grid = BrickColors::lookup(&all);
        let mut colors = vec![0u32; all.len() * 64];
        let mut triples = vec![0u32; if want_triples { all.len() * 64 * 3 } else { 0 }];
        self.for_each_group(&all, job, |group, c, t| {
            for (j, b) in group.iter().enumerate() {
                let slot = BrickColors::slot_in(&all, grid.as_ref(), *b).expect("requested brick");
                colors[slot * 64..(slot + 1) * 64].copy_from_slice(&c[j * 64..(j + 1) * 64]);
                if want_triples {
                    triples[slot * 192..(slot + 1) * 192]
                        .copy_from_slice(&t[j * 192..(j + 1) * 192]);
                }
            }
            Ok(())
        })?;
        Ok(BrickColors {
            bricks: all,
            grid,
            colors,
            triples,
        })
    }
}
