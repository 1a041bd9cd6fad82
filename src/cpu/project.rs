//! CPU reference of `wgsl/project.wgsl`: PCA projection of every exemplar neighbourhood with
//! 8-bit quantization, packed four bytes per u32 word.

use crate::contract::pca::PcaBasis;
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
                crate::contract::pca::gather(img, border, x, y as u32, &mut gathered);
                project_vector(pca, &gathered, &mut bytes);
                let dst = &mut row[x as usize * words..][..words];
                for (w, word) in dst.iter_mut().enumerate() {
                    *word = u32::from_le_bytes(bytes[w * 4..w * 4 + 4].try_into().unwrap());
                }
            }
        });
    // Bytes past output_dims in the last word stay zero (never written), as in the shader.
    out
}

/// Project one raw vector exactly as the kernels do (the CPU reference's inner step).
#[inline]
pub fn project_vector(pca: &PcaBasis, x: &[u8], out: &mut [u8]) {
    let d = pca.input_dims as usize;
    let round = 1i32 << (pca.shift - 1);
    for (j, o) in out.iter_mut().enumerate().take(pca.output_dims as usize) {
        let row = &pca.weights[j * d..(j + 1) * d];
        let mut acc = 0i32;
        for i in 0..d {
            acc += (x[i] as i32 - pca.mean[i]) * row[i];
        }
        *o = (((acc + round) >> pca.shift) + 128).clamp(0, 255) as u8;
    }
}
