# Generates scenes/room.json: python3 scenes/gen/room.py pa=0.002 > scenes/room.json
# (pa: radiosity patch_area, pe: patch_edge). Kept so the room can be changed by recipe.
import json, sys
W, H, D = 5.0, 2.8, 5.5
args = dict(a.split('=') for a in sys.argv[1:])
patch_area = float(args.get('pa', 0.001))
pe = float(args.get('pe', 0.25))
objs = []
def quad(name, mat, v):
    objs.append({"name": name, "type": "quad", "material": mat, "vertices": v})
def box(name, mat, mn, mx, tf=None):
    o = {"name": name, "type": "box", "material": mat, "min": mn, "max": mx}
    if tf: o["transform"] = tf
    objs.append(o)
def place(deg, x, z, y=0):
    t = []
    if deg: t.append({"rotate": {"axis": [0, 1, 0], "degrees": deg}})
    t.append({"translate": [x, y, z]})
    return t

# room, quads facing inwards (counter-clockwise seen from inside)
quad("floor", "floor", [[0, 0, 0], [0, 0, D], [W, 0, D], [W, 0, 0]])
quad("ceiling", "ceiling", [[0, H, 0], [W, H, 0], [W, H, D], [0, H, D]])
quad("back_wall", "wall", [[0, 0, 0], [W, 0, 0], [W, H, 0], [0, H, 0]])
quad("front_wall", "wall", [[0, 0, D], [0, H, D], [W, H, D], [W, 0, D]])
quad("left_wall", "blue_wall", [[0, 0, 0], [0, H, 0], [0, H, D], [0, 0, D]])
quad("right_wall", "wall", [[W, 0, 0], [W, 0, D], [W, H, D], [W, H, 0]])
# lights: a ceiling panel and a window in the right wall (facing in, 2 mm off the surfaces)
e = 0.002
quad("ceiling_lamp", "lamp", [[2.0, H - e, 1.6], [3.0, H - e, 1.6], [3.0, H - e, 2.6], [2.0, H - e, 2.6]])
wz0, wz1, wy0, wy1 = 0.9, 2.5, 0.9, 2.3
quad("window", "sky", [[W - e, wy0, wz0], [W - e, wy0, wz1], [W - e, wy1, wz1], [W - e, wy1, wz0]])
# window frame and cross bars (in front of the sky panel)
f = 0.06
box("window_sill", "white_paint", [W - 0.18, wy0 - 0.05, wz0 - f], [W, wy0, wz1 + f])
box("window_head", "white_paint", [W - 0.08, wy1, wz0 - f], [W, wy1 + f, wz1 + f])
box("window_jamb_a", "white_paint", [W - 0.08, wy0, wz0 - f], [W, wy1, wz0])
box("window_jamb_b", "white_paint", [W - 0.08, wy0, wz1], [W, wy1, wz1 + f])
box("window_bar_v", "white_paint", [W - 0.05, wy0, (wz0 + wz1) / 2 - 0.025], [W - e, wy1, (wz0 + wz1) / 2 + 0.025])
box("window_bar_h", "white_paint", [W - 0.05, (wy0 + wy1) / 2 - 0.025, wz0], [W - e, (wy0 + wy1) / 2 + 0.025, wz1])
# mirror on the left wall, in a dark frame
mz0, mz1, my0, my1 = 1.3, 2.9, 0.85, 2.05
quad("mirror", "mirror", [[e, my0, mz0], [e, my1, mz0], [e, my1, mz1], [e, my0, mz1]])
fw, fd = 0.05, 0.03
box("mirror_frame_bottom", "dark_wood", [0, my0 - fw, mz0 - fw], [fd, my0, mz1 + fw])
box("mirror_frame_top", "dark_wood", [0, my1, mz0 - fw], [fd, my1 + fw, mz1 + fw])
box("mirror_frame_near", "dark_wood", [0, my0, mz1], [fd, my1, mz1 + fw])
box("mirror_frame_far", "dark_wood", [0, my0, mz0 - fw], [fd, my1, mz0])
# rug under the table
quad("rug", "rug", [[1.3, e, 1.6], [1.3, e, 3.6], [3.7, e, 3.6], [3.7, e, 1.6]])
# table (local frame: centred on the origin, standing on y = 0)
tx, tz = 2.5, 2.6
tt = place(8, tx, tz)
box("table_top", "wood", [-0.8, 0.72, -0.45], [0.8, 0.76, 0.45], tt)
for i, (lx, lz) in enumerate([(-0.72, -0.37), (0.72, -0.37), (0.72, 0.37), (-0.72, 0.37)]):
    box("table_leg_%d" % i, "wood", [lx - 0.03, 0, lz - 0.03], [lx + 0.03, 0.72, lz + 0.03], tt)
