#!/usr/bin/env python3
"""Writes tests/data/meshes/leaves10.ply: the first ten leaves of the potted
plant of scenes/gen/interior.py (closed, 2.5 mm thick, about 3e-5 square
units a triangle), turned 25 degrees about y as in scenes/interior.glb and
lowered 0.3, for test_energy's flat_small_patches.

    python3 tests/data/meshes/leaves10.py      # from the repo root
"""
import os
import random
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
sys.path.insert(0, os.path.join(ROOT, 'scenes', 'gen'))
import interior as I  # noqa: E402

K = 10
rng = random.Random(1)
# The same draws as interior.py's build() before the plant.
I.room()
I.ceiling_panel()
I.shelf(rng)
plant, _ = I.plant(rng)
verts, tris, starts = plant.prims["Leaf"]
v_end, t_end = starts[K]
m = I.trs((0.0, -0.3, 0.0), I.quat((0, 1, 0), 25))
V = [I.xf(m, p) for p in verts[:v_end]]
T = tris[:t_end]
out = os.path.join(ROOT, 'tests', 'data', 'meshes', 'leaves10.ply')
with open(out, 'wb') as f:
    f.write(("ply\nformat binary_little_endian 1.0\n"
             "comment the first %d leaves of scenes/gen/interior.py's plant (tests/data/meshes/leaves10.py)\n"
             "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
             "element face %d\nproperty list uchar int vertex_indices\nend_header\n" % (K, len(V), len(T))).encode())
    for p in V:
        f.write(struct.pack('<3f', *p))
    for t in T:
        f.write(struct.pack('<B3i', 3, *t))
print("wrote %s: %d vertices, %d triangles" % (os.path.relpath(out), len(V), len(T)))
