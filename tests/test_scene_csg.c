/* test_scene_csg.c - solids in the scene format: "quadric" objects and "csg"
 * trees (notes/scene-format.md, "Solids"; the contract in scene.h). Good
 * input: each quadric shape's Q and clip box, transforms composed down the
 * tree, material inheritance, the left fold, bounds pruning, mesh leaves,
 * culling; bad input: every error names the file, the JSON path and what is
 * wrong. */
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

/* x^T Q x with x = (p, 1). */
static double qform(const double q[4][4], rr_vec3 p)
{
    double x[4] = {p.x, p.y, p.z, 1}, r = 0;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            r += x[i] * q[i][j] * x[j];
    return r;
}

static void assert_sym(const double q[4][4])
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            assert_true(q[i][j] == q[j][i]);
}

/* One object in the default scene. */
static scene *load_obj(const char *obj, const scene_load_opts *opts)
{
    char objs[8192];
    snprintf(objs, sizeof objs, "[%s]", obj);
    return load_ok(make_scene(NULL, NULL, "", objs, ""), opts);
}

static const scene_csg_node *root_of(const scene *s, size_t oi)
{
    assert_int_equal(s->objects[oi].kind, SCENE_OBJ_CSG);
    assert_true(s->objects[oi].csg_root < s->ncsg);
    return &s->csg[s->objects[oi].csg_root];
}

/* A point inside (sign < 0) or outside (sign > 0) a quadric leaf, tested in
 * its local frame. */
static void assert_q(const scene_csg_node *n, rr_vec3 local, int sign)
{
    double v = qform(n->q, local);
    if (!(sign < 0 ? v < 0 : v > 0))
        fail_msg("%s: x^T Q x = %g at (%g, %g, %g), expected %s", n->name, v, local.x, local.y, local.z,
                 sign < 0 ? "< 0 (inside)" : "> 0 (outside)");
}

/* ---- good input ---- */

static void quadric_shapes(void **state)
{
    (void)state;
    scene *s = load_obj("{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[1,2,3],\"material\":\"red\"}", NULL);
    const scene_csg_node *n = root_of(s, 0);
    assert_int_equal(s->ncsg, 1);
    assert_int_equal(n->op, SCENE_CSG_LEAF);
    assert_int_equal(n->solid, SCENE_SOLID_QUADRIC);
    assert_int_equal(n->shape, SCENE_QUADRIC_ELLIPSOID);
    assert_int_equal(n->material, 1);
    assert_int_equal(n->object, 0);
    assert_string_equal(n->name, "objects[0]");
    assert_sym(n->q);
    assert_near(n->q[0][0], 1, 1e-15);
    assert_near(n->q[1][1], 0.25, 1e-15);
    assert_near(n->q[2][2], 1.0 / 9, 1e-15);
    assert_near(n->q[3][3], -1, 1e-15);
    assert_q(n, rr_v3(0.9, 0, 0), -1);
    assert_q(n, rr_v3(0, 1.9, 0), -1);
    assert_q(n, rr_v3(0, 0, 3.1), 1);
    assert_q(n, rr_v3(0.8, 1.5, 0), 1); /* 0.64 + 0.5625 > 1 */
    assert_v3(n->clip_lo, -1, -2, -3);
    assert_v3(n->clip_hi, 1, 2, 3);
    assert_v3(n->bbox_lo, -1, -2, -3);
    assert_v3(n->bbox_hi, 1, 2, 3);
    assert_v3(s->bbox_min, -1, -2, -3); /* the solid is the only object */
    assert_v3(s->bbox_max, 1, 2, 3);
    assert_int_equal(s->objects[0].cull_backfaces, 1);
    scene_destroy(s);

    s = load_obj("{\"type\":\"quadric\",\"shape\":\"cylinder\",\"radius\":1,\"height\":2,\"material\":\"white\"}", NULL);
    n = root_of(s, 0);
    assert_int_equal(n->shape, SCENE_QUADRIC_CYLINDER);
    assert_sym(n->q);
    assert_q(n, rr_v3(0.5, 0.9, 0.5), -1);
    assert_q(n, rr_v3(0, 100, 0.99), -1); /* infinite along y: the clip box ends it */
    assert_q(n, rr_v3(1.1, 0, 0), 1);
    assert_q(n, rr_v3(0.75, 0, 0.75), 1);
    assert_v3(n->clip_lo, -1, -1, -1);
    assert_v3(n->clip_hi, 1, 1, 1);
    scene_destroy(s);

    s = load_obj("{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":2,\"material\":\"white\"}", NULL);
    n = root_of(s, 0);
    assert_int_equal(n->shape, SCENE_QUADRIC_CONE);
    assert_sym(n->q);
    assert_q(n, rr_v3(0, 1, 0.4), -1); /* radius at y = 1 is 0.5 */
    assert_q(n, rr_v3(0, 1, 0.6), 1);
    assert_q(n, rr_v3(0.99, 2, 0), -1);
    assert_near(qform(n->q, rr_v3(0, 0, 0)), 0, 0); /* apex */
    assert_v3(n->clip_lo, -1, 0, -1);
    assert_v3(n->clip_hi, 1, 2, 1);
    scene_destroy(s);

    s = load_obj("{\"type\":\"quadric\",\"shape\":\"paraboloid\",\"radius\":1,\"height\":2,\"material\":\"white\"}",
                 NULL);
    n = root_of(s, 0);
    assert_int_equal(n->shape, SCENE_QUADRIC_PARABOLOID);
    assert_sym(n->q);
    assert_q(n, rr_v3(0.5, 1, 0), -1); /* 0.25 - 0.5 */
    assert_q(n, rr_v3(0.8, 1, 0), 1);  /* 0.64 - 0.5 */
    assert_q(n, rr_v3(0, -0.1, 0), 1); /* below the vertex */
    assert_near(qform(n->q, rr_v3(1, 2, 0)), 0, 1e-15); /* the rim: radius 1 at height 2 */
    assert_v3(n->clip_lo, -1, 0, -1);
    assert_v3(n->clip_hi, 1, 2, 1);
    scene_destroy(s);

    s = load_obj("{\"type\":\"quadric\",\"shape\":\"hyperboloid\",\"radius\":1,\"end_radius\":2,\"height\":2,"
                 "\"material\":\"white\"}",
                 NULL);
    n = root_of(s, 0);
    assert_int_equal(n->shape, SCENE_QUADRIC_HYPERBOLOID);
    assert_sym(n->q);
    assert_q(n, rr_v3(0.9, 0, 0), -1);
    assert_q(n, rr_v3(1.1, 0, 0), 1);
    assert_q(n, rr_v3(0, 1, 1.9), -1);
    assert_q(n, rr_v3(0, -1, 1.9), -1);
    assert_near(qform(n->q, rr_v3(2, 1, 0)), 0, 1e-12); /* end radius at y = h/2 */
    assert_v3(n->clip_lo, -2, -1, -2);
    assert_v3(n->clip_hi, 2, 1, 2);
    scene_destroy(s);

    /* general: a unit sphere written out, clipped to its upper half */
    s = load_obj("{\"type\":\"quadric\",\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]],"
                 "\"clip\":{\"min\":[-1,0,-1],\"max\":[1,1,1]},\"material\":\"white\"}",
                 NULL);
    n = root_of(s, 0);
    assert_int_equal(n->shape, SCENE_QUADRIC_GENERAL);
    assert_q(n, rr_v3(0.5, 0.5, 0.5), -1);
    assert_q(n, rr_v3(0.7, 0.7, 0.7), 1);
    assert_v3(n->clip_lo, -1, 0, -1);
    assert_v3(n->bbox_lo, -1, 0, -1);
    assert_v3(n->bbox_hi, 1, 1, 1);
    scene_destroy(s);

    /* a general q symmetric only up to rounding is made exactly symmetric */
    s = load_obj("{\"type\":\"quadric\",\"shape\":\"general\",\"q\":[[1,0.5,0,0],[0.5000000000000001,1,0,0],"
                 "[0,0,1,0],[0,0,0,-1]],\"clip\":{\"min\":[-2,-2,-2],\"max\":[2,2,2]},\"material\":\"white\"}",
                 NULL);
    assert_sym(root_of(s, 0)->q);
    scene_destroy(s);
}