# chairs (local frame: seat centred on the origin, back towards -z)
def chair(n, deg, x, z):
    t = place(deg, x, z)
    box("chair%d_seat" % n, "chair", [-0.22, 0.43, -0.22], [0.22, 0.47, 0.22], t)
    for i, (lx, lz) in enumerate([(-0.19, -0.19), (0.19, -0.19), (0.19, 0.19), (-0.19, 0.19)]):
        box("chair%d_leg_%d" % (n, i), "chair", [lx - 0.02, 0, lz - 0.02], [lx + 0.02, 0.43, lz + 0.02], t)
    box("chair%d_back" % n, "chair", [-0.22, 0.47, -0.22], [0.22, 0.95, -0.18], t)
chair(0, 5, 2.3, 1.75)
chair(1, 180 - 12, 2.75, 3.5)
chair(2, -90 + 10, 1.35, 2.45)
# bookshelf against the back wall (local frame: left-back-bottom corner at the origin)
bt = place(0, 0.45, 0.0)
bw, bd, bh = 1.3, 0.34, 2.0
box("shelf_side_l", "white_paint", [0, 0, 0], [0.03, bh, bd], bt)
box("shelf_side_r", "white_paint", [bw - 0.03, 0, 0], [bw, bh, bd], bt)
box("shelf_back", "white_paint", [0.03, 0, 0], [bw - 0.03, bh, 0.01], bt)
levels = [0.0, 0.5, 1.0, 1.5, bh - 0.03]
for i, y in enumerate(levels):
    box("shelf_%d" % i, "white_paint", [0.03, y, 0.01], [bw - 0.03, y + 0.03, bd], bt)
cols = ["book_red", "book_yellow", "book_teal", "book_orange", "book_blue", "book_green"]
k = 0
for i, y in enumerate(levels[:4]):
    x = 0.06 + 0.07 * (i % 2)
    n = 0
    while x < bw - 0.25:
        wdt = 0.04 + 0.015 * ((k * 7) % 5)
        hgt = 0.28 + 0.03 * ((k * 5) % 4)
        if i == 0:
            hgt += 0.05
        box("book_%d" % k, cols[k % len(cols)], [x, y + 0.03, 0.06], [x + wdt, y + 0.03 + hgt, 0.29], bt)
        x += wdt + 0.005
        k += 1
        n += 1
        if n == 7:
            x += 0.2
            n = 0
# low cabinet on the right wall under the window is the sill; a sideboard at the back right
box("sideboard", "lacquer", [3.2, 0, 0.02], [4.6, 0.8, 0.5])
# glossy objects: a ball on the table and a vase-like ball on the sideboard
objs.append({"name": "glossy_ball", "type": "sphere", "material": "glossy_red", "center": [0, 0, 0], "radius": 0.13,
             "transform": [{"translate": [2.25, 0.76 + 0.13, 2.55]}]})
objs.append({"name": "sideboard_ball", "type": "sphere", "material": "glossy_green", "center": [3.9, 0.8 + 0.18, 0.26], "radius": 0.18})
box("table_block", "glossy_blue", [-0.1, 0, -0.1], [0.1, 0.2, 0.1], [{"rotate": {"axis": [0, 1, 0], "degrees": 30}}, {"translate": [2.85, 0.76, 2.75]}])

materials = {
    "floor": {"diffuse": [0.55, 0.42, 0.3]},
    "ceiling": {"diffuse": [0.82, 0.82, 0.8]},
    "wall": {"diffuse": [0.78, 0.74, 0.66]},
    "blue_wall": {"diffuse": [0.25, 0.42, 0.7]},
    "white_paint": {"diffuse": [0.82, 0.82, 0.82], "specular": 0.05, "k": 20},
    "dark_wood": {"diffuse": [0.18, 0.1, 0.06]},
    "wood": {"diffuse": [0.5, 0.3, 0.15], "specular": 0.08, "k": 30},
    "chair": {"diffuse": [0.62, 0.45, 0.25]},
    "rug": {"diffuse": [0.7, 0.12, 0.08]},
    "lacquer": {"diffuse": [0.08, 0.08, 0.09], "specular": 0.6, "k": 200},
    "glossy_red": {"diffuse": [0.6, 0.05, 0.05], "specular": 0.7, "k": 120},
    "glossy_green": {"diffuse": [0.1, 0.5, 0.2], "specular": 0.5, "k": 60},
    "glossy_blue": {"diffuse": [0.1, 0.2, 0.6], "specular": 0.5, "k": 80},
    "mirror": {"diffuse": 0, "mirror": [0.9, 0.9, 0.9]},
    "book_red": {"diffuse": [0.7, 0.1, 0.08]},
    "book_yellow": {"diffuse": [0.8, 0.65, 0.1]},
    "book_teal": {"diffuse": [0.1, 0.5, 0.5]},
    "book_orange": {"diffuse": [0.8, 0.4, 0.1]},
    "book_blue": {"diffuse": [0.1, 0.15, 0.5]},
    "book_green": {"diffuse": [0.15, 0.45, 0.15]},
    "lamp": {"diffuse": 0.8, "emission": [9, 8, 6.5]},
    "sky": {"diffuse": 0.8, "emission": [4.5, 5.2, 6.5]},
}
for m in materials.values():
    if "emission" not in m and m.get("diffuse", 0.5) != 0:
        m["ambient"] = 1
