//! PLY meshes in (ASCII or binary), through `ply-rs-bw`: the header is read and checked
//! first, so that a file declaring more elements than its bytes can hold, or than memory can,
//! is refused before any element is read, and the data must end the file.

use super::Mesh;
use crate::error::{Error, Result};
use ply_rs_bw::ply::{Encoding, Header, PropertyType, ScalarType};

/// The memory `ply-rs-bw` takes per element read, about: a map of its properties (measured
/// with the crate's `DefaultElement`: a hash map node, the name and the value per property).
const BYTES_PER_ELEMENT: u64 = 64;
const BYTES_PER_PROPERTY: u64 = 128;

/// Parse a PLY file (ASCII or binary): `vertex` elements with x, y, z and `face` elements with
/// a `vertex_indices` (or `vertex_index`) list; polygons are fanned into triangles. The mesh
/// passes [`Mesh::validate`].
pub fn parse_ply(bytes: &[u8], name: &str) -> Result<Mesh> {
    use ply_rs_bw::parser::{Parser, Reader};
    use ply_rs_bw::ply::{DefaultElement, Property};
    let bad = |why: String| Error::invalid(name, why);
    let not_ply = |e: ply_rs_bw::parser::ParseError| bad(format!("not a valid PLY file: {e}"));
    let parser = Parser::<DefaultElement>::new();
    let mut reader = Reader::new(bytes);
    let header = parser.read_header(&mut reader).map_err(not_ply)?;
    check_counts(&header, reader.get_ref().len()).map_err(bad)?;
    let payload = parser.read_payload(&mut reader, &header).map_err(not_ply)?;
    check_end(&header, reader.into_inner()).map_err(bad)?;
    let scalar = |p: Option<&Property>| -> Option<f32> {
        Some(match p? {
            Property::Float(v) => *v,
            Property::Double(v) => *v as f32,
            Property::Int(v) => *v as f32,
            Property::UInt(v) => *v as f32,
            Property::Short(v) => *v as f32,
            Property::UShort(v) => *v as f32,
            Property::Char(v) => *v as f32,
            Property::UChar(v) => *v as f32,
            _ => return None,
        })
    };
    let vertices = payload
        .get("vertex")
        .ok_or_else(|| bad("no vertex element".into()))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let c = ["x", "y", "z"].map(|k| scalar(v.get(k)));
        match c {
            [Some(x), Some(y), Some(z)] => positions.push([x, y, z]),
            _ => return Err(bad(format!("vertex {i} lacks a numeric x, y or z"))),
        }
    }
    // Per-vertex texture coordinates under any of their usual names, and normals: kept when
    // every vertex has them.
    let uv_names = [
        ["u", "v"],
        ["s", "t"],
        ["texture_u", "texture_v"],
        ["texture_s", "texture_t"],
    ];
    let vertex_uvs: Option<Vec<[f32; 2]>> = uv_names.iter().find_map(|[u, v]| {
        vertices
            .iter()
            .map(|p| Some([scalar(p.get(*u))?, 1.0 - scalar(p.get(*v))?]))
            .collect()
    });
    let vertex_normals: Option<Vec<[f32; 3]>> = vertices
        .iter()
        .map(|p| Some(["nx", "ny", "nz"].map(|k| scalar(p.get(k)))))
        .map(|n| match n? {
            [Some(x), Some(y), Some(z)] => Some([x, y, z]),
            _ => None,
        })
        .collect();
    let mut triangles = Vec::new();
    for (i, f) in payload.get("face").into_iter().flatten().enumerate() {
        let list = f.get("vertex_indices").or_else(|| f.get("vertex_index"));
        let idx: Vec<i64> = match list {
            Some(Property::ListInt(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUInt(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListShort(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUShort(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListChar(v)) => v.iter().map(|&x| x as i64).collect(),
            Some(Property::ListUChar(v)) => v.iter().map(|&x| x as i64).collect(),
            _ => return Err(bad(format!("face {i} has no integer vertex_indices list"))),
        };
        if idx.iter().any(|&x| x < 0 || x > u32::MAX as i64) {
            return Err(bad(format!("face {i} has a negative or huge vertex index")));
        }
        for k in 1..idx.len().saturating_sub(1) {
            triangles.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    // (Corners out of range are refused by `validate`; they get no attributes here.)
    let per_corner = |t: &[u32; 3], of: &dyn Fn(usize) -> Option<[f32; 3]>| {
        t.map(|i| of(i as usize).unwrap_or_default())
    };
    let uvs = vertex_uvs.filter(|u| !u.is_empty()).map(|u| {
        triangles
            .iter()
            .map(|t| per_corner(t, &|i| u.get(i).map(|c| [c[0], c[1], 0.0])).map(|c| [c[0], c[1]]))
            .collect()
    });
    let normals = vertex_normals.filter(|n| !n.is_empty()).map(|n| {
        triangles
            .iter()
            .map(|t| per_corner(t, &|i| n.get(i).copied()))
            .collect()
    });
    let mesh = Mesh {
        positions,
        triangles,
        uvs,
        normals,
    };
    mesh.validate(name)?;
    Ok(mesh)
}

/// How far into a gzipped PLY's inflated bytes its header is looked for.
const MAX_HEADER_BYTES: u64 = 1 << 20;
/// The most bytes one number of an ASCII payload may take with its separators, when bounding
/// how far a gzipped PLY may inflate (a float printed in full takes under 30).
const MAX_ASCII_NUMBER_BYTES: u64 = 256;
/// Blank lines an ASCII payload may end in, within that bound.
const MAX_ASCII_TRAILING_BYTES: u64 = 64 << 10;

/// Parse a gzipped PLY. Its header is inflated first, then the whole stream only up to the
/// most bytes the header's elements can take (or the memory there is, if less): a small file
/// inflating to gigabytes is refused once past what its header declares, not read whole first.
pub fn parse_ply_gz(bytes: &[u8], name: &str) -> Result<Mesh> {
    use crate::util::gzip::{inflate, inflate_prefix, InflateError};
    use crate::util::memory::{available_memory, available_text, human_bytes};
    use ply_rs_bw::parser::{Parser, Reader};
    let bad = |why: String| Error::invalid(name, why);
    let prefix = inflate_prefix(bytes, MAX_HEADER_BYTES).map_err(|e| bad(e.to_string()))?;
    let mut reader = Reader::new(&prefix[..]);
    let header = match Parser::<ply_rs_bw::ply::DefaultElement>::new().read_header(&mut reader) {
        Ok(header) => header,
        Err(_) if prefix.len() as u64 == MAX_HEADER_BYTES && prefix.starts_with(b"ply") => {
            return Err(bad(format!(
                "no end_header in its first {} of inflated data",
                human_bytes(MAX_HEADER_BYTES)
            )))
        }
        Err(e) => return Err(bad(format!("not a valid PLY file: {e}"))),
    };
    let header_bytes = (prefix.len() - reader.get_ref().len()) as u64;
    let most = header_bytes.saturating_add(payload_max_bytes(&header));
    let available = available_memory();
    let raw = inflate(bytes, most.min(available)).map_err(|e| match e {
        InflateError::TooLarge if most <= available => bad(format!(
            "inflates past the {} its header and elements can take",
            human_bytes(most)
        )),
        InflateError::TooLarge => bad(format!(
            "inflates to more than the memory there is: {}",
            available_text(available)
        )),
        other => bad(other.to_string()),
    })?;
    parse_ply(&raw, name)
}

/// The most bytes the payload `header` declares can take: binary scalars their size, lists
/// their count and as many items as the count's type can say; ASCII numbers
/// [`MAX_ASCII_NUMBER_BYTES`] each, and blank lines after them.
fn payload_max_bytes(header: &Header) -> u64 {
    let ascii = header.encoding == Encoding::Ascii;
    let number = |t: &ScalarType| match ascii {
        true => MAX_ASCII_NUMBER_BYTES,
        false => scalar_bytes(t),
    };
    let most_items = |t: &ScalarType| -> u64 {
        match t {
            ScalarType::Char => i8::MAX as u64,
            ScalarType::UChar => u8::MAX as u64,
            ScalarType::Short => i16::MAX as u64,
            ScalarType::UShort => u16::MAX as u64,
            ScalarType::Int => i32::MAX as u64,
            _ => u32::MAX as u64,
        }
    };
    let mut total = if ascii { MAX_ASCII_TRAILING_BYTES } else { 0 };
    for element in header.elements.values() {
        let element_bytes = element
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) => number(t),
                PropertyType::List(count, item) => {
                    number(count).saturating_add(most_items(count).saturating_mul(number(item)))
                }
            })
            .fold(0u64, u64::saturating_add);
        total = total.saturating_add((element.count as u64).saturating_mul(element_bytes));
    }
    total
}

fn scalar_bytes(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The smallest number of bytes one element of `properties` takes in the payload: a binary
/// scalar's size, a binary list's count (the list may be empty); in ASCII a number and a space
/// or line end each. At least one byte, so that a count of elements without properties is
/// bounded by the file too.
fn element_min_bytes(encoding: Encoding, properties: &[&PropertyType]) -> u64 {
    let bytes: u64 = match encoding {
        Encoding::Ascii => 2 * properties.len() as u64,
        _ => properties
            .iter()
            .map(|p| match p {
                PropertyType::Scalar(t) => scalar_bytes(t),
                PropertyType::List(count, _) => scalar_bytes(count),
            })
            .sum(),
    };
    bytes.max(1)
}

/// Refuse element counts that the `data` bytes after the header cannot hold, or that would take
/// more memory to read than there is.
fn check_counts(header: &Header, data: usize) -> std::result::Result<(), String> {
    let mut memory = 0u64;
    for (name, element) in &header.elements {
        let properties: Vec<&PropertyType> =
            element.properties.values().map(|p| &p.data_type).collect();
        let count = element.count as u64;
        let least = count.saturating_mul(element_min_bytes(header.encoding, &properties));
        if least > data as u64 {
            return Err(format!(
                "declares {count} '{name}' elements, which take at least {least} bytes, and \
                 {data} bytes follow the header"
            ));
        }
        memory = memory.saturating_add(
            count.saturating_mul(BYTES_PER_ELEMENT + BYTES_PER_PROPERTY * properties.len() as u64),
        );
    }
    let available = crate::util::memory::available_memory();
    if memory > available {
        use crate::util::memory::{available_text, human_bytes};
        return Err(format!(
            "reading its elements needs about {} of memory, {}",
            human_bytes(memory),
            available_text(available)
        ));
    }
    Ok(())
}

/// Refuse bytes after the last element (an ASCII file may end in blank lines).
fn check_end(header: &Header, rest: &[u8]) -> std::result::Result<(), String> {
    let extra = match header.encoding {
        Encoding::Ascii => rest.iter().filter(|b| !b.is_ascii_whitespace()).count(),
        _ => rest.len(),
    };
    match extra {
        0 => Ok(()),
        _ => Err(format!(
            "{} bytes follow the elements its header declares",
            rest.len()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRIANGLE: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list uchar int \
        vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

    fn refused(bytes: &[u8], needle: &str) {
        let e = parse_ply(bytes, "m.ply").unwrap_err().to_string();
        assert!(e.contains(needle), "expected {needle:?} in: {e}");
    }

    #[test]
    fn counts_are_checked_against_the_file_before_reading() {
        assert_eq!(
            parse_ply(TRIANGLE.as_bytes(), "m.ply")
                .unwrap()
                .triangles
                .len(),
            1
        );
        // Elements without properties take no bytes, and memory for each one read.
        let empty = TRIANGLE.replace("end_header", "element junk 3000000000\nend_header");
        refused(empty.as_bytes(), "declares 3000000000 'junk' elements");
        let many = TRIANGLE.replace("element vertex 3", "element vertex 300000");
        refused(many.as_bytes(), "which take at least 1800000 bytes");
        let binary = TRIANGLE
            .replace("ascii", "binary_little_endian")
            .replace("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "");
        refused(binary.as_bytes(), "0 bytes follow the header");
    }

    use crate::io::nrrd::gzip_bytes as gzip;

    #[test]
    fn a_gzipped_file_inflates_only_as_far_as_its_header_allows() {
        let mesh = parse_ply_gz(&gzip(TRIANGLE.as_bytes()), "m.ply.gz").unwrap();
        assert_eq!(mesh.triangles.len(), 1);
        // 3 vertices of 3 numbers and a face of up to 256 numbers, at most 256 bytes each, and
        // 64 KiB of blank lines: 64 MiB of zeros after them is refused after about 200 KiB.
        let bomb = [TRIANGLE.as_bytes(), &vec![0u8; 64 << 20]].concat();
        let e = parse_ply_gz(&gzip(&bomb), "m.ply.gz")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("inflates past the") && e.contains("its header and elements can take"),
            "{e}"
        );
        let binary = TRIANGLE
            .replace("ascii", "binary_little_endian")
            .replace("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "");
        // Binary: 3 x 12 bytes of vertices and a face of at most 1 + 255 x 4 bytes.
        let header = binary.len() as u64;
        let parsed = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new()
            .read_header(&mut ply_rs_bw::parser::Reader::new(binary.as_bytes()))
            .unwrap();
        assert_eq!(payload_max_bytes(&parsed), 36 + 1 + 255 * 4);
        let e = parse_ply_gz(
            &gzip(&[binary.as_bytes(), &[0u8; 2000]].concat()),
            "m.ply.gz",
        )
        .unwrap_err()
        .to_string();
        let most = crate::util::memory::human_bytes(header + 1057);
        assert!(e.contains(&format!("past the {most} its")), "{e}");
        let text = parse_ply_gz(&gzip(&vec![b'c'; 2 << 20]), "m.ply.gz").unwrap_err();
        assert!(text.to_string().contains("not a valid PLY file"), "{text}");
        let endless = [b"ply\nformat ascii 1.0\n".as_slice(), &vec![b'c'; 2 << 20]].concat();
        let endless = parse_ply_gz(&gzip(&endless), "m.ply.gz").unwrap_err();
        assert!(
            endless
                .to_string()
                .contains("no end_header in its first 1.0 MiB"),
            "{endless}"
        );
    }

    #[test]
    fn the_elements_end_the_file() {
        let padded = format!("{TRIANGLE}\n \n");
        assert!(parse_ply(padded.as_bytes(), "m.ply").is_ok());
        refused(
            format!("{TRIANGLE}junk\n").as_bytes(),
            "bytes follow the elements",
        );
        let mut binary = TRIANGLE
            .replace("ascii", "binary_little_endian")
            .replace("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "")
            .into_bytes();
        for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
            binary.extend(v.iter().flat_map(|c| c.to_le_bytes()));
        }
        binary.push(3);
        binary.extend([0i32, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
        assert!(parse_ply(&binary, "m.ply").is_ok());
        binary.push(b'\n');
        refused(&binary, "1 bytes follow the elements");
    }
}
