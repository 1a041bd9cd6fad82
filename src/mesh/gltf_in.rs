//! glTF 2.0 meshes in (`.glb`, or `.gltf` with its buffers beside it or embedded), through the
//! `gltf` crate: every triangle primitive of the default scene's mesh instances, placed by their
//! nodes' world transforms, as one triangle mesh, with their first texture coordinates and their
//! normals where every primitive has them. Materials, textures and animation are ignored.

use super::Mesh;
use crate::error::{Error, Result};
use std::path::Path;

/// Parse glTF `bytes` (binary or JSON) named `name`; external buffers are read relative to
/// `base` (none: only embedded and GLB buffers).
pub fn parse_gltf(bytes: &[u8], name: &str, base: Option<&Path>) -> Result<Mesh> {
    // The crate's validator indexes some arrays unchecked (gltf-json 1.4.1 panics on a POSITION
    // accessor index out of range): the indices are checked first, and any panic left in the
    // crate on a malformed file still becomes an input error, not a crash.
    std::panic::catch_unwind(|| parse_checked(bytes, name, base)).unwrap_or_else(|_| {
        Err(Error::invalid(
            name,
            "the glTF reader failed on this file: it is malformed",
        ))
    })
}

fn parse_checked(bytes: &[u8], name: &str, base: Option<&Path>) -> Result<Mesh> {
    let invalid = |problem: String| Error::invalid(name, problem);
    let not_gltf = |e: gltf::Error| invalid(format!("not a valid glTF file: {e}"));
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(not_gltf)?;
    check_indices(document.as_json()).map_err(invalid)?;
    // The crate's own validation, on the document already parsed.
    let document = gltf::Document::from_json(document.into_json()).map_err(not_gltf)?;
    let buffers = gltf::import_buffers(&document, base, blob)
        .map_err(|e| invalid(format!("its buffers cannot be read: {e}")))?;
    let mut mesh = Mesh {
        positions: Vec::new(),
        triangles: Vec::new(),
        uvs: None,
        normals: None,
    };
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| invalid("has no scene".into()))?;
    let mut stack: Vec<(gltf::Node, glam::Mat4)> =
        scene.nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect();
    let mut visited = vec![false; document.nodes().len()];
    // Filled while every primitive so far had the attribute.
    mesh.uvs = Some(Vec::new());
    mesh.normals = Some(Vec::new());
    while let Some((node, parent)) = stack.pop() {
        // A node reached twice: the hierarchy is not the tree glTF requires (a cycle would
        // never end).
        if std::mem::replace(&mut visited[node.index()], true) {
            return Err(invalid(format!(
                "node {} is reached twice: the node hierarchy is not a tree",
                node.index()
            )));
        }
        let world = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(m) = node.mesh() {
            for primitive in m.primitives() {
                add_primitive(&mut mesh, &primitive, &buffers, world, name)?;
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    if mesh.triangles.is_empty() {
        return Err(invalid("has no triangles in its scene".into()));
    }
    Ok(mesh)
}

/// Every index the reading follows, in range: scenes to nodes, nodes to meshes and children,
/// primitives to accessors, accessors to buffer views, views to buffers.
fn check_indices(root: &gltf::json::Root) -> std::result::Result<(), String> {
    let within = |what: &str, index: usize, len: usize| {
        if index < len {
            Ok(())
        } else {
            Err(format!(
                "{what} index {index} is out of range (there are {len})"
            ))
        }
    };
    for scene in &root.scenes {
        for n in &scene.nodes {
            within("node", n.value(), root.nodes.len())?;
        }
    }
    for node in &root.nodes {
        if let Some(m) = &node.mesh {
            within("mesh", m.value(), root.meshes.len())?;
        }
        for c in node.children.iter().flatten() {
            within("node", c.value(), root.nodes.len())?;
        }
    }
    for mesh in &root.meshes {
        for p in &mesh.primitives {
            for a in p.attributes.values() {
                within("accessor", a.value(), root.accessors.len())?;
            }
            if let Some(i) = &p.indices {
                within("accessor", i.value(), root.accessors.len())?;
            }
            for target in p.targets.iter().flatten() {
                for a in [&target.positions, &target.normals, &target.tangents]
                    .into_iter()
                    .flatten()
                {
                    within("accessor", a.value(), root.accessors.len())?;
                }
            }
        }
    }
    for accessor in &root.accessors {
        if let Some(v) = &accessor.buffer_view {
            within("buffer view", v.value(), root.buffer_views.len())?;
        }
        if let Some(sparse) = &accessor.sparse {
            within(
                "buffer view",
                sparse.indices.buffer_view.value(),
                root.buffer_views.len(),
            )?;
            within(
                "buffer view",
                sparse.values.buffer_view.value(),
                root.buffer_views.len(),
            )?;
        }
    }
    for view in &root.buffer_views {
        within("buffer", view.buffer.value(), root.buffers.len())?;
    }
    Ok(())
}

fn add_primitive(
    mesh: &mut Mesh,
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    world: glam::Mat4,
    name: &str,
) -> Result<()> {
    let invalid = |problem: String| Error::invalid(name, problem);
    if primitive.mode() != gltf::mesh::Mode::Triangles {
        return Err(invalid(format!(
            "has a {:?} primitive: only triangle primitives are taken",
            primitive.mode()
        )));
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let positions: Vec<[f32; 3]> = reader
        .read_positions()
        .ok_or_else(|| invalid("has a primitive without positions".into()))?
        .map(|p| world.transform_point3(glam::Vec3::from(p)).to_array())
        .collect();
    let base = mesh.positions.len() as u32;
    let count = positions.len() as u32;
    let indices: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..count).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(invalid(format!(
            "has a triangle primitive of {} indices, not a multiple of 3",
            indices.len()
        )));
    }
    if let Some(&i) = indices.iter().find(|&&i| i >= count) {
        return Err(invalid(format!(
            "has an index {i} beyond its primitive's {count} vertices"
        )));
    }
    let corners = |values: &[[f32; 2]]| -> Vec<[[f32; 2]; 3]> {
        indices
            .chunks_exact(3)
            .map(|t| [0, 1, 2].map(|k| values[t[k] as usize]))
            .collect()
    };
    let uvs: Option<Vec<[f32; 2]>> = reader
        .read_tex_coords(0)
        .map(|c| c.into_f32().collect())
        .filter(|c: &Vec<[f32; 2]>| c.len() == positions.len());
    match (&mut mesh.uvs, uvs) {
        (Some(out), Some(uvs)) => out.extend(corners(&uvs)),
        (out, _) => *out = None,
    }
    // Normals go through the inverse transpose of the node's transform.
    let normal_matrix = glam::Mat3::from_mat4(world).inverse().transpose();
    let normals: Option<Vec<[f32; 3]>> = reader
        .read_normals()
        .map(|n| {
            n.map(|n| (normal_matrix * glam::Vec3::from(n)).to_array())
                .collect()
        })
        .filter(|n: &Vec<[f32; 3]>| n.len() == positions.len());
    match (&mut mesh.normals, normals) {
        (Some(out), Some(normals)) => out.extend(
            indices
                .chunks_exact(3)
                .map(|t| [0, 1, 2].map(|k| normals[t[k] as usize])),
        ),
        (out, _) => *out = None,
    }
    mesh.positions.extend(positions);
    mesh.triangles.extend(
        indices
            .chunks_exact(3)
            .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_glb_written_here_reads_back_with_its_triangles() {
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            uvs: None,
            normals: None,
        };
        let atlas = crate::mesh::bake::Atlas::new(1, 4, 0).unwrap();
        let glb = crate::mesh::glb::glb_bytes(&mesh, &atlas, &[0u8; 8]);
        let back = parse_gltf(&glb, "t.glb", None).unwrap();
        assert_eq!(back.triangles.len(), 1);
        assert_eq!(back.positions, mesh.positions);
        // Its texture coordinates and normals come back per corner.
        assert_eq!(back.uvs, Some(atlas.uvs.clone()));
        assert_eq!(back.normals, Some(mesh.corner_normals()));
    }

    #[test]
    fn bad_gltf_is_refused_by_name() {
        let err = parse_gltf(b"{\"asset\":{\"version\":\"2.0\"}}", "empty.gltf", None)
            .unwrap_err()
            .to_string();
        assert!(err.contains("empty.gltf"), "{err}");
        let err = parse_gltf(b"not gltf", "junk.glb", None)
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a valid glTF"), "{err}");
    }
}
