//! The `correct` kernel's candidate tables: a level's 2D and 3D candidate lists with what scoring
//! a candidate reads beside it, laid out so that one candidate is one contiguous run of words.
//!
//! Scoring a candidate from the level data reads its coordinate from one table, its projection
//! from another and its usage penalty from a third (a 3D candidate: three coordinates, two
//! projections, three penalties), each at an unrelated address. On an H100 the correction kernel
//! ran far below its arithmetic rate, waiting on such scattered reads of level data too large
//! for the L1 cache; the CPU backend had already gathered each candidate's data into one record
//! (`Prepared` in src/cpu/correct/prepared.rs). These tables do the same for the GPU: every value is the
//! one the kernel read before (the CPU reference still reads the level data, so the
//! kernels-tests compare the two paths), only its place changes; the one derived value is each
//! candidate's p.p, summed into its scale word (`scale_word`).
//!
//! Layout (u32 words): a header of [`HEADER_WORDS`], then the tables.
//! - header: the word offsets of plane a's 2D table (words 0..3) and of 3D candidate set s's table
//!   (words 3..6; one set when the analysis is shared, its offset repeated), then the 3D slots per
//!   pixel (word 6).
//! - 2D table of plane a: per exemplar pixel, its `k2d` candidates, each [`entry_2d`] words: the
//!   candidate's coordinate, its scale word, its projection. The scale word (`scale_word`)
//!   holds 16 + its usage penalty (the distance's scale) and its projection's sum of squares.
//! - 3D table of set s: per exemplar pixel, `slots` candidates (unused ones zero), each
//!   [`entry_3d`] words: the triple, its scale word (16 + the usage penalties of its three
//!   pixels, and the sum of squares of both projections that follow), the projection of its
//!   coordinate on plane (s + 1) % 3, then on plane (s + 2) % 3. For a shared
//!   analysis (set 0, rotated per plane by the kernel) those are the projections of the triple's
//!   y and z coordinates, which the rotation for plane a puts on planes (a + 1) % 3 and
//!   (a + 2) % 3: the same order.

use crate::contract::level::LevelPack;
use rayon::prelude::*;

pub const HEADER_WORDS: usize = 8;

/// Words per 2D candidate: 2 + proj_words, padded to whole 16-byte vectors (so a candidate
/// never straddles two of the GPU's 32-byte sectors: one at the finest level's 8 PCA
/// dimensions, two at 12).
pub fn entry_2d(proj_words: u32) -> u32 {
    (2 + proj_words).next_multiple_of(4)
}

/// Words per 3D candidate: 4 + 2 proj_words, padded likewise (8 at 8 PCA dimensions, 12 at 12).
pub fn entry_3d(proj_words: u32) -> u32 {
    (4 + 2 * proj_words).next_multiple_of(4)
}

/// Bits of a scale word that hold the distance's scale: 16 + at most three usage penalties of
/// at most 255 (u8 in the .ssa) is at most 781.
pub const SCALE_BITS: u32 = 10;

/// A candidate's scale word: `scale` (below 2^SCALE_BITS) in the low bits and `squares`, the sum
/// of squares of its stored projections' bytes, above them. The kernel's distance is
/// q.q + p.p - 2 q.p; p.p is the candidate's alone, so it is summed here once instead of by
/// every voxel that scores the candidate. At most 16 PCA dimensions (GpuSynth refuses more
/// before it builds tables) and two projections: below 2 x 16 x 255^2 < 2^21, so the word fits.
fn scale_word(scale: u32, squares: u32) -> u32 {
    debug_assert!(scale < 1 << SCALE_BITS && squares < 1 << (32 - SCALE_BITS));
    scale | squares << SCALE_BITS
}

/// Sum of squares of the first `dims` bytes of projection words `p` (the kernel's p.p; the
/// bytes past `dims` are not part of the projection).
fn squares(p: &[u32], dims: u32) -> u32 {
    (0..dims as usize)
        .map(|j| {
            let byte = (p[j / 4] >> (8 * (j % 4))) & 0xFF;
            byte * byte
        })
        .sum()
}

/// Plane a's (or set a's) word offsets of level data in `p`.
struct Planes {
    pixels: [usize; 3],
    projected: [usize; 3],
}

impl Planes {
    fn of(p: &LevelPack) -> Planes {
        let o = &p.offsets;
        Planes {
            pixels: o.pixels.map(|w| w as usize),
            projected: o.projected.map(|w| w as usize),
        }
    }

    fn pixel(p: &LevelPack, c: u32) -> usize {
        let (x, y) = (c & 0xFFFF, c >> 16);
        (y * p.width + x) as usize
    }

    /// 16 + the usage penalty of pixel `c` of plane `a` (right after its pixels).
    fn factor(&self, p: &LevelPack, a: usize, c: u32) -> u32 {
        let table = self.pixels[a] + (p.width * p.height * p.pixel_words) as usize;
        16 + p.words[table + Self::pixel(p, c)]
    }