/* The object's transform: to_world maps the canonical frame into the world,
 * to_local is its inverse; world points test inside through to_local. */
static void quadric_transform(void **state)
{
    (void)state;
    scene *s = load_obj("{\"type\":\"quadric\",\"shape\":\"cylinder\",\"radius\":1,\"height\":2,\"material\":\"white\","
                        "\"transform\":[{\"scale\":[2,1,1]},{\"rotate\":{\"axis\":[0,0,1],\"degrees\":90}},"
                        "{\"translate\":[0,5,0]}]}",
                        NULL);
    const scene_csg_node *n = root_of(s, 0);
    /* scale x by 2, then rotate x -> y, then move up 5: the axis (y) lies along -x */
    assert_v3(rr_xform_point(&n->to_world, rr_v3(1, 0, 0)), 0, 7, 0);
    assert_v3(rr_xform_point(&n->to_world, rr_v3(0, 1, 0)), -1, 5, 0);
    for (int i = 0; i < 5; i++) {
        rr_vec3 p = rr_v3(0.3 * i - 0.7, 0.2 * i, 1.1 - 0.4 * i);
        rr_vec3 back = rr_xform_point(&n->to_local, rr_xform_point(&n->to_world, p));
        assert_near(back.x, p.x, 1e-12);
        assert_near(back.y, p.y, 1e-12);
        assert_near(back.z, p.z, 1e-12);
    }
    /* world (0.9, 5, 0) is 0.9 along the axis, on the axis: inside; world
     * (0, 6.9, 0) is 1.9 from the axis (radius 2 after the scale) */
    assert_q(n, rr_xform_point(&n->to_local, rr_v3(0.9, 5, 0)), -1);
    assert_q(n, rr_xform_point(&n->to_local, rr_v3(0, 6.9, 0)), -1);
    assert_q(n, rr_xform_point(&n->to_local, rr_v3(0, 7.1, 0)), 1);
    assert_q(n, rr_xform_point(&n->to_local, rr_v3(0, 5, 1.1)), 1);
    /* bounds: local [-1,1]^3 scaled to x in [-2,2], then rotated and moved */
    assert_v3(n->bbox_lo, -1, 3, -1);
    assert_v3(n->bbox_hi, 1, 7, 1);
    assert_v3(s->bbox_max, 1, 7, 1);
    scene_destroy(s);
}

/* Transforms compose down the tree: the leaf's own first, then each parent's
 * up to the object's. */
