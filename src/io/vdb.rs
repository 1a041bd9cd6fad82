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
//! | compression       | u32 flags: `COMPRESS_ACTIVE_MASK`, and `COMPRESS_ZIP` unless the     |
//! |                   | options ask for raw values (no Blosc)                                |
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
//! With `COMPRESS_ZIP` (the default) the values follow as OpenVDB's zip chunk: an i64 byte
//! count, then that many bytes of a zlib stream, or, where zlib would not make them smaller
//! (an empty array, a noisy leaf), minus the values' byte count and the values as they are.
//! Both grids are zipped; OpenVDB's own writer leaves fog volumes such as `density` unzipped,
//! and its readers take either, grid by grid.
//!
//! `scripts/vdb_prototype.py` is the same writer in Python and writes the same bytes for raw
//! values (with `--zip`, the same layout around its own zlib's streams);
//! `scripts/vdb_check.py` reads a file with OpenVDB and compares it with the raw volume.

use super::atomic;
use crate::error::{Error, Result};
use crate::volume::Volume;
use flate2::{Compress, Compression, FlushCompress, Status};
use rayon::prelude::*;
use std::path::Path;

const MAGIC: i64 = 0x5644_4220;
const FILE_VERSION: u32 = 224;
const LIBRARY_VERSION: [u32; 2] = [10, 0];
const COMPRESS_ZIP: u32 = 0x1;
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
    /// zlib-compress the values (OpenVDB's `COMPRESS_ZIP` chunks): about 5x smaller for a
    /// synthesized solid (a 128^3 one, 34.6 MB raw, 7.2 MB zipped). `false` writes them raw,
    /// for readers without zlib (OpenVDB itself always has it).
    pub zip: bool,
}

impl Default for VdbOptions {
    fn default() -> VdbOptions {
        VdbOptions {
            voxel_size: 1.0,
            origin: [0.0; 3],
            zip: true,
        }
    }
}

/// The voxel sizes a file takes, in world units: the transform also stores 1 / size^2, which
/// stays well inside f64 for these.
pub const VOXEL_SIZE_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=1e6;

