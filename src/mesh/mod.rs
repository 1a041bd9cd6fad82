//! Triangle meshes: loading (OBJ through `tobj`, PLY and gzipped PLY through `ply-rs-bw`),
//! validation, and placement in the solid's voxel space. The surface baker lives in [`bake`].
//!
//! Only positions and triangles are read (polygons are fanned into triangles). Open,
//! non-manifold and degenerate meshes are fine for baking; empty meshes, non-finite coordinates
//! and out-of-range indices are errors naming the file.

pub mod bake;
pub mod glb;
pub mod gltf_in;

use crate::error::{Error, Result};
use glam::DVec3;
use std::io::Read;
use std::path::Path;

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Check the mesh is usable; `what` names it in errors.
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.positions.is_empty() || self.triangles.is_empty() {
            return Err(Error::invalid(what, "the mesh has no triangles"));
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(Error::invalid(
                what,
                format!("vertex {i} has a non-finite coordinate"),
            ));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i >= n))
        {
            return Err(Error::invalid(
                what,
                format!("face {t} refers to a vertex beyond the {n} defined"),
            ));
        }
        Ok(())
    }

    /// Smooth unit normals per vertex: the sum of the normals of the triangles around it
    /// weighted by their areas (the unnormalized cross products), in the triangles' winding.
    /// A vertex whose triangles cancel out or have no area gets +z, so every normal is a unit
    /// vector (glTF requires it).
    pub fn vertex_normals(&self) -> Vec<[f32; 3]> {
        let mut sums = vec![DVec3::ZERO; self.positions.len()];
        let at = |i: u32| {
            let p = self.positions[i as usize];
            DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
        };
        for t in &self.triangles {
            let weighted = (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0]));
            for &i in t {
                sums[i as usize] += weighted;
            }
        }
        sums.into_iter()
            .map(|n| {
                let n = n.try_normalize().unwrap_or(DVec3::Z);
                [n.x as f32, n.y as f32, n.z as f32]
            })
            .collect()
    }

    /// Axis-aligned bounds.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.positions {
            let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (lo, hi)
    }
}

/// Maps mesh coordinates into the solid: voxel-space point = (p - origin) * scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub origin: DVec3,
    pub scale: f64,
}

impl Placement {
    /// Scale the mesh so its longest side spans `resolution` voxels, its bounds starting at
    /// voxel 0 (the mesh lies in the box [0, resolution)^3 of the solid).
    pub fn fit(mesh: &Mesh, resolution: u32) -> Placement {
        let (lo, hi) = mesh.bounds();
        let extent = (hi - lo).max_element();
        // Keep the far side inside the last voxel: points exactly at `resolution` would sample
        // voxel `resolution`.
        let scale = if extent > 0.0 {
            (resolution as f64 - 1e-6) / extent
        } else {
            1.0
        };
        Placement { origin: lo, scale }
    }

    pub fn to_voxels(&self, p: [f32; 3]) -> DVec3 {
        (DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - self.origin) * self.scale
    }
}

/// Load an OBJ, PLY, gzipped PLY or glTF (`.glb`, `.gltf`) mesh (by extension).
pub fn load(path: &Path) -> Result<Mesh> {
    let name = path.display().to_string();
    let lower = name.to_ascii_lowercase();
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let mesh = if lower.ends_with(".obj") {
        parse_obj(&bytes, &name)?
    } else if lower.ends_with(".ply") {
        parse_ply(&bytes, &name)?
    } else if lower.ends_with(".ply.gz") {
        let mut raw = Vec::new();
        flate2::read::GzDecoder::new(&bytes[..])
            .read_to_end(&mut raw)
            .map_err(|e| Error::invalid(&name, format!("not a valid gzip file: {e}")))?;
        parse_ply(&raw, &name)?
    } else if lower.ends_with(".glb") || lower.ends_with(".gltf") {
        gltf_in::parse_gltf(&bytes, &name, path.parent())?
    } else {
        return Err(Error::invalid(
            &name,
            "unknown mesh format: expected .obj, .ply, .ply.gz, .glb or .gltf",
        ));
    };
    mesh.validate(&name)?;
    Ok(mesh)
}

/// Parse OBJ text (materials are ignored).
pub fn parse_obj(bytes: &[u8], name: &str) -> Result<Mesh> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut &bytes[..], &options, |_| {
        Err(tobj::LoadError::MaterialParseError)
    })
    .map_err(|e| Error::invalid(name, format!("not a valid OBJ file: {e}")))?;
    let mut mesh = Mesh {
        positions: Vec::new(),
        triangles: Vec::new(),
    };
    for m in models {
        let base = mesh.positions.len() as u32;
        let p = &m.mesh.positions;
        if p.len() % 3 != 0 || m.mesh.indices.len() % 3 != 0 {
            return Err(Error::invalid(name, "malformed OBJ geometry"));
        }
        mesh.positions
            .extend(p.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        for t in m.mesh.indices.chunks_exact(3) {
            let tri = [t[0], t[1], t[2]].map(|i| i.checked_add(base).unwrap_or(u32::MAX));
            mesh.triangles.push(tri);
        }
    }
    Ok(mesh)
}