static void nested_transforms(void **state)
{
    (void)state;
    scene *s = load_obj(
        "{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"transform\":[{\"translate\":[10,0,0]}],"
        "\"children\":["
        " {\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]},"
        " {\"type\":\"csg\",\"op\":\"intersection\",\"transform\":[{\"scale\":2}],\"children\":["
        "   {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"transform\":[{\"translate\":[1,0,0]}]},"
        "   {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"transform\":[{\"scale\":[1,3,1]}]}]}]}",
        NULL);
    assert_int_equal(s->ncsg, 5);
    const scene_csg_node *root = root_of(s, 0);
    assert_int_equal(root->op, SCENE_CSG_UNION);
    const scene_csg_node *box = &s->csg[root->left], *inter = &s->csg[root->right];
    assert_string_equal(box->name, "objects[0].children[0]");
    assert_string_equal(inter->name, "objects[0].children[1]");
    assert_int_equal(box->solid, SCENE_SOLID_BOX);
    assert_v3(rr_xform_point(&box->to_world, rr_v3(1, 1, 1)), 11, 1, 1);
    assert_int_equal(inter->op, SCENE_CSG_INTERSECTION);
    const scene_csg_node *a = &s->csg[inter->left], *b = &s->csg[inter->right];
    assert_string_equal(a->name, "objects[0].children[1].children[0]");
    /* a: translate (1,0,0), then scale 2, then translate (10,0,0):
     * p -> 2 (p + (1,0,0)) + (10,0,0); the other order would give 12 + ... */
    assert_v3(rr_xform_point(&a->to_world, rr_v3(0, 0, 0)), 12, 0, 0);
    assert_v3(rr_xform_point(&a->to_world, rr_v3(1, 1, 0)), 14, 2, 0);
    assert_v3(rr_xform_point(&a->to_local, rr_v3(14, 2, 0)), 1, 1, 0);
    assert_int_equal(a->solid, SCENE_SOLID_SPHERE);
    assert_v3(a->center, 0, 0, 0);
    assert_near(a->radius, 1, 0);
    /* b: a non-uniformly scaled sphere stays a sphere in its local frame */
    assert_int_equal(b->solid, SCENE_SOLID_SPHERE);
    assert_v3(rr_xform_point(&b->to_world, rr_v3(0, 1, 0)), 10, 6, 0);
    /* bounds: a is [10,14]x[-2,2]x[-2,2], b is [8,12]x[-6,6]x[-2,2]; their
     * overlap, then the union with the box [10,11]x[0,1]x[0,1] */
    assert_v3(a->bbox_lo, 10, -2, -2);
    assert_v3(a->bbox_hi, 14, 2, 2);
    assert_v3(b->bbox_lo, 8, -6, -2);
    assert_v3(inter->bbox_lo, 10, -2, -2);
    assert_v3(inter->bbox_hi, 12, 2, 2);
    assert_v3(root->bbox_lo, 10, -2, -2);
    assert_v3(root->bbox_hi, 12, 2, 2);
    for (size_t i = 0; i < s->ncsg; i++)
        assert_int_equal(s->csg[i].object, 0);
    /* inner nodes hold no transform of their own */
    assert_v3(rr_xform_point(&inter->to_world, rr_v3(1, 2, 3)), 1, 2, 3);
    scene_destroy(s);
}

static void material_inheritance(void **state)
{
    (void)state;
    scene *s = load_obj("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"red\",\"children\":["
                        " {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
                        " {\"type\":\"csg\",\"op\":\"union\",\"material\":\"green\",\"children\":["
                        "   {\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]},"
                        "   {\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1],\"material\":\"white\"}]}]}",
                        NULL);
    const scene_csg_node *root = root_of(s, 0);
    assert_int_equal(s->objects[0].material, 1); /* red */
    assert_int_equal(s->csg[root->left].material, 1);
    const scene_csg_node *in = &s->csg[root->right];
    assert_int_equal(in->material, 2); /* green */
    assert_int_equal(s->csg[in->left].material, 2);
    assert_int_equal(s->csg[in->right].material, 0); /* white */
    assert_int_equal(s->objects[0].cull_backfaces, 1);
    scene_destroy(s);

    /* "auto" culling: not when the object or any leaf is a mirror */
    s = load_obj("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"red\",\"children\":["
                 " {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"material\":\"chrome\"},"
                 " {\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]}]}",
                 NULL);
    assert_int_equal(s->objects[0].cull_backfaces, 0);
    scene_destroy(s);
    s = load_obj("{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":1,\"material\":\"chrome\"}", NULL);
    assert_int_equal(s->objects[0].cull_backfaces, 0);
    scene_destroy(s);
    s = load_obj("{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":1,\"material\":\"white\","
                 "\"cull\":false,\"name\":\"funnel\"}",
                 NULL);
    assert_int_equal(s->objects[0].cull_backfaces, 0);
    assert_string_equal(s->objects[0].name, "funnel");
    scene_destroy(s);
}

/* n-ary children fold left: difference [a, b, c, d] = ((a - b) - c) - d. */
static void fold_left(void **state)
{
    (void)state;
    scene *s = load_obj("{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"white\",\"children\":["
                        " {\"type\":\"box\",\"min\":[0,0,0],\"max\":[4,4,4]},"
                        " {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
                        " {\"type\":\"sphere\",\"center\":[4,0,0],\"radius\":1},"
                        " {\"type\":\"sphere\",\"center\":[9,9,9],\"radius\":1}]}",
                        NULL);
    assert_int_equal(s->ncsg, 7);
    const scene_csg_node *n3 = root_of(s, 0);
    assert_string_equal(n3->name, "objects[0]");
    assert_int_equal(n3->op, SCENE_CSG_DIFFERENCE);
    assert_string_equal(s->csg[n3->right].name, "objects[0].children[3]");
    const scene_csg_node *n2 = &s->csg[n3->left];
    assert_int_equal(n2->op, SCENE_CSG_DIFFERENCE);
    assert_string_equal(n2->name, "objects[0].children[0..2]");
    assert_string_equal(s->csg[n2->right].name, "objects[0].children[2]");
    const scene_csg_node *n1 = &s->csg[n2->left];
    assert_int_equal(n1->op, SCENE_CSG_DIFFERENCE);
    assert_string_equal(n1->name, "objects[0].children[0..1]");
    assert_string_equal(s->csg[n1->left].name, "objects[0].children[0]");
    assert_string_equal(s->csg[n1->right].name, "objects[0].children[1]");
    assert_v3(s->csg[s->csg[n1->right].left].bbox_lo, 0, 0, 0); /* leaves' left is 0: no crash, no meaning */
    /* difference keeps the left child's bounds, however far the others reach */
    assert_v3(n3->bbox_lo, 0, 0, 0);
    assert_v3(n3->bbox_hi, 4, 4, 4);
    assert_v3(s->bbox_max, 4, 4, 4);
    scene_destroy(s);
}

