//! The exemplar patches of one synthesis level (paper 4.2.1, 4.2.3): N x N samples at pixel
//! spacing s ("fractional sampling": coarser levels double the spacing instead of shrinking the
//! grid), their PCA projections for the nearest-patch search, and what the bucket step reads back: the sample
//! values and, at the finest level, their colour clusters.

use super::pca::{PatchPca, KEPT};
use crate::error::{Error, Result};
use crate::exemplar::Image;
use rayon::prelude::*;

/// At most this many candidate patches per level (a larger exemplar is sampled on a stride):
/// bounds the projection and tree cost.
const MAX_CANDIDATES: usize = 16384;

/// acc[l] += sum over dimensions j of (block[j][l] - query[j])^2, lanes side by side.
#[inline(always)]
fn accumulate(acc: &mut [f32; LANES], block: &[[f32; LANES]], query: &[f32]) {
    for j in 0..block.len() {
        let q = query[j];
        let lanes = &block[j];
        for l in 0..LANES {
            let d = lanes[l] - q;
            acc[l] += d * d;
        }
    }
}

/// Whether any lane is at most `limit` (a lane-wise compare and a mask test: no serial
/// horizontal minimum, which cost more than the partial distances themselves).
#[inline(always)]
fn any_at_most(acc: &[f32; LANES], limit: f32) -> bool {
    let mut any = false;
    for &a in acc {
        any |= a <= limit;
    }
    any
}

/// Which line of a patch a crossbar compares (paper Fig. 3).
#[derive(Clone, Copy, Debug)]
pub enum Line {
    /// The centre column: pixels (h, b) for b in 0..N.
    Column,
    /// The centre row: pixels (a, h) for a in 0..N.
    Row,
}

pub struct LevelPatches {
    /// Pixel spacing s of the samples (and voxel spacing in the solid).
    pub spacing: u32,
    /// Samples per patch side, N (odd).
    pub size: u32,
    pub channels: usize,
    width: u32,
    /// The exemplar low-passed for spacing s (a box of width 2s - 1; s = 1: unchanged).
    image: Vec<u8>,
    /// Colour cluster per pixel (quantized levels only).
    clusters: Option<Vec<u8>>,
    /// With a mask: per cluster, whether its pixels lie in the positive region.
    cluster_regions: Option<Vec<bool>>,
    /// Centre pixel of every candidate patch.
    centres: Vec<(u32, u32)>,
    /// Set by `build` (an option only so `vector` can be used while building).
    pca: Option<PatchPca>,
    /// The candidates' projections, 8 per block, dimension-major inside a block (padding lanes
    /// hold a huge value): the layout an exhaustive search vectorizes over.
    /// The first EARLY dimensions of every block, apart from the rest: the pass that rejects
    /// most blocks reads only these (186 KB for 11,664 patches: they stay in the L2 cache).
    early_blocks: Vec<[[f32; LANES]; EARLY]>,
    late_blocks: Vec<[[f32; LANES]; KEPT - EARLY]>,
}

/// Candidates per block of the exhaustive search.
const LANES: usize = 8;
/// PCA dimensions (the largest) scored before the first rejection test, and before the second.
const EARLY: usize = 4;
const MIDDLE: usize = 8;
/// Stride of the nearest-neighbour search's first, sparse pass over the blocks.
const PROBE: usize = 16;
/// Coordinate of the padding lanes: their distance to any query is infinite.
const PADDING: f32 = 1e30;

/// The exemplar box-filtered over (2s - 1)^2 pixels, clamped at the edges.
fn prefilter(img: &Image, s: u32) -> Vec<u8> {
    if s <= 1 {
        return img.pixels.clone();
    }
    let (w, h, c) = (img.width as i32, img.height as i32, img.channels as usize);
    let r = s as i32 - 1;
    let mut out = vec![0u8; img.pixels.len()];
    out.par_chunks_mut(w as usize * c)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let mut sum = vec![0u32; c];
                let mut n = 0u32;
                for yy in (y as i32 - r).max(0)..=(y as i32 + r).min(h - 1) {
                    for xx in (x - r).max(0)..=(x + r).min(w - 1) {
                        let p = img.at(xx as u32, yy as u32);
                        sum.iter_mut().zip(p).for_each(|(s, &v)| *s += v as u32);
                        n += 1;
                    }
                }
                for k in 0..c {
                    row[x as usize * c + k] = ((sum[k] + n / 2) / n) as u8;
                }
            }
        });
    out
}

