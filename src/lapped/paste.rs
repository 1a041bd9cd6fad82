//! The pasting loop (paper 5.2.3-5.2.7): pick a random uncovered seed tet, map it into texture
//! space along its tensor, grow a clump of tets the mask reaches, optimize the clump's texture
//! coordinates so every tet's tensor axes map to the texture axes (sparse least squares), and
//! accumulate the mask's alpha at each tet's 165 sample points until every tet is covered.
//!
//! Deterministic: one seeded generator drives every random choice, in a fixed order.

use super::exemplar::{layer_for_depth, Mask};
use super::field::{Field, TetFrame, TextureType};
use super::tetmesh::{coverage_samples, TetMesh};
use crate::error::{Error, Result};
use crate::util::hash::SeededRng;
use glam::{DMat3, DQuat, DVec3};
use nalgebra::DMatrix;
use nalgebra_sparse::{factorization::CscCholesky, CooMatrix, CscMatrix};
use std::collections::{HashMap, HashSet, VecDeque};

/// One pasted patch: its clump and the texture coordinates of the clump's vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// Index of the mask (0 for homogeneous textures; 0, 1, 2 = outer, middle, inner).
    pub mask: u8,
    pub tets: Vec<u32>,
    /// Texture coordinate of each vertex the clump uses.
    pub coords: HashMap<u32, DVec3>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FillStats {
    pub patches: usize,
    /// Tets declared covered after being the seed three times without reaching full alpha
    /// (tets too large for the patch scale).
    pub forced: usize,
    /// Clump extensions after optimization (paper 5.2.5, last paragraph).
    pub extensions: usize,
    pub mean_clump_tets: f64,
}

/// Weight of the seed's positional constraint against the axis rows.
const POSITION_WEIGHT: f64 = 10.0;
/// Primary axes closer than this (|cos|) count as "not markedly different" (45 degrees).
const SIMILAR_COS: f64 = std::f64::consts::FRAC_1_SQRT_2;
const MAX_EXTENSION_ROUNDS: usize = 3;
const SEED_ATTEMPTS: u8 = 3;

fn unit(rng: &mut SeededRng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

/// A uniformly random rotation (Shoemake 1992).
fn random_rotation(rng: &mut SeededRng) -> DQuat {
    let (u1, u2, u3) = (unit(rng), unit(rng), unit(rng));
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    DQuat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    )
    .normalize()
}

/// How a patch orients every tet of its clump.
enum Orientation {
    /// Type 0: one rotation for the whole patch.
    Rotation(DQuat),
    /// Types 1-*: the tet's primary axis, the patch's secondary projected onto its plane.
    Secondary(DVec3),
    /// Types 2-*: the field's frame as is.
    Field,
}

struct Filler<'a> {
    mesh: &'a TetMesh,
    field: &'a Field,
    masks: &'a [Mask],
    frames: Vec<TetFrame>,
    neighbors: Vec<[u32; 4]>,
    grads: Vec<[DVec3; 4]>,
    probe: Vec<[f64; 4]>,
    samples: Vec<[f64; 4]>,
}

