//! The exemplar patches of one synthesis level (paper 4.2.1, 4.2.3): N x N samples at pixel
//! spacing s ("fractional sampling": coarser levels double the spacing instead of shrinking the
//! grid), their PCA projections for the nearest-patch search, and what the bucket step reads back: the sample
//! values and, at the finest level, their colour clusters.

use super::folded::FoldedProjection;
use super::ivf::IvfIndex;
use super::pca::{PatchPca, KEPT, MAX_SAMPLES};
use crate::backend::buckets::PackedSums;
use crate::error::{Error, Result};
use crate::exemplar::Image;
use rayon::prelude::*;

/// At most this many candidate patches per level (a larger exemplar is sampled on a stride):
/// bounds the projection and tree cost.
const MAX_CANDIDATES: usize = 16384;
/// Lines are stored zero-padded to a multiple of this many bytes ([`LevelPatches::line_distance`]).
const LINE_CHUNK: usize = 16;

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
    /// Every candidate's PCA projection (for scoring a few chosen candidates).
    points: Vec<[f32; KEPT]>,
    /// The projections' inverted-file index (the nearest-patch search).
    index: Option<IvfIndex>,
    /// Centre column and row of every candidate ([`Self::gather_lines`]).
    lines: Vec<u8>,
}

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
            points: Vec::new(),
            index: None,
            lines: Vec::new(),
        };
        level.lines = level.gather_lines();
        level.packed_samples = level.pack_samples();
        let dims = level.dims();
        // The PCA is fitted to (at most) MAX_SAMPLES evenly strided candidates: gather only
        // those (`fit` strides the same way, so passing it every vector gave the same basis).
        let count = level.centres.len();
        let stride = count.div_ceil(MAX_SAMPLES).max(1);
        let sampled: Vec<f32> = (0..count as u32)
            .step_by(stride)
            .flat_map(|i| level.vector(i))
            .collect();
        let pca = PatchPca::fit(&sampled, dims, seed);
        let points = pca.project_each(count, |i, buffer| level.write_vector(i as u32, buffer));
        level.index = Some(IvfIndex::build(&points));
        level.points = points;
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

    /// The PCA projection of candidate `i`.
    #[inline(always)]
    pub fn point(&self, i: u32) -> &[f32; KEPT] {
        &self.points[i as usize]
    }

    /// The `k` candidates nearest to a projected query, nearest first (ties by index):
    /// [`IvfIndex::nearest`] over the candidates' projections.
    pub fn nearest(&self, query: &[f32; KEPT], k: usize, probes: Option<usize>) -> Vec<(f32, u32)> {
        self.index
            .as_ref()
            .expect("built")
            .nearest(query, k, probes)
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
        self.write_vector(i, &mut v);
        v
    }

    /// [`Self::vector`], appended to `v`.
    pub fn write_vector(&self, i: u32, v: &mut Vec<f32>) {
        for b in 0..self.size {
            for a in 0..self.size {
                v.extend(
                    self.value(self.pixel_index(i, a, b))
                        .iter()
                        .map(|&x| x as f32),
                );
            }
        }
    }

    /// Sum of squared differences between `line_a` of candidate `a` and `line_b` of `b`
    /// (the crossbar consistency of paper 4.2.1).
    /// Inlined, over 16-byte chunks of zero-padded lines: in the AVX2-compiled matching it
    /// becomes a few vector instructions per chunk (as an iterator chain it was compiled
    /// apart, without AVX2, and cost a quarter of the synthesis).
    #[inline(always)]
    pub fn line_distance(&self, a: u32, line_a: Line, b: u32, line_b: Line) -> u32 {
        let (pa, pb) = (self.padded_line(a, line_a), self.padded_line(b, line_b));
        let mut sum = 0i32;
        for (ca, cb) in pa.chunks_exact(LINE_CHUNK).zip(pb.chunks_exact(LINE_CHUNK)) {
            for l in 0..LINE_CHUNK {
                let d = ca[l] as i16 - cb[l] as i16;
                sum += d as i32 * d as i32;
            }
        }
        sum as u32
    }

    /// Values of a line: N * channels.
    #[inline(always)]
    pub fn line_len(&self) -> usize {
        self.size as usize * self.channels
    }

    /// Bytes a line takes in [`Self::lines`]: its values, zero-padded to whole chunks.
    #[inline(always)]
    fn line_stride(&self) -> usize {
        self.line_len().next_multiple_of(LINE_CHUNK)
    }

    /// The values of `line` of candidate `i`, sample after sample (N * channels bytes).
    #[inline(always)]
    pub fn line(&self, i: u32, line: Line) -> &[u8] {
        &self.padded_line(i, line)[..self.line_len()]
    }

    /// [`Self::line`] with its zero padding.
    #[inline(always)]
    fn padded_line(&self, i: u32, line: Line) -> &[u8] {
        let stride = self.line_stride();
        let start = (2 * i as usize + matches!(line, Line::Row) as usize) * stride;
        &self.lines[start..start + stride]
    }

    /// Every candidate's centre column then centre row, contiguous (what [`Self::line`] reads):
    /// the crossbar tests compare ~120 lines per check point, which gathered pixel by pixel
    /// from the exemplar cost more than the comparisons.
    fn gather_lines(&self) -> Vec<u8> {
        let h = self.size / 2;
        let padding = self.line_stride() - self.line_len();
        let mut lines = Vec::with_capacity(self.centres.len() * 2 * self.line_stride());
        for i in 0..self.centres.len() as u32 {
            for t in 0..self.size {
                lines.extend_from_slice(self.value(self.pixel_index(i, h, t)));
            }
            lines.extend(std::iter::repeat_n(0, padding));
            for t in 0..self.size {
                lines.extend_from_slice(self.value(self.pixel_index(i, t, h)));
            }
            lines.extend(std::iter::repeat_n(0, padding));
        }
        lines
    }
}
