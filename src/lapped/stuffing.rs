//! Tetrahedral meshing of a closed (or nearly closed) triangle mesh by isosurface stuffing on a
//! body-centred cubic lattice (Labelle and Shewchuk 2007).
//!
//! - Inside test: the generalized winding number ([`super::winding`]) at each lattice vertex;
//!   f = 0.5 - w is negative inside, so small holes in the input do not break it.
//! - Cut points where f changes sign along a lattice edge, by bisection on f.
//! - Warping: a lattice vertex within alpha of an edge's length of a cut point on one of its
//!   edges moves onto the nearest such cut point and becomes a zero (alpha_long = 0.24999 for
//!   the black edges of length h, alpha_short = 0.41189 for the red ones of length h sqrt(3)/2:
//!   the paper's values).
//! - Stencils: each BCC tet with an inside vertex is clipped to the inside: a tet, a pyramid or a
//!   prism, split into tets. Where a quadrilateral face must be split, the diagonal through its
//!   smallest global vertex id is used (Dompierre et al. 1999); that choice depends only on the
//!   face, so the two tets sharing it always agree and the mesh is conforming. This replaces the
//!   paper's parity rule, so its dihedral bounds (10.7-164.8 degrees) are not guaranteed; the
//!   measured angles are reported by `lapped fill`.

use super::tetmesh::TetMesh;
use super::winding::Winding;
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

const ALPHA_LONG: f64 = 0.24999;
const ALPHA_SHORT: f64 = 0.41189;
const BISECTION_STEPS: usize = 10;

/// Lattice resolution limits (cells along the longest side of the mesh's bounds).
pub const MIN_RESOLUTION: u32 = 2;
pub const MAX_RESOLUTION: u32 = 96;

struct Lattice {
    origin: DVec3,
    h: f64,
    /// Cells per axis (centres); corners are `n + 1` per axis.
    n: [usize; 3],
}

impl Lattice {
    fn corners(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }
    fn corner(&self, i: usize, j: usize, k: usize) -> u32 {
        (i + (self.n[0] + 1) * (j + (self.n[1] + 1) * k)) as u32
    }
    fn center(&self, i: usize, j: usize, k: usize) -> u32 {
        (self.corners() + i + self.n[0] * (j + self.n[1] * k)) as u32
    }
    fn count(&self) -> usize {
        self.corners() + self.n[0] * self.n[1] * self.n[2]
    }
    fn position(&self, id: u32) -> DVec3 {
        let id = id as usize;
        let (c, off) = if id < self.corners() {
            (self.n.map(|x| x + 1), 0.0)
        } else {
            (self.n, 0.5)
        };
        let local = if id < self.corners() {
            id
        } else {
            id - self.corners()
        };
        let i = local % c[0];
        let j = (local / c[0]) % c[1];
        let k = local / (c[0] * c[1]);
        self.origin + DVec3::new(i as f64 + off, j as f64 + off, k as f64 + off) * self.h
    }

    /// Every BCC tet: two face-adjacent centres and an edge of their shared square face.
    fn tets(&self) -> Vec<[u32; 4]> {
        let n = self.n;
        let mut out = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let c1 = self.center(i, j, k);
                    for axis in 0..3 {
                        let mut next = [i, j, k];
                        next[axis] += 1;
                        if next[axis] >= n[axis] {
                            continue;
                        }
                        let c2 = self.center(next[0], next[1], next[2]);
                        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                        let corner = |db: usize, dc: usize| {
                            let mut p = [i, j, k];
                            p[axis] += 1;
                            p[b] += db;
                            p[c] += dc;
                            self.corner(p[0], p[1], p[2])
                        };
                        let square = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                        for e in 0..4 {
                            out.push([c1, c2, square[e], square[(e + 1) % 4]]);
                        }
                    }
                }
            }
        }
        out
    }

    /// Lattice edges of a tet as (a, b, long?): centre-centre and corner-corner are long.
    fn is_long(&self, a: u32, b: u32) -> bool {
        let corners = self.corners() as u32;
        (a < corners) == (b < corners)
    }
}

/// Statistics of a meshing run.
#[derive(Clone, Copy, Debug, Default)]
pub struct StuffingStats {
    pub lattice_vertices: usize,
    pub warped: usize,
    pub dropped_degenerate: usize,
}

