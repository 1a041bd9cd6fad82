//! Triangle meshes: loading (OBJ through `tobj`, PLY and gzipped PLY through `ply-rs-bw`),
//! validation, and placement in the solid's voxel space. The surface baker lives in [`bake`].
//!
//! Positions, triangles (polygons are fanned into triangles) and, where the file has them for
//! every corner, texture coordinates and normals are read. Open, non-manifold and degenerate
//! meshes are fine for baking; empty meshes, non-finite coordinates and out-of-range indices are
//! errors naming the file.

pub mod bake;
pub mod dilate;
pub mod glb;
pub mod gltf_in;
pub mod pack;
mod ply_in;
pub mod uv_raster;

use crate::error::{Error, Result};
use glam::DVec3;
use std::path::Path;

pub use ply_in::{parse_ply, parse_ply_gz};

/// The Stanford bunny as an OBJ file (`assets/meshes/bunny.obj`): the viewer's built-in mesh and
/// the surface job of `bench compare`.
pub const BUNNY_OBJ: &[u8] = include_bytes!("../../assets/meshes/bunny.obj");

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, its corners' texture coordinates from the file (u right, v down: glTF's
    /// convention; OBJ's and PLY's v is flipped on reading), when every corner has one.
    pub uvs: Option<Vec<[[f32; 2]; 3]>>,
    /// Per triangle, its corners' normals from the file, when every corner has one.
    pub normals: Option<Vec<[[f32; 3]; 3]>>,
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
                format!(
                    "vertex {i} has a non-finite coordinate (or one beyond f32's range, \
                     about 3.4e38)"
                ),
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
        // Nothing to texture or fill: every triangle a point or a segment.
        let at = |i: u32| glam::Vec3::from(self.positions[i as usize]).as_dvec3();
        if self
            .triangles
            .iter()
            .all(|t| (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0])) == DVec3::ZERO)
        {
            return Err(Error::invalid(
                what,
                "every triangle has zero area (its corners coincide or lie on a line)",
            ));
        }
        if let Some(uvs) = &self.uvs {
            self.check_corner_values(what, uvs, "texture coordinate")?;
        }
        if let Some(normals) = &self.normals {
            self.check_corner_values(what, normals, "normal")?;
        }
        Ok(())
    }

    /// Per-corner `values` (named `kind`): one triple per triangle, every number finite.
    fn check_corner_values<const N: usize>(
        &self,
        what: &str,
        values: &[[[f32; N]; 3]],
        kind: &str,
    ) -> Result<()> {
        if values.len() != self.triangles.len() {
            return Err(Error::invalid(
                what,
                format!(
                    "{} triangles' {kind}s for {} triangles",
                    values.len(),
                    self.triangles.len()
                ),
            ));
        }
        match values
            .iter()
            .position(|c| c.iter().flatten().any(|v| !v.is_finite()))
        {
            Some(t) => Err(Error::invalid(
                what,
                format!("face {t} has a non-finite {kind}"),
            )),
            None => Ok(()),
        }
    }

    /// Per triangle, its corners' unit normals: the file's (normalized; a zero one becomes the
    /// area-weighted normal of its vertex) when it has them, else [`Self::vertex_normals`].
    ///
    /// # Panics
    /// If a triangle refers to a vertex beyond `positions` (a mesh [`Self::validate`] refuses).
    pub fn corner_normals(&self) -> Vec<[[f32; 3]; 3]> {
        let smooth = self.vertex_normals();
        let from_vertex = |t: &[u32; 3]| t.map(|i| smooth[i as usize]);
        match &self.normals {
            None => self.triangles.iter().map(from_vertex).collect(),
            Some(given) => self
                .triangles
                .iter()
                .zip(given)
                .map(|(t, n)| {
                    let fallback = from_vertex(t);
                    let mut out = [[0.0; 3]; 3];
                    for k in 0..3 {
                        let v = glam::Vec3::from(n[k]);
                        out[k] = v.try_normalize().map_or(fallback[k], |v| v.to_array());
                    }
                    out
                })
                .collect(),
        }
    }

    /// Smooth unit normals per vertex: the sum of the normals of the triangles around it
    /// weighted by their areas (the unnormalized cross products), in the triangles' winding.
    /// A vertex whose triangles cancel out or have no area gets +z, so every normal is a unit
    /// vector (glTF requires it).
    ///
    /// # Panics
    /// If a triangle refers to a vertex beyond `positions` (a mesh [`Self::validate`] refuses).
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
    let bytes = crate::io::input::read(path)?;
    let mesh = if lower.ends_with(".obj") {
        parse_obj(&bytes, &name)?
    } else if lower.ends_with(".ply") {
        parse_ply(&bytes, &name)?
    } else if lower.ends_with(".ply.gz") {
        ply_in::parse_ply_gz(&bytes, &name)?
    } else if lower.ends_with(".glb") || lower.ends_with(".gltf") {
        gltf_in::parse_gltf(&bytes, &name, path.parent())?
    } else {
        return Err(Error::invalid(
            &name,
            "unknown mesh format: expected .obj, .ply, .ply.gz, .glb or .gltf",
        ));
    };
    Ok(mesh)
}

