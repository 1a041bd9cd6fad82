//! The tensor field that orients and scales the pasted patches (paper 5.2.2), from the
//! constraints file ([`Constraints`]) instead of the paper's sketching interface.
//!
//! - Depth (1-b, 2-a, 2-b): thin-plate RBF interpolation in 3D (phi(r) = r^3 plus a linear
//!   polynomial, Turk and O'Brien 1999) of 0 on the surface (boundary vertices, subsampled) and
//!   1 along the `inner` strokes and on the surface inside the `inner_regions` balls (the paper's
//!   painted surface regions: e.g. the cut face of a cake).
//! - Vectors and scales: Laplacian smoothing on the tet mesh vertices (eq. 1) with soft
//!   constraints (eq. 2) at the stroke segments' midpoints (value: the segment's direction) and
//!   at the scale points, as one sparse least-squares solve (normal equations, sparse Cholesky).
//!   For 2-a/2-b the weights are depth-aware, w_ij ~ exp(-((d_i - d_j)/sigma)^2). The paper
//!   writes exp(-(d_i - d_j)^2) with depth in [0, 1]; neighbouring vertices differ by a few
//!   hundredths, which makes those weights uniform to 0.1%, so we divide by sigma, the mean
//!   depth difference along mesh edges (our choice, so the weights do what the paper intends).
//! - Axes: the primary direction (depth gradient, or the strokes for 1-a) is the texture's s (y)
//!   axis; for 2-a/2-b the secondary (strokes, orthogonalized) is r (x) and t = r x s. Types 0
//!   and 1-* leave the free axes to a random rotation per patch.
//! - Scale: 1-b and 2-b take 1 / |grad depth| (paper 5.2.7), the others the constraints or the
//!   default scale.

mod constraints;

pub use constraints::{Constraints, TextureType};

use super::tetmesh::TetMesh;
use crate::error::{Error, Result};
use glam::DVec3;
use nalgebra::{DMatrix, DVector};
use nalgebra_sparse::{factorization::CscCholesky, CooMatrix, CscMatrix};

/// Per-vertex field values.
#[derive(Clone, Debug)]
pub struct Field {
    pub kind: TextureType,
    /// Unit primary direction (texture s), where the type has one.
    pub primary: Option<Vec<DVec3>>,
    /// Unit secondary direction (texture r), orthogonal to the primary, for 2-a/2-b.
    pub secondary: Option<Vec<DVec3>>,
    /// World size of one exemplar cube.
    pub scale: Vec<f64>,
    /// Depth in [0, 1] (1-b, 2-a, 2-b).
    pub depth: Option<Vec<f64>>,
}

/// Per-tet frame: the three texture axes in world space, scaled (|axis| = world length of one
/// texture unit), with `free` set when the r/t (and for type 0 all) axes are to be randomized.
#[derive(Clone, Copy, Debug)]
pub struct TetFrame {
    pub r: DVec3,
    pub s: DVec3,
    pub t: DVec3,
    pub depth: f64,
}

/// Weight of the soft constraints against the Laplacian rows.
const CONSTRAINT_WEIGHT: f64 = 10.0;
/// Most surface points used as RBF centres (the dense solve is cubic in their number).
const MAX_RBF_SURFACE: usize = 400;