    /// The projection words of pixel `c` on plane `a`.
    fn projection<'a>(&self, p: &'a LevelPack, a: usize, c: u32) -> &'a [u32] {
        let at = self.projected[a] + Self::pixel(p, c) * p.proj_words as usize;
        &p.words[at..at + p.proj_words as usize]
    }
}

/// The tables of level `p` with `slots` 3D candidates per pixel (at least the `k3d_used` of any
/// correction of this level; see [`LevelPack::k3d_used`]).
pub fn candidate_tables(p: &LevelPack, slots: u32) -> Vec<u32> {
    assert!(
        p.pca_out <= 16,
        "the GPU correction takes at most 16 PCA dimensions (GpuSynth::new checks it)"
    );
    let planes = &Planes::of(p);
    let pixels = (p.width * p.height) as usize;
    let pw = p.proj_words as usize;
    let mut words = vec![0u32; HEADER_WORDS];
    words[6] = slots;

    // 2D tables, one per distinct (list, projections, penalties), as the CPU backend shares them.
    let mut built: Vec<([u32; 3], u32)> = Vec::new();
    for a in 0..3 {
        let key = [
            p.offsets.cand2d[a],
            p.offsets.projected[a],
            p.offsets.pixels[a],
        ];
        if let Some(&(_, at)) = built.iter().find(|(k, _)| *k == key) {
            words[a] = at;
            continue;
        }
        let at = words.len() as u32;
        let list = p.offsets.cand2d[a] as usize;
        let n = pixels * p.k2d as usize;
        let entry = entry_2d(p.proj_words) as usize;
        let start = words.len();
        words.resize(start + n * entry, 0);
        words[start..]
            .par_chunks_mut(entry)
            .zip(&p.words[list..list + n])
            .for_each(|(e, &c)| {
                let projection = planes.projection(p, a, c);
                e[0] = c;
                e[1] = scale_word(planes.factor(p, a, c), squares(projection, p.pca_out));
                e[2..2 + pw].copy_from_slice(projection);
            });
        words[a] = at;
        built.push((key, at));
    }

    // 3D tables.
    let sets = if p.shared { 1 } else { 3 };
    let entry = entry_3d(p.proj_words) as usize;
    for s in 0..sets {
        let at = words.len() as u32;
        let counts = p.offsets.counts[s] as usize;
        let list = p.offsets.cand3d[s] as usize;
        let (next, last) = ((s + 1) % 3, (s + 2) % 3);
        let start = words.len();
        words.resize(start + pixels * slots as usize * entry, 0);
        words[start..]
            .par_chunks_mut(slots as usize * entry)
            .enumerate()
            .for_each(|(pixel, candidates)| {
                let count = p.words[counts + pixel].min(slots) as usize;
                for (j, e) in candidates.chunks_exact_mut(entry).take(count).enumerate() {
                    let at = list + (pixel * p.k3d_stride as usize + j) * 3;
                    let t = [p.words[at], p.words[at + 1], p.words[at + 2]];
                    e[..3].copy_from_slice(&t);
                    // Shared: one penalty table for the three (the sum is rotation-free).
                    let scale = (0..3).map(|b| planes.factor(p, b, t[b]) - 16).sum::<u32>() + 16;
                    let (on_next, on_last) = (
                        planes.projection(p, next, t[next]),
                        planes.projection(p, last, t[last]),
                    );
                    let both = squares(on_next, p.pca_out) + squares(on_last, p.pca_out);
                    e[3] = scale_word(scale, both);
                    e[4..4 + pw].copy_from_slice(on_next);
                    e[4 + pw..4 + 2 * pw].copy_from_slice(on_last);
                }
            });
        for t in if p.shared { 0..3 } else { s..s + 1 } {
            words[3 + t] = at;
        }
    }
    words
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kernel splits the scale word where the tables put the split.
    #[test]
    fn the_kernel_splits_the_scale_word_here() {
        let source = crate::gpu::shaders::source("correct");
        assert!(source.contains(&format!("const SCALE_BITS: u32 = {SCALE_BITS}u;")));
    }

    /// p.p counts a projection's first `dims` bytes only, and the word keeps the largest scale
    /// and the largest p.p of two 16-dimensional projections apart.
    #[test]
    fn scale_words_hold_the_scale_and_the_squares() {
        // Bytes 0xFF, 2, 3, 4, 5, 6, 0xFF, 0xFF (little-endian words).
        let p = [0x0403_02FF_u32, 0xFFFF_0605];
        let first6 = 255 * 255 + 4 + 9 + 16 + 25 + 36;
        assert_eq!(squares(&p, 6), first6);
        assert_eq!(squares(&p, 8), first6 + 2 * 255 * 255);
        let (scale, pp) = (16 + 3 * 255, 2 * 16 * 255 * 255);
        let word = scale_word(scale, pp);
        assert_eq!(word & ((1 << SCALE_BITS) - 1), scale);
        assert_eq!(word >> SCALE_BITS, pp);
    }
}
