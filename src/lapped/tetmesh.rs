//! Tetrahedral meshes: storage, quality measures, adjacency, boundary faces and the fixed
//! per-tet sample points of the coverage test.
//!
//! Tets are positively oriented: (b - a) . ((c - a) x (d - a)) > 0.

use glam::DVec3;
use std::collections::HashMap;

#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    pub vertices: Vec<DVec3>,
    pub tets: Vec<[u32; 4]>,
}

/// Quality summary of a tet mesh (what `lapped fill` reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    pub tets: usize,
    pub vertices: usize,
    /// Smallest and largest dihedral angle over all tets, degrees.
    pub min_dihedral: f64,
    pub max_dihedral: f64,
    /// Tets with non-positive signed volume (must be 0).
    pub inverted: usize,
    pub volume: f64,
}

/// A tet's four triangular faces, each listed so that its normal (right-hand rule) points out of
/// a positively oriented tet; face k is the one opposite vertex k.
pub const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

impl TetMesh {
    pub fn corners(&self, t: usize) -> [DVec3; 4] {
        self.tets[t].map(|i| self.vertices[i as usize])
    }

    /// Six times the signed volume.
    pub fn signed_volume6(p: &[DVec3; 4]) -> f64 {
        (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0]))
    }

    pub fn centroid(&self, t: usize) -> DVec3 {
        let p = self.corners(t);
        (p[0] + p[1] + p[2] + p[3]) / 4.0
    }

    /// The six dihedral angles of a tet, degrees.
    pub fn dihedrals(p: &[DVec3; 4]) -> [f64; 6] {
        // The dihedral at edge (i, j) is the angle between the two faces containing it, i.e.
        // pi minus the angle between their outward normals.
        let normal = |f: [usize; 3]| (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]).normalize();
        let n = FACES.map(normal);
        let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
        pairs.map(|(a, b)| {
            let c = n[a].dot(n[b]).clamp(-1.0, 1.0);
            180.0 - c.acos().to_degrees()
        })
    }

    pub fn quality(&self) -> Quality {
        let mut q = Quality {
            tets: self.tets.len(),
            vertices: self.vertices.len(),
            min_dihedral: f64::INFINITY,
            max_dihedral: 0.0,
            inverted: 0,
            volume: 0.0,
        };
        for t in 0..self.tets.len() {
            let p = self.corners(t);
            let v6 = Self::signed_volume6(&p);
            if v6 <= 0.0 {
                q.inverted += 1;
                continue;
            }
            q.volume += v6 / 6.0;
            for a in Self::dihedrals(&p) {
                q.min_dihedral = q.min_dihedral.min(a);
                q.max_dihedral = q.max_dihedral.max(a);
            }
        }
        q
    }

    /// For each tet and each face k (opposite vertex k), the tet across it, or `u32::MAX` on the
    /// boundary.
    pub fn face_neighbors(&self) -> Vec<[u32; 4]> {
        let mut open: HashMap<[u32; 3], (u32, usize)> = HashMap::new();
        let mut out = vec![[u32::MAX; 4]; self.tets.len()];
        for (t, tet) in self.tets.iter().enumerate() {
            for (k, f) in FACES.iter().enumerate() {
                let mut key = f.map(|i| tet[i]);
                key.sort_unstable();
                match open.remove(&key) {
                    Some((u, j)) => {
                        out[t][k] = u;
                        out[u as usize][j] = t as u32;
                    }
                    None => {
                        open.insert(key, (t as u32, k));
                    }
                }
            }
        }
        out
    }

    /// The boundary triangles (outward facing) with the tet each belongs to, in tet order.
    pub fn boundary_faces(&self, neighbors: &[[u32; 4]]) -> Vec<([u32; 3], u32)> {
        let mut out = Vec::new();
        for (t, tet) in self.tets.iter().enumerate() {
            for (k, f) in FACES.iter().enumerate() {
                if neighbors[t][k] == u32::MAX {
                    out.push((f.map(|i| tet[i]), t as u32));
                }
            }
        }
        out
    }

    /// Per vertex, the area-weighted mean normal of the boundary `faces` around it (zero for
    /// interior vertices): smooth shading of the surface.
    pub fn surface_normals(&self, faces: &[([u32; 3], u32)]) -> Vec<DVec3> {
        let mut normals = vec![DVec3::ZERO; self.vertices.len()];
        for (f, _) in faces {
            let p = f.map(|v| self.vertices[v as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            for &v in f {
                normals[v as usize] += n;
            }
        }
        normals.iter().map(|n| n.normalize_or_zero()).collect()
    }

    /// Each vertex's one-ring (vertices sharing an edge), sorted.
    pub fn vertex_neighbors(&self) -> Vec<Vec<u32>> {
        let mut ring = vec![Vec::new(); self.vertices.len()];
        for tet in &self.tets {
            for a in 0..4 {
                for b in 0..4 {
                    if a != b {
                        ring[tet[a] as usize].push(tet[b]);
                    }
                }
            }
        }
        for r in &mut ring {
            r.sort_unstable();
            r.dedup();
        }
        ring
    }

    /// Gradients of the four barycentric coordinate functions of tet `t` (constant in the tet):
    /// lambda_k(p) = lambda_k(v0) + grad_k . (p - v0). They sum to zero.
    pub fn barycentric_gradients(&self, t: usize) -> [DVec3; 4] {
        let p = self.corners(t);
        let v6 = Self::signed_volume6(&p);
        FACES.map(|f| {
            // The gradient of lambda_k is the inward normal of the face opposite k, scaled by
            // area / (3 volume): -(cross of the outward-oriented face) / (6 V).
            -(p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]) / v6
        })
    }

    /// Barycentric coordinates of `q` in tet `t`.
    pub fn barycentric(&self, t: usize, q: DVec3) -> [f64; 4] {
        let p = self.corners(t);
        let g = self.barycentric_gradients(t);
        let mut l = [0.0; 4];
        for k in 1..4 {
            l[k] = g[k].dot(q - p[0]);
        }
        l[0] = 1.0 - l[1] - l[2] - l[3];
        l
    }
}

