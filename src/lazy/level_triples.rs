//! The triples of a level's bricks kept on the host between groups: a box's shared coarse
//! levels, synthesized once and handed to each group of the finer level as its parents.

use super::bricks::{self, Brick, BrickGrid, SparseLevel};
use super::BrickColors;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// The triples of a set of bricks of one level, held on the host: 64 per brick in
/// [`bricks::voxel_of`] order. A level whose exemplars fit 256 x 256 pixels (every analysed
/// level of an exemplar up to 512 pixels) keeps each packed coordinate (x | y << 16) in 16 bits
/// as x | y << 8: 6 bytes a voxel instead of 12, the shared levels' host memory halved.
pub(super) struct LevelTriples {
    /// Sorted as [`bricks::normalize`] sorts them.
    bricks: Vec<Brick>,
    grid: Option<BrickGrid>,
    /// 16-bit units per coordinate: 1 (narrow) or 2 (the low and high halves of the word).
    units: usize,
    coords: Vec<u16>,
}

impl LevelTriples {
    /// Room for `bricks`' triples at a level whose exemplars are `width` x `height` pixels.
    pub(super) fn new(bricks: Vec<Brick>, width: u32, height: u32) -> LevelTriples {
        let units = if width <= 256 && height <= 256 { 1 } else { 2 };
        LevelTriples {
            grid: BrickColors::lookup(&bricks),
            coords: vec![0; bricks.len() * BRICK_COORDS * units],
            units,
            bricks,
        }
    }

    fn slot(&self, b: Brick) -> usize {
        BrickColors::slot_in(&self.bricks, self.grid.as_ref(), b).expect("brick held")
    }

    /// Store the triples of `group`'s bricks (every one held here) from a synthesized state:
    /// `grid` its storage, `stride` words per voxel. Bricks in parallel, each into its own
    /// part of the store.
    pub(super) fn set_bricks(
        &mut self,
        group: &[Brick],
        grid: &BrickGrid,
        state: &[u32],
        stride: usize,
    ) -> Result<()> {
        let n = BRICK_COORDS * self.units;
        let units = self.units;
        let mut slots: Vec<(usize, Brick)> = group.iter().map(|&b| (self.slot(b), b)).collect();
        slots.sort_unstable_by_key(|&(slot, _)| slot);
        let mut parts = Vec::with_capacity(slots.len());
        let (mut rest, mut at) = (&mut self.coords[..], 0);
        for (slot, b) in slots {
            let (_, tail) = std::mem::take(&mut rest).split_at_mut((slot - at) * n);
            let (part, tail) = tail.split_at_mut(n);
            (rest, at) = (tail, slot + 1);
            parts.push((part, b));
        }
        parts.into_par_iter().try_for_each(|(dst, b)| {
            let base = grid.slot(b).expect("wanted bricks are stored") as usize * 64;
            let triples = (0..64).flat_map(|l| {
                let i = (base + l) * stride;
                state[i..i + 3].iter().copied()
            });
            pack_brick(units, dst, triples)
        })
    }

    /// A state of `level`'s bricks (every one held here), `pixel_words` value words per voxel
    /// left zero: upsampling reads only the triples.
    pub(super) fn state_words(&self, level: &SparseLevel, pixel_words: u32) -> Vec<u32> {
        let stride = 3 + pixel_words as usize;
        let n = BRICK_COORDS * self.units;
        let mut words = vec![0u32; level.bricks.len() * 64 * stride];
        words
            .par_chunks_mut(64 * stride)
            .zip(&level.bricks)
            .for_each(|(chunk, &b)| {
                let s = self.slot(b);
                let src = &self.coords[s * n..(s + 1) * n];
                for (voxel, t) in chunk
                    .chunks_mut(stride)
                    .zip(src.chunks_exact(3 * self.units))
                {
                    for (k, word) in voxel[..3].iter_mut().enumerate() {
                        *word = if self.units == 1 {
                            let c = t[k] as u32;
                            crate::analysis::frame::pack(c & 0xFF, c >> 8)
                        } else {
                            t[2 * k] as u32 | (t[2 * k + 1] as u32) << 16
                        };
                    }
                }
            });
        words
    }
}

