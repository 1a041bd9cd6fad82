//! Where the matched patches' samples land: every sample of every check point's three slices
//! that falls in a tile, with its bucket and exemplar pixel (`Tile::for_each_sample`), and the
//! fast path for axis-aligned slices.

use super::super::matching::UNMATCHED;
use super::super::wrap;
use super::Tile;
use crate::gradient::SPACING;

/// The samples t in 0..n of a slice axis whose coordinates `c0 + s t`, wrapped, lie in the
/// band [lo, lo + len) of a period `p`: for each, its share of the bucket index (`stride` per
/// voxel from the band start) and of the exemplar pixel (`pixel_step` per sample), pushed to
/// `out`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn indices_in_band(
    c0: i64,
    s: i64,
    n: usize,
    lo: i64,
    len: i64,
    p: i64,
    pixel_step: usize,
    stride: usize,
    out: &mut Vec<(usize, usize)>,
) {
    out.clear();
    // Offsets from the band start, wrapped into [0, p); s < p, so one subtraction wraps.
    let mut r = wrap(c0 - lo, p);
    for t in 0..n {
        if r < len {
            out.push((r as usize * stride, t * pixel_step));
        }
        r += s;
        if r >= p {
            r -= p;
        }
    }
}

impl Tile<'_> {
    /// Calls `visit(bucket, exemplar_pixel)` for every sample landing in this tile.
    pub(super) fn for_each_sample(&self, mut visit: impl FnMut(usize, usize)) {
        let ctx = self.ctx;
        let (m, p_len) = (self.solid.m as i64, self.period());
        let nc = ctx.params.check_points as usize;
        let n = ctx.patches.size;
        let h = ctx.patches.half_extent() as i64;
        // Farthest a slice sample lies from its check point along an axis: h for axis-aligned
        // slices, up to h sqrt 2 (+ rounding) for turned ones.
        let axis_aligned = ctx.params.field == super::super::Field::None;
        let reach = if axis_aligned {
            h
        } else {
            (h as f64 * std::f64::consts::SQRT_2).ceil() as i64 + 1
        };
        let d = SPACING as i64;
        // The cubes whose check points lie within `reach` of the tile along `axis`: their
        // first index and count.
        let cubes = |axis: usize, reach: i64| {
            let (lo, len, _) = self.band(axis);
            let first = (lo - reach).div_euclid(d);
            (
                first,
                ((lo + len - 1 + reach).div_euclid(d) - first + 1).min(m),
            )
        };
        // Whether check point `p` lies within `reach[axis]` of the tile along every axis.
        let near = |p: [i64; 3], reach: [i64; 3]| {
            (0..3).all(|axis| {
                let (lo, len, _) = self.band(axis);
                wrap(p[axis] - lo + reach[axis], p_len) < len + 2 * reach[axis]
            })
        };
        let in_tile = |q: [i64; 3]| {
            (0..3).all(|axis| {
                let (lo, len, _) = self.band(axis);
                wrap(q[axis] - lo, p_len) < len
            })
        };
        let mut scratch: [Vec<(usize, usize)>; 2] = [
            Vec::with_capacity(n as usize),
            Vec::with_capacity(n as usize),
        ];
        let cube_index = |c: [i64; 3]| {
            let c = c.map(|c| c.rem_euclid(m) as usize);
            (c[2] * m as usize + c[1]) * m as usize + c[0]
        };
        if axis_aligned {
            // Slice by slice orientation: a slice lies in its check point's plane, so along
            // its normal only the check points inside the tile's band land samples (within
            // reach along its two axes): a third of the visits of a box grown on every side.
            for o in 0..3 {
                let (u, v) = ctx.params.slice_axes().of(o);
                let mut reaches = [reach; 3];
                reaches[3 - u - v] = 0;
                let ranges: [(i64, i64); 3] =
                    std::array::from_fn(|axis| cubes(axis, reaches[axis]));
                // Wrapped cube coordinates, once per axis (not a division per cube).
                let wrapped = |axis: usize| -> Vec<usize> {
                    let (first, count) = ranges[axis];
                    (first..first + count)
                        .map(|c| c.rem_euclid(m) as usize)
                        .collect()
                };
                let (zs, ys, xs) = (wrapped(2), wrapped(1), wrapped(0));
                let m = m as usize;
                for &cz in &zs {
                    for &cy in &ys {
                        let row = (cz * m + cy) * m;
                        for &cx in &xs {
                            let cube = row + cx;
                            for i in cube * nc..(cube + 1) * nc {
                                let p = self.points[i].map(i64::from);
                                let candidate = self.matches[i][o];
                                if candidate == UNMATCHED || !near(p, reaches) {
                                    continue;
                                }
                                self.axis_aligned_samples(
                                    p,
                                    o,
                                    candidate,
                                    &mut scratch,
                                    &mut visit,
                                );
                            }
                        }
                    }
                }
            }
            return;
        }
        let (first_z, layers) = cubes(2, reach);
        let (first_y, rows) = cubes(1, reach);
        let (first_x, cols) = cubes(0, reach);
        for cz in first_z..first_z + layers {
            for cy in first_y..first_y + rows {
                for cx in first_x..first_x + cols {
                    let cube = cube_index([cx, cy, cz]);
                    for i in cube * nc..(cube + 1) * nc {
                        let p = self.points[i].map(i64::from);
                        // Beyond the slices' reach of the tile along an axis: nothing lands.
                        if !near(p, [reach; 3]) {
                            continue;
                        }
                        let frame = ctx.frame(p, p_len);
                        let matched = &self.matches[i];
                        for (o, &candidate) in matched.iter().enumerate() {
                            if candidate == UNMATCHED {
                                continue;
                            }
                            if frame.is_identity() {
                                self.axis_aligned_samples(
                                    p,
                                    o,
                                    candidate,
                                    &mut scratch,
                                    &mut visit,
                                );
                                continue;
                            }
                            for b in 0..n {
                                // Coordinates are monotone along a row: its two ends bound
                                // them, and a row outside the tile's z or y band is skipped.
                                let ends = [
                                    ctx.sample_position(p, &frame, o, 0, b),
                                    ctx.sample_position(p, &frame, o, n - 1, b),
                                ];
                                let misses = |axis: usize, lo: i64, len: i64| {
                                    let (e0, e1) = (ends[0][axis], ends[1][axis]);
                                    let offset = wrap(e0.min(e1) - lo, p_len);
                                    offset >= len && offset + (e0 - e1).abs() < p_len
                                };
                                if (0..3).any(|axis| {
                                    let (lo, len, _) = self.band(axis);
                                    misses(axis, lo, len)
                                }) {
                                    continue;
                                }
                                for a in 0..n {
                                    let q = ctx.sample_position(p, &frame, o, a, b);
                                    if in_tile(q) {
                                        visit(
                                            self.bucket(q),
                                            ctx.patches.pixel_index(candidate, a, b),
                                        );
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// [`Self::for_each_sample`] for one axis-aligned slice (no direction field): the samples
    /// step by whole voxels along the slice's two axes, so the indices a (along U) and b (along
    /// V) inside the tile are found once per axis, each with its share of the bucket index and
    /// of the exemplar pixel (both are sums of one term per axis), and only those samples are
    /// visited (the same samples as [`MatchContext::sample_position`] gives). The inner loop
    /// runs along x where the slice has it (neighbouring buckets in memory).
    fn axis_aligned_samples(
        &self,
        p: [i64; 3],
        o: usize,
        candidate: u32,
        scratch: &mut [Vec<(usize, usize)>; 2],
        visit: &mut impl FnMut(usize, usize),
    ) {
        let ctx = self.ctx;
        let patches = ctx.patches;
        let p_len = self.period();
        let (n, s) = (patches.size as usize, patches.spacing as i64);
        let h = (n / 2) as i64;
        let (u, v) = ctx.params.slice_axes().of(o);
        let w = 3 - u - v;
        let (wlo, wlen, wstride) = self.band(w);
        let w_offset = wrap(p[w] - wlo, p_len);
        if w_offset >= wlen {
            return;
        }
        let first_pixel = patches.pixel_index(candidate, 0, 0);
        let pixel_step = [
            patches.pixel_index(candidate, 1, 0) - first_pixel,
            patches.pixel_index(candidate, 0, 1) - first_pixel,
        ];
        let [along_u, along_v] = scratch;
        for (axis, step, out) in [
            (u, pixel_step[0], &mut *along_u),
            (v, pixel_step[1], &mut *along_v),
        ] {
            let (lo, len, stride) = self.band(axis);
            indices_in_band(p[axis] - s * h, s, n, lo, len, p_len, step, stride, out);
        }
        if along_u.is_empty() || along_v.is_empty() {
            return;
        }
        let origin = (w_offset as usize * wstride, first_pixel);
        let (outer, inner) = if v == 0 {
            // x runs along the slice's columns: walk those innermost.
            (&*along_u, &*along_v)
        } else {
            (&*along_v, &*along_u)
        };
        for &(bucket_o, pixel_o) in outer {
            let (bucket_o, pixel_o) = (origin.0 + bucket_o, origin.1 + pixel_o);
            for &(bucket_i, pixel_i) in inner {
                visit(bucket_o + bucket_i, pixel_o + pixel_i);
            }
        }
    }
}
