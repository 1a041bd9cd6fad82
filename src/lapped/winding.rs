//! The generalized winding number of a triangle mesh (Jacobson et al. 2013): the sum of the
//! signed solid angles its triangles subtend at a point, over 4 pi. It is 1 inside a closed,
//! outward-oriented mesh and 0 outside, and degrades gracefully (values near 0.5 only near the
//! gap) when the mesh has small holes, like the decimated dragon's: the inside test of the
//! tet mesher is `w >= 0.5`.

use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;

pub struct Winding {
    triangles: Vec<[DVec3; 3]>,
}

impl Winding {
    pub fn new(mesh: &Mesh) -> Winding {
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        Winding {
            triangles: mesh.triangles.iter().map(|t| t.map(p)).collect(),
        }
    }

    /// Winding number at `q`.
    pub fn at(&self, q: DVec3) -> f64 {
        let mut omega = 0.0;
        for t in &self.triangles {
            let (a, b, c) = (t[0] - q, t[1] - q, t[2] - q);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            // Van Oosterom and Strackee (1983): tan(Omega / 2) = det / denominator.
            let det = a.dot(b.cross(c));
            let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            omega += 2.0 * det.atan2(den);
        }
        omega / (4.0 * std::f64::consts::PI)
    }

    /// Winding numbers of many points, in parallel (order kept).
    pub fn at_all(&self, points: &[DVec3]) -> Vec<f64> {
        points.par_iter().map(|&q| self.at(q)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An outward-oriented unit cube, optionally without its top face.
    pub fn cube(open_top: bool) -> Mesh {
        let positions = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let mut quads = vec![
            [0, 2, 3, 1], // z = 0, normal -z
            [0, 1, 5, 4], // y = 0
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
            [2, 6, 7, 3], // y = 1
        ];
        if !open_top {
            quads.push([4, 5, 7, 6]); // z = 1
        }
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Mesh {
            positions,
            triangles,
            uvs: None,
            normals: None,
        }
    }

    #[test]
    fn inside_outside_and_holes() {
        let w = Winding::new(&cube(false));
        assert!((w.at(DVec3::splat(0.5)) - 1.0).abs() < 1e-9);
        assert!(w.at(DVec3::splat(1.5)).abs() < 1e-9);
        // Open top: the centre still reads well above 0.5, a point just under the hole near 0.5.
        let open = Winding::new(&cube(true));
        let c = open.at(DVec3::new(0.5, 0.5, 0.3));
        assert!(c > 0.7 && c < 1.0, "{c}");
        assert!(open.at(DVec3::new(0.5, 0.5, 1.5)) < 0.3);
    }
}
