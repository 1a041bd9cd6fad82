//! OpenVDB (`.vdb`) files for solid volumes: two grids over the same dense box, `density` (a
//! `FloatGrid` of class "fog volume": the mean of r, g, b over 255, or the first channel for 1
//! or 2 channels) and `color` (a `Vec3SGrid`: r, g, b over 255, grey replicated below 3
//! channels). Voxel (x, y, z) lies at index coordinate (x, y, z); every voxel of the box is
//! active and the background is 0. No crate writes VDB; the format (file version 224, the one
//! OpenVDB 10 writes) is simple enough for the fixed tree shape written here.
//!
//! All numbers are little-endian; a string is a u32 length then its bytes. The file holds:
//!
//! | section           | contents                                                             |
//! |-------------------|----------------------------------------------------------------------|
//! | header            | magic 0x56444220 (i64), format 224 (u32), library 10.0 (2 × u32),    |
//! |                   | "has grid offsets" 1 (u8), a 36-character UUID, file metadata (0)    |
//! | grid count        | u32 (2)                                                              |
//! | grid descriptor   | name, tree type, instance parent (""), then i64 offsets of the grid  |
//! |                   | (just past them), of its leaf buffers and of its end                 |
//! | compression       | u32 flags: `COMPRESS_ACTIVE_MASK` only (no zlib, no Blosc)           |
//! | metadata          | u32 count, then per entry name, type name and u32-sized value        |
//! | transform         | map type name, then the map's `Vec3d` fields, derived terms included |
//! | topology          | buffer count 1; root: background, 0 tiles, child count, then per     |
//! |                   | child its origin and its 5-level node; internal nodes: child mask,   |
//! |                   | value mask, tile values, children in index order; leaves: value mask |
//! | buffers           | per leaf, in the same order: value mask, then its values             |
//!
//! Nodes span 4096 (5-level), 128 (4-level) and 8 (leaf) voxels per axis; inside a node the
//! linear index is `(x << 2n) | (y << n) | z` (z fastest) and a mask is one bit per index, bit
//! i in byte i / 8. Every value array starts with a metadata byte, 0 ("inactive values are the
//! background"), and, because the grid sets `COMPRESS_ACTIVE_MASK`, holds only the active
//! values: none for internal nodes (they hold no tiles), the voxels inside the box for a leaf.
//!
//! `scripts/vdb_prototype.py` is the same writer in Python and writes the same bytes;
//! `scripts/vdb_check.py` reads a file with OpenVDB and compares it with the raw volume.

use super::atomic;
use crate::error::Result;
use crate::volume::Volume;
use std::path::Path;

const MAGIC: i64 = 0x5644_4220;
const FILE_VERSION: u32 = 224;
const LIBRARY_VERSION: [u32; 2] = [10, 0];
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// The per-array compression metadata saying every inactive value is the background.
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
/// log2 of the voxels per axis spanned by a 5-level node, a 4-level node and a leaf.
const LOG2_SPAN: [u32; 3] = [12, 7, 3];

/// Where the grids lie in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VdbOptions {
    /// The edge of a voxel, in world units.
    pub voxel_size: f64,
    /// The world position of voxel (0, 0, 0).
    pub origin: [f64; 3],
}

impl Default for VdbOptions {
    fn default() -> VdbOptions {
        VdbOptions {
            voxel_size: 1.0,
            origin: [0.0; 3],
        }
    }
}

/// One grid written from the volume: its value type's name, size and encoding.
struct Grid {
    name: &'static str,
    tree_type: &'static str,
    class: Option<&'static str>,
    value_size: usize,
    /// Appends the value of the voxel whose first byte is at the given index.
    encode: fn(&Volume, usize, &mut Vec<u8>),
}

