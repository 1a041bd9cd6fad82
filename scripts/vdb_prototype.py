#!/usr/bin/env python3
"""Reference OpenVDB (.vdb) writer for a dense 8-bit volume, in plain Python.

This is the prototype that `src/io/vdb.rs` translates line for line; the two write the same
bytes for the same input (the Rust output can be checked with `cmp` against this one).

Usage:
    vdb_prototype.py RAW NX NY NZ C OUT [--voxel-size S] [--origin X Y Z] [--zip]

RAW holds NX*NY*NZ*C bytes, channel fastest, then x, y, z (the NRRD order of a solidsynth
volume). OUT receives two grids: `density` (FloatGrid, fog volume, the mean of r, g, b in
[0, 1], or the first channel for 1 or 2 channels) and `color` (Vec3SGrid, r, g, b in [0, 1],
grey replicated below 3 channels). Voxel (x, y, z) lies at index coordinate (x, y, z); every
voxel of the box is active; the background is 0.

The layout (file format 224, the one OpenVDB 10 writes and reads):

    header       magic 0x56444220 (i64), format 224 (u32), library 10.0 (2 x u32),
                 "has grid offsets" 1 (u8), a 36-character UUID, file metadata (count 0)
    grid count   u32
    per grid     name, tree type, instance parent (u32-length strings), then three i64
                 offsets: the grid's start (just after them), its leaf buffers, its end
                 compression flags (u32): 2 = COMPRESS_ACTIVE_MASK (3 with --zip)
                 metadata (u32 count, then name, type name, u32-sized value each, sorted)
                 transform: map type name, then the map's Vec3d fields
                 topology: buffer count 1, root (background, 0 tiles, child count,
                 per child its origin then the 5-level node), internal nodes (child mask,
                 value mask, a compressed value array), leaves (value mask)
                 buffers: per leaf, in tree order, value mask then compressed values
    compressed values: one metadata byte, 0 = "inactive values are the background", then,
                 because the grid sets COMPRESS_ACTIVE_MASK, only the active values
                 (none for internal nodes: they hold no tiles); with --zip those values
                 are an i64 byte count then zlib data (a negative count means raw bytes).
"""

import argparse
import struct
import sys
import zlib

MAGIC = 0x56444220
FILE_VERSION = 224
LIBRARY_VERSION = (10, 0)
COMPRESS_ZIP = 0x1
COMPRESS_ACTIVE_MASK = 0x2
# Per-node compression metadata: every inactive value equals the background.
NO_MASK_OR_INACTIVE_VALS = 0
# log2 of the voxels per axis covered by a 5-level node, a 4-level node and a leaf.
LOG2_SPAN = (12, 7, 3)


def put_u32(out, v):
    out += struct.pack('<I', v)


def put_i32(out, v):
    out += struct.pack('<i', v)


def put_i64(out, v):
    out += struct.pack('<q', v)


def put_f64(out, v):
    out += struct.pack('<d', v)


def put_string(out, s):
    b = s.encode() if isinstance(s, str) else s
    put_u32(out, len(b))
    out += b


def put_meta(out, name, type_name, value):
    put_string(out, name)
    put_string(out, type_name)
    put_string(out, value)


def uuid(vol, opts):
    """A UUID derived from the content, so that equal inputs give equal files."""
    key = struct.pack('<4I4d', vol.nx, vol.ny, vol.nz, vol.c, opts.voxel_size, *opts.origin)
    if opts.zip:
        key += b'\x01'  # zipped files differ, so their UUIDs do too
    words = (
        zlib.crc32(vol.data),
        zlib.crc32(key),
        zlib.crc32(vol.data, zlib.crc32(key)),
        zlib.crc32(key, zlib.crc32(vol.data)),
    )
    h = ''.join('%08x' % w for w in words)
    return '%s-%s-%s-%s-%s' % (h[0:8], h[8:12], h[12:16], h[16:20], h[20:32])


def density(vol, i):
    """The luminance of the voxel whose first byte is at `i`, as float32 bytes."""
    d = vol.data
    v = (d[i] + d[i + 1] + d[i + 2]) / 765.0 if vol.c >= 3 else d[i] / 255.0
    return struct.pack('<f', v)


