//! The solid exemplar a lapped model pastes, and the alpha masks its patches carry.
//!
//! - [`SolidExemplar`]: a cubic RGBA volume (from an NRRD file, e.g. `solidsynth synth
//!   --tileable`), sampled trilinearly at texture coordinates in [0, 1]^3, wrapping around like
//!   the tileable volume it is, except along s (y) for depth-varying textures, where s is depth
//!   and clamps.
//! - [`Mask`]: a "splotch" (paper 5.2.1): an irregular blob around the cube's centre whose alpha
//!   falls off over [`FALLOFF`] (7.5% of the texture size; the paper found 5-10% best) and is 0
//!   outside; for depth-varying textures the outer, middle and inner masks of 5.2.7: the same
//!   splotch outline in (r, t) over a band of depth s each, open at the model surface (outer)
//!   and the innermost depth (inner) so the skin and the core are fully covered.

use crate::error::{Error, Result};
use crate::util::hash::SeededRng;
use crate::volume::Volume;
use glam::DVec3;

/// Width of the alpha fall-off, as a fraction of the texture size.
pub const FALLOFF: f64 = 0.075;
/// Mask resolution (voxels per side).
pub const MASK_SIZE: u32 = 32;
/// Depth bands [lo, hi] of the outer, middle and inner masks.
pub const LAYER_BANDS: [[f64; 2]; 3] = [[0.0, 0.45], [0.25, 0.75], [0.55, 1.0]];
/// Largest exemplar side accepted.
pub const MAX_EXEMPLAR: u32 = 256;

/// A cubic exemplar as RGBA8.
#[derive(Clone, Debug, PartialEq)]
pub struct SolidExemplar {
    pub size: u32,
    /// RGBA, x fastest.
    pub rgba: Vec<u8>,
}

impl SolidExemplar {
    /// Validate a volume as an exemplar; `what` names it in errors.
    pub fn from_volume(v: &Volume, what: &str) -> Result<SolidExemplar> {
        if v.nx == 0 || v.data.is_empty() {
            return Err(Error::invalid(what, "the exemplar volume is empty"));
        }
        if v.nx != v.ny || v.ny != v.nz {
            return Err(Error::invalid(
                what,
                format!(
                    "the exemplar must be a cube; it is {}x{}x{}",
                    v.nx, v.ny, v.nz
                ),
            ));
        }
        if !(2..=MAX_EXEMPLAR).contains(&v.nx) {
            return Err(Error::invalid(
                what,
                format!(
                    "the exemplar side must be 2..={MAX_EXEMPLAR}; it is {}",
                    v.nx
                ),
            ));
        }
        let c = v.channels as usize;
        if !(1..=4).contains(&c) {
            return Err(Error::invalid(
                what,
                format!("1 to 4 channels expected, found {c}"),
            ));
        }
        v.check(what)?;
        let rgba = v
            .data
            .chunks_exact(c)
            .flat_map(|p| match c {
                1 => [p[0], p[0], p[0], 255],
                2 => [p[0], p[0], p[0], p[1]],
                3 => [p[0], p[1], p[2], 255],
                _ => [p[0], p[1], p[2], p[3]],
            })
            .collect();
        Ok(SolidExemplar { size: v.nx, rgba })
    }

    pub fn to_volume(&self) -> Volume {
        Volume {
            nx: self.size,
            ny: self.size,
            nz: self.size,
            channels: 4,
            data: self.rgba.clone(),
        }
    }

    /// Trilinear RGBA (0..255 floats) at texture coordinate `w`; s clamps when `depth_varying`.
    pub fn sample(&self, w: DVec3, depth_varying: bool) -> [f32; 4] {
        let n = self.size as usize;
        trilinear(n, w, [true, !depth_varying, true], |i| {
            let o = i * 4;
            [
                self.rgba[o] as f32,
                self.rgba[o + 1] as f32,
                self.rgba[o + 2] as f32,
                self.rgba[o + 3] as f32,
            ]
        })
    }

