//! CPU reference of `wgsl/project.wgsl`: PCA projection of every exemplar neighbourhood with
//! 8-bit quantization, packed four bytes per u32 word.

use crate::analysis::pca::PcaBasis;
use crate::exemplar::{Border, Image};
use rayon::prelude::*;

/// Project every pixel's neighbourhood; returns `pixel_count * words_per_vector` words.
pub fn project(img: &Image, border: Border, pca: &PcaBasis) -> Vec<u32> {
    let words = pca.words_per_vector() as usize;
    let mut out = vec![0u32; img.pixel_count() * words];
    out.par_chunks_mut(words * img.width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let mut gathered = Vec::with_capacity(pca.input_dims as usize);
            let mut bytes = [0u8; 16];
            for x in 0..img.width {
                gathered.clear();
                crate::analysis::neighbourhood::gather(img, border, x, y as u32, &mut gathered);
                crate::analysis::pca::project_vector(pca, &gathered, &mut bytes);
                let dst = &mut row[x as usize * words..][..words];
                for (w, word) in dst.iter_mut().enumerate() {
                    *word = u32::from_le_bytes(bytes[w * 4..w * 4 + 4].try_into().unwrap());
                }
            }
        });
    // Bytes past output_dims in the last word stay zero (never written), as in the shader.
    out
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