const GRIDS: [Grid; 2] = [
    Grid {
        name: "density",
        tree_type: "Tree_float_5_4_3",
        class: Some("fog volume"),
        value_size: 4,
        encode: density,
    },
    Grid {
        name: "color",
        tree_type: "Tree_vec3s_5_4_3",
        // Unknown class: OpenVDB writes no "class" entry then.
        class: None,
        value_size: 12,
        encode: color,
    },
];

fn density(v: &Volume, i: usize, out: &mut Vec<u8>) {
    let d = &v.data;
    let value = if v.channels >= 3 {
        (d[i] as u32 + d[i + 1] as u32 + d[i + 2] as u32) as f64 / 765.0
    } else {
        d[i] as f64 / 255.0
    };
    out.extend_from_slice(&(value as f32).to_le_bytes());
}

fn color(v: &Volume, i: usize, out: &mut Vec<u8>) {
    let d = &v.data;
    let rgb = if v.channels >= 3 {
        [d[i], d[i + 1], d[i + 2]]
    } else {
        [d[i]; 3]
    };
    for c in rgb {
        out.extend_from_slice(&((c as f64 / 255.0) as f32).to_le_bytes());
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f64(out: &mut Vec<u8>, v: f64) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_string(out: &mut Vec<u8>, s: &[u8]) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s);
}

fn put_meta(out: &mut Vec<u8>, name: &str, type_name: &str, value: &[u8]) {
    put_string(out, name.as_bytes());
    put_string(out, type_name.as_bytes());
    put_string(out, value);
}