def color(vol, i):
    d = vol.data
    if vol.c >= 3:
        rgb = (d[i] / 255.0, d[i + 1] / 255.0, d[i + 2] / 255.0)
    else:
        rgb = (d[i] / 255.0,) * 3
    return struct.pack('<3f', *rgb)


GRIDS = (
    # name, tree type, class, value size, voxel encoder
    ('density', 'Tree_float_5_4_3', 'fog volume', 4, density),
    ('color', 'Tree_vec3s_5_4_3', None, 12, color),
)


def children(vol, origin, level):
    """The (origin, index in the parent's masks) of the children of the node at `origin` of
    `level` (0 = 5-level node, 1 = 4-level node) that touch the volume, in index order."""
    span, child = LOG2_SPAN[level], LOG2_SPAN[level + 1]
    log2_dim = span - child
    dims = (vol.nx, vol.ny, vol.nz)
    ranges = [range(origin[a], min(origin[a] + (1 << span), dims[a]), 1 << child)
              for a in range(3)]
    out = []
    for x in ranges[0]:
        for y in ranges[1]:
            for z in ranges[2]:
                i = ((x - origin[0]) >> child) << (2 * log2_dim)
                i |= ((y - origin[1]) >> child) << log2_dim
                i |= (z - origin[2]) >> child
                out.append(((x, y, z), i))
    return out


def mask(log2_dim, indices):
    """A node mask: 2^(3 log2_dim) bits as little-endian u64 words, i.e. bit i of byte i/8."""
    m = bytearray(1 << (3 * log2_dim - 3))
    for i in indices:
        m[i >> 3] |= 1 << (i & 7)
    return m


def leaf_extent(vol, origin):
    """How many voxels of the leaf at `origin` lie inside the volume, per axis."""
    dims = (vol.nx, vol.ny, vol.nz)
    return [min(8, dims[a] - origin[a]) for a in range(3)]


def leaf_mask(vol, origin):
    ex, ey, ez = leaf_extent(vol, origin)
    return mask(3, [(x << 6) | (y << 3) | z
                    for x in range(ex) for y in range(ey) for z in range(ez)])


def put_values(out, raw, zip_):
    """One compressed value array: the metadata byte, then the (active) values."""
    out.append(NO_MASK_OR_INACTIVE_VALS)
    if not zip_:
        out += raw
        return
    packed = zlib.compress(bytes(raw), 6)
    if len(packed) < len(raw):
        put_i64(out, len(packed))
        out += packed
    else:
        # OpenVDB's own convention for data that zlib does not shrink (and for no data).
        put_i64(out, -len(raw))
        out += raw


def put_internal(out, vol, origin, level, leaves, zip_):
    """An internal node's topology: its masks, its (empty) tile values, then its children.
    The leaves' origins are appended to `leaves` in the order their buffers follow."""
    kids = children(vol, origin, level)
    out += mask(LOG2_SPAN[level] - LOG2_SPAN[level + 1], [i for _, i in kids])
    out += mask(LOG2_SPAN[level] - LOG2_SPAN[level + 1], [])
    put_values(out, b'', zip_)
    for child, _ in kids:
        if level == 0:
            put_internal(out, vol, child, 1, leaves, zip_)
        else:
            out += leaf_mask(vol, child)
            leaves.append(child)


def put_topology(out, vol, value_size, zip_):
    put_u32(out, 1)  # buffer count
    out += bytes(value_size)  # background: zero
    roots = [(x, y, z)
             for x in range(0, vol.nx, 1 << LOG2_SPAN[0])
             for y in range(0, vol.ny, 1 << LOG2_SPAN[0])
             for z in range(0, vol.nz, 1 << LOG2_SPAN[0])]
    put_u32(out, 0)  # tiles
    put_u32(out, len(roots))
    leaves = []
    for origin in roots:
        for c in origin:
            put_i32(out, c)
        put_internal(out, vol, origin, 0, leaves, zip_)
    return leaves


