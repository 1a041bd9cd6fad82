//! An inverted-file index of projected points (candidate patches, or crossbar lines) for the
//! nearest-neighbour searches of gradient synthesis (the paper uses an approximate search, ANN,
//! at this step: 4.2.1). The points are split into lists by k-means; a query scans only the
//! lists whose centres lie nearest to it ([`IvfIndex::nearest`]). Deterministic: fixed initial
//! centres, a fixed number of Lloyd iterations, sums in index order.
//!

use super::pca::KEPT;
use rayon::prelude::*;

/// Lloyd iterations of the partition.
const ITERATIONS: usize = 8;

/// Squared distance of two projections, summed in dimension order.
#[inline]
pub fn distance(a: &[f32; KEPT], b: &[f32; KEPT]) -> f32 {
    let mut d = 0.0;
    for j in 0..KEPT {
        let t = a[j] - b[j];
        d += t * t;
    }
    d
}

/// Squared distance of two projections, summed as 8 lanes (dimensions j and j + 8) and then
/// pairwise: a fixed order that vectorizes, unlike [`distance`]'s. For scoring a few chosen
/// points against each other ([`super::matching`]); not comparable bit for bit with
/// [`distance`].
#[inline(always)]
pub fn lane_distance(a: &[f32; KEPT], b: &[f32; KEPT]) -> f32 {
    const HALF: usize = KEPT / 2;
    let mut acc = [0f32; HALF];
    for j in 0..HALF {
        let (s, t) = (a[j] - b[j], a[j + HALF] - b[j + HALF]);
        acc[j] = s * s + t * t;
    }
    let quad: [f32; 4] = std::array::from_fn(|j| acc[j] + acc[j + 4]);
    (quad[0] + quad[2]) + (quad[1] + quad[3])
}

/// The list count for `n` candidates: about sqrt(n), a power of two, 1..=256.
pub fn list_count(n: usize) -> usize {
    ((n as f64).sqrt() as usize)
        .next_power_of_two()
        .clamp(1, 256)
}

/// `centres` 8 per block, dimension-major (padding lanes far away): the layout
/// [`accumulate`] scores 8 at a time.
fn centre_blocks(centres: &[[f32; KEPT]]) -> Vec<[[f32; LANES]; KEPT]> {
    centres
        .chunks(LANES)
        .map(|chunk| {
            std::array::from_fn(|j| std::array::from_fn(|l| chunk.get(l).map_or(PADDING, |c| c[j])))
        })
        .collect()
}

/// Index of the centre nearest to each of `points` (ties: the lower index), the centres
/// given as [`centre_blocks`]. Each lane sums its dimensions in order, like [`distance`]:
/// the same distances as one centre at a time, 8 centres per vector operation.
#[inline(always)]
fn nearest_centres(points: &[[f32; KEPT]], blocks: &[[[f32; LANES]; KEPT]]) -> Vec<u32> {
    let mut labels = Vec::with_capacity(points.len());
    for p in points {
        let mut best = (f32::INFINITY, 0);
        for (bi, block) in blocks.iter().enumerate() {
            let mut acc = [0f32; LANES];
            accumulate(&mut acc, block, p);
            for (l, &d) in acc.iter().enumerate() {
                if d < best.0 {
                    best = (d, (bi * LANES + l) as u32);
                }
            }
        }
        labels.push(best.1);
    }
    labels
}

/// [`nearest_centres`] in parallel, compiled for AVX2 when the CPU has it (the same
/// operations in the same order either way).
fn label(points: &[[f32; KEPT]], centres: &[[f32; KEPT]]) -> Vec<u32> {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn nearest_centres_avx2(
        points: &[[f32; KEPT]],
        blocks: &[[[f32; LANES]; KEPT]],
    ) -> Vec<u32> {
        nearest_centres(points, blocks)
    }
    let blocks = centre_blocks(centres);
    points
        .par_chunks(256)
        .flat_map_iter(|chunk| {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                return unsafe { nearest_centres_avx2(chunk, &blocks) };
            }
            nearest_centres(chunk, &blocks)
        })
        .collect()
}

