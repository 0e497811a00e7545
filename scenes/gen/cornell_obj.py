#!/usr/bin/env python3
"""Writes the Cornell box of scenes/cornell.json as an OBJ + MTL pair, so that
an imported Cornell box can be checked against the JSON one:

    scenes/cornell-obj/cornell.obj   the geometry, one `o` per JSON object
    scenes/cornell-obj/cornell.mtl   one `newmtl` per JSON material
    scenes/cornell-obj.json          cornell.json's camera, lights, render and
                                     radiosity settings, with the OBJ as one
                                     "model" object (its materials come from
                                     the .mtl, so no "materials" block)

    python3 scenes/gen/cornell_obj.py           write the three files
    python3 scenes/gen/cornell_obj.py --check   re-read the OBJ and MTL and
                                                compare them with cornell.json

Geometry, as the loader builds it (notes/scene-format.md, scene/scene_objects.c,
scene/scene_xform.c):
  - quad: one 4-vertex face in the file's vertex order. Splitting it as
    (v0, v1, v2), (v0, v2, v3) gives radray's two triangles; OBJ faces are
    counter-clockwise = front, as in radray.
  - triangles: one 3-vertex face per triangle, all of the object's vertices
    written (in order, used or not).
  - box: the 8 corners (corner i takes x from bit 0, y from bit 1, z from
    bit 2 of i, 0 = min, 1 = max) and the 6 faces of build_box, in its order.
  - transform: steps composed exactly as scene_xform.c does it (the same
    double operations in the same order, so the points are bit-identical):
    p' = M p + t, the first step acting first; rotations by multiples of 90
    degrees use exact sines.
  - mirror (det M < 0) XOR "flip": radray swaps the 2nd and 3rd index of each
    triangle; here every face is reversed keeping its first vertex,
    [a, b, c, d] -> [a, d, c, b], whose fan split is the same two triangles.
Numbers are written with repr(), which round-trips doubles exactly.

Only what OBJ + MTL can say exactly is accepted: quad, triangles and box
objects, and materials with diffuse and emission only (Ks 0 0 0, Ns 1 and
illum 1 say "no Phong, no mirror"). Anything else (spheres, solids, meshes,
specular, mirror, ambient) is refused with a message rather than approximated.

--check reads the written OBJ back, splits every face as a fan from its first
vertex, drops zero-area triangles with radray's test, and compares the result
triangle for triangle (bit-exact doubles, same vertex order in each triangle)
with the triangles the loader makes from cornell.json, computed here from the
JSON: radray has no command that dumps its triangles (`radray info` prints
counts and bounds only), so this is a second, separate implementation of the
loader's rules (index lists and an index swap, not the writer's face lists and
reversal). It also compares the MTL with the JSON materials and, when
build/radray exists, the per-object triangle counts with `radray info`, and
renders cornell.json and the OBJ read back as inline triangles (hybrid and
direct, all AOVs) to compare the pixels: the binary's own check of winding and
materials (see render_check).
"""
import json
import math
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.dirname(HERE)
ROOT = os.path.dirname(SCENES)
SRC = os.path.join(SCENES, "cornell.json")
OUT_DIR = os.path.join(SCENES, "cornell-obj")
OBJ = os.path.join(OUT_DIR, "cornell.obj")
MTL = os.path.join(OUT_DIR, "cornell.mtl")
MODEL_SCENE = os.path.join(SCENES, "cornell-obj.json")
GEN = "scenes/gen/cornell_obj.py"


class Refused(Exception):
    pass


# ---- transforms, as scene_xform.c and core/rr_math.h compute them ----

def identity():
    return ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0, 0.0, 0.0])


def xform_vector(x, v):
    m = x[0]
    return [m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2]]


def xform_point(x, p):
    v = xform_vector(x, p)
    t = x[1]
    return [v[0] + t[0], v[1] + t[1], v[2] + t[2]]


def compose(a, b):
    """a after b (rr_xform_compose)."""
    am, bm = a[0], b[0]
    m = [[am[i][0] * bm[0][j] + am[i][1] * bm[1][j] + am[i][2] * bm[2][j] for j in range(3)] for i in range(3)]
    return (m, xform_point(a, b[1]))