impl Field {
    pub fn compute(mesh: &TetMesh, c: &Constraints, default_scale: f64) -> Result<Field> {
        let n = mesh.vertices.len();
        let ring = mesh.vertex_neighbors();
        let depth = if c.kind.uses_depth() {
            Some(depth_rbf(
                mesh,
                &c.inner,
                &c.inner_regions,
                &c.outer_regions,
            )?)
        } else {
            None
        };
        let sigma = depth.as_ref().map_or(1.0, |(d, _)| depth_sigma(d, &ring));
        let weights = |i: usize, j: usize| -> f64 {
            match (&depth, c.kind.full_tensor()) {
                (Some((d, _)), true) => (-((d[i] - d[j]) / sigma).powi(2)).exp(),
                _ => 1.0,
            }
        };
        let locate = Locator::new(mesh);
        // Directions from strokes: constraints at segment midpoints.
        let stroke_field = if c.kind.uses_strokes() {
            let mut cons = Vec::new();
            for s in &c.strokes {
                for w in s.windows(2) {
                    let d = w[1] - w[0];
                    if d.length() > 0.0 {
                        cons.push((locate.at(0.5 * (w[0] + w[1])), d.normalize().to_array()));
                    }
                }
            }
            let v = laplacian_fit(mesh, &ring, &weights, &cons, 3)?;
            Some(
                (0..n)
                    .map(|i| DVec3::new(v[(i, 0)], v[(i, 1)], v[(i, 2)]))
                    .collect::<Vec<_>>(),
            )
        } else {
            None
        };
        let base = c.scale.unwrap_or(default_scale);
        let mut scale = if c.scales.is_empty() {
            vec![base; n]
        } else {
            let cons: Vec<_> = c
                .scales
                .iter()
                .map(|(p, s)| (locate.at(*p), [*s, 0.0, 0.0]))
                .collect();
            let v = laplacian_fit(mesh, &ring, &weights, &cons, 1)?;
            let floor = c.scales.iter().map(|s| s.1).fold(f64::INFINITY, f64::min) * 0.25;
            (0..n).map(|i| v[(i, 0)].max(floor)).collect()
        };
        let (primary, secondary) = match (&depth, c.kind) {
            (None, TextureType::Isotropic) => (None, None),
            (None, _) => (
                Some(
                    stroke_field
                        .unwrap()
                        .iter()
                        .map(|v| v.normalize_or(DVec3::Y))
                        .collect(),
                ),
                None,
            ),
            (Some((_, grad)), kind) => {
                let p: Vec<DVec3> = grad.iter().map(|g| g.normalize_or(DVec3::Y)).collect();
                let sec = stroke_field.map(|v| {
                    v.iter()
                        .zip(&p)
                        .map(|(v, p)| {
                            let o = *v - v.dot(*p) * *p;
                            if o.length() > 1e-9 {
                                o.normalize()
                            } else {
                                p.any_orthonormal_vector()
                            }
                        })
                        .collect()
                });
                if kind.depth_varying() {
                    // Paper 5.2.7: the texture scale is the inverse of |grad depth|, bounded so
                    // the singular centre of radial fields does not blow it up.
                    let extent = mesh_extent(mesh);
                    scale = grad
                        .iter()
                        .map(|g| (1.0 / g.length().max(1e-9)).clamp(0.05 * extent, 2.0 * extent))
                        .collect();
                }
                (Some(p), sec)
            }
        };
        Ok(Field {
            kind: c.kind,
            primary,
            secondary,
            scale,
            depth: depth.map(|(d, _)| d),
        })
    }

    /// The frame of tet `t`: the average of its vertices' values (paper 5.2.2), made
    /// orthonormal again, with placeholder axes where the type leaves them free.
    pub fn tet_frame(&self, mesh: &TetMesh, t: usize) -> TetFrame {
        let v = mesh.tets[t].map(|i| i as usize);
        let avg = |f: &dyn Fn(usize) -> DVec3| v.iter().map(|&i| f(i)).sum::<DVec3>() / 4.0;
        let scale = v.iter().map(|&i| self.scale[i]).sum::<f64>() / 4.0;
        let depth = self
            .depth
            .as_ref()
            .map_or(0.0, |d| v.iter().map(|&i| d[i]).sum::<f64>() / 4.0);
        let s = match &self.primary {
            Some(p) => avg(&|i| p[i]).normalize_or(DVec3::Y),
            None => DVec3::Y,
        };
        let r = match &self.secondary {
            Some(q) => {
                let q = avg(&|i| q[i]);
                let o = q - q.dot(s) * s;
                o.try_normalize()
                    .unwrap_or_else(|| s.any_orthonormal_vector())
            }
            None => {
                let o = DVec3::X - DVec3::X.dot(s) * s;
                o.try_normalize()
                    .unwrap_or_else(|| s.any_orthonormal_vector())
            }
        };
        let t_axis = r.cross(s);
        TetFrame {
            r: r * scale,
            s: s * scale,
            t: t_axis * scale,
            depth,
        }
    }
}

