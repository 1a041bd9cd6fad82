//! Representation update (paper 4.2.2): the matched patches' samples are scattered into
//! per-voxel buckets and each control point is refitted to the buckets nearest to it (eq. 2).
//!
//! Bucket reuse: buckets exist for one tile at a time (the voxels whose nearest control points
//! are in layers K0..K1, rows R0..R1 and columns C0..C1: z in [4 K0 - 2, 4 K1 - 2), y in
//! [4 R0 - 2, 4 R1 - 2), x in [4 C0 - 2, 4 C1 - 2)): a cube of about 5^3 control points, whose
//! buckets fit a core's L2 cache (O(1) memory per tile instead of O(P^3)). Only check points
//! whose slices can reach the tile are visited. Tiles are independent (they read the previous
//! solid and the matches) and run in parallel.
//!
//! Accumulation is kernel `bucket_accumulate` (wgsl/bucket_accumulate.wgsl): pass 1 counts the
//! samples of every (voxel, colour cluster), pass 2 sums, in 8.8 fixed point, the samples of each
//! voxel's two dominant clusters. On the CPU backend the samples are streamed straight into
//! per-(voxel, cluster) counts and sums (packed 16-bit lanes, `PackedSums`, or with four
//! channels plain ones), from which each voxel keeps its two dominant clusters': the same
//! integers as the kernel's CPU reference, without the kernel's sample list. On the GPU
//! the tiles' samples are listed in parallel and a batch of tiles dispatched at once.

use super::matching::{Match, MatchContext};
use super::refine::Targets;
use super::{wrap, PeriodicSolid};
use crate::backend::buckets::{dominant, Buckets, PackedSums};
use crate::backend::Compute;
use crate::error::Result;
use crate::gradient::SPACING;
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

mod samples;

/// Voxels of a control layer's buckets along z (one control spacing).
const LAYER: i64 = SPACING as i64;
// A control point's buckets (LAYER x SPACING^2) are the bits of a u64 in `Tile::fit`.
const _: () = assert!(LAYER * SPACING as i64 * SPACING as i64 == 64);
/// Ridge on the gradient unknowns of eq. 2 (in bucket-count x voxel^2 units; a full
/// neighbourhood has ~100 on the diagonal): keeps under-determined directions (all buckets
/// coplanar) at zero gradient instead of singular.
const RIDGE: f64 = 0.5;

/// Voxels per tile the CPU backend aims at: its per-cluster counts and sums (96 bytes a voxel
/// packed, with 12 clusters; 240 unpacked with 4 channels) then stay in a core's L2 cache.
const TILE_VOXELS: i64 = 8 << 10;

/// One tile's view of the samples: the buckets of control layers `layers` (voxels z in
/// [4 layers.start - 2, 4 layers.end - 2)), control rows `rows` (likewise along y) and control
/// columns `cols` (along x): exactly the buckets the tile's control points are fitted to.
struct Tile<'a> {
    solid: &'a PeriodicSolid,
    matches: &'a [Match],
    /// Every check point's voxel, in the order of `matches` ([`super::matching::check_points`]).
    points: &'a [[u16; 3]],
    ctx: &'a MatchContext<'a>,
    /// Control layers (z) of the tile.
    layers: std::ops::Range<u32>,
    /// Control rows (y) and columns (x) of the tile.
    rows: std::ops::Range<u32>,
    cols: std::ops::Range<u32>,
    /// The level's cluster count (clusters 0..clusters; 1: plain averaging).
    clusters: usize,
}

