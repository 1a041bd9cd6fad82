//! Baking an LST model's surface into a textured triangle mesh: the tet mesh's boundary faces
//! with the per-triangle atlas of the lazy engine's surface baker ([`crate::mesh::bake`]), every
//! texel composited from the layers of the tet its face belongs to.

use super::model::LstModel;
use crate::error::Result;
use crate::mesh::bake::Atlas;
use crate::mesh::Mesh;
use rayon::prelude::*;

/// The boundary surface as a triangle mesh (vertices compacted) and, per triangle, its tet.
pub fn surface(model: &LstModel) -> (Mesh, Vec<u32>) {
    let neighbors = model.mesh.face_neighbors();
    let faces = model.mesh.boundary_faces(&neighbors);
    let mut remap = vec![u32::MAX; model.mesh.vertices.len()];
    let mut positions = Vec::new();
    let mut triangles = Vec::with_capacity(faces.len());
    let mut tets = Vec::with_capacity(faces.len());
    for (f, t) in faces {
        triangles.push(f.map(|v| {
            if remap[v as usize] == u32::MAX {
                remap[v as usize] = positions.len() as u32;
                positions.push(model.mesh.vertices[v as usize].as_vec3().to_array());
            }
            remap[v as usize]
        }));
        tets.push(t);
    }
    (
        Mesh {
            positions,
            triangles,
            uvs: None,
            normals: None,
        },
        tets,
    )
}

/// Texels per triangle giving about `texels_per_unit` texels per exemplar voxel on the median
/// face: the atlas resolves the pasted texture without blowing up. An error for a mesh
/// [`Mesh::validate`] refuses.
pub fn auto_texels(mesh: &Mesh, model: &LstModel, scale: f64) -> Result<u32> {
    mesh.validate("mesh")?;
    let mut edges: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| glam::Vec3::from_array(mesh.positions[i as usize]).as_dvec3());
            ((p[1] - p[0]).length() + (p[2] - p[0]).length()) / 2.0
        })
        .collect();
    edges.sort_by(f64::total_cmp);
    let median = edges[edges.len() / 2];
    let voxels = median / scale * model.exemplar.size as f64;
    Ok((voxels.ceil() as u32 + 1).clamp(2, 64))
}

/// The atlas image (RGBA) of the surface `mesh` whose triangle k lies on tet `tets[k]`.
pub fn bake(
    model: &LstModel,
    mesh: &Mesh,
    tets: &[u32],
    atlas: &Atlas,
) -> Result<image::RgbaImage> {
    let points = atlas.texel_points(mesh);
    let pixels: Vec<[u8; 4]> = points
        .par_iter()
        .map(|&(tri, p)| {
            if tri == u32::MAX {
                return [0, 0, 0, 0];
            }
            let t = tets[tri as usize] as usize;
            // The point is on a face of t: clamp rounding off the tet and renormalize.
            let b = model.mesh.barycentric(t, p).map(|x| x.max(0.0));
            let sum: f64 = b.iter().sum();
            let rgba = model.shade(t, b.map(|x| (x / sum) as f32));
            [
                rgba[0].round().clamp(0.0, 255.0) as u8,
                rgba[1].round().clamp(0.0, 255.0) as u8,
                rgba[2].round().clamp(0.0, 255.0) as u8,
                255,
            ]
        })
        .collect();
    Ok(
        image::RgbaImage::from_raw(atlas.width, atlas.height, pixels.concat())
            .expect("atlas size matches"),
    )
}
