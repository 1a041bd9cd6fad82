//! Per-level static data of a synthesis, packed into one u32 buffer with word offsets: the layout
//! the WGSL kernels bind (one storage buffer) and the CPU references read, so both index it the
//! same way.

use crate::analysis::Analysis;

/// Word offsets of each exemplar's data inside [`LevelPack::words`]. For a shared analysis the
/// three exemplars point at the same data and 3D candidate sets are rotations of set 0.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LevelOffsets {
    /// Each exemplar's pixels, immediately followed by its usage penalties (one word per pixel,
    /// see `analysis::balance`): kernels find those at `pixels + width * height * pixel_words`
    /// without an offset of their own.
    pub pixels: [u32; 3],
    pub projected: [u32; 3],
    pub mean: [u32; 3],
    pub weights: [u32; 3],
    pub cand2d: [u32; 3],
    pub cand3d: [u32; 3],
    pub counts: [u32; 3],
    /// Slab triples of exemplar 0.
    pub slab: u32,
    /// The `--color matched` table (`color_match`, 256 words): the identity until a
    /// [`crate::lazy::Synthesizer`] fills the finest level's from its probe.
    pub color_match: u32,
}

/// One pyramid level's exemplar data for synthesis.
#[derive(Clone, Debug)]
pub struct LevelPack {
    /// The level data. A [`crate::lazy::Synthesizer`]'s packs are layouts only: it hands the
    /// words to its executor ([`crate::lazy::exec::Executor::new`]).
    pub words: Vec<u32>,
    pub offsets: LevelOffsets,
    pub width: u32,
    pub height: u32,
    /// Working channels (colour + feature).
    pub channels: u32,
    pub color_channels: u32,
    /// u32 words per exemplar pixel (channels packed 4 per word).
    pub pixel_words: u32,
    pub pca_in: u32,
    pub pca_out: u32,
    pub shift: u32,
    pub proj_words: u32,
    pub k2d: u32,
    /// Stride of the 3D candidate lists (the analysis' max_3d).
    pub k3d_stride: u32,
    pub shared: bool,
}

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

    /// This pack without its words: its layout, which is all planning reads.
    pub fn clone_layout(&self) -> LevelPack {
        LevelPack {
            words: Vec::new(),
            offsets: self.offsets.clone(),
            ..*self
        }
    }

    /// 3D candidates a correction of this level scores per plane: the paper's reduced search
    /// at the finest level (4), every kept one elsewhere.
    pub fn k3d_used(&self, finest: bool) -> u32 {
        if finest {
            FINEST_3D_CANDIDATES.min(self.k3d_stride)
        } else {
            self.k3d_stride
        }
    }
}

/// The paper's reduced 3D search at the finest level.
const FINEST_3D_CANDIDATES: u32 = 4;
