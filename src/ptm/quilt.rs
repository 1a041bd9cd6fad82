//! Block-based synthesis over reflectance functions (the paper's sections IV and VI): image
//! quilting (Efros-Freeman) where pixels are PTM texels and neighbourhoods are compared in the
//! orthonormal Legendre coefficients, so distances are distances between reflectance functions.
//!
//! Blocks of `block` x `block` pixels are placed (as if) in raster order with `overlap` pixels shared with
//! the left and top neighbours. Each block is drawn at random (seeded per block) among the source
//! blocks whose overlap distance is within the tolerance of the best ([`search`]); the seam is a
//! minimum-error cut through the overlap (errors in the orthonormal basis) or an alpha blend.
//! With cuts every output texel is a source texel, byte for byte. The result is a pure function
//! of (source, parameters, seed): the search is exact and integer, choices are seeded per block,
//! so any thread count gives byte-identical output.

use super::search::{self, FeatureImage, Matches, SearchStats, Searcher, Shape, Tolerance};
use super::Ptm;
use crate::error::{Error, Result};
use crate::util::hash::{mix64, SeededRng};
use crate::util::memory;
use rayon::prelude::*;

/// The smallest block side: a block's overlap strips (at least one texel on each side) must
/// leave texels of its own.
pub const MIN_BLOCK: u32 = 4;

/// How a block joins its neighbours in the overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Boundary {
    /// Minimum-error boundary cut (dynamic programming through the overlap).
    Cut,
    /// Linear alpha blend across the overlap (the paper's choice; blending coefficients blends
    /// the reflectance functions with the same weights).
    Blend,
}

/// Which search finds the candidate blocks (same result, different cost).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SearchMethod {
    /// The exact projection-kernel rejection scheme.
    ExactProjection,
    /// Every candidate's full distance.
    Brute,
}

/// Synthesis parameters; [`QuiltParams::validate`] checks them against the source, naming flags.
#[derive(Clone, Debug)]
pub struct QuiltParams {
    pub width: u32,
    pub height: u32,
    pub block: u32,
    pub overlap: u32,
    pub seed: u64,
    pub tolerance: Tolerance,
    pub boundary: Boundary,
    pub search: SearchMethod,
}

impl QuiltParams {
    /// Output `size` x `size`, blocks of 32 with overlap 6, tolerance 10% (Efros-Freeman's),
    /// minimum-error cuts, the projection search.
    pub fn new(size: u32) -> Self {
        QuiltParams {
            width: size,
            height: size,
            block: 32,
            overlap: 6,
            seed: 0,
            tolerance: Tolerance { permille: 100 },
            boundary: Boundary::Cut,
            search: SearchMethod::ExactProjection,
        }
    }

    pub fn validate(&self, src: &Ptm) -> Result<()> {
        // The output's texels and features are held in memory (4096^2 RGB: ~1.5 GB).
        if !(8..=4096).contains(&self.width) || !(8..=4096).contains(&self.height) {
            return Err(Error::invalid(
                format!("--size {}x{}", self.width, self.height),
                "must be 8..=4096",
            ));
        }
        check_source(src, "the source PTM")?;
        if self.block < MIN_BLOCK || self.block > src.width.min(src.height) {
            return Err(Error::invalid(
                format!("--block {}", self.block),
                format!(
                    "must be {MIN_BLOCK}..={} (the source is {}x{})",
                    src.width.min(src.height),
                    src.width,
                    src.height
                ),
            ));
        }
        if self.overlap == 0 || u64::from(self.overlap) * 2 > u64::from(self.block) {
            return Err(Error::invalid(
                format!("--overlap {}", self.overlap),
                format!("must be 1..={} (at most half of --block)", self.block / 2),
            ));
        }
        if self.tolerance.permille > 10_000 {
            return Err(Error::invalid(
                "--tolerance",
                "must be 0..=10 (a fraction of the best distance)",
            ));
        }
        Ok(())
    }

    /// Refuse a synthesis whose [`memory_bytes`](Self::memory_bytes) exceed the memory
    /// available (the machine's, its cgroup's, `ulimit -v`'s or `SOLIDSYNTH_MEMORY_BUDGET_MIB`),
    /// before anything is allocated.
    pub fn check_memory(&self, src: &Ptm) -> Result<()> {
        let (estimate, available) = (self.memory_bytes(src), memory::available_memory());
        if estimate > available {
            return Err(Error::invalid(
                format!("--size {}x{}", self.width, self.height),
                format!(
                    "needs about {} of memory, {}",
                    memory::human_bytes(estimate),
                    memory::available_text(available)
                ),
            ));
        }
        Ok(())
    }

