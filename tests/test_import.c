/* test_import.c - "model" objects (import/, scene/scene_model.c): whole
 * files in, with their materials and lights.
 *
 *  - scenes/cornell-obj.json (the Cornell box written as OBJ + MTL by
 *    scenes/gen/cornell_obj.py) renders as scenes/cornell.json in every
 *    mode of the integrator table. The triangles are the same up to
 *    Assimp's single-precision coordinates (3e-5 mm in a 559 mm box), in the
 *    same order, so every random stream is the same: the images differ only
 *    where a path is steered by that rounding. Measured: at most 0.2 % on an
 *    object, 0.0 % over the image (64 px, 64 spp); tolerances 1 % (objects
 *    of >= 40 pixels) and 0.5 % (whole image).
 *  - a glTF room written here (closed box, an emissive ceiling panel placed
 *    by a node's TRS) renders, with no material typed in JSON, like the same
 *    room written in JSON: hybrid and secondary, floor and whole image
 *    within 3 % (two different triangulations, so two different noise
 *    draws; 16 spp x >= 300 pixels per mean: ~1 % noise).
 *  - the mapping table (notes/import.md), one rule each: MTL illum 2 Phong,
 *    illum 3 mirror with the diffuse lowered, d < 1, a PNG texture's mean;
 *    glTF emissive strength, metallic mirror, rough metal, alpha blend.
 *  - overrides ("materials", "material"), "scale" and "up".
 *  - the example assets load as their descriptions say: scenes/interior.json
 *    (glTF: mirror, emitters, approximations noted, a watertight bunny),
 *    scenes/bunny.json and scenes/bunny-csg.json (the bunny as a CSG leaf).
 *  - bad input: clear messages (file, material or line, cause), and at the
 *    command line exit code 2 and no output file.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ig.h"
#include "img.h"
#include "test_cli_run.h"
#include "test_world.h"

static char g_dir[64]; /* this run's scratch folder */

static void put(const char *name, const void *data, size_t n)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static void put_text(const char *name, const char *text) { put(name, text, strlen(text)); }

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/radray-import-XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* A scene around one model object; extra: more keys of that object. */
static rr_status load_model(const char *file, const char *extra, scene **s, rr_error *err)
{
    char json[2048];
    snprintf(json, sizeof json,
             "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 2.5], "
             "\"target\": [0, 1, 0], \"up\": [0, 1, 0], \"fov\": 70, \"width\": 24, \"height\": 24}, "
             "\"objects\": [{\"type\": \"model\", \"file\": \"%s\"%s%s}]}",
             file, extra ? ", " : "", extra ? extra : "");
    return scene_load_string(json, "m.json", g_dir, NULL, s, err);
}

static const scene_material *material_named(const scene *s, const char *name)
{
    for (size_t i = 0; i < s->nmaterials; i++)
        if (strcmp(s->materials[i].name, name) == 0)
            return &s->materials[i];
    fail_msg("no material %s", name);
    return NULL;
}

static void expect_error(const char *file, const char *extra, const char *want)
{
    scene *s = NULL;
    rr_error err;
    rr_error_clear(&err);
    if (load_model(file, extra, &s, &err) == RR_OK) {
        scene_destroy(s);
        fail_msg("%s loaded; expected an error containing \"%s\"", file, want);
    }
    if (!strstr(err.msg, want) || strncmp(err.msg, "m.json: objects[0]", 18) != 0)
        fail_msg("message \"%s\"\n  does not start with the scene and object, or lacks \"%s\"", err.msg, want);
}

/* Mean luminance-free sum (r + g + b) over the pixels whose centre ray hits
 * an object whose name ends in suffix (NULL: every pixel); *n pixels. */
static double mean_over(const world *w, const rr_image *im, const char *suffix, int *n)
{
    double sum = 0;
    *n = 0;
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) {
            if (suffix) {
                rt_hit h;
                if (!rt_accel_closest(w->a, rr_view_ray(&w->s->view, x, y, 0.0, 0.0), 0.0, INFINITY, &h))
                    continue;
                const char *name = w->s->objects[h.object].name;
                size_t ln = strlen(name), ls = strlen(suffix);
                if (ln < ls || strcmp(name + ln - ls, suffix) != 0)
                    continue;
            }
            const float *p = rr_image_at(im, x, y);
            sum += (double)p[0] + p[1] + p[2];
            (*n)++;
        }
    return *n ? sum / *n : 0;
}