def put_buffers(out, vol, leaves, encode, zip_):
    for origin in leaves:
        out += leaf_mask(vol, origin)
        ex, ey, ez = leaf_extent(vol, origin)
        raw = bytearray()
        for x in range(origin[0], origin[0] + ex):
            for y in range(origin[1], origin[1] + ey):
                for z in range(origin[2], origin[2] + ez):
                    raw += encode(vol, ((z * vol.ny + y) * vol.nx + x) * vol.c)
        put_values(out, raw, zip_)


def put_transform(out, opts):
    s = opts.voxel_size
    if any(opts.origin):
        put_string(out, 'UniformScaleTranslateMap')
        vecs = [tuple(opts.origin)]
    else:
        put_string(out, 'UniformScaleMap')
        vecs = []
    # The map stores its derived terms too (read back as is): scale, voxel size, 1/scale,
    # 1/scale^2, 1/(2 scale).
    vecs += [(s,) * 3, (s,) * 3, (1.0 / s,) * 3, (1.0 / (s * s),) * 3, (0.5 / s,) * 3]
    for v in vecs:
        for c in v:
            put_f64(out, c)


def put_grid_meta(out, vol, name, grid_class, zip_):
    entries = []
    if grid_class:
        entries.append(('class', 'string', grid_class.encode()))
    entries += [
        ('file_bbox_max', 'vec3i', struct.pack('<3i', vol.nx - 1, vol.ny - 1, vol.nz - 1)),
        ('file_bbox_min', 'vec3i', struct.pack('<3i', 0, 0, 0)),
        ('file_compression', 'string', b'zip + active values' if zip_ else b'active values'),
        ('file_voxel_count', 'int64', struct.pack('<q', vol.nx * vol.ny * vol.nz)),
        ('name', 'string', name.encode()),
    ]
    put_u32(out, len(entries))
    for e in entries:
        put_meta(out, *e)


def put_grid(out, vol, opts, grid):
    name, tree_type, grid_class, value_size, encode = grid
    put_string(out, name)
    put_string(out, tree_type)
    put_string(out, '')  # instance parent: none
    offsets_at = len(out)
    out += bytes(24)  # grid, buffers and end offsets, filled in below
    grid_pos = len(out)
    put_u32(out, COMPRESS_ACTIVE_MASK | (COMPRESS_ZIP if opts.zip else 0))
    put_grid_meta(out, vol, name, grid_class, opts.zip)
    put_transform(out, opts)
    leaves = put_topology(out, vol, value_size, opts.zip)
    block_pos = len(out)
    put_buffers(out, vol, leaves, encode, opts.zip)
    out[offsets_at:offsets_at + 24] = struct.pack('<3q', grid_pos, block_pos, len(out))


def to_bytes(vol, opts):
    out = bytearray()
    put_i64(out, MAGIC)
    put_u32(out, FILE_VERSION)
    put_u32(out, LIBRARY_VERSION[0])
    put_u32(out, LIBRARY_VERSION[1])
    out.append(1)  # has grid offsets
    out += uuid(vol, opts).encode()
    put_u32(out, 0)  # file metadata: none
    put_u32(out, len(GRIDS))
    for grid in GRIDS:
        put_grid(out, vol, opts, grid)
    return bytes(out)


class Volume:
    def __init__(self, nx, ny, nz, c, data):
        assert 1 <= c <= 4 and len(data) == nx * ny * nz * c, 'raw size does not match dims'
        self.nx, self.ny, self.nz, self.c, self.data = nx, ny, nz, c, bytes(data)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('raw')
    ap.add_argument('nx', type=int)
    ap.add_argument('ny', type=int)
    ap.add_argument('nz', type=int)
    ap.add_argument('c', type=int)
    ap.add_argument('out')
    ap.add_argument('--voxel-size', type=float, default=1.0)
    ap.add_argument('--origin', type=float, nargs=3, default=[0.0, 0.0, 0.0])
    ap.add_argument('--zip', action='store_true')
    a = ap.parse_args()
    with open(a.raw, 'rb') as f:
        vol = Volume(a.nx, a.ny, a.nz, a.c, f.read())
    a.origin = tuple(a.origin)
    with open(a.out, 'wb') as f:
        f.write(to_bytes(vol, a))


if __name__ == '__main__':
    sys.exit(main())
