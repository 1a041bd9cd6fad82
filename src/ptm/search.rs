//! Block neighbourhood search (the paper's section VII): which source blocks have a causal
//! neighbourhood (the overlap with already synthesized blocks) within a tolerance of the best?
//!
//! Two searches with identical results:
//! - [`Searcher::brute`]: the exact distance to every candidate block.
//! - [`Searcher::projection`]: the projection-kernel rejection scheme of Hel-Or & Hel-Or. The
//!   neighbourhood is projected onto an energy-compacting orthogonal basis, one group of kernels
//!   at a time, and the squared distance of the projections is a lower bound of the full distance
//!   (the paper's eq. 2). Our kernels are the Haar / Walsh-Hadamard box kernels: level 0 is the
//!   sum over each rectangle of the template (the DC kernel), and each level splits every cell in
//!   two along its longer side. The span of a level's kernels is the functions constant on its
//!   cells, so the energy of the projection of a difference x - y is sum_cells (S_c(x) -
//!   S_c(y))^2 / n_c (S: the sum over the cell, n: its pixel count), nondecreasing with the level
//!   and equal to |x - y|^2 at single pixels. The source's projections are computed once (per
//!   template shape), so a bound costs a few subtractions and multiplications per candidate.
//!   Candidates whose bound exceeds the threshold of the best distance found so far are rejected;
//!   the survivors get exact distances.
//!
//! Exactness: features are integers (the orthonormal Legendre coefficients quantized, see
//! [`FEATURE_SCALE`]), so every distance and bound is integer arithmetic, which is exact and
//! independent of summation order and thread count. Each bound is rounded down
//! (floor(sum / n)), so it never exceeds the true distance, which is an integer. A candidate is
//! rejected only when its bound exceeds the threshold derived from a distance already achieved,
//! which is at least the final threshold (the threshold is nondecreasing in the best distance),
//! so no candidate within the final threshold is ever rejected. Both searches then keep exactly
//! the candidates with distance <= threshold(best): the same set, in index order, so the same
//! seeded choice. Ties are resolved by the smallest candidate index.

use super::{legendre, Ptm, COEFFS};
use rayon::prelude::*;

/// Legendre coefficients (unit intensity) are stored as round(b * FEATURE_SCALE), clamped to
/// i16 range (|b| <= 16): 1/2048 of full intensity is an eighth of an 8-bit level. With |f| <
/// 2^15 a difference squared fits a u32, which keeps the inner loop narrow.
pub const FEATURE_SCALE: f64 = 2048.0;

/// Per pixel, the quantized orthonormal coefficients of its reflectance functions: 6 for LRGB
/// (the luminance polynomial), 18 for RGB (the three channels stacked).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FeatureImage {
    pub width: u32,
    pub height: u32,
    pub dims: usize,
    pub data: Vec<i32>,
}

impl FeatureImage {
    pub fn new(width: u32, height: u32, dims: usize) -> Self {
        FeatureImage {
            width,
            height,
            dims,
            data: vec![0; width as usize * height as usize * dims],
        }
    }

    /// The values of `len` pixels of row y starting at column x.
    #[inline]
    pub fn run(&self, x: u32, y: u32, len: u32) -> &[i32] {
        let i = (y as usize * self.width as usize + x as usize) * self.dims;
        &self.data[i..i + len as usize * self.dims]
    }

    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [i32] {
        let i = (y as usize * self.width as usize + x as usize) * self.dims;
        &mut self.data[i..i + self.dims]
    }
}

/// Feature dimensions of a PTM's format.
pub fn feature_dims(ptm: &Ptm) -> usize {
    ptm.format.planes() * COEFFS
}

