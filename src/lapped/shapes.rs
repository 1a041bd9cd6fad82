//! Built-in closed meshes for the examples and tests: a UV sphere (the "kiwi") and a bent
//! cylinder (a tube along a quarter circle), both outward oriented and watertight.

use crate::mesh::Mesh;
use std::f32::consts::PI;

/// The unit sphere with `segments` around and `rings` from pole to pole.
///
/// # Panics
/// With fewer than 3 segments or 2 rings (no closed surface).
pub fn sphere(segments: u32, rings: u32) -> Mesh {
    assert!(
        segments >= 3 && rings >= 2,
        "a sphere needs at least 3 segments and 2 rings; asked for {segments} and {rings}"
    );
    let mut positions = vec![[0.0, 0.0, 1.0f32]];
    for r in 1..rings {
        let th = PI * r as f32 / rings as f32;
        for s in 0..segments {
            let ph = 2.0 * PI * s as f32 / segments as f32;
            positions.push([th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()]);
        }
    }
    positions.push([0.0, 0.0, -1.0]);
    let last = positions.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, ring(1, s), ring(1, s + 1)]);
        triangles.push([last, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s + 1),
                ring(r + 1, s),
            );
            triangles.push([a, d, c]);
            triangles.push([a, c, b]);
        }
    }
    Mesh {
        positions,
        triangles,
        uvs: None,
        normals: None,
    }
}

/// A tube of radius `radius` whose axis is a quarter circle of radius `bend` in the xy plane
/// (from (bend, 0, 0) to (0, bend, 0)), capped at both ends.
///
/// # Panics
/// With fewer than 3 vertices `around` or 1 step `along` (no closed surface).
pub fn bent_cylinder(radius: f32, bend: f32, around: u32, along: u32) -> Mesh {
    assert!(
        around >= 3 && along >= 1,
        "a tube needs at least 3 vertices around and 1 step along; asked for {around} and {along}"
    );
    let mut positions = Vec::new();
    for a in 0..=along {
        let t = 0.5 * PI * a as f32 / along as f32;
        // Axis point and the frame (radial outward in-plane, z) of the cross-section.
        let (c, s) = (t.cos(), t.sin());
        for k in 0..around {
            let ph = 2.0 * PI * k as f32 / around as f32;
            let (u, w) = (ph.cos() * radius, ph.sin() * radius);
            positions.push([(bend + u) * c, (bend + u) * s, w]);
        }
    }
    let ring = |a: u32, k: u32| a * around + k % around;
    let mut triangles = Vec::new();
    for a in 0..along {
        for k in 0..around {
            let (p, q, r, s) = (
                ring(a, k),
                ring(a, k + 1),
                ring(a + 1, k + 1),
                ring(a + 1, k),
            );
            triangles.push([p, q, r]);
            triangles.push([p, r, s]);
        }
    }
    // Caps: a centre vertex at each end.
    let start = positions.len() as u32;
    positions.push([bend, 0.0, 0.0]);
    positions.push([0.0, bend, 0.0]);
    for k in 0..around {
        triangles.push([start, ring(0, k + 1), ring(0, k)]);
        triangles.push([start + 1, ring(along, k), ring(along, k + 1)]);
    }
    // The windings above face inward; turn them all outward.
    for t in &mut triangles {
        t.swap(1, 2);
    }
    Mesh {
        positions,
        triangles,
        uvs: None,
        normals: None,
    }
}

/// OBJ text of a mesh (positions and faces only).
pub fn obj_text(mesh: &Mesh) -> String {
    let mut s = String::new();
    for p in &mesh.positions {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lapped::winding::Winding;
    use glam::DVec3;

    #[test]
    fn shapes_are_closed_and_outward() {
        let s = Winding::new(&sphere(24, 12));
        assert!((s.at(DVec3::ZERO) - 1.0).abs() < 1e-6);
        let c = Winding::new(&bent_cylinder(0.3, 1.0, 16, 16));
        let mid = std::f64::consts::FRAC_PI_4;
        assert!((c.at(DVec3::new(mid.cos(), mid.sin(), 0.0)) - 1.0).abs() < 1e-6);
        assert!(c.at(DVec3::ZERO).abs() < 1e-6);
    }

    #[test]
    #[should_panic(expected = "at least 3 segments and 2 rings")]
    fn a_sphere_of_one_ring_is_refused() {
        sphere(8, 1);
    }
}