/// A UUID derived from the content (OpenVDB only stores it), so equal inputs give equal files.
fn uuid(v: &Volume, o: &VdbOptions) -> String {
    let mut key = Vec::with_capacity(48);
    for n in [v.nx, v.ny, v.nz, v.channels] {
        key.extend_from_slice(&n.to_le_bytes());
    }
    for f in [o.voxel_size, o.origin[0], o.origin[1], o.origin[2]] {
        key.extend_from_slice(&f.to_le_bytes());
    }
    let crc = |parts: [&[u8]; 2]| {
        let mut h = crc32fast::Hasher::new();
        for p in parts {
            h.update(p);
        }
        h.finalize()
    };
    let (data, key, none): (&[u8], &[u8], &[u8]) = (&v.data, &key, &[]);
    let words = [
        crc([data, none]),
        crc([key, none]),
        crc([key, data]),
        crc([data, key]),
    ];
    let h: String = words.iter().map(|w| format!("{w:08x}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}

/// The (origin, index in the parent's masks) of the children of the node at `origin` of
/// `level` (0: 5-level node, 1: 4-level node) that touch the volume, in index order (the order
/// OpenVDB writes and reads them in).
fn children(v: &Volume, origin: [u32; 3], level: usize) -> Vec<([u32; 3], u32)> {
    let (span, child) = (LOG2_SPAN[level], LOG2_SPAN[level + 1]);
    let log2_dim = span - child;
    let dims = v.dims();
    let axis = |a: usize| {
        let end = dims[a].min(origin[a].saturating_add(1 << span));
        (origin[a]..end).step_by(1 << child)
    };
    let mut out = Vec::new();
    for x in axis(0) {
        for y in axis(1) {
            for z in axis(2) {
                let i = (((x - origin[0]) >> child) << (2 * log2_dim))
                    | (((y - origin[1]) >> child) << log2_dim)
                    | ((z - origin[2]) >> child);
                out.push(([x, y, z], i));
            }
        }
    }
    out
}

/// A node mask of 2^(3 log2_dim) bits: little-endian u64 words, so bit i is in byte i / 8.
fn mask(log2_dim: u32, indices: impl IntoIterator<Item = u32>) -> Vec<u8> {
    let mut m = vec![0u8; 1 << (3 * log2_dim - 3)];
    for i in indices {
        m[(i >> 3) as usize] |= 1 << (i & 7);
    }
    m
}

/// How many voxels of the leaf at `origin` lie inside the volume, per axis.
fn leaf_extent(v: &Volume, origin: [u32; 3]) -> [u32; 3] {
    let dims = v.dims();
    [0usize, 1, 2].map(|a| (dims[a] - origin[a]).min(8))
}

fn leaf_mask(v: &Volume, origin: [u32; 3]) -> Vec<u8> {
    let [ex, ey, ez] = leaf_extent(v, origin);
    let mut bits = Vec::with_capacity(512);
    for x in 0..ex {
        for y in 0..ey {
            for z in 0..ez {
                bits.push((x << 6) | (y << 3) | z);
            }
        }
    }
    mask(3, bits)
}

/// One value array: the metadata byte, then the active values (uncompressed).
fn put_values(out: &mut Vec<u8>, raw: &[u8]) {
    out.push(NO_MASK_OR_INACTIVE_VALS);
    out.extend_from_slice(raw);
}

/// An internal node's topology: masks, (no) tile values, then its children's topology. The
/// leaves' origins go to `leaves` in the order their buffers follow the topology.
fn put_internal(
    out: &mut Vec<u8>,
    v: &Volume,
    origin: [u32; 3],
    level: usize,
    leaves: &mut Vec<[u32; 3]>,
) {
    let kids = children(v, origin, level);
    let log2_dim = LOG2_SPAN[level] - LOG2_SPAN[level + 1];
    out.extend_from_slice(&mask(log2_dim, kids.iter().map(|k| k.1)));
    out.extend_from_slice(&mask(log2_dim, std::iter::empty::<u32>()));
    put_values(out, &[]);
    for (child, _) in kids {
        if level == 0 {
            put_internal(out, v, child, 1, leaves);
        } else {
            out.extend_from_slice(&leaf_mask(v, child));
            leaves.push(child);
        }
    }
}

/// The tree's topology; returns the leaves' origins in buffer order.
fn put_topology(out: &mut Vec<u8>, v: &Volume, value_size: usize) -> Vec<[u32; 3]> {
    put_u32(out, 1); // buffer count
    out.resize(out.len() + value_size, 0); // background: zero
    let step = 1usize << LOG2_SPAN[0];
    let mut roots = Vec::new();
    // x, then y, then z: the order of the root's map of children (by coordinate).
    for x in (0..v.nx).step_by(step) {
        for y in (0..v.ny).step_by(step) {
            for z in (0..v.nz).step_by(step) {
                roots.push([x, y, z]);
            }
        }
    }
    put_u32(out, 0); // tiles
    put_u32(out, roots.len() as u32);
    let mut leaves = Vec::new();
    for origin in roots {
        for c in origin {
            out.extend_from_slice(&(c as i32).to_le_bytes());
        }
        put_internal(out, v, origin, 0, &mut leaves);
    }
    leaves
}

fn put_buffers(out: &mut Vec<u8>, v: &Volume, leaves: &[[u32; 3]], grid: &Grid) {
    let mut raw = Vec::with_capacity(512 * grid.value_size);
    let (nx, ny, c) = (v.nx as usize, v.ny as usize, v.channels as usize);
    for &origin in leaves {
        out.extend_from_slice(&leaf_mask(v, origin));
        let [ex, ey, ez] = leaf_extent(v, origin);
        raw.clear();
        // Leaf index order: x, then y, then z fastest.
        for x in origin[0]..origin[0] + ex {
            for y in origin[1]..origin[1] + ey {
                for z in origin[2]..origin[2] + ez {
                    let i = ((z as usize * ny + y as usize) * nx + x as usize) * c;
                    (grid.encode)(v, i, &mut raw);
                }
            }
        }
        put_values(out, &raw);
    }
}

/// A uniform scale map, with a translation when the origin is not zero. OpenVDB reads the
/// derived terms back as stored rather than recomputing them, so all are written: (the
/// translation,) the scale, the voxel size, 1 / scale, 1 / scale², 1 / (2 scale).
fn put_transform(out: &mut Vec<u8>, o: &VdbOptions) {
    let s = o.voxel_size;
    let mut vecs = Vec::new();
    if o.origin != [0.0; 3] {
        put_string(out, b"UniformScaleTranslateMap");
        vecs.push(o.origin);
    } else {
        put_string(out, b"UniformScaleMap");
    }
    vecs.extend([
        [s; 3],
        [s; 3],
        [1.0 / s; 3],
        [1.0 / (s * s); 3],
        [0.5 / s; 3],
    ]);
    for c in vecs.into_iter().flatten() {
        put_f64(out, c);
    }
}

/// The grid's metadata, sorted by name as OpenVDB writes it; the `file_*` entries are the
/// statistics OpenVDB adds on write (readers show them without loading the tree).
fn put_grid_meta(out: &mut Vec<u8>, v: &Volume, grid: &Grid) {
    let vec3i = |a: [i32; 3]| a.iter().flat_map(|c| c.to_le_bytes()).collect::<Vec<u8>>();
    let max = [v.nx, v.ny, v.nz].map(|n| n as i32 - 1);
    let voxels = v.nx as i64 * v.ny as i64 * v.nz as i64;
    let mut entries: Vec<(&str, &str, Vec<u8>)> = Vec::new();
    if let Some(class) = grid.class {
        entries.push(("class", "string", class.as_bytes().to_vec()));
    }
    entries.extend([
        ("file_bbox_max", "vec3i", vec3i(max)),
        ("file_bbox_min", "vec3i", vec3i([0; 3])),
        ("file_compression", "string", b"active values".to_vec()),
        ("file_voxel_count", "int64", voxels.to_le_bytes().to_vec()),
        ("name", "string", grid.name.as_bytes().to_vec()),
    ]);
    put_u32(out, entries.len() as u32);
    for (name, type_name, value) in &entries {
        put_meta(out, name, type_name, value);
    }
}

fn put_grid(out: &mut Vec<u8>, v: &Volume, o: &VdbOptions, grid: &Grid) {
    put_string(out, grid.name.as_bytes());
    put_string(out, grid.tree_type.as_bytes());
    put_string(out, b""); // instance parent: none
    let offsets_at = out.len();
    out.extend_from_slice(&[0; 24]); // filled in below
    let grid_pos = out.len();
    put_u32(out, COMPRESS_ACTIVE_MASK);
    put_grid_meta(out, v, grid);
    put_transform(out, o);
    let leaves = put_topology(out, v, grid.value_size);
    let block_pos = out.len();
    put_buffers(out, v, &leaves, grid);
    let end_pos = out.len();
    for (k, pos) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        let at = offsets_at + 8 * k;
        out[at..at + 8].copy_from_slice(&(pos as i64).to_le_bytes());
    }
}

/// The .vdb bytes of a volume (see the module documentation for the layout).
///
/// # Panics
/// If the volume is empty, has other than 1 to 4 channels or a data length that does not
/// match its dimensions, or is wider than OpenVDB's i32 coordinates.
pub fn to_bytes(v: &Volume, options: VdbOptions) -> Vec<u8> {
    let voxels = v.nx as usize * v.ny as usize * v.nz as usize;
    assert!(voxels > 0 && (1..=4).contains(&v.channels), "not a volume");
    assert_eq!(
        v.data.len(),
        voxels * v.channels as usize,
        "data does not match dims"
    );
    assert!(
        v.dims().iter().all(|&n| n <= i32::MAX as u32),
        "too wide for OpenVDB"
    );
    let mut out = Vec::with_capacity(voxels * 16 + (1 << 16));
    out.extend_from_slice(&MAGIC.to_le_bytes());
    put_u32(&mut out, FILE_VERSION);
    put_u32(&mut out, LIBRARY_VERSION[0]);
    put_u32(&mut out, LIBRARY_VERSION[1]);
    out.push(1); // has grid offsets
    out.extend_from_slice(uuid(v, &options).as_bytes());
    put_u32(&mut out, 0); // file metadata: none
    put_u32(&mut out, GRIDS.len() as u32);
    for grid in &GRIDS {
        put_grid(&mut out, v, &options, grid);
    }
    out
}

pub fn save(v: &Volume, path: &Path, options: VdbOptions) -> Result<()> {
    atomic::write_file(path, &to_bytes(v, options))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The volume `scripts/vdb_prototype.py`'s checks were run on (see `golden_files`).
    fn pattern(nx: u32, ny: u32, nz: u32, channels: u32) -> Volume {
        let mut v = Volume::new(nx, ny, nz, channels);
        for (i, b) in v.data.iter_mut().enumerate() {
            *b = ((i * 7 + (i >> 9)) % 251) as u8;
        }
        v
    }

    /// The file length for a box at the index origin (it does not depend on the channels).
    fn expected_len(dims: [u32; 3], translated: bool) -> usize {
        let [nx, ny, nz] = dims.map(|n| n as usize);
        let count = |span: usize| nx.div_ceil(span) * ny.div_ceil(span) * nz.div_ceil(span);
        let (n5, n4, leaves, voxels) = (count(4096), count(128), count(8), nx * ny * nz);
        let mut total = 65; // header, file metadata count and grid count
        for grid in &GRIDS {
            let (name, vs) = (grid.name.len(), grid.value_size);
            total += 12 + name + grid.tree_type.len() + 24 + 4; // descriptor, compression
                                                                // Metadata: per entry 12 bytes of lengths, then name, type name and value.
            total += 4 + (12 + 13 + 5 + 12) * 2 + (12 + 16 + 6 + 13) + (12 + 16 + 5 + 8);
            total += (12 + 4 + 6 + name) + grid.class.map_or(0, |c| 12 + 5 + 6 + c.len());
            total += if translated {
                4 + 24 + 6 * 24
            } else {
                4 + 15 + 5 * 24
            };
            total += 12 + vs + n5 * (12 + 8192 + 1) + n4 * (1024 + 1) + leaves * 64;
            total += leaves * (64 + 1) + voxels * vs;
        }
        total
    }

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    fn i64_at(b: &[u8], at: usize) -> i64 {
        i64::from_le_bytes(b[at..at + 8].try_into().unwrap())
    }

    #[test]
    fn header_and_descriptors() {
        let b = to_bytes(&pattern(13, 7, 21, 3), VdbOptions::default());
        assert_eq!(&b[..8], b" BDV\0\0\0\0");
        assert_eq!(
            (u32_at(&b, 8), u32_at(&b, 12), u32_at(&b, 16)),
            (224, 10, 0)
        );
        assert_eq!(b[20], 1);
        let uuid = std::str::from_utf8(&b[21..57]).unwrap();
        assert!([8usize, 13, 18, 23]
            .iter()
            .all(|&i| uuid.as_bytes()[i] == b'-'));
        assert_eq!((u32_at(&b, 57), u32_at(&b, 61)), (0, 2));
        // Each descriptor's offsets: the grid right after them, its end the next descriptor.
        let mut at = 65;
        for grid in &GRIDS {
            for s in [grid.name, grid.tree_type, ""] {
                assert_eq!(&b[at + 4..at + 4 + s.len()], s.as_bytes());
                at += 4 + s.len();
            }
            let grid_pos = i64_at(&b, at);
            let (block_pos, end) = (i64_at(&b, at + 8), i64_at(&b, at + 16));
            assert_eq!(grid_pos as usize, at + 24);
            assert_eq!(u32_at(&b, grid_pos as usize), COMPRESS_ACTIVE_MASK);
            assert!(grid_pos < block_pos && block_pos < end);
            at = end as usize;
        }
        assert_eq!(at, b.len());
    }

    #[test]
    fn length_follows_the_tree_shape() {
        let translated = VdbOptions {
            voxel_size: 0.5,
            origin: [1.5, -2.0, 3.0],
        };
        for (dims, c, o) in [
            ([8, 8, 8], 3, VdbOptions::default()),
            ([13, 7, 21], 1, VdbOptions::default()),
            ([100, 40, 9], 4, VdbOptions::default()),
            ([8, 8, 8], 1, translated),
            ([4100, 2, 3], 1, VdbOptions::default()),
        ] {
            let b = to_bytes(&pattern(dims[0], dims[1], dims[2], c), o);
            assert_eq!(
                b.len(),
                expected_len(dims, o.origin != [0.0; 3]),
                "{dims:?}"
            );
        }
        // Lengths of the prototype's files, which OpenVDB 10 read back correctly.
        assert_eq!(expected_len([13, 7, 21], false), 51532);
        assert_eq!(expected_len([100, 40, 9], false), 628948);
    }

    #[test]
    fn first_leaf_holds_density_in_leaf_order() {
        let v = pattern(8, 8, 8, 3);
        let b = to_bytes(&v, VdbOptions::default());
        let block_pos = i64_at(&b, 65 + 4 + 7 + 4 + 16 + 4 + 8) as usize;
        assert!(b[block_pos..block_pos + 64].iter().all(|&m| m == 0xff));
        assert_eq!(b[block_pos + 64], NO_MASK_OR_INACTIVE_VALS);
        let values = block_pos + 65;
        for (x, y, z) in [(0, 0, 0), (1, 2, 3), (7, 0, 5), (7, 7, 7)] {
            let at = values + 4 * ((x << 6) | (y << 3) | z) as usize;
            let got = f32::from_le_bytes(b[at..at + 4].try_into().unwrap());
            let p = v.at(x, y, z);
            let want = (p[0] as u32 + p[1] as u32 + p[2] as u32) as f32 / 765.0;
            assert!(
                (got - want).abs() < 1e-6,
                "({x}, {y}, {z}): {got} vs {want}"
            );
        }
    }

    /// The CRC-32 of `scripts/vdb_prototype.py`'s output for the same volumes: the port
    /// writes the prototype's bytes, which `scripts/vdb_check.py` validated with OpenVDB.
    #[test]
    fn golden_files() {
        let translated = VdbOptions {
            voxel_size: 0.5,
            origin: [1.5, -2.0, 3.0],
        };
        for (dims, c, o, crc, uuid_head) in [
            (
                [8, 8, 8],
                3,
                VdbOptions::default(),
                0x92b8ac80u32,
                "765887c8-e92f",
            ),
            (
                [13, 7, 21],
                3,
                VdbOptions::default(),
                0xbce9c04e,
                "8e63396d-8fe0",
            ),
            (
                [100, 40, 9],
                4,
                VdbOptions::default(),
                0x810743fa,
                "49835d6a-28c9",
            ),
            ([8, 8, 8], 1, translated, 0xd01f21f9, "d3ac1c26-3b0d"),
            (
                [4100, 2, 3],
                1,
                VdbOptions::default(),
                0xf8f2acb7,
                "532d167f-770c",
            ),
        ] {
            let b = to_bytes(&pattern(dims[0], dims[1], dims[2], c), o);
            assert_eq!(
                std::str::from_utf8(&b[21..34]).unwrap(),
                uuid_head,
                "{dims:?}"
            );
            assert_eq!(crc32fast::hash(&b), crc, "{dims:?} x {c}");
        }
    }

    #[test]
    fn equal_inputs_give_equal_files() {
        let v = pattern(9, 4, 3, 2);
        let a = to_bytes(&v, VdbOptions::default());
        assert_eq!(a, to_bytes(&v, VdbOptions::default()));
        let mut w = v.clone();
        w.data[0] ^= 1;
        let b = to_bytes(&w, VdbOptions::default());
        assert_ne!(&a[21..57], &b[21..57], "the UUID follows the content");
    }
}