def det(x):
    m = x[0]
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
            m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def rotation(axis, deg):
    ax = [float(a) for a in axis]
    l = math.sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2])
    if not l > 0:
        raise Refused("rotation axis is the zero vector")
    s = 1.0 / l
    x, y, z = ax[0] * s, ax[1] * s, ax[2] * s
    d = math.fmod(float(deg), 360.0)
    if d < 0:
        d += 360.0
    if d == 0:
        cs, sn = 1.0, 0.0
    elif d == 90:
        cs, sn = 0.0, 1.0
    elif d == 180:
        cs, sn = -1.0, 0.0
    elif d == 270:
        cs, sn = 0.0, -1.0
    else:
        cs = math.cos(d * 3.14159265358979323846 / 180.0)
        sn = math.sin(d * 3.14159265358979323846 / 180.0)
    t = 1 - cs
    return ([[cs + t * x * x, t * x * y - sn * z, t * x * z + sn * y],
             [t * x * y + sn * z, cs + t * y * y, t * y * z - sn * x],
             [t * x * z - sn * y, t * y * z + sn * x, cs + t * z * z]], [0.0, 0.0, 0.0])


def parse_transform(steps, where):
    """Returns (xform, has_transform)."""
    out = identity()
    if steps is None:
        return out, False
    for i, step in enumerate(steps):
        if not isinstance(step, dict) or len(step) != 1:
            raise Refused("%s.transform[%d]: expected one of translate, scale, rotate, matrix" % (where, i))
        (k, v), = step.items()
        x = identity()
        if k == "translate":
            x = (x[0], [float(c) for c in v])
        elif k == "scale":
            s = [float(v)] * 3 if isinstance(v, (int, float)) else [float(c) for c in v]
            if 0.0 in s:
                raise Refused("%s.transform[%d]: a zero scale" % (where, i))
            x[0][0][0], x[0][1][1], x[0][2][2] = s
        elif k == "rotate":
            x = rotation(v["axis"], v["degrees"])
        elif k == "matrix":
            x = ([[float(r[0]), float(r[1]), float(r[2])] for r in v], [float(r[3]) for r in v])
        else:
            raise Refused("%s.transform[%d]: unknown step '%s'" % (where, i, k))
        out = compose(x, out)
    return out, True


# ---- the JSON objects ----

BOX_FACES = [  # scene_objects.c build_box: -x, +x, -y, +y, -z, +z, counter-clockwise from outside
    (0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]


def box_corners(o):
    lo, hi = [float(c) for c in o["min"]], [float(c) for c in o["max"]]
    if not all(h > l for h, l in zip(hi, lo)):
        raise Refused("box max must be greater than min on every axis")
    return [[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)]


def object_name(o, i):
    return o.get("name", "objects[%d]" % i)


def check_supported(o, i):
    t = o.get("type")
    if t not in ("quad", "triangles", "box"):
        raise Refused("objects[%d] (%s): type '%s' has no exact OBJ form (only quad, triangles, box)"
                      % (i, object_name(o, i), t))


def object_geometry(o, i):
    """Writer's view: (transformed vertices, faces as lists of local indices)."""
    check_supported(o, i)
    t = o["type"]
    if t == "quad":
        pts = [[float(c) for c in p] for p in o["vertices"]]
        faces = [[0, 1, 2, 3]]
    elif t == "triangles":
        pts = [[float(c) for c in p] for p in o["vertices"]]
        faces = [list(f) for f in o["indices"]]
    else:
        pts = box_corners(o)
        faces = [list(f) for f in BOX_FACES]
    x, has_x = parse_transform(o.get("transform"), "objects[%d]" % i)
    reverse = bool(o.get("flip", False))
    if has_x:
        pts = [xform_point(x, p) for p in pts]
        if det(x) < 0:
            reverse = not reverse
    if reverse:
        faces = [[f[0]] + f[1:][::-1] for f in faces]
    return pts, faces


def loader_triangles(o, i):
    """Check's view, the loader's rules on index lists (build_quad / build_box /
    build_triangles, then transform_geom and the zero-area drop)."""
    t = o["type"]
    if t == "quad":
        pos = [[float(c) for c in p] for p in o["vertices"]]
        tris = [0, 1, 2, 0, 2, 3]
    elif t == "triangles":
        pos = [[float(c) for c in p] for p in o["vertices"]]
        tris = [int(k) for tri in o["indices"] for k in tri]
    elif t == "box":
        pos = box_corners(o)
        tris = []
        for q in BOX_FACES:
            tris += [q[0], q[1], q[2], q[0], q[2], q[3]]
    else:
        raise Refused("objects[%d]: type %s" % (i, t))
    x, has_x = parse_transform(o.get("transform"), "objects[%d]" % i)
    mirrored = bool(o.get("flip", False))
    if has_x:
        pos = [xform_point(x, p) for p in pos]
        if det(x) < 0:
            mirrored = not mirrored
    if mirrored:
        for k in range(0, len(tris), 3):
            tris[k + 1], tris[k + 2] = tris[k + 2], tris[k + 1]
    out = [tuple(tuple(pos[tris[k + j]]) for j in range(3)) for k in range(0, len(tris), 3)]
    return [tr for tr in out if not degenerate(*tr)]


def degenerate(a, b, c):
    """sp_tri_degenerate: twice the area below 1e-12 of the longest edge squared."""
    def sub(p, q):
        return (p[0] - q[0], p[1] - q[1], p[2] - q[2])

    def dot(p, q):
        return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]

    e0, e1, e2 = sub(b, a), sub(c, a), sub(c, b)
    cr = (e0[1] * e1[2] - e0[2] * e1[1], e0[2] * e1[0] - e0[0] * e1[2], e0[0] * e1[1] - e0[1] * e1[0])
    crl = math.sqrt(dot(cr, cr))
    l2 = max(dot(e0, e0), max(dot(e1, e1), dot(e2, e2)))
    return not (crl > 1e-12 * l2)


