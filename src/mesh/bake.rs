//! Baking the solid onto a mesh surface: a packed per-triangle UV atlas whose every texel holds
//! the solid at its 3D point (paper 6.2: only the voxels the surface passes through, with their
//! dependencies, are synthesized).
//!
//! Atlas layout: triangle k owns a square cell of `texels` x `texels` texels, cell (k mod cols,
//! k / cols). Its corners a, b, c sit at the centres of the cell's texels (0, 0), (T-1, 0) and
//! (0, T-1); texel (i, j) is the point a + i/(T-1) (b - a) + j/(T-1) (c - a). Texels beyond the
//! hypotenuse (i + j > T - 1) take the nearest point on it, so bilinear filtering inside the
//! triangle never reads another triangle's texels.

use super::{Mesh, Placement};
use crate::error::{Error, Result};
use crate::exemplar::Image;
use glam::DVec3;

/// Largest atlas side accepted.
pub const MAX_ATLAS_SIDE: u32 = 16384;

#[derive(Clone, Debug)]
pub struct Atlas {
    pub texels: u32,
    pub cols: u32,
    pub width: u32,
    pub height: u32,
    /// Per triangle, its corners' texture coordinates in [0, 1] (u right, v down: row 0 first).
    pub uvs: Vec<[[f32; 2]; 3]>,
}

impl Atlas {
    /// Lay out `triangles` cells of `texels`^2.
    pub fn new(triangles: usize, texels: u32) -> Result<Atlas> {
        if !(2..=256).contains(&texels) {
            return Err(Error::invalid(
                format!("--texels {texels}"),
                "must be 2..=256",
            ));
        }
        let cols = (triangles as f64).sqrt().ceil().max(1.0) as u32;
        let rows = (triangles as u32).div_ceil(cols).max(1);
        let (width, height) = (cols as u64 * texels as u64, rows as u64 * texels as u64);
        if width > MAX_ATLAS_SIDE as u64 || height > MAX_ATLAS_SIDE as u64 {
            return Err(Error::invalid(
                format!("--texels {texels}"),
                format!(
                    "{triangles} triangles need a {width}x{height} atlas, over the \
                     {MAX_ATLAS_SIDE} limit; use fewer texels per triangle"
                ),
            ));
        }
        let (width, height) = (width as u32, height as u32);
        let t = texels as f32;
        let uvs = (0..triangles as u32)
            .map(|k| {
                let (cx, cy) = ((k % cols) as f32 * t, (k / cols) as f32 * t);
                let at = |i: f32, j: f32| {
                    [
                        (cx + i + 0.5) / width as f32,
                        (cy + j + 0.5) / height as f32,
                    ]
                };
                [at(0.0, 0.0), at(t - 1.0, 0.0), at(0.0, t - 1.0)]
            })
            .collect();
        Ok(Atlas {
            texels,
            cols,
            width,
            height,
            uvs,
        })
    }

    /// The voxel-space point of texel (i, j) of triangle `corners`' cell.
    fn point(&self, corners: &[DVec3; 3], i: u32, j: u32) -> DVec3 {
        let n = (self.texels - 1) as f64;
        let (mut s, mut t) = (i as f64 / n, j as f64 / n);
        if s + t > 1.0 {
            // Nearest point of the hypotenuse s + t = 1 (in the cell's parameter space).
            let d = (s + t - 1.0) / 2.0;
            s = (s - d).clamp(0.0, 1.0);
            t = (t - d).clamp(0.0, 1.0);
        }
        let p = corners[0] + s * (corners[1] - corners[0]) + t * (corners[2] - corners[0]);
        // Rounding must not push a point off its triangle's box (a coordinate of -1e-15 would
        // sample voxel -1).
        let lo = corners[0].min(corners[1]).min(corners[2]);
        let hi = corners[0].max(corners[1]).max(corners[2]);
        p.clamp(lo, hi)
    }

    /// The voxel every atlas texel samples (row-major; texels of unused cells sample voxel of
    /// the first triangle's corner so the request stays local).
    pub fn texel_voxels(&self, mesh: &Mesh, place: &Placement) -> Vec<[i32; 3]> {
        let mut out = vec![[0i32; 3]; self.width as usize * self.height as usize];
        self.for_each_texel_voxel(mesh, place, |i, p| out[i] = p);
        out
    }

    /// [`Self::texel_voxels`] without the list: `visit(texel index, voxel)`, every texel first
    /// with the fallback voxel, then each used texel again with its own (large atlases: the
    /// list is 75 MB at 1024^3).
    pub fn for_each_texel_voxel(
        &self,
        mesh: &Mesh,
        place: &Placement,
        mut visit: impl FnMut(usize, [i32; 3]),
    ) {
        let t = self.texels;
        let fallback = place
            .to_voxels(mesh.positions[mesh.triangles[0][0] as usize])
            .floor();
        let fallback = [fallback.x as i32, fallback.y as i32, fallback.z as i32];
        for i in 0..self.width as usize * self.height as usize {
            visit(i, fallback);
        }
        for (k, tri) in mesh.triangles.iter().enumerate() {
            let corners = tri.map(|i| place.to_voxels(mesh.positions[i as usize]));
            let (cx, cy) = ((k as u32 % self.cols) * t, (k as u32 / self.cols) * t);
            for j in 0..t {
                for i in 0..t {
                    let p = self.point(&corners, i, j).floor();
                    visit(
                        ((cy + j) * self.width + cx + i) as usize,
                        [p.x as i32, p.y as i32, p.z as i32],
                    );
                }
            }
        }
    }
}