impl Tile<'_> {
    fn period(&self) -> i64 {
        self.solid.period()
    }
    /// First voxel z of the tile's buckets.
    fn z0(&self) -> i64 {
        self.layers.start as i64 * LAYER - LAYER / 2
    }
    /// Voxels of the tile's buckets along z.
    fn depth(&self) -> i64 {
        self.layers.len() as i64 * LAYER
    }
    /// First voxel y of the tile's buckets, and their rows.
    fn y0(&self) -> i64 {
        self.rows.start as i64 * SPACING as i64 - SPACING as i64 / 2
    }
    fn height(&self) -> i64 {
        self.rows.len() as i64 * SPACING as i64
    }
    /// First voxel x of the tile's buckets, and their columns.
    fn x0(&self) -> i64 {
        self.cols.start as i64 * SPACING as i64 - SPACING as i64 / 2
    }
    fn width(&self) -> i64 {
        self.cols.len() as i64 * SPACING as i64
    }
    fn voxels(&self) -> usize {
        (self.width() * self.height() * self.depth()) as usize
    }
    /// Per axis: the tile's band of voxels (first, length) and the bucket index stride of one
    /// voxel.
    fn band(&self, axis: usize) -> (i64, i64, usize) {
        match axis {
            2 => (
                self.z0(),
                self.depth(),
                (self.height() * self.width()) as usize,
            ),
            1 => (self.y0(), self.height(), self.width() as usize),
            _ => (self.x0(), self.width(), 1),
        }
    }

    /// The bucket of voxel `q` (which must lie in the tile).
    #[inline(always)]
    fn bucket(&self, q: [i64; 3]) -> usize {
        let p_len = self.period();
        ((wrap(q[2] - self.z0(), p_len) * self.height() + wrap(q[1] - self.y0(), p_len))
            * self.width()
            + wrap(q[0] - self.x0(), p_len)) as usize
    }

    /// Both passes of the bucket accumulation in one (CPU backend): every sample adds to its
    /// (voxel, cluster) count and channel sums, then each voxel keeps the sums of its two
    /// dominant clusters. The same integers as the kernel's two passes (a dominant cluster's
    /// sums are the sums of its samples), without listing or generating the samples twice;
    /// the tile's per-cluster sums stay in the core's L2 cache.
    fn accumulate_streaming(&self) -> Buckets {
        let patches = self.ctx.patches;
        let clusters = self.clusters;
        let channels = self.solid.channels;
        let voxels = self.voxels();
        let per = 1 + channels;
        // Per voxel and cluster: count, then the channel sums in 8.8 fixed point.
        let mut acc = vec![0u32; voxels * clusters * per];
        let mut sample = |v: usize, px: usize| {
            let base = (v * clusters + patches.cluster(px) as usize) * per;
            let slot = &mut acc[base..base + per];
            slot[0] += 1;
            for (sum, &value) in slot[1..].iter_mut().zip(patches.value(px)) {
                *sum += (value as u32) << 8;
            }
        };
        self.for_each_sample(&mut sample);
        let counts: Vec<u32> = acc.iter().step_by(per).copied().collect();
        let mut sums = vec![0u32; voxels * 2 * per];
        for (v, out) in sums.chunks_exact_mut(2 * per).enumerate() {
            let ids = dominant(&counts[v * clusters..(v + 1) * clusters]);
            for (slot, &id) in ids.iter().enumerate() {
                if id != u32::MAX {
                    let from = (v * clusters + id as usize) * per;
                    out[slot * per..(slot + 1) * per].copy_from_slice(&acc[from..from + per]);
                }
            }
        }
        Buckets { counts, sums }
    }

    /// The tile's samples as the kernel's list: bucket, cluster, channel values.
    fn sample_list(&self) -> Vec<u32> {
        let patches = self.ctx.patches;
        let mut list = Vec::new();
        self.for_each_sample(|v, px| {
            list.push(v as u32);
            list.push(patches.cluster(px));
            list.extend(patches.value(px).iter().map(|&x| x as u32));
        });
        list
    }

    /// [`Self::accumulate_streaming`] in [`PackedSums`] (`packed`: per pixel, its cluster and
    /// its sample packed alike): one addition per sample, and half the memory, so the tile's
    /// sums sit well inside the L2 cache. The same integers.
    fn accumulate_packed(&self, packed: &[(u32, u64)]) -> Buckets {
        let mut sums = PackedSums::new(self.voxels(), self.clusters);
        self.for_each_sample(|v, px| sums.add(v, packed[px]));
        sums.finish(
            self.solid.channels,
            self.ctx.patches.cluster_regions().is_some(),
        )
    }

    fn accumulate_on_cpu(&self) -> Buckets {
        match self.ctx.patches.packed_samples() {
            Some(packed) => self.accumulate_packed(packed),
            None => self.accumulate_streaming(),
        }
    }

    /// The average of every bucket of the tile (per voxel, per channel; NaN when empty), in
    /// the tile's bucket order. With a mask (region-pure clusters), only the samples of
    /// one region are averaged: that of the dominant slot holding more samples (ties: the first
    /// slot's), so a voxel's colour and distance come from one side of the boundary (the
    /// samples of the final region separation, paper 4.3).
    fn bucket_values(&self, buckets: &Buckets) -> Vec<f32> {
        let c = self.solid.channels;
        let per = 1 + c;
        let patches = self.ctx.patches;
        let regions = patches.cluster_regions();
        let clusters = self.clusters;
        (0..self.voxels())
            .flat_map(|v| {
                let slots = [v * 2 * per, (v * 2 + 1) * per];
                let mut use_slot = [true, true];
                if let Some(regions) = regions {
                    let ids = dominant(&buckets.counts[v * clusters..(v + 1) * clusters]);
                    let region = |k: usize| regions.get(ids[k] as usize).copied();
                    let n = |k: usize| buckets.sums[slots[k]];
                    if let (Some(r0), Some(r1)) = (region(0), region(1)) {
                        if r0 != r1 {
                            let keep = if n(1) > n(0) { 1 } else { 0 };
                            use_slot = [keep == 0, keep == 1];
                        }
                    }
                }
                let count: u32 = (0..2)
                    .filter(|&k| use_slot[k])
                    .map(|k| buckets.sums[slots[k]])
                    .sum();
                (0..c).map(move |ch| {
                    if count == 0 {
                        f32::NAN
                    } else {
                        let sum: u32 = (0..2)
                            .filter(|&k| use_slot[k])
                            .map(|k| buckets.sums[slots[k] + 1 + ch])
                            .sum();
                        sum as f32 / (256.0 * count as f32)
                    }
                })
            })
            .collect()
    }

    /// Eq. 2 for every control point of the tile: f + grad f . (x - p) ~ bucket value, over
    /// the non-empty buckets whose nearest point it is. Points without samples keep their
    /// values. Returns the tile's new values (row after row) and how many points were refitted.
    fn fit(&self, buckets: &Buckets) -> (Vec<f32>, usize) {
        let solid = self.solid;
        let c = solid.channels;
        let per = 1 + c;
        let d = SPACING as i64;
        let (height, width) = (self.height(), self.width());
        let mut out =
            Vec::with_capacity(self.layers.len() * self.rows.len() * self.cols.len() * c * 4);
        let mut refitted = 0;
        // The normal matrix of eq. 2 over the buckets that hold samples (row (1, dx, dy, dz)
        // per bucket; its sums are small integers, exact in any order), ridged and inverted.
        let offsets: Vec<Vector4<f64>> = (-LAYER / 2..LAYER / 2)
            .flat_map(|dz| {
                (-d / 2..d / 2).flat_map(move |dy| {
                    (-d / 2..d / 2)
                        .map(move |dx| Vector4::new(1.0, dx as f64, dy as f64, dz as f64))
                })
            })
            .collect();
        let inverse = |filled: u64| {
            let mut ata = Matrix4::<f64>::zeros();
            for (k, row) in offsets.iter().enumerate() {
                if filled >> k & 1 == 1 {
                    ata += row * row.transpose();
                }
            }
            for i in 1..4 {
                ata[(i, i)] += RIDGE;
            }
            ata.try_inverse().unwrap_or_else(Matrix4::zeros)
        };
        // Usually (at the finer levels nearly always) every bucket holds samples: that
        // matrix is inverted once.
        const ALL: u64 = u64::MAX;
        let full_inverse = inverse(ALL);
        let mut atb = vec![Vector4::<f64>::zeros(); c];
        for z in self.layers.clone().map(i64::from) {
            for y in self.rows.clone().map(i64::from) {
                for x in self.cols.clone().map(i64::from) {
                    let old = solid.offset([x, y, z]);
                    atb.iter_mut().for_each(|b| *b = Vector4::zeros());
                    let mut filled = 0u64;
                    let mut k = 0;
                    for dz in -LAYER / 2..LAYER / 2 {
                        for dy in -d / 2..d / 2 {
                            for dx in -d / 2..d / 2 {
                                let bz = z * LAYER + dz - self.z0();
                                let by = y * d + dy - self.y0();
                                debug_assert!((0..height).contains(&by));
                                let bx = x * d + dx - self.x0();
                                debug_assert!((0..width).contains(&bx));
                                let v = ((bz * height + by) * width + bx) as usize;
                                let (s0, s1) = (v * 2 * per, (v * 2 + 1) * per);
                                let count = buckets.sums[s0] + buckets.sums[s1];
                                k += 1;
                                if count == 0 {
                                    continue;
                                }
                                filled |= 1 << (k - 1);
                                let row = &offsets[k - 1];
                                for (ch, b) in atb.iter_mut().enumerate() {
                                    let sum = (buckets.sums[s0 + 1 + ch]
                                        + buckets.sums[s1 + 1 + ch])
                                        as f64;
                                    *b += row * (sum / (256.0 * count as f64));
                                }
                            }
                        }
                    }
                    if filled == 0 {
                        out.extend_from_slice(&solid.data[old..old + c * 4]);
                        continue;
                    }
                    refitted += 1;
                    let inv = if filled == ALL {
                        full_inverse
                    } else {
                        inverse(filled)
                    };
                    for b in &atb {
                        let sol = inv * b;
                        out.extend(sol.iter().map(|&v| v as f32));
                    }
                }
            }
        }
        (out, refitted)
    }
}