# ---- materials ----

def rgb(v, default):
    if v is None:
        return [float(default)] * 3
    if isinstance(v, (int, float)):
        return [float(v)] * 3
    return [float(c) for c in v]


def material_terms(name, m):
    """(Kd, Ke or None); refuses what an MTL with Ks 0 and illum 1 cannot say."""
    for key in ("specular", "mirror"):
        if key in m and any(c != 0 for c in rgb(m[key], 0)):
            raise Refused("material '%s': '%s' has no place in an illum 1 MTL material" % (name, key))
    if m.get("ambient", 0) != 0:
        raise Refused("material '%s': 'ambient' has no place in an illum 1 MTL material" % name)
    extra = set(m) - {"diffuse", "emission", "specular", "mirror", "ambient", "k"}
    if extra:
        raise Refused("material '%s': unknown keys %s" % (name, sorted(extra)))
    kd = rgb(m.get("diffuse"), 0.0 if "mirror" in m and "diffuse" not in m else 0.5)
    ke = rgb(m.get("emission"), 0.0)
    return kd, (ke if any(c != 0 for c in ke) else None)


def check_name(kind, name):
    if not name or re.search(r"\s", name):
        raise Refused("%s name %r: OBJ/MTL names cannot hold white space" % (kind, name))


def fmt(v):
    return " ".join(repr(float(c)) for c in v)


# ---- writing ----

def write_all(scene):
    os.makedirs(OUT_DIR, exist_ok=True)
    header = ("# Generated by %s from scenes/cornell.json; do not edit, run the generator.\n"
              "# The Cornell box of scenes/cornell.json, same geometry (millimetres), same winding\n"
              "# (counter-clockwise = front), numbers as repr() of the loader's doubles.\n" % GEN)
    mats = scene["materials"]
    mtl = [header, "# Materials: Kd = diffuse, Ke = emission (emitters only); Ks 0 0 0, Ns 1, illum 1:\n"
                   "# nothing specular, nothing mirrored.\n"]
    for name, m in mats.items():
        check_name("material", name)
        kd, ke = material_terms(name, m)
        mtl.append("\nnewmtl %s\nKd %s\n" % (name, fmt(kd)))
        if ke:
            mtl.append("Ke %s\n" % fmt(ke))
        mtl.append("Ks 0 0 0\nNs 1\nillum 1\n")

    obj = [header, "mtllib cornell.mtl\n"]
    base = 1
    for i, o in enumerate(scene["objects"]):
        name = object_name(o, i)
        check_name("object", name)
        if o.get("material") not in mats:
            raise Refused("objects[%d]: unknown material %r" % (i, o.get("material")))
        pts, faces = object_geometry(o, i)
        obj.append("\no %s\nusemtl %s\n" % (name, o["material"]))
        obj += ["v %s\n" % fmt(p) for p in pts]
        obj += ["f %s\n" % " ".join(str(base + k) for k in f) for f in faces]
        base += len(pts)

    model = {"format": scene["format"], "name": "cornell-obj",
             "description": "scenes/cornell.json as an imported OBJ + MTL (cornell-obj/cornell.obj, written by %s): "
                            "the same camera, render and radiosity settings, the geometry and materials from "
                            "the model, to check the importer against cornell.json." % GEN}
    for key in ("camera", "lights"):
        if key in scene:
            model[key] = scene[key]
    model["objects"] = [{"type": "model", "name": "cornell", "file": "cornell-obj/cornell.obj"}]
    for key in ("render", "radiosity"):
        if key in scene:
            model[key] = scene[key]

    for path, text in ((OBJ, "".join(obj)), (MTL, "".join(mtl)), (MODEL_SCENE, dumps(model))):
        with open(path, "w") as f:
            f.write(text)
        print("wrote %s" % os.path.relpath(path, ROOT))


