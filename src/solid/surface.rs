//! Baking the solid onto a mesh's surface: a texture atlas whose every texel is the solid's voxel
//! at its 3D point. Planned first ([`SurfacePlan`]: the atlas layout and the memory it needs,
//! refused before anything is allocated), then baked group by group as the synthesis delivers
//! them, so the request's colours are never held whole.

use super::Solid;
use crate::error::{Error, Result};
use crate::lazy::bricks::{self, Brick, BrickSet};
use crate::lazy::{memory, BrickColors};
use crate::mesh::bake::{self, Atlas};
use crate::mesh::{Mesh, Placement};
use rayon::prelude::*;

/// How texels are laid out in the atlas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AtlasLayout {
    /// `--texels N`: every triangle an N x N cell, each with `gutter` texels of dilated room
    /// around it.
    Texels { texels: u32, gutter: u32 },
    /// `--texel-size S`: cells fitted to their triangles at S voxels per texel (None: about one
    /// texel per voxel, the coarsest the memory allows), each with `gutter` texels around it.
    TexelSize { size: Option<f64>, gutter: u32 },
    /// `--uv own`: the mesh's own texture coordinates in a square texture of `texture_size`
    /// texels (None: about one texel per voxel), every texel outside the triangles dilated.
    MeshUvs { texture_size: Option<u32> },
}

impl AtlasLayout {
    /// The gutter that protects the first `mips` mip levels of a packed atlas: 2^mips texels
    /// (none without mips).
    pub fn gutter_for_mips(mips: u32) -> u32 {
        if mips == 0 {
            0
        } else {
            // (Saturating: a gutter past any atlas is refused by the atlas's own check.)
            1u32.checked_shl(mips).unwrap_or(u32::MAX)
        }
    }
}

/// A surface bake planned: where the mesh lies in the solid, the atlas, and the bricks its
/// texels need.
pub struct SurfacePlan {
    pub placement: Placement,
    pub atlas: Atlas,
    /// The voxels per texel of a fitted layout.
    pub texel_size: Option<f64>,
    /// The layout in words, and the flag that chose it (for reports and errors).
    pub layout: String,
    pub flag: String,
    /// The estimate of the bake's memory, bytes.
    pub estimate: u64,
    wanted: Vec<Brick>,
    /// The mesh it was planned for ([`mesh_fingerprint`]).
    mesh_fingerprint: u64,
}

/// Per texel: its image pixel (4 bytes), its index and colour while its group places it (8),
/// then its PNG (at most about 4), and a bit of bookkeeping.
const BYTES_PER_TEXEL: u64 = 16;

