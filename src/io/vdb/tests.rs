//! The writer's layout against the prototype's golden files, its zip chunks against raw values.

use super::*;

/// Raw values: the layout the golden files and the prototype's lengths describe.
fn raw() -> VdbOptions {
    VdbOptions {
        zip: false,
        ..VdbOptions::default()
    }
}

/// Raw values, a half-size voxel and the grids translated: the prototype's placed case.
fn translated() -> VdbOptions {
    VdbOptions {
        voxel_size: 0.5,
        origin: [1.5, -2.0, 3.0],
        zip: false,
    }
}

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
    let b = to_bytes(&pattern(13, 7, 21, 3), raw()).unwrap();
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
    for (dims, c, o) in [
        ([8, 8, 8], 3, raw()),
        ([13, 7, 21], 1, raw()),
        ([100, 40, 9], 4, raw()),
        ([8, 8, 8], 1, translated()),
        ([4100, 2, 3], 1, raw()),
    ] {
        let b = to_bytes(&pattern(dims[0], dims[1], dims[2], c), o).unwrap();
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
    let b = to_bytes(&v, raw()).unwrap();
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
    for (dims, c, o, crc, uuid_head) in [
        ([8, 8, 8], 3, raw(), 0x92b8ac80u32, "765887c8-e92f"),
        ([13, 7, 21], 3, raw(), 0xbce9c04e, "8e63396d-8fe0"),
        ([100, 40, 9], 4, raw(), 0x810743fa, "49835d6a-28c9"),
        ([8, 8, 8], 1, translated(), 0xd01f21f9, "d3ac1c26-3b0d"),
        ([4100, 2, 3], 1, raw(), 0xf8f2acb7, "532d167f-770c"),
    ] {
        let b = to_bytes(&pattern(dims[0], dims[1], dims[2], c), o).unwrap();
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
    let a = to_bytes(&v, VdbOptions::default()).unwrap();
    assert_eq!(a, to_bytes(&v, VdbOptions::default()).unwrap());
    let mut w = v.clone();
    w.data[0] ^= 1;
    let b = to_bytes(&w, VdbOptions::default()).unwrap();
    assert_ne!(&a[21..57], &b[21..57], "the UUID follows the content");
}

#[test]
fn files_do_not_depend_on_the_thread_count() {
    // More leaves than one parallel task takes, so that several tasks share the work.
    let v = pattern(96, 40, 72, 3);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    for options in [VdbOptions::default(), raw()] {
        let serial = one.install(|| to_bytes(&v, options).unwrap());
        assert_eq!(serial, three.install(|| to_bytes(&v, options).unwrap()));
    }
}

/// Each grid's (grid, leaf buffers, end) positions, from the descriptors.
fn grid_offsets(b: &[u8]) -> Vec<[usize; 3]> {
    let mut at = 65;
    GRIDS
        .iter()
        .map(|grid| {
            at += 12 + grid.name.len() + grid.tree_type.len();
            let offsets = [0, 8, 16].map(|k| i64_at(b, at + k) as usize);
            at = offsets[2];
            offsets
        })
        .collect()
}

/// Each grid's leaf buffers, values inflated where zipped: (value mask, metadata, values).
fn leaf_buffers(b: &[u8]) -> Vec<(Vec<u8>, u8, Vec<u8>)> {
    let mut leaves = Vec::new();
    for (grid, [grid_pos, block_pos, end]) in GRIDS.iter().zip(grid_offsets(b)) {
        let zip = u32_at(b, grid_pos) & COMPRESS_ZIP != 0;
        let mut p = block_pos;
        while p < end {
            let mask = b[p..p + 64].to_vec();
            let meta = b[p + 64];
            p += 65;
            let active: usize = mask.iter().map(|m| m.count_ones() as usize).sum();
            let len = active * grid.value_size;
            let n = if zip { i64_at(b, p) } else { -(len as i64) };
            if zip {
                p += 8;
            }
            let values = if n <= 0 {
                assert_eq!(-n as usize, len);
                b[p..p + len].to_vec()
            } else {
                let mut inflated = Vec::new();
                let zipped = &b[p..p + n as usize];
                std::io::Read::read_to_end(
                    &mut flate2::read::ZlibDecoder::new(zipped),
                    &mut inflated,
                )
                .unwrap();
                inflated
            };
            p += n.unsigned_abs() as usize;
            leaves.push((mask, meta, values));
        }
        assert_eq!(p, end);
    }
    leaves
}

#[test]
fn zipped_files_hold_the_raw_files_values() {
    for (dims, c) in [([8, 8, 8], 3), ([13, 7, 21], 1), ([100, 40, 9], 4)] {
        let v = pattern(dims[0], dims[1], dims[2], c);
        let zipped = to_bytes(&v, VdbOptions::default()).unwrap();
        let plain = to_bytes(&v, raw()).unwrap();
        assert!(zipped.len() < plain.len(), "{dims:?}");
        // Both grids zipped; their topology gains the longer `file_compression` string and an
        // empty zip chunk (8 bytes) per internal node.
        let internal_nodes: u32 = [4096, 128]
            .map(|s| dims.map(|n| n.div_ceil(s)).iter().product::<u32>())
            .iter()
            .sum();
        for (z, p) in grid_offsets(&zipped).into_iter().zip(grid_offsets(&plain)) {
            assert_eq!(u32_at(&zipped, z[0]), COMPRESS_ACTIVE_MASK | COMPRESS_ZIP);
            assert_eq!(
                z[1] - z[0],
                p[1] - p[0] + 6 + 8 * internal_nodes as usize,
                "{dims:?}"
            );
        }
        let leaves = leaf_buffers(&zipped);
        assert_eq!(leaves, leaf_buffers(&plain), "{dims:?}");
        assert_eq!(
            leaves.len(),
            2 * dims.map(|n| n.div_ceil(8)).iter().product::<u32>() as usize
        );
    }
    // A flat volume: each leaf keeps its 64-byte mask, its values shrink to a few bytes.
    let flat = Volume::new(64, 64, 64, 3);
    let (z, p) = (
        to_bytes(&flat, VdbOptions::default()).unwrap(),
        to_bytes(&flat, raw()).unwrap(),
    );
    assert!(z.len() * 20 < p.len(), "{} against {}", z.len(), p.len());
}
