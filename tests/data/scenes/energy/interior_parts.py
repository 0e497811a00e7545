#!/usr/bin/env python3
"""Writes two parts of scenes/interior.json's room as test scenes (glTF 2.0,
scenes/gen/interior.py's functions; tests/test_energy.c slivers_split,
near_sources_split), each the room's shell, its window pane and its three
ceiling fixtures, with:
- window-slots.glb / .json: the window's vertical glazing bar and the two
  horizontal ones that meet its sides across 0.5 mm slots, 1 mm in front of
  the pane, rounded boxes whose long faces are triangles 3 cm x 30-70 cm;
  the bars' faces that look along -x and +x (the vertical bar's sides, the
  horizontal bars' ends) are the nodes Bars_XM and Bars_XP;
- raised-box.glb / .json: the sofa's base, a rounded box 2 x 0.22 x 0.9 m
  standing 8 cm over the floor (on no legs) and 3 cm from the left wall;
  its underside is the node Box_Bottom, its back Box_Back, the rest Box.
- table-rlc.glb / .json: the dining table (turned legs, rails), its faces
  that look down (the top's underside, the rails' bottoms) the node
  Table_Down, the rest Table, solved with receiving leaf clusters on
  (radiosity.receiving_clusters 1: clusters of its small triangles receive
  their links as one, as they do in the whole room).
- vase-rlc.glb / .json: the table with the vase on it, the vase (a closed
  thin-walled lathe) in two nodes: its inner wall Vase_In (which the room
  sees through the neck alone), its outer wall and lip Vase_Out; receiving
  leaf clusters on, as in table-rlc.
- leaf-window.glb / .json: one of the plant's leaves (scenes/gen/interior.py
  leaf()) 0.35 m in front of the back wall and 0.4 m left of the window, the
  room's surfaces black and the ceiling fixtures dark: the window pane, seen
  at a slant past its edge, is the only light and the leaf (node Leaf, black)
  takes it in directly.
Run from anywhere: python3 tests/data/scenes/energy/interior_parts.py"""
import json, os, sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "..", "..", "..", "scenes", "gen"))
import interior as I


def by_normal(mesh, name_of):
    """The triangles of mesh regrouped into meshes by name_of(normal)."""
    groups = {}
    for mat, (vs, ts, st) in mesh.prims.items():
        for t in ts:
            a, b, c = (vs[i] for i in t)
            groups.setdefault(name_of(I.cross(I.sub(b, a), I.sub(c, a))), []).append((mat, (a, b, c)))
    out = {}
    for name, tl in groups.items():
        m = I.Mesh(name)
        for mat in sorted({t[0] for t in tl}):
            tris = [t[1] for t in tl if t[0] == mat]
            m.add(mat, ([p for t in tris for p in t], [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(len(tris))]),
                  closed=False)
        out[name] = m
    return out


def axis_name(n, pre):
    k = max(range(3), key=lambda i: abs(n[i]))
    return pre + "_" + "XYZ"[k] + ("P" if n[k] > 0 else "M")


def write(name, nodes, desc, radiosity=None):
    rm, sky, _ = I.room()
    panel = I.ceiling_panel()
    shell = [I.Node("Room", rm), I.Node("Window_Sky", sky)] + \
        [I.Node("Ceiling_Panel.%03d" % (i + 1), panel, t=[x, I.H - 0.003, 0.0], s=[0.6, 1, 0.6])
         for i, x in enumerate((-1.9, 0.0, 1.9))]
    I.write_glb(I.Node("Interior", children=shell + nodes), os.path.join(here, name + ".glb"))
    scene = {"format": "radray-scene/1", "name": name,
             "description": desc + " (written by interior_parts.py from scenes/gen/interior.py).",
             "camera": {"type": "lookat", "eye": [2.65, 1.5, 1.95], "target": [-0.41, 0.9, -0.62],
                        "up": [0, 1, 0], "fov": 60, "width": 32, "height": 20},
             "radiosity": dict({"method": "hierarchical"}, **(radiosity or {})),
             "objects": [{"type": "model", "name": "part", "file": name + ".glb"}]}
    with open(os.path.join(here, name + ".json"), "w") as f:
        json.dump(scene, f, indent=1)
        f.write("\n")


