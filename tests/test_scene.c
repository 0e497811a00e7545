/* test_scene.c - scene loader on good input: the radray-scene/1 format, its
 * defaults, transforms, culling rule and overrides. (Bad input:
 * test_scene_errors.c.) */
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
#include "test_scene_util.h"
#include "test_scenes.h"

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
    scene *s = test_doc_scene("## Complete example", "example.json");
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
    assert_true(s->radiosity.relative_tolerance == 0.0); /* off */
    assert_true(s->radiosity.receiving_clusters == 0.0);  /* automatic */
    assert_int_equal(s->radiosity.solver, SCENE_RAD_AUTO);
    scene_destroy(s);
    snprintf(text, sizeof text, "%s,\"radiosity\":{\"receiving_clusters\":0}}", head);
    assert_int_equal(scene_load_string(text, "r.json", "", NULL, &s, &err), RR_OK);
    assert_true(s->radiosity.receiving_clusters < 0.0); /* never */
    scene_destroy(s);
    snprintf(text, sizeof text,
             "%s,\"radiosity\":{\"patch_area\":0.01,\"patch_edge\":0.2,\"solver\":\"direct\","
             "\"form_factors\":\"quadrature\",\"ff_samples\":64,\"tolerance\":1e-7,\"relative_tolerance\":0.05,\"receiving_clusters\":1.5}}",
             head);
    assert_int_equal(scene_load_string(text, "r.json", "", NULL, &s, &err), RR_OK);
    assert_true(s->radiosity.patch_area == 0.01 && s->radiosity.patch_edge == 0.2);
    assert_int_equal(s->radiosity.solver, SCENE_RAD_DIRECT);
    assert_int_equal(s->radiosity.form_factors, SCENE_FF_QUADRATURE);
    assert_int_equal(s->radiosity.ff_samples, 64);
    assert_true(s->radiosity.relative_tolerance == 0.05);
    assert_true(s->radiosity.receiving_clusters == 1.5);
    scene_destroy(s);
    static const struct {
        const char *block, *want;
    } bad[] = {
        {"{\"solver\":\"cg\"}", "r.json: radiosity.solver: expected one of auto, direct, iterative (got \"cg\")"},
        {"{\"patch_area\":-1}", "r.json: radiosity.patch_area"},
        {"{\"ff_samples\":0}", "r.json: radiosity.ff_samples"},
        {"{\"form_factors\":3}", "r.json: radiosity.form_factors: expected a string"},
        {"{\"patches\":3}", "r.json: radiosity: unknown key 'patches'"},
        {"{\"relative_tolerance\":-0.1}", "r.json: radiosity.relative_tolerance"},
        {"{\"relative_tolerance\":2}", "r.json: radiosity.relative_tolerance"},
        {"{\"receiving_clusters\":-1}", "r.json: radiosity.receiving_clusters"},
        {"{\"receiving_clusters\":true}", "r.json: radiosity.receiving_clusters"},
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


/* "camera_path": frames on the keys are the keys' lookat views exactly;
 * between them the eye moves smoothly (the middle of a straight two-key
 * path is its midpoint, the Hermite spline of collinear keys being the
 * line); bad paths are refused with their JSON path. */
static void camera_path_views(void **state)
{
    (void)state;
    const char *head = "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 5], "
                       "\"target\": [0, 1, 0], \"up\": [0, 1, 0], \"fov\": 40, \"width\": 8, \"height\": 6}, "
                       "\"materials\": {\"m\": {}}, \"objects\": [{\"type\": \"sphere\", \"material\": \"m\", "
                       "\"center\": [0, 1, 0], \"radius\": 1}], \"camera_path\": ";
    char json[2048];
    snprintf(json, sizeof json, "%s{\"frames\": 9, \"keys\": [{\"frame\": 1, \"eye\": [0, 1, 5], \"target\": [0, 1, 0], "
             "\"fov\": 40}, {\"frame\": 9, \"eye\": [4, 1, 5], \"target\": [0, 1, 0], \"fov\": 60}]}}", head);
    scene *s = load_ok(json, NULL);
    assert_int_equal(s->path_frames, 9);
    rr_view v, k;
    rr_error err;
    assert_int_equal(scene_path_view(s, 9, &v, &err), RR_OK);
    assert_int_equal(rr_view_lookat(rr_v3(4, 1, 5), rr_v3(0, 1, 0), rr_v3(0, 1, 0), 60, 8, 6, &k, &err), RR_OK);
    assert_true(rr_v3_len(rr_v3_sub(v.E, k.E)) < 1e-12 && rr_v3_len(rr_v3_sub(v.O, k.O)) < 1e-12);
    assert_int_equal(scene_path_view(s, 5, &v, &err), RR_OK);
    assert_true(fabs(v.E.x - 2) < 1e-12 && fabs(v.E.z - 5) < 1e-12); /* the midpoint, fov 50 */
    assert_int_equal(scene_path_view(s, 10, &v, &err), RR_ERR_INVALID);
    scene_destroy(s);
    snprintf(json, sizeof json, "%s{\"frames\": 9, \"keys\": [{\"frame\": 5, \"eye\": [0, 1, 5], \"target\": [0, 1, 0], "
             "\"fov\": 40}, {\"frame\": 3, \"eye\": [4, 1, 5], \"target\": [0, 1, 0], \"fov\": 60}]}}", head);
    expect_fail(json, RR_ERR_INVALID, "bad.json: camera_path.keys[1]: frame 3 does not come after the key before it (5)");
    snprintf(json, sizeof json, "%s{\"frames\": 4, \"keys\": [{\"frame\": 5, \"eye\": [0, 1, 5], \"target\": [0, 1, 0], "
             "\"fov\": 40}]}}", head);
    expect_fail(json, RR_ERR_INVALID, "bad.json: camera_path.keys[0].frame");
    snprintf(json, sizeof json, "%s{\"frames\": 4, \"keys\": [{\"frame\": 1, \"eye\": [0, 1, 0], \"target\": [0, 1, 0], "
             "\"fov\": 40}]}}", head);
    expect_fail(json, RR_ERR_INVALID, "bad.json: camera_path.keys[0]: eye and target are the same point");
    snprintf(json, sizeof json, "%s{\"frames\": 4}}", head);
    expect_fail(json, RR_ERR_INVALID, "bad.json: camera_path.keys: missing");
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
        cmocka_unit_test(mesh_from_file),
        cmocka_unit_test(normals_mixed),
        cmocka_unit_test(cornell_scene),
        cmocka_unit_test(documented_example),
        cmocka_unit_test(camera_path_views),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
