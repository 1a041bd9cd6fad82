#!/usr/bin/python3
"""Check a solidsynth .vdb file with OpenVDB itself (Debian's python3-openvdb).

Usage:
    /usr/bin/python3 scripts/vdb_check.py FILE.vdb
        prints what OpenVDB reads: grids, types, classes, active voxel counts, bounding
        boxes, voxel sizes, origins and a few sample values;
    /usr/bin/python3 scripts/vdb_check.py FILE.vdb RAW NX NY NZ C [--voxel-size S]
                                          [--origin X Y Z]
        also compares every voxel against RAW (NX*NY*NZ*C bytes, channel fastest, then x,
        y, z) and prints `ok`, or the first mismatch (and exits with status 1).

Expected grids: `density` (FloatGrid, class "fog volume", the mean of r, g, b over 255, or
the first channel for 1 or 2 channels) and `color` (Vec3SGrid, r, g, b over 255, grey
replicated below 3 channels), both active exactly on the box [0, N-1], background 0.
"""

import argparse
import sys

import numpy as np
import pyopenvdb as vdb


def describe(grids, file_meta):
    print('file metadata:', dict(file_meta))
    for g in grids:
        lo, hi = g.evalActiveVoxelBoundingBox()
        print('grid %r: %s class=%r active=%d bbox=%s..%s voxel_size=%s origin=%s' % (
            g.name, type(g).__name__, g.gridClass, g.activeVoxelCount(), lo, hi,
            g.transform.voxelSize(), g.transform.indexToWorld((0, 0, 0))))
        print('   metadata:', {k: v for k, v in g.metadata.items()})
        acc = g.getConstAccessor()
        for ijk in [lo, hi, tuple((a + b) // 2 for a, b in zip(lo, hi))]:
            print('   value at %s: %s' % (ijk, acc.probeValue(ijk)))


def expected(raw, dims, c):
    """(density, color) as float32 arrays indexed [x, y, z] (and [.., channel])."""
    nx, ny, nz = dims
    a = np.frombuffer(raw, dtype=np.uint8).reshape(nz, ny, nx, c).transpose(2, 1, 0, 3)
    a = a.astype(np.float64)
    rgb = a[..., :3] if c >= 3 else np.repeat(a[..., :1], 3, axis=3)
    dens = (a[..., 0] + a[..., 1] + a[..., 2]) / 765.0 if c >= 3 else a[..., 0] / 255.0
    return dens.astype(np.float32), (rgb / 255.0).astype(np.float32)


def first_mismatch(name, got, want):
    bad = np.argwhere(np.abs(got - want) > 1e-6)
    if len(bad) == 0:
        return None
    at = tuple(int(i) for i in bad[0])
    return '%s: %d values differ; first at %s: got %r, want %r' % (
        name, len(bad), at, got[at], want[at])


def compare(grids, raw, dims, c, voxel_size, origin):
    by_name = {g.name: g for g in grids}
    if set(by_name) != {'density', 'color'}:
        return 'grids are %s, want density and color' % sorted(by_name)
    want = dict(zip(('density', 'color'), expected(raw, dims, c)))
    kinds = {'density': vdb.FloatGrid, 'color': vdb.Vec3SGrid}
    hi = tuple(n - 1 for n in dims)
    for name, g in by_name.items():
        if not isinstance(g, kinds[name]):
            return '%s is a %s' % (name, type(g).__name__)
        if g.activeVoxelCount() != dims[0] * dims[1] * dims[2]:
            return '%s: %d active voxels' % (name, g.activeVoxelCount())
        if g.evalActiveVoxelBoundingBox() != ((0, 0, 0), hi):
            return '%s: bbox %s' % (name, g.evalActiveVoxelBoundingBox())
        if any(abs(s - voxel_size) > 1e-12 for s in g.transform.voxelSize()):
            return '%s: voxel size %s' % (name, g.transform.voxelSize())
        o = g.transform.indexToWorld((0, 0, 0))
        if any(abs(a - b) > 1e-9 for a, b in zip(o, origin)):
            return '%s: origin %s' % (name, o)
        # One voxel past the box on each side: inactive background.
        acc = g.getConstAccessor()
        for ijk in [(-1, 0, 0), (0, -1, 0), (0, 0, -1), (dims[0], 0, 0), (0, dims[1], 0),
                    (0, 0, dims[2]), hi]:
            value, active = acc.probeValue(ijk)
            inside = ijk == hi
            if active != inside or (not inside and np.any(np.asarray(value) != 0)):
                return '%s: at %s value %r active %r' % (name, ijk, value, active)
        got = np.zeros(want[name].shape, dtype=np.float32)
        g.copyToArray(got, ijk=(0, 0, 0))
        msg = first_mismatch(name, got, want[name])
        if msg:
            return msg
    if by_name['density'].gridClass != vdb.GridClass.FOG_VOLUME:
        return 'density class %r' % by_name['density'].gridClass
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('vdb')
    ap.add_argument('rest', nargs='*', help='RAW NX NY NZ C')
    ap.add_argument('--voxel-size', type=float, default=1.0)
    ap.add_argument('--origin', type=float, nargs=3, default=[0.0, 0.0, 0.0])
    ap.add_argument('--quiet', action='store_true')
    a = ap.parse_args()
    grids, file_meta = vdb.readAll(a.vdb)
    # Reading a grid by name goes through the descriptor's offsets: check them too.
    by_offset = [vdb.read(a.vdb, g.name) for g in grids]
    if not a.quiet:
        describe(grids, file_meta)
    if not a.rest:
        return 0
    if len(a.rest) != 5:
        ap.error('expected RAW NX NY NZ C')
    dims = tuple(int(n) for n in a.rest[1:4])
    c = int(a.rest[4])
    with open(a.rest[0], 'rb') as f:
        raw = f.read()
    if len(raw) != dims[0] * dims[1] * dims[2] * c:
        print('RAW holds %d bytes, not %d' % (len(raw), dims[0] * dims[1] * dims[2] * c))
        return 1
    for source in (grids, by_offset):
        msg = compare(source, raw, dims, c, a.voxel_size, a.origin)
        if msg:
            print(msg)
            return 1
    print('ok')
    return 0


if __name__ == '__main__':
    sys.exit(main())