# the bars as interior.py's room() draws them (pieces 4, 5, 6 of its frame)
x0, x1, y0, y1 = I.WIN
f, zb, e = 0.06, -I.Z + 0.001, 0.00025
xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
bars = I.Mesh("Bars")
for lo, hi in (((xm - 0.02, y0, zb), (xm + 0.02, y1, -I.Z + 0.03)),
               ((x0, ym - 0.02, zb), (xm - 0.02, ym + 0.02, -I.Z + 0.03)),
               ((xm + 0.02, ym - 0.02, zb), (x1, ym + 0.02, -I.Z + 0.03))):
    bars.add_box("Window_Frame", (lo[0] + e, lo[1] + e, zb), (hi[0] - e, hi[1] - e, hi[2]), r=0.004, k=2, step=0.5)
parts = by_normal(bars, lambda n: "Bars_XM" if axis_name(n, "")[1:] == "XM" else
                  "Bars_XP" if axis_name(n, "")[1:] == "XP" else "Bars")
write("window-slots", [I.Node(k, parts[k]) for k in sorted(parts)],
      "scenes/interior.json's room, window pane and ceiling fixtures with its three glazing bars, 1 mm in front of "
      "the pane, the horizontal ones 0.5 mm short of the vertical one (slots where they meet); the bars' faces "
      "along -x and +x are the nodes Bars_XM and Bars_XP")

# the sofa's base as interior.py's sofa() draws it, placed as its Sofa node is
base = I.Mesh("Base")
base.add_box("Sofa_Fabric", (-1.0, 0.08, -0.45), (1.0, 0.30, 0.45), r=0.03, k=4, step=0.04)
parts = by_normal(base, lambda n: {"YM": "Box_Bottom", "ZM": "Box_Back"}.get(axis_name(n, "")[1:], "Box"))
write("raised-box", [I.Node("Sofa", None, t=[-I.X + 0.48, 0, 0.3], r=I.quat((0, 1, 0), 90),
                            children=[I.Node(k, parts[k]) for k in sorted(parts)])],
      "scenes/interior.json's room, window pane and ceiling fixtures with its sofa's base, a rounded box 2 x 0.22 x "
      "0.9 m standing 8 cm over the floor and 3 cm from the left wall; its underside is the node Box_Bottom, its "
      "back Box_Back")

# the table as interior.py's table() draws it, placed as its Table node is
parts = by_normal(I.table(), lambda n: "Table_Down" if axis_name(n, "")[1:] == "YM" else "Table")
write("table-rlc", [I.Node("Dining", None, t=[1.0, 0, 0], children=[I.Node(k, parts[k]) for k in sorted(parts)])],
      "scenes/interior.json's room, window pane and ceiling fixtures with its dining table, its faces that look "
      "down the node Table_Down, solved with receiving leaf clusters on",
      {"receiving_clusters": 1})

# the vase as interior.py's vase() draws it (its profile cut where the lip's
# top turns inwards), on the table as its Vase node stands
P = I.VASE_PROFILE
vase_out, vase_in = I.Mesh("Vase_Out"), I.Mesh("Vase_In")
vase_out.add("Vase", I.lathe(P[:12], 96), closed=False)
vase_in.add("Vase", I.lathe(P[11:], 96), closed=False)
write("vase-rlc", [I.Node("Dining", I.table(), t=[1.0, 0, 0], children=[
          I.Node("Vase", None, t=[0.33, 0.7605, -0.14], children=[I.Node("Vase_Out", vase_out),
                                                                 I.Node("Vase_In", vase_in)])])],
      "scenes/interior.json's room, window pane and ceiling fixtures with its dining table and the vase on it, the "
      "vase's inner wall the node Vase_In, its outer wall and lip Vase_Out, solved with receiving leaf clusters on",
      {"receiving_clusters": 1})

# a leaf beside the window, lit by the pane alone: the room's surfaces black
# and the fixtures dark in this file only
saved = json.dumps(I.MATERIALS)
for name in ("Wall_Paint", "Ceiling", "Floor_Wood", "Fixture", "Leaf"):
    I.MATERIALS[I.MAT[name]]["pbrMetallicRoughness"]["baseColorFactor"][:3] = [0.0, 0.0, 0.0]
for key in ("emissiveFactor", "extensions"):
    I.MATERIALS[I.MAT["Ceiling_Panel"]].pop(key, None)
leaf = I.Mesh("Leaf")
leaf.add("Leaf", I.leaf(0.15, 0.06, 0.0025, 0.2, 0.3))
write("leaf-window", [I.Node("Leaf", leaf, t=[-0.7, 1.4, -1.9])],
      "scenes/interior.json's room with its surfaces black and its ceiling fixtures dark, lit by its window pane "
      "alone, with one of its plant's leaves (black, the node Leaf) 0.35 m in front of the back wall and 0.4 m left "
      "of the window")
I.MATERIALS[:] = json.loads(saved)