    /// Blocks per row and column, and the canvas they cover (the output and the last blocks'
    /// overhang).
    fn canvas(&self) -> ((u32, u32), (u32, u32)) {
        let (b, ov) = (self.block, self.overlap);
        let step = b - ov;
        let nbx = (self.width.saturating_sub(ov)).div_ceil(step).max(1);
        let nby = (self.height.saturating_sub(ov)).div_ceil(step).max(1);
        ((nbx, nby), (nbx * step + ov, nby * step + ov))
    }

    /// The bytes a synthesis from `src` holds at most, about: the source's features (as i32
    /// and i16) and the three overlap parts' projections of every candidate block, the canvas's
    /// texels and features, and the output with its encoded file. For a 64^2 LRGB source with
    /// 16-texel blocks it is 10-20% above the peaks measured on the 2-core Xeon development
    /// machine at 1024^2 to 4096^2 (684 MiB at 4096^2).
    pub fn memory_bytes(&self, src: &Ptm) -> u64 {
        let dims = search::feature_dims(src) as u64;
        let texel = src.format.texel_bytes() as u64;
        let source = src.width as u64 * src.height as u64 * dims * (4 + 2);
        let candidates = (src.width.saturating_sub(self.block) + 1) as u64
            * (src.height.saturating_sub(self.block) + 1) as u64;
        let projections = 3 * candidates * (search::KERNELS + search::STAGES[0]) as u64 * 4;
        let (_, (cw, ch)) = self.canvas();
        let canvas = cw as u64 * ch as u64 * (texel + dims * 4);
        let output = 2 * self.width as u64 * self.height as u64 * texel;
        source + projections + canvas + output
    }
}

/// What a synthesis did.
#[derive(Clone, Debug, Default)]
pub struct QuiltReport {
    /// Blocks per row and column.
    pub blocks: (u32, u32),
    /// Source candidate (block origin index) chosen per block, raster order.
    pub choices: Vec<u32>,
    /// Candidates within the tolerance per block (the random choice was among them).
    pub within: Vec<u32>,
    /// Projection search counters (empty for brute force).
    pub stats: SearchStats,
}

/// Refuse a source too small to copy blocks from; `name` names it in the message.
pub fn check_source(src: &Ptm, name: &str) -> Result<()> {
    src.check(name)?;
    if src.width.min(src.height) < MIN_BLOCK {
        return Err(Error::invalid(
            name,
            format!(
                "is a {}x{} PTM; synthesis copies blocks of at least {MIN_BLOCK}x{MIN_BLOCK} \
                 texels from it",
                src.width, src.height
            ),
        ));
    }
    Ok(())
}

/// Synthesize a PTM with the source's format, scale and bias. `progress(done, total)` is called
/// after each block.
pub fn synthesize(
    src: &Ptm,
    p: &QuiltParams,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Ptm, QuiltReport)> {
    p.validate(src)?;
    p.check_memory(src)?;
    let searcher = Searcher::new(search::features(src), p.block, p.overlap);
    synthesize_with(src, &searcher, p, progress)
}

/// [`synthesize`] with a prepared searcher (benchmarks reuse its precomputed projections).
pub fn synthesize_with(
    src: &Ptm,
    searcher: &Searcher,
    p: &QuiltParams,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Ptm, QuiltReport)> {
    p.validate(src)?;
    let ((nbx, nby), (cw, ch)) = p.canvas();
    let step = p.block - p.overlap;
    let s = src.format.texel_bytes();
    let dims = searcher.source.dims;
    let mut texels = vec![0u8; cw as usize * ch as usize * s];
    let mut feats = FeatureImage::new(cw, ch, dims);
    let mut report = QuiltReport {
        blocks: (nbx, nby),
        ..Default::default()
    };
    let total = (nbx * nby) as usize;
    report.choices = vec![0; total];
    report.within = vec![0; total];
    // Wavefront order: block (bx, by) reads the overlaps of its left, top and top-right
    // neighbours, all on earlier waves of t = bx + 2 by, and two blocks of one wave neither
    // overlap nor read each other's pixels (they are 2 steps apart in x, and 2 * overlap <=
    // block). So a wave's searches run in parallel on the same canvas, then its blocks are
    // placed. Choices are seeded per block and the search is exact, so the result is the same
    // as in raster order, at any thread count.
    let mut done = 0;
    for wave in 0..nbx + 2 * nby {
        let blocks: Vec<(u32, u32)> = (0..nby)
            .filter_map(|by| wave.checked_sub(2 * by).map(|bx| (bx, by)))
            .filter(|&(bx, _)| bx < nbx)
            .collect();
        let chosen: Vec<(u32, u32, SearchStats)> = blocks
            .par_iter()
            .map(|&(bx, by)| choose(searcher, &feats, &report.choices, (bx, by), nbx, p))
            .collect();
        for (&(bx, by), (choice, within, stats)) in blocks.iter().zip(chosen) {
            let index = (by * nbx + bx) as usize;
            report.choices[index] = choice;
            report.within[index] = within;
            report.stats.add(&stats);
            place(
                src,
                searcher,
                &mut texels,
                &mut feats,
                (bx * step, by * step),
                searcher.origin(choice),
                shape_of(bx, by),
                p,
            );
            done += 1;
            progress(done, total);
        }
    }
    // Crop the canvas to the requested size.
    let mut out = Vec::with_capacity(p.width as usize * p.height as usize * s);
    for y in 0..p.height as usize {
        let row = y * cw as usize * s;
        out.extend_from_slice(&texels[row..row + p.width as usize * s]);
    }
    Ok((
        Ptm {
            format: src.format,
            width: p.width,
            height: p.height,
            scale: src.scale,
            bias: src.bias,
            texels: out,
        },
        report,
    ))
}