fn mesh_extent(mesh: &TetMesh) -> f64 {
    let lo = mesh.vertices.iter().fold(DVec3::INFINITY, |a, b| a.min(*b));
    let hi = mesh
        .vertices
        .iter()
        .fold(DVec3::NEG_INFINITY, |a, b| a.max(*b));
    (hi - lo).max_element()
}

fn depth_sigma(d: &[f64], ring: &[Vec<u32>]) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, r) in ring.iter().enumerate() {
        for &j in r {
            sum += (d[i] - d[j as usize]).abs();
            count += 1;
        }
    }
    (sum / count.max(1) as f64).max(1e-6)
}

/// Point location for constraints: the tet whose barycentre is nearest (paper 5.2.2) and the
/// barycentric coordinates of the point in it.
struct Locator<'a> {
    mesh: &'a TetMesh,
    centroids: Vec<DVec3>,
}

impl<'a> Locator<'a> {
    fn new(mesh: &'a TetMesh) -> Self {
        let centroids = (0..mesh.tets.len()).map(|t| mesh.centroid(t)).collect();
        Locator { mesh, centroids }
    }
    fn at(&self, p: DVec3) -> (usize, [f64; 4]) {
        let t = (0..self.centroids.len())
            .min_by(|&a, &b| {
                (self.centroids[a] - p)
                    .length_squared()
                    .total_cmp(&(self.centroids[b] - p).length_squared())
            })
            .unwrap();
        (t, self.mesh.barycentric(t, p))
    }
}

/// Minimize sum_i |x_i - sum_j w_ij x_j|^2 + W^2 sum_c |lambda_c . x - value_c|^2 for `dims`
/// columns at once (sparse normal equations, Cholesky).
fn laplacian_fit(
    mesh: &TetMesh,
    ring: &[Vec<u32>],
    weight: &dyn Fn(usize, usize) -> f64,
    constraints: &[((usize, [f64; 4]), [f64; 3])],
    dims: usize,
) -> Result<DMatrix<f64>> {
    let n = mesh.vertices.len();
    let rows = n + constraints.len();
    let mut a = CooMatrix::new(rows, n);
    let mut b = DMatrix::zeros(rows, dims);
    for (i, r) in ring.iter().enumerate() {
        a.push(i, i, 1.0);
        let total: f64 = r.iter().map(|&j| weight(i, j as usize)).sum();
        for &j in r {
            a.push(i, j as usize, -weight(i, j as usize) / total);
        }
    }
    for (k, ((t, lambda), value)) in constraints.iter().enumerate() {
        for (c, &v) in mesh.tets[*t].iter().enumerate() {
            a.push(n + k, v as usize, CONSTRAINT_WEIGHT * lambda[c]);
        }
        for d in 0..dims {
            b[(n + k, d)] = CONSTRAINT_WEIGHT * value[d];
        }
    }
    let a = CscMatrix::from(&a);
    let at = a.transpose();
    let ata = &at * &a;
    let atb = &at * &b;
    let chol = CscCholesky::factor(&ata).map_err(|e| {
        Error::invalid(
            "--field",
            format!("the constraints do not determine the field ({e:?})"),
        )
    })?;
    Ok(chol.solve(&atb))
}