impl VdbOptions {
    /// Refuse a voxel size outside [`VOXEL_SIZE_RANGE`] or an origin that is not finite.
    pub fn check(&self) -> Result<()> {
        if !VOXEL_SIZE_RANGE.contains(&self.voxel_size) {
            return Err(Error::invalid(
                format!(
                    "VDB voxel size {}",
                    crate::util::number_text(self.voxel_size)
                ),
                "must be a number from 1e-6 to 1e6",
            ));
        }
        if self.origin.iter().any(|c| !c.is_finite()) {
            return Err(Error::invalid(
                format!("VDB origin {:?}", self.origin),
                "must be finite",
            ));
        }
        Ok(())
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
    // Raw values keep the UUIDs the format's golden files were validated with.
    if o.zip {
        key.push(1);
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

/// Writes value arrays, raw or as zip chunks. Its zlib compressor (a few hundred KB of state) is
/// made at the first array worth compressing and reused for the rest.
struct ValueWriter {
    zip: bool,
    compressor: Option<Compress>,
}

impl ValueWriter {
    fn new(zip: bool) -> ValueWriter {
        ValueWriter {
            zip,
            compressor: None,
        }
    }

    /// One value array: the metadata byte, then the active values.
    fn put(&mut self, out: &mut Vec<u8>, raw: &[u8]) {
        out.push(NO_MASK_OR_INACTIVE_VALS);
        if !self.zip {
            out.extend_from_slice(raw);
            return;
        }
        let mut zipped = Vec::new();
        // An empty array never shrinks: its chunk is the raw branch's zero length.
        if !raw.is_empty() {
            let z = self
                .compressor
                .get_or_insert_with(|| Compress::new(Compression::default(), true));
            z.reset();
            // Room for a stream shorter than the values: a longer one is not used.
            zipped.reserve(raw.len());
            if !matches!(
                z.compress_vec(raw, &mut zipped, FlushCompress::Finish),
                Ok(Status::StreamEnd)
            ) {
                zipped.clear();
            }
        }
        if !zipped.is_empty() && zipped.len() < raw.len() {
            out.extend_from_slice(&(zipped.len() as i64).to_le_bytes());
            out.extend_from_slice(&zipped);
        } else {
            out.extend_from_slice(&(-(raw.len() as i64)).to_le_bytes());
            out.extend_from_slice(raw);
        }
    }
}

/// An internal node's topology: masks, (no) tile values, then its children's topology. The
/// leaves' origins go to `leaves` in the order their buffers follow the topology.
fn put_internal(
    out: &mut Vec<u8>,
    v: &Volume,
    origin: [u32; 3],
    level: usize,
    leaves: &mut Vec<[u32; 3]>,
    values: &mut ValueWriter,
) {
    let kids = children(v, origin, level);
    let log2_dim = LOG2_SPAN[level] - LOG2_SPAN[level + 1];
    out.extend_from_slice(&mask(log2_dim, kids.iter().map(|k| k.1)));
    out.extend_from_slice(&mask(log2_dim, std::iter::empty::<u32>()));
    values.put(out, &[]);
    for (child, _) in kids {
        if level == 0 {
            put_internal(out, v, child, 1, leaves, values);
        } else {
            out.extend_from_slice(&leaf_mask(v, child));
            leaves.push(child);
        }
    }
}

/// The tree's topology; returns the leaves' origins in buffer order.
fn put_topology(out: &mut Vec<u8>, v: &Volume, value_size: usize, zip: bool) -> Vec<[u32; 3]> {
    let mut values = ValueWriter::new(zip);
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
        put_internal(out, v, origin, 0, &mut leaves, &mut values);
    }
    leaves
}

/// The leaves' buffers, each encoded (and compressed) on its own, in parallel; the file keeps
/// their order.
fn put_buffers(out: &mut Vec<u8>, v: &Volume, leaves: &[[u32; 3]], grid: &Grid, zip: bool) {
    let (nx, ny, c) = (v.nx as usize, v.ny as usize, v.channels as usize);
    let buffer = |values: &mut ValueWriter, &origin: &[u32; 3]| {
        let mut raw = Vec::with_capacity(512 * grid.value_size);
        let [ex, ey, ez] = leaf_extent(v, origin);
        // Leaf index order: x, then y, then z fastest.
        for x in origin[0]..origin[0] + ex {
            for y in origin[1]..origin[1] + ey {
                for z in origin[2]..origin[2] + ez {
                    let i = ((z as usize * ny + y as usize) * nx + x as usize) * c;
                    (grid.encode)(v, i, &mut raw);
                }
            }
        }
        let mut bytes = leaf_mask(v, origin);
        values.put(&mut bytes, &raw);
        bytes
    };
    // A chunk of leaves per task keeps the collected pieces few, and shares a compressor.
    let pieces: Vec<Vec<u8>> = leaves
        .par_chunks(64)
        .map(|chunk| {
            let mut values = ValueWriter::new(zip);
            chunk.iter().flat_map(|o| buffer(&mut values, o)).collect()
        })
        .collect();
    for piece in pieces {
        out.extend_from_slice(&piece);
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
fn put_grid_meta(out: &mut Vec<u8>, v: &Volume, grid: &Grid, zip: bool) {
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
        (
            "file_compression",
            "string",
            if zip {
                b"zip + active values".to_vec()
            } else {
                b"active values".to_vec()
            },
        ),
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
    let zip_flag = if o.zip { COMPRESS_ZIP } else { 0 };
    put_u32(out, COMPRESS_ACTIVE_MASK | zip_flag);
    put_grid_meta(out, v, grid, o.zip);
    put_transform(out, o);
    let leaves = put_topology(out, v, grid.value_size, o.zip);
    let block_pos = out.len();
    put_buffers(out, v, &leaves, grid, o.zip);
    let end_pos = out.len();
    for (k, pos) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        let at = offsets_at + 8 * k;
        out[at..at + 8].copy_from_slice(&(pos as i64).to_le_bytes());
    }
}

/// The .vdb bytes of a volume (see the module documentation for the layout). An error for an
/// empty volume, one with other than 1 to 4 channels or a data length that does not match its
/// dimensions, one wider than OpenVDB's i32 coordinates, or options [`VdbOptions::check`]
/// refuses.
pub fn to_bytes(v: &Volume, options: VdbOptions) -> Result<Vec<u8>> {
    crate::io::slab_order::check_dims(v.dims(), v.channels)?;
    v.check("volume")?;
    options.check()?;
    if v.dims().iter().any(|&n| n > i32::MAX as u32) {
        return Err(Error::invalid(
            "volume",
            "is wider than OpenVDB's coordinates (2^31 - 1 voxels a side)",
        ));
    }
    let voxels = v.nx as usize * v.ny as usize * v.nz as usize;
    // Zipped values of a synthesized solid take about a fifth of their raw 16 bytes a voxel.
    let per_voxel = if options.zip { 4 } else { 16 };
    let mut out = Vec::with_capacity(voxels * per_voxel + (1 << 16));
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
    Ok(out)
}

pub fn save(v: &Volume, path: &Path, options: VdbOptions) -> Result<()> {
    atomic::write_file(path, &to_bytes(v, options)?)
}

#[cfg(test)]
mod tests;
