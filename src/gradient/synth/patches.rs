//! The exemplar patches of one synthesis level (paper 4.2.1, 4.2.3): N x N samples at pixel
//! spacing s ("fractional sampling": coarser levels double the spacing instead of shrinking the
//! grid), their PCA projections for the nearest-patch search, and what the bucket step reads back: the sample
//! values and, at the finest level, their colour clusters.

use super::buckets::PackedSums;
use super::folded::FoldedProjection;
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

/// A (distance, index) pair as one integer that orders like the pair: distances are squared
/// sums, never negative or NaN, so their bit patterns order like the values. One compare
/// instead of two in the selections below.
#[inline(always)]
fn key(distance: f32, index: u32) -> u64 {
    ((distance.to_bits() as u64) << 32) | index as u64
}

/// Moves the `p` smallest keys of `order` to its front, in ascending order (the rest after
/// them, in no particular order): one pass with an insertion into the sorted front.
fn nearest_first(order: &mut [u64], p: usize) {
    if p == 0 {
        return;
    }
    order[..p].sort_unstable();
    let mut last = order[p - 1];
    for i in p..order.len() {
        let item = order[i];
        if item < last {
            // Insert into the front run (shifting its larger keys up); its largest goes to
            // position i.
            order[i] = last;
            let mut j = p - 1;
            while j > 0 && order[j - 1] > item {
                order[j] = order[j - 1];
                j -= 1;
            }
            order[j] = item;
            last = order[p - 1];
        }
    }
}

/// The k smallest (distance, candidate) [`key`]s offered, kept as an unsorted buffer that
/// is cut back to its k smallest whenever it reaches 2k (amortized constant work per offer;
/// a binary heap's sift per replacement cost a third of the search). The keys are distinct,
/// so the k smallest are one set whatever the order of the offers.
struct KBest {
    k: usize,
    items: Vec<u64>,
    /// The k-th smallest distance at the last cut (infinite before k were kept): anything
    /// larger can never enter.
    worst: f32,
}

impl KBest {
    fn new(k: usize) -> KBest {
        KBest {
            k,
            items: Vec::with_capacity(2 * k),
            worst: f32::INFINITY,
        }
    }

    #[inline(always)]
    fn worst(&self) -> f32 {
        self.worst
    }

    #[inline(always)]
    fn offer(&mut self, item: u64) {
        if self.k == 1 {
            // The nearest only: keep the smaller key, the bound exact at once.
            match self.items.first_mut() {
                Some(kept) if *kept <= item => {}
                Some(kept) => *kept = item,
                None => self.items.push(item),
            }
            self.worst = f32::from_bits((self.items[0] >> 32) as u32);
            return;
        }
        self.items.push(item);
        if self.items.len() == 2 * self.k {
            self.cut();
        }
    }

    /// Keeps the k smallest pairs.
    fn cut(&mut self) {
        let k = self.k;
        if self.items.len() > k {
            self.items.select_nth_unstable(k - 1);
            self.items.truncate(k);
        }
        if self.items.len() == k {
            let kth = self.items.iter().max().expect("k >= 1");
            self.worst = f32::from_bits((kth >> 32) as u32);
        }
    }

