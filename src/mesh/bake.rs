//! Baking the solid onto a mesh surface: a UV atlas whose every texel holds the solid at its 3D
//! point (paper 6.2: only the voxels the surface passes through, with their dependencies, are
//! synthesized).
//!
//! Two kinds of layout ([`TexelLayout`]):
//! - Packed cells (`super::pack`): triangle k owns a rectangular cell of `width` x `height`
//!   texels. One of its corners, a (the cell's `first`), and the two that follow it cyclically,
//!   b and c, sit at the centres of the cell's texels (0, 0), (W-1, 0) and (0, H-1); texel (i, j)
//!   is the point a + i/(W-1) (b - a) + j/(H-1) (c - a). Texels beyond the hypotenuse
//!   (i/(W-1) + j/(H-1) > 1) take the point of the hypotenuse nearest to them in texel space, so
//!   bilinear filtering inside the triangle never reads another triangle's texels and near the
//!   long edge blends points of that edge. A gutter of texels around each cell is filled by
//!   dilation after the bake (`super::dilate`), so mip levels do not mix cells.
//! - The mesh's own texture coordinates (`super::uv_raster`): a texel belongs to the triangle
//!   whose UV triangle holds its centre and samples the point with the same barycentric
//!   coordinates; texels outside every triangle are filled by dilation.

use super::{Mesh, Placement};
use crate::error::{Error, Result};
use glam::DVec3;

/// Largest atlas side accepted.
pub const MAX_ATLAS_SIDE: u32 = 16384;

/// One triangle's rectangle of the atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    /// The cell's top-left texel.
    pub x: u32,
    pub y: u32,
    /// Texels along the a -> b edge (columns) and the a -> c edge (rows); at least 2 each.
    pub width: u32,
    pub height: u32,
    /// Which of the triangle's corners (0, 1, 2) is a; b and c follow it cyclically.
    pub first: u8,
}

impl Cell {
    /// The triangle's corners in the cell's order (a, b, c).
    pub(super) fn ordered<T: Copy>(&self, corners: [T; 3]) -> [T; 3] {
        let f = self.first as usize;
        [corners[f], corners[(f + 1) % 3], corners[(f + 2) % 3]]
    }

    /// The point of texel (i, j) of the cell on the triangle `corners` (in the triangle's own
    /// corner order).
    fn point(&self, corners: &[DVec3; 3], i: u32, j: u32) -> DVec3 {
        let [a, b, c] = self.ordered(*corners);
        let (mut s, mut t) = (
            i as f64 / (self.width - 1) as f64,
            j as f64 / (self.height - 1) as f64,
        );
        if s + t > 1.0 {
            // The nearest point of the hypotenuse s + t = 1 in texel space (x = s (W-1),
            // y = t (H-1)), where bilinear filtering blends texels: moving along the line's
            // normal (1/(W-1), 1/(H-1)) there gives these shares of the excess (for a square
            // cell, half each).
            let (a2, b2) = (
                ((self.width - 1) as f64).powi(2),
                ((self.height - 1) as f64).powi(2),
            );
            let excess = s + t - 1.0;
            s = (s - excess * (b2 / (a2 + b2))).clamp(0.0, 1.0);
            t = (t - excess * (a2 / (a2 + b2))).clamp(0.0, 1.0);
        }
        let p = a + s * (b - a) + t * (c - a);
        // Rounding must not push a point off its triangle's box (a coordinate of -1e-15 would
        // sample voxel -1).
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        p.clamp(lo, hi)
    }
}

/// Where each triangle's texels lie in the atlas.
#[derive(Clone, Debug, PartialEq)]
pub enum TexelLayout {
    /// Per triangle, its packed cell.
    Cells(Vec<Cell>),
    /// The texels whose centres the triangle's own texture coordinates cover.
    MeshUvs,
}

#[derive(Clone, Debug)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    pub texels: TexelLayout,
    /// Per triangle, its corners' texture coordinates in [0, 1] (u right, v down: row 0 first),
    /// in the triangle's own corner order.
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// Packed cells: the rings of texels around each cell that the bake fills by dilation (0:
    /// none).
    pub gutter: u32,
}

impl Atlas {
    /// Per triangle, its packed cell (none for [`TexelLayout::MeshUvs`]).
    pub fn cells(&self) -> &[Cell] {
        match &self.texels {
            TexelLayout::Cells(cells) => cells,
            TexelLayout::MeshUvs => &[],
        }
    }

    /// How many rings of texels around the baked ones dilation fills: the gutter of packed
    /// cells, every texel (`None`) around the mesh's own UV islands.
    pub fn dilation_rings(&self) -> Option<u32> {
        match self.texels {
            TexelLayout::Cells(_) => Some(self.gutter),
            TexelLayout::MeshUvs => None,
        }
    }