    /// [`Self::sample`]'s colour channels in f32 arithmetic: the inner loop of cuts and bakes.
    pub fn sample_rgb(&self, w: [f32; 3], depth_varying: bool) -> [f32; 3] {
        let n = self.size as usize;
        let (x0, x1, fx) = cell(w[0], n, true);
        let (y0, y1, fy) = cell(w[1], n, !depth_varying);
        let (z0, z1, fz) = cell(w[2], n, true);
        let rgba = &self.rgba;
        let mut out = [0.0f32; 3];
        for (z, wz) in [(z0, 1.0 - fz), (z1, fz)] {
            for (y, wy) in [(y0, 1.0 - fy), (y1, fy)] {
                let row = (z * n + y) * n;
                for (x, wx) in [(x0, 1.0 - fx), (x1, fx)] {
                    let weight = wx * wy * wz;
                    let o = (row + x) * 4;
                    for c in 0..3 {
                        out[c] += weight * rgba[o + c] as f32;
                    }
                }
            }
        }
        out
    }
}

/// The two grid cells a cell-centred linear filter reads along one axis, and the weight of the
/// second: wrapping around or clamped to the edge.
#[inline]
fn cell(x: f32, n: usize, wrap: bool) -> (usize, usize, f32) {
    let x = x * n as f32 - 0.5;
    let f = x.floor();
    let i = f as i64;
    if wrap {
        (
            i.rem_euclid(n as i64) as usize,
            (i + 1).rem_euclid(n as i64) as usize,
            x - f,
        )
    } else {
        (
            i.clamp(0, n as i64 - 1) as usize,
            (i + 1).clamp(0, n as i64 - 1) as usize,
            x - f,
        )
    }
}

/// Trilinear interpolation on an n^3 grid of cell-centred samples; `wrap[a]` wraps axis a,
/// otherwise it clamps to the edge.
fn trilinear(n: usize, w: DVec3, wrap: [bool; 3], at: impl Fn(usize) -> [f32; 4]) -> [f32; 4] {
    let mut idx = [[0usize; 2]; 3];
    let mut frac = [0.0f32; 3];
    for a in 0..3 {
        let x = w[a] * n as f64 - 0.5;
        let f = x.floor();
        frac[a] = (x - f) as f32;
        let i0 = f as i64;
        for (k, slot) in idx[a].iter_mut().enumerate() {
            let i = i0 + k as i64;
            *slot = if wrap[a] {
                i.rem_euclid(n as i64) as usize
            } else {
                i.clamp(0, n as i64 - 1) as usize
            };
        }
    }
    let mut out = [0.0f32; 4];
    for (dz, &z) in idx[2].iter().enumerate() {
        let fz = if dz == 1 { frac[2] } else { 1.0 - frac[2] };
        for (dy, &y) in idx[1].iter().enumerate() {
            let fy = if dy == 1 { frac[1] } else { 1.0 - frac[1] };
            for (dx, &x) in idx[0].iter().enumerate() {
                let fx = if dx == 1 { frac[0] } else { 1.0 - frac[0] };
                let weight = fx * fy * fz;
                if weight == 0.0 {
                    continue;
                }
                let v = at((z * n + y) * n + x);
                for c in 0..4 {
                    out[c] += weight * v[c];
                }
            }
        }
    }
    out
}

/// An alpha mask over texture space, 0 outside [0, 1]^3.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub size: u32,
    pub alpha: Vec<u8>,
}

impl Mask {
    /// Alpha in [0, 1] at `w`: trilinear inside the cube (clamped to the edge voxels), 0
    /// outside it.
    pub fn sample(&self, w: DVec3) -> f32 {
        self.sample_f32(w.as_vec3().to_array())
    }

    /// [`Self::sample`] in f32 arithmetic: the innermost loop of cuts, bakes and the fill.
    pub fn sample_f32(&self, w: [f32; 3]) -> f32 {
        if w.iter().any(|&c| !(0.0..=1.0).contains(&c)) {
            return 0.0;
        }
        let n = self.size as usize;
        let (x0, x1, fx) = cell(w[0], n, false);
        let (y0, y1, fy) = cell(w[1], n, false);
        let (z0, z1, fz) = cell(w[2], n, false);
        let a = &self.alpha;
        let at = |x: usize, y: usize, z: usize| a[(z * n + y) * n + x] as f32;
        let lerp = |p: f32, q: f32, t: f32| p + (q - p) * t;
        let plane = |z: usize| {
            lerp(
                lerp(at(x0, y0, z), at(x1, y0, z), fx),
                lerp(at(x0, y1, z), at(x1, y1, z), fx),
                fy,
            )
        };
        lerp(plane(z0), plane(z1), fz) / 255.0
    }