/// The features of one texel of `ptm` into `out` (`feature_dims` values).
pub fn texel_features(ptm: &Ptm, texel: &[u8], out: &mut [i32]) {
    for p in 0..ptm.format.planes() {
        let a: [f64; COEFFS] = std::array::from_fn(|i| ptm.decode(i, texel[p * COEFFS + i]) as f64);
        let b = legendre::to_legendre(&a);
        for i in 0..COEFFS {
            out[p * COEFFS + i] = (b[i] * FEATURE_SCALE).round().clamp(-32767.0, 32767.0) as i32;
        }
    }
}

/// The feature image of a whole PTM.
pub fn features(ptm: &Ptm) -> FeatureImage {
    let mut f = FeatureImage::new(ptm.width, ptm.height, feature_dims(ptm));
    let d = f.dims;
    let s = ptm.format.texel_bytes();
    f.data
        .par_chunks_mut(d)
        .zip(ptm.texels.par_chunks(s))
        .for_each(|(out, t)| texel_features(ptm, t, out));
    f
}

/// A rectangle of pixels relative to a block's top-left corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl Rect {
    fn pixels(&self) -> u64 {
        self.w as u64 * self.h as u64
    }
    /// Halves along the longer side (None for a single pixel).
    fn split(&self) -> Option<(Rect, Rect)> {
        if self.w >= self.h && self.w > 1 {
            let a = self.w / 2;
            Some((
                Rect { w: a, ..*self },
                Rect {
                    x: self.x + a,
                    w: self.w - a,
                    ..*self
                },
            ))
        } else if self.h > 1 {
            let a = self.h / 2;
            Some((
                Rect { h: a, ..*self },
                Rect {
                    y: self.y + a,
                    h: self.h - a,
                    ..*self
                },
            ))
        } else {
            None
        }
    }
}

/// Which neighbours a block overlaps: the shape of its causal neighbourhood.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A block of the first row (after the first): its left overlap.
    Left,
    /// A block of the first column: its top overlap.
    Top,
    /// Every other block: the L of top and left overlaps.
    Both,
}

/// The disjoint rectangles of a neighbourhood shape for blocks of side `block`, overlap `overlap`.
pub fn template(shape: Shape, block: u32, overlap: u32) -> Vec<Rect> {
    let top = Rect {
        x: 0,
        y: 0,
        w: block,
        h: overlap,
    };
    let left = |y0: u32| Rect {
        x: 0,
        y: y0,
        w: overlap,
        h: block - y0,
    };
    match shape {
        Shape::Left => vec![left(0)],
        Shape::Top => vec![top],
        Shape::Both => vec![top, left(overlap)],
    }
}

/// Which candidates are acceptable: those with distance <= best + best * permille / 1000
/// (Efros-Freeman's "within a tolerance of the best"; 0 keeps only the best, ties included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tolerance {
    pub permille: u32,
}

impl Tolerance {
    /// The threshold for a best distance; nondecreasing in `best` (rejection relies on it).
    #[inline]
    pub fn threshold(&self, best: u64) -> u64 {
        best.saturating_add(best / 1000 * self.permille as u64 + (best % 1000) * self.permille as u64 / 1000)
    }
}

/// The result of a search: the best distance and every candidate within the tolerance of it
/// (index, distance), in index order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Matches {
    pub best: u64,
    pub within: Vec<(u32, u64)>,
}

/// Work counters of projection searches (summed over queries).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SearchStats {
    pub queries: u64,
    pub candidates: u64,
    /// Candidates still alive after each projection level.
    pub survivors: Vec<u64>,
    /// Exact distances computed.
    pub exact: u64,
}

/// One projection level of one shape: cells grouped by pixel count (one division per group per
/// candidate) and the source's cell sums, per candidate, per cell, per dimension.
struct Level {
    cells: Vec<Rect>,
    /// (pixels per cell, number of consecutive cells in `cells` with that count).
    groups: Vec<(u64, usize)>,
    sums: Vec<i64>,
}

