/* test_scene.c - scene loader: the radray-scene/1 format, its defaults,
 * transforms, culling rule, overrides, and every kind of bad input (each
 * checked for the JSON path in its message and for *out left untouched). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "scene.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static void assert_v3(rr_vec3 a, double x, double y, double z)
{
    if (!(fabs(a.x - x) <= 1e-9 && fabs(a.y - y) <= 1e-9 && fabs(a.z - z) <= 1e-9))
        fail_msg("got (%.12g, %.12g, %.12g), expected (%.12g, %.12g, %.12g)", a.x, a.y, a.z, x, y, z);
}

static void assert_rgb(rr_rgb a, double r, double g, double b)
{
    assert_v3(rr_v3(a.r, a.g, a.b), r, g, b);
}

/* A scene from parts; NULL parts take a small valid default, "" leaves an
 * optional part out. */
#define CAM "{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}"
#define MATS                                                                                                 \
    "{\"white\":{},\"red\":{\"diffuse\":[0.8,0.1,0.1]},\"green\":{\"diffuse\":[0.1,0.8,0.1]},"              \
    "\"chrome\":{\"mirror\":0.9},\"lamp\":{\"emission\":[4,3,2]}}"
#define QUAD(mat) "{\"type\":\"quad\",\"material\":\"" mat "\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"
#define OBJS "[" QUAD("white") "}]"

static char *make_scene(const char *cam, const char *mats, const char *lights, const char *objs, const char *render)
{
    static char buf[16384];
    snprintf(buf, sizeof buf, "{\"format\":\"radray-scene/1\",\"camera\":%s,\"materials\":%s%s%s,\"objects\":%s%s%s}",
             cam ? cam : CAM, mats ? mats : MATS, lights && lights[0] ? ",\"lights\":" : "", lights ? lights : "",
             objs ? objs : OBJS, render && render[0] ? ",\"render\":" : "", render ? render : "");
    return buf;
}

/* Warnings land here. */
typedef struct warn_log {
    int count;
    char last[RR_ERROR_MSG_MAX];
} warn_log;

static void warn_fn(void *user, const char *msg)
{
    warn_log *w = user;
    w->count++;
    snprintf(w->last, sizeof w->last, "%s", msg);
}

static scene *load_ok(const char *json, const scene_load_opts *opts)
{
    scene *s = NULL;
    rr_error err = {0};
    rr_status st = scene_load_string(json, "t.json", RR_TEST_DATA "/scenes", opts, &s, &err);
    if (st != RR_OK)
        fail_msg("scene_load_string failed: %s\n%s", err.msg, json);
    assert_non_null(s);
    return s;
}

/* Loads json expecting failure with code and a message that contains want
 * (and starts with the file name). *out must stay untouched. */
static void expect_fail_opts(const char *json, const scene_load_opts *opts, const char *base_dir, rr_status code,
                             const char *want)
{
    scene *sentinel = (scene *)(uintptr_t)0x1234;
    scene *s = sentinel;
    rr_error err = {0};
    rr_status st = scene_load_string(json, "bad.json", base_dir, opts, &s, &err);
    if (st == RR_OK) {
        scene_destroy(s);
        fail_msg("expected failure containing \"%s\", but it loaded:\n%s", want, json);
    }
    assert_ptr_equal(s, sentinel);
    if (!strstr(err.msg, want))
        fail_msg("message \"%s\"\n  does not contain \"%s\"", err.msg, want);
    if (strncmp(err.msg, "bad.json", 8) != 0 && strncmp(err.msg, "--set '", 7) != 0)
        fail_msg("message \"%s\" does not start with the file name", err.msg);
    if (st != code)
        fail_msg("status %s, expected %s (message: %s)", rr_status_name(st), rr_status_name(code), err.msg);
}

static void expect_fail(const char *json, rr_status code, const char *want)
{
    expect_fail_opts(json, NULL, "", code, want);
}

/* ---- good scenes ---- */

/* Every object type, light and material field in one scene. */
static void complete_scene(void **state)
{
    (void)state;
    const char *json =
        "{\"format\":\"radray-scene/1\",\"name\":\"full\",\"description\":\"all of it\","
        "\"camera\":" CAM ","
        "\"materials\":{\"white\":{\"diffuse\":[0.7,0.6,0.5],\"ambient\":0.2,\"specular\":[0.1,0.2,0.3],\"k\":20,"
        "\"mirror\":[0.1,0.2,0.3],\"emission\":0},"
        "\"lamp\":{\"diffuse\":0.25,\"specular\":0.5,\"mirror\":0,\"emission\":[4,3,2]}},"
        "\"lights\":[{\"type\":\"directional\",\"direction\":[0,0,2],\"intensity\":[1,2,3],\"name\":\"sun\"},"
        "{\"type\":\"point\",\"position\":[1,2,3],\"intensity\":5}],"
        "\"objects\":["
        "{\"type\":\"triangles\",\"name\":\"tri\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],"
        "\"indices\":[[0,1,2]]},"
        "{\"type\":\"quad\",\"material\":\"lamp\",\"vertices\":[[0,0,1],[1,0,1],[1,1,1],[0,1,1]]},"
        "{\"type\":\"box\",\"material\":\"white\",\"min\":[-1,-2,-3],\"max\":[1,2,3],\"cull\":false},"
        "{\"type\":\"sphere\",\"material\":\"white\",\"center\":[5,0,0],\"radius\":2,"
        "\"transform\":[{\"scale\":3},{\"rotate\":{\"axis\":[0,1,0],\"degrees\":90}}]},"
        "{\"type\":\"mesh\",\"material\":\"white\",\"file\":\"meshes/tetra.obj\"}],"
        "\"render\":{\"spp\":8,\"seed\":42,\"max_depth\":3,\"threads\":2,\"exposure\":-1.5,\"background\":[0.1,0.2,0.3],"
        "\"ambient\":0.05,\"light_samples\":4,\"half_float\":true}}";
    scene *s = load_ok(json, NULL);
    assert_string_equal(s->name, "full");
    assert_string_equal(s->path, "t.json");
    assert_int_equal(s->view.width, 5);
    assert_int_equal(s->view.height, 3);
    assert_v3(s->view.I, 1, 0, 0);
    assert_v3(s->view.J, 0, 1, 0);

    assert_int_equal(s->nmaterials, 2);
    const scene_material *w = &s->materials[0], *l = &s->materials[1];
    assert_string_equal(w->name, "white");
    assert_rgb(w->diffuse, 0.7, 0.6, 0.5);
    assert_near(w->ambient, 0.2, 0);
    assert_rgb(w->specular, 0.1, 0.2, 0.3);
    assert_near(w->k, 20, 0);
    assert_rgb(w->mirror, 0.1, 0.2, 0.3);
    assert_rgb(w->emission, 0, 0, 0);
    assert_string_equal(l->name, "lamp");
    assert_rgb(l->diffuse, 0.25, 0.25, 0.25);
    assert_rgb(l->specular, 0.5, 0.5, 0.5);
    assert_rgb(l->emission, 4, 3, 2);

    assert_int_equal(s->nlights, 2);
    assert_int_equal(s->lights[0].type, SCENE_LIGHT_DIRECTIONAL);
    assert_string_equal(s->lights[0].name, "sun");
    assert_v3(s->lights[0].direction, 0, 0, 1); /* normalised */
    assert_rgb(s->lights[0].intensity, 1, 2, 3);
    assert_int_equal(s->lights[1].type, SCENE_LIGHT_POINT);
    assert_string_equal(s->lights[1].name, "lights[1]");
    assert_v3(s->lights[1].position, 1, 2, 3);
    assert_rgb(s->lights[1].intensity, 5, 5, 5);

    assert_int_equal(s->nobjects, 5);
    assert_int_equal(s->objects[0].kind, SCENE_OBJ_TRIANGLES);
    assert_string_equal(s->objects[0].name, "tri");
    assert_int_equal(s->objects[0].tri_count, 1);
    assert_int_equal(s->objects[1].kind, SCENE_OBJ_QUAD);
    assert_string_equal(s->objects[1].name, "objects[1]");
    assert_int_equal(s->objects[1].material, 1);
    assert_int_equal(s->objects[1].tri_first, 1);
    assert_int_equal(s->objects[1].tri_count, 2);
    assert_int_equal(s->objects[2].kind, SCENE_OBJ_BOX);
    assert_int_equal(s->objects[2].tri_count, 12);
    assert_int_equal(s->objects[2].cull_backfaces, 0);
    assert_true(s->objects[2].report.watertight);
    /* Sphere: scaled by 3 then rotated 90 degrees about y: centre (5,0,0) ->
     * (15,0,0) -> (0,0,-15); radius 6. */
    assert_int_equal(s->objects[3].kind, SCENE_OBJ_SPHERE);
    assert_int_equal(s->objects[3].tri_count, 0);
    assert_v3(s->objects[3].center, 0, 0, -15);
    assert_near(s->objects[3].radius, 6, 1e-12);
    assert_int_equal(s->objects[4].kind, SCENE_OBJ_MESH);
    assert_string_equal(s->objects[4].source, RR_TEST_DATA "/scenes/meshes/tetra.obj");
    assert_int_equal(s->objects[4].tri_count, 4);
    assert_int_equal(s->ntris, 1 + 2 + 12 + 4);
    assert_int_equal(s->nverts, 3 + 4 + 8 + 4);
    for (size_t i = 0; i < s->ntris; i++)
        assert_true(s->tris[i].material < s->nmaterials && s->tris[i].object < s->nobjects);

    /* The lamp quad's two triangles are the emissive ones. */
    assert_int_equal(s->nemissive, 2);
    assert_int_equal(s->emissive_tris[0], 1);
    assert_int_equal(s->emissive_tris[1], 2);

    /* Bounds: the box (-1..1, -2..2, -3..3) and the sphere (z down to -21). */
    assert_v3(s->bbox_min, -6, -6, -21);
    assert_v3(s->bbox_max, 6, 6, 3);

    const scene_settings *r = &s->settings;
    assert_int_equal(r->spp, 8);
    assert_int_equal(r->seed, 42);
    assert_int_equal(r->max_depth, 3);
    assert_int_equal(r->threads, 2);
    assert_near(r->exposure, -1.5, 0);
    assert_rgb(r->background, 0.1, 0.2, 0.3);
    assert_rgb(r->ambient, 0.05, 0.05, 0.05);
    assert_int_equal(r->light_samples, 4);
    assert_int_equal(r->half_float, 1);
    scene_destroy(s);
}

