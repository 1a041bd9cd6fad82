//! Representation update (paper 4.2.2): the matched patches' samples are scattered into
//! per-voxel buckets and each control point is refitted to the buckets nearest to it (eq. 2).
//!
//! Bucket reuse: buckets exist for one control layer at a time (the voxels z in [4K - 2, 4K + 2)
//! whose nearest control points are in layer K), so memory is O(P^2) per layer being processed
//! instead of O(P^3). Only check points whose slices can reach the layer are visited. Layers are
//! independent (they read the previous solid and the matches) and run in parallel.
//!
//! Accumulation is kernel `bucket_accumulate` (wgsl/bucket_accumulate.wgsl): pass 1 counts the
//! samples of every (voxel, colour cluster), pass 2 sums, in 8.8 fixed point, the samples of each
//! voxel's two dominant clusters. On the CPU backend the samples are streamed straight into the
//! counts and sums ([`accumulate_streaming`], the same integer arithmetic as
//! `crate::cpu::bucket_accumulate`; the kernel's sample list is not built, though a small
//! layer keeps (bucket, pixel) pairs between its two passes); on the GPU the
//! layer's samples are listed and dispatched. Both give the same integers.

use super::matching::{Match, MatchContext, UNMATCHED};
use super::refine::Targets;
use super::{wrap, PeriodicSolid};
use crate::backend::Compute;
use crate::cpu::bucket_accumulate::{dominant, Buckets};
use crate::error::Result;
use crate::gradient::SPACING;
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

/// Voxels of a layer's buckets along z (one control spacing).
const LAYER: i64 = SPACING as i64;
/// Ridge on the gradient unknowns of eq. 2 (in bucket-count x voxel^2 units; a full
/// neighbourhood has ~100 on the diagonal): keeps under-determined directions (all buckets
/// coplanar) at zero gradient instead of singular.
const RIDGE: f64 = 0.5;

/// Most samples one layer's accumulation keeps between its two passes (8 bytes each: 128 MiB
/// per layer in flight; one layer per thread). Measured at 128^3 (4 M samples per layer at the
/// finest level): the finest level's update 3.2 -> 2.9 s. Layers expected to hold more than
/// half of it (the finest level from 192^3 up: 16 M samples per layer at 256^3) are generated
/// twice instead.
const MAX_LISTED_SAMPLES: usize = 16 << 20;

/// One control layer's view of the samples.
struct Layer<'a> {
    solid: &'a PeriodicSolid,
    matches: &'a [Match],
    ctx: &'a MatchContext<'a>,
    /// Control layer index K.
    k: u32,
}