/// The source features and everything precomputed for searching its blocks.
pub struct Searcher {
    pub source: FeatureImage,
    pub block: u32,
    pub overlap: u32,
    /// Candidate block origins per row and column: (width - block + 1, height - block + 1).
    pub cand_w: u32,
    pub cand_h: u32,
    levels: std::sync::Mutex<std::collections::HashMap<Shape, std::sync::Arc<Vec<Level>>>>,
}

/// Projection levels computed for each shape (cells per rectangle: 1, 2, 4, 8); after them the
/// survivors get exact distances.
pub const PROJECTION_LEVELS: usize = 4;

impl Searcher {
    /// `block` and `overlap` must fit the source (checked by the caller).
    pub fn new(source: FeatureImage, block: u32, overlap: u32) -> Self {
        let cand_w = source.width - block + 1;
        let cand_h = source.height - block + 1;
        Searcher {
            source,
            block,
            overlap,
            cand_w,
            cand_h,
            levels: Default::default(),
        }
    }

    pub fn candidates(&self) -> usize {
        self.cand_w as usize * self.cand_h as usize
    }

    /// The top-left source pixel of candidate `i`.
    pub fn origin(&self, i: u32) -> (u32, u32) {
        (i % self.cand_w, i / self.cand_w)
    }

    /// Exact squared distance between the neighbourhood of candidate `i` and that of the output
    /// block at (qx, qy) of `out`, stopping early (returning a partial sum > limit) once it
    /// exceeds `limit`: partial sums of squares are lower bounds too.
    pub fn distance(&self, i: u32, out: &FeatureImage, qx: u32, qy: u32, rects: &[Rect], limit: u64) -> u64 {
        let (cx, cy) = self.origin(i);
        let mut acc = 0u64;
        for r in rects {
            for row in 0..r.h {
                let a = self.source.run(cx + r.x, cy + r.y + row, r.w);
                let b = out.run(qx + r.x, qy + r.y + row, r.w);
                acc += squared_difference(a, b);
            }
            if acc > limit {
                return acc;
            }
        }
        acc
    }

    fn levels_for(&self, shape: Shape) -> std::sync::Arc<Vec<Level>> {
        if let Some(l) = self.levels.lock().unwrap().get(&shape) {
            return l.clone();
        }
        let d = self.source.dims;
        let mut cells = template(shape, self.block, self.overlap);
        let mut levels = Vec::new();
        for _ in 0..PROJECTION_LEVELS {
            // Group cells by size (stable order) so a bound needs one division per group.
            cells.sort_by_key(|c| std::cmp::Reverse(c.pixels()));
            let mut groups: Vec<(u64, usize)> = Vec::new();
            for c in &cells {
                match groups.last_mut() {
                    Some((n, k)) if *n == c.pixels() => *k += 1,
                    _ => groups.push((c.pixels(), 1)),
                }
            }
            let per = cells.len() * d;
            let mut sums = vec![0i64; self.candidates() * per];
            sums.par_chunks_mut(per).enumerate().for_each(|(i, out)| {
                let (cx, cy) = self.origin(i as u32);
                for (k, c) in cells.iter().enumerate() {
                    cell_sums(&self.source, cx + c.x, cy + c.y, c, &mut out[k * d..(k + 1) * d]);
                }
            });
            levels.push(Level {
                cells: cells.clone(),
                groups,
                sums,
            });
            cells = cells
                .iter()
                .flat_map(|c| match c.split() {
                    Some((a, b)) => vec![a, b],
                    None => vec![*c],
                })
                .collect();
        }
        let levels = std::sync::Arc::new(levels);
        self.levels
            .lock()
            .unwrap()
            .insert(shape, levels.clone());
        levels
    }

    /// Brute force: the exact distance to every candidate.
    pub fn brute(&self, out: &FeatureImage, qx: u32, qy: u32, shape: Shape, tol: Tolerance) -> Matches {
        let rects = template(shape, self.block, self.overlap);
        let dist: Vec<u64> = (0..self.candidates() as u32)
            .into_par_iter()
            .map(|i| self.distance(i, out, qx, qy, &rects, u64::MAX))
            .collect();
        let best = dist.iter().copied().min().unwrap_or(u64::MAX);
        let thr = tol.threshold(best);
        let within = dist
            .iter()
            .enumerate()
            .filter(|(_, &d)| d <= thr)
            .map(|(i, &d)| (i as u32, d))
            .collect();
        Matches { best, within }
    }