static void lookat_camera(void **state)
{
    (void)state;
    scene *s = load_ok(make_scene("{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],"
                                  "\"fov\":90,\"width\":40,\"height\":20}",
                                  NULL, "", NULL, ""),
                       NULL);
    assert_int_equal(s->view.width, 40);
    assert_int_equal(s->view.height, 20);
    assert_v3(s->view.E, 0, 0, 5);
    assert_v3(s->view.O, 0, 0, 4);
    assert_v3(s->view.I, 1, 0, 0);
    /* fov 90 at distance 1: the screen is 2 units high over 20 pixels. */
    assert_near(s->view.s, 0.1, 1e-12);
    scene_destroy(s);
}

static void defaults(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err;
    const char *json = make_scene(NULL, "{\"m\":{}}", "", "[" QUAD("m") "}]", "");
    assert_int_equal(scene_load_string(json, "scenes/simple.json", "", NULL, &s, &err), RR_OK);
    assert_string_equal(s->name, "simple"); /* the file's base name */
    assert_string_equal(s->path, "scenes/simple.json");
    const scene_material *m = &s->materials[0];
    assert_rgb(m->diffuse, 0.5, 0.5, 0.5);
    assert_near(m->ambient, 0, 0);
    assert_rgb(m->specular, 0, 0, 0);
    assert_near(m->k, 1, 0);
    assert_rgb(m->mirror, 0, 0, 0);
    assert_rgb(m->emission, 0, 0, 0);
    const scene_settings *r = &s->settings;
    assert_int_equal(r->spp, 1);
    assert_int_equal(r->seed, 0);
    assert_int_equal(r->max_depth, 5);
    assert_int_equal(r->threads, 0);
    assert_near(r->exposure, 0, 0);
    assert_rgb(r->background, 0, 0, 0);
    assert_rgb(r->ambient, 0, 0, 0);
    assert_int_equal(r->light_samples, 16);
    assert_int_equal(r->half_float, 0);
    assert_int_equal(s->nlights, 0);
    assert_null(s->lights);
    assert_null(s->normals);
    assert_int_equal(s->nemissive, 0);
    assert_null(s->emissive_tris);
    assert_string_equal(s->objects[0].name, "objects[0]");
    assert_int_equal(s->objects[0].dropped_degenerate, 0);
    assert_v3(s->bbox_min, 0, 0, 0);
    assert_v3(s->bbox_max, 1, 1, 0);
    /* Quad split (v0,v1,v2), (v0,v2,v3), both facing +z. */
    assert_int_equal(s->tris[0].v[0], 0);
    assert_int_equal(s->tris[0].v[1], 1);
    assert_int_equal(s->tris[0].v[2], 2);
    assert_int_equal(s->tris[1].v[0], 0);
    assert_int_equal(s->tris[1].v[1], 2);
    assert_int_equal(s->tris[1].v[2], 3);
    assert_v3(scene_tri_normal(s, 0), 0, 0, 1);
    assert_v3(scene_tri_normal(s, 1), 0, 0, 1);
    assert_near(scene_tri_area(s, 0), 0.5, 1e-15);
    assert_near(scene_tri_area(s, 1), 0.5, 1e-15);
    scene_destroy(s);
    scene_destroy(NULL);
}

/* rotate 90 about z, then scale (2,3,4), then translate (10,20,30), by hand:
 * (1,0,0) -> (0,1,0) -> (0,3,0) -> (10,23,30)
 * (0,1,0) -> (-1,0,0) -> (-2,0,0) -> (8,20,30)
 * (0,0,1) -> (0,0,1) -> (0,0,4) -> (10,20,34)
 * A 30 degree turn about x takes (0,1,0) to (0, cos 30, sin 30); the matrix
 * step [[0,-1,0,1],[1,0,0,2],[0,0,1,3]] takes (1,0,0) to (1,3,3). */