    /// Check that this atlas was made for `mesh` (named `what` in errors): the mesh passes
    /// [`Mesh::validate`] and the atlas has texture coordinates (and, packed, a cell) for each of
    /// its triangles. The writers check it, so a mismatch is an error rather than a file whose
    /// faces refer to texture coordinates it lacks.
    pub fn check_mesh(&self, mesh: &Mesh, what: &str) -> Result<()> {
        mesh.validate(what)?;
        let triangles = mesh.triangles.len();
        let cells = match &self.texels {
            TexelLayout::Cells(cells) => cells.len(),
            TexelLayout::MeshUvs => triangles,
        };
        if self.uvs.len() != triangles || cells != triangles {
            return Err(Error::invalid(
                what,
                format!(
                    "the atlas was made for {} triangles, not this mesh's {triangles}",
                    self.uvs.len()
                ),
            ));
        }
        Ok(())
    }

    /// Whether a renderer may sample the atlas through mipmaps: the gutter keeps at least the
    /// first mip level from mixing cells, or the atlas follows the mesh's own UVs.
    pub fn mip_safe(&self) -> bool {
        self.gutter >= 2 || self.texels == TexelLayout::MeshUvs
    }

    /// An atlas of packed `cells` (each with `gutter` texels of room around it).
    pub(super) fn with_cells(width: u32, height: u32, cells: Vec<Cell>, gutter: u32) -> Atlas {
        let uvs = cells
            .iter()
            .map(|cell| {
                let at = |i: u32, j: u32| {
                    [
                        ((cell.x + i) as f32 + 0.5) / width as f32,
                        ((cell.y + j) as f32 + 0.5) / height as f32,
                    ]
                };
                // The cell's a, b, c back in the triangle's corner order.
                let ordered = [at(0, 0), at(cell.width - 1, 0), at(0, cell.height - 1)];
                let f = cell.first as usize;
                let mut uv = [[0.0; 2]; 3];
                for (k, c) in ordered.into_iter().enumerate() {
                    uv[(f + k) % 3] = c;
                }
                uv
            })
            .collect();
        Atlas {
            width,
            height,
            texels: TexelLayout::Cells(cells),
            uvs,
            gutter,
        }
    }

    /// Texels in the atlas.
    pub fn texel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// The longest step, in voxels, between neighbouring texels along a triangle's edges: at most
    /// the texel size for [`Self::fitted`]; for square cells, the longest edge over T - 1; for
    /// the mesh's own UVs, the longest edge over its length in texels.
    pub fn max_texel_step(&self, mesh: &Mesh, place: &Placement) -> f64 {
        let corners =
            |t: usize| mesh.triangles[t].map(|i| place.to_voxels(mesh.positions[i as usize]));
        match &self.texels {
            TexelLayout::Cells(cells) => cells
                .iter()
                .enumerate()
                .map(|(t, cell)| {
                    let [a, b, c] = cell.ordered(corners(t));
                    ((b - a).length() / (cell.width - 1) as f64)
                        .max((c - a).length() / (cell.height - 1) as f64)
                })
                .fold(0.0, f64::max),
            TexelLayout::MeshUvs => (0..mesh.triangles.len())
                .flat_map(|t| {
                    let p = corners(t);
                    let uv = self.uvs[t].map(|c| {
                        glam::DVec2::new(
                            c[0] as f64 * self.width as f64,
                            c[1] as f64 * self.height as f64,
                        )
                    });
                    (0..3).map(move |k| {
                        let texels = (uv[(k + 1) % 3] - uv[k]).length();
                        let voxels = (p[(k + 1) % 3] - p[k]).length();
                        if texels > 0.0 {
                            voxels / texels
                        } else {
                            0.0
                        }
                    })
                })
                .fold(0.0, f64::max),
        }
    }

    /// The voxel every atlas texel samples (row-major; texels outside every cell sample the
    /// voxel of the first triangle's corner so the request stays local).
    pub fn texel_voxels(&self, mesh: &Mesh, place: &Placement) -> Vec<[i32; 3]> {
        let mut out = vec![[0i32; 3]; self.texel_count() as usize];
        self.for_each_texel_voxel(mesh, place, |i, p| out[i] = p);
        out
    }

    /// [`Self::texel_voxels`] without the list: `visit(texel index, voxel)`, every texel first
    /// with the fallback voxel, then each texel of a cell again with its own (large atlases:
    /// the list is 75 MB at 1024^3).
    pub fn for_each_texel_voxel(
        &self,
        mesh: &Mesh,
        place: &Placement,
        mut visit: impl FnMut(usize, [i32; 3]),
    ) {
        let fallback = self.uncovered_texel_voxel(mesh, place);
        for i in 0..self.texel_count() as usize {
            visit(i, fallback);
        }
        for t in 0..mesh.triangles.len() {
            self.for_each_texel_voxel_of(mesh, place, t, &mut visit);
        }
    }

    /// The triangles whose texels' voxels may lie in `lo..=hi`: their corners' voxel bounds
    /// meet that box (a texel's point lies on its triangle, so its voxel lies within them).
    pub fn triangles_near(
        &self,
        mesh: &Mesh,
        place: &Placement,
        lo: [i32; 3],
        hi: [i32; 3],
    ) -> Vec<usize> {
        (0..mesh.triangles.len())
            .filter(|&t| {
                let corners =
                    mesh.triangles[t].map(|i| place.to_voxels(mesh.positions[i as usize]));
                let low = corners[0].min(corners[1]).min(corners[2]).floor();
                let high = corners[0].max(corners[1]).max(corners[2]).floor();
                let (low, high) = ([low.x, low.y, low.z], [high.x, high.y, high.z]);
                (0..3).all(|k| high[k] >= lo[k] as f64 && low[k] <= hi[k] as f64)
            })
            .collect()
    }