/// Depth at every vertex and its gradient, by thin-plate RBF interpolation of 0 on the boundary
/// vertices (1 inside the inner regions) and 1 along the inner polylines.
fn depth_rbf(
    mesh: &TetMesh,
    inner: &[Vec<DVec3>],
    regions: &[(DVec3, f64)],
    outer: &[(DVec3, f64)],
) -> Result<(Vec<f64>, Vec<DVec3>)> {
    let neighbors = mesh.face_neighbors();
    let mut surface: Vec<u32> = mesh
        .boundary_faces(&neighbors)
        .iter()
        .flat_map(|(f, _)| *f)
        .collect();
    surface.sort_unstable();
    surface.dedup();
    // Painted (depth 1) and unpainted (depth 0) surface vertices, each subsampled to at most
    // MAX_RBF_SURFACE / 2 centres (so a small painted region keeps all its vertices).
    let painted = |v: &u32| {
        let p = mesh.vertices[*v as usize];
        regions.iter().any(|(c, r)| (p - *c).length() <= *r)
    };
    let in_any = |v: u32, balls: &[(DVec3, f64)]| {
        let p = mesh.vertices[v as usize];
        balls.iter().any(|(c, r)| (p - *c).length() <= *r)
    };
    let (ones, rest): (Vec<u32>, Vec<u32>) = surface.iter().partition(|v| painted(v));
    // With outer regions, only they are depth 0; otherwise the whole unpainted surface is.
    let zeros: Vec<u32> = if outer.is_empty() {
        rest
    } else {
        rest.into_iter().filter(|&v| in_any(v, outer)).collect()
    };
    for (name, balls, set) in [
        ("inner_regions", regions, &ones),
        ("outer_regions", outer, &zeros),
    ] {
        for (i, (c, r)) in balls.iter().enumerate() {
            if !set.iter().any(|&v| in_any(v, &[(*c, *r)])) {
                return Err(Error::invalid(
                    "--field",
                    format!(
                        "depth.{name}[{i}] (centre ({}, {}, {}), radius {r}) contains no \
                         surface vertex",
                        c.x, c.y, c.z
                    ),
                ));
            }
        }
    }
    let mut centers: Vec<(DVec3, f64)> = Vec::new();
    for (set, value) in [(&zeros, 0.0), (&ones, 1.0)] {
        let stride = set.len().div_ceil(MAX_RBF_SURFACE / 2).max(1);
        centers.extend(
            set.iter()
                .step_by(stride)
                .map(|&v| (mesh.vertices[v as usize], value)),
        );
    }
    // Inner strokes, resampled at about the mesh's edge length.
    let edge = mesh_extent(mesh) / 24.0;
    for line in inner {
        centers.push((line[0], 1.0));
        for w in line.windows(2) {
            let steps = ((w[1] - w[0]).length() / edge).ceil().max(1.0) as usize;
            for k in 1..=steps {
                centers.push((w[0].lerp(w[1], k as f64 / steps as f64), 1.0));
            }
        }
    }
    let m = centers.len();
    let phi = |r: f64| r * r * r;
    let mut a = DMatrix::zeros(m + 4, m + 4);
    let mut rhs = DVector::zeros(m + 4);
    for i in 0..m {
        for j in 0..m {
            a[(i, j)] = phi((centers[i].0 - centers[j].0).length());
        }
        let p = centers[i].0;
        for (k, v) in [1.0, p.x, p.y, p.z].into_iter().enumerate() {
            a[(i, m + k)] = v;
            a[(m + k, i)] = v;
        }
        rhs[i] = centers[i].1;
    }
    let sol = a.lu().solve(&rhs).ok_or_else(|| {
        Error::invalid(
            "--field",
            "the depth constraints are degenerate (coincident points?)",
        )
    })?;
    let mut depth = Vec::with_capacity(mesh.vertices.len());
    let mut grad = Vec::with_capacity(mesh.vertices.len());
    for &p in &mesh.vertices {
        let mut d = sol[m] + sol[m + 1] * p.x + sol[m + 2] * p.y + sol[m + 3] * p.z;
        let mut g = DVec3::new(sol[m + 1], sol[m + 2], sol[m + 3]);
        for (i, (c, _)) in centers.iter().enumerate() {
            let diff = p - *c;
            let r = diff.length();
            d += sol[i] * phi(r);
            // grad r^3 = 3 r (p - c).
            g += sol[i] * 3.0 * r * diff;
        }
        depth.push(d.clamp(0.0, 1.0));
        // The depth increases inward; its gradient points inward.
        grad.push(g);
    }
    Ok((depth, grad))
}