/// Mesh the inside of `mesh` with about `resolution` lattice cells along its longest side.
pub fn stuff(mesh: &Mesh, resolution: u32, what: &str) -> Result<(TetMesh, StuffingStats)> {
    if !(MIN_RESOLUTION..=MAX_RESOLUTION).contains(&resolution) {
        return Err(Error::invalid(
            format!("--resolution {resolution}"),
            format!("must be {MIN_RESOLUTION}..={MAX_RESOLUTION}"),
        ));
    }
    mesh.validate(what)?;
    let (lo, hi) = mesh.bounds();
    let extent = (hi - lo).max_element();
    if extent.is_nan() || extent <= 0.0 {
        return Err(Error::invalid(
            what,
            "the mesh is flat: it encloses no volume",
        ));
    }
    let h = extent / resolution as f64;
    // One cell of margin on each side so every boundary square lies outside the surface.
    let origin = lo - DVec3::splat(h);
    let n = ((hi - lo) / h).to_array().map(|e| e.ceil() as usize + 2);
    let lattice = Lattice { origin, h, n };
    let winding = Winding::new(mesh);

    let count = lattice.count();
    let mut positions: Vec<DVec3> = (0..count as u32).map(|i| lattice.position(i)).collect();
    let mut f: Vec<f64> = winding
        .at_all(&positions)
        .into_iter()
        .map(|w| 0.5 - w)
        .collect();
    if f.iter().all(|&v| v >= 0.0) {
        return Err(Error::invalid(
            what,
            "the mesh encloses no volume at this resolution (no lattice point is inside; \
             is it a closed surface? try a higher --resolution)",
        ));
    }

    // All tets and their sign-changing edges; cut points by bisection, in parallel.
    let bcc = lattice.tets();
    let mut crossing: Vec<(u32, u32)> = bcc
        .iter()
        .flat_map(|t| {
            let mut e = Vec::new();
            for a in 0..4 {
                for b in a + 1..4 {
                    let (u, v) = (t[a].min(t[b]), t[a].max(t[b]));
                    if (f[u as usize] < 0.0) != (f[v as usize] < 0.0) {
                        e.push((u, v));
                    }
                }
            }
            e
        })
        .collect();
    crossing.sort_unstable();
    crossing.dedup();
    let cut_params: Vec<f64> = crossing
        .par_iter()
        .map(|&(u, v)| {
            let (pu, pv) = (positions[u as usize], positions[v as usize]);
            let inside_u = f[u as usize] < 0.0;
            let (mut a, mut b) = (0.0f64, 1.0f64);
            for _ in 0..BISECTION_STEPS {
                let m = 0.5 * (a + b);
                let inside_m = winding.at(pu.lerp(pv, m)) >= 0.5;
                if inside_m == inside_u {
                    a = m;
                } else {
                    b = m;
                }
            }
            0.5 * (a + b)
        })
        .collect();

    // Warping: each vertex takes the nearest violating cut point on its edges.
    let mut best: Vec<Option<(f64, DVec3)>> = vec![None; count];
    for (&(u, v), &t) in crossing.iter().zip(&cut_params) {
        let alpha = if lattice.is_long(u, v) {
            ALPHA_LONG
        } else {
            ALPHA_SHORT
        };
        let p = positions[u as usize].lerp(positions[v as usize], t);
        for (vertex, d) in [(u, t), (v, 1.0 - t)] {
            if d < alpha {
                let slot = &mut best[vertex as usize];
                if slot.is_none_or(|(bd, _)| d < bd) {
                    *slot = Some((d, p));
                }
            }
        }
    }
    let mut stats = StuffingStats {
        lattice_vertices: count,
        ..Default::default()
    };
    for (id, b) in best.iter().enumerate() {
        if let Some((_, p)) = b {
            positions[id] = *p;
            f[id] = 0.0;
            stats.warped += 1;
        }
    }
    let sign = |id: u32| {
        let v = f[id as usize];
        if v < 0.0 {
            -1
        } else if v > 0.0 {
            1
        } else {
            0
        }
    };
    // Cut points surviving the warp (both ends unwarped), as new vertex ids.
    let mut cut_vertex: HashMap<(u32, u32), u32> = HashMap::new();
    for (&(u, v), &t) in crossing.iter().zip(&cut_params) {
        if sign(u) * sign(v) < 0 {
            cut_vertex.insert((u, v), positions.len() as u32);
            positions.push(positions[u as usize].lerp(positions[v as usize], t));
        }
    }
    let cut = |a: u32, b: u32| cut_vertex[&(a.min(b), a.max(b))];

    let mut pieces: Vec<[u32; 4]> = Vec::new();
    for t in &bcc {
        let (mut ins, mut zeros, mut outs) = (Vec::new(), Vec::new(), Vec::new());
        for &v in t {
            match sign(v) {
                -1 => ins.push(v),
                0 => zeros.push(v),
                _ => outs.push(v),
            }
        }
        match (ins.len(), outs.len()) {
            (0, 0) => {
                // Every vertex warped onto the surface: keep the tet if its centre is inside.
                let c = t.iter().map(|&v| positions[v as usize]).sum::<DVec3>() / 4.0;
                if winding.at(c) >= 0.5 {
                    pieces.push(*t);
                }
            }
            (0, _) => {}
            (_, 0) => pieces.push(*t),
            (1, _) => {
                let a = ins[0];
                let mut tet = vec![a];
                tet.extend(&zeros);
                tet.extend(outs.iter().map(|&o| cut(a, o)));
                pieces.push([tet[0], tet[1], tet[2], tet[3]]);
            }
            (2, 2) => {
                let (a, b, c, d) = (ins[0], ins[1], outs[0], outs[1]);
                prism(
                    [a, cut(a, c), cut(a, d)],
                    [b, cut(b, c), cut(b, d)],
                    &mut pieces,
                );
            }
            (2, 1) => {
                let (a, b, c, z) = (ins[0], ins[1], outs[0], zeros[0]);
                pyramid(z, [a, b, cut(b, c), cut(a, c)], &mut pieces);
            }
            (3, 1) => {
                let (a, b, c, d) = (ins[0], ins[1], ins[2], outs[0]);
                prism([a, b, c], [cut(a, d), cut(b, d), cut(c, d)], &mut pieces);
            }
            _ => unreachable!("four vertices"),
        }
    }

    // Orient positively, drop degenerate slivers, compact the vertex ids in order of first use.
    let tiny = 1e-9 * h * h * h;
    let mut remap = vec![u32::MAX; positions.len()];
    let mut vertices = Vec::new();
    let mut tets = Vec::with_capacity(pieces.len());
    for mut t in pieces {
        let p = t.map(|v| positions[v as usize]);
        let v6 = TetMesh::signed_volume6(&p);
        if v6.abs() <= tiny {
            stats.dropped_degenerate += 1;
            continue;
        }
        if v6 < 0.0 {
            t.swap(2, 3);
        }
        tets.push(t.map(|v| {
            if remap[v as usize] == u32::MAX {
                remap[v as usize] = vertices.len() as u32;
                vertices.push(positions[v as usize]);
            }
            remap[v as usize]
        }));
    }
    if tets.is_empty() {
        return Err(Error::invalid(
            what,
            "the mesh encloses no volume at this resolution (try a higher --resolution)",
        ));
    }
    Ok((TetMesh { vertices, tets }, stats))
}

