//! Packing an analysis level into the level data of [`crate::contract::level::LevelPack`].

use crate::analysis::Analysis;
pub use crate::contract::level::{LevelOffsets, LevelPack};

impl LevelPack {
    /// Pack analysis level `level` (0 = finest).
    pub fn new(a: &Analysis, level: usize) -> LevelPack {
        let first = &a.exemplar(0).levels[level];
        let channels = first.image.channels;
        let pixel_words = channels.div_ceil(4);
        let mut words = Vec::new();
        let mut off = LevelOffsets::default();
        let owners = if a.shared { 1 } else { 3 };
        for e in 0..owners {
            let l = &a.exemplars[e].levels[level];
            let at = |w: &Vec<u32>| w.len() as u32;
            let o_pixels = at(&words);
            for px in l.image.pixels.chunks_exact(channels as usize) {
                for chunk in px.chunks(4) {
                    let mut b = [0u8; 4];
                    b[..chunk.len()].copy_from_slice(chunk);
                    words.push(u32::from_le_bytes(b));
                }
            }
            // Right after the pixels (see `LevelOffsets::pixels`).
            words.extend(l.penalty.iter().map(|&p| p as u32));
            let o_proj = at(&words);
            words.extend_from_slice(&l.projected);
            let o_mean = at(&words);
            words.extend(l.pca.mean.iter().map(|&m| m as u32));
            let o_weights = at(&words);
            words.extend(l.pca.weights.iter().map(|&w| w as u32));
            let o_cand2d = at(&words);
            words.extend_from_slice(&l.candidates_2d);
            let o_cand3d = at(&words);
            words.extend(l.candidates_3d.iter().flatten());
            let o_counts = at(&words);
            words.extend(l.counts_3d.iter().map(|&c| c as u32));
            if e == 0 {
                off.slab = at(&words);
                words.extend(l.slab.iter().flatten());
            }
            let targets: Vec<usize> = if a.shared { vec![0, 1, 2] } else { vec![e] };
            for t in targets {
                off.pixels[t] = o_pixels;
                off.projected[t] = o_proj;
                off.mean[t] = o_mean;
                off.weights[t] = o_weights;
                off.cand2d[t] = o_cand2d;
                off.cand3d[t] = o_cand3d;
                off.counts[t] = o_counts;
            }
        }
        let mut pack = LevelPack {
            words,
            offsets: off,
            width: first.image.width,
            height: first.image.height,
            channels,
            color_channels: a.color_channels,
            pixel_words,
            pca_in: first.pca.input_dims,
            pca_out: first.pca.output_dims,
            shift: first.pca.shift,
            proj_words: first.pca.words_per_vector(),
            k2d: a.params.k2d[level],
            k3d_stride: a.params.max_3d,
            shared: a.shared,
        };
        // Every level carries one (256 words); colorize reads the finest level's.
        pack.offsets.color_match = pack.words.len() as u32;
        pack.words.extend(super::color_match::identity());
        pack
    }
}
