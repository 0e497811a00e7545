#!/usr/bin/env python3
"""Writes scenes/interior.glb: a furnished living room as a glTF 2.0 binary
asset, for the `"type": "model"` scene object (scenes/interior.json).

    python3 scenes/gen/interior.py        # from the repo root

What it makes (Y up, metres, the glTF conventions): a closed room 6 x 2.7 x
4.5 m (x -3..3, y 0..2.7, z -2.25..2.25) whose floor, ceiling and walls face
inwards and form one watertight shell together with the emissive window pane
"Window_Sky" that closes the hole in the back wall (z = -2.25); three
emissive ceiling panels; a framed mirror on the left wall (x = -3) above a
sofa with rounded cushions; a bookshelf full of books; a floor lamp; a
potted plant with a few hundred leaves (most of the triangles); a rug; a
dining table with turned legs and four chairs (one mesh, four nodes); and on
the table a glass vase and the Stanford bunny. Every furniture piece is a
closed, outward-oriented triangle mesh. No normals, UVs or textures: radray
shades with face normals. The output is deterministic (random.Random(1)).

Before writing, the script checks itself: the room shell (with the window
pane) and every closed piece have each undirected edge used exactly twice,
once in each direction (positions welded after float32 rounding); the shell
encloses a negative volume (faces point in), every piece a positive one; each
primitive (one radray object) welds to a manifold mesh, no edge shared by more
than two triangles; no triangle is degenerate; every furniture vertex lies
inside the room (a box, so the furniture cannot cross the shell).

Only the Python 3 standard library is used.
"""
import json
import math
import os
import random
import struct
import sys
from array import array

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# The Stanford bunny: Stanford 3D Scanning Repository, as published in the npm
# package `bunny` 1.0.1 (public domain), converted to ASCII PLY unchanged.
BUNNY = os.path.join(ROOT, '..', 'shared', 'models', 'bunny.ply')
OUT = os.path.join(ROOT, 'scenes', 'interior.glb')

X, H, Z = 3.0, 2.7, 2.25            # room: x in [-X, X], y in [0, H], z in [-Z, Z]
WIN = (-0.3, 1.5, 0.9, 2.2)         # window hole in the back wall: x0, x1, y0, y1

# ---------------------------------------------------------------- materials
MATERIALS = []                      # glTF material dicts, in file order
MAT = {}                            # name -> index

def material(name, rgb, metal=0.0, rough=0.8, alpha=1.0, emit=None, strength=None, blend=False):
    m = {"name": name, "pbrMetallicRoughness": {
        "baseColorFactor": [float(c) for c in rgb] + [alpha],
        "metallicFactor": metal, "roughnessFactor": rough}}
    if emit:
        m["emissiveFactor"] = list(emit)
        m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
    if blend:
        m["alphaMode"] = "BLEND"
    MAT[name] = len(MATERIALS)
    MATERIALS.append(m)

def grey(v): return (v, v, v)

material("Wall_Paint", (0.75, 0.73, 0.70))
material("Ceiling", grey(0.8))
material("Floor_Wood", (0.45, 0.30, 0.18), rough=0.6)
material("Window_Sky", grey(0.0), emit=(0.6, 0.75, 1.0), strength=6)
material("Window_Frame", (0.82, 0.82, 0.80), rough=0.4)
material("Ceiling_Panel", grey(0.8), emit=(1.0, 0.95, 0.85), strength=12)
material("Fixture", grey(0.8), rough=0.5)
material("Sofa_Fabric", (0.22, 0.30, 0.42), rough=1.0)
material("Cushion", (0.55, 0.50, 0.42), rough=1.0)
material("Pillow", (0.65, 0.28, 0.15), rough=1.0)
material("Dark_Wood", (0.12, 0.07, 0.04), rough=0.5)
material("Table_Wood", (0.50, 0.33, 0.20), rough=0.5)
material("Chair", (0.35, 0.22, 0.12), rough=0.6)
material("Shelf_Wood", (0.62, 0.48, 0.32), rough=0.6)
BOOKS = {"Book_Red": (0.60, 0.10, 0.08), "Book_Blue": (0.10, 0.18, 0.45),
         "Book_Green": (0.14, 0.38, 0.18), "Book_Ochre": (0.75, 0.55, 0.15),
         "Book_Cream": (0.82, 0.78, 0.65), "Book_Black": (0.05, 0.05, 0.06),
         "Book_Teal": (0.08, 0.42, 0.45)}
for _n, _c in BOOKS.items():
    material(_n, _c, rough=0.7)
material("Lamp_Shade", (0.85, 0.80, 0.68), rough=1.0)
material("Lamp_Metal", (0.55, 0.55, 0.52), metal=1.0, rough=0.5)
material("Leaf", (0.10, 0.35, 0.08), rough=0.6)
material("Stem", (0.30, 0.38, 0.15))
material("Pot", (0.62, 0.32, 0.20))
material("Soil", (0.10, 0.07, 0.05), rough=1.0)
material("Rug", (0.55, 0.12, 0.10), rough=1.0)
material("Vase", (0.30, 0.55, 0.60), rough=0.05, alpha=0.5, blend=True)
material("Mirror", grey(0.9), metal=1.0, rough=0.0)
material("Bunny", (0.8, 0.78, 0.75), rough=0.7)