/// Parse OBJ text (materials are ignored). The mesh passes [`Mesh::validate`].
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
    if let Some((line, word)) = obj_unknown_statement(bytes) {
        return Err(Error::invalid(
            name,
            format!("line {line} begins with {word:?}, which is not an OBJ statement"),
        ));
    }
    if let Some((line, corners)) = obj_short_face(bytes) {
        return Err(Error::invalid(
            name,
            format!("the face on line {line} has {corners} vertices; a face needs at least 3"),
        ));
    }
    let mut mesh = Mesh {
        positions: Vec::new(),
        triangles: Vec::new(),
        uvs: None,
        normals: None,
    };
    // Texture coordinates and normals are kept only when every face of every object has them.
    let mut uvs = Some(Vec::new());
    let mut normals = Some(Vec::new());
    let malformed = || Error::invalid(name, "malformed OBJ geometry");
    for m in models {
        let base = mesh.positions.len() as u32;
        let m = &m.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(malformed());
        }
        mesh.positions
            .extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        for t in m.indices.chunks_exact(3) {
            let tri = [t[0], t[1], t[2]].map(|i| i.saturating_add(base));
            mesh.triangles.push(tri);
        }
        let flip_v = |uv: [f32; 2]| [uv[0], 1.0 - uv[1]];
        add_obj_corners(
            &mut uvs,
            &m.indices,
            &m.texcoord_indices,
            &m.texcoords,
            flip_v,
        )
        .ok_or_else(malformed)?;
        add_obj_corners(
            &mut normals,
            &m.indices,
            &m.normal_indices,
            &m.normals,
            |n| n,
        )
        .ok_or_else(malformed)?;
    }
    // (tobj fills a corner without them with index 0: the face lines decide.)
    let (all_uvs, all_normals) = obj_corners_have_attributes(bytes);
    mesh.uvs = uvs.filter(|u| all_uvs && !u.is_empty());
    mesh.normals = normals.filter(|n| all_normals && !n.is_empty());
    mesh.validate(name)?;
    Ok(mesh)
}

/// Append to `out` the per-corner values (N floats each, mapped by `map`) that `indices` pick
/// from `values`, one triple per triangle of `faces`; `out` becomes None when the object has no
/// such index for every corner. None when an index is out of range.
fn add_obj_corners<const N: usize>(
    out: &mut Option<Vec<[[f32; N]; 3]>>,
    faces: &[u32],
    indices: &[u32],
    values: &[f32],
    map: impl Fn([f32; N]) -> [f32; N],
) -> Option<()> {
    if indices.len() != faces.len() {
        *out = None;
    }
    let Some(out) = out else { return Some(()) };
    for t in indices.chunks_exact(3) {
        let mut corners = [[0.0f32; N]; 3];
        for (corner, &i) in corners.iter_mut().zip(t) {
            let i = i as usize;
            let v = values.get(N * i..N * i + N)?;
            *corner = map(v.try_into().expect("N values"));
        }
        out.push(corners);
    }
    Some(())
}

/// The statements of the OBJ format (geometry, grouping, display and free-form ones): a line
/// beginning with anything else means the file is not OBJ, which the parser would not say.
const OBJ_STATEMENTS: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "fo",
    "l",
    "p",
    "g",
    "o",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "call",
    "csh",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "maplib",
    "usemap",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
];

/// The first line (1-based) that begins with a word no OBJ statement has, and the word.
fn obj_unknown_statement(bytes: &[u8]) -> Option<(usize, String)> {
    String::from_utf8_lossy(bytes)
        .lines()
        .enumerate()
        .find_map(|(i, line)| {
            let word = line
                .trim_start_matches('\u{feff}')
                .split_whitespace()
                .next()?;
            let known = word.starts_with('#') || OBJ_STATEMENTS.contains(&word);
            (!known).then(|| (i + 1, word.chars().take(20).collect()))
        })
}