impl Filler<'_> {
    fn depth_varying(&self) -> bool {
        self.field.kind.depth_varying()
    }

    /// The texture axes of tet `t` under a patch's orientation (columns: world vectors of one
    /// texture unit along r, s, t).
    fn axes(&self, t: usize, o: &Orientation) -> [DVec3; 3] {
        let f = &self.frames[t];
        match o {
            Orientation::Rotation(q) => {
                let scale = f.s.length();
                [
                    *q * DVec3::X * scale,
                    *q * DVec3::Y * scale,
                    *q * DVec3::Z * scale,
                ]
            }
            Orientation::Secondary(r0) => {
                let scale = f.s.length();
                let s = f.s / scale;
                let r = (*r0 - r0.dot(s) * s)
                    .try_normalize()
                    .unwrap_or_else(|| s.any_orthonormal_vector());
                [r * scale, f.s, r.cross(s) * scale]
            }
            Orientation::Field => [f.r, f.s, f.t],
        }
    }

    fn similar(&self, seed: usize, t: usize, o: &Orientation) -> bool {
        let (a, b) = (self.axes(seed, o), self.axes(t, o));
        let ratio = b[1].length() / a[1].length();
        if !(0.5..=2.0).contains(&ratio) {
            return false;
        }
        let cos = |x: DVec3, y: DVec3| x.normalize().dot(y.normalize()).abs();
        match o {
            Orientation::Rotation(_) => true,
            Orientation::Secondary(_) => cos(a[1], b[1]) >= SIMILAR_COS,
            Orientation::Field => cos(a[1], b[1]) >= SIMILAR_COS && cos(a[0], b[0]) >= SIMILAR_COS,
        }
    }

    fn vertex_depth(&self, v: u32) -> f64 {
        self.field.depth.as_ref().map_or(0.0, |d| d[v as usize])
    }

    /// Does the mask reach any probe point of a tet mapped by `map`?
    fn touches(&self, mask: &Mask, map: &dyn Fn([f64; 4]) -> DVec3) -> bool {
        self.probe.iter().any(|b| mask.touches(map(*b)))
    }

    /// Paste one patch seeded at `seed`.
    fn paste(&self, seed: usize, rng: &mut SeededRng, stats: &mut FillStats) -> Result<Patch> {
        let orientation = match self.field.kind {
            TextureType::Isotropic => Orientation::Rotation(random_rotation(rng)),
            TextureType::Oriented | TextureType::Layered => {
                let f = &self.frames[seed];
                let s = f.s.normalize();
                let angle = unit(rng) * std::f64::consts::TAU;
                Orientation::Secondary(DQuat::from_axis_angle(s, angle) * f.r.normalize())
            }
            TextureType::Tensor | TextureType::TensorLayered => Orientation::Field,
        };
        let seed_depth = self.frames[seed].depth;
        let mask_index = if self.depth_varying() {
            layer_for_depth(seed_depth)
        } else {
            0
        };
        let mask = &self.masks[mask_index];
        let center = DVec3::new(
            0.5,
            if self.depth_varying() {
                seed_depth
            } else {
                0.5
            },
            0.5,
        );

        // The seed's affine map (5.2.4): axes to the unit texture axes, centroid to `center`.
        let axes = self.axes(seed, &orientation);
        let inverse = DMat3::from_cols(axes[0], axes[1], axes[2]).inverse();
        let c = self.mesh.centroid(seed);
        let seed_map = |p: DVec3, depth: f64| {
            let mut w = inverse * (p - c) + center;
            if self.depth_varying() {
                w.y = depth;
            }
            w
        };
        let tet_point = |t: usize, b: [f64; 4]| {
            let v = self.mesh.tets[t];
            let p = (0..4)
                .map(|k| self.mesh.vertices[v[k] as usize] * b[k])
                .sum::<DVec3>();
            let d = (0..4).map(|k| self.vertex_depth(v[k]) * b[k]).sum::<f64>();
            (p, d)
        };

        // Grow the clump breadth-first over face neighbours.
        let mut in_clump = HashSet::from([seed]);
        let mut clump = vec![seed];
        let mut queue = VecDeque::from([seed]);
        while let Some(t) = queue.pop_front() {
            for &n in &self.neighbors[t] {
                let n = n as usize;
                if n == u32::MAX as usize || in_clump.contains(&n) {
                    continue;
                }
                if !self.similar(seed, n, &orientation) {
                    continue;
                }
                let map = |b: [f64; 4]| {
                    let (p, d) = tet_point(n, b);
                    seed_map(p, d)
                };
                if self.touches(mask, &map) {
                    in_clump.insert(n);
                    clump.push(n);
                    queue.push_back(n);
                }
            }
        }

        // Optimize (5.2.5), then add tets the warped mask now reaches and optimize again.
        let mut coords;
        let mut round = 0;
        loop {
            coords = self.optimize(&clump, seed, &orientation, center)?;
            round += 1;
            if round > MAX_EXTENSION_ROUNDS {
                break;
            }
            let mut added = Vec::new();
            for &t in &clump {
                let w = self.mesh.tets[t].map(|v| coords[&v]);
                let g = &self.grads[t];
                let p0 = self.mesh.vertices[self.mesh.tets[t][0] as usize];
                for &n in &self.neighbors[t] {
                    let n = n as usize;
                    if n == u32::MAX as usize
                        || in_clump.contains(&n)
                        || !self.similar(seed, n, &orientation)
                    {
                        continue;
                    }
                    // Map n's probe points through t's affine map, extended beyond t.
                    let map = |b: [f64; 4]| {
                        let (p, d) = tet_point(n, b);
                        let mut l = [0.0; 4];
                        for k in 1..4 {
                            l[k] = g[k].dot(p - p0);
                        }
                        l[0] = 1.0 - l[1] - l[2] - l[3];
                        let mut x = (0..4).map(|k| w[k] * l[k]).sum::<DVec3>();
                        if self.depth_varying() {
                            x.y = d;
                        }
                        x
                    };
                    if self.touches(mask, &map) {
                        in_clump.insert(n);
                        added.push(n);
                    }
                }
            }
            if added.is_empty() {
                break;
            }
            stats.extensions += added.len();
            clump.extend(added);
        }
        Ok(Patch {
            mask: mask_index as u8,
            tets: clump.iter().map(|&t| t as u32).collect(),
            coords,
        })
    }

    /// Texture coordinates of the clump's vertices minimizing the axis differences d_r, d_s, d_t
    /// of every tet (5.2.5) with the seed's centroid held at `center`. Each coordinate is an
    /// independent least-squares problem with the same matrix: one factorization, three solves.
    fn optimize(
        &self,
        clump: &[usize],
        seed: usize,
        o: &Orientation,
        center: DVec3,
    ) -> Result<HashMap<u32, DVec3>> {
        let mut index: HashMap<u32, usize> = HashMap::new();
        let mut verts = Vec::new();
        for &t in clump {
            for &v in &self.mesh.tets[t] {
                index.entry(v).or_insert_with(|| {
                    verts.push(v);
                    verts.len() - 1
                });
            }
        }
        let rows = 3 * clump.len() + 1;
        let mut a = CooMatrix::new(rows, verts.len());
        let mut b = DMatrix::zeros(rows, 3);
        for (i, &t) in clump.iter().enumerate() {
            let axes = self.axes(t, o);
            let g = &self.grads[t];
            for (axis, x) in axes.iter().enumerate() {
                let row = 3 * i + axis;
                for (k, &v) in self.mesh.tets[t].iter().enumerate() {
                    a.push(row, index[&v], g[k].dot(*x));
                }
                b[(row, axis)] = 1.0;
            }
        }
        let last = rows - 1;
        for &v in &self.mesh.tets[seed] {
            a.push(last, index[&v], POSITION_WEIGHT * 0.25);
        }
        for c in 0..3 {
            b[(last, c)] = POSITION_WEIGHT * center[c];
        }
        let a = CscMatrix::from(&a);
        let at = a.transpose();
        let chol = CscCholesky::factor(&(&at * &a))
            .map_err(|e| Error::Internal(format!("lapped: clump solve failed ({e:?})")))?;
        let x = chol.solve(&(&at * &b));
        Ok(verts
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let mut w = DVec3::new(x[(i, 0)], x[(i, 1)], x[(i, 2)]);
                if self.depth_varying() {
                    w.y = self.vertex_depth(v);
                }
                (v, w)
            })
            .collect())
    }
}