impl Atlas {
    /// Every texel's point in the mesh's own coordinates, with its triangle (row-major; texels
    /// of unused cells get `u32::MAX` and the first corner of triangle 0).
    pub fn texel_points(&self, mesh: &Mesh) -> Vec<(u32, DVec3)> {
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        let fallback = (u32::MAX, p(mesh.triangles[0][0]));
        let mut out = vec![fallback; self.width as usize * self.height as usize];
        let t = self.texels;
        for (k, tri) in mesh.triangles.iter().enumerate() {
            let corners = tri.map(p);
            let (cx, cy) = ((k as u32 % self.cols) * t, (k as u32 / self.cols) * t);
            for j in 0..t {
                for i in 0..t {
                    out[((cy + j) * self.width + cx + i) as usize] =
                        (k as u32, self.point(&corners, i, j));
                }
            }
        }
        out
    }
}

/// Texels per triangle giving about one texel per voxel along the median edge (2..=64).
pub fn auto_texels(mesh: &Mesh, place: &Placement) -> u32 {
    let mut edges: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| place.to_voxels(mesh.positions[i as usize]));
            ((p[1] - p[0]).length() + (p[2] - p[0]).length()) / 2.0
        })
        .collect();
    edges.sort_by(f64::total_cmp);
    let median = edges[edges.len() / 2];
    (median.ceil() as u32 + 1).clamp(2, 64)
}

/// The baked atlas image from the packed colours of its texels.
pub fn atlas_image(atlas: &Atlas, colors: &[u32], channels: u32) -> Image {
    let mut img = Image::new(atlas.width, atlas.height, channels);
    let c = channels as usize;
    for (k, w) in colors.iter().enumerate() {
        img.pixels[k * c..(k + 1) * c].copy_from_slice(&w.to_le_bytes()[..c]);
    }
    img
}

/// OBJ + MTL referring to the atlas PNG (`png_name`, beside them); corners get their own
/// texture coordinates (v flipped: OBJ's v grows upwards).
pub fn obj_text(mesh: &Mesh, atlas: &Atlas, mtl_name: &str) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    writeln!(
        s,
        "# solidsynth surface bake: {} triangles",
        mesh.triangles.len()
    )
    .unwrap();
    writeln!(s, "mtllib {mtl_name}\nusemtl solid").unwrap();
    for p in &mesh.positions {
        writeln!(s, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for uv in &atlas.uvs {
        for c in uv {
            writeln!(s, "vt {} {}", c[0], 1.0 - c[1]).unwrap();
        }
    }
    for (k, t) in mesh.triangles.iter().enumerate() {
        let vt = 3 * k + 1;
        writeln!(
            s,
            "f {}/{} {}/{} {}/{}",
            t[0] + 1,
            vt,
            t[1] + 1,
            vt + 1,
            t[2] + 1,
            vt + 2
        )
        .unwrap();
    }
    s
}

pub fn mtl_text(png_name: &str) -> String {
    format!("newmtl solid\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {png_name}\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn texels_sample_points_on_their_triangle() {
        let mesh = tetra();
        let place = Placement::fit(&mesh, 64);
        let atlas = Atlas::new(4, 8).unwrap();
        assert_eq!((atlas.cols, atlas.width, atlas.height), (2, 16, 16));
        let voxels = atlas.texel_voxels(&mesh, &place);
        // Triangle 1 (cell (1, 0)), vertices 0, 1, 3, lies in the plane y = 0.
        for j in 0..8 {
            for i in 8..16 {
                assert_eq!(voxels[j * 16 + i][1], 0, "texel ({i}, {j})");
            }
        }
        // Corner texels sample the corners exactly.
        assert_eq!(voxels[0], [0, 0, 0]);
        // Triangle 0's b is vertex 2 = (0, 1, 0), at y = 64 - epsilon.
        assert_eq!(voxels[7], [0, 63, 0]);
        // Every texel lies in the mesh's box.
        assert!(voxels
            .iter()
            .all(|v| v.iter().all(|&c| (0..64).contains(&c))));
        // The uvs of a cell's corners land on the centres of its corner texels.
        let uv = atlas.uvs[3];
        assert_eq!(uv[0], [8.5 / 16.0, 8.5 / 16.0]);
        assert_eq!(uv[1], [15.5 / 16.0, 8.5 / 16.0]);
    }

    #[test]
    fn oversized_atlases_are_refused() {
        assert!(Atlas::new(10_000_000, 64).is_err());
        assert!(Atlas::new(10, 1).is_err());
    }
}