    /// The projection-kernel search: same result as [`Searcher::brute`], proven in the module
    /// docs and tested on many queries.
    pub fn projection(
        &self,
        out: &FeatureImage,
        qx: u32,
        qy: u32,
        shape: Shape,
        tol: Tolerance,
        stats: &mut SearchStats,
    ) -> Matches {
        let rects = template(shape, self.block, self.overlap);
        let levels = self.levels_for(shape);
        let d = self.source.dims;
        let mut survivors: Vec<u32> = (0..self.candidates() as u32).collect();
        let mut best = u64::MAX;
        stats.queries += 1;
        stats.candidates += survivors.len() as u64;
        stats.survivors.resize(levels.len(), 0);
        for (li, level) in levels.iter().enumerate() {
            let per = level.cells.len() * d;
            let mut q = vec![0i64; per];
            for (k, c) in level.cells.iter().enumerate() {
                cell_sums(out, qx + c.x, qy + c.y, c, &mut q[k * d..(k + 1) * d]);
            }
            let bounds: Vec<u64> = survivors
                .par_iter()
                .map(|&i| {
                    let s = &level.sums[i as usize * per..(i as usize + 1) * per];
                    let mut lb = 0u64;
                    let mut at = 0;
                    for &(n, count) in &level.groups {
                        let mut acc = 0u64;
                        for k in at * d..(at + count) * d {
                            let diff = (q[k] - s[k]).unsigned_abs();
                            acc += diff * diff;
                        }
                        lb += acc / n;
                        at += count;
                    }
                    lb
                })
                .collect();
            // Tighten the best distance so far with the most promising survivor (smallest
            // bound, then smallest index): its exact distance is achievable.
            if let Some((k, _)) = bounds.iter().enumerate().min_by_key(|(k, &b)| (b, *k)) {
                let dd = self.distance(survivors[k], out, qx, qy, &rects, u64::MAX);
                stats.exact += 1;
                best = best.min(dd);
            }
            let thr = tol.threshold(best);
            survivors = survivors
                .iter()
                .zip(&bounds)
                .filter(|(_, &b)| b <= thr)
                .map(|(&i, _)| i)
                .collect();
            stats.survivors[li] += survivors.len() as u64;
            if survivors.len() <= 1 {
                break;
            }
        }
        let limit = tol.threshold(best);
        stats.exact += survivors.len() as u64;
        let exact: Vec<(u32, u64)> = survivors
            .par_iter()
            .map(|&i| (i, self.distance(i, out, qx, qy, &rects, limit)))
            .collect();
        let best = exact.iter().map(|e| e.1).min().unwrap_or(best).min(best);
        let thr = tol.threshold(best);
        let within = exact.into_iter().filter(|e| e.1 <= thr).collect();
        Matches { best, within }
    }
}

/// Sum over the cell at (x, y) (absolute) of each feature dimension.
fn cell_sums(img: &FeatureImage, x: u32, y: u32, c: &Rect, out: &mut [i64]) {
    let d = img.dims;
    out.fill(0);
    for row in 0..c.h {
        for px in img.run(x, y + row, c.w).chunks_exact(d) {
            for k in 0..d {
                out[k] += px[k] as i64;
            }
        }
    }
}

/// Sum of squared differences of two equal-length runs. |values| < 2^15, so each square fits a
/// u32; the sum is exact in u64 whatever the order.
#[inline]
pub fn squared_difference(a: &[i32], b: &[i32]) -> u64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = (x - y).unsigned_abs();
            (d * d) as u64
        })
        .sum()
}