/// Which neighbours block (bx, by) overlaps; `None` for the first block.
fn shape_of(bx: u32, by: u32) -> Option<Shape> {
    match (bx, by) {
        (0, 0) => None,
        (_, 0) => Some(Shape::Left),
        (0, _) => Some(Shape::Top),
        _ => Some(Shape::Both),
    }
}

/// The source block for output block (bx, by), drawn (seeded per block) among the candidates
/// within the tolerance of the best: (choice, how many were within, search counters).
/// `choices` must hold the choices of the blocks on earlier waves.
fn choose(
    searcher: &Searcher,
    feats: &FeatureImage,
    choices: &[u32],
    (bx, by): (u32, u32),
    nbx: u32,
    p: &QuiltParams,
) -> (u32, u32, SearchStats) {
    let step = p.block - p.overlap;
    let (ox, oy) = (bx * step, by * step);
    let index = (by * nbx + bx) as usize;
    let mut rng = SeededRng::new(mix64(
        p.seed ^ mix64((index as u64).wrapping_add(0x5054_4d51)),
    ));
    let mut stats = SearchStats::default();
    let Some(shape) = shape_of(bx, by) else {
        let n = searcher.candidates() as u32;
        return (rng.below(n as u64) as u32, n, stats);
    };
    let m: Matches = match p.search {
        SearchMethod::Brute => searcher.brute(feats, ox, oy, shape, p.tolerance),
        SearchMethod::ExactProjection => {
            // The sources continuing the left and top neighbours: usually good matches, so a
            // low starting threshold.
            let continuation = |b: usize, dx: u32, dy: u32| {
                let (sx, sy) = searcher.origin(choices[b]);
                (sx + dx < searcher.cand_w && sy + dy < searcher.cand_h)
                    .then(|| (sy + dy) * searcher.cand_w + sx + dx)
            };
            let mut hints = Vec::new();
            if bx > 0 {
                hints.extend(continuation(index - 1, step, 0));
            }
            if by > 0 {
                hints.extend(continuation(index - nbx as usize, 0, step));
            }
            searcher.projection(feats, ox, oy, shape, p.tolerance, &hints, &mut stats)
        }
    };
    let choice = m.within[rng.below(m.within.len() as u64) as usize].0;
    (choice, m.within.len() as u32, stats)
}

/// Copy source block (sx, sy) to output (ox, oy), joining it to what is there in the overlaps.
#[allow(clippy::too_many_arguments)]
fn place(
    src: &Ptm,
    searcher: &Searcher,
    texels: &mut [u8],
    feats: &mut FeatureImage,
    (ox, oy): (u32, u32),
    (sx, sy): (u32, u32),
    shape: Option<Shape>,
    p: &QuiltParams,
) {
    let (b, ov) = (p.block, p.overlap);
    let s = src.format.texel_bytes();
    let cw = feats.width as usize;
    let has_left = matches!(shape, Some(Shape::Left | Shape::Both));
    let has_top = matches!(shape, Some(Shape::Top | Shape::Both));
    let error = |x: u32, y: u32| -> u64 {
        search::squared_difference(
            feats.run(ox + x, oy + y, 1),
            searcher.source.run(sx + x, sy + y, 1),
        )
    };
    // Per pixel of the block: the new texel's weight out of 256.
    let mut weight = vec![256u32; (b * b) as usize];
    match p.boundary {
        Boundary::Cut => {
            if has_left {
                let cut = min_cut(b, ov, |along, across| error(across, along));
                for y in 0..b {
                    for x in 0..cut[y as usize] {
                        weight[(y * b + x) as usize] = 0;
                    }
                }
            }
            if has_top {
                let cut = min_cut(b, ov, error);
                for x in 0..b {
                    for y in 0..cut[x as usize] {
                        weight[(y * b + x) as usize] = 0;
                    }
                }
            }
        }
        Boundary::Blend => {
            let ramp = |t: u32| {
                if t < ov {
                    256 * (t + 1) / (ov + 1)
                } else {
                    256
                }
            };
            for y in 0..b {
                for x in 0..b {
                    let wx = if has_left { ramp(x) } else { 256 };
                    let wy = if has_top { ramp(y) } else { 256 };
                    weight[(y * b + x) as usize] = wx * wy / 256;
                }
            }
        }
    }
    for y in 0..b {
        for x in 0..b {
            let w = weight[(y * b + x) as usize];
            if w == 0 {
                continue;
            }
            let (tx, ty) = ((ox + x) as usize, (oy + y) as usize);
            let dst = &mut texels[(ty * cw + tx) * s..][..s];
            let new = src.texel(sx + x, sy + y);
            if w == 256 {
                dst.copy_from_slice(new);
                feats
                    .pixel_mut(ox + x, oy + y)
                    .copy_from_slice(searcher.source.run(sx + x, sy + y, 1));
            } else {
                // Integer blend of the quantized coefficients: all texels share one scale and
                // bias, so this blends the coefficients (and the functions) linearly.
                for (d, &n) in dst.iter_mut().zip(new) {
                    *d = ((*d as u32 * (256 - w) + n as u32 * w + 128) >> 8) as u8;
                }
                let blended = dst.to_vec();
                search::texel_features(src, &blended, feats.pixel_mut(ox + x, oy + y));
            }
        }
    }
}

