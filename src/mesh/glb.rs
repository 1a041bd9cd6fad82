//! Binary glTF 2.0 (`.glb`) of a textured triangle mesh: one primitive, unindexed (each
//! triangle corner has its own texture coordinate in the atlas), with smooth normals
//! ([`Mesh::vertex_normals`]), the atlas PNG embedded.

use super::bake::Atlas;
use super::Mesh;
use serde_json::json;

/// The .glb bytes of `mesh` textured by `png` through `atlas`.
pub fn glb_bytes(mesh: &Mesh, atlas: &Atlas, png: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    write_glb(&mut out, mesh, atlas, png).expect("writing to memory");
    out
}

/// Write the .glb of [`glb_bytes`] to `out`, the PNG straight from `png` (a large atlas's PNG is
/// not copied into the file's bytes first).
pub fn write_glb(
    out: &mut impl std::io::Write,
    mesh: &Mesh,
    atlas: &Atlas,
    png: &[u8],
) -> std::io::Result<()> {
    let corners = mesh.triangles.len() * 3;
    // The binary chunk: positions, texture coordinates, the PNG, zeros to a whole word.
    let mut geometry = Vec::with_capacity(corners * 32);
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for t in &mesh.triangles {
        for &i in t {
            let p = mesh.positions[i as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
                geometry.extend_from_slice(&p[k].to_le_bytes());
            }
        }
    }
    let normal_offset = geometry.len();
    let normals = mesh.vertex_normals();
    for t in &mesh.triangles {
        for &i in t {
            for c in normals[i as usize] {
                geometry.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let uv_offset = geometry.len();
    for uv in &atlas.uvs {
        for c in uv {
            geometry.extend_from_slice(&c[0].to_le_bytes());
            geometry.extend_from_slice(&c[1].to_le_bytes());
        }
    }
    let png_offset = geometry.len();
    let padding = (4 - (png_offset + png.len()) % 4) % 4;
    let bin_len = png_offset + png.len() + padding;
    let doc = json!({
        "asset": {"version": "2.0", "generator": "solidsynth"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 2, "TEXCOORD_0": 1},
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
        // Linear filtering, clamped: the atlas keeps each triangle's texels inside its cell.
        "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"bufferView": 2, "mimeType": "image/png"}],
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normal_offset, "target": 34962},
            {"buffer": 0, "byteOffset": uv_offset, "byteLength": png_offset - uv_offset, "target": 34962},
            {"buffer": 0, "byteOffset": png_offset, "byteLength": png.len()},
            {"buffer": 0, "byteOffset": normal_offset, "byteLength": uv_offset - normal_offset, "target": 34962}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": corners, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": corners, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5126, "count": corners, "type": "VEC3"}
        ]
    });
    let mut json_bytes = serde_json::to_vec(&doc).expect("serializable");
    while json_bytes.len() % 4 != 0 {
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
        };
        let atlas = Atlas::new(1, 4).unwrap();
        let png = [1u8, 2, 3, 4, 5];
        let b = glb_bytes(&mesh, &atlas, &png);
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
            b.len()
        );
        let jlen = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        let doc: serde_json::Value = serde_json::from_slice(&b[20..20 + jlen]).unwrap();
        assert_eq!(doc["accessors"][0]["count"], 3);
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
