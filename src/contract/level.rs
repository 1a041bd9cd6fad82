//! Per-level static data of a synthesis, packed into one u32 buffer with word offsets: the layout
//! the WGSL kernels bind (one storage buffer) and the CPU references read, so both index it the
//! same way. Built from an analysis by `lazy::pack`.

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
    /// `lazy::Synthesizer` fills the finest level's from its probe.
    pub color_match: u32,
}

/// One pyramid level's exemplar data for synthesis.
#[derive(Clone, Debug)]
pub struct LevelPack {
    /// The level data. A `lazy::Synthesizer`'s packs are layouts only: it hands the
    /// words to its executor (`backend::synthesis::Executor::new`).
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