/// The first `f` line with fewer than three corners (its 1-based number and corner count): the
/// OBJ parser would make a degenerate triangle of it.
fn obj_short_face(bytes: &[u8]) -> Option<(usize, usize)> {
    String::from_utf8_lossy(bytes)
        .lines()
        .enumerate()
        .find_map(|(i, line)| {
            let mut words = line.split_whitespace();
            (words.next() == Some("f"))
                .then(|| words.count())
                .filter(|&corners| corners < 3)
                .map(|corners| (i + 1, corners))
        })
}

/// Whether every corner of every `f` line names a texture coordinate (`v/vt`) and a normal
/// (`v/vt/vn` or `v//vn`).
fn obj_corners_have_attributes(bytes: &[u8]) -> (bool, bool) {
    let (mut uvs, mut normals) = (true, true);
    for line in String::from_utf8_lossy(bytes).lines() {
        let mut words = line.split_whitespace();
        if words.next() != Some("f") {
            continue;
        }
        for corner in words {
            let mut parts = corner.split('/');
            parts.next();
            uvs &= parts.next().is_some_and(|p| !p.is_empty());
            normals &= parts.next().is_some_and(|p| !p.is_empty());
        }
    }
    (uvs, normals)
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
    fn a_file_that_is_not_obj_is_refused_by_its_first_foreign_line() {
        let text = format!("\u{feff}# made by hand\no tetra\n{TETRA_OBJ}\nthis is not obj\n");
        let e = parse_obj(text.as_bytes(), "t.obj").unwrap_err().to_string();
        assert!(e.contains("line 12 begins with \"this\""), "{e}");
        let fine = format!("\u{feff}# made by hand\r\no tetra\r\ns off\n{TETRA_OBJ}");
        assert_eq!(
            parse_obj(fine.as_bytes(), "t.obj").unwrap().triangles.len(),
            4
        );
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
    fn texture_coordinates_and_normals_are_read_per_corner() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0.25\nvn 0 0 2\nf 1/1/1 2/2/1 3/1/1\n";
        let mesh = parse_obj(obj.as_bytes(), "t.obj").unwrap();
        // OBJ's v grows upwards: stored from the top.
        assert_eq!(mesh.uvs, Some(vec![[[0.0, 1.0], [1.0, 0.75], [0.0, 1.0]]]));
        assert_eq!(mesh.normals, Some(vec![[[0.0, 0.0, 2.0]; 3]]));
        assert_eq!(mesh.corner_normals()[0], [[0.0, 0.0, 1.0]; 3]);
        // A face without them: none kept.
        let partial = format!("{obj}v 1 1 0\nf 2 4 3\n");
        let mesh = parse_obj(partial.as_bytes(), "t.obj").unwrap();
        assert_eq!((mesh.uvs, mesh.normals), (None, None));
        let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                   property float z\nproperty float s\nproperty float t\nelement face 1\n\
                   property list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n\
                   0 1 0 0 1\n3 0 1 2\n";
        let mesh = parse_ply(ply.as_bytes(), "t.ply").unwrap();
        assert_eq!(mesh.uvs, Some(vec![[[0.0, 1.0], [1.0, 1.0], [0.0, 0.0]]]));
        assert_eq!(mesh.normals, None);
        mesh.validate("t.ply").unwrap();
        let mut broken = mesh.clone();
        broken.uvs.as_mut().unwrap()[0][1][0] = f32::NAN;
        let err = broken.validate("t.ply").unwrap_err().to_string();
        assert!(
            err.contains("face 0 has a non-finite texture coordinate"),
            "{err}"
        );
        broken.uvs = Some(vec![]);
        let err = broken.validate("t.ply").unwrap_err().to_string();
        assert!(
            err.contains("0 triangles' texture coordinates for 1 triangles"),
            "{err}"
        );
    }

    #[test]
    fn quads_are_fanned_and_bad_meshes_are_refused() {
        let quad = parse_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "q").unwrap();
        assert_eq!(quad.triangles.len(), 2);
        let empty = parse_obj(b"v 0 0 0\n", "e").unwrap_err().to_string();
        assert!(empty.contains("no triangles"), "{empty}");
        let nan = Mesh {
            positions: vec![[0.0, f32::NAN, 0.0]; 3],
            triangles: vec![[0, 1, 2]],
            uvs: None,
            normals: None,
        };
        assert!(nan
            .validate("n")
            .unwrap_err()
            .to_string()
            .contains("non-finite"));
        let out = Mesh {
            positions: vec![[0.0; 3]; 3],
            triangles: vec![[0, 1, 3]],
            uvs: None,
            normals: None,
        };
        assert!(out.validate("o").is_err());
    }

    #[test]
    fn a_face_of_two_vertices_is_refused_by_line() {
        let err = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n", "t.obj")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("t.obj") && err.contains("line 5 has 2 vertices"),
            "{err}"
        );
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
