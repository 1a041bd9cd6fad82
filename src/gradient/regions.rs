//! Region separation (paper 3.2, 5.3): a signed distance field stored on the same control grid
//! (value and gradients, interpolated like the colours), and, at every control point next to a
//! cube where the distance changes sign, two feature sets f^P and f^N. A sample takes the set of
//! its interpolated distance's sign, so boundaries stay sharp while each region stays C^1.
//! Rendering blends the two sets linearly within half a voxel of the boundary (the paper's
//! anti-aliasing); [`Blend::Exact`] switches that off.
//!
//! Held as three gradient solids over one grid: `distance` (1 channel, in voxels, positive where
//! the mask is set), `positive` and `negative` (the feature sets; equal where a point is not
//! split). Evaluation runs the existing `tricubic_eval` kernel (GPU or CPU) on each, then blends.
//!
//! File (`.gsolid` path, own magic): `GSREGION`, u32 version (1), u32 encoding (0 f32, 1 8-bit),
//! then u64 length + the distance solid as a `.gsolid`, u64 length + the positive solid as a
//! `.gsolid`, the split flags (one bit per control point, x fastest, LSB first), u64 length +
//! the negative set of the split points only (values encoded like a `.gsolid` payload), and a
//! CRC-32 of everything before it.
//!

use super::format::{self, Encoding};
use super::vectorize::{fit_point, grid_for, point_position};
use super::{GradientSolid, SPACING};
use crate::backend::host_tricubic_eval as tricubic_eval;
use crate::backend::Compute;
use crate::contract::tricubic::Query;
use crate::error::{Error, Result};
use crate::exemplar::feature::edt_1d;
use crate::volume::Volume;
use rayon::prelude::*;

const MAGIC: &[u8; 8] = b"GSREGION";
const VERSION: u32 = 1;

#[derive(Clone, Debug, PartialEq)]
pub struct RegionSolid {
    pub distance: GradientSolid,
    pub positive: GradientSolid,
    pub negative: GradientSolid,
    /// Per control point: carries two feature sets.
    pub split: Vec<bool>,
}

/// How samples near the boundary are coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blend {
    /// The set of the sample's sign (paper 3.2).
    Exact,
    /// Linear blend of both sets within half a voxel of the boundary (paper 5.3).
    Antialiased,
}