    /// The k smallest pairs (fewer if fewer were offered), nearest first.
    fn finish(mut self) -> Vec<(f32, u32)> {
        self.cut();
        self.items.sort_unstable();
        self.items
            .into_iter()
            .map(|item| (f32::from_bits((item >> 32) as u32), item as u32))
            .collect()
    }
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
    /// Per pixel, its cluster (0 on levels that do not quantize) and its sample as four
    /// 16-bit lanes: 1 (a count), then each channel's value. What the CPU bucket accumulation
    /// adds with one integer addition ([`Self::packed_samples`]); empty beyond 3 channels.
    packed_samples: Vec<(u32, u64)>,
    /// Centre pixel of every candidate patch.
    centres: Vec<(u32, u32)>,
    /// Set by `build` (an option only so `vector` can be used while building).
    pca: Option<PatchPca>,
    /// The axis-aligned slices' projection folded over control points (set by `build`).
    folded: Option<FoldedProjection>,
    /// The candidates' projections, 8 per block, dimension-major inside a block (padding lanes
    /// hold a huge value): the layout an exhaustive search vectorizes over. Blocks are grouped
    /// by list of the inverted-file partition ([`super::ivf`]), so a search can scan the lists
    /// nearest to its query first (exact) or only (approximate).
    /// The first EARLY dimensions of every block, apart from the rest: the pass that rejects
    /// most blocks reads only these (186 KB for 11,664 patches: they stay in the L2 cache).
    early_blocks: Vec<[[f32; LANES]; EARLY]>,
    late_blocks: Vec<[[f32; LANES]; KEPT - EARLY]>,
    /// Centre column and row of every candidate ([`Self::gather_lines`]).
    lines: Vec<u8>,
    /// Candidate index of every lane of every block (NO_CANDIDATE: padding).
    lane_candidates: Vec<[u32; LANES]>,
    /// Blocks of each list, and the list centres.
    lists: Vec<std::ops::Range<usize>>,
    /// Candidates of each list.
    list_sizes: Vec<usize>,
    /// Per block, a bit per lane holding a candidate (not padding).
    lane_masks: Vec<u8>,
    list_centres: Vec<[f32; KEPT]>,
    /// The list centres, 8 per block, dimension-major (the candidates' layout).
    centre_blocks: Vec<[[f32; LANES]; KEPT]>,
}

/// A padding lane's candidate index.
const NO_CANDIDATE: u32 = u32::MAX;