/// A brick's triples (64 voxels of 3 packed coordinates) into its part of a [`LevelTriples`]
/// store of `units` 16-bit units per coordinate.
fn pack_brick(units: usize, dst: &mut [u16], triples: impl Iterator<Item = u32>) -> Result<()> {
    let mut stored = 0;
    for (k, c) in triples.enumerate() {
        if units == 1 {
            let (x, y) = crate::analysis::frame::unpack(c);
            if x > 255 || y > 255 {
                return Err(Error::Internal(format!(
                    "coordinate ({x}, {y}) beyond a 256-pixel level"
                )));
            }
            dst[k] = (x | y << 8) as u16;
        } else {
            dst[2 * k] = c as u16;
            dst[2 * k + 1] = (c >> 16) as u16;
        }
        stored += 1;
    }
    debug_assert_eq!(stored, BRICK_COORDS);
    Ok(())
}

/// Coordinates (three per voxel) per brick.
const BRICK_COORDS: usize = bricks::BRICK_VOXELS as usize * 3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lazy::group_plans::parent_level;

    #[test]
    fn stored_triples_come_back_as_the_state_words_narrow_or_wide() {
        let bricks_held = vec![[0, 0, 0], [1, 0, 0], [-1, 2, 3]];
        for (width, max) in [(256, 255u32), (300, 299)] {
            let mut store = LevelTriples::new(bricks_held.clone(), width, 64);
            assert_eq!(store.units, if width <= 256 { 1 } else { 2 });
            let triple = |b: usize, l: u32, k: u32| {
                let x = (b as u32 * 97 + l * 13 + k * 5) % (max + 1);
                frame_pack(x, (l * 7 + k) % 64)
            };
            // A synthesized state holding the bricks (in its grid's slots), 2 value words.
            let grid = BrickGrid::new(&bricks_held);
            let mut state = vec![u32::MAX; bricks_held.len() * 64 * 5];
            for (i, &b) in bricks_held.iter().enumerate() {
                let slot = grid.slot(b).unwrap() as usize;
                for l in 0..64u32 {
                    for k in 0..3u32 {
                        state[(slot * 64 + l as usize) * 5 + k as usize] = triple(i, l, k);
                    }
                }
            }
            // Stored in two groups, the second out of order.
            store
                .set_bricks(&bricks_held[..1], &grid, &state, 5)
                .unwrap();
            store
                .set_bricks(&[bricks_held[2], bricks_held[1]], &grid, &state, 5)
                .unwrap();
            // A level of two of the bricks, in its own order, with one value word per voxel.
            let level = parent_level(&SparseLevel {
                bricks: vec![[-2, 4, 6], [0, 0, 0]],
                grid: BrickGrid::new(&[[-2, 4, 6], [0, 0, 0]]),
                subpasses: Vec::new(),
                deliver: Vec::new(),
            });
            assert_eq!(level.bricks, vec![[0, 0, 0], [-1, 2, 3]]);
            let words = store.state_words(&level, 1);
            for (j, chunk) in words.chunks(64 * 4).enumerate() {
                let i = if j == 0 { 0 } else { 2 };
                for l in 0..64u32 {
                    for k in 0..3u32 {
                        assert_eq!(chunk[l as usize * 4 + k as usize], triple(i, l, k));
                    }
                    assert_eq!(chunk[l as usize * 4 + 3], 0);
                }
            }
        }
        // A coordinate a narrow store cannot hold is an error, not a wrong solid.
        let mut store = LevelTriples::new(vec![[0, 0, 0]], 256, 256);
        let state = vec![frame_pack(256, 0); 64 * 3];
        assert!(store
            .set_bricks(&[[0, 0, 0]], &BrickGrid::new(&[[0, 0, 0]]), &state, 3)
            .is_err());
    }

    fn frame_pack(x: u32, y: u32) -> u32 {
        crate::analysis::frame::pack(x, y)
    }
}