/// A triangular prism (p0 p1 p2 below q0 q1 q2, pi - qi its vertical edges) as three tets whose
/// quad-face diagonals all pass through the smallest id on each face.
fn prism(mut p: [u32; 3], mut q: [u32; 3], out: &mut Vec<[u32; 4]>) {
    let min = *p.iter().chain(&q).min().unwrap();
    if q.contains(&min) {
        std::mem::swap(&mut p, &mut q);
    }
    let r = p.iter().position(|&v| v == min).unwrap();
    p.rotate_left(r);
    q.rotate_left(r);
    // The two quads at p0 are split through p0, so (p0, q0, q1, q2) is a tet; what is left is a
    // pyramid with apex p0 over the quad (p1, p2, q2, q1).
    out.push([p[0], q[0], q[1], q[2]]);
    pyramid(p[0], [p[1], p[2], q[2], q[1]], out);
}

/// A pyramid over the quad `a b c d` (cyclic) as two tets, split along the quad's diagonal
/// through its smallest id.
fn pyramid(apex: u32, quad: [u32; 4], out: &mut Vec<[u32; 4]>) {
    let [a, b, c, d] = quad;
    let min = *quad.iter().min().unwrap();
    if min == a || min == c {
        out.push([apex, a, b, c]);
        out.push([apex, a, c, d]);
    } else {
        out.push([apex, b, c, d]);
        out.push([apex, b, d, a]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_is_filled_conformingly_with_no_inverted_tets() {
        let (m, stats) = stuff(&super::super::shapes::sphere(32, 16), 10, "sphere").unwrap();
        let q = m.quality();
        assert_eq!(q.inverted, 0);
        assert_eq!(stats.dropped_degenerate, 0);
        // Volume close to the polyhedral sphere's (about 4.19 for the unit ball).
        assert!((q.volume - 4.0).abs() < 0.3, "volume {}", q.volume);
        assert!(q.min_dihedral > 3.0 && q.max_dihedral < 177.0, "{q:?}");
        // Conforming: every interior face is shared by exactly two tets, so the boundary is a
        // closed 2-manifold: Euler characteristic 2.
        let nb = m.face_neighbors();
        let faces = m.boundary_faces(&nb);
        let mut edges = std::collections::HashSet::new();
        let mut verts = std::collections::HashSet::new();
        for (f, _) in &faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                edges.insert((a.min(b), a.max(b)));
                verts.insert(a);
            }
        }
        let euler = verts.len() as i64 - edges.len() as i64 + faces.len() as i64;
        assert_eq!(euler, 2);
        // Boundary vertices lie on the surface (within the bisection's precision).
        for v in &verts {
            let r = m.vertices[*v as usize].length();
            assert!((r - 1.0).abs() < 0.05, "boundary vertex at radius {r}");
        }
    }

    #[test]
    fn flat_or_open_meshes_are_refused() {
        let flat = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            uvs: None,
            normals: None,
        };
        let err = stuff(&flat, 8, "flat.obj").unwrap_err().to_string();
        assert!(
            err.contains("flat.obj") && err.contains("no volume"),
            "{err}"
        );
        assert!(stuff(&super::super::shapes::sphere(8, 4), 1, "s").is_err());
    }
}