/// The bands of control layers, rows or columns of the CPU backend's tiles: about
/// cbrt([`TILE_VOXELS`] / 64) points each, so that a tile holds about [`TILE_VOXELS`] buckets.
/// Cubic tiles keep the check points visited per tile (those whose slices reach it: the tile
/// grown by a slice's reach on each side) fewest for their buckets; one-layer tiles visited
/// 1.7-2.5x more, and that visiting had cost as much as the samples' sums.
fn tile_bands(m: u32) -> Vec<std::ops::Range<u32>> {
    let side = ((TILE_VOXELS / (LAYER * SPACING as i64 * SPACING as i64)) as f64).cbrt() as u32;
    let bands = m.div_ceil(side.max(1));
    let size = m.div_ceil(bands);
    (0..m)
        .step_by(size as usize)
        .map(|r| r..(r + size).min(m))
        .collect()
}

/// The buckets of `tiles` from kernel `bucket_accumulate`: their sample lists built in
/// parallel, then as few dispatches as the device's binding size allows, each over several
/// tiles' buckets laid end to end.
fn accumulate_on_gpu(gpu: &Compute, tiles: &[Tile]) -> Result<Vec<Buckets>> {
    let Some(first) = tiles.first() else {
        return Ok(Vec::new());
    };
    let (clusters, channels) = (first.clusters, first.solid.channels);
    let stride = 2 + channels;
    let mut lists: Vec<Vec<u32>> = tiles.par_iter().map(Tile::sample_list).collect();
    let max_words = (gpu.max_binding_bytes() / 4) as usize;
    let sum_words = |voxels: usize| voxels * 2 * (1 + channels);
    let mut out = Vec::with_capacity(tiles.len());
    let mut start = 0;
    while start < tiles.len() {
        // Tiles start..end in one dispatch: their buckets within one binding (the kernel
        // splits the samples as needed).
        let (mut end, mut voxels) = (start, 0);
        while end < tiles.len() {
            let v = voxels + tiles[end].voxels();
            if end > start && sum_words(v).max(v * clusters) > max_words {
                break;
            }
            (voxels, end) = (v, end + 1);
        }
        // Each tile's buckets follow the previous tiles'.
        let firsts = tiles[start..end].iter().scan(0, |first, tile| {
            let this = *first;
            *first += tile.voxels();
            Some(this)
        });
        let firsts: Vec<usize> = firsts.collect();
        lists[start..end]
            .par_iter_mut()
            .zip(firsts)
            .for_each(|(list, first)| {
                for bucket in list.iter_mut().step_by(stride) {
                    *bucket += first as u32;
                }
            });
        let parts: Vec<&[u32]> = lists[start..end].iter().map(|l| &l[..]).collect();
        let all = gpu.bucket_accumulate_parts(&parts, voxels, clusters as u32, channels as u32)?;
        let (mut counts, mut sums) = (&all.counts[..], &all.sums[..]);
        for tile in &tiles[start..end] {
            let v = tile.voxels();
            let (c, rest_c) = counts.split_at(v * clusters);
            let (s, rest_s) = sums.split_at(sum_words(v));
            out.push(Buckets {
                counts: c.to_vec(),
                sums: s.to_vec(),
            });
            (counts, sums) = (rest_c, rest_s);
        }
        start = end;
    }
    Ok(out)
}

