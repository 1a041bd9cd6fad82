//! glTF 2.0 meshes in (`.glb`, or `.gltf` with its buffers beside it or embedded), through the
//! `gltf` crate: every triangle primitive of the default scene's mesh instances, placed by their
//! nodes' world transforms, as one triangle mesh, with their first texture coordinates and their
//! normals where every primitive has them. Materials, textures and animation are ignored.

use super::Mesh;
use crate::error::{Error, Result};
use std::path::Path;

/// Parse glTF `bytes` (binary or JSON) named `name`; external buffers are read relative to
/// `base` (none: only embedded and GLB buffers). The mesh passes [`Mesh::validate`].
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
    check_glb_length(bytes).map_err(invalid)?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(not_gltf)?;
    check_indices(document.as_json()).map_err(invalid)?;
    check_accessors(document.as_json()).map_err(invalid)?;
    // The crate's own validation, on the document already parsed.
    let document = gltf::Document::from_json(document.into_json()).map_err(not_gltf)?;
    let buffers = load_buffers(&document, base, blob).map_err(invalid)?;
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
    mesh.validate(name)?;
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

/// A binary glTF's header gives the file's length: anything after it, or a file cut short, is
/// refused.
fn check_glb_length(bytes: &[u8]) -> std::result::Result<(), String> {
    if !bytes.starts_with(b"glTF") || bytes.len() < 12 {
        return Ok(());
    }
    let declared = u32::from_le_bytes(bytes[8..12].try_into().expect("four bytes")) as usize;
    match declared == bytes.len() {
        true => Ok(()),
        false => Err(format!(
            "its header gives a length of {declared} bytes, and the file has {}",
            bytes.len()
        )),
    }
}