# ---------------------------------------------------------------- vectors and transforms

def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def scl(a, s): return (a[0] * s, a[1] * s, a[2] * s)
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def unit(a): return scl(a, 1.0 / math.sqrt(dot(a, a)))

def quat(axis, deg):
    """glTF rotation [x, y, z, w] of deg degrees about axis."""
    ax, h = unit(axis), math.radians(deg) / 2
    return [ax[0] * math.sin(h), ax[1] * math.sin(h), ax[2] * math.sin(h), math.cos(h)]

def trs(t=(0, 0, 0), r=(0, 0, 0, 1), s=(1, 1, 1)):
    """3x4 affine matrix (rows) of a glTF translation, rotation and scale."""
    x, y, z, w = r
    R = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    return [[R[i][0] * s[0], R[i][1] * s[1], R[i][2] * s[2], t[i]] for i in range(3)]

def mmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) + (a[i][3] if j == 3 else 0)
             for j in range(4)] for i in range(3)]

def xf(m, p): return tuple(m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3] for i in range(3))

def det3(m): return dot(m[0][:3], cross(m[1][:3], m[2][:3]))

def rot(axis, deg, t=(0, 0, 0)): return trs(t, quat(axis, deg))

# ---------------------------------------------------------------- shape generators
# Each returns (verts, tris); closed shapes are outward-oriented (counter-
# clockwise seen from outside) and share their vertices (watertight).

def tri_quads(quads):
    """Quads split into two triangles each, dropping those with a repeated vertex (at poles)."""
    return [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d)) if len(set(t)) == 3]

def cube_grid(coords, f=None):
    """The surface of the box spanned by the coordinate lists coords[0..2],
    sampled on their grid, each point mapped by f."""
    index, verts, quads = {}, [], []

    def vid(p):
        i = index.get(p)
        if i is None:
            i = index[p] = len(verts)
            verts.append(f(p) if f else p)
        return i
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        for side in (0, -1):
            cu, cv = coords[u], coords[v]
            for i in range(len(cu) - 1):
                for j in range(len(cv) - 1):
                    q = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = [0.0, 0.0, 0.0]
                        p[a], p[u], p[v] = coords[a][side], cu[i + di], cv[j + dj]
                        q.append(vid(tuple(p)))
                    quads.append(q if side == -1 else q[::-1])
    return verts, tri_quads(quads)

def rbox(lo, hi, r=0.0, k=3, step=10.0):
    """Box lo..hi with edges rounded to radius r (k segments per 45 degrees)."""
    c = [(l + h) / 2 for l, h in zip(lo, hi)]
    half = [(h - l) / 2 for l, h in zip(lo, hi)]
    inner = [h - r for h in half]
    assert min(inner) > 0, (lo, hi, r)
    coords = []
    for a in range(3):
        m = max(1, round(2 * inner[a] / step))
        flat = [-inner[a] + 2 * inner[a] * i / m for i in range(m + 1)]
        band = [inner[a] + r * math.tan(math.pi / 4 * j / k) for j in range(1, k + 1)] if r else []
        coords.append([-b for b in reversed(band)] + flat + band)

    def f(p):
        if not r:
            return (c[0] + p[0], c[1] + p[1], c[2] + p[2])
        q = [max(-inner[a], min(inner[a], p[a])) for a in range(3)]
        d = unit(sub(p, q))      # clamped: no rounding error past the box's faces
        return tuple(max(lo[a], min(hi[a], c[a] + q[a] + r * d[a])) for a in range(3))
    return cube_grid(coords, f)

def ellipsoid(c, radii, n=12):
    """A spherified cube: an n x n grid per face pushed onto the ellipsoid."""
    t = [math.tan(math.pi / 4 * (2 * i / n - 1)) for i in range(n + 1)]

    return cube_grid([t, t, t], lambda p: tuple(c[a] + radii[a] * unit(p)[a] for a in range(3)))

def sweep(rings, n, loop=False):
    """Rings (centre, A, B) -> the surface through centre + cos(phi) A + sin(phi) B;
    a ring with A None is a pole (one vertex). Outward when A x B points against
    the direction in which the rings advance."""
    verts, rows = [], []
    for c, A, B in rings:
        if A is None:
            rows.append([len(verts)] * n)
            verts.append(tuple(c))
            continue
        rows.append(list(range(len(verts), len(verts) + n)))
        for j in range(n):
            cs, sn = math.cos(2 * math.pi * j / n), math.sin(2 * math.pi * j / n)
            verts.append(tuple(c[a] + cs * A[a] + sn * B[a] for a in range(3)))
    quads = []
    for i in range(len(rows) if loop else len(rows) - 1):
        r0, r1 = rows[i], rows[(i + 1) % len(rows)]
        quads += [(r0[j], r1[j], r1[(j + 1) % n], r0[(j + 1) % n]) for j in range(n)]
    return verts, tri_quads(quads)