/// The fixed sample points of the coverage test (paper 5.2.6: 165 per tet): the barycentric grid
/// (i, j, k, l) / 8 with i + j + k + l = 8, which is exactly 165 points.
pub fn coverage_samples() -> Vec<[f64; 4]> {
    const N: usize = 8;
    let mut out = Vec::with_capacity(165);
    for i in 0..=N {
        for j in 0..=N - i {
            for k in 0..=N - i - j {
                let l = N - i - j - k;
                out.push([i, j, k, l].map(|x| x as f64 / N as f64));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> TetMesh {
        TetMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            tets: vec![[0, 1, 2, 3]],
        }
    }

    #[test]
    fn coverage_grid_has_165_points() {
        let s = coverage_samples();
        assert_eq!(s.len(), 165);
        assert!(s
            .iter()
            .all(|b| (b.iter().sum::<f64>() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn unit_tet_quality_and_barycentrics() {
        let m = unit_tet();
        let q = m.quality();
        assert_eq!(q.inverted, 0);
        assert!((q.volume - 1.0 / 6.0).abs() < 1e-12);
        // The corner tet's dihedrals: three right angles and three of acos(1/sqrt 3)... the
        // smallest is 54.7 degrees, the largest 90.
        assert!(
            (q.min_dihedral - 54.7356).abs() < 1e-3,
            "{}",
            q.min_dihedral
        );
        assert!((q.max_dihedral - 90.0).abs() < 1e-9);
        let b = m.barycentric(0, DVec3::new(0.1, 0.2, 0.3));
        assert!(
            (b[0] - 0.4).abs() < 1e-12 && (b[3] - 0.3).abs() < 1e-12,
            "{b:?}"
        );
        let n = m.face_neighbors();
        assert_eq!(m.boundary_faces(&n).len(), 4);
    }
}