    /// True where the mask is not zero.
    pub fn touches(&self, w: DVec3) -> bool {
        self.sample(w) > 0.0
    }

    /// Build a mask of `MASK_SIZE`^3 from an alpha function of the voxel centre.
    fn from_fn(f: impl Fn(DVec3) -> f64) -> Mask {
        let n = MASK_SIZE;
        let mut alpha = Vec::with_capacity((n * n * n) as usize);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) / n as f64;
                    alpha.push((f(p).clamp(0.0, 1.0) * 255.0).round() as u8);
                }
            }
        }
        Mask { size: n, alpha }
    }
}

/// Smooth ramp from 0 (at `edge`) to 1 (at `edge + FALLOFF`).
fn ramp(distance_inside: f64) -> f64 {
    let t = (distance_inside / FALLOFF).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The splotch outline: radius as a function of direction, a sum of a few seeded low-frequency
/// waves around 0.36 (so the blob stays within 0.45 of the centre, inside the cube).
struct Outline {
    waves: Vec<(DVec3, f64, f64)>,
}

impl Outline {
    fn new(seed: u64) -> Outline {
        let mut rng = SeededRng::new(seed);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let waves = (0..6)
            .map(|_| {
                let d = DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5).normalize_or(DVec3::X);
                (
                    d * (2.0 + 2.0 * unit()),
                    unit() * std::f64::consts::TAU,
                    0.5 + unit(),
                )
            })
            .collect();
        Outline { waves }
    }
    fn radius(&self, dir: DVec3) -> f64 {
        let total: f64 = self.waves.iter().map(|w| w.2).sum();
        let wobble: f64 = self
            .waves
            .iter()
            .map(|(f, ph, a)| a * (f.dot(dir) + ph).sin())
            .sum::<f64>()
            / total;
        0.36 * (1.0 + 0.2 * wobble)
    }
}

/// The splotch mask of homogeneous textures.
pub fn splotch(seed: u64) -> Mask {
    let outline = Outline::new(seed);
    Mask::from_fn(|p| {
        let d = p - DVec3::splat(0.5);
        let r = d.length();
        let dir = if r > 0.0 { d / r } else { DVec3::X };
        ramp(outline.radius(dir) - r)
    })
}

/// The outer, middle and inner masks of depth-varying textures (s = y is depth).
pub fn layered(seed: u64) -> [Mask; 3] {
    let outline = Outline::new(seed);
    [0, 1, 2].map(|layer| {
        let [lo, hi] = LAYER_BANDS[layer];
        Mask::from_fn(|p| {
            let d = DVec3::new(p.x - 0.5, 0.0, p.z - 0.5);
            let r = d.length();
            let dir = if r > 0.0 { d / r } else { DVec3::X };
            let across = ramp(outline.radius(dir) * 1.15 - r);
            // Open ends: no fall-off at s = 0 for the outer band, at s = 1 for the inner one.
            let below = if layer == 0 { 1.0 } else { ramp(p.y - lo) };
            let above = if layer == 2 { 1.0 } else { ramp(hi - p.y) };
            across * below * above
        })
    })
}

/// The mask layer for a seed at depth `d`: the band whose centre is nearest.
pub fn layer_for_depth(d: f64) -> usize {
    if d < 1.0 / 3.0 {
        0
    } else if d < 2.0 / 3.0 {
        1
    } else {
        2
    }
}