impl LevelPatches {
    /// Candidate patches of `img` with `size` samples per side at spacing `spacing`; with
    /// `quantize`, the filtered exemplar's colours are clustered into that many clusters for the
    /// buckets. With `distance_channel` (a mask's signed distance, 128 at the boundary), the
    /// clusters are allocated per region (the sign of the filtered distance) and hold the colour
    /// channels before it only ([`super::clusters::quantize_regions`]). `seed` seeds the PCA.
    pub fn build(
        img: &Image,
        spacing: u32,
        size: u32,
        quantize: Option<u32>,
        distance_channel: Option<usize>,
        seed: u64,
    ) -> Result<LevelPatches> {
        let span = (size - 1) * spacing + 1;
        if img.width < span || img.height < span {
            return Err(Error::invalid(
                "exemplar",
                format!(
                    "is {}x{}; gradient synthesis needs at least {span}x{span} pixels (patches of \
                     {size} samples at spacing {spacing})",
                    img.width, img.height
                ),
            ));
        }
        let half = (size / 2) * spacing;
        let (nx, ny) = (img.width - span + 1, img.height - span + 1);
        let stride = ((nx as usize * ny as usize) as f64 / MAX_CANDIDATES as f64)
            .sqrt()
            .ceil()
            .max(1.0) as u32;
        let centres: Vec<(u32, u32)> = (0..ny)
            .step_by(stride as usize)
            .flat_map(|y| {
                (0..nx)
                    .step_by(stride as usize)
                    .map(move |x| (x + half, y + half))
            })
            .collect();
        let image = prefilter(img, spacing);
        let (clusters, cluster_regions) = match quantize {
            None => (None, None),
            Some(k) => {
                let filtered = Image {
                    pixels: image.clone(),
                    ..img.clone()
                };
                match distance_channel {
                    None => (Some(super::clusters::quantize(&filtered, k)), None),
                    Some(d) => {
                        let c = img.channels as usize;
                        let positive: Vec<bool> =
                            image.chunks_exact(c).map(|p| p[d] >= 128).collect();
                        let (labels, regions) =
                            super::clusters::quantize_regions(&filtered, d, &positive, k);
                        (Some(labels), Some(regions))
                    }
                }
            }
        };
        let mut level = LevelPatches {
            spacing,
            size,
            channels: img.channels as usize,
            width: img.width,
            image,
            clusters,
            cluster_regions,
            centres,
            pca: None,
            early_blocks: Vec::new(),
            late_blocks: Vec::new(),
        };
        let dims = level.dims();
        let vectors: Vec<f32> = (0..level.centres.len() as u32)
            .into_par_iter()
            .flat_map_iter(|i| level.vector(i))
            .collect();
        let pca = PatchPca::fit(&vectors, dims, seed);
        let points: Vec<[f32; KEPT]> = vectors
            .par_chunks_exact(dims)
            .map(|v| pca.project(v))
            .collect();
        let lanes = |chunk: &[[f32; KEPT]], j: usize| -> [f32; LANES] {
            std::array::from_fn(|l| chunk.get(l).map_or(PADDING, |p| p[j]))
        };
        level.early_blocks = points
            .chunks(LANES)
            .map(|chunk| std::array::from_fn(|j| lanes(chunk, j)))
            .collect();
        level.late_blocks = points
            .chunks(LANES)
            .map(|chunk| std::array::from_fn(|j| lanes(chunk, EARLY + j)))
            .collect();
        level.pca = Some(pca);
        Ok(level)
    }

    /// Values per patch vector: N * N * channels.
    pub fn dims(&self) -> usize {
        (self.size * self.size) as usize * self.channels
    }

    pub fn pca(&self) -> &PatchPca {
        self.pca.as_ref().expect("built")
    }

    pub fn candidates(&self) -> usize {
        self.centres.len()
    }

    /// Half the patch extent in pixels (= voxels): (N / 2) s.
    pub fn half_extent(&self) -> i32 {
        ((self.size / 2) * self.spacing) as i32
    }

    /// Exemplar pixel index of sample (a, b) of candidate `i`.
    pub fn pixel_index(&self, i: u32, a: u32, b: u32) -> usize {
        let (cx, cy) = self.centres[i as usize];
        let h = self.size / 2;
        let x = cx + a * self.spacing - h * self.spacing;
        let y = cy + b * self.spacing - h * self.spacing;
        (y * self.width + x) as usize
    }

    /// The (filtered) channels of the exemplar pixel `p`.
    pub fn value(&self, p: usize) -> &[u8] {
        &self.image[p * self.channels..(p + 1) * self.channels]
    }

    /// Every pixel value of the filtered exemplar, per channel, sorted ascending (the target of
    /// histogram matching).
    pub fn filtered_values(&self) -> Vec<Vec<u8>> {
        (0..self.channels)
            .map(|c| {
                let mut v: Vec<u8> = self
                    .image
                    .iter()
                    .skip(c)
                    .step_by(self.channels)
                    .copied()
                    .collect();
                v.sort_unstable();
                v
            })
            .collect()
    }

    /// The colour cluster of pixel `p` (0 on levels that do not quantize).
    pub fn cluster(&self, p: usize) -> u32 {
        self.clusters.as_ref().map_or(0, |c| c[p] as u32)
    }

    /// With a mask: per cluster, whether it holds positive-region pixels.
    pub fn cluster_regions(&self) -> Option<&[bool]> {
        self.cluster_regions.as_deref()
    }