/// The accessors a primitive's positions, normals, first texture coordinates and indices are
/// read through: of the types those take, not empty, within their buffer views and views within
/// their buffers, and no larger than all the buffers together (an accessor without a view, or
/// sparse, reads as zeros: a count of millions in a small file is refused before it is read).
/// (Run after [`check_indices`].)
fn check_accessors(root: &gltf::json::Root) -> std::result::Result<(), String> {
    use gltf::json::accessor::{ComponentType as C, Type};
    use gltf::json::mesh::Semantic;
    use gltf::json::validation::Checked;
    let all_buffers: u64 = root.buffers.iter().map(|b| b.byte_length.0).sum();
    let check = |index: usize, what: &str, want: Type, components: &[C]| {
        let accessor = &root.accessors[index];
        let (Checked::Valid(kind), Checked::Valid(component)) =
            (accessor.type_, accessor.component_type)
        else {
            return Err(format!("accessor {index} has an unknown type"));
        };
        let component = component.0;
        if kind != want || !components.contains(&component) {
            return Err(format!(
                "the {what} accessor {index} is {kind:?} of {component:?}; {what} are \
                 {want:?} of {}",
                components
                    .iter()
                    .map(|c| format!("{c:?}"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ));
        }
        let count = accessor.count.0;
        if count == 0 {
            return Err(format!("the {what} accessor {index} is empty"));
        }
        let element = (kind.multiplicity() * component.size()) as u64;
        if count.saturating_mul(element) > all_buffers {
            return Err(format!(
                "the {what} accessor {index} holds {count} elements, more than its file's \
                 {all_buffers} bytes of buffers can"
            ));
        }
        if let Some(sparse) = &accessor.sparse {
            if sparse.count.0 > count {
                return Err(format!(
                    "the {what} accessor {index} replaces {} of its {count} elements",
                    sparse.count.0
                ));
            }
        }
        let Some(view_index) = accessor.buffer_view else {
            return Ok(());
        };
        let view = &root.buffer_views[view_index.value()];
        let stride = view.byte_stride.map_or(element, |s| s.0 as u64);
        let offset = accessor.byte_offset.map_or(0, |o| o.0);
        let end = offset
            .saturating_add(stride.saturating_mul(count - 1))
            .saturating_add(element);
        if end > view.byte_length.0 {
            return Err(format!(
                "the {what} accessor {index} reads {end} bytes of buffer view {}, which has {}",
                view_index.value(),
                view.byte_length.0
            ));
        }
        let buffer = &root.buffers[view.buffer.value()];
        let view_end = view.byte_offset.map_or(0, |o| o.0) + view.byte_length.0;
        if view_end > buffer.byte_length.0 {
            return Err(format!(
                "buffer view {} ends at byte {view_end} of buffer {}, which has {}",
                view_index.value(),
                view.buffer.value(),
                buffer.byte_length.0
            ));
        }
        Ok(())
    };
    for mesh in &root.meshes {
        for p in &mesh.primitives {
            for (semantic, accessor) in &p.attributes {
                let (what, want, components): (&str, Type, &[C]) = match semantic {
                    Checked::Valid(Semantic::Positions) => ("positions", Type::Vec3, &[C::F32]),
                    Checked::Valid(Semantic::Normals) => ("normals", Type::Vec3, &[C::F32]),
                    Checked::Valid(Semantic::TexCoords(0)) => {
                        ("texture coordinates", Type::Vec2, &[C::F32, C::U8, C::U16])
                    }
                    _ => continue,
                };
                check(accessor.value(), what, want, components)?;
            }
            if let Some(indices) = &p.indices {
                check(
                    indices.value(),
                    "indices",
                    Type::Scalar,
                    &[C::U8, C::U16, C::U32],
                )?;
            }
        }
    }
    Ok(())
}

/// The document's buffers: the GLB's binary chunk, embedded `data:` URIs, and files beside the
/// document (`base`; None: none are read). A file must be a regular file (not a device that
/// never ends) named by a relative path, and is read to its buffer's length only.
fn load_buffers(
    document: &gltf::Document,
    base: Option<&Path>,
    mut blob: Option<Vec<u8>>,
) -> std::result::Result<Vec<gltf::buffer::Data>, String> {
    use std::io::Read;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let length = buffer.length();
        let mut data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or(format!(
                "buffer {i} is the binary chunk, which the file lacks"
            ))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                gltf::buffer::Data::from_source(buffer.source(), None)
                    .map_err(|e| format!("buffer {i}'s data URI cannot be read: {e}"))?
                    .0
            }
            gltf::buffer::Source::Uri(uri) => {
                let Some(base) = base else {
                    return Err(format!(
                        "buffer {i} is the file {uri}; only buffers inside the file are read \
                         here (use a .glb)"
                    ));
                };
                let relative = urlencoding::decode(uri)
                    .ok()
                    .filter(|p| !p.contains(':') && !p.starts_with('/'))
                    .ok_or(format!(
                        "buffer {i} names {uri}; a buffer file is named by a path relative to \
                         the document"
                    ))?;
                let path = base.join(&*relative);
                let problem = |e: std::io::Error| {
                    format!(
                        "buffer {i}: {}: {}",
                        path.display(),
                        crate::error::io_problem(&e)
                    )
                };
                let file = std::fs::File::open(&path).map_err(problem)?;
                if !file.metadata().map_err(problem)?.is_file() {
                    return Err(format!("buffer {i}: {} is not a file", path.display()));
                }
                let mut data = Vec::new();
                file.take(length as u64)
                    .read_to_end(&mut data)
                    .map_err(problem)?;
                data
            }
        };
        if data.len() < length {
            return Err(format!(
                "buffer {i} has {} bytes; the document gives it {length}",
                data.len()
            ));
        }
        while data.len() % 4 != 0 {
            data.push(0);
        }
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
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
        let glb = crate::mesh::glb::glb_bytes(&mesh, &atlas, &[0u8; 8]).unwrap();
        let back = parse_gltf(&glb, "t.glb", None).unwrap();
        assert_eq!(back.triangles.len(), 1);
        assert_eq!(back.positions, mesh.positions);
        // Its texture coordinates and normals come back per corner.
        assert_eq!(back.uvs, Some(atlas.uvs.clone()));
        assert_eq!(back.normals, Some(mesh.corner_normals()));
        // A GLB is as long as its header says.
        for damaged in [[&glb[..], b"junk"].concat(), glb[..glb.len() - 4].to_vec()] {
            let e = parse_gltf(&damaged, "t.glb", None).unwrap_err().to_string();
            assert!(e.contains("and the file has"), "{e}");
        }
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

#[cfg(test)]
mod hostile_files {
    use super::*;

    /// A one-triangle glTF whose 36-byte buffer is embedded, with `accessor` as its positions
    /// accessor and `uri` as its buffer.
    fn gltf(accessor: &str, uri: &str) -> Vec<u8> {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0}}], "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "accessors": [{accessor}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "buffers": [{{"byteLength": 36, "uri": "{uri}"}}]}}"#
        )
        .into_bytes()
    }
    /// The triangle (0, 0, 0), (1, 0, 0), (0, 1, 0) as little-endian f32s.
    const TRIANGLE: [u8; 36] = [
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 128, 63, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 128, 63, 0, 0, 0, 0,
    ];
    /// [`TRIANGLE`] as a data URI.
    const TRIANGLE_URI: &str =
        "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";
    const FINE: &str = r#"{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0]}"#;

    fn refused(bytes: &[u8], base: Option<&Path>, needle: &str) {
        let e = parse_gltf(bytes, "m.gltf", base).unwrap_err().to_string();
        assert!(e.contains(needle), "expected {needle:?} in: {e}");
    }

    #[test]
    fn accessors_are_checked_before_they_are_read() {
        assert_eq!(
            parse_gltf(&gltf(FINE, TRIANGLE_URI), "m.gltf", None)
                .unwrap()
                .triangles
                .len(),
            1
        );
        // Millions of zeros from a sparse accessor without a view would be read.
        let bomb = FINE
            .replace("\"bufferView\": 0, ", "")
            .replace("3,", "400000000,");
        refused(&gltf(&bomb, TRIANGLE_URI), None, "holds 400000000 elements");
        let bytes = FINE.replace("5126", "5121");
        refused(
            &gltf(&bytes, TRIANGLE_URI),
            None,
            "positions are Vec3 of F32",
        );
        refused(
            &gltf(&FINE.replace("\"count\": 3", "\"count\": 0"), TRIANGLE_URI),
            None,
            "is empty",
        );
        let past = FINE.replace(
            "\"bufferView\": 0,",
            "\"bufferView\": 0, \"byteOffset\": 4,",
        );
        refused(
            &gltf(&past, TRIANGLE_URI),
            None,
            "reads 40 bytes of buffer view 0, which has 36",
        );
    }

    #[test]
    fn buffer_files_are_regular_files_beside_the_document() {
        refused(
            &gltf(FINE, "b.bin"),
            None,
            "only buffers inside the file are read",
        );
        let dir = tempfile::tempdir().unwrap();
        refused(
            &gltf(FINE, "file:///dev/zero"),
            Some(dir.path()),
            "relative to the document",
        );
        std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero")).unwrap();
        refused(&gltf(FINE, "zero"), Some(dir.path()), "is not a file");
        refused(
            &gltf(FINE, "missing%20file.bin"),
            Some(dir.path()),
            "No such file",
        );
        std::fs::write(dir.path().join("short file.bin"), [0u8; 20]).unwrap();
        refused(
            &gltf(FINE, "short%20file.bin"),
            Some(dir.path()),
            "has 20 bytes",
        );
        std::fs::write(dir.path().join("b.bin"), TRIANGLE).unwrap();
        assert!(parse_gltf(&gltf(FINE, "b.bin"), "m.gltf", Some(dir.path())).is_ok());
    }
}
