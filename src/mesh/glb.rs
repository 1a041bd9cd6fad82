//! Binary glTF 2.0 (`.glb`) of a textured triangle mesh: one indexed primitive whose vertices
//! are the distinct (position, texture coordinate, normal) corners (triangles of one UV island
//! share theirs; packed cells give each corner its own), with normals from the mesh
//! ([`Mesh::corner_normals`]: the file's, else area-weighted smooth ones), the atlas PNG
//! embedded.

use super::bake::Atlas;
use super::Mesh;
use serde_json::json;
use std::collections::HashMap;

/// The .glb bytes of `mesh` textured by `png` through `atlas`; an error when the atlas was not
/// made for the mesh ([`Atlas::check_mesh`]).
pub fn glb_bytes(mesh: &Mesh, atlas: &Atlas, png: &[u8]) -> crate::Result<Vec<u8>> {
    atlas.check_mesh(mesh, "mesh")?;
    let mut out = Vec::new();
    write_glb(&mut out, mesh, atlas, png).expect("writing to memory, the mesh checked");
    Ok(out)
}

/// The distinct corners of the mesh (position index, texture coordinate, normal, by their
/// bits) in order of first use, and per triangle corner its vertex.
struct Vertices {
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

fn vertices(mesh: &Mesh, atlas: &Atlas) -> Vertices {
    let normals = mesh.corner_normals();
    let mut seen: HashMap<(u32, [u32; 2], [u32; 3]), u32> = HashMap::new();
    let mut v = Vertices {
        positions: Vec::new(),
        uvs: Vec::new(),
        normals: Vec::new(),
        indices: Vec::with_capacity(mesh.triangles.len() * 3),
    };
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (uv, n) = (atlas.uvs[t][k], normals[t][k]);
            let key = (tri[k], uv.map(f32::to_bits), n.map(f32::to_bits));
            let next = v.positions.len() as u32;
            let index = *seen.entry(key).or_insert_with(|| {
                v.positions.push(mesh.positions[tri[k] as usize]);
                v.uvs.push(uv);
                v.normals.push(n);
                next
            });
            v.indices.push(index);
        }
    }
    v
}

/// Write the .glb of [`glb_bytes`] to `out`, the PNG straight from `png` (a large atlas's PNG is
/// not copied into the file's bytes first). An `InvalidInput` error, before anything is
/// written, when the atlas was not made for the mesh ([`Atlas::check_mesh`]).
pub fn write_glb(
    out: &mut impl std::io::Write,
    mesh: &Mesh,
    atlas: &Atlas,
    png: &[u8],
) -> std::io::Result<()> {
    atlas
        .check_mesh(mesh, "mesh")
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))?;
    let v = vertices(mesh, atlas);
    let count = v.positions.len();
    // The binary chunk: positions, normals, texture coordinates, indices, the PNG, zeros to a
    // whole word.
    let mut geometry = Vec::with_capacity(count * 32 + v.indices.len() * 4);
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &v.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
            geometry.extend_from_slice(&p[k].to_le_bytes());
        }
    }
    let normal_offset = geometry.len();
    for n in &v.normals {
        for c in n {
            geometry.extend_from_slice(&c.to_le_bytes());
        }
    }
    let uv_offset = geometry.len();
    for uv in &v.uvs {
        geometry.extend_from_slice(&uv[0].to_le_bytes());
        geometry.extend_from_slice(&uv[1].to_le_bytes());
    }
    let index_offset = geometry.len();
    for i in &v.indices {
        geometry.extend_from_slice(&i.to_le_bytes());
    }
    let png_offset = geometry.len();
    let padding = (4 - (png_offset + png.len()) % 4) % 4;
    let bin_len = png_offset + png.len() + padding;
    // Linear filtering, clamped; mipmapped only where the atlas keeps mip levels from mixing
    // cells (a gutter, or the mesh's own UVs dilated).
    let min_filter = if atlas.mip_safe() { 9987 } else { 9729 };
    let doc = json!({
        "asset": {"version": "2.0", "generator": "solidsynth"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 2, "TEXCOORD_0": 1},
            "indices": 3,
            "material": 0,
            "mode": 4
        }]}],
        "materials": [{
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0
            },
            "doubleSided": true
        }],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": min_filter, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"bufferView": 2, "mimeType": "image/png"}],
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normal_offset, "target": 34962},
            {"buffer": 0, "byteOffset": uv_offset, "byteLength": index_offset - uv_offset, "target": 34962},
            {"buffer": 0, "byteOffset": png_offset, "byteLength": png.len()},
            {"buffer": 0, "byteOffset": normal_offset, "byteLength": uv_offset - normal_offset, "target": 34962},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": png_offset - index_offset, "target": 34963}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": count, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5126, "count": count, "type": "VEC3"},
            {"bufferView": 4, "componentType": 5125, "count": v.indices.len(), "type": "SCALAR"}
        ]
    });
    let mut json_bytes = serde_json::to_vec(&doc).expect("serializable");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin_len;
    out.write_all(b"glTF")?;
    out.write_all(&2u32.to_le_bytes())?;
    out.write_all(&(total as u32).to_le_bytes())?;
    out.write_all(&(json_bytes.len() as u32).to_le_bytes())?;
    out.write_all(b"JSON")?;
    out.write_all(&json_bytes)?;
    out.write_all(&(bin_len as u32).to_le_bytes())?;
    out.write_all(b"BIN\0")?;
    out.write_all(&geometry)?;
    out.write_all(png)?;
    out.write_all(&[0u8; 3][..padding])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_chunks_are_consistent() {
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            uvs: None,
            normals: None,
        };
        let atlas = Atlas::new(1, 4, 0).unwrap();
        let png = [1u8, 2, 3, 4, 5];
        let b = glb_bytes(&mesh, &atlas, &png).unwrap();
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
            b.len()
        );
        let jlen = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        let doc: serde_json::Value = serde_json::from_slice(&b[20..20 + jlen]).unwrap();
        assert_eq!(doc["accessors"][0]["count"], 3);
        assert_eq!(doc["accessors"][3]["count"], 3);
        assert_eq!(doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"], 2);
        let blen = u32::from_le_bytes(b[20 + jlen..24 + jlen].try_into().unwrap()) as usize;
        assert_eq!(&b[24 + jlen..28 + jlen], b"BIN\0");
        assert_eq!(28 + jlen + blen, b.len());
        assert_eq!(doc["buffers"][0]["byteLength"], blen);
        // The embedded image is the PNG given.
        let view = &doc["bufferViews"][2];
        let off = 28 + jlen + view["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(&b[off..off + 5], &png);
    }
}