/// Parse a PLY file (ASCII or binary): `vertex` elements with x, y, z and `face` elements with
/// a `vertex_indices` (or `vertex_index`) list; polygons are fanned into triangles.
pub fn parse_ply(bytes: &[u8], name: &str) -> Result<Mesh> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let bad = |why: String| Error::invalid(name, why);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut &bytes[..])
        .map_err(|e| bad(format!("not a valid PLY file: {e}")))?;
    let scalar = |p: Option<&Property>| -> Option<f32> {
        Some(match p? {
            Property::Float(v) => *v,
            Property::Double(v) => *v as f32,
            Property::Int(v) => *v as f32,
            Property::UInt(v) => *v as f32,
            Property::Short(v) => *v as f32,
            Property::UShort(v) => *v as f32,
            Property::Char(v) => *v as f32,
            Property::UChar(v) => *v as f32,
            _ => return None,
        })
    };
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| bad("no vertex element".into()))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let c = ["x", "y", "z"].map(|k| scalar(v.get(k)));
        match c {
            [Some(x), Some(y), Some(z)] => positions.push([x, y, z]),
            _ => return Err(bad(format!("vertex {i} lacks a numeric x, y or z"))),
        }
    }
    let mut triangles = Vec::new();
    for (i, f) in ply.payload.get("face").into_iter().flatten().enumerate() {
        let list = f.get("vertex_indices").or_else(|| f.get("vertex_index"));
        let idx: Vec<i64> = match list {
            Some(Property::ListInt(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUInt(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListShort(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUShort(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListChar(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUChar(v)) => v.iter().map(|&x| x as i64).collect(),
            _ => return Err(bad(format!("face {i} has no integer vertex_indices list"))),
        };
        if idx.iter().any(|&x| x < 0 || x > u32::MAX as i64) {
            return Err(bad(format!("face {i} has a negative or huge vertex index")));
        }
        for k in 1..idx.len().saturating_sub(1) {
            triangles.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    Ok(Mesh {
        positions,
        triangles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TETRA_OBJ: &str =
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    #[test]
    fn vertex_normals_are_unit_area_weighted_and_point_out() {
        let mesh = parse_obj(TETRA_OBJ.as_bytes(), "tetra").unwrap();
        let normals = mesh.vertex_normals();
        for n in &normals {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6);
        }
        // The corner at the origin: its three faces' outward normals (-x, -y, -z) of equal area.
        let k = -1.0 / 3f32.sqrt();
        for c in normals[0] {
            assert!((c - k).abs() < 1e-6, "{:?}", normals[0]);
        }
        // A vertex on no triangle gets +z, still a unit vector.
        let mut lonely = mesh.clone();
        lonely.positions.push([5.0, 5.0, 5.0]);
        assert_eq!(lonely.vertex_normals()[4], [0.0, 0.0, 1.0]);
    }

    #[test]
    fn obj_and_ply_give_the_same_mesh() {
        let obj = parse_obj(TETRA_OBJ.as_bytes(), "t.obj").unwrap();
        let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                   property float z\nelement face 4\nproperty list uchar int vertex_indices\n\
                   end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
        let ply = parse_ply(ply.as_bytes(), "t.ply").unwrap();
        // tobj renumbers vertices in order of use: compare triangles by their corners.
        let corners = |m: &Mesh| -> Vec<[[f32; 3]; 3]> {
            m.triangles
                .iter()
                .map(|t| t.map(|i| m.positions[i as usize]))
                .collect()
        };
        assert_eq!(corners(&obj), corners(&ply));
        assert_eq!(obj.triangles.len(), 4);
        obj.validate("t").unwrap();
    }

    #[test]
    fn quads_are_fanned_and_bad_meshes_are_refused() {
        let quad = parse_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "q").unwrap();
        assert_eq!(quad.triangles.len(), 2);
        let empty = parse_obj(b"v 0 0 0\n", "e").unwrap();
        assert!(empty.validate("e").is_err());
        let nan = Mesh {
            positions: vec![[0.0, f32::NAN, 0.0]; 3],
            triangles: vec![[0, 1, 2]],
        };
        assert!(nan
            .validate("n")
            .unwrap_err()
            .to_string()
            .contains("non-finite"));
        let out = Mesh {
            positions: vec![[0.0; 3]; 3],
            triangles: vec![[0, 1, 3]],
        };
        assert!(out.validate("o").is_err());
    }

    #[test]
    fn parsers_survive_mutated_input() {
        // Fuzz: random byte mutations and truncations of valid files must give a mesh or an
        // error, never a panic.
        let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                    end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let mut rng = crate::util::hash::SeededRng::new(11);
        for (base, is_obj) in [(TETRA_OBJ.as_bytes(), true), (&ply[..], false)] {
            for _ in 0..1500 {
                let mut b = base.to_vec();
                for _ in 0..1 + rng.below(4) {
                    let i = rng.below(b.len() as u64) as usize;
                    b[i] = rng.below(256) as u8;
                }
                if rng.below(4) == 0 {
                    b.truncate(rng.below(b.len() as u64) as usize);
                }
                let r = if is_obj {
                    parse_obj(&b, "f")
                } else {
                    parse_ply(&b, "f")
                };
                if let Ok(m) = r {
                    let _ = m.validate("f");
                }
            }
        }
    }
}