static void bounds_pruning(void **state)
{
    (void)state;
    const char *fmt = "{\"type\":\"csg\",\"op\":\"%s\",\"material\":\"white\",\"children\":["
                      " {\"type\":\"box\",\"min\":[0,0,0],\"max\":[2,2,2]},"
                      " {\"type\":\"box\",\"min\":[1,1,1],\"max\":[3,3,3]}]}";
    char obj[1024];
    snprintf(obj, sizeof obj, fmt, "intersection");
    scene *s = load_obj(obj, NULL);
    assert_v3(root_of(s, 0)->bbox_lo, 1, 1, 1);
    assert_v3(root_of(s, 0)->bbox_hi, 2, 2, 2);
    scene_destroy(s);
    snprintf(obj, sizeof obj, fmt, "union");
    s = load_obj(obj, NULL);
    assert_v3(root_of(s, 0)->bbox_lo, 0, 0, 0);
    assert_v3(root_of(s, 0)->bbox_hi, 3, 3, 3);
    assert_v3(s->bbox_max, 3, 3, 3);
    scene_destroy(s);
    snprintf(obj, sizeof obj, fmt, "difference");
    s = load_obj(obj, NULL);
    assert_v3(root_of(s, 0)->bbox_hi, 2, 2, 2);
    scene_destroy(s);

    /* An intersection of disjoint parts is empty: a warning, finite bounds
     * with lo > hi, and the scene's bounds are those of the rest. A union
     * with an empty part is the other part. */
    warn_log w = {0};
    scene_load_opts opts = {0};
    opts.warn.fn = warn_fn;
    opts.warn.user = &w;
    s = load_obj(QUAD("white") "},{\"type\":\"csg\",\"op\":\"intersection\",\"material\":\"white\","
                 "\"children\":[{\"type\":\"box\",\"min\":[10,10,10],\"max\":[11,11,11]},"
                 " {\"type\":\"sphere\",\"center\":[20,10,10],\"radius\":1}]}",
                 &opts);
    assert_int_equal(w.count, 1);
    assert_non_null(strstr(w.last, "t.json: objects[1]: the solid is empty"));
    const scene_csg_node *r = root_of(s, 1);
    assert_true(r->bbox_lo.x > r->bbox_hi.x);
    assert_true(rr_v3_isfinite(r->bbox_lo) && rr_v3_isfinite(r->bbox_hi));
    assert_v3(s->bbox_min, 0, 0, 0); /* the quad of the default scene only */
    assert_v3(s->bbox_max, 1, 1, 0);
    scene_destroy(s);

    w.count = 0;
    s = load_obj("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":["
                 " {\"type\":\"csg\",\"op\":\"intersection\",\"children\":["
                 "   {\"type\":\"box\",\"min\":[10,10,10],\"max\":[11,11,11]},"
                 "   {\"type\":\"box\",\"min\":[20,10,10],\"max\":[21,11,11]}]},"
                 " {\"type\":\"box\",\"min\":[-1,-2,-3],\"max\":[0,0,0]}]}",
                 &opts);
    assert_int_equal(w.count, 0);
    assert_v3(root_of(s, 0)->bbox_lo, -1, -2, -3);
    assert_v3(root_of(s, 0)->bbox_hi, 0, 0, 0);
    scene_destroy(s);
}

/* Several solid objects: nodes of each object are contiguous, roots last. */
static void several_objects(void **state)
{
    (void)state;
    char objs[4096];
    snprintf(objs, sizeof objs,
             "[" QUAD("white") "},"
             "{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[1,1,1],\"material\":\"white\"},"
             "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"material\":\"white\"},"
             "{\"type\":\"csg\",\"op\":\"union\",\"material\":\"green\",\"children\":["
             " {\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]},{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,5]}]}]");
    scene *s = load_ok(make_scene(NULL, NULL, "", objs, ""), NULL);
    assert_int_equal(s->nobjects, 4);
    assert_int_equal(s->ncsg, 4);
    assert_int_equal(s->objects[1].csg_root, 0);
    assert_int_equal(s->objects[3].csg_root, 3);
    assert_int_equal(s->csg[1].object, 3);
    assert_int_equal(s->objects[2].kind, SCENE_OBJ_SPHERE);
    assert_int_equal(s->objects[1].tri_count, 0);
    assert_true(s->objects[3].report.watertight && s->objects[3].report.consistently_oriented);
    assert_v3(s->bbox_max, 1, 1, 5);
    scene_destroy(s);
}

/* ---- mesh leaves ---- */

static char g_dir[64];

static void write_file(const char *name, const char *text)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

#define CUBE_V "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"

static int make_meshes(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/radray-csg-XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    /* the unit cube of tests/data/meshes/cube_quads.obj ... */
    write_file("cube.obj", CUBE_V "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
    /* ... without its top face (4 boundary edges) */
    write_file("open.obj", CUBE_V "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 4 1 5 8\n");
    /* ... wound inwards */
    write_file("inward.obj", CUBE_V "f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n");
    /* ... with one face turned over (its 4 edges misoriented) */
    write_file("turned.obj", CUBE_V "f 1 4 3 2\nf 5 8 7 6\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
    /* ... with an extra fin on an edge (non-manifold) */
    write_file("fin.obj", CUBE_V "v 0.5 -1 -1\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
                                 "f 1 2 9\nf 2 1 9\n");
    /* a closed surface around no volume: two triangles back to back */
    write_file("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n");
    return 0;
}

static int remove_meshes(void **state)
{
    (void)state;
    static const char *const names[] = {"cube.obj", "open.obj", "inward.obj", "turned.obj", "fin.obj", "flat.obj"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char path[256];
        snprintf(path, sizeof path, "%s/%s", g_dir, names[i]);
        unlink(path);
    }
    rmdir(g_dir);
    return 0;
}

static scene *load_dir(const char *obj, const char *dir)
{
    char objs[8192];
    snprintf(objs, sizeof objs, "[%s]", obj);
    scene *s = NULL;
    rr_error err = {0};
    if (scene_load_string(make_scene(NULL, NULL, "", objs, ""), "m.json", dir, NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

static void mesh_leaf(void **state)
{
    (void)state;
    /* A cube mesh minus a sphere, moved: the mesh leaf lives in world space. */
    scene *s = load_dir("{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"white\","
                        "\"transform\":[{\"translate\":[0,0,10]}],\"children\":["
                        " {\"type\":\"mesh\",\"file\":\"cube.obj\",\"transform\":[{\"scale\":2}]},"
                        " {\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1}]}",
                        g_dir);
    const scene_csg_node *root = root_of(s, 0);
    const scene_csg_node *m = &s->csg[root->left];
    assert_int_equal(m->solid, SCENE_SOLID_MESH);
    assert_int_equal(m->tri_first, 0);
    assert_int_equal(m->tri_count, 12);
    assert_int_equal(s->ncsg_tris, 12);
    assert_int_equal(s->ncsg_verts, 8);
    assert_v3(rr_xform_point(&m->to_world, rr_v3(1, 2, 3)), 1, 2, 3); /* identity */
    assert_v3(rr_xform_point(&m->to_local, rr_v3(1, 2, 3)), 1, 2, 3);
    assert_v3(m->bbox_lo, 0, 0, 10);
    assert_v3(m->bbox_hi, 2, 2, 12);
    assert_v3(root->bbox_hi, 2, 2, 12);
    /* vertices in world space, every triangle counter-clockwise from outside:
     * its normal points away from the cube's centre */
    rr_vec3 centre = rr_v3(1, 1, 11);
    double vol = 0;
    for (size_t t = 0; t < s->ncsg_tris; t++) {
        const uint32_t *v = s->csg_tris[t];
        assert_true(v[0] < s->ncsg_verts && v[1] < s->ncsg_verts && v[2] < s->ncsg_verts);
        rr_vec3 a = s->csg_verts[v[0]], b = s->csg_verts[v[1]], c = s->csg_verts[v[2]];
        rr_vec3 n = rr_v3_cross(rr_v3_sub(b, a), rr_v3_sub(c, a));
        assert_true(rr_v3_dot(n, rr_v3_sub(a, centre)) > 0);
        vol += rr_v3_dot(a, rr_v3_cross(b, c)) / 6;
    }
    assert_near(vol, 8, 1e-9);
    assert_int_equal(s->ntris, 0); /* a solid adds no scene triangles */
    assert_int_equal(s->objects[0].cull_backfaces, 1);
    scene_destroy(s);

    /* A mirroring transform keeps the faces outward (the winding is reversed
     * as for mesh objects); "flip" turns an inward mesh right. */
    s = load_dir("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":["
                 " {\"type\":\"mesh\",\"file\":\"cube.obj\",\"transform\":[{\"scale\":[-1,1,1]}]},"
                 " {\"type\":\"mesh\",\"file\":\"inward.obj\",\"flip\":true,\"transform\":[{\"translate\":[5,0,0]}]}]}",
                 g_dir);
    root = root_of(s, 0);
    assert_int_equal(s->ncsg_tris, 24);
    assert_int_equal(s->csg[root->right].tri_first, 12);
    assert_int_equal(s->csg[root->right].tri_count, 12);
    for (int k = 0; k < 2; k++) {
        const scene_csg_node *leaf = &s->csg[k ? root->right : root->left];
        double vol2 = 0;
        for (size_t t = leaf->tri_first; t < leaf->tri_first + leaf->tri_count; t++) {
            const uint32_t *v = s->csg_tris[t];
            vol2 += rr_v3_dot(s->csg_verts[v[0]], rr_v3_cross(s->csg_verts[v[1]], s->csg_verts[v[2]])) / 6;
        }
        assert_near(vol2, 1, 1e-9);
    }
    assert_v3(root->bbox_lo, -1, 0, 0);
    assert_v3(root->bbox_hi, 6, 1, 1);
    scene_destroy(s);

    /* A file from the test data, with the scene folder's relative path. */
    s = load_obj("{\"type\":\"csg\",\"op\":\"intersection\",\"material\":\"white\",\"children\":["
                 " {\"type\":\"mesh\",\"file\":\"meshes/tetra.obj\"},"
                 " {\"type\":\"mesh\",\"file\":\"../meshes/cube_quads.obj\"}]}",
                 NULL);
    assert_int_equal(s->ncsg_tris, 4 + 12);
    assert_v3(root_of(s, 0)->bbox_hi, 1, 1, 1);
    scene_destroy(s);
}

/* The example in notes/scene-format.md ("Solids example") loads. */
static void documented_example(void **state)
{
    (void)state;
    scene *s = test_doc_scene("### Solids example", "solids.json");
    size_t nsolids = 0;
    for (size_t i = 0; i < s->nobjects; i++)
        nsolids += s->objects[i].kind == SCENE_OBJ_CSG;
    assert_true(nsolids >= 3);
    assert_true(s->ncsg_tris > 0);
    int shapes = 0;
    for (size_t i = 0; i < s->ncsg; i++)
        if (s->csg[i].op == SCENE_CSG_LEAF && s->csg[i].solid == SCENE_SOLID_QUADRIC)
            shapes |= 1 << s->csg[i].shape;
    assert_int_equal(shapes, 0x3f); /* every shape, general included */
    scene_destroy(s);
}

/* ---- bad input ---- */

static void bad_solids(void **state)
{
    (void)state;
#define Q(body) "{\"type\":\"quadric\",\"material\":\"white\"," body "}"
#define CSG(op, kids) "{\"type\":\"csg\",\"op\":\"" op "\",\"material\":\"white\",\"children\":[" kids "]}"
#define BOX "{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]}"
#define SPH "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1}"
    static const struct {
        const char *obj;
        rr_status code;
        const char *want;
    } cases[] = {
        /* quadrics */
        {Q("\"shape\":\"torus\""), RR_ERR_INVALID,
         "bad.json: objects[0].shape: unknown shape 'torus' (known: ellipsoid, cylinder, cone, paraboloid, hyperboloid, "
         "general)"},
        {Q("\"shape\":3"), RR_ERR_INVALID, "bad.json: objects[0].shape: expected one of ellipsoid"},
        {Q("\"shape\":\"cylinder\",\"height\":2"), RR_ERR_INVALID,
         "bad.json: objects[0].radius: missing (expected a number > 0)"},
        {Q("\"shape\":\"cylinder\",\"radius\":1,\"height\":-1"), RR_ERR_INVALID,
         "bad.json: objects[0].height: expected a number > 0 (got -1)"},
        {Q("\"shape\":\"cone\",\"radius\":0,\"height\":1"), RR_ERR_INVALID,
         "bad.json: objects[0].radius: expected a number > 0 (got 0)"},
        {Q("\"shape\":\"cone\",\"radius\":\"big\",\"height\":1"), RR_ERR_INVALID,
         "bad.json: objects[0].radius: expected a number (got the string \"big\")"},
        {Q("\"shape\":\"paraboloid\",\"radius\":1,\"height\":1e999"), RR_ERR_INVALID,
         "bad.json: objects[0].height: the number is out of range"},
        {Q("\"shape\":\"cylinder\",\"radius\":1,\"height\":1,\"radii\":[1,1,1]"), RR_ERR_INVALID,
         "bad.json: objects[0]: unknown key 'radii' (allowed: type, name, material, transform, cull, shape, radius, "
         "height)"},
        {Q("\"shape\":\"cylinder\",\"radius\":1e200,\"height\":1"), RR_ERR_INVALID,
         "bad.json: objects[0]: the cylinder's coefficients overflow (lengths out of range)"},
        {Q("\"shape\":\"ellipsoid\",\"radii\":[1,1e-200,1]"), RR_ERR_INVALID,
         "bad.json: objects[0].radii[1]: the radius 1e-200 is out of range"},
        {Q("\"shape\":\"general\",\"q\":[[1e308,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]],\"clip\":{\"min\":[-1,-1,-1],"
           "\"max\":[1e308,1,1]},\"transform\":[{\"scale\":10}]"),
         RR_ERR_INVALID, "bad.json: objects[0]: the transformed solid is not finite"},
        {Q("\"shape\":\"ellipsoid\",\"radii\":[1,-2,1]"), RR_ERR_INVALID,
         "bad.json: objects[0].radii[1]: expected a number > 0 (got -2)"},
        {Q("\"shape\":\"ellipsoid\",\"radii\":[1,2]"), RR_ERR_INVALID,
         "bad.json: objects[0].radii: expected an array of 3 numbers"},
        {Q("\"shape\":\"hyperboloid\",\"radius\":2,\"end_radius\":1,\"height\":1"), RR_ERR_INVALID,
         "bad.json: objects[0].end_radius: must be greater than radius"},
        {Q("\"shape\":\"general\",\"q\":[[1,2,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]],\"clip\":{\"min\":[-1,-1,-1],"
           "\"max\":[1,1,1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].q: must be symmetric: q[0][1] = 2 but q[1][0] = 0"},
        {Q("\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]]"), RR_ERR_INVALID,
         "bad.json: objects[0].clip: missing (expected a finite box"},
        {Q("\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0]],\"clip\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].q: expected a symmetric 4x4 matrix"},
        {Q("\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,null]],\"clip\":{\"min\":[-1,-1,-1],"
           "\"max\":[1,1,1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].q[3][3]: expected a number (got null)"},
        {Q("\"shape\":\"general\",\"q\":[[0,0,0,0],[0,0,0,0],[0,0,0,0],[0,0,0,-1]],\"clip\":{\"min\":[-1,-1,-1],"
           "\"max\":[1,1,1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].q: has no x, y or z terms"},
        {Q("\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]],\"clip\":{\"min\":[-1,-1,-1],"
           "\"max\":[1,-2,1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].clip.max: must be greater than min on every axis"},
        {Q("\"shape\":\"general\",\"q\":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,-1]],\"clip\":{\"lo\":[-1,-1,-1]}"),
         RR_ERR_INVALID, "bad.json: objects[0].clip: unknown key 'lo' (allowed: min, max)"},
        {Q("\"shape\":\"ellipsoid\",\"radii\":[1,1,1],\"transform\":[{\"scale\":[1,0,1]}]"), RR_ERR_INVALID,
         "bad.json: objects[0].transform[0].scale: a zero scale flattens the object"},
        /* csg structure */
        {CSG("xor", BOX "," SPH), RR_ERR_INVALID,
         "bad.json: objects[0].op: unknown op 'xor' (known: union, intersection, difference)"},
        {CSG("union", BOX), RR_ERR_INVALID,
         "bad.json: objects[0].children: expected at least 2 children (got 1): a csg combines two or more solids"},
        {"{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":{}}", RR_ERR_INVALID,
         "bad.json: objects[0].children: expected an array of at least 2 solids (got an object)"},
        {"{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\"}", RR_ERR_INVALID,
         "bad.json: objects[0].children: missing (expected an array of at least 2 solids)"},
        {CSG("union", BOX ",3"), RR_ERR_INVALID, "bad.json: objects[0].children[1]: expected a solid object (got the number 3)"},
        {CSG("union", BOX ",{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].type: a 'quad' cannot be part of a csg: it does not enclose a volume"},
        {CSG("union", BOX ",{\"type\":\"torus\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].type: unknown type 'torus' (solids: sphere, quadric, box, mesh, csg)"},
        {CSG("union", BOX ",{\"center\":[0,0,0]}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].type: missing (expected one of sphere, quadric, box, mesh, csg)"},
        {CSG("union", BOX ",{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"name\":\"x\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: 'name' is allowed only on the object itself, not on a csg child"},
        {CSG("union", BOX ",{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"cull\":true}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: 'cull' is allowed only on the object itself"},
        {CSG("union", BOX ",{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"colour\":1}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: unknown key 'colour' (allowed: type, material, transform, center, radius)"},
        {CSG("union", BOX ",{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":-1}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].radius: expected a number > 0 (got -1)"},
        {CSG("union", BOX ",{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"material\":\"blue\"}"),
         RR_ERR_INVALID, "bad.json: objects[0].children[1].material: unknown material 'blue'"},
        {CSG("union", BOX ",{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,0,1]}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].max: must be greater than min on every axis"},
        {CSG("union", BOX ",{\"type\":\"quadric\",\"shape\":\"cylinder\",\"radius\":1}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].height: missing (expected a number > 0)"},
        {CSG("union", BOX ",{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":-1}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].height: expected a number > 0 (got -1)"},
        {CSG("union", BOX "," CSG("intersection", BOX ",{\"type\":\"quadric\",\"shape\":\"cube\"}")), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].children[1].shape: unknown shape 'cube'"},
        {CSG("union", BOX ",{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1],"
                          "\"transform\":[{\"matrix\":[[1,0,0,0],[0,1,0,0],[1,0,0,0]]}]}"),
         RR_ERR_INVALID,
         "bad.json: objects[0].children[1].transform: the transform is singular (determinant 0): it flattens the "
         "object"},
        /* each transform is fine alone, their composition underflows to a singular map */
        {CSG("union", BOX ",{\"type\":\"csg\",\"op\":\"union\",\"transform\":[{\"scale\":1e-100}],\"children\":["
                          BOX ",{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1],\"transform\":[{\"scale\":1e-100}]}]}"),
         RR_ERR_INVALID,
         "bad.json: objects[0].children[1].children[1]: the transform, composed with those of the enclosing csg nodes, "
         "is singular"},
        /* materials: the object's own is required as for every object */
        {"{\"type\":\"csg\",\"op\":\"union\",\"children\":[" BOX "," SPH "]}", RR_ERR_INVALID,
         "bad.json: objects[0].material: missing (expected the name of a material)"},
        {"{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":1}", RR_ERR_INVALID,
         "bad.json: objects[0].material: missing (expected the name of a material)"},
        /* meshes that bound no volume */
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"open.obj\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: mesh 'open.obj' is not watertight: 4 boundary edges; a mesh inside CSG "
         "must be closed"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"inward.obj\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: mesh 'inward.obj' is oriented inwards (signed volume -1 < 0); a mesh "
         "inside CSG must face outwards: set \"flip\": true"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"cube.obj\",\"flip\":true}"), RR_ERR_INVALID,
         "mesh 'cube.obj' is oriented inwards (signed volume -1 < 0); a mesh inside CSG must face outwards: remove "
         "\"flip\": true"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"turned.obj\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: mesh 'turned.obj' is not consistently oriented: 4 edges with "
         "inconsistent orientation"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"fin.obj\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: mesh 'fin.obj' is not manifold: 1 edge shared by three or more triangles"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"flat.obj\"}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1]: mesh 'flat.obj' encloses no volume"},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"gone.obj\"}"), RR_ERR_IO,
         "bad.json: objects[0].children[1].file: "},
        {CSG("union", BOX ",{\"type\":\"mesh\",\"file\":\"cube.obj\",\"flip\":1}"), RR_ERR_INVALID,
         "bad.json: objects[0].children[1].flip: expected true or false (got the number 1)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char objs[8192];
        snprintf(objs, sizeof objs, "[%s]", cases[i].obj);
        expect_fail_opts(make_scene(NULL, NULL, "", objs, ""), NULL, g_dir, cases[i].code, cases[i].want);
    }
}

/* Too deep: nesting, and a long left fold; both stop before recursing far. */
static void too_deep(void **state)
{
    (void)state;
    static char obj[8000];
    size_t len = 0;
    int levels = 40;
    for (int i = 0; i < levels; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len,
                                "{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":[" BOX ",");
    len += (size_t)snprintf(obj + len, sizeof obj - len, BOX);
    for (int i = 0; i < levels; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len, "]}");
    char objs[8192];
    snprintf(objs, sizeof objs, "[%s]", obj);
    expect_fail(make_scene(NULL, NULL, "", objs, ""), RR_ERR_LIMIT,
                "the CSG tree is nested deeper than the limit of 32 levels");

    /* A difference of 40 children folds into a chain 39 deep */
    len = (size_t)snprintf(obj, sizeof obj,
                           "{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"white\",\"children\":[");
    for (int i = 0; i < 40; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len, "%s" BOX, i ? "," : "");
    snprintf(obj + len, sizeof obj - len, "]}");
    snprintf(objs, sizeof objs, "[%s]", obj);
    expect_fail(make_scene(NULL, NULL, "", objs, ""), RR_ERR_LIMIT,
                "bad.json: objects[0].children: 40 children fold into 39 levels of binary nodes (a chain: difference "
                "folds left), deeper than the limit of 32 levels");

    /* 17 children, the first of which has 17 children, as differences:
     * each fold alone is within the limit, together they are 16 + 17 = 33
     * deep */
    len = (size_t)snprintf(obj, sizeof obj,
                           "{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"white\",\"children\":[");
    for (int k = 0; k < 2; k++) {
        if (k == 0)
            len += (size_t)snprintf(obj + len, sizeof obj - len,
                                    "{\"type\":\"csg\",\"op\":\"difference\",\"children\":[");
        for (int i = 0; i < 17 - k; i++)
            len += (size_t)snprintf(obj + len, sizeof obj - len, "%s" BOX, i ? "," : "");
        if (k == 0)
            len += (size_t)snprintf(obj + len, sizeof obj - len, "]},");
    }
    snprintf(obj + len, sizeof obj - len, "]}");
    snprintf(objs, sizeof objs, "[%s]", obj);
    expect_fail(make_scene(NULL, NULL, "", objs, ""), RR_ERR_LIMIT,
                "bad.json: objects[0]: the CSG tree is at least 33 levels deep, over the limit of 32");

    /* 20 levels of nesting with 2 children each is fine */
    len = 0;
    for (int i = 0; i < 20; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len,
                                "{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":[" BOX ",");
    len += (size_t)snprintf(obj + len, sizeof obj - len, BOX);
    for (int i = 0; i < 20; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len, "]}");
    scene *s = load_obj(obj, NULL);
    assert_int_equal(s->ncsg, 41);
    scene_destroy(s);
}

/* Unions fold into balanced trees: 1024 children are 10 levels of binary
 * nodes, not a chain of 1023 (refused before); three children are still
 * (a u b) u c, as a left fold. */
static void union_folds_balanced(void **state)
{
    (void)state;
    static char obj[1 << 17];
    size_t len = (size_t)snprintf(obj, sizeof obj,
                                  "{\"format\":\"radray-scene/1\",\"camera\":" CAM ",\"materials\":" MATS
                                  ",\"objects\":[{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":[");
    for (int i = 0; i < 1024; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len, "%s{\"type\":\"sphere\",\"center\":[%d,0,0],\"radius\":0.6}",
                                i ? "," : "", i);
    snprintf(obj + len, sizeof obj - len, "]}]}");
    scene *s = load_ok(obj, NULL);
    assert_int_equal(s->ncsg, 2047);
    /* Depth: the longest root-to-leaf path. */
    int deepest = 0;
    for (size_t i = 0; i < s->ncsg; i++) {
        if (s->csg[i].op != SCENE_CSG_LEAF)
            continue;
        int d = 1;
        for (size_t k = i, up = 1; up;) {
            up = 0;
            for (size_t j = 0; j < s->ncsg; j++)
                if (s->csg[j].op != SCENE_CSG_LEAF && (s->csg[j].left == k || s->csg[j].right == k)) {
                    k = j, d++, up = 1;
                    break;
                }
        }
        deepest = d > deepest ? d : deepest;
    }
    assert_int_equal(deepest, 11);
    assert_v3(root_of(s, 0)->bbox_hi, 1023.6, 0.6, 0.6);
    scene_destroy(s);
    s = load_obj("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"white\",\"children\":[" BOX "," BOX "," BOX "]}",
                 NULL);
    const scene_csg_node *r = root_of(s, 0);
    assert_string_equal(s->csg[r->left].name, "objects[0].children[0..1]");
    assert_string_equal(s->csg[r->right].name, "objects[0].children[2]");
    scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(quadric_shapes),     cmocka_unit_test(quadric_transform), cmocka_unit_test(nested_transforms),
        cmocka_unit_test(material_inheritance), cmocka_unit_test(fold_left),       cmocka_unit_test(bounds_pruning),
        cmocka_unit_test(several_objects),    cmocka_unit_test(mesh_leaf),         cmocka_unit_test(documented_example),
        cmocka_unit_test(bad_solids),         cmocka_unit_test(too_deep),          cmocka_unit_test(union_folds_balanced),
    };
    return cmocka_run_group_tests(tests, make_meshes, remove_meshes);
}
