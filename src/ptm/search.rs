//! Block neighbourhood search (the paper's section VII): which source blocks have a causal
//! neighbourhood (the overlap with already synthesized blocks) within a tolerance of the best?
//!
//! Two searches with identical results:
//! - [`Searcher::brute`]: the exact distance to every candidate block.
//! - [`Searcher::projection`]: the projection-kernel rejection scheme of Hel-Or & Hel-Or. Each
//!   neighbourhood vector is projected onto an energy-compacting basis, and the squared distance
//!   of the first few projections is a lower bound of the full distance (the paper's eq. 2).
//!   The basis is the paper's "SVD of the neighbourhood ensemble": per rectangle of the
//!   neighbourhood (top strip, corner, lower-left strip), the principal components of a sample of
//!   the source's blocks, computed once, as are the source's projections onto them. A query is
//!   projected once; a candidate's bound then costs a few subtractions and multiplications.
//!   Projections are accumulated in stages (8, 16, 32 kernels); candidates whose bound exceeds
//!   the threshold of the best distance found so far are rejected; survivors get exact distances
//!   (which themselves stop early once a partial sum exceeds the threshold).
//!
//! Exactness: features are integers (the orthonormal Legendre coefficients quantized, see
//! [`FEATURE_SCALE`]) and the basis is rounded to an integer matrix P, so every projection,
//! distance and bound is integer arithmetic: exact, independent of summation order and thread
//! count. Rounding makes P only nearly orthogonal, so the bound divides by S, an integer upper
//! bound of P's largest squared singular value (Gershgorin's bound on the exact Gram matrix
//! P P^T): |P x|^2 <= lambda_max(P P^T) |x|^2 <= S |x|^2, hence floor(|P (q - c)|^2 / S) <=
//! |q - c|^2 for every candidate, whatever P is. (So exactness does not depend on the floating
//! point PCA, only the speed does.) A candidate is rejected only when its bound exceeds the
//! threshold of a distance already achieved, which is at least the final threshold (the
//! threshold is nondecreasing in the best distance), so no candidate within the final threshold
//! is ever rejected. Both searches keep exactly the candidates with distance <= threshold(best):
//! the same set, in index order, so the same seeded choice. Ties go to the smallest index.
//!
//! The features the searches compare ([`FeatureImage`]) and the neighbourhood shapes
//! ([`template`]) are submodules of their own.

mod features;
mod neighbourhood;

pub use features::{
    feature_dims, features, squared_difference, texel_features, FeatureImage, FEATURE_SCALE,
};
use neighbourhood::{part_rect, parts};
pub use neighbourhood::{template, Rect, Shape};

use rayon::prelude::*;

/// Which candidates are acceptable: those with distance <= best + best * permille / 1000
/// (Efros-Freeman's "within a tolerance of the best"; 0 keeps only the best, ties included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tolerance {
    pub permille: u32,
}