impl SurfacePlan {
    /// Plan the bake of `mesh` (named `mesh_name` in errors) fitted into a cube of `resolution`
    /// voxels, with `layout`, for a solid whose coarse cache is `coarse_cache`, in groups of
    /// `group_side` voxels. Refused (naming the flag) when it cannot fit in the memory available.
    pub fn new(
        mesh: &Mesh,
        mesh_name: &str,
        resolution: u32,
        layout: AtlasLayout,
        coarse_cache: Option<u32>,
        group_side: u32,
    ) -> Result<SurfacePlan> {
        mesh.validate(mesh_name)?;
        super::limits::check_surface_resolution(resolution)?;
        let placement = Placement::fit(mesh, resolution);
        let available = crate::util::memory::available_memory();
        let fits = |atlas: &Atlas| atlas.texel_count() * BYTES_PER_TEXEL <= available;
        let (atlas, texel_size, words, flag) = match layout {
            AtlasLayout::Texels { texels, gutter } => (
                Atlas::new(mesh.triangles.len(), texels, gutter)?,
                None,
                format!("{texels} x {texels} texels per triangle"),
                format!("--texels {texels}"),
            ),
            AtlasLayout::TexelSize { size, gutter } => {
                let (atlas, size) = Atlas::fitted_within(mesh, &placement, size, gutter, fits)?;
                (
                    atlas,
                    Some(size),
                    format!("cells fitted at {size} voxels per texel"),
                    format!("--texel-size {size}"),
                )
            }
            AtlasLayout::MeshUvs { texture_size } => {
                let atlas = Atlas::mesh_uvs(mesh, &placement, texture_size, mesh_name, fits)?;
                let side = atlas.width;
                (
                    atlas,
                    None,
                    format!("the mesh's own UVs in {side} x {side} texels"),
                    format!("--texture-size {side}"),
                )
            }
        };
        let fewer = match layout {
            AtlasLayout::Texels { .. } => "a smaller --texels",
            AtlasLayout::TexelSize { .. } => "a larger --texel-size",
            AtlasLayout::MeshUvs { .. } => "a smaller --texture-size",
        };
        let estimate = atlas.texel_count() * BYTES_PER_TEXEL;
        use crate::util::memory::{available_text, human_bytes};
        if estimate > available {
            return Err(Error::invalid(
                flag,
                format!(
                    "a {}x{} atlas needs about {}, {}; use fewer texels ({fewer})",
                    atlas.width,
                    atlas.height,
                    human_bytes(estimate),
                    available_text(available)
                ),
            ));
        }
        // The texel positions are visited twice (for their bricks, then for their colours)
        // rather than listed: at 1024^3 the list is 75 MB.
        let mut wanted = BrickSet::default();
        atlas.for_each_texel_voxel(mesh, &placement, |_, p| wanted.add(p));
        let wanted = wanted.finish();
        let working = memory::sparse_working_bytes(
            wanted.len() as u64,
            resolution as f64,
            group_side,
            coarse_cache,
        );
        let total = working + estimate;
        if total > available {
            return Err(Error::invalid(
                format!("surface --resolution {resolution}"),
                format!(
                    "needs about {} of memory ({} bricks of 4^3 voxels), {}",
                    human_bytes(total),
                    wanted.len(),
                    available_text(available)
                ),
            ));
        }
        Ok(SurfacePlan {
            placement,
            atlas,
            texel_size,
            layout: words,
            flag,
            estimate: total,
            wanted,
            mesh_fingerprint: mesh_fingerprint(mesh),
        })
    }
}

/// A hash of what a plan depends on in its mesh (positions, triangles, texture coordinates), so
/// that baking another mesh with it is refused rather than indexing past its atlas.
fn mesh_fingerprint(mesh: &Mesh) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for p in &mesh.positions {
        p.map(f32::to_bits).hash(&mut h);
    }
    mesh.triangles.hash(&mut h);
    for uv in mesh.uvs.iter().flatten() {
        uv.map(|c| c.map(f32::to_bits)).hash(&mut h);
    }
    h.finish()
}

impl std::fmt::Debug for SurfacePlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SurfacePlan")
            .field("placement", &self.placement)
            .field(
                "atlas",
                &format_args!("{}x{}", self.atlas.width, self.atlas.height),
            )
            .field("layout", &self.layout)
            .field("estimate", &self.estimate)
            .field("bricks", &self.wanted.len())
            .finish_non_exhaustive()
    }
}

/// A baked atlas: `texel_bytes` bytes per texel (RGB, or RGBA for a solid of four channels),
/// rows of `atlas.width` texels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BakedSurface {
    pub width: u32,
    pub height: u32,
    pub texel_bytes: usize,
    pub pixels: Vec<u8>,
}

impl BakedSurface {
    /// The atlas as a PNG file's bytes.
    pub fn png(&self) -> Result<Vec<u8>> {
        let (w, h) = (self.width, self.height);
        if self.texel_bytes == 4 {
            let img = image::RgbaImage::from_raw(w, h, self.pixels.clone()).expect("sized");
            crate::io::atomic::png_bytes(&img)
        } else {
            let img = image::RgbImage::from_raw(w, h, self.pixels.clone()).expect("sized");
            crate::io::atomic::png_bytes(&img)
        }
    }
}

