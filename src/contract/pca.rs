//! A quantized PCA basis as the `project` kernel reads it (fitted by `analysis::pca`), and the
//! packing of its projected vectors: `output_dims` bytes per vector, four per word. A
//! neighbourhood vector's layout (shared with `wgsl/project.wgsl`): rows dv = -2..=2 outermost,
//! then columns du = -2..=2, then channels: index ((dv + 2) * 5 + (du + 2)) * C + channel.

use crate::exemplar::{Border, Image};

/// A fitted, quantized PCA basis.
#[derive(Clone, Debug, PartialEq)]
pub struct PcaBasis {
    /// Length of the input vectors (25 x channels).
    pub input_dims: u32,
    /// Kept dimensions (8..=12): bytes per projected neighbourhood.
    pub output_dims: u32,
    /// Fixed-point shift F.
    pub shift: u32,
    /// Rounded mean of the raw input values.
    pub mean: Vec<i32>,
    /// output_dims x input_dims fixed-point weights, row-major.
    pub weights: Vec<i32>,
    /// All eigenvalues of the weighted covariance, descending (for the energy report).
    pub eigenvalues: Vec<f32>,
}

/// Unpack `words_per_vector`-word vectors into `output_dims` bytes each.
pub fn unpack_bytes(packed: &[u32], pca: &PcaBasis) -> Vec<u8> {
    let (words, k) = (pca.words_per_vector() as usize, pca.output_dims as usize);
    packed
        .chunks_exact(words)
        .flat_map(|v| {
            let bytes: Vec<u8> = v.iter().flat_map(|w| w.to_le_bytes()).collect();
            bytes[..k].to_vec()
        })
        .collect()
}

/// Side of the square 2D neighbourhoods (the paper's N).
pub const NEIGHBOURHOOD: i32 = 5;
/// Half side: offsets run over -HALF..=HALF.
pub const HALF: i32 = NEIGHBOURHOOD / 2;
/// Pixels in one 2D neighbourhood.
pub const NEIGHBOURHOOD_PIXELS: usize = (NEIGHBOURHOOD * NEIGHBOURHOOD) as usize;

/// The neighbourhood vector of pixel (x, y), appended to `out`.
pub fn gather(img: &Image, border: Border, x: u32, y: u32, out: &mut Vec<u8>) {
    for dv in -HALF..=HALF {
        for du in -HALF..=HALF {
            out.extend_from_slice(img.at_border(x as i32 + du, y as i32 + dv, border));
        }
    }
}