/* ---- the OBJ Cornell box against cornell.json ---- */

/* small: the Cornell box's lecture camera at 48 x 48 pixels. */
static scene *load_file(const char *rel, int small)
{
    static const char *const px48[] = {"camera.w=48", "camera.h=48", "camera.s=0.52083333"};
    scene_load_opts o = {0};
    o.overrides = small ? px48 : NULL;
    o.noverrides = small ? 3 : 0;
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", RR_SOURCE_DIR, rel);
    scene *s = NULL;
    rr_error err;
    if (scene_load(path, &o, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

static void obj_cornell_every_mode(void **state)
{
    (void)state;
    world a, b;
    world_open(&a, load_file("scenes/cornell.json", 1));
    world_open(&b, load_file("scenes/cornell-obj.json", 1));
    assert_int_equal(a.s->ntris, b.s->ntris);
    assert_int_equal(b.s->nmodels, 1);
    static const char *const objects[] = {"floor", "ceiling", "back_wall", "left_wall", "right_wall", "short_block",
                                          "tall_block"};
    for (size_t m = 0; m < ig_count(); m++) {
        const ig_integrator *ig = &ig_table[m];
        rt_film fa, fb;
        world_render(&a, ig, 16, &fa);
        world_render(&b, ig, 16, &fb);
        int na, nb;
        double ja = mean_over(&a, &fa.beauty, NULL, &na), ob = mean_over(&b, &fb.beauty, NULL, &nb);
        printf("%-10s image %+.2f %%", ig->name, 100 * (ob / ja - 1));
        assert_true(fabs(ob / ja - 1) < 0.005);
        for (size_t k = 0; k < sizeof objects / sizeof objects[0]; k++) {
            char suffix[64];
            snprintf(suffix, sizeof suffix, "%s", objects[k]);
            double va = mean_over(&a, &fa.beauty, suffix, &na), vb = mean_over(&b, &fb.beauty, suffix, &nb);
            assert_int_equal(na, nb); /* the same pixels see the same object */
            if (na < 40 || va <= 0)
                continue;
            printf("  %s %+.2f", objects[k], 100 * (vb / va - 1));
            if (fabs(vb / va - 1) > 0.01)
                fail_msg("%s: %s differs by %+.2f %%", ig->name, objects[k], 100 * (vb / va - 1));
        }
        printf("\n");
        rt_film_free(&fa);
        rt_film_free(&fb);
    }
    world_free(&a);
    world_free(&b);
}

/* ---- a glTF room against the same room in JSON ---- */

/* A closed box [-1,1] x [0,2] x [-1,1] facing in, and a 0.6 x 0.6 panel
 * facing down, placed by its node at y = 1.99. Buffer: positions then
 * indices, in room.bin. */
static void write_gltf_room(void)
{
    float pos[] = {-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1, -1, 2, -1, 1, 2, -1, 1, 2, 1, -1, 2, 1,
                   /* panel, local, centred on the node */
                   -0.3f, 0, -0.3f, 0.3f, 0, -0.3f, 0.3f, 0, 0.3f, -0.3f, 0, 0.3f};
    /* counter-clockwise seen from inside: floor up, ceiling down, walls in */
    uint32_t idx[] = {0, 2, 1, 0, 3, 2,  4, 5, 6, 4, 6, 7,  0, 1, 5, 0, 5, 4,  2, 3, 7, 2, 7, 6,
                      1, 2, 6, 1, 6, 5,  3, 0, 4, 3, 4, 7,
                      /* panel facing up (+y) in its node's frame; the node turns it down */
                      0, 2, 1, 0, 3, 2};
    unsigned char bin[sizeof pos + sizeof idx];
    memcpy(bin, pos, sizeof pos);
    memcpy(bin + sizeof pos, idx, sizeof idx);
    put("room.bin", bin, sizeof bin);
    char json[4096];
    snprintf(json, sizeof json,
             "{\"asset\": {\"version\": \"2.0\"}, \"extensionsUsed\": [\"KHR_materials_emissive_strength\"],"
             "\"buffers\": [{\"uri\": \"room.bin\", \"byteLength\": %zu}],"
             "\"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 96},"
             " {\"buffer\": 0, \"byteOffset\": 96, \"byteLength\": 48},"
             " {\"buffer\": 0, \"byteOffset\": %zu, \"byteLength\": 144},"
             " {\"buffer\": 0, \"byteOffset\": %zu, \"byteLength\": 24}],"
             "\"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 8, \"type\": \"VEC3\","
             " \"min\": [-1, 0, -1], \"max\": [1, 2, 1]},"
             " {\"bufferView\": 1, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC3\","
             " \"min\": [-0.3, 0, -0.3], \"max\": [0.3, 0, 0.3]},"
             " {\"bufferView\": 2, \"componentType\": 5125, \"count\": 36, \"type\": \"SCALAR\"},"
             " {\"bufferView\": 3, \"componentType\": 5125, \"count\": 6, \"type\": \"SCALAR\"}],"
             "\"materials\": [{\"name\": \"Wall\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.7, 0.7, 0.7, 1],"
             " \"metallicFactor\": 0, \"roughnessFactor\": 1}},"
             " {\"name\": \"Panel\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.5, 0.5, 0.5, 1],"
             " \"metallicFactor\": 0, \"roughnessFactor\": 1}, \"emissiveFactor\": [1, 0.8, 0.6],"
             " \"extensions\": {\"KHR_materials_emissive_strength\": {\"emissiveStrength\": 5}}}],"
             "\"meshes\": [{\"name\": \"Box\", \"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 2,"
             " \"material\": 0}]},"
             " {\"name\": \"Lamp\", \"primitives\": [{\"attributes\": {\"POSITION\": 1}, \"indices\": 3,"
             " \"material\": 1}]}],"
             "\"nodes\": [{\"name\": \"Room\", \"children\": [1, 2]}, {\"name\": \"Walls\", \"mesh\": 0},"
             " {\"name\": \"Panel\", \"mesh\": 1, \"translation\": [0, 1.99, 0], \"rotation\": [1, 0, 0, 0]}],"
             "\"scenes\": [{\"nodes\": [0]}], \"scene\": 0}",
             sizeof bin, sizeof pos, sizeof pos + 144);
    put_text("room.gltf", json);
}

/* The same room in radray's own JSON. */
static const char *k_room_json =
    "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 0.95], "
    "\"target\": [0, 0.6, -1], \"up\": [0, 1, 0], \"fov\": 80, \"width\": 40, \"height\": 40},"
    "\"materials\": {\"Wall\": {\"diffuse\": 0.7}, \"Panel\": {\"diffuse\": 0.5, \"emission\": [5, 4, 3]}},"
    "\"objects\": [{\"type\": \"box\", \"name\": \"Walls\", \"material\": \"Wall\", \"min\": [-1, 0, -1], "
    "\"max\": [1, 2, 1], \"flip\": true},"
    "{\"type\": \"quad\", \"name\": \"Panel\", \"material\": \"Panel\", \"vertices\": [[-0.3, 1.99, -0.3], "
    "[0.3, 1.99, -0.3], [0.3, 1.99, 0.3], [-0.3, 1.99, 0.3]]}]}";

static void gltf_room_no_material_typed(void **state)
{
    (void)state;
    write_gltf_room();
    char json[1024];
    snprintf(json, sizeof json,
             "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 0.95], "
             "\"target\": [0, 0.6, -1], \"up\": [0, 1, 0], \"fov\": 80, \"width\": 40, \"height\": 40},"
             "\"objects\": [{\"type\": \"model\", \"file\": \"room.gltf\"}]}");
    scene *s = NULL, *r = NULL;
    rr_error err;
    if (scene_load_string(json, "m.json", g_dir, NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    if (scene_load_string(k_room_json, "r.json", "", NULL, &r, &err) != RR_OK)
        fail_msg("%s", err.msg);
    /* the mapping: names, emissive strength, the node's TRS (rotation by pi
     * about x turns the panel to face down) */
    const scene_material *panel = material_named(s, "room/Panel");
    assert_true(fabs(panel->emission.r - 5) < 1e-6 && fabs(panel->emission.g - 4) < 1e-6);
    assert_true(fabs(material_named(s, "room/Wall")->diffuse.g - 0.7) < 1e-6);
    assert_int_equal(s->nemissive, 2);
    rr_vec3 n = scene_tri_normal(s, s->emissive_tris[0]);
    assert_true(n.y < -0.999);
    assert_true(fabs(s->verts[s->tris[s->emissive_tris[0]].v[0]].y - 1.99) < 1e-6);
    assert_int_equal(s->objects[0].cull_backfaces, 1); /* closed and oriented, as the JSON box: culled */
    world ws, wr;
    world_open(&ws, s);
    world_open(&wr, r);
    const char *modes[] = {"hybrid", "secondary"};
    for (int m = 0; m < 2; m++) {
        rt_film fs, fr;
        world_render(&ws, ig_find(modes[m]), 16, &fs);
        world_render(&wr, ig_find(modes[m]), 16, &fr);
        int ns, nr;
        double is = mean_over(&ws, &fs.beauty, NULL, &ns), ir = mean_over(&wr, &fr.beauty, NULL, &nr);
        double fls = mean_over(&ws, &fs.beauty, "Walls", &ns), flr = mean_over(&wr, &fr.beauty, "Walls", &nr);
        printf("%-9s image %+.2f %%, walls %+.2f %% (%d px)\n", modes[m], 100 * (is / ir - 1), 100 * (fls / flr - 1),
               ns);
        assert_true(ns >= 300);
        assert_true(fabs(is / ir - 1) < 0.03);
        assert_true(fabs(fls / flr - 1) < 0.03);
        rt_film_free(&fs);
        rt_film_free(&fr);
    }
    world_free(&ws);
    world_free(&wr);
}

/* ---- the mapping table ---- */

static const char *k_quad_obj = "mtllib m.mtl\n"
                                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                "o phong\nusemtl phong\nf 1 2 3 4\n"
                                "o mirror\nusemtl mirror\nf 1 2 3\n"
                                "o glass\nusemtl glass\nf 1 3 4\n"
                                "o tex\nusemtl tex\nf 2 3 4\n";

static void mtl_mapping(void **state)
{
    (void)state;
    /* a uniform texture of linear (0.2, 0.5, 0.8), written as sRGB */
    rr_image im;
    assert_int_equal(rr_image_init(&im, 4, 4, NULL), RR_OK);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 4; x++)
            rr_image_set(&im, x, y, rr_rgb_make(0.2, 0.5, 0.8));
    char png[256];
    snprintf(png, sizeof png, "%s/t.png", g_dir);
    assert_int_equal(img_write_png(png, &im, 0, NULL), RR_OK);
    rr_image_free(&im);
    put_text("m.obj", k_quad_obj);
    put_text("m.mtl", "# materials\n"
                      "newmtl phong\nKd 0.6 0.5 0.4\nKs 0.3 0.3 0.3\nNs 50\nillum 2\n"
                      "newmtl mirror\nKd 0.8 0.8 0.8\nKs 0.5 0.6 0.7\nillum 3\n"
                      "newmtl glass\nKd 0.5\nd 0.4\nillum 1\n"
                      "newmtl tex\nKd 0.5 0.5 0.5\nmap_Kd -s 1 1 1 t.png\n");
    scene *s = NULL;
    rr_error err;
    if (load_model("m.obj", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    const scene_material *p = material_named(s, "m/phong"), *m = material_named(s, "m/mirror");
    const scene_material *g = material_named(s, "m/glass"), *t = material_named(s, "m/tex");
    assert_true(p->diffuse.r == 0.6 && p->specular.g == 0.3 && p->k == 50 && rr_rgb_max(p->mirror) == 0);
    /* illum 3: Ks is the mirror; the diffuse goes down to 1 - mirror */
    assert_true(m->mirror.b == 0.7 && fabs(m->diffuse.r - 0.5) < 1e-12 && fabs(m->diffuse.b - 0.3) < 1e-12);
    assert_true(m->notes & IMP_NOTE_CLAMPED);
    assert_true(g->notes & IMP_NOTE_TRANSPARENT && g->specular.r == 0);
    /* the texture's mean (8-bit sRGB, so within 1 %) times Kd */
    assert_true(t->notes & IMP_NOTE_TEXTURE_AVG);
    assert_true(fabs(t->diffuse.r - 0.1) < 1e-3 && fabs(t->diffuse.g - 0.25) < 2.5e-3 && fabs(t->diffuse.b - 0.4) < 4e-3);
    assert_int_equal(s->nmodels, 1);
    assert_int_equal(s->models[0].object_count, 4);
    scene_destroy(s);
}

static void gltf_mapping(void **state)
{
    (void)state;
    write_gltf_room();
    /* the same buffer, other materials: a polished metal, a rough metal, a
     * blended glass (the room file's text with its materials replaced) */
    char *text = NULL;
    char path[256];
    snprintf(path, sizeof path, "%s/room.gltf", g_dir);
    assert_int_equal(rr_file_read_all(path, &text, NULL, NULL), RR_OK);
    char *a = strstr(text, "\"materials\""), *b = strstr(text, "\"meshes\"");
    assert_true(a && b && a < b);
    char out[8192];
    snprintf(out, sizeof out, "%.*s\"materials\": [{\"name\": \"Chrome\", \"pbrMetallicRoughness\": "
             "{\"baseColorFactor\": [0.9, 0.8, 0.7, 1], \"metallicFactor\": 1, \"roughnessFactor\": 0}},"
             " {\"name\": \"Brushed\", \"alphaMode\": \"BLEND\", \"pbrMetallicRoughness\": "
             "{\"baseColorFactor\": [0.6, 0.6, 0.6, 0.5], \"metallicFactor\": 1, \"roughnessFactor\": 0.6}}], %s",
             (int)(a - text), text, b);
    free(text);
    put_text("metal.gltf", out);
    scene *s = NULL;
    rr_error err;
    if (load_model("metal.gltf", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    const scene_material *c = material_named(s, "metal/Chrome"), *r = material_named(s, "metal/Brushed");
    assert_true(fabs(c->mirror.g - 0.8) < 1e-6 && rr_rgb_max(c->diffuse) == 0 && c->notes == 0);
    assert_true(fabs(r->diffuse.r - 0.6) < 1e-6 && rr_rgb_max(r->mirror) == 0);
    assert_true((r->notes & IMP_NOTE_ROUGH) && (r->notes & IMP_NOTE_TRANSPARENT));
    scene_destroy(s);
}

/* ---- overrides, one material, scale and up ---- */

static void overrides_and_frame(void **state)
{
    (void)state;
    write_gltf_room();
    scene *s = NULL;
    rr_error err;
    if (load_model("room.gltf", "\"name\": \"r\", \"materials\": {\"Wall\": {\"diffuse\": [0.2, 0.3, 0.4]}}", &s, &err) !=
        RR_OK)
        fail_msg("%s", err.msg);
    const scene_material *w = material_named(s, "r/Wall");
    assert_true(w->diffuse.g == 0.3 && w->overridden);
    assert_true(material_named(s, "r/Panel")->emission.r == 5);
    scene_destroy(s);

    /* one material for everything: the file's are not added */
    const char *one = "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 2.5], "
                      "\"target\": [0, 1, 0], \"up\": [0, 1, 0], \"fov\": 70, \"width\": 8, \"height\": 8}, "
                      "\"materials\": {\"clay\": {}}, \"lights\": [{\"type\": \"point\", \"position\": [0, 1, 0], "
                      "\"intensity\": 1}], \"objects\": [{\"type\": \"model\", \"file\": \"room.gltf\", "
                      "\"material\": \"clay\", \"scale\": 0.01, \"up\": \"z\"}]}";
    if (scene_load_string(one, "m.json", g_dir, NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(s->nmaterials, 1);
    for (size_t i = 0; i < s->nobjects; i++)
        assert_int_equal(s->objects[i].material, 0);
    /* up "z": the file's +z is the scene's +y, its +y the scene's -z; scale 0.01 */
    assert_true(fabs(s->bbox_min.y + 0.01) < 1e-9 && fabs(s->bbox_max.y - 0.01) < 1e-9);
    assert_true(fabs(s->bbox_min.z + 0.02) < 1e-9 && fabs(s->bbox_max.z - 0.0) < 1e-9);
    scene_destroy(s);
}

/* ---- the example scenes made of real assets ---- */

static const scene_object *object_named(const scene *s, const char *name)
{
    for (size_t i = 0; i < s->nobjects; i++)
        if (strcmp(s->objects[i].name, name) == 0)
            return &s->objects[i];
    fail_msg("no object %s", name);
    return NULL;
}

static void example_assets(void **state)
{
    (void)state;
    /* scenes/interior.json: the glTF interior, nothing typed in JSON */
    scene *s = load_file("scenes/interior.json", 0);
    assert_int_equal(s->nmodels, 1);
    assert_true(s->ntris > 300000);
    assert_true(fabs(material_named(s, "interior/Mirror")->mirror.r - 0.9) < 1e-6);
    assert_true(material_named(s, "interior/Ceiling_Panel")->emission.r > 1);
    assert_true(material_named(s, "interior/Window_Sky")->emission.b > 1);
    assert_true(material_named(s, "interior/Vase")->notes & IMP_NOTE_TRANSPARENT);
    assert_true(material_named(s, "interior/Lamp_Metal")->notes & IMP_NOTE_ROUGH);
    const scene_object *bunny = object_named(s, "interior/Bunny");
    assert_true(bunny->report.watertight && bunny->report.consistently_oriented && bunny->cull_backfaces);
    assert_true(s->nemissive >= 4);
    scene_destroy(s);
    /* the bunny as a mesh object, and as a CSG leaf */
    s = load_file("scenes/bunny.json", 0);
    int found = 0;
    for (size_t i = 0; i < s->nobjects; i++)
        if (s->objects[i].kind == SCENE_OBJ_MESH && s->objects[i].tri_count == 3674) {
            assert_true(s->objects[i].report.watertight && s->objects[i].report.consistently_oriented);
            found = 1;
        }
    assert_true(found);
    scene_destroy(s);
    /* the bunny's PLY as a model: Assimp's generic path (no material in the
     * file: the default grey, noted), welded watertight again */
    char json[1024];
    snprintf(json, sizeof json,
             "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 5, 20], "
             "\"target\": [0, 5, 0], \"up\": [0, 1, 0], \"fov\": 40, \"width\": 8, \"height\": 8}, "
             "\"objects\": [{\"type\": \"model\", \"file\": \"%s/scenes/meshes/bunny.ply\"}]}", RR_SOURCE_DIR);
    rr_error err;
    if (scene_load_string(json, "m.json", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(s->nobjects, 1);
    assert_int_equal(s->objects[0].tri_count, 3674);
    assert_true(s->objects[0].report.watertight && s->objects[0].report.consistently_oriented);
    assert_true(s->materials[s->objects[0].material].notes & IMP_NOTE_DEFAULT);
    assert_true(strcmp(s->models[0].format, "ply") == 0);
    scene_destroy(s);
    s = load_file("scenes/bunny-csg.json", 0);
    found = 0;
    for (size_t i = 0; i < s->ncsg; i++)
        found |= s->csg[i].op == SCENE_CSG_LEAF && s->csg[i].solid == SCENE_SOLID_MESH && s->csg[i].tri_count == 3674;
    assert_true(found);
    scene_destroy(s);
}

/* ---- bad input ---- */

static void bad_obj_and_mtl(void **state)
{
    (void)state;
    put_text("a.obj", "mtllib nope.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_error("a.obj", NULL, "a.obj:1: mtllib 'nope.mtl': the material library is missing");
    put_text("b.obj", "mtllib b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
    put_text("b.mtl", "newmtl red\nKd 0.5 0 0\nshine 3\n");
    expect_error("b.obj", NULL, "b.mtl:3: material 'red': unknown statement 'shine'");
    put_text("b.mtl", "newmtl red\nKd nan 0 0\n");
    expect_error("b.obj", NULL, "b.mtl:2: material 'red': Kd: 'nan' is not a finite number");
    put_text("b.mtl", "newmtl red\nKd -0.5 0 0\n");
    expect_error("b.obj", NULL, "b.mtl:2: material 'red': Kd: each channel must be in [0, 1]");
    put_text("b.mtl", "newmtl red\nKe 1 1\n");
    expect_error("b.obj", NULL, "b.mtl:2: material 'red': Ke: expected 1 or 3 numbers");
    put_text("b.mtl", "newmtl blue\nKd 0 0 0.5\n");
    expect_error("b.obj", NULL, "b.obj:5: usemtl 'red': no such material");
    /* a texture that is a FIFO: dropped (noted), not read (it would block) */
    char fifo[256];
    snprintf(fifo, sizeof fifo, "%s/pipe.png", g_dir);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    put_text("b.mtl", "newmtl red\nKd 0.5 0 0\nmap_Kd pipe.png\n");
    alarm(20);
    scene *s = NULL;
    rr_error err;
    if (load_model("b.obj", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    alarm(0);
    assert_true(material_named(s, "b/red")->notes & IMP_NOTE_TEXTURE_DROP);
    scene_destroy(s);
    /* lines end at a lone CR too (as Assimp reads them): nothing hides behind one */
    put_text("b.mtl", "# exported\rnewmtl red\rKd 0.5 0 0\rshine 2\r");
    expect_error("b.obj", NULL, "b.mtl:4: material 'red': unknown statement 'shine'");
    put_text("c.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nl 1 2 3\n");
    expect_error("c.obj", NULL, "c.obj: the file has no triangles (only points or lines");
}

static void bad_gltf(void **state)
{
    (void)state;
    write_gltf_room();
    char *text = NULL, path[256];
    snprintf(path, sizeof path, "%s/room.gltf", g_dir);
    assert_int_equal(rr_file_read_all(path, &text, NULL, NULL), RR_OK);
    char out[8192];
    /* a missing buffer */
    char *u = strstr(text, "room.bin");
    snprintf(out, sizeof out, "%.*sgone.bin%s", (int)(u - text), text, u + 8);
    put_text("nobuf.gltf", out);
    expect_error("nobuf.gltf", NULL, "gone.bin");
    /* a negative factor; a number JSON cannot hold (1e999: JSON has no inf or nan) */
    char *f = strstr(text, "[0.7, 0.7, 0.7, 1]");
    snprintf(out, sizeof out, "%.*s[-0.5, 0.7, 0.7, 1]%s", (int)(f - text), text, f + 18);
    put_text("neg.gltf", out);
    expect_error("neg.gltf", NULL, "material 'Wall' (materials[0]): pbrMetallicRoughness.baseColorFactor[0] is -0.5");
    char *e = strstr(text, "\"emissiveStrength\": 5");
    snprintf(out, sizeof out, "%.*s\"emissiveStrength\": 1e999%s", (int)(e - text), text, e + 21);
    put_text("inf.gltf", out);
    expect_error("inf.gltf", NULL, "number overflow parsing '1e999'");
    snprintf(out, sizeof out, "%.*s\"emissiveStrength\": -2%s", (int)(e - text), text, e + 21);
    put_text("negs.gltf", out);
    expect_error("negs.gltf", NULL, "material 'Panel' (materials[1]): ");
    /* a required extension radray does not have */
    snprintf(out, sizeof out, "{\"extensionsRequired\": [\"EXT_meshopt_compression\"], %s", text + 1);
    put_text("req.gltf", out);
    expect_error("req.gltf", NULL, "requires extension 'EXT_meshopt_compression'");
    free(text);
    /* the scene's side */
    expect_error("room.gltf", "\"materials\": {\"Nope\": {}}", "objects[0].materials.Nope: the file has no material 'Nope'");
    expect_error("room.gltf", "\"up\": \"x\"", "objects[0].up: expected \"y\" or \"z\"");
    expect_error("room.gltf", "\"scale\": 0", "objects[0].scale: must be > 0");
    expect_error("room.gltf", "\"material\": \"x\", \"materials\": {}", "not both");
    expect_error("none.glb", NULL, "none.glb");
}

static void cli_bad_model_exit_2(void **state)
{
    (void)state;
    put_text("d.obj", "mtllib d.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    put_text("d.mtl", "newmtl a\nKd 0.5\nillum 12\n");
    char json[1024], sc[256], out[256], log[256], msg[4096];
    snprintf(json, sizeof json,
             "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 0, 3], "
             "\"target\": [0, 0, 0], \"up\": [0, 1, 0], \"fov\": 40, \"width\": 8, \"height\": 8}, "
             "\"objects\": [{\"type\": \"model\", \"file\": \"d.obj\"}]}");
    put_text("d.json", json);
    snprintf(sc, sizeof sc, "%s/d.json", g_dir);
    snprintf(out, sizeof out, "%s/d.exr", g_dir);
    snprintf(log, sizeof log, "%s/log", g_dir);
    const char *args[] = {"render", sc, "-o", out, NULL};
    assert_int_equal(test_cli_run(log, args, msg, sizeof msg), 2);
    if (!strstr(msg, "d.mtl:3: material 'a': illum: in [0, 10] (got 12)"))
        fail_msg("unexpected output: %s", msg);
    struct stat st;
    assert_int_not_equal(stat(out, &st), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(obj_cornell_every_mode), cmocka_unit_test(gltf_room_no_material_typed),
        cmocka_unit_test(mtl_mapping),           cmocka_unit_test(gltf_mapping),
        cmocka_unit_test(overrides_and_frame),   cmocka_unit_test(example_assets),
        cmocka_unit_test(bad_obj_and_mtl),
        cmocka_unit_test(bad_gltf),              cmocka_unit_test(cli_bad_model_exit_2),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
