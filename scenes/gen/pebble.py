#!/usr/bin/env python3
"""Writes scenes/meshes/pebble.obj: a closed, outward-oriented rounded cube
(the superellipsoid |x|^4 + |y|^4 + |z|^4 = 1, half-size 1) for scenes/csg.json.

Recipe: the six faces of the cube [-1, 1]^3 on an n x n grid, grid points
shared between faces (so the mesh is watertight), each pushed radially onto
the superellipsoid. n = 24 gives 6 * 24 * 24 * 2 = 6912 triangles.

    python3 scenes/gen/pebble.py [n]
"""
import os
import sys

n = int(sys.argv[1]) if len(sys.argv) > 1 else 24
E = 4.0

verts, index = [], {}


def vid(c):
    key = tuple(round(v * n) for v in c)  # grid coordinates: exact sharing
    if key not in index:
        s = sum(abs(v) ** E for v in c) ** (1.0 / E)
        index[key] = len(verts)
        verts.append(tuple(v / s for v in c))
    return index[key]


tris = []
for axis in range(3):
    for sign in (-1.0, 1.0):
        u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
        ids = {}
        for i in range(n + 1):
            for j in range(n + 1):
                c = [0.0, 0.0, 0.0]
                c[axis] = sign
                c[u_axis] = -1.0 + 2.0 * i / n
                c[v_axis] = -1.0 + 2.0 * j / n
                ids[i, j] = vid(c)
        for i in range(n):
            for j in range(n):
                a, b, cc, d = ids[i, j], ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]
                # u x v points along +axis: counter-clockwise seen from outside on the + face.
                if sign > 0:
                    tris += [(a, b, cc), (a, cc, d)]
                else:
                    tris += [(a, cc, b), (a, d, cc)]

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "meshes", "pebble.obj")
with open(out, "w") as f:
    f.write("# rounded cube |x|^4+|y|^4+|z|^4 = 1, n = %d: scenes/gen/pebble.py\n" % n)
    for v in verts:
        f.write("v %.9f %.9f %.9f\n" % v)
    for t in tris:
        f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))
print("%s: %d vertices, %d triangles" % (out, len(verts), len(tris)))
