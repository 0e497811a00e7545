/* test_csg_util.h - shared by the solids tests (test_csg.c, test_csg_mesh.c):
 * scenes with solids built by hand (so the span code is tested without the
 * loader), rays, and checks of span lists. Header-only; include after cmocka.h. */
#ifndef TEST_CSG_UTIL_H
#define TEST_CSG_UTIL_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rr_rng.h"
#include "rt.h"

#define assert_near(a, b, tol)                                                                                  \
    do {                                                                                                        \
        double a_ = (double)(a), b_ = (double)(b);                                                              \
        if (!(fabs(a_ - b_) <= (tol)))                                                                          \
            fail_msg("%s = %.17g, expected %.17g (tol %g)", #a, a_, b_, (double)(tol));                         \
    } while (0)

/* ---- hand-built scenes ---- */

static inline scene *scene_new(void)
{
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    snprintf(s->path, sizeof s->path, "<test_csg>");
    s->nmaterials = 4;
    s->materials = calloc(s->nmaterials, sizeof *s->materials);
    for (size_t i = 0; i < s->nmaterials; i++)
        snprintf(s->materials[i].name, sizeof s->materials[i].name, "m%zu", i);
    return s;
}

static inline uint32_t add_node(scene *s, const scene_csg_node *n)
{
    s->csg = realloc(s->csg, (s->ncsg + 1) * sizeof *s->csg);
    assert_non_null(s->csg);
    s->csg[s->ncsg] = *n;
    return (uint32_t)s->ncsg++;
}

static inline scene_csg_node leaf_base(scene_solid_kind kind, uint32_t mat)
{
    scene_csg_node n;
    memset(&n, 0, sizeof n);
    n.op = SCENE_CSG_LEAF;
    n.solid = kind;
    n.material = mat;
    n.to_world = rr_xform_identity();
    n.to_local = rr_xform_identity();
    return n;
}

static inline uint32_t sphere_leaf(scene *s, rr_vec3 c, double r, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_SPHERE, mat);
    n.center = c;
    n.radius = r;
    n.bbox_lo = rr_v3_sub(c, rr_v3(r, r, r));
    n.bbox_hi = rr_v3_add(c, rr_v3(r, r, r));
    return add_node(s, &n);
}

static inline uint32_t box_leaf(scene *s, rr_vec3 lo, rr_vec3 hi, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_BOX, mat);
    n.clip_lo = n.bbox_lo = lo;
    n.clip_hi = n.bbox_hi = hi;
    return add_node(s, &n);
}

static inline uint32_t quadric_leaf(scene *s, const double q[4][4], rr_vec3 lo, rr_vec3 hi, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_QUADRIC, mat);
    memcpy(n.q, q, sizeof n.q);
    n.clip_lo = n.bbox_lo = lo;
    n.clip_hi = n.bbox_hi = hi;
    return add_node(s, &n);
}