impl Layer<'_> {
    fn period(&self) -> i64 {
        self.solid.period()
    }
    /// First voxel z of the layer's buckets.
    fn z0(&self) -> i64 {
        self.k as i64 * SPACING as i64 - LAYER / 2
    }
    fn voxels(&self) -> usize {
        (self.period() * self.period() * LAYER) as usize
    }

    /// Calls `visit(bucket, exemplar_pixel)` for every sample landing in this layer.
    fn for_each_sample(&self, mut visit: impl FnMut(usize, usize)) {
        let ctx = self.ctx;
        let (m, p_len) = (self.solid.m as i64, self.period());
        let nc = ctx.params.check_points as usize;
        let n = ctx.patches.size;
        let h = ctx.patches.half_extent() as i64;
        // Farthest a slice sample lies from its check point along z: h for axis-aligned slices,
        // up to h sqrt 2 (+ rounding) for turned ones.
        let reach = if ctx.params.field == super::Field::None {
            h
        } else {
            (h as f64 * std::f64::consts::SQRT_2).ceil() as i64 + 1
        };
        let d = SPACING as i64;
        let (zlo, zhi) = (self.z0() - reach, self.z0() + LAYER - 1 + reach);
        let first = zlo.div_euclid(d);
        let layers = (zhi.div_euclid(d) - first + 1).min(m);
        let in_layer = |z: i64| wrap(z - self.z0(), p_len) < LAYER;
        for cz in first..first + layers {
            let cz = cz.rem_euclid(m) as u32;
            for cy in 0..m as u32 {
                for cx in 0..m as u32 {
                    let cube = [cx, cy, cz];
                    let cube_index =
                        ((cz as usize * m as usize) + cy as usize) * m as usize + cx as usize;
                    for k in 0..nc {
                        let p = ctx.check_point(cube, k as u32);
                        let frame = ctx.frame(p, p_len);
                        let matched = &self.matches[cube_index * nc + k];
                        for (o, &candidate) in matched.iter().enumerate() {
                            if candidate == UNMATCHED {
                                continue;
                            }
                            if frame.is_identity() {
                                self.axis_aligned_samples(p, o, candidate, &mut visit);
                                continue;
                            }
                            for b in 0..n {
                                // z is monotone along a row: its two ends bound it.
                                let (za, zb) = (
                                    ctx.sample_position(p, &frame, o, 0, b)[2],
                                    ctx.sample_position(p, &frame, o, n - 1, b)[2],
                                );
                                let (lo, span) = (za.min(zb), (za - zb).abs());
                                let dz = wrap(lo - self.z0(), p_len);
                                if dz >= LAYER && dz + span < p_len {
                                    continue;
                                }
                                for a in 0..n {
                                    let q = ctx.sample_position(p, &frame, o, a, b);
                                    if !in_layer(q[2]) {
                                        continue;
                                    }
                                    let bucket = ((wrap(q[2] - self.z0(), p_len) * p_len
                                        + wrap(q[1], p_len))
                                        * p_len
                                        + wrap(q[0], p_len))
                                        as usize;
                                    visit(bucket, ctx.patches.pixel_index(candidate, a, b));
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`Self::for_each_sample`] for one axis-aligned slice (no direction field): the samples
    /// step by whole voxels along the slice's two axes, so a row whose z is constant is tested
    /// against the layer once, and positions and exemplar pixels advance incrementally (the
    /// same samples as [`MatchContext::sample_position`] gives, in the same order).
    fn axis_aligned_samples(
        &self,
        p: [i64; 3],
        o: usize,
        candidate: u32,
        visit: &mut impl FnMut(usize, usize),
    ) {
        let ctx = self.ctx;
        let patches = ctx.patches;
        let p_len = self.period();
        let (n, s) = (patches.size, patches.spacing as i64);
        let h = (n / 2) as i64;
        let (u, v) = ctx.params.slice_axes().of(o);
        let z0 = self.z0();
        let in_layer = |z: i64| wrap(z - z0, p_len) < LAYER;
        let bucket = |q: [i64; 3]| {
            ((wrap(q[2] - z0, p_len) * p_len + wrap(q[1], p_len)) * p_len + wrap(q[0], p_len))
                as usize
        };
        let mut start = p;
        start[u] -= s * h;
        start[v] -= s * h;
        if u == 2 {
            // The slice's rows run along z. Walk it column by column instead (along v, not z:
            // neighbouring buckets in memory), and only through the z positions inside the
            // layer (a slice is visited by every layer its z extent reaches).
            for a in 0..n {
                let mut q = start;
                q[2] += s * a as i64;
                if !in_layer(q[2]) {
                    continue;
                }
                for b in 0..n {
                    visit(bucket(q), patches.pixel_index(candidate, a, b));
                    q[v] += s;
                }
            }
            return;
        }
        for b in 0..n {
            let mut q = start;
            q[v] += s * b as i64;
            // Along a row only q[u] changes, and u is not z: the row is in the layer or not.
            if !in_layer(q[2]) {
                continue;
            }
            let first_pixel = patches.pixel_index(candidate, 0, b);
            for a in 0..n as usize {
                visit(bucket(q), first_pixel + a * patches.spacing as usize);
                q[u] += s;
            }
        }
    }

    /// Both passes of the bucket accumulation, streamed (CPU backend).
    fn accumulate_streaming(&self) -> Buckets {
        let patches = self.ctx.patches;
        let clusters = patches.cluster_count() as usize;
        let channels = self.solid.channels;
        let voxels = self.voxels();
        let per = 1 + channels;
        let mut counts = vec![0u32; voxels * clusters];
        // Pass 1 lists the samples it generates so that pass 2 reads them instead of
        // generating them again, when the layer is expected to hold well under the cap (on
        // average, every check point's samples of one cell layer; a list that overflowed
        // would be wasted work). Otherwise pass 2 generates them again: the same integers.
        let n = patches.size as usize;
        let m = self.solid.m as usize;
        let expected = m
            * m
            * self.ctx.params.check_points as usize
            * self.ctx.params.matched_slices as usize
            * n
            * n;
        let mut listed: Vec<(u32, u32)> = Vec::new();
        let mut complete = expected <= MAX_LISTED_SAMPLES / 2;
        if complete {
            listed.reserve(expected + expected / 4);
        }
        self.for_each_sample(|v, px| {
            counts[v * clusters + patches.cluster(px) as usize] += 1;
            if complete {
                if listed.len() < MAX_LISTED_SAMPLES {
                    listed.push((v as u32, px as u32));
                } else {
                    complete = false;
                }
            }
        });
        if !complete {
            listed = Vec::new();
        }
        let dominant: Vec<[u32; 2]> = counts.chunks_exact(clusters).map(dominant).collect();
        let mut sums = vec![0u32; voxels * 2 * per];
        let mut add = |v: usize, px: usize| {
            let cluster = patches.cluster(px);
            let Some(slot) = dominant[v].iter().position(|&c| c == cluster) else {
                return;
            };
            let base = (v * 2 + slot) * per;
            sums[base] += 1;
            for (c, &value) in patches.value(px).iter().enumerate() {
                sums[base + 1 + c] += (value as u32) << 8;
            }
        };
        if complete {
            for &(v, px) in &listed {
                add(v as usize, px as usize);
            }
        } else {
            self.for_each_sample(add);
        }
        Buckets { counts, sums }
    }

    /// The layer's samples as the kernel's list: bucket, cluster, channel values.
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

    fn accumulate(&self, compute: &Compute) -> Result<Buckets> {
        match compute {
            Compute::Cpu => Ok(self.accumulate_streaming()),
            Compute::Gpu(gpu) => crate::gpu::bucket_accumulate::bucket_accumulate(
                gpu,
                &self.sample_list(),
                self.voxels(),
                self.ctx.patches.cluster_count(),
                self.solid.channels as u32,
            ),
        }
    }

    /// The average of every bucket of the layer (per voxel, per channel; NaN when empty), z
    /// from the layer's first voxel. With a mask (region-pure clusters), only the samples of
    /// one region are averaged: that of the dominant slot holding more samples (ties: the first
    /// slot's), so a voxel's colour and distance come from one side of the boundary (the
    /// samples of the final region separation, paper 4.3).
    fn bucket_values(&self, buckets: &Buckets) -> Vec<f32> {
        let c = self.solid.channels;
        let per = 1 + c;
        let patches = self.ctx.patches;
        let regions = patches.cluster_regions();
        let clusters = patches.cluster_count() as usize;
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

    /// Eq. 2 for every control point of the layer: f + grad f . (x - p) ~ bucket value, over
    /// the non-empty buckets whose nearest point it is. Points without samples keep their
    /// values. Returns the layer's new values and how many points were refitted.
    fn fit(&self, buckets: &Buckets) -> (Vec<f32>, usize) {
        let solid = self.solid;
        let (m, c) = (solid.m as i64, solid.channels);
        let p_len = self.period();
        let per = 1 + c;
        let d = SPACING as i64;
        let mut out = Vec::with_capacity((m * m) as usize * c * 4);
        let mut refitted = 0;
        for y in 0..m {
            for x in 0..m {
                let old = solid.offset([x, y, self.k as i64]);
                let mut ata = Matrix4::<f64>::zeros();
                let mut atb = vec![Vector4::<f64>::zeros(); c];
                let mut samples = 0;
                for dz in -LAYER / 2..LAYER / 2 {
                    for dy in -d / 2..d / 2 {
                        for dx in -d / 2..d / 2 {
                            let bz = dz + LAYER / 2;
                            let by = (y * d + dy).rem_euclid(p_len);
                            let bx = (x * d + dx).rem_euclid(p_len);
                            let v = ((bz * p_len + by) * p_len + bx) as usize;
                            let (s0, s1) = (v * 2 * per, (v * 2 + 1) * per);
                            let count = buckets.sums[s0] + buckets.sums[s1];
                            if count == 0 {
                                continue;
                            }
                            samples += 1;
                            let row = Vector4::new(1.0, dx as f64, dy as f64, dz as f64);
                            ata += row * row.transpose();
                            for (ch, b) in atb.iter_mut().enumerate() {
                                let sum =
                                    (buckets.sums[s0 + 1 + ch] + buckets.sums[s1 + 1 + ch]) as f64;
                                *b += row * (sum / (256.0 * count as f64));
                            }
                        }
                    }
                }
                if samples == 0 {
                    out.extend_from_slice(&solid.data[old..old + c * 4]);
                    continue;
                }
                refitted += 1;
                for i in 1..4 {
                    ata[(i, i)] += RIDGE;
                }
                let inv = ata.try_inverse().unwrap_or_else(Matrix4::zeros);
                for b in &atb {
                    let sol = inv * b;
                    out.extend(sol.iter().map(|&v| v as f32));
                }
            }
        }
        (out, refitted)
    }
}

/// One representation update: the new solid and the fraction of points refitted. With
/// `targets`, also every bucket's average (the samples of eq. 3).
pub fn update(
    solid: &PeriodicSolid,
    matches: &[Match],
    ctx: &MatchContext,
    compute: &Compute,
    targets: Option<&mut Targets>,
) -> Result<(PeriodicSolid, f64)> {
    let want_values = targets.is_some();
    let layer = |k: u32| -> Result<(Vec<f32>, usize, Vec<f32>)> {
        let layer = Layer {
            solid,
            matches,
            ctx,
            k,
        };
        let buckets = layer.accumulate(compute)?;
        let (values, refitted) = layer.fit(&buckets);
        let averages = if want_values {
            layer.bucket_values(&buckets)
        } else {
            Vec::new()
        };
        Ok((values, refitted, averages))
    };
    // The GPU path runs its layers one after another (one queue); the CPU path in parallel.
    let mut layers: Vec<(Vec<f32>, usize, Vec<f32>)> = match compute {
        Compute::Cpu => (0..solid.m)
            .into_par_iter()
            .map(layer)
            .collect::<Result<_>>()?,
        Compute::Gpu(_) => (0..solid.m).map(layer).collect::<Result<_>>()?,
    };
    if let Some(t) = targets {
        let (p_len, c) = (solid.period() as usize, solid.channels);
        let plane = p_len * p_len * c;
        for (k, layer) in layers.iter_mut().enumerate() {
            let averages = std::mem::take(&mut layer.2);
            for (bz, slab) in averages.chunks_exact(plane).enumerate() {
                let z = (k as i64 * SPACING as i64 - LAYER / 2 + bz as i64).rem_euclid(p_len as i64)
                    as usize;
                t.values[z * plane..(z + 1) * plane].copy_from_slice(slab);
            }
        }
    }
    let refitted: usize = layers.iter().map(|l| l.1).sum();
    let data = layers.into_iter().flat_map(|l| l.0).collect();
    Ok((
        PeriodicSolid {
            m: solid.m,
            channels: solid.channels,
            data,
        },
        refitted as f64 / (solid.m as f64).powi(3),
    ))
}