/// Candidates per block of the exhaustive search.
const LANES: usize = 8;
/// PCA dimensions (the largest) scored before the first rejection test, and before the second.
const EARLY: usize = 4;
const MIDDLE: usize = 8;
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
            packed_samples: Vec::new(),
            centres,
            pca: None,
            folded: None,
            early_blocks: Vec::new(),
            late_blocks: Vec::new(),
            lines: Vec::new(),
            lane_candidates: Vec::new(),
            lists: Vec::new(),
            list_sizes: Vec::new(),
            lane_masks: Vec::new(),
            list_centres: Vec::new(),
            centre_blocks: Vec::new(),
        };
        level.lines = level.gather_lines();
        level.packed_samples = level.pack_samples();
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
        let (labels, centres) =
            super::ivf::partition(&points, super::ivf::list_count(points.len()));
        let mut members = vec![Vec::new(); centres.len()];
        for (i, &list) in labels.iter().enumerate() {
            members[list as usize].push(i as u32);
        }
        let lanes = |chunk: &[u32], j: usize| -> [f32; LANES] {
            std::array::from_fn(|l| chunk.get(l).map_or(PADDING, |&i| points[i as usize][j]))
        };
        for list in &members {
            let start = level.early_blocks.len();
            for chunk in list.chunks(LANES) {
                level
                    .early_blocks
                    .push(std::array::from_fn(|j| lanes(chunk, j)));
                level
                    .late_blocks
                    .push(std::array::from_fn(|j| lanes(chunk, EARLY + j)));
                level.lane_candidates.push(std::array::from_fn(|l| {
                    chunk.get(l).copied().unwrap_or(NO_CANDIDATE)
                }));
                level.lane_masks.push(((1u32 << chunk.len()) - 1) as u8);
            }
            level.lists.push(start..level.early_blocks.len());
            level.list_sizes.push(list.len());
        }
        level.centre_blocks = centres
            .chunks(LANES)
            .map(|chunk| {
                std::array::from_fn(|j| {
                    std::array::from_fn(|l| chunk.get(l).map_or(PADDING, |c| c[j]))
                })
            })
            .collect();
        level.list_centres = centres;
        level.folded = Some(FoldedProjection::new(
            &pca,
            level.size,
            level.spacing,
            level.channels,
        ));
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

    /// The projection of axis-aligned slices, folded over control points.
    pub fn folded(&self) -> &FoldedProjection {
        self.folded.as_ref().expect("built")
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

    /// Per pixel, its cluster and its sample packed as 16-bit lanes (count 1, then the channel
    /// values), when the level has at most 3 channels; `None` otherwise.
    pub fn packed_samples(&self) -> Option<&[(u32, u64)]> {
        (!self.packed_samples.is_empty()).then_some(&self.packed_samples[..])
    }

    fn pack_samples(&self) -> Vec<(u32, u64)> {
        if self.channels > PackedSums::CHANNELS {
            return Vec::new();
        }
        (0..self.image.len() / self.channels)
            .map(|p| (self.cluster(p), PackedSums::pack(self.value(p))))
            .collect()
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
    /// With `probes: None`, exhaustive, hence exact: with 16 dimensions and ~10^4 candidates a
    /// k-d tree visits most leaves anyway (kiddo measured no faster). With `Some(p)`, the
    /// approximate search the paper uses at this step (ANN, 4.2.1): only the `p` lists of the
    /// inverted-file partition whose centres are nearest to the query are scanned (more if
    /// they hold fewer than `k` candidates). Either way the lists are scanned nearest first,
    /// so the k-th distance is tight early; blocks of 8 candidates are scored together, and
    /// after the first `EARLY` dimensions (the PCA's largest) a block whose partial distances
    /// all reach the current k-th best is skipped: partial sums of squares only grow, so this
    /// rejection never changes the result.
    pub fn nearest(&self, query: &[f32; KEPT], k: usize, probes: Option<usize>) -> Vec<(f32, u32)> {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2")
            && std::is_x86_feature_detected!("popcnt")
            && std::is_x86_feature_detected!("bmi1")
        {
            // SAFETY: the CPU supports AVX2, POPCNT and BMI1 (checked above). Only the vector
            // width and the bit instructions change: the same IEEE operations in the same
            // order (no FMA contraction), so the same result.
            return unsafe { self.nearest_avx2(query, k, probes) };
        }
        self.nearest_portable(query, k, probes)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt,bmi1")]
    unsafe fn nearest_avx2(
        &self,
        query: &[f32; KEPT],
        k: usize,
        probes: Option<usize>,
    ) -> Vec<(f32, u32)> {
        self.nearest_with::<true>(query, k, probes)
    }

    fn nearest_portable(
        &self,
        query: &[f32; KEPT],
        k: usize,
        probes: Option<usize>,
    ) -> Vec<(f32, u32)> {
        self.nearest_with::<false>(query, k, probes)
    }

    /// The search; with `AVX2` (only inside [`Self::nearest_avx2`]) its blocks are scored by
    /// [`Self::scan_block_avx2`].
    #[inline(always)]
    fn nearest_with<const AVX2: bool>(
        &self,
        query: &[f32; KEPT],
        k: usize,
        probes: Option<usize>,
    ) -> Vec<(f32, u32)> {
        let k = k.clamp(1, self.centres.len());
        // Lists by the distance of their centre to the query (ties by list index), the centres
        // scored 8 at a time like the candidates.
        let mut order: Vec<u64> = Vec::with_capacity(self.list_centres.len());
        for (bi, block) in self.centre_blocks.iter().enumerate() {
            let mut acc = [0f32; LANES];
            accumulate(&mut acc, block, query);
            for (l, d) in acc.iter().enumerate() {
                let list = bi * LANES + l;
                if list < self.list_centres.len() {
                    order.push(key(*d, list as u32));
                }
            }
        }
        // The approximate search needs only its nearest `p` lists in order: an insertion into
        // a short sorted run (sorting all of them, or a selection, cost about as much as
        // scanning those). The rest is sorted only if those hold fewer than k candidates.
        let sorted = match probes {
            Some(p) if p < order.len() => {
                nearest_first(&mut order, p);
                p
            }
            _ => {
                order.sort_unstable();
                order.len()
            }
        };
        let mut best = KBest::new(k);
        let mut scanned = 0;
        for probed in 0..order.len() {
            if probes.is_some_and(|p| probed >= p && scanned >= k) {
                break;
            }
            if probed == sorted {
                order[sorted..].sort_unstable();
            }
            let list = order[probed] as u32 as usize;
            for bi in self.lists[list].clone() {
                #[cfg(target_arch = "x86_64")]
                if AVX2 {
                    // SAFETY: AVX2 is only set inside `nearest_avx2`, called once the CPU's
                    // AVX2 support was detected.
                    unsafe { self.scan_block_avx2(bi, query, &mut best) };
                    continue;
                }
                self.scan_block(bi, query, &mut best);
            }
            scanned += self.list_sizes[list];
        }
        best.finish()
    }

    /// [`Self::scan_block`] written with AVX2 intrinsics: the partial sums stay in one
    /// register and the lane tests are one compare and a mask (the compiler's version spilled
    /// them and compared lane by lane). The same operations per lane in the same order (sub,
    /// mul, add; no FMA), so the same distances and the same offers.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn scan_block_avx2(&self, bi: usize, query: &[f32; KEPT], best: &mut KBest) {
        use std::arch::x86_64::*;
        let worst = best.worst();
        let limit = _mm256_set1_ps(worst);
        let early = &self.early_blocks[bi];
        let late = &self.late_blocks[bi];
        let lanes = |j: usize| {
            let row = if j < EARLY {
                &early[j]
            } else {
                &late[j - EARLY]
            };
            _mm256_loadu_ps(row.as_ptr())
        };
        let mut acc = _mm256_setzero_ps();
        let add = |acc: &mut __m256, j: usize| {
            let d = _mm256_sub_ps(lanes(j), _mm256_set1_ps(query[j]));
            *acc = _mm256_add_ps(*acc, _mm256_mul_ps(d, d));
        };
        let at_most = |acc: __m256| _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(acc, limit));
        for j in 0..EARLY {
            add(&mut acc, j);
        }
        if at_most(acc) == 0 {
            return;
        }
        for j in EARLY..MIDDLE {
            add(&mut acc, j);
        }
        if at_most(acc) == 0 {
            return;
        }
        for j in MIDDLE..KEPT {
            add(&mut acc, j);
        }
        let mut entering = at_most(acc) as u32 & self.lane_masks[bi] as u32;
        if entering == 0 {
            return;
        }
        let mut distances = [0f32; LANES];
        _mm256_storeu_ps(distances.as_mut_ptr(), acc);
        let candidates = &self.lane_candidates[bi];
        while entering != 0 {
            let l = entering.trailing_zeros() as usize;
            entering &= entering - 1;
            best.offer(key(distances[l], candidates[l]));
        }
    }

    /// Scores block `bi` against the query and offers its candidates within the worst kept
    /// distance to `best`.
    #[inline(always)]
    fn scan_block(&self, bi: usize, query: &[f32; KEPT], best: &mut KBest) {
        let candidates = &self.lane_candidates[bi];
        let worst = best.worst();
        let mut acc = [0f32; LANES];
        accumulate(&mut acc, &self.early_blocks[bi], &query[..EARLY]);
        // (Partial sums only grow: a block whose lanes all exceed the worst kept distance
        // holds no better candidate; a tie may still win on its index, so <= keeps it.)
        if !any_at_most(&acc, worst) {
            return;
        }
        let late = &self.late_blocks[bi];
        accumulate(&mut acc, &late[..MIDDLE - EARLY], &query[EARLY..MIDDLE]);
        if !any_at_most(&acc, worst) {
            return;
        }
        accumulate(&mut acc, &late[MIDDLE - EARLY..], &query[MIDDLE..]);
        // Only the lanes within the worst kept distance can enter (a lane-wise compare; most
        // fully scored blocks hold one or two such lanes), padding lanes never.
        let mut entering = 0u32;
        for (l, (&d, &index)) in acc.iter().zip(candidates).enumerate() {
            entering |= ((d <= worst && index != NO_CANDIDATE) as u32) << l;
        }
        while entering != 0 {
            let l = entering.trailing_zeros() as usize;
            entering &= entering - 1;
            best.offer(key(acc[l], candidates[l]));
        }
    }

    /// Sum of squared differences between `line_a` of candidate `a` and `line_b` of `b`
    /// (the crossbar consistency of paper 4.2.1).
    pub fn line_distance(&self, a: u32, line_a: Line, b: u32, line_b: Line) -> u32 {
        let (pa, pb) = (self.line(a, line_a), self.line(b, line_b));
        pa.iter()
            .zip(pb)
            .map(|(&x, &y)| {
                let d = x as i32 - y as i32;
                (d * d) as u32
            })
            .sum()
    }

    /// The values of `line` of candidate `i`, sample after sample (N * channels bytes).
    fn line(&self, i: u32, line: Line) -> &[u8] {
        let len = self.size as usize * self.channels;
        let start = (2 * i as usize + matches!(line, Line::Row) as usize) * len;
        &self.lines[start..start + len]
    }

    /// Every candidate's centre column then centre row, contiguous (what [`Self::line`] reads):
    /// the crossbar tests compare ~120 lines per check point, which gathered pixel by pixel
    /// from the exemplar cost more than the comparisons.
    fn gather_lines(&self) -> Vec<u8> {
        let h = self.size / 2;
        let mut lines =
            Vec::with_capacity(self.centres.len() * 2 * self.size as usize * self.channels);
        for i in 0..self.centres.len() as u32 {
            for t in 0..self.size {
                lines.extend_from_slice(self.value(self.pixel_index(i, h, t)));
            }
            for t in 0..self.size {
                lines.extend_from_slice(self.value(self.pixel_index(i, t, h)));
            }
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::hash::SeededRng;

    #[test]
    fn selection_helpers_equal_a_full_sort() {
        let mut rng = SeededRng::new(7);
        for round in 0..200 {
            let n = 1 + rng.below(300) as usize;
            // Few distinct distances: many ties, broken by the index.
            let pairs: Vec<(u32, u32)> = (0..n)
                .map(|i| (rng.below(1 + round % 20) as u32, i as u32))
                .collect();
            let mut sorted = pairs.clone();
            sorted.sort_unstable();
            let p = 1 + rng.below(n as u64) as usize;
            let mut order: Vec<u64> = pairs
                .iter()
                .map(|&(d, i)| key(f32::from_bits(d), i))
                .collect();
            nearest_first(&mut order, p);
            let order: Vec<(u32, u32)> = order
                .iter()
                .map(|&k| ((k >> 32) as u32, k as u32))
                .collect();
            assert_eq!(order[..p], sorted[..p]);
            let mut rest = order[p..].to_vec();
            rest.sort_unstable();
            assert_eq!(rest, sorted[p..]);
            let k = 1 + rng.below(60) as usize;
            let mut best = KBest::new(k);
            for &(d, i) in &pairs {
                if f32::from_bits(d) <= best.worst() {
                    best.offer(key(f32::from_bits(d), i));
                }
            }
            let kept: Vec<(u32, u32)> = best
                .finish()
                .iter()
                .map(|&(d, i)| (d.to_bits(), i))
                .collect();
            assert_eq!(kept, sorted[..k.min(n)]);
        }
    }

    /// Candidates of a 64x64 crop of the built-in exemplar (3,600 patches of 5x5 samples).
    fn level() -> LevelPatches {
        let full = crate::exemplar::default_exemplar();
        let mut img = Image::new(64, 64, full.channels);
        for y in 0..64 {
            for x in 0..64 {
                let p = full.at(x, y).to_vec();
                let i = ((y * 64 + x) * full.channels) as usize;
                img.pixels[i..i + p.len()].copy_from_slice(&p);
            }
        }
        LevelPatches::build(&img, 1, 5, None, None, 3).unwrap()
    }

    /// Every candidate's projection, by candidate index (read back from the blocks).
    fn projections(level: &LevelPatches) -> Vec<[f32; KEPT]> {
        let mut out = vec![[0f32; KEPT]; level.candidates()];
        for (bi, lanes) in level.lane_candidates.iter().enumerate() {
            for (l, &i) in lanes.iter().enumerate() {
                if i != NO_CANDIDATE {
                    out[i as usize] = std::array::from_fn(|j| {
                        if j < EARLY {
                            level.early_blocks[bi][j][l]
                        } else {
                            level.late_blocks[bi][j - EARLY][l]
                        }
                    });
                }
            }
        }
        out
    }

    /// The k nearest by brute force, distances summed in the search's order.
    fn brute(points: &[[f32; KEPT]], q: &[f32; KEPT], k: usize) -> Vec<(f32, u32)> {
        let mut all: Vec<(u32, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| (super::super::ivf::distance(q, p).to_bits(), i as u32))
            .collect();
        all.sort_unstable();
        all.truncate(k);
        all.into_iter()
            .map(|(d, i)| (f32::from_bits(d), i))
            .collect()
    }

    /// Queries near the candidates (a candidate's projection plus noise), as in synthesis.
    fn queries(points: &[[f32; KEPT]], n: usize) -> Vec<[f32; KEPT]> {
        let mut rng = SeededRng::new(11);
        (0..n)
            .map(|_| {
                let p = points[rng.below(points.len() as u64) as usize];
                std::array::from_fn(|j| p[j] + (rng.below(2001) as f32 - 1000.0) / 50.0)
            })
            .collect()
    }

    #[test]
    fn every_candidate_is_in_exactly_one_list() {
        let level = level();
        let mut seen = vec![0u32; level.candidates()];
        for list in &level.lists {
            for bi in list.clone() {
                for &i in &level.lane_candidates[bi] {
                    if i != NO_CANDIDATE {
                        seen[i as usize] += 1;
                    }
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1));
        assert_eq!(
            level.lists.len(),
            super::super::ivf::list_count(level.candidates())
        );
    }

    #[test]
    fn exact_search_equals_brute_force() {
        let level = level();
        let points = projections(&level);
        for q in queries(&points, 60) {
            for k in [1, 20, 50] {
                assert_eq!(level.nearest(&q, k, None), brute(&points, &q, k), "k = {k}");
            }
        }
        // Probing every list is the exact search.
        let q = queries(&points, 1)[0];
        let all = Some(level.lists.len());
        assert_eq!(level.nearest(&q, 20, all), level.nearest(&q, 20, None));
    }

    #[test]
    fn approximate_search_finds_most_nearest_patches() {
        let level = level();
        let points = projections(&level);
        let qs = queries(&points, 400);
        let (mut hits, mut recall) = (0, 0.0);
        for q in &qs {
            let approx = level.nearest(q, 20, Some(8));
            let exact = brute(&points, q, 20);
            // k distinct candidates, nearest first, with their true distances.
            assert_eq!(approx.len(), 20);
            assert!(approx
                .windows(2)
                .all(|w| (w[0].0, w[0].1) < (w[1].0, w[1].1)));
            for &(d, i) in &approx {
                assert_eq!(d, super::super::ivf::distance(q, &points[i as usize]));
            }
            hits += (approx[0] == exact[0]) as u32;
            recall += approx.iter().filter(|a| exact.contains(a)).count() as f64 / 20.0;
        }
        let (hit_rate, recall) = (hits as f64 / qs.len() as f64, recall / qs.len() as f64);
        assert!(
            hit_rate >= 0.95,
            "nearest found for {hit_rate:.3} of the queries"
        );
        assert!(recall >= 0.9, "recall of the 20 nearest {recall:.3}");
        // Fewer candidates in the probed lists than k: more lists are scanned.
        assert_eq!(level.nearest(&qs[0], 3000, Some(1)).len(), 3000);
    }
}