/// A procedural depth-varying exemplar for the kiwi example (texture y = depth: 0 at the skin,
/// 1 at the core; periodic in x and z): a thin brown skin, green flesh with fibres along depth,
/// a band of dark seeds at depth 0.55-0.72, and a pale core.
pub fn kiwi(size: u32) -> SolidExemplar {
    let n = size as usize;
    let mut rgba = Vec::with_capacity(n * n * n * 4);
    // Seeds: hashed centres on a coarse x-z grid inside the seed band, ellipsoids elongated
    // along depth.
    let cells = 7usize;
    let seeds: Vec<[f64; 3]> = (0..cells * cells)
        .map(|k| {
            let h = crate::util::hash::hash32(k as u32 * 7 + 3);
            let jitter = |b: u32| ((h >> b) & 0xff) as f64 / 255.0;
            [
                ((k % cells) as f64 + 0.2 + 0.6 * jitter(0)) / cells as f64,
                0.58 + 0.1 * jitter(8),
                ((k / cells) as f64 + 0.2 + 0.6 * jitter(16)) / cells as f64,
            ]
        })
        .collect();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = [x, y, z].map(|c| (c as f64 + 0.5) / n as f64);
                let d = p[1];
                let fibre = 0.5
                    + 0.5
                        * (std::f64::consts::TAU * 6.0 * p[0]).sin()
                        * (std::f64::consts::TAU * 5.0 * p[2]).cos();
                let mut c = if d < 0.05 {
                    [110.0, 80.0, 45.0]
                } else if d > 0.82 {
                    [235.0, 235.0, 200.0]
                } else {
                    let g = 150.0 + 60.0 * d + 20.0 * fibre;
                    [90.0 + 40.0 * d, g, 40.0 + 30.0 * fibre]
                };
                for s in &seeds {
                    // Periodic distance in x and z.
                    let wrap = |a: f64, b: f64| {
                        let t = (a - b).abs();
                        t.min(1.0 - t)
                    };
                    let (dx, dy, dz) = (wrap(p[0], s[0]), (p[1] - s[1]).abs(), wrap(p[2], s[2]));
                    if (dx / 0.03).powi(2) + (dy / 0.07).powi(2) + (dz / 0.03).powi(2) < 1.0 {
                        c = [25.0, 20.0, 15.0];
                    }
                }
                rgba.extend_from_slice(&[c[0] as u8, c[1] as u8, c[2] as u8, 255]);
            }
        }
    }
    SolidExemplar { size, rgba }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splotch_is_opaque_inside_and_zero_at_the_faces() {
        let m = splotch(1);
        assert!((m.sample(DVec3::splat(0.5)) - 1.0).abs() < 1e-6);
        assert_eq!(m.sample(DVec3::new(0.02, 0.5, 0.5)), 0.0);
        assert_eq!(m.sample(DVec3::new(1.2, 0.5, 0.5)), 0.0);
        // Fall-off: some voxels strictly between 0 and 255.
        assert!(m.alpha.iter().any(|&a| a > 20 && a < 235));
    }

    #[test]
    fn layered_masks_cover_skin_and_core() {
        let [outer, middle, inner] = layered(1);
        let at = |s: f64| DVec3::new(0.5, s, 0.5);
        assert!(outer.sample(at(0.0)) > 0.99 && outer.sample(at(0.7)) == 0.0);
        assert!(middle.sample(at(0.5)) > 0.99 && middle.sample(at(0.05)) == 0.0);
        assert!(inner.sample(at(1.0)) > 0.99 && inner.sample(at(0.3)) == 0.0);
        for d in [0.0, 0.2, 0.34, 0.5, 0.66, 0.8, 1.0] {
            let m = [&outer, &middle, &inner][layer_for_depth(d)];
            assert!(m.sample(at(d)) > 0.9, "depth {d}");
        }
    }

    #[test]
    fn exemplar_checks_and_wraps() {
        let mut v = Volume::new(4, 4, 4, 1);
        v.at_mut(0, 0, 0)[0] = 200;
        let e = SolidExemplar::from_volume(&v, "e.nrrd").unwrap();
        // Cell centre of voxel 0 and its wrapped twin at 1 + 1/8.
        let a = e.sample(DVec3::splat(0.125), false);
        let b = e.sample(DVec3::splat(1.125), false);
        assert_eq!(a, b);
        assert_eq!(a[0], 200.0);
        let bad = Volume::new(4, 4, 3, 1);
        let err = SolidExemplar::from_volume(&bad, "e.nrrd")
            .unwrap_err()
            .to_string();
        assert!(err.contains("cube"), "{err}");
    }
}