    /// [`Self::for_each_texel_voxel`] for the texels of triangle `t` only.
    pub fn for_each_texel_voxel_of(
        &self,
        mesh: &Mesh,
        place: &Placement,
        t: usize,
        mut visit: impl FnMut(usize, [i32; 3]),
    ) {
        let corners = mesh.triangles[t].map(|i| place.to_voxels(mesh.positions[i as usize]));
        self.for_each_texel_point(t, &corners, |i, p| {
            let p = p.floor();
            visit(i, [p.x as i32, p.y as i32, p.z as i32])
        });
    }

    /// Every texel of triangle `t` with its point on the triangle `corners` (in the triangle's
    /// own corner order, in any space).
    fn for_each_texel_point(
        &self,
        t: usize,
        corners: &[DVec3; 3],
        mut visit: impl FnMut(usize, DVec3),
    ) {
        match &self.texels {
            TexelLayout::Cells(cells) => {
                let cell = &cells[t];
                for j in 0..cell.height {
                    for i in 0..cell.width {
                        visit(self.texel_index(cell, i, j), cell.point(corners, i, j));
                    }
                }
            }
            TexelLayout::MeshUvs => {
                let width = self.width as usize;
                super::uv_raster::for_each_covered_texel(self, t, |x, y, weights| {
                    let p =
                        corners[0] * weights[0] + corners[1] * weights[1] + corners[2] * weights[2];
                    // Rounding must not push a point off its triangle's box.
                    let lo = corners[0].min(corners[1]).min(corners[2]);
                    let hi = corners[0].max(corners[1]).max(corners[2]);
                    visit(y as usize * width + x as usize, p.clamp(lo, hi));
                });
            }
        }
    }

    /// The voxel that [`Self::for_each_texel_voxel`] gives the texels outside every cell.
    pub fn uncovered_texel_voxel(&self, mesh: &Mesh, place: &Placement) -> [i32; 3] {
        let p = place
            .to_voxels(mesh.positions[mesh.triangles[0][0] as usize])
            .floor();
        [p.x as i32, p.y as i32, p.z as i32]
    }

    /// Every texel's point in the mesh's own coordinates, with its triangle (row-major; texels
    /// outside every triangle get `u32::MAX` and the first corner of triangle 0).
    pub fn texel_points(&self, mesh: &Mesh) -> Vec<(u32, DVec3)> {
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        let fallback = (u32::MAX, p(mesh.triangles[0][0]));
        let mut out = vec![fallback; self.texel_count() as usize];
        for (k, tri) in mesh.triangles.iter().enumerate() {
            self.for_each_texel_point(k, &tri.map(p), |i, point| out[i] = (k as u32, point));
        }
        out
    }

    pub(super) fn texel_index(&self, cell: &Cell, i: u32, j: u32) -> usize {
        (cell.y + j) as usize * self.width as usize + (cell.x + i) as usize
    }
}
/// The atlas pixel of a packed colour of `channels` channels (little-endian bytes), as
/// [`crate::exemplar::Image::to_rgba8`] shows an image of that many channels: grey for one or two, opaque for
/// three.
pub fn atlas_pixel(color: u32, channels: u32) -> [u8; 4] {
    let b = color.to_le_bytes();
    match channels {
        1 | 2 => [b[0], b[0], b[0], 255],
        3 => [b[0], b[1], b[2], 255],
        _ => b,
    }
}

/// OBJ + MTL referring to the atlas PNG (`png_name`, beside them); corners get their own
/// texture coordinates (v flipped: OBJ's v grows upwards) and normals ([`Mesh::corner_normals`]).
/// An error when the atlas was not made for the mesh ([`Atlas::check_mesh`]).
pub fn obj_text(mesh: &Mesh, atlas: &Atlas, mtl_name: &str) -> Result<String> {
    use std::fmt::Write;
    atlas.check_mesh(mesh, "mesh")?;
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
    for corners in mesh.corner_normals() {
        for n in corners {
            writeln!(s, "vn {} {} {}", n[0], n[1], n[2]).unwrap();
        }
    }
    // Corner k of triangle t has texture coordinate and normal 3 t + k + 1.
    for (k, t) in mesh.triangles.iter().enumerate() {
        let c = 3 * k + 1;
        writeln!(
            s,
            "f {}/{c}/{c} {}/{}/{} {}/{}/{}",
            t[0] + 1,
            t[1] + 1,
            c + 1,
            c + 1,
            t[2] + 1,
            c + 2,
            c + 2
        )
        .unwrap();
    }
    Ok(s)
}

pub fn mtl_text(png_name: &str) -> String {
    format!("newmtl solid\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {png_name}\n")
}