impl Tolerance {
    /// floor(best * (1000 + permille) / 1000) without overflow; nondecreasing in `best`
    /// (rejection relies on it).
    #[inline]
    pub fn threshold(&self, best: u64) -> u64 {
        let p = self.permille as u64;
        best.saturating_add((best / 1000) * p + (best % 1000) * p / 1000)
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
    /// Candidates still alive after each projection stage.
    pub survivors: Vec<u64>,
    /// Exact distances computed (most stop early).
    pub exact: u64,
}

impl SearchStats {
    /// Adds another search's counters to these.
    pub fn add(&mut self, other: &SearchStats) {
        self.queries += other.queries;
        self.candidates += other.candidates;
        if self.survivors.len() < other.survivors.len() {
            self.survivors.resize(other.survivors.len(), 0);
        }
        for (a, b) in self.survivors.iter_mut().zip(&other.survivors) {
            *a += b;
        }
        self.exact += other.exact;
    }
}

/// Kernels per rectangle, and the stages at which bounds are evaluated (kernels used so far).
pub const KERNELS: usize = 32;
pub const STAGES: [usize; 3] = [8, 16, 32];
/// Exact distances computed at each stage, for the survivors with the smallest bounds.
const TIGHTEN: usize = 4;
/// Blocks sampled for the principal components.
const PCA_SAMPLE: usize = 144;
/// The unit basis vectors are scaled by this before rounding to integers.
const BASIS_SCALE: f64 = 256.0;
/// Every projection (of any neighbourhood: features are clamped to +-32767) stays below this in
/// magnitude, kernels being scaled down until their L1 norm guarantees it: differences then fit
/// an i32 and the sum of 2 x 32 squared differences fits a u64, with no overflow checks.
const PROJECTION_LIMIT: i64 = 1 << 28;

/// The integer projection kernels of one rectangle and the source's projections onto them.
struct Projection {
    rect: Rect,
    /// KERNELS x (pixels x dims), row-major; |values| <= 256.
    basis: Vec<i16>,
    /// For each stage, S: an integer >= the largest eigenvalue of the Gram matrix of the
    /// stage's kernels (Gershgorin: the largest absolute row sum).
    norm: [u128; STAGES.len()],
    /// candidates x KERNELS.
    proj: Vec<i32>,
    /// The first stage's projections again, kernel-major (STAGES[0] x candidates): the first
    /// stage bounds every candidate in loops the compiler vectorizes across candidates.
    first: Vec<i32>,
}

/// The source features and everything precomputed for searching its blocks.
pub struct Searcher {
    pub source: FeatureImage,
    pub block: u32,
    pub overlap: u32,
    /// Candidate block origins per row and column: (width - block + 1, height - block + 1).
    pub cand_w: u32,
    pub cand_h: u32,
    /// The source features as i16 (they are clamped to its range), for the projections.
    source16: Vec<i16>,
    parts: std::sync::Mutex<[Option<std::sync::Arc<Projection>>; 3]>,
}

impl Searcher {
    /// `block` and `overlap` must fit the source (checked by the caller).
    pub fn new(source: FeatureImage, block: u32, overlap: u32) -> Self {
        let cand_w = source.width - block + 1;
        let cand_h = source.height - block + 1;
        let source16 = source.data.iter().map(|&v| v as i16).collect();
        Searcher {
            source16,
            source,
            block,
            overlap,
            cand_w,
            cand_h,
            parts: Default::default(),
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
    /// block at (qx, qy) of `out`. Stops early, returning a partial sum > limit, once the sum
    /// exceeds `limit` (partial sums of squares are lower bounds too).
    pub fn distance(
        &self,
        i: u32,
        out: &FeatureImage,
        qx: u32,
        qy: u32,
        rects: &[Rect],
        limit: u64,
    ) -> u64 {
        let (cx, cy) = self.origin(i);
        let mut acc = 0u64;
        for r in rects {
            for row in 0..r.h {
                let a = self.source.run(cx + r.x, cy + r.y + row, r.w);
                let b = out.run(qx + r.x, qy + r.y + row, r.w);
                acc += squared_difference(a, b);
                if acc > limit {
                    return acc;
                }
            }
        }
        acc
    }

    /// The values of rectangle `r` of the block at (x, y) of `img`, row by row, as i16.
    fn gather(img: &FeatureImage, x: u32, y: u32, r: &Rect, out: &mut Vec<i16>) {
        out.clear();
        for row in 0..r.h {
            out.extend(
                img.run(x + r.x, y + r.y + row, r.w)
                    .iter()
                    .map(|&v| v as i16),
            );
        }
    }

    /// [`Searcher::gather`] from the source's i16 copy.
    fn gather_source(&self, x: u32, y: u32, r: &Rect, out: &mut Vec<i16>) {
        out.clear();
        let (w, d) = (self.source.width as usize, self.source.dims);
        for row in 0..r.h as usize {
            let i = ((y + r.y) as usize + row) * w + (x + r.x) as usize;
            out.extend_from_slice(&self.source16[i * d..(i + r.w as usize) * d]);
        }
    }

    /// The projection of part `part`, computed on first use.
    fn projection_of(&self, part: usize) -> std::sync::Arc<Projection> {
        if let Some(p) = &self.parts.lock().unwrap()[part] {
            return p.clone();
        }
        let rect = part_rect(part, self.block, self.overlap);
        let n = (rect.w * rect.h) as usize * self.source.dims;
        let cands = self.candidates();
        // Principal components of a regular sample of the source's blocks (snapshot method:
        // eigenvectors of the m x m Gram matrix of the centred sample).
        // A low-discrepancy (R2, Roberts 2018) sample of origins: spread over the source
        // without the aliasing of a regular grid or of a regular step through the indices,
        // either of which can lock onto a periodic texture.
        let m = PCA_SAMPLE.min(cands);
        let origins: Vec<(u32, u32)> = (0..m)
            .map(|s| {
                let (a1, a2) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_3);
                let fx = (0.5 + a1 * s as f64).fract();
                let fy = (0.5 + a2 * s as f64).fract();
                (
                    ((fx * self.cand_w as f64) as u32).min(self.cand_w - 1),
                    ((fy * self.cand_h as f64) as u32).min(self.cand_h - 1),
                )
            })
            .collect();
        let mut x = nalgebra::DMatrix::<f64>::zeros(m, n);
        let mut buf = Vec::with_capacity(n);
        for (s, &(cx, cy)) in origins.iter().enumerate() {
            self.gather_source(cx, cy, &rect, &mut buf);
            for (j, &v) in buf.iter().enumerate() {
                x[(s, j)] = v as f64;
            }
        }
        for j in 0..n {
            let mean = x.column(j).sum() / m as f64;
            for s in 0..m {
                x[(s, j)] -= mean;
            }
        }
        let gram = &x * x.transpose();
        let eig = gram.symmetric_eigen();
        let mut order: Vec<usize> = (0..m).collect();
        order.sort_by(|&a, &b| {
            eig.eigenvalues[b]
                .total_cmp(&eig.eigenvalues[a])
                .then(a.cmp(&b))
        });
        let mut basis = vec![0i16; KERNELS * n];
        for (k, &e) in order.iter().take(KERNELS).enumerate() {
            let u = x.transpose() * eig.eigenvectors.column(e);
            let len = u.norm();
            if len == 0.0 {
                continue;
            }
            let row = &mut basis[k * n..(k + 1) * n];
            let mut scale = BASIS_SCALE;
            loop {
                for (r, &v) in row.iter_mut().zip(u.iter()) {
                    *r = (v / len * scale).round() as i16;
                }
                let l1: i64 = row.iter().map(|&v| (v as i64).abs()).sum();
                if l1 * 32767 < PROJECTION_LIMIT {
                    break;
                }
                scale *= 0.75;
            }
        }
        // Gershgorin bounds of the Gram matrices of each stage's kernels, exactly in integers.
        let mut gram_i = [[0i128; KERNELS]; KERNELS];
        for a in 0..KERNELS {
            for b in 0..KERNELS {
                gram_i[a][b] = basis[a * n..(a + 1) * n]
                    .iter()
                    .zip(&basis[b * n..(b + 1) * n])
                    .map(|(&p, &q)| p as i128 * q as i128)
                    .sum();
            }
        }
        let norm = STAGES.map(|k| {
            (0..k)
                .map(|a| (0..k).map(|b| gram_i[a][b].unsigned_abs()).sum::<u128>())
                .max()
                .unwrap_or(1)
                .max(1)
        });
        let mut proj = vec![0i32; cands * KERNELS];
        proj.par_chunks_mut(KERNELS)
            .enumerate()
            .for_each_init(Vec::new, |buf, (i, out)| {
                let (cx, cy) = self.origin(i as u32);
                self.gather_source(cx, cy, &rect, buf);
                for (k, o) in out.iter_mut().enumerate() {
                    *o = dot(&basis[k * n..(k + 1) * n], buf) as i32;
                }
            });
        let mut first = vec![0i32; STAGES[0] * cands];
        for (i, row) in proj.chunks_exact(KERNELS).enumerate() {
            for t in 0..STAGES[0] {
                first[t * cands + i] = row[t];
            }
        }
        let p = std::sync::Arc::new(Projection {
            rect,
            basis,
            norm,
            proj,
            first,
        });
        self.parts.lock().unwrap()[part] = Some(p.clone());
        p
    }

    /// Brute force: the exact distance to every candidate.
    pub fn brute(
        &self,
        out: &FeatureImage,
        qx: u32,
        qy: u32,
        shape: Shape,
        tol: Tolerance,
    ) -> Matches {
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

    /// The projection-kernel search: same result as [`Searcher::brute`] (proven in the module
    /// docs, tested on many queries). `hints` are candidates likely to match well (e.g. the
    /// continuations of the neighbouring blocks' sources): their exact distances start the best
    /// distance low, so early stages reject more. They change the cost, never the result.
    #[allow(clippy::too_many_arguments)]
    pub fn projection(
        &self,
        out: &FeatureImage,
        qx: u32,
        qy: u32,
        shape: Shape,
        tol: Tolerance,
        hints: &[u32],
        stats: &mut SearchStats,
    ) -> Matches {
        let rects = template(shape, self.block, self.overlap);
        // (The parts' first uses compute them, in parallel.)
        let projections: Vec<std::sync::Arc<Projection>> = parts(shape)
            .par_iter()
            .map(|&p| self.projection_of(p))
            .collect();
        // The query's projections, per part.
        let mut buf = Vec::new();
        let query: Vec<[i32; KERNELS]> = projections
            .iter()
            .map(|p| {
                Self::gather(out, qx, qy, &p.rect, &mut buf);
                let n = buf.len();
                std::array::from_fn(|k| dot(&p.basis[k * n..(k + 1) * n], &buf) as i32)
            })
            .collect();
        // One normalization for all parts (the largest S): floor(sum_parts |P(q - c)|^2 / S_max)
        // is still a lower bound, and comparing sum > thr * S_max needs no division.
        let norms: Vec<u128> = (0..STAGES.len())
            .map(|st| projections.iter().map(|p| p.norm[st]).max().unwrap_or(1))
            .collect();
        // Squared projection differences are accumulated per candidate (|difference| < 2^29, at
        // most 64 terms: no overflow, see PROJECTION_LIMIT).
        let n = self.candidates();
        let mut best = u64::MAX;
        for &h in hints.iter().filter(|&&h| (h as usize) < n) {
            best = best.min(self.distance(h, out, qx, qy, &rects, u64::MAX));
            stats.exact += 1;
        }
        stats.queries += 1;
        stats.candidates += n as u64;
        stats.survivors.resize(STAGES.len(), 0);
        // Stage 0 bounds every candidate.
        const CHUNK: usize = 2048;
        let mut acc0 = vec![0u64; n];
        acc0.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                let start = ci * CHUNK;
                for (p, q) in projections.iter().zip(&query) {
                    for (t, &qt) in q.iter().enumerate().take(STAGES[0]) {
                        let col = &p.first[t * n + start..][..chunk.len()];
                        for (a, &c) in chunk.iter_mut().zip(col) {
                            // |qt|, |c| < 2^29 (PROJECTION_LIMIT): the difference fits
                            // 32 bits, and a u32 x u32 -> u64 square vectorizes (pmuludq).
                            let d = (qt - c).unsigned_abs() as u64;
                            *a += d * d;
                        }
                    }
                }
            });
        let mut survivors: Vec<(u32, u64)> = Vec::new();
        let mut done = 0;
        for (stage, &k) in STAGES.iter().enumerate() {
            if stage > 0 {
                // (Work per candidate is tiny: split only in large pieces.)
                survivors
                    .par_iter_mut()
                    .with_min_len(512)
                    .for_each(|(i, acc)| {
                        let mut sum = 0u64;
                        for (p, q) in projections.iter().zip(&query) {
                            let c = &p.proj[*i as usize * KERNELS..][done..k];
                            sum += c
                                .iter()
                                .zip(&q[done..k])
                                .map(|(&c, &q)| {
                                    let d = (q - c).unsigned_abs() as u64;
                                    d * d
                                })
                                .sum::<u64>();
                        }
                        *acc += sum;
                    });
            }
            done = k;
            // Tighten the best distance so far with the most promising survivors (smallest
            // bounds, then smallest indices): their exact distances are achieved by candidates.
            let promising = if stage == 0 {
                smallest(acc0.iter().enumerate().map(|(i, &a)| (a, i as u32)))
            } else {
                smallest(survivors.iter().map(|&(i, a)| (a, i)))
            };
            for i in promising {
                best = best.min(self.distance(i, out, qx, qy, &rects, best));
                stats.exact += 1;
            }
            // Reject when floor(acc / S) > thr, i.e. acc >= (thr + 1) * S.
            let reject_at = (tol.threshold(best) as u128 + 1) * norms[stage];
            if stage == 0 {
                survivors = acc0
                    .iter()
                    .enumerate()
                    .filter(|&(_, &a)| (a as u128) < reject_at)
                    .map(|(i, &a)| (i as u32, a))
                    .collect();
            } else {
                survivors.retain(|&(_, acc)| (acc as u128) < reject_at);
            }
            stats.survivors[stage] += survivors.len() as u64;
            if survivors.len() <= 1 {
                break;
            }
        }
        let survivors: Vec<u32> = survivors.into_iter().map(|(i, _)| i).collect();
        let limit = tol.threshold(best);
        stats.exact += survivors.len() as u64;
        let exact: Vec<(u32, u64)> = survivors
            .par_iter()
            .with_min_len(32)
            .map(|&i| (i, self.distance(i, out, qx, qy, &rects, limit)))
            .collect();
        let best = exact.iter().map(|e| e.1).min().unwrap_or(best).min(best);
        let thr = tol.threshold(best);
        let within = exact.into_iter().filter(|e| e.1 <= thr).collect();
        Matches { best, within }
    }
}

/// The candidates of the TIGHTEN smallest (bound, index) pairs, in one pass.
fn smallest(items: impl Iterator<Item = (u64, u32)>) -> Vec<u32> {
    let mut top: Vec<(u64, u32)> = Vec::with_capacity(TIGHTEN + 1);
    for item in items {
        if top.len() == TIGHTEN && item >= top[TIGHTEN - 1] {
            continue;
        }
        let at = top.partition_point(|&t| t < item);
        top.insert(at, item);
        top.truncate(TIGHTEN);
    }
    top.into_iter().map(|(_, i)| i).collect()
}

/// Integer dot product of a projection kernel and a neighbourhood (|values| <= 32767). Kernels
/// are scaled so that their L1 norm times 32767 stays below PROJECTION_LIMIT (2^28): every
/// partial sum of products, in whatever order or grouping, is then below 2^28 in magnitude, so
/// one i32 accumulation is exact. The compiler turns it into 16-bit multiply-adds (one
/// horizontal reduction at the end). On x86-64 with AVX2 (detected at run time) the same code is
/// compiled for 256-bit registers; integer arithmetic, so the result is identical.
#[inline]
fn dot(a: &[i16], b: &[i16]) -> i64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { dot_avx2(a, b) };
    }
    dot_portable(a, b)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn dot_avx2(a: &[i16], b: &[i16]) -> i64 {
    dot_portable(a, b)
}

#[inline(always)]
fn dot_portable(a: &[i16], b: &[i16]) -> i64 {
    a.iter()
        .zip(b)
        .map(|(&p, &x)| p as i32 * x as i32)
        .sum::<i32>() as i64
}