static void transform_vertices(void **state)
{
    (void)state;
    const char *objs =
        "[{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[1,0,0],[0,1,0],[0,0,1]],\"indices\":[[0,1,2]],"
        "\"transform\":[{\"rotate\":{\"axis\":[0,0,1],\"degrees\":90}},{\"scale\":[2,3,4]},"
        "{\"translate\":[10,20,30]}]},"
        "{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[1,0,0],[0,1,0],[0,0,1]],\"indices\":[[0,1,2]],"
        "\"transform\":[{\"rotate\":{\"axis\":[2,0,0],\"degrees\":30}}]},"
        "{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[1,0,0],[0,1,0],[0,0,1]],\"indices\":[[0,1,2]],"
        "\"transform\":[{\"matrix\":[[0,-1,0,1],[1,0,0,2],[0,0,1,3]]}]}]";
    scene *s = load_ok(make_scene(NULL, NULL, "", objs, ""), NULL);
    assert_v3(s->verts[0], 10, 23, 30);
    assert_v3(s->verts[1], 8, 20, 30);
    assert_v3(s->verts[2], 10, 20, 34);
    assert_v3(s->verts[4], 0, sqrt(3) / 2, 0.5);
    assert_v3(s->verts[6], 1, 3, 3);
    /* Positive determinants keep the winding. */
    assert_int_equal(s->tris[0].v[1], 1);
    assert_int_equal(s->tris[0].v[2], 2);
    scene_destroy(s);
}

static void negative_determinant_flips_winding(void **state)
{
    (void)state;
    /* A +z-facing quad mirrored in x still faces +z; a mirrored box still
     * has every face pointing outwards. */
    const char *objs = "[" QUAD("white") ",\"transform\":[{\"scale\":[-1,1,1]}]},"
                       "{\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,2,3],"
                       "\"transform\":[{\"scale\":[1,-1,1]},{\"translate\":[5,0,0]}]}]";
    scene *s = load_ok(make_scene(NULL, NULL, "", objs, ""), NULL);
    assert_v3(s->verts[1], -1, 0, 0);
    assert_v3(scene_tri_normal(s, 0), 0, 0, 1);
    assert_v3(scene_tri_normal(s, 1), 0, 0, 1);
    assert_int_equal(s->tris[0].v[1], 2); /* (v0, v2, v1) */
    assert_int_equal(s->tris[0].v[2], 1);
    rr_vec3 centre = rr_v3(5.5, -1, 1.5);
    double area = 0;
    for (size_t i = s->objects[1].tri_first; i < s->objects[1].tri_first + s->objects[1].tri_count; i++) {
        const scene_tri *t = &s->tris[i];
        rr_vec3 c = rr_v3_scale(rr_v3_add(rr_v3_add(s->verts[t->v[0]], s->verts[t->v[1]]), s->verts[t->v[2]]), 1.0 / 3);
        assert_true(rr_v3_dot(scene_tri_normal(s, i), rr_v3_sub(c, centre)) > 0);
        area += scene_tri_area(s, i);
    }
    assert_near(area, 2 * (1 * 2 + 2 * 3 + 1 * 3), 1e-12);
    assert_true(s->objects[1].report.watertight && s->objects[1].report.consistently_oriented);
    scene_destroy(s);
}

/* Box triangles face outwards (untransformed), 12 of them, 8 shared corners. */
static void box_outward(void **state)
{
    (void)state;
    scene *s = load_ok(
        make_scene(NULL, NULL, "", "[{\"type\":\"box\",\"material\":\"white\",\"min\":[-1,0,2],\"max\":[3,1,4]}]", ""),
        NULL);
    assert_int_equal(s->ntris, 12);
    assert_int_equal(s->nverts, 8);
    rr_vec3 centre = rr_v3(1, 0.5, 3);
    int axis_count[6] = {0};
    for (size_t i = 0; i < s->ntris; i++) {
        const scene_tri *t = &s->tris[i];
        rr_vec3 c = rr_v3_scale(rr_v3_add(rr_v3_add(s->verts[t->v[0]], s->verts[t->v[1]]), s->verts[t->v[2]]), 1.0 / 3);
        rr_vec3 n = scene_tri_normal(s, i);
        assert_true(rr_v3_dot(n, rr_v3_sub(c, centre)) > 0);
        for (int a = 0; a < 3; a++) {
            if (rr_v3_get(n, a) > 0.5)
                axis_count[2 * a + 1]++;
            if (rr_v3_get(n, a) < -0.5)
                axis_count[2 * a]++;
        }
    }
    for (int f = 0; f < 6; f++)
        assert_int_equal(axis_count[f], 2);
    assert_v3(s->bbox_min, -1, 0, 2);
    assert_v3(s->bbox_max, 3, 1, 4);
    scene_destroy(s);
}

#define TETRA_V "\"vertices\":[[0,0,0],[1,0,0],[0,1,0],[0,0,1]]"
#define TETRA_I "\"indices\":[[0,2,1],[0,1,3],[0,3,2],[1,2,3]]"

static void cull_auto(void **state)
{
    (void)state;
    const char *objs =
        "[{\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,1,1]},"       /* 0 closed: cull */
        QUAD("white") "},"                                                                /* 1 open: no */
        "{\"type\":\"box\",\"material\":\"chrome\",\"min\":[0,0,0],\"max\":[1,1,1]},"        /* 2 mirror: no */
        "{\"type\":\"sphere\",\"material\":\"white\",\"center\":[0,0,0],\"radius\":1},"       /* 3 closed: cull */
        "{\"type\":\"triangles\",\"material\":\"white\"," TETRA_V "," TETRA_I "},"             /* 4 closed: cull */
        "{\"type\":\"triangles\",\"material\":\"white\"," TETRA_V ",\"indices\":[[0,2,1]]}," /* 5 open: no */
        "{\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,1,1],\"cull\":false}," /* 6 */
        QUAD("white") ",\"cull\":true},"                                                  /* 7 forced */
        "{\"type\":\"triangles\",\"material\":\"white\"," TETRA_V                          /* 8 misoriented */
        ",\"indices\":[[0,1,2],[0,1,3],[0,3,2],[1,2,3]]},"
        "{\"type\":\"sphere\",\"material\":\"chrome\",\"center\":[0,0,0],\"radius\":1,\"cull\":\"auto\"}]"; /* 9 */
    scene *s = load_ok(make_scene(NULL, NULL, "", objs, ""), NULL);
    static const int want[] = {1, 0, 0, 1, 1, 0, 0, 1, 0, 0};
    assert_int_equal(s->nobjects, 10);
    for (size_t i = 0; i < 10; i++)
        if (s->objects[i].cull_backfaces != want[i])
            fail_msg("objects[%zu]: cull_backfaces %d, expected %d", i, s->objects[i].cull_backfaces, want[i]);
    assert_true(s->objects[4].report.watertight && s->objects[4].report.consistently_oriented);
    assert_false(s->objects[5].report.watertight);
    assert_false(s->objects[8].report.consistently_oriented);
    scene_destroy(s);
}

