//! A level's brick index as the kernels read it: its brick table, brick lists and voxel masks
//! in one buffer of words.

use super::bricks::{self, Brick, SparseLevel};
use rayon::prelude::*;

/// Where a level's brick tables and lists sit in its brick index (words).
pub(super) struct IndexLayout {
    pub(super) words: Vec<u32>,
    pub(super) storage_list: u32,
    /// Per sub-pass: word offset and length of its brick list, and word offset of its voxel
    /// masks (one byte per listed brick).
    pub(super) subpass_lists: Vec<(u32, u32, u32)>,
    pub(super) parent_table: u32,
    pub(super) output_list: u32,
}

impl IndexLayout {
    /// The level's table first (offset 0), then its stored bricks, each sub-pass's bricks, a
    /// copy of the parent level's table (for `upsample`) and the output bricks (finest level).
    ///
    /// A sub-pass that covers at least half the stored bricks (in a box, nearly all do) runs
    /// over the storage list itself, with a zero mask for the bricks it skips: 1 byte per
    /// stored brick instead of 13 per listed one. Its voxels, and so the results, are the same.
    pub(super) fn new(
        level: &SparseLevel,
        parent: Option<&SparseLevel>,
        output: Option<&[Brick]>,
    ) -> Self {
        let shares_storage =
            |sp: &bricks::SubpassPlan| sp.over_storage || 2 * sp.bricks.len() >= level.bricks.len();
        // Sized exactly up front: a large box's index is tens of MB, doubling growth would
        // nearly double it.
        let len = level.grid.table.len()
            + 3 * level.bricks.len()
            + level
                .subpasses
                .iter()
                .map(|sp| match shares_storage(sp) {
                    true => level.bricks.len().div_ceil(4),
                    false => 3 * sp.bricks.len() + sp.masks.len().div_ceil(4),
                })
                .sum::<usize>()
            + parent.map_or(0, |p| p.grid.table.len())
            + 3 * output.map_or(0, <[Brick]>::len);
        let mut words = Vec::with_capacity(len);
        words.extend_from_slice(&level.grid.table);
        let push = bricks::push_list;
        let storage_list = push(&mut words, &level.bricks);
        // Each sub-pass's part (a brick list and its masks, or masks over the storage list),
        // built in parallel, then appended in order.
        let pack_masks = |masks: &[u8]| -> Vec<u32> {
            masks
                .chunks(4)
                .map(|m| {
                    m.iter()
                        .enumerate()
                        .fold(0u32, |w, (i, &b)| w | (b as u32) << (8 * i))
                })
                .collect()
        };
        let parts: Vec<(Option<&[Brick]>, Vec<u32>)> = level
            .subpasses
            .par_iter()
            .map(|sp| {
                if sp.over_storage {
                    (None, pack_masks(&sp.masks))
                } else if shares_storage(sp) {
                    let mut masks = vec![0u8; level.bricks.len()];
                    for (b, &m) in sp.bricks.iter().zip(&sp.masks) {
                        let slot = level.grid.slot(*b).expect("sub-pass bricks are stored");
                        masks[slot as usize] = m;
                    }
                    (None, pack_masks(&masks))
                } else {
                    (Some(&sp.bricks[..]), pack_masks(&sp.masks))
                }
            })
            .collect();
        let subpass_lists = parts
            .into_iter()
            .map(|(own_list, masks)| {
                let (list, count) = match own_list {
                    None => (storage_list, level.bricks.len() as u32),
                    Some(list) => (push(&mut words, list), list.len() as u32),
                };
                let at = words.len() as u32;
                words.extend_from_slice(&masks);
                (list, count, at)
            })
            .collect();
        let parent_table = words.len() as u32;
        if let Some(p) = parent {
            words.extend_from_slice(&p.grid.table);
        }
        let output_list = push(&mut words, output.unwrap_or(&[]));
        IndexLayout {
            words,
            storage_list,
            subpass_lists,
            parent_table,
            output_list,
        }
    }
}