/// One representation update: the new solid and the fraction of points refitted. With
/// `targets`, also every bucket's average (the samples of eq. 3).
///
/// Both backends work tile by tile (cubes of control points, `tile_bands`), in parallel;
/// the GPU accumulates a batch of tiles per dispatch (`accumulate_on_gpu`). A bucket's
/// samples are the same whichever tile holds it, so both give the same integers.
pub fn update(
    solid: &PeriodicSolid,
    points: &[[u16; 3]],
    matches: &[Match],
    ctx: &MatchContext,
    compute: &Compute,
    targets: Option<&mut Targets>,
) -> Result<(PeriodicSolid, f64)> {
    type Band = std::ops::Range<u32>;
    let want_values = targets.is_some();
    let m = solid.m;
    let clusters = ctx.patches.cluster_count() as usize;
    // (layers, rows, columns) of every tile.
    let bands = tile_bands(m);
    let tiles: Vec<(Band, Band, Band)> = bands
        .iter()
        .flat_map(|layers| {
            bands.iter().flat_map(|rows| {
                bands
                    .iter()
                    .map(|cols| (layers.clone(), rows.clone(), cols.clone()))
            })
        })
        .collect();
    let tile_at = |(layers, rows, cols): &(Band, Band, Band)| Tile {
        solid,
        matches,
        points,
        ctx,
        layers: layers.clone(),
        rows: rows.clone(),
        cols: cols.clone(),
        clusters,
    };
    let finish = |tile: &Tile, buckets: &Buckets| -> (Vec<f32>, usize, Vec<f32>) {
        let (values, refitted) = tile.fit(buckets);
        let averages = if want_values {
            tile.bucket_values(buckets)
        } else {
            Vec::new()
        };
        (values, refitted, averages)
    };
    let results: Vec<(Vec<f32>, usize, Vec<f32>)> = match compute {
        Compute::Cpu => tiles
            .par_iter()
            .map(|t| {
                let tile = tile_at(t);
                let buckets = tile.accumulate_on_cpu();
                finish(&tile, &buckets)
            })
            .collect(),
        Compute::Gpu(_) => {
            // The host's work (sample lists, fits) in parallel; the device's, a batch of tiles
            // per dispatch (one control layer per dispatch, with the host's work on one thread,
            // was 13x slower than the CPU backend on an H100, and a layer's list outgrew a
            // storage binding at 512^3).
            // Two tiles a thread keep the cores busy; at most 16 bound the lists held (a tile's
            // list is ~12 MB: some 75 samples of 5 words per bucket).
            let batch = (2 * rayon::current_num_threads()).clamp(4, 16);
            let mut results = Vec::with_capacity(tiles.len());
            for chunk in tiles.chunks(batch) {
                let chunk: Vec<Tile> = chunk.iter().map(tile_at).collect();
                let buckets = accumulate_on_gpu(compute, &chunk)?;
                results.par_extend(
                    chunk
                        .par_iter()
                        .zip(buckets.par_iter())
                        .map(|(tile, b)| finish(tile, b)),
                );
            }
            results
        }
    };
    let (p_len, c) = (solid.period(), solid.channels);
    let d = SPACING as i64;
    if let Some(t) = targets {
        // Each tile's averages, voxel by voxel (its bands may wrap around the period).
        for ((layers, rows, cols), result) in tiles.iter().zip(&results) {
            let (height, width) = (rows.len() as i64 * d, cols.len() as i64 * d);
            for (i, voxel) in result.2.chunks_exact(c).enumerate() {
                let i = i as i64;
                let (bz, by, bx) = (i / (height * width), (i / width) % height, i % width);
                let at = |first: u32, b: i64| (first as i64 * d - d / 2 + b).rem_euclid(p_len);
                let (z, y, x) = (at(layers.start, bz), at(rows.start, by), at(cols.start, bx));
                let at = ((z * p_len + y) * p_len + x) as usize * c;
                t.values[at..at + c].copy_from_slice(voxel);
            }
        }
    }
    let refitted: usize = results.iter().map(|r| r.1).sum();
    // Each tile's points, row after row, to their places in the solid.
    let per = c * 4;
    let mut data = vec![0f32; solid.data.len()];
    for ((layers, rows, cols), result) in tiles.iter().zip(&results) {
        let zy = layers
            .clone()
            .flat_map(|z| rows.clone().map(move |y| (z, y)));
        for ((z, y), values) in zy.zip(result.0.chunks_exact(cols.len() * per)) {
            let at = solid.offset([cols.start as i64, y as i64, z as i64]);
            data[at..at + values.len()].copy_from_slice(values);
        }
    }
    Ok((
        PeriodicSolid {
            m: solid.m,
            channels: solid.channels,
            data,
        },
        refitted as f64 / (solid.m as f64).powi(3),
    ))
}