static void zero_area_triangles(void **state)
{
    (void)state;
    warn_log log = {0};
    scene_load_opts opts = {0};
    opts.warn.fn = warn_fn;
    opts.warn.user = &log;
    /* Triangle 1 repeats a vertex, triangle 2 is collinear (after a 30 degree
     * rotation, so only up to rounding). */
    const char *objs = "[{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0],[2,0,0]],"
                       "\"indices\":[[0,1,2],[0,1,1],[0,1,3]],"
                       "\"transform\":[{\"rotate\":{\"axis\":[1,1,1],\"degrees\":30}}]}]";
    scene *s = load_ok(make_scene(NULL, NULL, "", objs, ""), &opts);
    assert_int_equal(s->ntris, 1);
    assert_int_equal(s->objects[0].tri_count, 1);
    assert_int_equal(s->objects[0].dropped_degenerate, 2);
    assert_int_equal(log.count, 1);
    assert_string_equal(log.last, "t.json: objects[0]: dropped 2 zero-area triangles");
    scene_destroy(s);

    /* All degenerate: an error (and nothing is warned about a scene that is not built). */
    expect_fail(make_scene(NULL, NULL, "",
                           "[" QUAD("white") "},{\"type\":\"triangles\",\"material\":\"white\","
                           "\"vertices\":[[0,0,0],[1,1,1],[2,2,2]],\"indices\":[[0,1,2]]}]",
                           ""),
                RR_ERR_INVALID, "bad.json: objects[1]: every triangle has zero area (1 dropped); the object is empty");
}

static void overrides_good(void **state)
{
    (void)state;
    const char *ovs[] = {
        "render.spp=64",
        "camera.w=100",
        "objects[0].material=red",
        "materials.white.diffuse=[0.7,0.7,0.7]",
        "materials.new={\"emission\":2}",
        "render.light_samples=3",
        "name=renamed",
        "objects[0].vertices[3]=[0,2,0]",
        "render.half_float=true",
    };
    scene_load_opts opts = {0};
    opts.overrides = ovs;
    opts.noverrides = sizeof ovs / sizeof ovs[0];
    /* The file has no "render": the override creates it. */
    scene *s = load_ok(make_scene(NULL, NULL, "", NULL, ""), &opts);
    assert_int_equal(s->settings.spp, 64);
    assert_int_equal(s->settings.light_samples, 3);
    assert_int_equal(s->settings.half_float, 1);
    assert_int_equal(s->view.width, 201);
    assert_string_equal(s->materials[s->objects[0].material].name, "red");
    assert_rgb(s->materials[0].diffuse, 0.7, 0.7, 0.7);
    assert_string_equal(s->materials[s->nmaterials - 1].name, "new");
    assert_rgb(s->materials[s->nmaterials - 1].emission, 2, 2, 2);
    assert_string_equal(s->name, "renamed");
    assert_v3(s->verts[3], 0, 2, 0);
    scene_destroy(s);
}

