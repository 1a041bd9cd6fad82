#!/usr/bin/env python3
"""Converts an OBJ triangle mesh into the viewer's bunny.bin (run once; the output is committed).

bunny.bin, little-endian: u32 vertex count V, u32 triangle count T, V x 3 f32 positions
(centred at the origin and scaled so the longest side of the bounding box spans [-0.5, 0.5]),
T x 3 u16 vertex indices (counter-clockwise seen from outside, as in the OBJ).

usage: bunny_bin.py /work/shared/meshes/bunny.obj assets/viewer/bunny.bin
"""
import struct
import sys

src, dst = sys.argv[1], sys.argv[2]
verts, tris = [], []
for line in open(src):
    f = line.split()
    if not f:
        continue
    if f[0] == "v":
        verts.append(tuple(float(x) for x in f[1:4]))
    elif f[0] == "f":
        idx = [int(x.split("/")[0]) - 1 for x in f[1:]]
        for k in range(1, len(idx) - 1):  # fan-triangulate polygons
            tris.append((idx[0], idx[k], idx[k + 1]))
assert len(verts) < 65536 and all(0 <= i < len(verts) for t in tris for i in t)
lo = [min(v[i] for v in verts) for i in range(3)]
hi = [max(v[i] for v in verts) for i in range(3)]
centre = [(a + b) / 2 for a, b in zip(lo, hi)]
scale = 1.0 / max(b - a for a, b in zip(lo, hi))
out = struct.pack("<II", len(verts), len(tris))
out += b"".join(struct.pack("<3f", *[(v[i] - centre[i]) * scale for i in range(3)]) for v in verts)
out += b"".join(struct.pack("<3H", *t) for t in tris)
open(dst, "wb").write(out)
print(f"{dst}: {len(verts)} vertices, {len(tris)} triangles, {len(out)} bytes")
