//! A lapped model as the render pipeline draws it (`crate::contract::lapped::RenderScene`).

use super::model::LstModel;
use crate::contract::lapped::{RenderScene, VERTEX_FLOATS};

impl LstModel {
    /// The model's vertex streams and textures for `lapped_render`.
    pub fn render_scene(&self) -> RenderScene<'_> {
        let (prepass, layered) = vertex_streams(self);
        RenderScene {
            prepass,
            layered,
            exemplar_size: self.exemplar.size,
            exemplar_rgba: &self.exemplar.rgba,
            mask_size: self.masks[0].size,
            mask_count: self.masks.len() as u32,
            mask_alpha: self.masks.iter().flat_map(|k| k.alpha.clone()).collect(),
            depth_varying: self.kind.depth_varying(),
        }
    }
}

/// The vertex stream: the depth pre-pass (one copy of each face) and the layers (one copy per
/// face and layer, sorted by patch). Normals are the smooth per-vertex surface normals.
fn vertex_streams(model: &LstModel) -> (Vec<f32>, Vec<f32>) {
    let faces = model.mesh.boundary_faces(&model.mesh.face_neighbors());
    let normals = model.mesh.surface_normals(&faces);
    let mut prepass = Vec::new();
    let mut layered: Vec<(u32, [f32; 3 * VERTEX_FLOATS])> = Vec::new();
    for (face, t) in &faces {
        let tet = model.mesh.tets[*t as usize];
        // The face's corners as indices into the tet (for the layers' texture coordinates).
        let local = face.map(|v| tet.iter().position(|&u| u == v).expect("face of its tet"));
        let corner = |c: usize, coord: [f32; 3], mask: f32| {
            let q = model.mesh.vertices[face[c] as usize].as_vec3();
            let n = normals[face[c] as usize].as_vec3();
            [
                q.x, q.y, q.z, n.x, n.y, n.z, coord[0], coord[1], coord[2], mask,
            ]
        };
        for c in 0..3 {
            prepass.extend_from_slice(&corner(c, [0.0; 3], 0.0));
        }
        for layer in &model.layers[*t as usize] {
            let mut tri = [0.0f32; 3 * VERTEX_FLOATS];
            for c in 0..3 {
                tri[c * VERTEX_FLOATS..(c + 1) * VERTEX_FLOATS].copy_from_slice(&corner(
                    c,
                    layer.coords[local[c]],
                    layer.mask as f32,
                ));
            }
            layered.push((layer.patch, tri));
        }
    }
    // Stable: within a patch, triangles keep tet order.
    layered.sort_by_key(|(patch, _)| *patch);
    (prepass, layered.iter().flat_map(|(_, t)| *t).collect())
}