    /// Clusters the buckets of this level distinguish (1: plain averaging).
    pub fn cluster_count(&self) -> u32 {
        self.clusters
            .as_ref()
            .map_or(1, |c| c.iter().map(|&v| v as u32 + 1).max().unwrap_or(1))
    }

    /// Candidate `i` as a patch vector (row b, then column a, then channel).
    pub fn vector(&self, i: u32) -> Vec<f32> {
        let mut v = Vec::with_capacity(self.dims());
        for b in 0..self.size {
            for a in 0..self.size {
                v.extend(
                    self.value(self.pixel_index(i, a, b))
                        .iter()
                        .map(|&x| x as f32),
                );
            }
        }
        v
    }

    /// The `k` candidates nearest to a projected query, nearest first (ties by index).
    ///
    /// Exhaustive, hence exact: with 16 dimensions and ~10^4 candidates a k-d tree visits most
    /// leaves anyway (kiddo measured no faster). Blocks of 8 candidates are scored together;
    /// after the first `EARLY` dimensions (the PCA's largest) a block whose partial distances
    /// all reach the current k-th best is skipped: partial sums of squares only grow, so this
    /// rejection never changes the result.
    pub fn nearest(&self, query: &[f32; KEPT], k: usize) -> Vec<(f32, u32)> {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked above). Only the vector width changes: the
            // same IEEE operations in the same order (no FMA contraction), so the same result.
            return unsafe { self.nearest_avx2(query, k) };
        }
        self.nearest_portable(query, k)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn nearest_avx2(&self, query: &[f32; KEPT], k: usize) -> Vec<(f32, u32)> {
        self.nearest_portable(query, k)
    }

    #[inline(always)]
    fn nearest_portable(&self, query: &[f32; KEPT], k: usize) -> Vec<(f32, u32)> {
        let k = k.clamp(1, self.centres.len());
        // The k smallest (distance, index) pairs so far, as a max-heap: distances are squared
        // sums, never negative or NaN, so their bit patterns order like the values. Keeping the
        // k smallest pairs makes the result independent of the visiting order: a sparse first
        // pass (every PROBE-th block, spread over the exemplar) finds a tight k-th distance
        // early, so the full pass rejects more blocks and inserts fewer candidates.
        let mut best: std::collections::BinaryHeap<(u32, u32)> =
            std::collections::BinaryHeap::with_capacity(k + 1);
        let blocks = self.early_blocks.len();
        let probe = (0..blocks).step_by(PROBE);
        let rest = (0..blocks).filter(|bi| bi % PROBE != 0);
        for bi in probe.chain(rest) {
            // Worst kept distance (infinite until k are kept).
            let worst = if best.len() == k {
                f32::from_bits(best.peek().expect("k >= 1").0)
            } else {
                f32::INFINITY
            };
            let mut acc = [0f32; LANES];
            accumulate(&mut acc, &self.early_blocks[bi], &query[..EARLY]);
            // (Partial sums only grow: a block whose lanes all exceed the worst kept distance
            // holds no better candidate; a tie may still win on its index, so <= keeps it.)
            if !any_at_most(&acc, worst) {
                continue;
            }
            let late = &self.late_blocks[bi];
            accumulate(&mut acc, &late[..MIDDLE - EARLY], &query[EARLY..MIDDLE]);
            if !any_at_most(&acc, worst) {
                continue;
            }
            accumulate(&mut acc, &late[MIDDLE - EARLY..], &query[MIDDLE..]);
            for (l, &d) in acc.iter().enumerate() {
                let index = (bi * LANES + l) as u32;
                if index as usize >= self.centres.len() {
                    continue;
                }
                let item = (d.to_bits(), index);
                if best.len() < k {
                    best.push(item);
                } else if let Some(mut top) = best.peek_mut().filter(|top| item < **top) {
                    // Replace the worst kept pair in place (one sift-down).
                    *top = item;
                }
            }
        }
        // (The pairs are distinct: an unstable sort gives the same order.)
        let mut best = best.into_vec();
        best.sort_unstable();
        best.into_iter()
            .map(|(d, i)| (f32::from_bits(d), i))
            .collect()
    }

    /// Sum of squared differences between `line_a` of candidate `a` and `line_b` of `b`
    /// (the crossbar consistency of paper 4.2.1).
    pub fn line_distance(&self, a: u32, line_a: Line, b: u32, line_b: Line) -> u32 {
        let h = self.size / 2;
        let at = |i: u32, line: Line, t: u32| match line {
            Line::Column => self.pixel_index(i, h, t),
            Line::Row => self.pixel_index(i, t, h),
        };
        let mut sum = 0u32;
        for t in 0..self.size {
            let (pa, pb) = (self.value(at(a, line_a, t)), self.value(at(b, line_b, t)));
            for (x, y) in pa.iter().zip(pb) {
                let d = *x as i32 - *y as i32;
                sum += (d * d) as u32;
            }
        }
        sum
    }
}