/// K-means of `points` into `lists` lists: every point's list and the list centres. The
/// initial centres are points picked by a golden-ratio sequence over the candidate order (a
/// regular stride would alias with the raster order of the candidates' exemplar positions);
/// an emptied list keeps its centre.
pub fn partition(points: &[[f32; KEPT]], lists: usize) -> (Vec<u32>, Vec<[f32; KEPT]>) {
    let lists = lists.clamp(1, points.len().max(1));
    const GOLDEN: f64 = 0.618_033_988_749_894_9;
    let mut centres: Vec<[f32; KEPT]> = (0..lists)
        .map(|j| {
            let t = (0.5 + j as f64 * GOLDEN).fract();
            points[((t * points.len() as f64) as usize).min(points.len() - 1)]
        })
        .collect();
    let mut labels = vec![0u32; points.len()];
    for _ in 0..ITERATIONS {
        labels = label(points, &centres);
        let mut sums = vec![[0f64; KEPT]; lists];
        let mut counts = vec![0usize; lists];
        for (p, &l) in points.iter().zip(&labels) {
            counts[l as usize] += 1;
            for (s, &v) in sums[l as usize].iter_mut().zip(p) {
                *s += v as f64;
            }
        }
        for j in 0..lists {
            if counts[j] > 0 {
                centres[j] = std::array::from_fn(|d| (sums[j][d] / counts[j] as f64) as f32);
            }
        }
    }
    let labels = label(points, &centres);
    (labels, centres)
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

/// Points in blocks of 8, grouped by list of a k-means partition ([`partition`]).
pub struct IvfIndex {
    /// The points' projections, 8 per block, dimension-major inside a block (padding lanes
    /// hold a huge value): the layout an exhaustive search vectorizes over. Blocks are grouped
    /// by list, so a search can scan the lists nearest to its query first (exact) or only
    /// (approximate).
    /// The first EARLY dimensions of every block, apart from the rest: the pass that rejects
    /// most blocks reads only these (186 KB for 11,664 patches: they stay in the L2 cache).
    early_blocks: Vec<[[f32; LANES]; EARLY]>,
    late_blocks: Vec<[[f32; LANES]; KEPT - EARLY]>,
    /// Point index of every lane of every block (NO_CANDIDATE: padding).
    lane_candidates: Vec<[u32; LANES]>,
    /// Blocks of each list.
    lists: Vec<std::ops::Range<usize>>,
    /// Points of each list.
    list_sizes: Vec<usize>,
    /// Per block, a bit per lane holding a point (not padding).
    lane_masks: Vec<u8>,
    list_centres: Vec<[f32; KEPT]>,
    /// The list centres, 8 per block, dimension-major (the points' layout).
    centre_blocks: Vec<[[f32; LANES]; KEPT]>,
    /// Points indexed.
    len: usize,
}

impl IvfIndex {
    /// The index of `points` (about sqrt(n) lists, [`list_count`]).
    pub fn build(points: &[[f32; KEPT]]) -> IvfIndex {
        let (labels, centres) = partition(points, list_count(points.len()));
        let mut members = vec![Vec::new(); centres.len()];
        for (i, &list) in labels.iter().enumerate() {
            members[list as usize].push(i as u32);
        }
        let lanes = |chunk: &[u32], j: usize| -> [f32; LANES] {
            std::array::from_fn(|l| chunk.get(l).map_or(PADDING, |&i| points[i as usize][j]))
        };
        let mut index = IvfIndex {
            early_blocks: Vec::new(),
            late_blocks: Vec::new(),
            lane_candidates: Vec::new(),
            lists: Vec::new(),
            list_sizes: Vec::new(),
            lane_masks: Vec::new(),
            list_centres: Vec::new(),
            centre_blocks: Vec::new(),
            len: points.len(),
        };
        for list in &members {
            let start = index.early_blocks.len();
            for chunk in list.chunks(LANES) {
                index
                    .early_blocks
                    .push(std::array::from_fn(|j| lanes(chunk, j)));
                index
                    .late_blocks
                    .push(std::array::from_fn(|j| lanes(chunk, EARLY + j)));
                index.lane_candidates.push(std::array::from_fn(|l| {
                    chunk.get(l).copied().unwrap_or(NO_CANDIDATE)
                }));
                index.lane_masks.push(((1u32 << chunk.len()) - 1) as u8);
            }
            index.lists.push(start..index.early_blocks.len());
            index.list_sizes.push(list.len());
        }
        index.centre_blocks = centre_blocks(&centres);
        index.list_centres = centres;
        index
    }

    /// Lists of the partition.
    pub fn list_count(&self) -> usize {
        self.lists.len()
    }

    /// The `k` points nearest to a projected query, nearest first (ties by index).
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
        let k = k.clamp(1, self.len);
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
}

#[cfg(test)]
mod tests;