def dumps(v):
    """JSON with 2-space indents, arrays of numbers on one line."""
    text = json.dumps(v, indent=2)
    return re.sub(r"\[\s*([-+0-9.eE,\s]*?)\s*\]", lambda m: "[" + ", ".join(m.group(1).replace(",", " ").split()) + "]",
                  text) + "\n"


# ---- checking ----

def read_obj(path):
    """Objects in file order: [name, material, vertices written after its `o`,
    faces as lists of indices into those vertices]."""
    verts, objs = [], []
    cur = None
    with open(path) as f:
        for ln, line in enumerate(f, 1):
            parts = line.split("#", 1)[0].split()
            if not parts:
                continue
            key = parts[0]
            if key == "o":
                cur = [parts[1], None, [], [], len(verts)]
                objs.append(cur)
            elif key == "mtllib":
                continue
            elif cur is None:
                raise SystemExit("%s:%d: '%s' before the first 'o'" % (path, ln, key))
            elif key == "v":
                verts.append(tuple(float(c) for c in parts[1:4]))
                cur[2].append(verts[-1])
            elif key == "usemtl":
                cur[1] = parts[1]
            elif key == "f":
                idx = [int(c.split("/")[0]) for c in parts[1:]]
                idx = [(k - 1 if k > 0 else len(verts) + k) - cur[4] for k in idx]
                if not all(0 <= k < len(cur[2]) for k in idx):
                    raise SystemExit("%s:%d: face outside its object's vertices" % (path, ln))
                cur[3].append(idx)
            else:
                raise SystemExit("%s:%d: unexpected '%s'" % (path, ln, key))
    return [o[:4] for o in objs]


def read_mtl(path):
    mats, cur = {}, None
    with open(path) as f:
        for line in f:
            parts = line.split("#", 1)[0].split()
            if not parts:
                continue
            if parts[0] == "newmtl":
                cur = mats.setdefault(parts[1], {})
            else:
                cur[parts[0]] = [float(c) for c in parts[1:]]
    return mats


def fan(face):
    return [(face[0], face[k], face[k + 1]) for k in range(1, len(face) - 1)]


def render_check(scene, objs):
    """Renders cornell.json and the OBJ read back (as inline "triangles"
    objects: each object's vertices as written, its faces fan-split) with
    build/radray, and compares the pixels (beauty and all AOV layers) by
    radray-exr-digest. Same triangles in the same order give the same
    scene, so the same image bit for bit; a reversed triangle (one-sided
    radiosity patches, the emitter's side), a wrong material or a visibly
    moved vertex changes it (tried: reversing the light's face or one
    triangle of the tall block changes the digest). It is the loader's own
    word on winding and materials, not a bit-exact test of the points (a
    vertex moved by one ulp renders the same at this size): that is the
    triangle comparison's job. Returns None without the binaries."""
    exe = os.path.join(ROOT, "build", "radray")
    dig = os.path.join(ROOT, "build", "radray-exr-digest")
    if not (os.access(exe, os.X_OK) and os.access(dig, os.X_OK)):
        return None
    import tempfile
    back = dict(scene)
    back["objects"] = [{"name": name, "type": "triangles", "material": mat, "vertices": [list(v) for v in verts],
                        "indices": [list(t) for f in faces for t in fan(f)]}
                       for name, mat, verts, faces in objs]
    results = []
    with tempfile.TemporaryDirectory(prefix="cornell_obj_check.") as tmp:
        back_path = os.path.join(tmp, "cornell.json")
        with open(back_path, "w") as f:
            json.dump(back, f)
        for mode in ("hybrid", "direct"):
            digests = []
            for i, src in enumerate((SRC, back_path)):
                out = os.path.join(tmp, "%s-%d.exr" % (mode, i))
                subprocess.run([exe, "render", src, "-o", out, "--no-png", "--width", "64", "--spp", "1",
                                "--mode", mode, "--aov", "all", "-q"], check=True)
                digests.append(subprocess.run([dig, out], capture_output=True, text=True,
                                              check=True).stdout.split()[0])
            results.append((mode, digests[0], digests[1]))
    return results