def lathe(profile, n=48, c=(0, 0, 0), loop=False):
    """Surface of revolution about the vertical axis through c of the (r, y)
    profile; r = 0 at an end closes it with a pole. Outward when the profile
    runs counter-clockwise in the (r, y) half plane (e.g. bottom to top)."""
    rings = [((c[0], c[1] + y, c[2]), None, None) if r == 0 else
             ((c[0], c[1] + y, c[2]), (r, 0, 0), (0, 0, r)) for r, y in profile]
    return sweep(rings, n, loop)

def cylinder(c, r, h, n=48): return lathe([(0, 0), (r, 0), (r, h), (0, h)], n, c)

def tube(path, radius, n=10):
    """A capped tube along the polyline path (parallel-transported frames)."""
    T = [unit(sub(path[min(i + 1, len(path) - 1)], path[max(i - 1, 0)])) for i in range(len(path))]
    N = unit(cross(T[0], (1, 0, 0) if abs(T[0][0]) < 0.9 else (0, 1, 0)))
    rings = [(path[0], None, None)]
    for i, p in enumerate(path):
        N = unit(sub(N, scl(T[i], dot(N, T[i]))))
        r = radius(i / (len(path) - 1)) if callable(radius) else radius
        rings.append((p, scl(N, r), scl(cross(N, T[i]), r)))
    rings.append((path[-1], None, None))
    return sweep(rings, n)

def leaf(length, width, thick, fold, droop, nr=14, n=16):
    """A closed leaf along +x from the origin: an elliptic cross-section that
    follows the leaf outline, folded along the midrib and drooping."""
    rings = [((0, 0, 0), None, None)]
    for i in range(1, nr - 1):
        u = i / (nr - 1)
        w = math.sin(math.pi * u ** 0.8) ** 0.7
        rings.append(((u * length, 0, 0), (0, 0, width / 2 * w), (0, thick / 2 * w, 0)))
    rings.append(((length, 0, 0), None, None))
    verts, tris = sweep(rings, n)
    return [(x, y + fold * abs(z) - droop * x * x / length, z) for x, y, z in verts], tris

def subset(verts, tris):
    """The vertices tris use, renumbered."""
    ren = {}
    for i in (i for t in tris for i in t):
        ren.setdefault(i, len(ren))
    return [verts[i] for i in sorted(ren, key=ren.get)], [tuple(ren[i] for i in t) for t in tris]

# ---------------------------------------------------------------- mesh builder

class Mesh:
    """Triangles grouped by material (one glTF primitive each). Every add is
    a piece; pieces of one closed surface (even across materials) share a
    group, which the self-check tests for watertightness."""

    def __init__(self, name):
        self.name, self.prims, self.groups = name, {}, []

    def add(self, mat, geom, m=None, group=None, closed=True):
        verts, tris = geom
        if m is not None:
            assert det3(m) > 0
            verts = [xf(m, p) for p in verts]
        vs, ts, starts = self.prims.setdefault(mat, ([], [], []))
        base, t0 = len(vs), len(ts)
        starts.append((base, t0))
        vs.extend(verts)
        ts.extend((a + base, b + base, c + base) for a, b, c in tris)
        if group is None:
            group = [closed, []]
            self.groups.append(group)
        group[1].append((mat, t0, len(ts)))
        return group

    def add_box(self, mat, lo, hi, r=0.0, m=None, k=3, step=10.0):
        return self.add(mat, rbox(lo, hi, r, k, step), m)

    def add_quad(self, mat, quad, group):
        return self.add(mat, (quad, [(0, 1, 2), (0, 2, 3)]), group=group)

    def ntris(self):
        return sum(len(p[1]) for p in self.prims.values())

class Node:
    def __init__(self, name, mesh=None, t=None, r=None, s=None, children=()):
        self.name, self.mesh, self.t, self.r, self.s = name, mesh, t, r, s
        self.children = list(children)

    def matrix(self):
        return trs(self.t or (0, 0, 0), self.r or (0, 0, 0, 1), self.s or (1, 1, 1))

# ---------------------------------------------------------------- the room