/// Minimum-error path through a `len` x `width` overlap strip (one position across the strip
/// per step along it, moving at most one across per step): for each step, the first position
/// across that takes the new block. `err(along, across)`. Integer costs; ties go to the smaller
/// position, so the cut is deterministic.
fn min_cut(len: u32, width: u32, err: impl Fn(u32, u32) -> u64) -> Vec<u32> {
    let (n, w) = (len as usize, width as usize);
    let mut cost = vec![0u64; n * w];
    for a in 0..n {
        for c in 0..w {
            let e = err(a as u32, c as u32);
            cost[a * w + c] = if a == 0 {
                e
            } else {
                let lo = c.saturating_sub(1);
                let hi = (c + 1).min(w - 1);
                e + (lo..=hi).map(|k| cost[(a - 1) * w + k]).min().unwrap()
            };
        }
    }
    let mut path = vec![0u32; n];
    let argmin =
        |a: usize, lo: usize, hi: usize| (lo..=hi).min_by_key(|&k| (cost[a * w + k], k)).unwrap();
    let mut c = argmin(n - 1, 0, w - 1);
    for a in (0..n).rev() {
        if a + 1 < n {
            c = argmin(a, c.saturating_sub(1), (c + 1).min(w - 1));
        }
        path[a] = c as u32;
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ptm::{capture, fit, PtmFormat};

    /// The wavefront gives what placing the blocks one by one in raster order gives: same
    /// choices, same texels (also with the largest overlap, half a block, where blocks of one
    /// wave touch). A wave of t = bx + by instead fails it.
    #[test]
    fn wavefront_equals_raster_order() {
        let src = fit::fit(&capture::synthetic(48, 8, 1), PtmFormat::Lrgb, "test").unwrap();
        for (block, overlap) in [(16, 4), (16, 8)] {
            let mut p = QuiltParams::new(100);
            p.block = block;
            p.overlap = overlap;
            p.seed = 7;
            let searcher = Searcher::new(search::features(&src), p.block, p.overlap);
            let (out, report) = synthesize_with(&src, &searcher, &p, &mut |_, _| {}).unwrap();

            let step = block - overlap;
            let (nbx, nby) = report.blocks;
            let cw = nbx * step + overlap;
            let s = src.format.texel_bytes();
            let mut texels = vec![0u8; (cw * (nby * step + overlap)) as usize * s];
            let mut feats = FeatureImage::new(cw, nby * step + overlap, searcher.source.dims);
            let mut choices = vec![0u32; (nbx * nby) as usize];
            for by in 0..nby {
                for bx in 0..nbx {
                    let (choice, _, _) = choose(&searcher, &feats, &choices, (bx, by), nbx, &p);
                    choices[(by * nbx + bx) as usize] = choice;
                    place(
                        &src,
                        &searcher,
                        &mut texels,
                        &mut feats,
                        (bx * step, by * step),
                        searcher.origin(choice),
                        shape_of(bx, by),
                        &p,
                    );
                }
            }
            assert_eq!(report.choices, choices, "block {block}, overlap {overlap}");
            for y in 0..p.height as usize {
                let row = &texels[y * cw as usize * s..][..p.width as usize * s];
                let got = &out.texels[y * p.width as usize * s..][..p.width as usize * s];
                assert!(
                    row == got,
                    "row {y} differs (block {block}, overlap {overlap})"
                );
            }
        }
    }
}
