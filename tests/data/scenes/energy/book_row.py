#!/usr/bin/env python3
"""Writes book-row.json (tests/test_energy.c slot_walls_read): the cube of
thin-gap-open.json (2 m, lit by a quad lamp under its ceiling) with a row of
ten books standing on its floor 1.5 mm apart, each book six quads; a book's
sides are named book<i>_xm and book<i>_xp (normals -x, +x), the others _top,
_bottom, _front, _back. Sizes as scenes/gen/interior.py draws a shelf's books."""
import json, random, os

rng = random.Random(3)
scene = json.load(open(os.path.join(os.path.dirname(__file__), "thin-gap-open.json")))
scene["name"] = "book-row"
scene["description"] = ("The cube of thin-gap-open.json without its fixture, a quad lamp under the ceiling, "
                        "and ten books (boxes of quads, sides named _xm and _xp) standing on the floor 1.5 mm "
                        "apart: slots a sixtieth of the patches' size between them (written by book_row.py).")
objs = [o for o in scene["objects"] if o["name"] in ("floor", "ceiling", "left", "right", "back", "front")]
scene["materials"]["book"] = {"diffuse": [0.5, 0.4, 0.3]}
scene["materials"]["lamp"] = {"diffuse": [0, 0, 0], "emission": [10, 10, 10]}
objs.append({"type": "quad", "name": "lamp", "material": "lamp",
             "vertices": [[-0.3, 0.98, -0.3], [0.3, 0.98, -0.3], [0.3, 0.98, 0.3], [-0.3, 0.98, 0.3]]})

def quad(name, a, b, c, d):
    objs.append({"type": "quad", "name": name, "material": "book", "vertices": [a, b, c, d]})

x, y0, z0 = -0.2, -1.0, -0.1
for i in range(10):
    w, h, d = rng.uniform(0.018, 0.055), rng.uniform(0.2, 0.33), rng.uniform(0.15, 0.27)
    x0, x1, y1, z1 = x, x + w, y0 + h, z0 + d
    r = lambda v: [round(c, 6) for c in v]
    quad("book%d_xm" % i, r([x0, y0, z0]), r([x0, y0, z1]), r([x0, y1, z1]), r([x0, y1, z0]))
    quad("book%d_xp" % i, r([x1, y0, z0]), r([x1, y1, z0]), r([x1, y1, z1]), r([x1, y0, z1]))
    quad("book%d_top" % i, r([x0, y1, z0]), r([x0, y1, z1]), r([x1, y1, z1]), r([x1, y1, z0]))
    quad("book%d_bottom" % i, r([x0, y0, z0]), r([x1, y0, z0]), r([x1, y0, z1]), r([x0, y0, z1]))
    quad("book%d_front" % i, r([x0, y0, z1]), r([x1, y0, z1]), r([x1, y1, z1]), r([x0, y1, z1]))
    quad("book%d_back" % i, r([x0, y0, z0]), r([x0, y1, z0]), r([x1, y1, z0]), r([x1, y0, z0]))
    x += w + 0.0015
scene["objects"] = objs
with open(os.path.join(os.path.dirname(__file__), "book-row.json"), "w") as f:
    json.dump(scene, f, indent=1)