static void overrides_bad(void **state)
{
    (void)state;
    static const struct {
        const char *ov;
        rr_status code;
        const char *want;
    } cases[] = {
        {"render.spp", RR_ERR_INVALID, "--set 'render.spp': expected KEY=VALUE"},
        {"=3", RR_ERR_INVALID, "--set '=3': the key before '=' is empty"},
        {"objects[5].material=red", RR_ERR_INVALID, "index 5 is out of range: objects has 1 item"},
        {"objects.material=red", RR_ERR_INVALID, "objects is not an object"},
        {"camera.w.x=1", RR_ERR_INVALID, "camera.w is not an object"},
        {"camera[0]=1", RR_ERR_INVALID, "camera is not an array"},
        {"objects[x]=1", RR_ERR_INVALID, "an array index must be a number in brackets"},
        {"objects[0=1", RR_ERR_INVALID, "missing ']'"},
        {"render..spp=1", RR_ERR_INVALID, "empty key"},
        {"lights[0].type=point", RR_ERR_INVALID, "lights does not exist, so it has no index 0"},
        /* Well-formed overrides are validated like the file. */
        {"render.spp=0", RR_ERR_INVALID, "bad.json: render.spp: must be an integer in [1, 16777216] (got 0)"},
        {"render.spq=2", RR_ERR_INVALID, "bad.json: render: unknown key 'spq'"},
        {"objects[0].material=blue", RR_ERR_INVALID, "bad.json: objects[0].material: unknown material 'blue'"},
        {"objects[0].vertices[0]=[nan,0,0]", RR_ERR_INVALID,
         "bad.json: objects[0].vertices[0]: expected an array of 3 numbers [x, y, z] (got the string \"[nan,0,0]\")"},
        {"format=radray-scene/2", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        scene_load_opts opts = {0};
        opts.overrides = &cases[i].ov;
        opts.noverrides = 1;
        expect_fail_opts(make_scene(NULL, NULL, "", NULL, ""), &opts, "", cases[i].code, cases[i].want);
    }
}

static void invalid_json(void **state)
{
    (void)state;
    static const struct {
        const char *text, *want;
    } cases[] = {
        /* Line 3, column 14 is the ',' where a key should be. */
        {"{\n  \"format\": \"radray-scene/1\",\n  \"camera\": {, \"w\": 1}\n}",
         "bad.json:3:14: invalid JSON near ', \"w\": 1}': expected a key in double quotes"},
        {"{\"format\": \"radray-scene/1\", \"camera\": {\"s\": NaN}}",
         "bad.json:1:46: invalid JSON near 'NaN}}': NaN and infinities are not JSON numbers"},
        {"{\"format\": \"radray-scene/1\",\n\"x\": Infinity}", "bad.json:2:6: invalid JSON near 'Infinity}'"},
        {"{\"x\": -Infinity}", "bad.json:1:7: invalid JSON near '-Infinity}'"},
        {"{\"format\": \"radray-scene/1\"} trailing",
         "bad.json:1:30: invalid JSON near 'trailing': unexpected text after the end of the JSON value"},
        {"{\"format\": \"radray-scene/1\",\n  \"camera\": {",
         "bad.json:2:14: invalid JSON at the end of the text: unexpected end of the text inside an object"},
        {"{\"a\": [1, 2,]}", "bad.json:1:13: invalid JSON near ']}': a comma before ']' (JSON allows no trailing comma)"},
        {"{\"a\": 1,\n}", "bad.json:2:1: invalid JSON near '}': a comma before '}' (JSON allows no trailing comma)"},
        {"{\"a\": 1 \"b\": 2}", "bad.json:1:9: invalid JSON near '\"b\": 2}': expected ',' or '}' after a value"},
        {"{'a': 1}", "bad.json:1:2: invalid JSON near ''a': 1}': strings and keys take double quotes"},
        {"{\"a\": \"abc\n\"}", "bad.json:1:11: invalid JSON at the end of the line: line break inside a string"},
        {"{\"a\": \"a\tb\"}", "bad.json:1:9: invalid JSON near '?b\"}': control character inside a string"},
        {"{\"a\": \"a\\qb\"}", "bad.json:1:9: invalid JSON near '\\qb\"}': invalid escape in a string"},
        {"{\"a\": 01}", "bad.json:1:7: invalid JSON near '01}': a number cannot have a leading zero"},
        {"{\"a\": 1.}", "bad.json:1:7: invalid JSON near '1.}': a number needs digits after '.'"},
        {"{\"a\": 1e}", "bad.json:1:7: invalid JSON near '1e}': a number needs digits in its exponent"},
        {"{\"a\": -}", "bad.json:1:7: invalid JSON near '-}': a number needs digits after '-'"},
        {"\xEF\xBB\xBF{\"a\": x}", "bad.json:1:10: invalid JSON near 'x}': expected a value"},
        {"{\"a\": \"abc", "bad.json:1:7: invalid JSON near '\"abc': unterminated string (it starts here)"},
        {"{\"a\": tru}", "bad.json:1:7: invalid JSON near 'tru}': expected a value"},
        {"{\"a\" 1}", "bad.json:1:6: invalid JSON near '1}': expected ':' after the key"},
        {"{\"a\": .5}", "bad.json:1:7: invalid JSON near '.5}': expected a value"},
        {"{\"a\": 1.00000000000000000000000000000000000000000000000000000000000000001}",
         "bad.json:1:7: invalid JSON near '1.0000000000000000000000': a number longer than 63 characters"},
        {"  \n ", "bad.json: the file is empty"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_fail(cases[i].text, RR_ERR_PARSE, cases[i].want);
}

/* Every other kind of bad input: the message names the place. */
static void bad_inputs(void **state)
{
    (void)state;
#define TRI(extra) "[{\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1,2]]" extra "}]"
#define OBJ1(body) "[{" body "}]"
    static const struct {
        const char *cam, *mats, *lights, *objs, *render, *raw;
        rr_status code;
        const char *want;
    } cases[] = {
        /* the file as a whole */
        {0, 0, 0, 0, 0, "[1, 2]", RR_ERR_INVALID, "bad.json: expected a JSON object with \"format\": \"radray-scene/1\" (got an array of 2 items)"},
        {0, 0, 0, 0, 0, "{\"camera\": {}}", RR_ERR_INVALID, "bad.json: format: missing (expected \"radray-scene/1\""},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/2\"}", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\" (got the string \"radray-scene/2\")"},
        {0, 0, 0, 0, 0, "{\"format\": 1}", RR_ERR_INVALID, "bad.json: format: expected \"radray-scene/1\" (got the number 1)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"lihgts\": []}", RR_ERR_INVALID,
         "bad.json: unknown key 'lihgts' (allowed: format, name, description, camera, materials, lights, objects, render, radiosity)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"format\": \"radray-scene/1\"}", RR_ERR_INVALID, "bad.json: key 'format' appears twice"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"name\": 3}", RR_ERR_INVALID, "bad.json: name: expected a string (got the number 3)"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"description\": []}", RR_ERR_INVALID, "bad.json: description: expected a string"},
        {0, 0, 0, 0, 0, "{\"format\": \"radray-scene/1\", \"materials\": {\"a\": {}}, \"objects\": []}", RR_ERR_INVALID,
         "bad.json: camera: missing (expected an object"},
        /* camera */
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1,\"fov\":3}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: unknown key 'fov' (allowed: type, E, O, U, s, w, h)"},
        {"{\"type\":\"pinhole\"}", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera.type: expected \"lecture\" or \"lookat\" (got the string \"pinhole\")"},
        {"{\"E\":[0,0,5]}", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera.type: missing"},
        {"[]", 0, 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: camera: expected an object (got an array of 0 items)"},
        {"{\"type\":\"lecture\",\"E\":\"here\",\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E: expected an array of 3 numbers [x, y, z] (got the string \"here\")"},
        {"{\"type\":\"lecture\",\"E\":[0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E: expected an array of 3 numbers [x, y, z] (got an array of 2 items)"},
        {"{\"type\":\"lecture\",\"E\":[0,null,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E[1]: expected a number (got null)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.O: missing (expected an array of 3 numbers [x, y, z])"},
        {"{\"type\":\"lecture\",\"E\":[0,0,1e999],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.E[2]: the number is out of range (it overflows a double to infinity)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":-3,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.w: must be an integer in [0, 1073741823] (got -3)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1.5}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.h: expected an integer (got 1.5)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.s: the pixel scale must be > 0 (got 0)"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,0,-2],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the up vector U is parallel to the view direction"},
        {"{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,5],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the screen centre O equals the viewpoint E"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":180,\"width\":4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.fov: must be in (0, 180) degrees (got 180)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":-4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.width: must be an integer in [1, 2147483647] (got -4)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera.height: missing (expected an integer)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,\"width\":4,\"height\":4,\"s\":1}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: unknown key 's' (allowed: type, eye, target, up, fov, width, height)"},
        {"{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1e-30,-1],\"fov\":60,\"width\":4,\"height\":4}", 0, 0, 0, 0, 0,
         RR_ERR_INVALID, "bad.json: camera: the up vector U is parallel to the view direction"},
        /* materials */
        {0, "[]", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials: expected an object mapping names to materials (got an array of 0 items)"},
        {0, "{}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials: expected at least one material"},
        {0, "{\"white\":{\"difuse\":0.5}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: materials.white: unknown key 'difuse' (allowed: diffuse, ambient, specular, k, mirror, emission)"},
        {0, "{\"white\":{\"diffuse\":[1.5,0,0]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.diffuse[0]: must be in [0, 1] (got 1.5)"},
        {0, "{\"white\":{\"diffuse\":2}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.diffuse: must be in [0, 1] (got 2)"},
        {0, "{\"white\":{\"diffuse\":[0.5,0.5]}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "bad.json: materials.white.diffuse: expected a number or an array of 3 numbers [r, g, b] (got an array of 2 items)"},
        {0, "{\"white\":{\"mirror\":[0,0,1.1]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.mirror[2]: must be in [0, 1] (got 1.1)"},
        {0, "{\"white\":{\"emission\":[0,0,-1]}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.emission[2]: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"specular\":-0.5}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.specular: must be >= 0 (got -0.5)"},
        {0, "{\"white\":{\"ambient\":-1}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.ambient: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"k\":-1}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.k: must be >= 0 (got -1)"},
        {0, "{\"white\":{\"k\":\"high\"}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white.k: expected a number (got the string \"high\")"},
        {0, "{\"white\":3}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white: expected an object (got the number 3)"},
        {0, "{\"white\":{},\"white\":{}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials.white: material 'white' is defined twice"},
        {0, "{\"\":{}}", 0, 0, 0, 0, RR_ERR_INVALID, "bad.json: materials: a material name is empty"},
        {0, "{\"a234567890123456789012345678901234567890123456789012345678901234\":{}}", 0, 0, 0, 0, RR_ERR_INVALID,
         "the material name is too long (64 bytes, at most 63)"},
        /* lights */
        {0, 0, "{}", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights: expected an array of lights (got an object)"},
        {0, 0, "[{\"type\":\"spot\",\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].type: expected \"directional\" or \"point\" (got the string \"spot\")"},
        {0, 0, "[{\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].type: missing"},
        {0, 0, "[{\"type\":\"directional\",\"direction\":[0,0,0],\"intensity\":1}]", 0, 0, 0, RR_ERR_INVALID,
         "bad.json: lights[0].direction: the direction is the zero vector"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1},{\"type\":\"point\",\"direction\":[0,0,1],\"intensity\":1}]", 0, 0, 0,
         RR_ERR_INVALID, "bad.json: lights[1]: unknown key 'direction' (allowed: type, name, position, intensity)"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0]}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].intensity: missing"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":-2}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].intensity: must be >= 0 (got -2)"},
        {0, 0, "[{\"type\":\"point\",\"position\":[0,0,0],\"intensity\":1,\"name\":7}]", 0, 0, 0, RR_ERR_INVALID, "bad.json: lights[0].name: expected a string"},
        /* objects */
        {0, 0, 0, "{}", 0, 0, RR_ERR_INVALID, "bad.json: objects: expected an array of objects (got an object)"},
        {0, 0, 0, "[]", 0, 0, RR_ERR_INVALID, "bad.json: objects: expected at least one object"},
        {0, 0, 0, "[3]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: expected an object (got the number 3)"},
        {0, 0, 0, OBJ1("\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].type: missing"},
        {0, 0, 0, OBJ1("\"type\":\"cube\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].type: unknown type 'cube' (known: mesh, triangles, quad, box, sphere)"},
        {0, 0, 0, "[" QUAD("white") "},{\"type\":\"csg\",\"material\":\"white\"}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[1].type: 'csg' is reserved for a later radray-scene/1 extension and not supported yet"},
        {0, 0, 0, OBJ1("\"type\":\"quadric\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].type: 'quadric' is reserved for a later radray-scene/1 extension and not supported yet"},
        {0, 0, 0, "[" QUAD("white") ",\"colour\":\"red\"}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'colour' (allowed: type, name, material, transform, cull, vertices)"},
        {0, 0, 0, "[" QUAD("white") ",\"material\":\"red\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: key 'material' appears twice"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].material: missing (expected the name of a material)"},
        {0, "{\"white\":{},\"red\":{},\"green\":{}}", 0, "[" QUAD("white") "}," QUAD("blue") "}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[1].material: unknown material 'blue' (known: white, red, green)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":3,\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].material: expected the name of a material (got the number 3)"},
        {0, 0, 0, "[" QUAD("white") ",\"cull\":\"yes\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].cull: expected true, false or \"auto\" (got the string \"yes\")"},
        {0, 0, 0, "[" QUAD("white") ",\"name\":\"\"}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].name: expected a non-empty string"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices: expected an array of 4 points [x, y, z] (got an array of 3 items)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].vertices: missing"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1e999,0],[0,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices[2][1]: the number is out of range (it overflows a double to infinity)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[-1e999,1,0]]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].vertices[3][0]: the number is out of range (it overflows a double to -infinity)"},
        {0, 0, 0, TRI(",\"indices\":[[0,1,2]]"), 0, 0, RR_ERR_INVALID, "bad.json: objects[0]: key 'indices' appears twice"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1,2],[0,2,3]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[1][2]: vertex index 3 is out of range (the object has 3 vertices, 0..2)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[-1,1,2]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0][0]: vertex index -1 is out of range"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1.5,2]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0][1]: expected an integer (got 1.5)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[[0,1]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices[0]: expected a triangle [i, j, k] of 3 vertex indices (got an array of 2 items)"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]],\"indices\":[]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices: expected an array of triangles"},
        {0, 0, 0, OBJ1("\"type\":\"triangles\",\"material\":\"white\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].indices: missing"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,0,1]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].max: must be greater than min on every axis"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"max\":[1,1,1]"), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].min: missing"},
        {0, 0, 0, OBJ1("\"type\":\"box\",\"material\":\"white\",\"min\":[0,0,0],\"max\":[1,1,1],\"radius\":1"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'radius' (allowed: type, name, material, transform, cull, min, max)"},
        {0, 0, 0, OBJ1("\"type\":\"sphere\",\"material\":\"white\",\"center\":[0,0,0],\"radius\":0"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].radius: must be > 0 (got 0)"},
        {0, 0, 0, OBJ1("\"type\":\"sphere\",\"material\":\"white\",\"center\":[0,0,0],\"radius\":1,\"transform\":[{\"scale\":[1,2,1]}]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0].transform: a sphere takes only rotations, translations and uniform scales; "
                         "non-uniform scale (or shear) of a sphere needs the quadric type"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\""), 0, 0, RR_ERR_INVALID, "bad.json: objects[0].file: missing (expected a string)"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\",\"file\":\"x.obj\",\"flip\":1"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].flip: expected true or false (got the number 1)"},
        {0, 0, 0, OBJ1("\"type\":\"mesh\",\"material\":\"white\",\"file\":\"x.obj\",\"indices\":[]"), 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'indices' (allowed: type, name, material, transform, cull, file, flip)"},
        /* transforms */
        {0, 0, 0, "[" QUAD("white") ",\"transform\":{\"scale\":2}}]", 0, 0, RR_ERR_INVALID, "bad.json: objects[0].transform: expected an array of steps"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"scale\":[1,0,1]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].scale: a zero scale flattens the object"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"translate\":[1,0,0]},{\"scale\":2,\"translate\":[1,0,0]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[1]: expected exactly one of translate, scale, rotate, matrix (got 2 keys)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"shear\":2}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0]: unknown key 'shear' (allowed: translate, scale, rotate, matrix)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0]: expected exactly one of translate, scale, rotate, matrix (got 0 keys)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,0],\"degrees\":5}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate.axis: the rotation axis is the zero vector"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,1]}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate.degrees: missing (expected a number)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"rotate\":{\"axis\":[0,0,1],\"degrees\":5,\"angle\":1}}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].rotate: unknown key 'angle' (allowed: axis, degrees)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"translate\":[0,0,\"1\"]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].translate[2]: expected a number (got the string \"1\")"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"matrix\":[[1,0,0,0],[0,1,0],[0,0,1,0]]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].matrix[1]: expected a row of 4 numbers (got an array of 3 items)"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"matrix\":[[1,0,0,0],[0,1,0,0],[1,1,0,0]]}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform: the transform is singular (determinant 0): it flattens the object"},
        {0, 0, 0, "[" QUAD("white") ",\"transform\":[{\"scale\":1e200},{\"scale\":1e200}]}]", 0, 0, RR_ERR_INVALID,
         "bad.json: objects[0].transform: the combined transform overflows (it is not finite)"},
        {0, 0, 0, OBJ1("\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[1e300,0,0],[1,1,0],[0,1,0]],\"transform\":[{\"scale\":1e10}]"), 0, 0,
         RR_ERR_INVALID, "bad.json: objects[0]: vertex 1 is not finite after the transform"},
        /* render */
        {0, 0, 0, 0, "[]", 0, RR_ERR_INVALID, "bad.json: render: expected an object (got an array of 0 items)"},
        {0, 0, 0, 0, "{\"sp\":4}", 0, RR_ERR_INVALID,
         "bad.json: render: unknown key 'sp' (allowed: spp, seed, max_depth, threads, exposure, background, ambient, light_samples, half_float)"},
        {0, 0, 0, 0, "{\"spp\":0}", 0, RR_ERR_INVALID, "bad.json: render.spp: must be an integer in [1, 16777216] (got 0)"},
        {0, 0, 0, 0, "{\"spp\":2.5}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer (got 2.5)"},
        {0, 0, 0, 0, "{\"spp\":\"4\"}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer (got the string \"4\")"},
        {0, 0, 0, 0, "{\"spp\":1e999}", 0, RR_ERR_INVALID, "bad.json: render.spp: expected an integer in [1, 16777216] (got a number too large to be exact)"},
        {0, 0, 0, 0, "{\"seed\":-1}", 0, RR_ERR_INVALID, "bad.json: render.seed: must be an integer in [0, 9007199254740992] (got -1)"},
        {0, 0, 0, 0, "{\"max_depth\":-1}", 0, RR_ERR_INVALID, "bad.json: render.max_depth: must be an integer in [0, 1000] (got -1)"},
        {0, 0, 0, 0, "{\"threads\":100000}", 0, RR_ERR_INVALID, "bad.json: render.threads: must be an integer in [0, 4096] (got 100000)"},
        {0, 0, 0, 0, "{\"light_samples\":0}", 0, RR_ERR_INVALID, "bad.json: render.light_samples: must be an integer in [1, 65536] (got 0)"},
        {0, 0, 0, 0, "{\"exposure\":\"bright\"}", 0, RR_ERR_INVALID, "bad.json: render.exposure: expected a number (got the string \"bright\")"},
        {0, 0, 0, 0, "{\"background\":[-0.5,0,0]}", 0, RR_ERR_INVALID, "bad.json: render.background[0]: must be >= 0 (got -0.5)"},
        {0, 0, 0, 0, "{\"ambient\":true}", 0, RR_ERR_INVALID, "bad.json: render.ambient: expected a number or an array of 3 numbers [r, g, b] (got true)"},
        {0, 0, 0, 0, "{\"half_float\":1}", 0, RR_ERR_INVALID, "bad.json: render.half_float: expected true or false (got the number 1)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *json = cases[i].raw ? cases[i].raw
                                        : make_scene(cases[i].cam, cases[i].mats, cases[i].lights ? cases[i].lights : "",
                                                     cases[i].objs, cases[i].render ? cases[i].render : "");
        expect_fail(json, cases[i].code, cases[i].want);
    }
#undef TRI
#undef OBJ1
}

static void resolution_limits(void **state)
{
    (void)state;
    /* 2000001 x 2000001 pixels: about 357 TiB of film. */
    expect_fail(make_scene("{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":1000000,\"h\":1000000}",
                           NULL, "", NULL, ""),
                RR_ERR_LIMIT, "bad.json: camera: a 2000001 x 2000001 image needs 357628.2 GiB of film, over the limit of");
    /* So large that the byte count overflows size_t. */
    expect_fail(make_scene("{\"type\":\"lookat\",\"eye\":[0,0,5],\"target\":[0,0,0],\"up\":[0,1,0],\"fov\":60,"
                           "\"width\":2147483647,\"height\":2147483647}",
                           NULL, "", NULL, ""),
                RR_ERR_LIMIT, "bad.json: camera: a 2147483647 x 2147483647 image needs");
    /* The caller's limit: 5 x 3 pixels need 5*3*12*8 = 1440 bytes. */
    scene_load_opts opts = {0};
    opts.max_image_bytes = 1439;
    expect_fail_opts(make_scene(NULL, NULL, "", NULL, ""), &opts, "", RR_ERR_LIMIT,
                     "bad.json: camera: a 5 x 3 image needs 1.4 KiB of film, over the limit of 1.4 KiB");
    opts.max_image_bytes = 1440;
    scene_destroy(load_ok(make_scene(NULL, NULL, "", NULL, ""), &opts));
}

static void missing_scene_file(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err = {0};
    assert_int_equal(scene_load("/nonexistent/dir/x.json", NULL, &s, &err), RR_ERR_IO);
    assert_null(s);
    assert_non_null(strstr(err.msg, "/nonexistent/dir/x.json"));
}

/* The scene file's folder is where its meshes are looked for. */
static void mesh_from_file(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err = {0};
    if (scene_load(RR_TEST_DATA "/scenes/mesh_tetra.json", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_string_equal(s->name, "mesh_tetra");
    assert_int_equal(s->nobjects, 4);
    assert_string_equal(s->objects[0].source, RR_TEST_DATA "/scenes/meshes/tetra.obj");
    assert_int_equal(s->ntris, 16);
    assert_int_equal(s->nverts, 16);
    for (size_t o = 0; o < 4; o++) {
        assert_int_equal(s->objects[o].kind, SCENE_OBJ_MESH);
        assert_true(s->objects[o].report.watertight && s->objects[o].report.consistently_oriented);
        assert_int_equal(s->objects[o].cull_backfaces, 1);
    }
    rr_vec3 centroid = rr_v3(0.25, 0.25, 0.25);
    for (size_t i = 0; i < 4; i++) { /* the tetra as written faces outwards */
        const scene_tri *t = &s->tris[i];
        assert_true(rr_v3_dot(scene_tri_normal(s, i), rr_v3_sub(s->verts[t->v[0]], centroid)) > 0);
    }
    for (size_t i = 12; i < 16; i++) { /* "flip": inwards */
        const scene_tri *t = &s->tris[i];
        assert_true(rr_v3_dot(scene_tri_normal(s, i), rr_v3_sub(s->verts[t->v[0]], centroid)) < 0);
    }
    /* Mirrored by scale (-2,1,1): still outward-facing around the mirrored centroid. */
    rr_vec3 mc = rr_v3(-0.5, 0.25, 0.25);
    for (size_t i = 8; i < 12; i++) {
        const scene_tri *t = &s->tris[i];
        assert_true(rr_v3_dot(scene_tri_normal(s, i), rr_v3_sub(s->verts[t->v[0]], mc)) > 0);
    }
    /* Vertex normals: vertex 3 of each copy had (1,1,1)/sqrt(3). Under scale
     * (2,1,1) the inverse transpose diag(1/2,1,1) gives (1/2,1,1)/1.5 =
     * (1/3,2/3,2/3); under (-2,1,1), (-1/3,2/3,2/3); flipped, the negation. */
    assert_non_null(s->normals);
    assert_v3(s->normals[3], 1 / sqrt(3), 1 / sqrt(3), 1 / sqrt(3));
    assert_v3(s->normals[4 + 3], 1.0 / 3, 2.0 / 3, 2.0 / 3);
    assert_v3(s->normals[8 + 3], -1.0 / 3, 2.0 / 3, 2.0 / 3);
    assert_v3(s->normals[12 + 3], -1 / sqrt(3), -1 / sqrt(3), -1 / sqrt(3));
    scene_destroy(s);
}

/* Vertices without normals get the zero vector once another object has some. */
static void normals_mixed(void **state)
{
    (void)state;
    scene *s = load_ok(make_scene(NULL, NULL, "",
                                  "[" QUAD("white") "},{\"type\":\"mesh\",\"material\":\"white\",\"file\":\"meshes/tetra.obj\"}]", ""),
                       NULL);
    assert_non_null(s->normals);
    for (size_t i = 0; i < 4; i++)
        assert_v3(s->normals[i], 0, 0, 0);
    for (size_t i = 4; i < 8; i++)
        assert_near(rr_v3_len(s->normals[i]), 1, 1e-9);
    scene_destroy(s);
}

static void write_file(const char *path, const char *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static void bad_mesh_files(void **state)
{
    (void)state;
    char dir[] = "/tmp/radray-test-scene-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char p_empty[512], p_garbage[512], p_scene[512];
    snprintf(p_empty, sizeof p_empty, "%s/empty.obj", dir);
    snprintf(p_garbage, sizeof p_garbage, "%s/garbage.ply", dir);
    snprintf(p_scene, sizeof p_scene, "%s/nul.json", dir);
    write_file(p_empty, "", 0);
    static const char garbage[] = "ply\nformat binary_little_endian 1.0\nelement vertex 1000000\n"
                                  "property float x\nproperty float y\nproperty float z\nend_header\n\x01\x02\x03";
    write_file(p_garbage, garbage, sizeof garbage - 1);
    write_file(p_scene, "{\"format\": \"radray-scene/1\"}\0junk", 34);

    static const char *const files[] = {"missing.obj", "empty.obj", "garbage.ply"};
    for (size_t i = 0; i < 3; i++) {
        char objs[512], want[1024];
        snprintf(objs, sizeof objs, "[" QUAD("white") "},{\"type\":\"mesh\",\"material\":\"white\",\"file\":\"%s\"}]",
                 files[i]);
        /* mesh_load's own message, which names the file, after the scene's place. */
        snprintf(want, sizeof want, "bad.json: objects[1].file: %s/%s", dir, files[i]);
        scene *sentinel = (scene *)(uintptr_t)0x1234, *s = sentinel;
        rr_error err = {0};
        rr_status st = scene_load_string(make_scene(NULL, NULL, "", objs, ""), "bad.json", dir, NULL, &s, &err);
        assert_int_not_equal(st, RR_OK);
        assert_ptr_equal(s, sentinel);
        if (strncmp(err.msg, want, strlen(want)) != 0)
            fail_msg("message \"%s\" does not start with \"%s\"", err.msg, want);
    }
    /* A NUL byte in a scene file is refused, not silently cut. */
    scene *s = NULL;
    rr_error err = {0};
    assert_int_equal(scene_load(p_scene, NULL, &s, &err), RR_ERR_PARSE);
    assert_null(s);
    assert_non_null(strstr(err.msg, "NUL byte at offset 28"));

    unlink(p_empty);
    unlink(p_garbage);
    unlink(p_scene);
    rmdir(dir);
}

/* The repository's Cornell box loads as the lecture describes it. */
static void cornell_scene(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err = {0};
    if (scene_load(RR_SOURCE_DIR "/scenes/cornell.json", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_string_equal(s->name, "cornell");
    assert_int_equal(s->view.width, 255);
    assert_int_equal(s->nmaterials, 4);
    assert_int_equal(s->nobjects, 8);
    assert_int_equal(s->ntris, 6 * 2 + 2 * 10);
    assert_int_equal(s->nemissive, 2);
    assert_int_equal(s->settings.spp, 4);
    /* Floor faces up, into the box. */
    assert_v3(scene_tri_normal(s, s->objects[0].tri_first), 0, 1, 0);
    scene_destroy(s);
}

/* The complete example in notes/scene-format.md is a valid scene. */
static void documented_example(void **state)
{
    (void)state;
    char *doc = NULL;
    rr_error err = {0};
    if (rr_file_read_all(RR_SOURCE_DIR "/notes/scene-format.md", &doc, NULL, &err) != RR_OK)
        fail_msg("%s", err.msg);
    const char *h = strstr(doc, "## Complete example");
    assert_non_null(h);
    const char *start = strstr(h, "```json\n");
    assert_non_null(start);
    start += 8;
    const char *end = strstr(start, "```");
    assert_non_null(end);
    char *json = strndup(start, (size_t)(end - start));
    assert_non_null(json);
    scene *s = NULL;
    if (scene_load_string(json, "example.json", RR_TEST_DATA "/scenes", NULL, &s, &err) != RR_OK)
        fail_msg("the documented example does not load: %s", err.msg);
    assert_int_equal(s->nobjects, 6);
    assert_string_equal(s->name, "example");
    assert_int_equal(s->view.width, 321);
    assert_int_equal(s->view.height, 241);
    static const int cull[6] = {0, 0, 1, 0, 0, 1}; /* quad, quad, box, mirror sphere, cull:false, closed mesh */
    for (size_t i = 0; i < 6; i++)
        assert_int_equal(s->objects[i].cull_backfaces, cull[i]);
    assert_int_equal(s->nemissive, 2);
    assert_int_equal(s->nlights, 2);
    scene_destroy(s);
    free(json);
    free(doc);
}

/* The "radiosity" block: defaults, every key, and its bad values. */
static void radiosity_block(void **state)
{
    (void)state;
    const char *head = "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
                       "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},\"materials\":{\"m\":{}},\"objects\":[{\"type\":"
                       "\"quad\",\"material\":\"m\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]";
    char text[1024];
    scene *s = NULL;
    rr_error err;
    snprintf(text, sizeof text, "%s}", head);
    assert_int_equal(scene_load_string(text, "r.json", "", NULL, &s, &err), RR_OK);
    assert_true(s->radiosity.patch_area == 0 && s->radiosity.ff_samples == 512);
    assert_int_equal(s->radiosity.solver, SCENE_RAD_AUTO);
    scene_destroy(s);
    snprintf(text, sizeof text,
             "%s,\"radiosity\":{\"patch_area\":0.01,\"patch_edge\":0.2,\"solver\":\"direct\","
             "\"form_factors\":\"quadrature\",\"ff_samples\":64,\"tolerance\":1e-7}}",
             head);
    assert_int_equal(scene_load_string(text, "r.json", "", NULL, &s, &err), RR_OK);
    assert_true(s->radiosity.patch_area == 0.01 && s->radiosity.patch_edge == 0.2);
    assert_int_equal(s->radiosity.solver, SCENE_RAD_DIRECT);
    assert_int_equal(s->radiosity.form_factors, SCENE_FF_QUADRATURE);
    assert_int_equal(s->radiosity.ff_samples, 64);
    scene_destroy(s);
    static const struct {
        const char *block, *want;
    } bad[] = {
        {"{\"solver\":\"cg\"}", "r.json: radiosity.solver: expected one of auto, direct, iterative (got \"cg\")"},
        {"{\"patch_area\":-1}", "r.json: radiosity.patch_area"},
        {"{\"ff_samples\":0}", "r.json: radiosity.ff_samples"},
        {"{\"form_factors\":3}", "r.json: radiosity.form_factors: expected a string"},
        {"{\"patches\":3}", "r.json: radiosity: unknown key 'patches'"},
        {"[]", "r.json: radiosity: expected an object"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(text, sizeof text, "%s,\"radiosity\":%s}", head, bad[i].block);
        s = NULL;
        assert_int_not_equal(scene_load_string(text, "r.json", "", NULL, &s, &err), RR_OK);
        assert_null(s);
        if (!strstr(err.msg, bad[i].want))
            fail_msg("case %zu: '%s' does not contain '%s'", i, err.msg, bad[i].want);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(radiosity_block),
        cmocka_unit_test(complete_scene),
        cmocka_unit_test(lookat_camera),
        cmocka_unit_test(defaults),
        cmocka_unit_test(transform_vertices),
        cmocka_unit_test(negative_determinant_flips_winding),
        cmocka_unit_test(box_outward),
        cmocka_unit_test(cull_auto),
        cmocka_unit_test(zero_area_triangles),
        cmocka_unit_test(overrides_good),
        cmocka_unit_test(overrides_bad),
        cmocka_unit_test(invalid_json),
        cmocka_unit_test(bad_inputs),
        cmocka_unit_test(resolution_limits),
        cmocka_unit_test(missing_scene_file),
        cmocka_unit_test(mesh_from_file),
        cmocka_unit_test(normals_mixed),
        cmocka_unit_test(bad_mesh_files),
        cmocka_unit_test(cornell_scene),
        cmocka_unit_test(documented_example),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