/// True when `bytes` hold a region solid (rather than a plain `.gsolid`).
pub fn is_region_file(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Squared distance from every voxel to the nearest voxel where `feature` is true.
fn squared_distance(n: [usize; 3], feature: &[bool]) -> Vec<f32> {
    const FAR: f32 = 1e12;
    let mut d: Vec<f32> = feature.iter().map(|&f| if f { 0.0 } else { FAR }).collect();
    let index = |x: usize, y: usize, z: usize| (z * n[1] + y) * n[0] + x;
    // One 1D transform per line along each axis in turn (separable: exact in 3D).
    for axis in 0..3 {
        let len = n[axis];
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut line = vec![0f32; len];
        let mut out = vec![0f32; len];
        let mut v = vec![0usize; len];
        let mut z = vec![0f32; len + 1];
        for j in 0..n[b] {
            for i in 0..n[a] {
                let at = |t: usize| {
                    let mut c = [0usize; 3];
                    c[axis] = t;
                    c[a] = i;
                    c[b] = j;
                    index(c[0], c[1], c[2])
                };
                for t in 0..len {
                    line[t] = d[at(t)];
                }
                edt_1d(&line, &mut out, &mut v, &mut z);
                for t in 0..len {
                    d[at(t)] = out[t];
                }
            }
        }
    }
    d
}

/// Signed distance (voxels) of every voxel to the mask's boundary: positive where the mask's
/// first channel is >= 128, the boundary half way between two voxels of different regions.
pub fn signed_distance(mask: &Volume) -> Vec<f32> {
    let n = [mask.nx as usize, mask.ny as usize, mask.nz as usize];
    let c = mask.channels as usize;
    let inside: Vec<bool> = mask.data.chunks_exact(c).map(|p| p[0] >= 128).collect();
    let outside: Vec<bool> = inside.iter().map(|&i| !i).collect();
    let to_outside = squared_distance(n, &outside);
    let to_inside = squared_distance(n, &inside);
    inside
        .iter()
        .zip(to_outside.iter().zip(&to_inside))
        .map(
            |(&i, (&o, &n))| {
                if i {
                    o.sqrt() - 0.5
                } else {
                    0.5 - n.sqrt()
                }
            },
        )
        .collect()
}

/// Vectorize `v` with region separation along `mask` (same size; its first channel, set where
/// >= 128). `mask_name` labels errors.
pub fn vectorize_regions(v: &Volume, mask: &Volume, mask_name: &str) -> Result<RegionSolid> {
    if mask.dims() != v.dims() {
        return Err(Error::invalid(
            mask_name,
            format!(
                "the mask is {:?} voxels, the volume {:?}: they must match",
                mask.dims(),
                v.dims()
            ),
        ));
    }
    let sd = signed_distance(mask);
    let n = v.dims();
    if sd.iter().all(|&d| d >= 0.0) || sd.iter().all(|&d| d < 0.0) {
        return Err(Error::invalid(
            mask_name,
            "the mask has a single region (all set or all clear): nothing to separate",
        ));
    }
    let dims = n.map(|e| grid_for(e).max(2));
    let at = |x: u32, y: u32, z: u32| ((z * n[1] + y) * n[0] + x) as usize;
    // The distance is sampled, not fitted: the value at the control point's voxel and central
    // differences for the gradient. (Eq. 2's least squares over the 9^3 neighbourhood smooths a
    // curved boundary's distance and moves its zero set inward by up to a voxel.)
    let mut distance = GradientSolid::new(dims, 1)?;
    distance.size = n;
    let sample = |q: [i64; 3]| {
        let c = [0, 1, 2].map(|a| q[a].clamp(0, n[a] as i64 - 1) as u32);
        sd[at(c[0], c[1], c[2])]
    };
    distance
        .data
        .par_chunks_mut(4)
        .enumerate()
        .for_each(|(i, out)| {
            let p = point_position(dims, i);
            let p = [0, 1, 2].map(|a| p[a].min(n[a] as i64 - 1));
            out[0] = sample(p);
            for a in 0..3 {
                let (mut lo, mut hi) = (p, p);
                lo[a] = (p[a] - 1).max(0);
                hi[a] = (p[a] + 1).min(n[a] as i64 - 1);
                let span = (hi[a] - lo[a]).max(1) as f32;
                out[1 + a] = (sample(hi) - sample(lo)) / span;
            }
        });
    // A cube is mixed when its voxels (corner to corner, inclusive) hold both signs.
    let cubes = dims.map(|d| (d - 1) as usize);
    let mixed: Vec<bool> = (0..cubes[0] * cubes[1] * cubes[2])
        .into_par_iter()
        .map(|k| {
            let c = [
                k % cubes[0],
                (k / cubes[0]) % cubes[1],
                k / (cubes[0] * cubes[1]),
            ];
            let lo = c.map(|v| (v as u32 * SPACING) as usize);
            let (mut pos, mut neg) = (false, false);
            for z in lo[2]..=(lo[2] + SPACING as usize).min(n[2] as usize - 1) {
                for y in lo[1]..=(lo[1] + SPACING as usize).min(n[1] as usize - 1) {
                    for x in lo[0]..=(lo[0] + SPACING as usize).min(n[0] as usize - 1) {
                        if sd[at(x as u32, y as u32, z as u32)] >= 0.0 {
                            pos = true;
                        } else {
                            neg = true;
                        }
                    }
                }
            }
            pos && neg
        })
        .collect();
    let points = dims.iter().map(|&d| d as usize).product::<usize>();
    let split: Vec<bool> = (0..points)
        .map(|i| {
            let p = [
                i % dims[0] as usize,
                (i / dims[0] as usize) % dims[1] as usize,
                i / (dims[0] as usize * dims[1] as usize),
            ];
            // The up to 8 cubes having this point as a corner.
            (0..8).any(|corner| {
                let c: Vec<Option<usize>> = (0..3)
                    .map(|a| {
                        let off = (corner >> a) & 1;
                        (p[a] >= off && p[a] - off < cubes[a]).then(|| p[a] - off)
                    })
                    .collect();
                match (c[0], c[1], c[2]) {
                    (Some(x), Some(y), Some(z)) => mixed[(z * cubes[1] + y) * cubes[0] + x],
                    _ => false,
                }
            })
        })
        .collect();
    let channels = v.channels;
    let fit_set = |keep: &(dyn Fn(f32) -> bool + Sync)| -> Result<GradientSolid> {
        let mut s = GradientSolid::new(dims, channels)?;
        s.size = n;
        s.data
            .par_chunks_mut(channels as usize * 4)
            .enumerate()
            .for_each(|(i, out)| {
                let split_here = split[i];
                fit_point(point_position(dims, i), n, out, &|x, y, z, px| {
                    if split_here && !keep(sd[at(x, y, z)]) {
                        return false;
                    }
                    for (o, &b) in px.iter_mut().zip(v.at(x, y, z)) {
                        *o = b as f64;
                    }
                    true
                });
            });
        Ok(s)
    };
    let positive = fit_set(&|d| d >= 0.0)?;
    let negative = fit_set(&|d| d < 0.0)?;
    Ok(RegionSolid {
        distance,
        positive,
        negative,
        split,
    })
}

impl RegionSolid {
    pub fn channels(&self) -> u32 {
        self.positive.channels
    }

    /// Voxels per axis covered.
    pub fn extent(&self) -> [u32; 3] {
        self.positive.extent()
    }

    /// Eq. 3 for a region solid: both feature sets refined together so the exact evaluation
    /// (each voxel with its own sign's set) fits every voxel of `v`; the distance stays as is.
    /// Returns the RMS error after each conjugate-gradient step.
    pub fn optimize(&mut self, v: &Volume, iterations: usize) -> Vec<f64> {
        let n = v.dims();
        let negative_voxel: Vec<bool> = tricubic_eval(&self.distance, &Query::volume(n))
            .iter()
            .map(|&d| d < 0.0)
            .collect();
        let points = self.split.len();
        let split = &self.split;
        // Unknowns: every point's positive set, then every point's negative set (used only
        // where the point is split: elsewhere its one set stands for both).
        let point = |vox: usize, p: usize| {
            if negative_voxel[vox] && split[p] {
                points + p
            } else {
                p
            }
        };
        let mut x: Vec<f64> = self
            .positive
            .data
            .iter()
            .chain(&self.negative.data)
            .map(|&d| d as f64)
            .collect();
        let history = super::vectorize::cgnr(&self.positive, v, &point, &mut x, iterations);
        let per = self.channels() as usize * 4;
        let (pos, neg) = x.split_at(points * per);
        self.positive.data = pos.iter().map(|&d| d as f32).collect();
        for i in 0..points {
            let src = if self.split[i] { neg } else { pos };
            for k in 0..per {
                self.negative.data[i * per + k] = src[i * per + k] as f32;
            }
        }
        history
    }

    /// Split control points (for reports).
    pub fn split_points(&self) -> usize {
        self.split.iter().filter(|&&s| s).count()
    }

    /// `channels` values per point of `query`, on `compute`'s backend (three `tricubic_eval`
    /// runs, then the blend on the host).
    pub fn eval_query(&self, query: &Query, compute: &Compute, blend: Blend) -> Result<Vec<f32>> {
        let run = |s: &GradientSolid| compute.tricubic_eval(s, query);
        let d = run(&self.distance)?;
        let p = run(&self.positive)?;
        let n = run(&self.negative)?;
        let c = self.channels() as usize;
        Ok(p.chunks_exact(c)
            .zip(n.chunks_exact(c))
            .zip(&d)
            .flat_map(|((p, n), &d)| {
                let w = match blend {
                    Blend::Exact => {
                        if d >= 0.0 {
                            1.0
                        } else {
                            0.0
                        }
                    }
                    Blend::Antialiased => (d + 0.5).clamp(0.0, 1.0),
                };
                p.iter()
                    .zip(n)
                    .map(move |(&p, &n)| w * p + (1.0 - w) * n)
                    .collect::<Vec<_>>()
            })
            .collect())
    }

    /// The box [0, n)^3 rounded to 8 bits.
    pub fn render(&self, n: [u32; 3], compute: &Compute, blend: Blend) -> Result<Volume> {
        let values = self.eval_query(&Query::volume(n), compute, blend)?;
        let mut v = Volume::new(n[0], n[1], n[2], self.channels());
        for (o, x) in v.data.iter_mut().zip(values) {
            *o = x.round().clamp(0.0, 255.0) as u8;
        }
        Ok(v)
    }

    pub fn to_bytes(&self, encoding: Encoding) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        out.extend(VERSION.to_le_bytes());
        out.extend(((encoding == Encoding::U8) as u32).to_le_bytes());
        for s in [&self.distance, &self.positive] {
            let b = format::to_bytes(s, encoding);
            out.extend((b.len() as u64).to_le_bytes());
            out.extend(b);
        }
        let mut bits = vec![0u8; self.split.len().div_ceil(8)];
        for (i, _) in self.split.iter().enumerate().filter(|(_, &s)| s) {
            bits[i / 8] |= 1 << (i % 8);
        }
        out.extend(bits);
        let per = self.channels() as usize * 4;
        let negative: Vec<f32> = self
            .split
            .iter()
            .enumerate()
            .filter(|(_, &s)| s)
            .flat_map(|(i, _)| self.negative.data[i * per..(i + 1) * per].iter().copied())
            .collect();
        let b = format::encode_values(&negative, per, encoding);
        out.extend((b.len() as u64).to_le_bytes());
        out.extend(b);
        let crc = crc32fast::hash(&out);
        out.extend(crc.to_le_bytes());
        out
    }

    /// Parse; `name` labels errors.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<RegionSolid> {
        let bad = |why: &str| Error::invalid(name, why.to_string());
        if bytes.len() < 20 || !is_region_file(bytes) {
            return Err(bad("not a region .gsolid (bad magic or too short)"));
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32fast::hash(body) != u32::from_le_bytes(crc.try_into().unwrap()) {
            return Err(bad("checksum mismatch: the file is corrupt"));
        }
        let word = |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().unwrap());
        if word(8) != VERSION {
            return Err(bad("unsupported region .gsolid version"));
        }
        let encoding = match word(12) {
            0 => Encoding::F32,
            1 => Encoding::U8,
            _ => return Err(bad("unknown encoding")),
        };
        let mut at = 16usize;
        let mut take = |what: &str| -> Result<&[u8]> {
            let len_bytes = body
                .get(at..at + 8)
                .ok_or_else(|| bad(&format!("truncated before the {what}")))?;
            let len = u64::from_le_bytes(len_bytes.try_into().unwrap());
            let start = at + 8;
            let end = start
                .checked_add(usize::try_from(len).map_err(|_| bad("length overflow"))?)
                .filter(|&e| e <= body.len())
                .ok_or_else(|| bad(&format!("the {what} runs past the end of the file")))?;
            at = end;
            Ok(&body[start..end])
        };
        let distance = format::from_bytes(take("distance solid")?, name)?;
        let positive = format::from_bytes(take("positive set")?, name)?;
        if distance.channels != 1 || distance.dims != positive.dims {
            return Err(bad("the distance and feature grids do not match"));
        }
        let points = positive.dims.iter().map(|&d| d as usize).product::<usize>();
        let bits = body
            .get(at..at + points.div_ceil(8))
            .ok_or_else(|| bad("truncated split flags"))?;
        let split: Vec<bool> = (0..points)
            .map(|i| bits[i / 8] >> (i % 8) & 1 == 1)
            .collect();
        at += points.div_ceil(8);
        let mut rest_at = at;
        let len_bytes = body
            .get(rest_at..rest_at + 8)
            .ok_or_else(|| bad("truncated before the negative set"))?;
        let len = u64::from_le_bytes(len_bytes.try_into().unwrap()) as usize;
        rest_at += 8;
        if body.len() - rest_at != len {
            return Err(bad("the negative set's length does not match the file"));
        }
        let per = positive.channels as usize * 4;
        let count = split.iter().filter(|&&s| s).count();
        let values = format::decode_values(&body[rest_at..], per, count * per, encoding)
            .ok_or_else(|| bad("the negative set does not hold its split points' values"))?;
        let mut negative = positive.clone();
        for (k, i) in (0..points).filter(|&i| split[i]).enumerate() {
            negative.data[i * per..(i + 1) * per].copy_from_slice(&values[k * per..(k + 1) * per]);
        }
        Ok(RegionSolid {
            distance,
            positive,
            negative,
            split,
        })
    }
}

#[cfg(test)]
mod tests;