/// Fill the mesh with patches until every tet is covered. `progress(covered, total)` is called
/// after each patch.
pub fn fill(
    mesh: &TetMesh,
    field: &Field,
    masks: &[Mask],
    seed: u64,
    progress: &dyn Fn(usize, usize),
) -> Result<(Vec<Patch>, FillStats)> {
    let frames = (0..mesh.tets.len())
        .map(|t| field.tet_frame(mesh, t))
        .collect();
    let grads = (0..mesh.tets.len())
        .map(|t| mesh.barycentric_gradients(t))
        .collect();
    // Probe points for "partially inside the mask": the order-4 barycentric grid (35 points).
    let probe = coverage_samples()
        .into_iter()
        .filter(|b| {
            b.iter()
                .all(|x| ((x * 8.0).round() as u32).is_multiple_of(2))
        })
        .collect();
    let filler = Filler {
        mesh,
        field,
        masks,
        frames,
        neighbors: mesh.face_neighbors(),
        grads,
        probe,
        samples: coverage_samples(),
    };
    let n = mesh.tets.len();
    let s = filler.samples.len();
    let mut alpha = vec![0u8; n * s];
    let mut covered = vec![false; n];
    let mut attempts = vec![0u8; n];
    let mut uncovered: Vec<u32> = (0..n as u32).collect();
    let mut rng = SeededRng::new(seed);
    let mut patches = Vec::new();
    let mut stats = FillStats::default();
    let limit = 20 * n + 1000;
    let mut clump_total = 0usize;
    while !uncovered.is_empty() {
        if patches.len() >= limit {
            return Err(Error::invalid(
                "--scale",
                format!("{limit} patches did not cover the model; the scale is too small"),
            ));
        }
        let seed_tet = uncovered[rng.below(uncovered.len() as u64) as usize] as usize;
        let patch = filler.paste(seed_tet, &mut rng, &mut stats)?;
        let mask = &masks[patch.mask as usize];
        for &t in &patch.tets {
            let t = t as usize;
            let w = mesh.tets[t].map(|v| patch.coords[&v]);
            let acc = &mut alpha[t * s..(t + 1) * s];
            for (slot, b) in acc.iter_mut().zip(&filler.samples) {
                if *slot == 255 {
                    continue;
                }
                let p = w[0] * b[0] + w[1] * b[1] + w[2] * b[2] + w[3] * b[3];
                let a = (mask.sample(p) * 255.0).round() as u32;
                *slot = (*slot as u32 + a).min(255) as u8;
            }
            if acc.iter().all(|&a| a == 255) {
                covered[t] = true;
            }
        }
        attempts[seed_tet] = attempts[seed_tet].saturating_add(1);
        if !covered[seed_tet] && attempts[seed_tet] >= SEED_ATTEMPTS {
            covered[seed_tet] = true;
            stats.forced += 1;
        }
        clump_total += patch.tets.len();
        patches.push(patch);
        uncovered.retain(|&t| !covered[t as usize]);
        progress(n - uncovered.len(), n);
    }
    stats.patches = patches.len();
    stats.mean_clump_tets = clump_total as f64 / patches.len().max(1) as f64;
    Ok((patches, stats))
}