def radray_info_counts(path):
    """Per-object triangle counts from `build/radray info`, or None without the binary."""
    exe = os.path.join(ROOT, "build", "radray")
    if not os.access(exe, os.X_OK):
        return None
    out = subprocess.run([exe, "info", path], capture_output=True, text=True, check=True).stdout
    counts = {}
    for line in out.splitlines():
        m = re.match(r"^  (\S+)\s+(quad|triangles|box|mesh)\s+(\d+) tri", line)
        if m:
            counts[m.group(1)] = int(m.group(3))
    return counts


def check(scene):
    ok = True
    objs = read_obj(OBJ)
    want = [(object_name(o, i), o["material"], loader_triangles(o, i)) for i, o in enumerate(scene["objects"])]
    if [o[0] for o in objs] != [w[0] for w in want]:
        print("FAIL objects: OBJ has %s, cornell.json %s" % ([o[0] for o in objs], [w[0] for w in want]))
        return False
    total = 0
    for (name, mat, verts, faces), (wname, wmat, wtris) in zip(objs, want):
        got = [t for f in faces for t in fan([verts[k] for k in f]) if not degenerate(*t)]
        total += len(got)
        if mat != wmat:
            ok = False
            print("FAIL %s: usemtl %s, cornell.json material %s" % (name, mat, wmat))
        if got == wtris:
            print("ok   %-12s %3d triangles identical (bit-exact, same order), material %s" % (name, len(got), mat))
        elif sorted(got) == sorted(wtris):
            print("ok   %-12s %3d triangles identical as a set (each bit-exact, same vertex order; "
                  "face halves swapped by a mirror)" % (name, len(got)))
        else:
            ok = False
            extra = [t for t in got if t not in wtris]
            missing = [t for t in wtris if t not in got]
            print("FAIL %s: %d vs %d triangles; %d not in cornell.json, %d missing, first: %s / %s"
                  % (name, len(got), len(wtris), len(extra), len(missing), extra[:1], missing[:1]))
    print("%s %d triangles in all" % ("ok  " if ok else "FAIL", total))

    mtl = read_mtl(MTL)
    for name, m in scene["materials"].items():
        kd, ke = material_terms(name, m)
        g = mtl.get(name)
        good = (g is not None and g.get("Kd") == kd and g.get("Ke") == ke and g.get("Ks") == [0, 0, 0]
                and g.get("Ns") == [1] and g.get("illum") == [1])
        ok = ok and good
        print("%s material %-6s Kd %s%s" % ("ok  " if good else "FAIL", name, kd, " Ke %s" % ke if ke else ""))
    if set(mtl) != set(scene["materials"]):
        ok = False
        print("FAIL MTL materials %s vs %s" % (sorted(mtl), sorted(scene["materials"])))

    counts = radray_info_counts(SRC)
    if counts is None:
        print("note build/radray not found: no cross-check of the triangle counts with the loader")
    else:
        mine = {w[0]: len(w[2]) for w in want}
        good = counts == mine
        ok = ok and good
        print("%s per-object triangle counts match `build/radray info scenes/cornell.json` (%d objects)%s"
              % ("ok  " if good else "FAIL", len(counts), "" if good else ": %s vs %s" % (counts, mine)))
    rend = render_check(scene, objs)
    if rend is None:
        print("note build/radray or build/radray-exr-digest not found: no render comparison")
    for mode, a, b in rend or []:
        ok = ok and a == b
        print("%s %s render of cornell.json and of the OBJ read back as triangles, 65 x 65, AOVs too: "
              "pixel digests %s %s %s" % ("ok  " if a == b else "FAIL", mode, a, "==" if a == b else "!=", b))
    print("PASS" if ok else "FAIL")
    return ok


def main(argv):
    if any(a not in ("--check",) for a in argv[1:]):
        raise SystemExit(__doc__)
    with open(SRC) as f:
        scene = json.load(f)
    try:
        if "--check" in argv[1:]:
            return 0 if check(scene) else 1
        write_all(scene)
    except Refused as e:
        raise SystemExit("%s: %s" % (os.path.relpath(SRC, ROOT), e))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