def room():
    """The inward-facing shell; the back wall has the window hole, closed by
    the Window_Sky pane (same corner positions)."""
    m, sky = Mesh("Room"), Mesh("Window_Sky")
    x0, x1, y0, y1 = WIN
    g = m.add_quad("Floor_Wood", [(-X, 0, -Z), (-X, 0, Z), (X, 0, Z), (X, 0, -Z)], None)
    m.add_quad("Ceiling", [(-X, H, -Z), (X, H, -Z), (X, H, Z), (-X, H, Z)], g)
    for q in ([(-X, 0, Z), (-X, H, Z), (X, H, Z), (X, 0, Z)],       # front wall
              [(-X, 0, -Z), (-X, H, -Z), (-X, H, Z), (-X, 0, Z)],   # left wall
              [(X, 0, -Z), (X, 0, Z), (X, H, Z), (X, H, -Z)]):      # right wall
        m.add_quad("Wall_Paint", q, g)
    A, B, C, D = (-X, 0, -Z), (X, 0, -Z), (X, H, -Z), (-X, H, -Z)
    a, b, c, d = (x0, y0, -Z), (x1, y0, -Z), (x1, y1, -Z), (x0, y1, -Z)
    m.add("Wall_Paint", ([A, B, C, D, a, b, c, d],
                         [(0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5),
                          (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]), group=g)
    sky.add_quad("Window_Sky", [a, b, c, d], None)
    g[0] = False                     # closed only together with the pane: checked separately
    sky.groups[0][0] = False
    # window frame, sill and glazing bars, 1 mm in front of the wall; 0.5 mm
    # gaps between the pieces keep each of them a separate closed surface
    f, zb, zf, e = 0.06, -Z + 0.001, -Z + 0.05, 0.00025
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    fr = Mesh("Window_Frame")
    for lo, hi in (((x0 - f, y0, zb), (x0, y1 + f, zf)), ((x1, y0, zb), (x1 + f, y1 + f, zf)),
                   ((x0, y1, zb), (x1, y1 + f, zf)), ((x0 - 0.1, y0 - 0.04, zb), (x1 + 0.1, y0, -Z + 0.16)),
                   ((xm - 0.02, y0, zb), (xm + 0.02, y1, -Z + 0.03)),
                   ((x0, ym - 0.02, zb), (xm - 0.02, ym + 0.02, -Z + 0.03)),
                   ((xm + 0.02, ym - 0.02, zb), (x1, ym + 0.02, -Z + 0.03))):
        fr.add_box("Window_Frame", (lo[0] + e, lo[1] + e, zb), (hi[0] - e, hi[1] - e, hi[2]), r=0.004, k=2, step=0.5)
    return m, sky, fr

def ceiling_panel():
    """A unit fixture box 12 mm thick, top at y = 0; only its bottom emits
    (the nodes scale it to 0.6 x 0.6 m)."""
    m = Mesh("Ceiling_Panel")
    verts, tris = rbox((-0.5, -0.012, -0.5), (0.5, 0.0, 0.5))
    bottom = [t for t in tris if all(verts[i][1] == -0.012 for i in t)]
    g = m.add("Fixture", subset(verts, [t for t in tris if t not in bottom]))
    m.add("Ceiling_Panel", subset(verts, bottom), group=g)
    return m

def mirror():
    """Local: facing +z, its back 2 mm off the wall plane z = 0."""
    m = Mesh("Mirror")
    m.add_box("Dark_Wood", (-0.66, -0.51, 0.002), (0.66, 0.51, 0.024), r=0.006, k=3, step=0.2)
    m.add_box("Mirror", (-0.6, -0.45, 0.025), (0.6, 0.45, 0.029))
    return m

# ---------------------------------------------------------------- furniture

def sofa():
    """Local: 2 m wide along x, back at z = -0.45, facing +z."""
    m = Mesh("Sofa")
    for x in (-0.9, 0.9):
        for z in (-0.36, 0.36):
            m.add("Dark_Wood", lathe([(0, 0), (0.02, 0), (0.028, 0.07), (0.028, 0.08), (0, 0.08)], 32, (x, 0, z)))
    m.add_box("Sofa_Fabric", (-1.0, 0.08, -0.45), (1.0, 0.30, 0.45), r=0.03, k=4, step=0.04)
    for x in (-1.0, 0.82):
        m.add_box("Sofa_Fabric", (x, 0.301, -0.45), (x + 0.18, 0.64, 0.45), r=0.07, k=5, step=0.04)
    m.add_box("Sofa_Fabric", (-0.815, 0.301, -0.45), (0.815, 0.86, -0.28), r=0.06, k=5, step=0.04)
    w = (1.62 - 0.02) / 3
    for i in range(3):
        x = -0.81 + i * (w + 0.01)
        m.add_box("Cushion", (x, 0.302, -0.275), (x + w, 0.46, 0.44), r=0.06, k=6, step=0.025)
        m.add_box("Cushion", (x, 0.462, -0.275), (x + w, 0.82, -0.11), r=0.07, k=6, step=0.025)
    for x, tilt in ((-0.58, 10), (0.58, -10)):
        mt = mmul(rot((0, 0, 1), tilt, (x, 0.67, -0.034)), rot((1, 0, 0), -12))
        m.add("Pillow", ellipsoid((0, 0, 0), (0.19, 0.18, 0.065), 20), mt)
    return m

def table():
    """Local: 1.4 x 0.84 m top at y 0.72..0.76, centred on the origin."""
    m = Mesh("Table")
    m.add_box("Table_Wood", (-0.7, 0.72, -0.42), (0.7, 0.76, 0.42), r=0.012, k=4, step=0.03)
    leg = [(0, 0), (0.022, 0), (0.026, 0.01), (0.024, 0.05), (0.02, 0.25), (0.024, 0.42),
           (0.032, 0.47), (0.024, 0.52), (0.03, 0.58), (0.032, 0.6), (0.032, 0.72), (0, 0.72)]
    for x in (-0.62, 0.62):
        for z in (-0.34, 0.34):
            m.add("Table_Wood", lathe(leg, 64, (x, 0, z)))
    for z in (-0.3, 0.28):
        m.add_box("Table_Wood", (-0.56, 0.64, z), (0.56, 0.7199, z + 0.02), r=0.004, k=2)
    for x in (-0.58, 0.56):
        m.add_box("Table_Wood", (x, 0.64, -0.28), (x + 0.02, 0.7199, 0.28), r=0.004, k=2)
    return m

def chair():
    """Local: seat centred on the origin at y 0.43..0.47, the sitter facing +z."""
    m = Mesh("Chair")
    m.add_box("Chair", (-0.22, 0.43, -0.21), (0.22, 0.47, 0.23), r=0.015, k=4, step=0.03)
    for x in (-0.19, 0.19):
        for z in (-0.18, 0.19):
            m.add("Chair", lathe([(0, 0), (0.014, 0), (0.018, 0.4), (0.018, 0.43), (0, 0.43)], 40, (x, 0, z)))
        m.add("Chair", lathe([(0, 0), (0.016, 0), (0.016, 0.43), (0.012, 0.45), (0, 0.45)], 40, (x, 0.47, -0.18)))
    bend = lambda g: ([(x, y, z + 0.25 * x * x) for x, y, z in g[0]], g[1])
    for y0, y1 in ((0.58, 0.64), (0.74, 0.9)):
        m.add("Chair", bend(rbox((-0.17, y0, -0.2), (0.17, y1, -0.18), r=0.008, k=3, step=0.02)))
    return m

def shelf(rng):
    """Local: 1.2 m wide (x 0..1.2), back against z = 0, 2 m tall; the books
    are a child node."""
    m, b = Mesh("Shelf"), Mesh("Books")
    boards = (0.0, 0.42, 0.82, 1.22, 1.62, 1.98)
    for x in (0.0, 1.18):
        m.add_box("Shelf_Wood", (x, 0, 0.001), (x + 0.02, 2.0, 0.34), r=0.003, k=2, step=0.5)
    m.add_box("Shelf_Wood", (0.02, 0.06, 0.001), (1.18, 1.98, 0.012))
    for i, y in enumerate(boards):
        y0, y1 = (0.0, 0.06) if i == 0 else (y, y + 0.02)
        m.add_box("Shelf_Wood", (0.02, y0, 0.012), (1.18, y1, 0.34), r=0.003, k=2, step=0.5)
    names = list(BOOKS)
    for i in range(1, 5):
        base, room_h = boards[i] + 0.02, boards[i + 1] - boards[i] - 0.02
        x = 0.03 + rng.uniform(0, 0.05)
        while True:
            if rng.random() < 0.12:          # a stack of books lying flat
                w = rng.uniform(0.16, 0.24)
                if x + w > 1.17:
                    break
                y = base
                for _ in range(rng.randint(2, 5)):
                    t = rng.uniform(0.02, 0.045)
                    d = rng.uniform(0.15, 0.22)
                    dx = rng.uniform(0, 0.02)
                    b.add_box(rng.choice(names), (x + dx, y, 0.02), (x + dx + w - 0.02, y + t, 0.02 + d), r=0.003, k=2, step=0.5)
                    y += t
                x += w + 0.01
                continue
            w = rng.uniform(0.018, 0.055)
            if x + w > 1.17:
                break
            h = rng.uniform(0.6, 0.92) * room_h
            d = rng.uniform(0.15, 0.27)
            b.add_box(rng.choice(names), (x, base, 0.02), (x + w, base + h, 0.02 + d), r=0.003, k=2, step=0.5)
            x += w + (rng.uniform(0.04, 0.12) if rng.random() < 0.05 else 0.0015)
    return m, b

def lamp():
    """Local: a floor lamp standing at the origin."""
    m = Mesh("Lamp")
    m.add("Lamp_Metal", lathe([(0, 0), (0.15, 0), (0.16, 0.006), (0.16, 0.016), (0.14, 0.026),
                               (0.03, 0.032), (0, 0.034)], 64))
    m.add("Lamp_Metal", cylinder((0, 0.034, 0), 0.011, 1.52, 24))
    m.add("Lamp_Metal", lathe([(0, 0), (0.02, 0), (0.02, 0.05), (0, 0.05)], 24, (0, 1.554, 0)))
    m.add("Fixture", ellipsoid((0, 1.655, 0), (0.035, 0.05, 0.035), 8))
    m.add("Lamp_Shade", lathe([(0.22, 1.40), (0.14, 1.70), (0.136, 1.70), (0.216, 1.40)], 96, loop=True))
    for k in range(3):
        a = 2 * math.pi * k / 3
        m.add("Lamp_Metal", tube([(0.015 * math.cos(a), 1.6, 0.015 * math.sin(a)),
                                  (0.158 * math.cos(a), 1.6, 0.158 * math.sin(a))], 0.003, 8))
    return m

def plant(rng):
    """Local: a pot on the origin with curved stems carrying many leaves.
    Leaves are kept within 0.55 m of the pot's axis and below 1.9 m."""
    m = Mesh("Plant")
    m.add("Pot", lathe([(0, 0), (0.15, 0), (0.2, 0.33), (0.215, 0.335), (0.215, 0.37),
                        (0.195, 0.37), (0.19, 0.34), (0, 0.34)], 96))
    m.add("Soil", cylinder((0, 0.341, 0), 0.185, 0.009, 96))
    nleaf = 0
    for s in range(9):
        az = 2 * math.pi * (s + rng.uniform(-0.3, 0.3)) / 9
        lean, top = rng.uniform(0.1, 0.3), rng.uniform(0.8, 1.35)
        base = (0.05 * math.cos(az), 0.35, 0.05 * math.sin(az))
        tip = (lean * math.cos(az), 0.35 + top, lean * math.sin(az))
        mid = (base[0] * 0.5, 0.35 + 0.55 * top, base[2] * 0.5)
        curve = lambda t: tuple((1 - t) ** 2 * base[a] + 2 * t * (1 - t) * mid[a] + t * t * tip[a] for a in range(3))
        m.add("Stem", tube([curve(i / 24) for i in range(25)], lambda t: 0.008 * (1 - 0.6 * t), 10))
        k = 0
        for i in range(60):
            t = 0.2 + 0.8 * i / 59
            p = curve(t)
            L = (0.09 + 0.11 * math.sin(math.pi * min(1, t * 1.1))) * rng.uniform(0.8, 1.15)
            yaw = az + (math.pi * 0.6 if k % 2 else -math.pi * 0.6) + rng.uniform(-0.6, 0.6)
            pitch = rng.uniform(15, 55) * (1.2 - 0.4 * t)
            k += 1
            mt = mmul(rot((0, 1, 0), -math.degrees(yaw), p),
                      mmul(rot((0, 0, 1), pitch), rot((1, 0, 0), rng.uniform(-25, 25))))
            g = leaf(L, L * rng.uniform(0.35, 0.45), 0.0025, rng.uniform(0.1, 0.25), rng.uniform(0.2, 0.5))
            pts = [xf(mt, q) for q in g[0]]
            if all(q[0] ** 2 + q[2] ** 2 < 0.55 ** 2 and 0.35 < q[1] < 1.9 for q in pts):
                m.add("Leaf", (pts, g[1]))
                nleaf += 1
    return m, nleaf

def rug():
    m = Mesh("Rug")
    m.add_box("Rug", (-0.8, 0.001, -0.95), (0.8, 0.012, 0.95), r=0.005, k=3, step=0.1)
    return m

# The vase's (r, y) profile: up the outer wall to the lip, down the inner wall.
VASE_PROFILE = [(0, 0), (0.04, 0), (0.046, 0.004), (0.058, 0.04), (0.064, 0.08), (0.058, 0.12),
                (0.042, 0.16), (0.03, 0.19), (0.032, 0.215), (0.037, 0.23), (0.035, 0.234),
                (0.031, 0.232), (0.027, 0.215), (0.025, 0.19), (0.037, 0.16), (0.053, 0.12),
                (0.059, 0.08), (0.053, 0.04), (0.037, 0.01), (0, 0.008)]

def vase():
    """Local: a hollow glass vase on the origin (closed: outer wall, lip, inner wall)."""
    m = Mesh("Vase")
    m.add("Vase", lathe(VASE_PROFILE, 96))
    return m

def bunny():
    """The bunny as stored (y up already, about 9.66 units tall); its node scales it."""
    with open(BUNNY) as f:
        lines = f.read().split('\n')
    end = lines.index('end_header')
    count = {w[1]: int(w[2]) for w in (l.split() for l in lines[:end]) if w[0] == 'element'}
    nv, nf = count['vertex'], count['face']
    verts = [tuple(map(float, l.split()[:3])) for l in lines[end + 1:end + 1 + nv]]
    tris = []
    for l in lines[end + 1 + nv:end + 1 + nv + nf]:
        w = list(map(int, l.split()))
        tris += [(w[1], w[1 + i], w[2 + i]) for i in range(1, w[0] - 1)]
    m = Mesh("Bunny")
    m.add("Bunny", (verts, tris))
    return m

# ---------------------------------------------------------------- the scene

def build():
    rng = random.Random(1)
    rm, sky, frame = room()
    panel = ceiling_panel()
    sh, books = shelf(rng)
    pl, nleaf = plant(rng)
    ch = chair()
    bn = bunny()
    ymin = min(p[1] for p in bn.prims["Bunny"][0])
    ymax = max(p[1] for p in bn.prims["Bunny"][0])
    s = 0.25 / (ymax - ymin)
    chairs = [Node("Chair.%03d" % (i + 1), ch, t=[x, 0, z], r=quat((0, 1, 0), deg))
              for i, (x, z, deg) in enumerate(((0.65, -0.7, 4), (1.35, -0.7, -7),
                                                (0.65, 0.7, 174), (1.38, 0.72, 190)))]
    tbl = Node("Table", table(), t=[1.0, 0, 0], children=[
        Node("Bunny", bn, t=[-0.15, 0.7605 - s * ymin, 0.02], r=quat((0, 1, 0), 120), s=[s, s, s]),
        Node("Vase", vase(), t=[0.33, 0.7605, -0.14])])
    root = Node("Interior", children=[
        Node("Room", rm), Node("Window_Sky", sky), Node("Window_Frame", frame)] +
        [Node("Ceiling_Panel.%03d" % (i + 1), panel, t=[x, H - 0.003, 0.0], s=[0.6, 1, 0.6])
         for i, x in enumerate((-1.9, 0.0, 1.9))] + [
        Node("Mirror", mirror(), t=[-X, 1.6, 0.3], r=quat((0, 1, 0), 90)),
        Node("Sofa", sofa(), t=[-X + 0.48, 0, 0.3], r=quat((0, 1, 0), 90)),
        Node("Rug", rug(), t=[-1.15, 0, 0.3]),
        tbl] + chairs + [
        Node("Shelf", sh, t=[-2.85, 0, -Z], children=[Node("Books", books, t=[0, 0, 0.01])]),
        Node("Lamp", lamp(), t=[-2.62, 0, -1.4]),
        Node("Plant", pl, t=[-1.0, 0, -1.65], r=quat((0, 1, 0), 25))])
    return root, nleaf

def walk(node, parent=None):
    """(node, world matrix) for every node, depth first."""
    m = node.matrix() if parent is None else mmul(parent, node.matrix())
    yield node, m
    for c in node.children:
        yield from walk(c, m)

# ---------------------------------------------------------------- self-check

def f32(verts):
    a = array('f', [c for p in verts for c in p]).tolist()
    return [tuple(a[i:i + 3]) for i in range(0, len(a), 3)]

def edge_check(tris):
    """tris: triangles as position triples, welded by position. Returns (edges
    not used exactly once in each direction, edges used more than twice, volume)."""
    ids, edges, vol = {}, {}, 0.0
    for t in tris:
        k = [ids.setdefault(p, len(ids)) for p in t]
        for e in ((k[0], k[1]), (k[1], k[2]), (k[2], k[0])):
            edges[e] = edges.get(e, 0) + 1
        vol += dot(t[0], cross(t[1], t[2])) / 6
    bad = sum(1 for (a, b), n in edges.items() if n != 1 or edges.get((b, a)) != 1)
    over = sum(1 for (a, b), n in edges.items() if a < b and n + edges.get((b, a), 0) > 2)
    return bad, over, vol

def self_check(root):
    problems, min_area, npieces = [], 1e9, 0
    shell, seen = [], set()
    for node, m in walk(root):
        mesh = node.mesh
        if mesh is None:
            continue
        pos = {mat: f32(p[0]) for mat, p in mesh.prims.items()}
        for mat, (vs, ts, _) in mesh.prims.items():
            P = pos[mat]
            for a, b, c in ts:
                n = cross(sub(P[b], P[a]), sub(P[c], P[a]))
                min_area = min(min_area, math.sqrt(dot(n, n)) / 2)
            if node.name in ("Room", "Window_Sky"):
                shell += [tuple(tuple(xf(m, P[i])) for i in t) for t in ts]
            else:
                for p in P:
                    w = xf(m, p)
                    if not (-X < w[0] < X and -1e-7 <= w[1] < H and -Z < w[2] < Z):
                        problems.append("%s: vertex %s outside the room" % (node.name, w))
                        break
        if id(mesh) in seen:         # an instance: its pieces are checked already
            continue
        seen.add(id(mesh))
        for mat, (vs, ts, _) in mesh.prims.items():   # one radray object each: welded, manifold
            over = edge_check([tuple(pos[mat][i] for i in t) for t in ts])[1]
            if over:
                problems.append("%s: primitive %s has %d non-manifold edges" % (mesh.name, mat, over))
        for closed, parts in mesh.groups:
            if not closed:
                continue
            npieces += 1
            tris = [tuple(pos[mat][i] for i in t) for mat, t0, t1 in parts
                    for t in mesh.prims[mat][1][t0:t1]]
            bad, _, vol = edge_check(tris)
            if bad or vol <= 0:
                problems.append("%s: a piece (%s) has %d bad edges, volume %g" % (mesh.name, parts[0][0], bad, vol))
    # float32 positions transformed by an identity matrix are unchanged, so the weld is exact
    bad, _, vol = edge_check(shell)
    if bad or vol >= 0:
        problems.append("room shell: %d bad edges, volume %g (expected < 0: facing in)" % (bad, vol))
    if min_area < 1e-12:
        problems.append("degenerate triangle (area %g)" % min_area)
    for mt in MATERIALS:
        c = mt["pbrMetallicRoughness"]["baseColorFactor"][:3]
        if max(c) > 0.85 and mt["name"] != "Mirror":
            problems.append("material %s: base colour over 0.85" % mt["name"])
    return problems, npieces, min_area, vol

# ---------------------------------------------------------------- glTF writer

def write_glb(root, path):
    nodes, meshes, mesh_ids = [], [], {}
    accessors, views, blob = [], [], bytearray()

    def view(data, target):
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        return len(views) - 1

    def prim(mat, verts, tris):
        a = array('f', [c for p in verts for c in p])
        if sys.byteorder != 'little':
            a.byteswap()
        vals = a.tolist()
        lo = [min(vals[k::3]) for k in range(3)]
        hi = [max(vals[k::3]) for k in range(3)]
        accessors.append({"bufferView": view(a.tobytes(), 34962), "componentType": 5126,
                          "count": len(verts), "type": "VEC3", "min": lo, "max": hi})
        small = len(verts) < 65536
        ia = array('H' if small else 'I', [i for t in tris for i in t])
        if sys.byteorder != 'little':
            ia.byteswap()
        accessors.append({"bufferView": view(ia.tobytes(), 34963), "componentType": 5123 if small else 5125,
                          "count": len(ia), "type": "SCALAR"})
        return {"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
                "material": MAT[mat], "mode": 4}

    def mesh_index(mesh):
        if id(mesh) in mesh_ids:
            return mesh_ids[id(mesh)]
        prims = []
        for mat, (vs, ts, starts) in mesh.prims.items():
            # split at piece boundaries so that each primitive has < 65536 vertices
            bounds = [s for s in starts] + [(len(vs), len(ts))]
            c0 = 0
            for i in range(1, len(bounds)):
                last = i == len(bounds) - 1
                if last or bounds[i + 1][0] - bounds[c0][0] >= 65536:
                    v0, t0 = bounds[c0]
                    v1, t1 = bounds[i]
                    prims.append(prim(mat, vs[v0:v1], [(a - v0, b - v0, c - v0) for a, b, c in ts[t0:t1]]))
                    c0 = i
        meshes.append({"name": mesh.name, "primitives": prims})
        mesh_ids[id(mesh)] = len(meshes) - 1
        return len(meshes) - 1

    def add_node(node):
        idx = len(nodes)
        nd = {"name": node.name}
        nodes.append(nd)
        if node.mesh is not None:
            nd["mesh"] = mesh_index(node.mesh)
        for key, val in (("translation", node.t), ("rotation", node.r), ("scale", node.s)):
            if val is not None:
                nd[key] = [round(v, 9) + 0.0 for v in val]
        if node.children:
            nd["children"] = [add_node(c) for c in node.children]
        return idx
    add_node(root)
    while len(blob) % 4:
        blob.append(0)
    doc = {"asset": {"version": "2.0", "generator": "radray scenes/gen/interior.py"},
           "extensionsUsed": ["KHR_materials_emissive_strength"],
           "scene": 0, "scenes": [{"name": "Interior", "nodes": [0]}],
           "nodes": nodes, "meshes": meshes, "materials": MATERIALS,
           "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}]}
    js = json.dumps(doc, separators=(',', ':')).encode('utf-8')
    js += b' ' * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    out = struct.pack('<III', 0x46546C67, 2, total)
    out += struct.pack('<II', len(js), 0x4E4F534A) + js
    out += struct.pack('<II', len(blob), 0x004E4942) + bytes(blob)
    with open(path, 'wb') as f:
        f.write(out)
    return len(out), sum(len(m["primitives"]) for m in meshes)

def main():
    root, nleaf = build()
    problems, npieces, min_area, shell_vol = self_check(root)
    for p in problems[:20]:
        print("self-check:", p, file=sys.stderr)
    if problems:
        sys.exit("self-check failed (%d problems)" % len(problems))
    meshes = [node.mesh for node, _ in walk(root) if node.mesh is not None]
    unique = {id(m): m for m in meshes}
    scene_tris = sum(m.ntris() for m in meshes)
    file_tris = sum(m.ntris() for m in unique.values())
    size, nprims = write_glb(root, OUT)
    print("self-check passed: room shell watertight (volume %.3f m^3, facing in), %d closed pieces, "
          "smallest triangle %.3g m^2, %d leaves" % (-shell_vol, npieces, min_area, nleaf))
    for m in unique.values():
        print("  %-14s %7d triangles" % (m.name, m.ntris()))
    print("wrote %s: %d meshes (%d primitives), %d materials, %d triangles in the file, "
          "%d in the scene (instances counted), %d bytes (%.2f MB)"
          % (os.path.relpath(OUT), len(unique), nprims, len(MATERIALS), file_tris, scene_tris, size, size / 1e6))

if __name__ == '__main__':
    main()