impl Solid {
    /// Bake the solid onto `mesh` as `plan` lays it out: every texel the solid's voxel at its 3D
    /// point, then gutters and the texels around UV islands dilated (texels still outside every
    /// cell take the colour of one surface voxel).
    pub fn bake_surface(&mut self, mesh: &Mesh, plan: &SurfacePlan) -> Result<BakedSurface> {
        let (atlas, place) = (&plan.atlas, &plan.placement);
        if mesh_fingerprint(mesh) != plan.mesh_fingerprint
            || atlas.uvs.len() != mesh.triangles.len()
        {
            return Err(Error::invalid(
                "mesh",
                "is not the mesh its surface plan was made for",
            ));
        }
        let texels = atlas.texel_count() as usize;
        let channels = self.color_channels();
        // Three bytes a texel unless the solid has a fourth channel: the atlas is the largest
        // buffer the bake holds (the bunny at 1024: 16 MB as RGB, 22 MB as RGBA).
        let texel_bytes = if channels >= 4 { 4 } else { 3 };
        let mut pixels = vec![0u8; texels * texel_bytes];
        let mut placed = vec![0u64; texels.div_ceil(64)];
        let uncovered_voxel = atlas.uncovered_texel_voxel(mesh, place);
        let mut uncovered_color = None;
        let mut bake_group = |group: BrickColors| {
            let (lo, hi) = bricks::bounds(&group.bricks).expect("a group has bricks");
            let (lo, hi) = (lo.map(|v| v * 4), hi.map(|v| v * 4 + 3));
            // The group's texels, found in parallel (the cores are otherwise idle between
            // groups), then placed. (Texel indices fit u32: atlases are at most 16384^2.)
            let found: Vec<Vec<(u32, u32)>> = atlas
                .triangles_near(mesh, place, lo, hi)
                .par_iter()
                .map(|&t| {
                    let mut last = None;
                    let mut out = Vec::new();
                    atlas.for_each_texel_voxel_of(mesh, place, t, |i, p| {
                        // (Most texels of the triangles at the group's edges fall outside it.)
                        if (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]) {
                            return;
                        }
                        if let Some(c) = group.color_near(p, &mut last) {
                            out.push((i as u32, c));
                        }
                    });
                    out
                })
                .collect();
            for (i, c) in found.into_iter().flatten() {
                let i = i as usize;
                pixels[texel_bytes * i..texel_bytes * (i + 1)]
                    .copy_from_slice(&bake::atlas_pixel(c, channels)[..texel_bytes]);
                placed[i / 64] |= 1 << (i % 64);
            }
            if uncovered_color.is_none() {
                uncovered_color = group.color(uncovered_voxel);
            }
        };
        // Groups are baked on a thread of their own while the next ones are synthesized (on a
        // GPU the bake took as long as planning and running the groups). One group waits in the
        // channel, so about four groups' colours are held at once.
        let report = super::reporter(&self.progress);
        let synth = &mut self.synth;
        std::thread::scope(|scope| -> Result<()> {
            let (finished, to_bake) = std::sync::mpsc::sync_channel(1);
            let baker = scope.spawn(move || to_bake.into_iter().for_each(&mut bake_group));
            let synthesized = synth.synthesize_bricks_by_group(&plan.wanted, report, |group| {
                finished
                    .send(group)
                    .map_err(|_| Error::Internal("the atlas bake stopped".into()))
            });
            drop(finished);
            if let Err(panic) = baker.join() {
                std::panic::resume_unwind(panic);
            }
            synthesized
        })?;
        // Gutters and the space around UV islands take their neighbours' colours.
        crate::mesh::dilate::dilate(
            &mut pixels,
            atlas.width,
            atlas.height,
            texel_bytes,
            &mut placed,
            atlas.dilation_rings(),
        );
        let uncovered_color = uncovered_color.ok_or_else(|| {
            Error::invalid(
                "surface plan",
                "its bricks do not hold its atlas's voxels (was it changed after it was made?)",
            )
        })?;
        let uncovered_pixel = bake::atlas_pixel(uncovered_color, channels);
        for (i, p) in pixels.chunks_exact_mut(texel_bytes).enumerate() {
            if placed[i / 64] & (1 << (i % 64)) == 0 {
                p.copy_from_slice(&uncovered_pixel[..texel_bytes]);
            }
        }
        Ok(BakedSurface {
            width: atlas.width,
            height: atlas.height,
            texel_bytes,
            pixels,
        })
    }
}