scene = {
    "format": "radray-scene/1",
    "name": "room",
    "description": "A diffuse-heavy room for the hybrid (5 x 2.8 x 5.5 m, metres): inward-facing quads for floor, ceiling and walls (the left wall blue), a 1 x 1 ceiling panel light and a window in the right wall (an emissive sky-blue quad 2 mm inside the wall, behind a white frame and cross bars), a mirror in a dark frame on the left wall (mirror 0.9, diffuse 0), a table, three chairs, a bookshelf with coloured books and a sideboard built from transformed boxes, a red rug, and glossy objects (a red ball and a blue block on the table, a green ball on the black lacquered sideboard). Look for: the ceiling, lit mostly by interreflection: warmer and brighter (light from the wooden floor and the walls) with --mode hybrid, radiosity and secondary, a flat bluish grey in --mode whitted (the window's direct light plus the constant ambient term render.ambient, which stands in for interreflection there); shadows under the table and chairs that the hybrid fills with bounced light where Whitted mode puts the same grey everywhere; the EXR layer 'indirect' (hybrid) against 'ambient' (whitted); the soft window light on the floor and wall; and the mirror showing the shaded room in every mode (light by way of the mirror is carried by both passes: images of the lamps for direct light, form-factor rays that reflect off it for interreflection). The radiosity pass has 114,898 patches (patch_area 0.002, patch_edge 0.25: the explicit edge limit keeps thin boxes such as table legs and shelves from being split far finer than the walls) and takes most of the render time.",
    "camera": {"type": "lookat", "eye": [3.1, 1.6, 5.35], "target": [2.3, 1.05, 1.2], "up": [0, 1, 0], "fov": 60, "width": 640, "height": 400},
    # a walkthrough (render --frames 1..60): from the door along the front of the room and back
    "camera_path": {"frames": 60, "keys": [
        {"frame": 1, "eye": [3.1, 1.6, 5.35], "target": [2.3, 1.05, 1.2], "fov": 60},
        {"frame": 20, "eye": [1.4, 1.6, 4.8], "target": [3.2, 1.0, 1.4], "fov": 60},
        {"frame": 40, "eye": [0.9, 1.5, 3.6], "target": [4.2, 1.2, 1.8], "fov": 55},
        {"frame": 60, "eye": [4.3, 1.65, 4.9], "target": [1.0, 1.0, 1.0], "fov": 62}]},
    "materials": materials,
    "objects": objs,
    "render": {"spp": 16, "seed": 1, "light_samples": 8, "exposure": -0.3, "ambient": [0.25, 0.25, 0.25]},
    "radiosity": {"patch_area": patch_area, "patch_edge": pe},
}
# compact, one item per line
def dump(v, ind=0):
    pad = "  " * ind
    if isinstance(v, dict) and ind < 2 and v and any(isinstance(x, (dict, list)) for x in v.values()) and ind < 2:
        items = [pad + "  " + json.dumps(k) + ": " + dump(x, ind + 1) for k, x in v.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(v, list) and ind < 2 and v and isinstance(v[0], dict):
        return "[\n" + ",\n".join(pad + "  " + json.dumps(x) for x in v) + "\n" + pad + "]"
    return json.dumps(v)
def rnd(v):
    if isinstance(v, float):
        r = round(v, 4)
        return int(r) if r == int(r) and abs(r) < 1e6 else r
    if isinstance(v, list):
        return [rnd(x) for x in v]
    if isinstance(v, dict):
        return {k: rnd(x) for k, x in v.items()}
    return v
print(dump(rnd(scene)))