static inline rr_xform xform_inverse(const rr_xform *x)
{
    const double(*m)[3] = x->m;
    double det = rr_xform_det(x);
    rr_xform r;
    r.m[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
    r.m[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
    r.m[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
    r.m[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
    r.m[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
    r.m[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
    r.m[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
    r.m[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
    r.m[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
    r.t = rr_v3_neg(rr_xform_vector(&r, x->t));
    return r;
}

/* Gives leaf `id` (built in its local frame) the transform to_world and its
 * world bbox (the transformed corners of its local bbox). */
static inline void leaf_transform(scene *s, uint32_t id, rr_xform to_world)
{
    scene_csg_node *n = &s->csg[id];
    rr_vec3 lo = n->bbox_lo, hi = n->bbox_hi;
    n->to_world = to_world;
    n->to_local = xform_inverse(&to_world);
    n->bbox_lo = rr_v3(INFINITY, INFINITY, INFINITY);
    n->bbox_hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (int c = 0; c < 8; c++) {
        rr_vec3 p = rr_v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
        p = rr_xform_point(&to_world, p);
        n->bbox_lo = rr_v3_min(n->bbox_lo, p);
        n->bbox_hi = rr_v3_max(n->bbox_hi, p);
    }
}

static inline uint32_t op_node(scene *s, scene_csg_op op, uint32_t l, uint32_t r)
{
    scene_csg_node n;
    memset(&n, 0, sizeof n);
    n.op = op;
    n.left = l;
    n.right = r;
    rr_vec3 llo = s->csg[l].bbox_lo, lhi = s->csg[l].bbox_hi, rlo = s->csg[r].bbox_lo, rhi = s->csg[r].bbox_hi;
    if (op == SCENE_CSG_UNION) {
        n.bbox_lo = rr_v3_min(llo, rlo);
        n.bbox_hi = rr_v3_max(lhi, rhi);
    } else if (op == SCENE_CSG_INTERSECTION) {
        n.bbox_lo = rr_v3_max(llo, rlo);
        n.bbox_hi = rr_v3_min(lhi, rhi);
    } else {
        n.bbox_lo = llo;
        n.bbox_hi = lhi;
    }
    return add_node(s, &n);
}

static inline void set_object(scene *s, uint32_t node, uint32_t obj)
{
    s->csg[node].object = obj;
    if (s->csg[node].op != SCENE_CSG_LEAF) {
        set_object(s, s->csg[node].left, obj);
        set_object(s, s->csg[node].right, obj);
    }
}

static inline uint32_t add_solid(scene *s, uint32_t root, int cull)
{
    s->objects = realloc(s->objects, (s->nobjects + 1) * sizeof *s->objects);
    assert_non_null(s->objects);
    scene_object *o = &s->objects[s->nobjects];
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "objects[%zu]", s->nobjects);
    o->kind = SCENE_OBJ_CSG;
    o->cull_backfaces = cull;
    o->csg_root = root;
    set_object(s, root, (uint32_t)s->nobjects);
    s->bbox_min = rr_v3_min(s->nobjects ? s->bbox_min : s->csg[root].bbox_lo, s->csg[root].bbox_lo);
    s->bbox_max = rr_v3_max(s->nobjects ? s->bbox_max : s->csg[root].bbox_hi, s->csg[root].bbox_hi);
    return (uint32_t)s->nobjects++;
}

/* A mesh leaf from vertices and counter-clockwise (outward) triangles. */
static inline uint32_t mesh_leaf(scene *s, const rr_vec3 *v, size_t nv, const uint32_t (*t)[3], size_t nt, uint32_t mat)
{
    size_t v0 = s->ncsg_verts, t0 = s->ncsg_tris;
    s->csg_verts = realloc(s->csg_verts, (v0 + nv) * sizeof *s->csg_verts);
    s->csg_tris = realloc(s->csg_tris, (t0 + nt) * sizeof *s->csg_tris);
    assert_non_null(s->csg_verts);
    assert_non_null(s->csg_tris);
    scene_csg_node n = leaf_base(SCENE_SOLID_MESH, mat);
    n.bbox_lo = rr_v3(INFINITY, INFINITY, INFINITY);
    n.bbox_hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t i = 0; i < nv; i++) {
        s->csg_verts[v0 + i] = v[i];
        n.bbox_lo = rr_v3_min(n.bbox_lo, v[i]);
        n.bbox_hi = rr_v3_max(n.bbox_hi, v[i]);
    }
    for (size_t i = 0; i < nt; i++)
        for (int k = 0; k < 3; k++)
            s->csg_tris[t0 + i][k] = (uint32_t)(v0 + t[i][k]);
    s->ncsg_verts += nv;
    s->ncsg_tris += nt;
    n.tri_first = t0;
    n.tri_count = nt;
    return add_node(s, &n);
}

/* Axis-aligned cube mesh [lo, hi], 12 outward triangles. */
static inline uint32_t cube_mesh(scene *s, rr_vec3 lo, rr_vec3 hi, uint32_t mat)
{
    rr_vec3 v[8];
    for (int c = 0; c < 8; c++)
        v[c] = rr_v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
    static const uint32_t t[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, /* -z, +z */
                                      {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3}, /* -y, +y */
                                      {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}}; /* -x, +x */
    return mesh_leaf(s, v, 8, t, 12, mat);
}

/* A UV sphere mesh with nu segments around and nv rings, vertices on the sphere. */
static inline uint32_t uv_sphere_mesh(scene *s, rr_vec3 c, double r, int nu, int nv, uint32_t mat)
{
    size_t nverts = 2 + (size_t)nu * (size_t)(nv - 1);
    rr_vec3 *v = malloc(nverts * sizeof *v);
    uint32_t(*t)[3] = malloc((size_t)2 * nu * nv * sizeof *t);
    size_t k = 0, nt = 0;
    v[k++] = rr_v3_add(c, rr_v3(0, 0, r));  /* north pole, 0 */
    v[k++] = rr_v3_add(c, rr_v3(0, 0, -r)); /* south pole, 1 */
    for (int i = 1; i < nv; i++) {
        double th = RR_PI * i / nv;
        for (int j = 0; j < nu; j++) {
            double ph = 2 * RR_PI * j / nu;
            v[k++] = rr_v3_add(c, rr_v3(r * sin(th) * cos(ph), r * sin(th) * sin(ph), r * cos(th)));
        }
    }
#define RING(i, j) ((uint32_t)(2 + ((i) - 1) * nu + ((j) % nu)))
    for (int j = 0; j < nu; j++) {
        t[nt][0] = 0, t[nt][1] = RING(1, j), t[nt][2] = RING(1, j + 1), nt++;
        t[nt][0] = 1, t[nt][1] = RING(nv - 1, j + 1), t[nt][2] = RING(nv - 1, j), nt++;
    }
    for (int i = 1; i < nv - 1; i++)
        for (int j = 0; j < nu; j++) {
            t[nt][0] = RING(i, j), t[nt][1] = RING(i + 1, j), t[nt][2] = RING(i + 1, j + 1), nt++;
            t[nt][0] = RING(i, j), t[nt][1] = RING(i + 1, j + 1), t[nt][2] = RING(i, j + 1), nt++;
        }
#undef RING
    uint32_t id = mesh_leaf(s, v, k, (const uint32_t(*)[3])t, nt, mat);
    free(v);
    free(t);
    return id;
}

static inline rr_ray ray_make(rr_vec3 o, rr_vec3 d)
{
    rr_ray r = {o, d};
    return r;
}

static inline void spans_well_formed(const rt_spans *sp)
{
    for (int i = 0; i < sp->n; i++) {
        if (!(sp->s[i].in.t < sp->s[i].out.t))
            fail_msg("span %d: [%.17g, %.17g] is not a positive interval", i, sp->s[i].in.t, sp->s[i].out.t);
        if (i > 0 && !(sp->s[i - 1].out.t < sp->s[i].in.t))
            fail_msg("spans %d, %d overlap or touch", i - 1, i);
    }
}

static inline void expect_spans(const rt_spans *sp, int n, const double *t, double tol)
{
    spans_well_formed(sp);
    if (sp->n != n) {
        for (int i = 0; i < sp->n; i++)
            printf("  span [%.17g, %.17g]\n", sp->s[i].in.t, sp->s[i].out.t);
        fail_msg("%d spans, expected %d", sp->n, n);
    }
    for (int i = 0; i < n; i++) {
        assert_near(sp->s[i].in.t, t[2 * i], tol);
        assert_near(sp->s[i].out.t, t[2 * i + 1], tol);
    }
}

static inline void q_zero(double q[4][4]) { memset(q, 0, sizeof(double[4][4])); }

#endif
