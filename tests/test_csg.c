/* test_csg.c - solids (rt_solid.c, rt_solid_mesh.c): leaf spans against closed
 * forms (spheres, every named quadric, boxes, meshes), CSG combinations,
 * volumes by ray casting, mesh parity for rays through vertices and along
 * edges, per-leaf BVH against brute force, the scene BVH against the
 * reference, normals, materials and point membership.
 *
 * Most scenes are built by hand (the span code is tested without the loader);
 * the last tests load the JSON format. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rr_file.h"
#include "rt.h"
#include "rr_rng.h"
#include "test_scenes.h"

#define assert_near(a, b, tol)                                                                                  \
    do {                                                                                                        \
        double a_ = (double)(a), b_ = (double)(b);                                                              \
        if (!(fabs(a_ - b_) <= (tol)))                                                                          \
            fail_msg("%s = %.17g, expected %.17g (tol %g)", #a, a_, b_, (double)(tol));                         \
    } while (0)

/* ---- hand-built scenes ---- */

static scene *scene_new(void)
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

static uint32_t add_node(scene *s, const scene_csg_node *n)
{
    s->csg = realloc(s->csg, (s->ncsg + 1) * sizeof *s->csg);
    assert_non_null(s->csg);
    s->csg[s->ncsg] = *n;
    return (uint32_t)s->ncsg++;
}

static scene_csg_node leaf_base(scene_solid_kind kind, uint32_t mat)
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

static uint32_t sphere_leaf(scene *s, rr_vec3 c, double r, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_SPHERE, mat);
    n.center = c;
    n.radius = r;
    n.bbox_lo = rr_v3_sub(c, rr_v3(r, r, r));
    n.bbox_hi = rr_v3_add(c, rr_v3(r, r, r));
    return add_node(s, &n);
}

static uint32_t box_leaf(scene *s, rr_vec3 lo, rr_vec3 hi, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_BOX, mat);
    n.clip_lo = n.bbox_lo = lo;
    n.clip_hi = n.bbox_hi = hi;
    return add_node(s, &n);
}

static uint32_t quadric_leaf(scene *s, const double q[4][4], rr_vec3 lo, rr_vec3 hi, uint32_t mat)
{
    scene_csg_node n = leaf_base(SCENE_SOLID_QUADRIC, mat);
    memcpy(n.q, q, sizeof n.q);
    n.clip_lo = n.bbox_lo = lo;
    n.clip_hi = n.bbox_hi = hi;
    return add_node(s, &n);
}

static rr_xform xform_inverse(const rr_xform *x)
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
static void leaf_transform(scene *s, uint32_t id, rr_xform to_world)
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

static uint32_t op_node(scene *s, scene_csg_op op, uint32_t l, uint32_t r)
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

static void set_object(scene *s, uint32_t node, uint32_t obj)
{
    s->csg[node].object = obj;
    if (s->csg[node].op != SCENE_CSG_LEAF) {
        set_object(s, s->csg[node].left, obj);
        set_object(s, s->csg[node].right, obj);
    }
}

static uint32_t add_solid(scene *s, uint32_t root, int cull)
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
static uint32_t mesh_leaf(scene *s, const rr_vec3 *v, size_t nv, const uint32_t (*t)[3], size_t nt, uint32_t mat)
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
static uint32_t cube_mesh(scene *s, rr_vec3 lo, rr_vec3 hi, uint32_t mat)
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
static uint32_t uv_sphere_mesh(scene *s, rr_vec3 c, double r, int nu, int nv, uint32_t mat)
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

static rr_ray ray_make(rr_vec3 o, rr_vec3 d)
{
    rr_ray r = {o, d};
    return r;
}

static void spans_well_formed(const rt_spans *sp)
{
    for (int i = 0; i < sp->n; i++) {
        if (!(sp->s[i].in.t < sp->s[i].out.t))
            fail_msg("span %d: [%.17g, %.17g] is not a positive interval", i, sp->s[i].in.t, sp->s[i].out.t);
        if (i > 0 && !(sp->s[i - 1].out.t < sp->s[i].in.t))
            fail_msg("spans %d, %d overlap or touch", i - 1, i);
    }
}

static void expect_spans(const rt_spans *sp, int n, const double *t, double tol)
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

/* ---- spheres ---- */

static void sphere_closed_form(void **state)
{
    (void)state;
    scene *s = scene_new();
    rr_vec3 c = rr_v3(1, 2, 3);
    double r = 2.0;
    uint32_t leaf = sphere_leaf(s, c, r, 1);
    uint32_t obj = add_solid(s, leaf, 0);
    rt_spans sp;
    rt_hit h;

    /* From outside along x, |d| = 3: t = (6 -+ 2) / 3. */
    rr_ray ray = ray_make(rr_v3(-5, 2, 3), rr_v3(3, 0, 0));
    rt_csg_spans(s, NULL, leaf, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){4.0 / 3.0, 8.0 / 3.0}, 1e-15);
    assert_int_equal(sp.s[0].in.surface, -1);
    assert_true(rt_solid_closest(s, NULL, obj, ray, 0, INFINITY, &h));
    assert_near(h.t, 4.0 / 3.0, 1e-15);
    assert_true(h.front);
    assert_near(h.normal.x, -1, 1e-15);
    assert_int_equal(h.material, 1);
    assert_int_equal(h.tri, -1);
    assert_int_equal(h.part, leaf);
    assert_int_equal(h.object, obj);
    assert_near(h.point.x, -1, 1e-14);

    /* From the centre: the span starts behind, the hit is the exit (a back face). */
    ray = ray_make(c, rr_v3(0, 0, 0.5));
    rt_csg_spans(s, NULL, leaf, ray, -INFINITY, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){-4, 4}, 1e-15);
    assert_true(rt_solid_closest(s, NULL, obj, ray, 0, INFINITY, &h));
    assert_near(h.t, 4, 1e-15);
    assert_false(h.front);
    assert_near(h.normal.z, -1, 1e-15); /* faces the ray's origin */
    /* Culling back faces: the only surface ahead is a back face. */
    s->objects[obj].cull_backfaces = 1;
    assert_false(rt_solid_closest(s, NULL, obj, ray, 0, INFINITY, &h));
    s->objects[obj].cull_backfaces = 0;

    /* Tangent (exactly, in binary): no span, no hit. */
    ray = ray_make(rr_v3(-5, 4, 3), rr_v3(1, 0, 0));
    rt_csg_spans(s, NULL, leaf, ray, -INFINITY, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    assert_false(rt_solid_closest(s, NULL, obj, ray, 0, INFINITY, &h));

    /* 1e6 away: t = 1e6 -+ 2 to the last bits. */
    ray = ray_make(rr_v3(1, 2, 3 + 1e6), rr_v3(0, 0, -1));
    rt_csg_spans(s, NULL, leaf, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){1e6 - 2, 1e6 + 2}, 1e-9);
    /* Oblique and far: closed form through the perpendicular distance. */
    rr_vec3 dir = rr_v3_norm(rr_v3(1, 2, -2));
    double off = 1.5; /* distance of the line from the centre */
    rr_vec3 perp = rr_v3_norm(rr_v3_cross(dir, rr_v3(1, 0, 0)));
    rr_vec3 foot = rr_v3_madd(c, perp, off);
    ray = ray_make(rr_v3_madd(foot, dir, -1e6), dir);
    double half = sqrt(r * r - off * off);
    rt_csg_spans(s, NULL, leaf, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){1e6 - half, 1e6 + half}, 1e-8);

    /* Grazing: the line passes at r (1 - 1e-12) from the centre, from 1000
     * away. The reference half chord is computed in long double from the
     * ray as rounded (rounding the origin moves the line by ~1e-13, which
     * matters against a sagitta of 4e-12). */
    double g = 1e-12;
    foot = rr_v3_madd(c, perp, r * (1 - g));
    ray = ray_make(rr_v3_madd(foot, dir, -1000), dir);
    {
        long double oc[3] = {(long double)ray.o.x - c.x, (long double)ray.o.y - c.y, (long double)ray.o.z - c.z};
        long double dd[3] = {ray.d.x, ray.d.y, ray.d.z};
        long double a = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2];
        long double b = dd[0] * oc[0] + dd[1] * oc[1] + dd[2] * oc[2];
        long double q2 = 0;
        for (int k = 0; k < 3; k++) {
            long double qk = oc[k] - dd[k] * b / a;
            q2 += qk * qk;
        }
        half = (double)(sqrtl((long double)r * r - q2) / sqrtl(a));
        rt_csg_spans(s, NULL, leaf, ray, 0, INFINITY, &sp);
        assert_int_equal(sp.n, 1);
        assert_near(sp.s[0].out.t - sp.s[0].in.t, 2 * half, 1e-3 * half);
        assert_near(0.5 * (sp.s[0].out.t + sp.s[0].in.t), (double)(-b / a), 1e-10);
    }
    /* Just outside: nothing. */
    foot = rr_v3_madd(c, perp, r * (1 + 1e-12));
    ray = ray_make(rr_v3_madd(foot, dir, -1000), dir);
    rt_csg_spans(s, NULL, leaf, ray, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);

    /* Agrees with rt_sphere_hit on random rays (the analytic sphere object). */
    rr_rng rng = rr_rng_make(7, 0);
    for (int i = 0; i < 2000; i++) {
        rr_vec3 o = rr_v3(8 * rr_rng_uniform(&rng) - 3, 8 * rr_rng_uniform(&rng) - 2, 8 * rr_rng_uniform(&rng) - 1);
        rr_vec3 d = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5);
        double t;
        int a = rt_sphere_hit(c, r, ray_make(o, d), 1e-9, INFINITY, &t);
        int b = rt_solid_closest(s, NULL, obj, ray_make(o, d), 1e-9, INFINITY, &h);
        assert_int_equal(a, b);
        if (a)
            assert_near(h.t, t, 1e-12 * fmax(1, t));
    }
    scene_destroy(s);
}

/* A transformed sphere leaf (scaled non-uniformly, rotated, moved) is an
 * ellipsoid: t is preserved by the affine map, normals use the inverse
 * transpose. */
static void transformed_leaf(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t leaf = sphere_leaf(s, rr_v3(0, 0, 0), 1, 0);
    /* to_world: scale (2, 1, 0.5), then rotate 90 degrees about z, then move by (1, 1, 1). */
    rr_xform x = {{{0, -1, 0}, {2, 0, 0}, {0, 0, 0.5}}, {1, 1, 1}};
    leaf_transform(s, leaf, x);
    uint32_t obj = add_solid(s, leaf, 0);
    /* World: ellipsoid with semi-axes 1 (x), 2 (y), 0.5 (z) about (1, 1, 1). */
    rt_hit h;
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(1, -9, 1), rr_v3(0, 2, 0)), 0, INFINITY, &h));
    assert_near(h.t, 4, 1e-14);
    assert_near(h.normal.y, -1, 1e-14);
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(1, 1, 9), rr_v3(0, 0, -1)), 0, INFINITY, &h));
    assert_near(h.t, 7.5, 1e-14);
    /* Off-axis point: (x-1)^2 + ((y-1)/2)^2 + ((z-1)/0.5)^2 = 1 at x - 1 = 0.6,
     * y - 1 = 1.6 * 0 ... take the ray along x at y - 1 = 1.2: x - 1 = -0.8. The
     * normal there is along (x/1, y/4, 0) = (-0.8, 0.3, 0). */
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(-9, 2.2, 1), rr_v3(1, 0, 0)), 0, INFINITY, &h));
    assert_near(h.t, 9.2, 1e-13);
    rr_vec3 n = rr_v3_norm(rr_v3(-0.8, 0.3, 0));
    assert_near(h.normal.x, n.x, 1e-13);
    assert_near(h.normal.y, n.y, 1e-13);
    assert_near(h.normal.z, 0, 1e-13);
    assert_true(rt_csg_contains(s, NULL, leaf, rr_v3(1, 2.9, 1)));
    assert_false(rt_csg_contains(s, NULL, leaf, rr_v3(1, 1, 1.6)));
    scene_destroy(s);
}

/* ---- quadrics ---- */

static void q_zero(double q[4][4]) { memset(q, 0, sizeof(double[4][4])); }

/* The one span of a quadric leaf along a ray, with the surfaces of its ends. */
static void quadric_case_tol(const double q[4][4], rr_vec3 lo, rr_vec3 hi, rr_ray ray, int n, double t0, double t1,
                             int s0, int s1, double tol)
{
    scene *s = scene_new();
    uint32_t leaf = quadric_leaf(s, q, lo, hi, 2);
    rt_spans sp;
    rt_csg_spans(s, NULL, leaf, ray, -INFINITY, INFINITY, &sp);
    if (n == 0) {
        expect_spans(&sp, 0, NULL, 0);
    } else {
        expect_spans(&sp, 1, (double[]){t0, t1}, tol * fmax(1, fabs(t1)));
        assert_int_equal(sp.s[0].in.surface, s0);
        assert_int_equal(sp.s[0].out.surface, s1);
        /* The middle of the span is inside, points just outside it are not. */
        double tm = 0.5 * (t0 + t1);
        assert_true(rt_csg_contains(s, NULL, leaf, rr_ray_at(ray, tm)));
        assert_false(rt_csg_contains(s, NULL, leaf, rr_ray_at(ray, t0 - 1e-6 * (t1 - t0))));
        assert_false(rt_csg_contains(s, NULL, leaf, rr_ray_at(ray, t1 + 1e-6 * (t1 - t0))));
    }
    scene_destroy(s);
}

static void quadric_case(const double q[4][4], rr_vec3 lo, rr_vec3 hi, rr_ray ray, int n, double t0, double t1,
                         int s0, int s1)
{
    quadric_case_tol(q, lo, hi, ray, n, t0, t1, s0, s1, 1e-12);
}

static void quadric_ellipsoid(void **state)
{
    (void)state;
    double q[4][4];
    q_zero(q);
    q[0][0] = 1.0 / 4, q[1][1] = 1, q[2][2] = 4, q[3][3] = -1; /* radii 2, 1, 0.5 */
    rr_vec3 lo = rr_v3(-2, -1, -0.5), hi = rr_v3(2, 1, 0.5);
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 1, 3, 7, -1, -1);
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 0, 5), rr_v3(0, 0, -2)), 1, 2.25, 2.75, -1, -1);
    /* At y = 0.6: x = +-2 sqrt(1 - 0.36) = +-1.6. */
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0.6, 0), rr_v3(1, 0, 0)), 1, 3.4, 6.6, -1, -1);
    /* From inside, 1e6 away, missing. */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 0, 0), rr_v3(0, 1, 0)), 1, -1, 1, -1, -1);
    quadric_case(q, lo, hi, ray_make(rr_v3(1e6, 0, 0), rr_v3(-1, 0, 0)), 1, 1e6 - 2, 1e6 + 2, -1, -1);
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 1.01, 0), rr_v3(1, 0, 0)), 0, 0, 0, 0, 0);
}

static void quadric_cylinder(void **state)
{
    (void)state;
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[2][2] = 1, q[3][3] = -1; /* radius 1, axis y, height 2 (clip) */
    rr_vec3 lo = rr_v3(-1, -1, -1), hi = rr_v3(1, 1, 1);
    /* Body: across at y = 0.5, z = 0.6: x = +-0.8. */
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0.5, 0.6), rr_v3(1, 0, 0)), 1, 4.2, 5.8, -1, -1);
    /* Caps: down the axis (A = 0: the linear case), faces +y (3) then -y (2). */
    quadric_case(q, lo, hi, ray_make(rr_v3(0.3, 5, 0.2), rr_v3(0, -1, 0)), 1, 4, 6, 3, 2);
    /* Parallel to the axis, outside: nothing. */
    quadric_case(q, lo, hi, ray_make(rr_v3(1.2, 5, 0), rr_v3(0, -1, 0)), 0, 0, 0, 0, 0);
    /* Body then cap: from (-3, 0, 0) along (3, 1.2, 0): the body at x = -1
     * (t = 2/3, y = 0.8), the cap y = 1 at t = 1/1.2 (x = -0.5). */
    quadric_case(q, lo, hi, ray_make(rr_v3(-3, 0, 0), rr_v3(3, 1.2, 0)), 1, 2.0 / 3.0, 1 / 1.2, -1, 3);
    /* Normals: cap and body. */
    scene *s = scene_new();
    uint32_t leaf = quadric_leaf(s, q, lo, hi, 0);
    uint32_t obj = add_solid(s, leaf, 0);
    rt_hit h;
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(0.3, 5, 0.2), rr_v3(0, -1, 0)), 0, INFINITY, &h));
    assert_near(h.normal.y, 1, 1e-15);
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(-5, 0.5, 0.6), rr_v3(1, 0, 0)), 0, INFINITY, &h));
    assert_near(h.normal.x, -0.8, 1e-15);
    assert_near(h.normal.z, 0.6, 1e-15);
    scene_destroy(s);
}

static void quadric_cone(void **state)
{
    (void)state;
    /* Apex at the origin, opening +y, radius 1 at height 2: x^2 + z^2 - y^2/4 <= 0, 0 <= y <= 2. */
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[1][1] = -0.25, q[2][2] = 1;
    rr_vec3 lo = rr_v3(-1, 0, -1), hi = rr_v3(1, 2, 1);
    /* At y = 1: radius 0.5. */
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 1, 0), rr_v3(1, 0, 0)), 1, 4.5, 5.5, -1, -1);
    /* Down the axis: the whole line is on the cone (double root, A < 0):
     * from the cap (+y, 3) to the apex plane (-y, 2). */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 5, 0), rr_v3(0, -1, 0)), 1, 3, 5, 3, 2);
    /* The lower nappe is clipped away: a ray at y = -1 misses. */
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, -1, 0), rr_v3(1, 0, 0)), 0, 0, 0, 0, 0);
    /* Parallel to a generator (A = 0): the line x = 0.5 y - 0.25 ... through
     * (0.25, 1, 0) with d = (0.5, 1, 0) meets x = y/2 never; inside the
     * cone where |x| <= y/2: x = 0.25 + 0.5 s, y = 1 + s: 0.25 + 0.5s <= 0.5 + 0.5s
     * always; and -(0.25 + 0.5 s) <= 0.5 + 0.5 s for s >= -0.75. So inside
     * from s = -0.75 (quadric) to the cap y = 2 at s = 1. */
    quadric_case(q, lo, hi, ray_make(rr_v3(0.25, 1, 0), rr_v3(0.5, 1, 0)), 1, -0.75, 1, -1, 3);
    /* Oblique: through (0, 1.2, -0.3) along z... at y = 1.2 radius 0.6: z = +-0.6. */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 1.2, -3), rr_v3(0, 0, 1)), 1, 2.4, 3.6, -1, -1);
}

static void quadric_paraboloid(void **state)
{
    (void)state;
    /* x^2 + z^2 <= y (radius 1 at height 1... use radius 2 at height 1: x^2 + z^2 <= 4y). */
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[2][2] = 1, q[1][3] = q[3][1] = -2; /* x^2 + z^2 - 4y */
    rr_vec3 lo = rr_v3(-2, 0, -2), hi = rr_v3(2, 1, 2);
    /* At y = 0.25: radius 1. */
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0.25, 0), rr_v3(1, 0, 0)), 1, 4, 6, -1, -1);
    /* At y = 0.5625: radius 1.5, from +z. */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 0.5625, 4), rr_v3(0, 0, -1)), 1, 2.5, 5.5, -1, -1);
    /* Down the axis: cap (+y at y = 1) to the vertex (quadric at y = 0). */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, 3, 0), rr_v3(0, -1, 0)), 1, 2, 3, 3, -1);
}

static void quadric_hyperboloid(void **state)
{
    (void)state;
    /* One sheet: waist radius 0.5, end radius 1 at y = +-1: x^2 + z^2 - 0.75 y^2 - 0.25 <= 0. */
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[1][1] = -0.75, q[2][2] = 1, q[3][3] = -0.25;
    rr_vec3 lo = rr_v3(-1, -1, -1), hi = rr_v3(1, 1, 1);
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 1, 4.5, 5.5, -1, -1);
    /* At y = 0.8: r^2 = 0.25 + 0.48 = 0.73. */
    double r = sqrt(0.73);
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0.8, 0), rr_v3(1, 0, 0)), 1, 5 - r, 5 + r, -1, -1);
    /* Along the axis: caps. */
    quadric_case(q, lo, hi, ray_make(rr_v3(0, -3, 0), rr_v3(0, 1, 0)), 1, 2, 4, 2, 3);
    /* A < 0 for a steep ray: inside outside the roots, two pieces, clipped by
     * the box to one span per nappe piece. Ray x = 0.6, z = 0, along y: inside
     * where 0.36 - 0.25 <= 0.75 y^2, |y| >= sqrt(0.11/0.75). */
    scene *s = scene_new();
    uint32_t leaf = quadric_leaf(s, q, lo, hi, 0);
    rt_spans sp;
    rt_csg_spans(s, NULL, leaf, ray_make(rr_v3(0.6, -3, 0), rr_v3(0, 1, 0)), -INFINITY, INFINITY, &sp);
    double y = sqrt(0.11 / 0.75);
    expect_spans(&sp, 2, (double[]){2, 3 - y, 3 + y, 4}, 1e-14);
    assert_int_equal(sp.s[0].in.surface, 2);
    assert_int_equal(sp.s[0].out.surface, -1);
    assert_int_equal(sp.s[1].in.surface, -1);
    assert_int_equal(sp.s[1].out.surface, 3);
    scene_destroy(s);
}

static void quadric_general(void **state)
{
    (void)state;
    /* Half-space x + y <= 1 (A = 0 for every ray: linear) in the box [-2, 2]^3. */
    double q[4][4];
    q_zero(q);
    q[0][3] = q[3][0] = 0.5, q[1][3] = q[3][1] = 0.5, q[3][3] = -1;
    rr_vec3 lo = rr_v3(-2, -2, -2), hi = rr_v3(2, 2, 2);
    quadric_case(q, lo, hi, ray_make(rr_v3(-5, 0.25, 0), rr_v3(1, 0, 0)), 1, 3, 5.75, 0, -1);
    quadric_case(q, lo, hi, ray_make(rr_v3(5, 0.25, 0), rr_v3(-1, 0, 0)), 1, 4.25, 7, -1, 0);
    /* Hyperbolic paraboloid (saddle) z <= x^2 - y^2 ... as -x^2 + y^2 + z <= 0:
     * along x at y = 0.5, z = 0: inside where x^2 >= 0.25: two spans. */
    q_zero(q);
    q[0][0] = -1, q[1][1] = 1, q[2][3] = q[3][2] = 0.5;
    scene *s = scene_new();
    uint32_t leaf = quadric_leaf(s, q, lo, hi, 0);
    rt_spans sp;
    rt_csg_spans(s, NULL, leaf, ray_make(rr_v3(-5, 0.5, 0), rr_v3(1, 0, 0)), -INFINITY, INFINITY, &sp);
    expect_spans(&sp, 2, (double[]){3, 4.5, 5.5, 7}, 1e-14);
    scene_destroy(s);
    /* A rotated, shifted ellipsoid given as a general Q: x = R p + c with
     * radii (1, 2, 3): Q = M^T diag(1, 1/4, 1/9, -1) M, M the world->unit map.
     * Check the t against the sphere in the unit frame. */
    double ang = 0.7, ca = cos(ang), sa = sin(ang);
    rr_xform unit = {{{ca / 1, sa / 1, 0}, {-sa / 2, ca / 2, 0}, {0, 0, 1.0 / 3}}, {0, 0, 0}};
    rr_vec3 cen = rr_v3(0.3, -0.2, 0.1);
    unit.t = rr_v3_neg(rr_xform_vector(&unit, cen)); /* unit(p) = L (p - c) */
    double M[4][4] = {{0}};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            M[i][j] = unit.m[i][j];
        M[i][3] = rr_v3_get(unit.t, i);
    }
    M[3][3] = 1;
    double D[4] = {1, 1, 1, -1};
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            q[i][j] = 0;
            for (int k = 0; k < 4; k++)
                q[i][j] += M[k][i] * D[k] * M[k][j];
        }
    lo = rr_v3(-4, -4, -4), hi = rr_v3(4, 4, 4);
    rr_rng rng = rr_rng_make(11, 0);
    int tested = 0;
    rr_xform world = xform_inverse(&unit);
    for (int i = 0; i < 200; i++) {
        rr_vec3 o = rr_v3(10 * rr_rng_uniform(&rng) - 5, 10 * rr_rng_uniform(&rng) - 5, 10 * rr_rng_uniform(&rng) - 5);
        /* Aimed at a point inside the ellipsoid (|unit point| < 0.9). */
        rr_vec3 u = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5);
        rr_vec3 d = rr_v3_sub(rr_xform_point(&world, rr_v3_scale(u, 1.5)), o);
        rr_ray ur = ray_make(rr_xform_point(&unit, o), rr_xform_vector(&unit, d));
        rr_vec3 oc = ur.o;
        double a = rr_v3_dot(ur.d, ur.d), b = rr_v3_dot(ur.d, oc), c = rr_v3_dot(oc, oc) - 1;
        double disc = b * b - a * c;
        if (disc <= 1e-4 * a * a) /* half chord below 0.01 in t: ill-conditioned */
            continue;
        double t0 = (-b - sqrt(disc)) / a, t1 = (-b + sqrt(disc)) / a;
        quadric_case_tol(q, lo, hi, ray_make(o, d), 1, t0, t1, -1, -1, 1e-10);
        tested++;
    }
    assert_true(tested > 30);
}

/* ---- boxes ---- */

static void box_leaf_faces(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t leaf = box_leaf(s, rr_v3(-1, -2, -3), rr_v3(1, 2, 3), 0);
    uint32_t obj = add_solid(s, leaf, 0);
    rt_spans sp;
    rt_csg_spans(s, NULL, leaf, ray_make(rr_v3(0, 0, 10), rr_v3(0, 0, -1)), 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){7, 13}, 0);
    assert_int_equal(sp.s[0].in.surface, 5);
    assert_int_equal(sp.s[0].out.surface, 4);
    rt_hit h;
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(5, 1, 1), rr_v3(-1, 0, 0)), 0, INFINITY, &h));
    assert_near(h.t, 4, 0);
    assert_near(h.normal.x, 1, 0);
    /* Along an edge: touching only, no span. */
    rt_csg_spans(s, NULL, leaf, ray_make(rr_v3(1, 2, 10), rr_v3(0, 0, -1)), 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    /* tmax cuts; a span beyond tmax is gone; tmin inside gives the exit. */
    rt_csg_spans(s, NULL, leaf, ray_make(rr_v3(0, 0, 10), rr_v3(0, 0, -1)), 0, 5, &sp);
    assert_int_equal(sp.n, 0);
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(0, 0, 10), rr_v3(0, 0, -1)), 8, 100, &h));
    assert_near(h.t, 13, 0);
    assert_false(h.front);
    scene_destroy(s);
}

/* ---- CSG ---- */

static void csg_sphere_minus_sphere(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t big = sphere_leaf(s, rr_v3(0, 0, 0), 1, 1);
    uint32_t bite = sphere_leaf(s, rr_v3(1, 0, 0), 0.5, 2);
    uint32_t root = op_node(s, SCENE_CSG_DIFFERENCE, big, bite);
    uint32_t obj = add_solid(s, root, 0);
    rt_spans sp;
    rt_csg_spans(s, NULL, root, ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){4, 5.5}, 1e-15);
    assert_int_equal(sp.s[0].in.leaf, big);
    assert_int_equal(sp.s[0].in.flip, 0);
    assert_int_equal(sp.s[0].out.leaf, bite);
    assert_int_equal(sp.s[0].out.flip, 1);
    /* From +x: the first surface is the bite at x = 0.5; its normal points
     * into the removed sphere (towards its centre (1, 0, 0)), i.e. outward
     * of the solid and towards the viewer; the material is the bite's. */
    rt_hit h;
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(5, 0, 0), rr_v3(-1, 0, 0)), 0, INFINITY, &h));
    assert_near(h.t, 4.5, 1e-15);
    assert_near(h.normal.x, 1, 1e-15);
    assert_true(h.front);
    assert_int_equal(h.material, 2);
    assert_int_equal(h.part, bite);
    /* Off-axis hit on the bite: the normal is (centre - p)/0.5. */
    rr_ray ray = ray_make(rr_v3(5, 0.3, 0), rr_v3(-1, 0, 0));
    assert_true(rt_solid_closest(s, NULL, obj, ray, 0, INFINITY, &h));
    rr_vec3 want = rr_v3_scale(rr_v3_sub(rr_v3(1, 0, 0), h.point), 2.0);
    assert_near(h.normal.x, want.x, 1e-12);
    assert_near(h.normal.y, want.y, 1e-12);
    assert_near(h.point.x, 1 - 0.4, 1e-14);
    /* Far off the bite (x < 0.5) the big sphere's material. */
    assert_true(rt_solid_closest(s, NULL, obj, ray_make(rr_v3(-5, 0.3, 0), rr_v3(1, 0, 0)), 0, INFINITY, &h));
    assert_int_equal(h.material, 1);
    /* Double negation: (A - (B - C)): C's surface is not flipped. A: big
     * sphere r = 2; B: sphere r = 1.5 at (2, 0, 0); C: sphere r = 0.5 at
     * (1, 0, 0). Along x from -5: A from -2; B removes [0.5, ...]; C restores
     * [0.5, 1.5] ... inside A - (B - C) = [-2, 0.5] U [0.5, 1.5] = [-2, 1.5]. */
    scene *s2 = scene_new();
    uint32_t A = sphere_leaf(s2, rr_v3(0, 0, 0), 2, 0);
    uint32_t B = sphere_leaf(s2, rr_v3(2, 0, 0), 1.5, 1);
    uint32_t C = sphere_leaf(s2, rr_v3(1.5, 0, 0), 0.5, 2);
    uint32_t bc = op_node(s2, SCENE_CSG_DIFFERENCE, B, C);
    uint32_t r2 = op_node(s2, SCENE_CSG_DIFFERENCE, A, bc);
    add_solid(s2, r2, 0);
    /* A: [-2, 2]; B: [0.5, 3.5]; C: [1, 2]; B - C: [0.5, 1] U [2, 3.5];
     * A - (B - C) = [-2, 0.5] U [1, 2]. The end at 1 is C's entry, flipped twice. */
    rt_csg_spans(s2, NULL, r2, ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 0, INFINITY, &sp);
    expect_spans(&sp, 2, (double[]){3, 5.5, 6, 7}, 1e-15);
    assert_int_equal(sp.s[0].out.leaf, B);
    assert_int_equal(sp.s[0].out.flip, 1);
    assert_int_equal(sp.s[1].in.leaf, C);
    assert_int_equal(sp.s[1].in.flip, 0);
    rt_hit h2;
    assert_true(rt_solid_closest(s2, NULL, 0, ray_make(rr_v3(0.75, 0, 0), rr_v3(1, 0, 0)), 0, INFINITY, &h2));
    assert_near(h2.t, 0.25, 1e-15);
    assert_true(h2.front);
    assert_near(h2.normal.x, -1, 1e-15); /* C's outward normal at its near pole */
    scene_destroy(s2);
    scene_destroy(s);
}

static void csg_lens_and_union(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t a = sphere_leaf(s, rr_v3(-0.5, 0, 0), 1, 1);
    uint32_t b = sphere_leaf(s, rr_v3(0.5, 0, 0), 1, 2);
    uint32_t lens = op_node(s, SCENE_CSG_INTERSECTION, a, b);
    uint32_t uni = op_node(s, SCENE_CSG_UNION, a, b);
    rt_spans sp;
    rr_ray ray = ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0));
    rt_csg_spans(s, NULL, lens, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){4.5, 5.5}, 1e-15);
    assert_int_equal(sp.s[0].in.leaf, b); /* entering the lens through b's surface */
    assert_int_equal(sp.s[0].out.leaf, a);
    rt_csg_spans(s, NULL, uni, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){3.5, 6.5}, 1e-15);
    assert_int_equal(sp.s[0].in.leaf, a);
    assert_int_equal(sp.s[0].out.leaf, b);
    /* Disjoint union: two spans; the lens of disjoint spheres: none. */
    uint32_t c = sphere_leaf(s, rr_v3(3, 0, 0), 0.5, 3);
    uint32_t u2 = op_node(s, SCENE_CSG_UNION, a, c);
    uint32_t i2 = op_node(s, SCENE_CSG_INTERSECTION, a, c);
    rt_csg_spans(s, NULL, u2, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 2, (double[]){3.5, 5.5, 7.5, 8.5}, 1e-15);
    rt_csg_spans(s, NULL, i2, ray, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    /* Two boxes sharing a face: one span (no inner face), and their
     * intersection is empty (a face has no volume). */
    uint32_t b1 = box_leaf(s, rr_v3(0, 0, 0), rr_v3(1, 1, 1), 0);
    uint32_t b2 = box_leaf(s, rr_v3(1, 0, 0), rr_v3(2, 1, 1), 0);
    uint32_t bu = op_node(s, SCENE_CSG_UNION, b1, b2);
    uint32_t bi = op_node(s, SCENE_CSG_INTERSECTION, b1, b2);
    rr_ray r2 = ray_make(rr_v3(-1, 0.5, 0.5), rr_v3(1, 0, 0));
    rt_csg_spans(s, NULL, bu, r2, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){1, 3}, 0);
    rt_csg_spans(s, NULL, bi, r2, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    /* Membership. */
    assert_true(rt_csg_contains(s, NULL, lens, rr_v3(0, 0.8, 0)));
    assert_false(rt_csg_contains(s, NULL, lens, rr_v3(0, 0.9, 0)));
    assert_true(rt_csg_contains(s, NULL, uni, rr_v3(-1.4, 0, 0)));
    assert_false(rt_csg_contains(s, NULL, lens, rr_v3(-1.4, 0, 0)));
    /* Bad node: nothing. */
    rt_csg_spans(s, NULL, (uint32_t)s->ncsg, ray, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    assert_false(rt_csg_contains(s, NULL, (uint32_t)s->ncsg, rr_v3(0, 0, 0)));
    scene_destroy(s);
}

/* ---- volumes by ray casting ----
 *
 * N x N parallel rays along +z through the centres of the cells of a grid
 * over the solid's bbox; volume = sum of span lengths x cell area. That is
 * the midpoint rule for the integral of the chord length L(x, y) over the
 * plane. Inside a silhouette L is smooth and the rule's error is O(h^2);
 * the error comes from the cells cut by a silhouette or crease curve, where
 * L behaves like sqrt(distance to the curve): about P/h such cells (P the
 * curves' length), each off by at most ~h^2 sqrt(h) (scaled by the
 * curvature), so the relative error is bounded by ~P h^1.5 / V. With N = 256
 * over a bbox of extent ~2, h ~ 0.008, P ~ 10, V ~ 1.3..8 that is ~5e-3 at
 * worst, and in practice far less because the signed cell errors cancel
 * along a smooth curve (measured: 1e-7..1e-4, printed). 0.5% therefore
 * holds with margin on any grid at least this fine, while a wrong
 * combination (a lost, doubled or unflipped piece) changes the volume by
 * the volume of that piece, 5% or more in each of these cases. */
static double cast_volume(const scene *s, const rt_accel *a, uint32_t node, int N)
{
    const scene_csg_node *n = &s->csg[node];
    double x0 = n->bbox_lo.x, y0 = n->bbox_lo.y, hx = (n->bbox_hi.x - x0) / N, hy = (n->bbox_hi.y - y0) / N;
    double z = n->bbox_lo.z - 1;
    double vol = 0;
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            rt_spans sp;
            rr_ray r = ray_make(rr_v3(x0 + (i + 0.5) * hx, y0 + (j + 0.5) * hy, z), rr_v3(0, 0, 1));
            rt_csg_spans(s, a, node, r, 0, INFINITY, &sp);
            for (int k = 0; k < sp.n; k++)
                vol += sp.s[k].out.t - sp.s[k].in.t;
        }
    return vol * hx * hy;
}

/* Volume of the intersection of two balls of radii R, r at distance d (d < R + r). */
static double lens_volume(double R, double r, double d)
{
    return RR_PI * (R + r - d) * (R + r - d) * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) /
           (12 * d);
}

static void check_volume(const char *what, double got, double want)
{
    double rel = fabs(got - want) / want;
    printf("[ volume   ] %-28s cast %.6f analytic %.6f relative error %.2e\n", what, got, want, rel);
    if (!(rel < 0.005))
        fail_msg("%s: volume %.6f, analytic %.6f", what, got, want);
}

static void csg_volumes(void **state)
{
    (void)state;
    scene *s = scene_new();
    /* Lens: balls of radius 1 at distance 1. */
    uint32_t a = sphere_leaf(s, rr_v3(-0.5, 0, 0), 1, 0);
    uint32_t b = sphere_leaf(s, rr_v3(0.5, 0, 0), 1, 0);
    uint32_t lens = op_node(s, SCENE_CSG_INTERSECTION, a, b);
    check_volume("lens (sphere & sphere)", cast_volume(s, NULL, lens, 256), lens_volume(1, 1, 1));
    /* Bite: ball radius 1 minus ball radius 0.6 at distance 0.9. */
    uint32_t big = sphere_leaf(s, rr_v3(0, 0, 0), 1, 0);
    uint32_t bite = sphere_leaf(s, rr_v3(0.9, 0, 0.1), 0.6, 0);
    uint32_t bitten = op_node(s, SCENE_CSG_DIFFERENCE, big, bite);
    double d = sqrt(0.81 + 0.01);
    check_volume("sphere - sphere (bite)", cast_volume(s, NULL, bitten, 256),
                 4.0 / 3.0 * RR_PI - lens_volume(1, 0.6, d));
    /* Union of the same two balls. */
    uint32_t uni = op_node(s, SCENE_CSG_UNION, big, bite);
    check_volume("sphere | sphere", cast_volume(s, NULL, uni, 256),
                 4.0 / 3.0 * RR_PI * (1 + 0.216) - lens_volume(1, 0.6, d));
    /* Mesh cube [-1, 1]^3 minus a ball of radius 0.7 at the corner (1, 1, 1):
     * an eighth of the ball is removed. Through the per-leaf BVH. */
    uint32_t cube = cube_mesh(s, rr_v3(-1, -1, -1), rr_v3(1, 1, 1), 0);
    uint32_t ball = sphere_leaf(s, rr_v3(1, 1, 1), 0.7, 0);
    uint32_t cut = op_node(s, SCENE_CSG_DIFFERENCE, cube, ball);
    add_solid(s, cut, 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    check_volume("mesh cube - sphere (corner)", cast_volume(s, acc, cut, 256),
                 8 - 4.0 / 3.0 * RR_PI * 0.343 / 8);
    /* A cylinder with caps and a cone (quadrics). */
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[2][2] = 1, q[3][3] = -0.25;
    uint32_t cyl = quadric_leaf(s, q, rr_v3(-0.5, -1, -0.5), rr_v3(0.5, 1, 0.5), 0);
    check_volume("cylinder r 0.5 h 2", cast_volume(s, NULL, cyl, 256), RR_PI * 0.25 * 2);
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* ---- meshes ---- */

/* Spans of the convex polyhedron of a closed mesh leaf by clipping the line
 * against every face plane (Cyrus-Beck): the analytic reference. Returns 0
 * when the line misses (or only touches). */
static int convex_span(const scene *s, uint32_t leaf, rr_ray r, double *t0, double *t1)
{
    const scene_csg_node *n = &s->csg[leaf];
    double lo = -INFINITY, hi = INFINITY;
    for (size_t i = n->tri_first; i < n->tri_first + n->tri_count; i++) {
        rr_vec3 A = s->csg_verts[s->csg_tris[i][0]], B = s->csg_verts[s->csg_tris[i][1]],
                C = s->csg_verts[s->csg_tris[i][2]];
        rr_vec3 nn = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
        double num = rr_v3_dot(nn, rr_v3_sub(A, r.o)), den = rr_v3_dot(nn, r.d);
        if (den == 0) {
            if (num < 0)
                return 0;
            continue;
        }
        double t = num / den;
        if (den < 0)
            lo = fmax(lo, t);
        else
            hi = fmin(hi, t);
    }
    *t0 = lo;
    *t1 = hi;
    return lo < hi;
}

static void mesh_cube_vertices_and_edges(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t cube = cube_mesh(s, rr_v3(0, 0, 0), rr_v3(1, 1, 1), 0);
    uint32_t obj = add_solid(s, cube, 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rt_spans sp, sp2;
    /* Down the body diagonal through two vertices. */
    rr_ray r = ray_make(rr_v3(-1, -1, -1), rr_v3(1, 1, 1));
    rt_csg_spans(s, NULL, cube, r, -INFINITY, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){1, 2}, 1e-15);
    /* Through the shared diagonal of the face triangles, from each side, and
     * through every face diagonal of the cube. */
    double diag[] = {0.25, 0.5, 0.75};
    for (int k = 0; k < 3; k++) {
        double u = diag[k];
        rr_vec3 o[6] = {rr_v3(u, u, -1), rr_v3(u, u, 2), rr_v3(u, -1, u), rr_v3(u, 2, u), rr_v3(-1, u, u), rr_v3(2, u, u)};
        rr_vec3 d[6] = {rr_v3(0, 0, 1), rr_v3(0, 0, -1), rr_v3(0, 1, 0), rr_v3(0, -1, 0), rr_v3(1, 0, 0), rr_v3(-1, 0, 0)};
        for (int i = 0; i < 6; i++) {
            rt_csg_spans(s, NULL, cube, ray_make(o[i], d[i]), -INFINITY, INFINITY, &sp);
            expect_spans(&sp, 1, (double[]){1, 2}, 1e-15);
            /* Diagonals the other way (x = 1 - y). */
            rr_vec3 o2 = o[i];
            if (d[i].z != 0)
                o2.y = 1 - u;
            else if (d[i].y != 0)
                o2.z = 1 - u;
            else
                o2.z = 1 - u;
            rt_csg_spans(s, NULL, cube, ray_make(o2, d[i]), -INFINITY, INFINITY, &sp);
            expect_spans(&sp, 1, (double[]){1, 2}, 1e-15);
        }
    }
    /* Along edges and in face planes: the ray is on the boundary; whether it
     * counts as inside may go either way, but the spans are well formed and
     * lie on the closed cube, and the BVH agrees with brute force. */
    rr_ray edge_rays[] = {
        ray_make(rr_v3(-1, 0, 0), rr_v3(1, 0, 0)),     ray_make(rr_v3(-1, 1, 1), rr_v3(1, 0, 0)),
        ray_make(rr_v3(0, -1, 1), rr_v3(0, 1, 0)),     ray_make(rr_v3(1, 1, 3), rr_v3(0, 0, -1)),
        ray_make(rr_v3(-1, 0.5, 0), rr_v3(1, 0, 0)),   ray_make(rr_v3(-1, 0.3, 1), rr_v3(2, 1, 0)),
        ray_make(rr_v3(0.5, 0.5, 1), rr_v3(1, 0, 0)),  ray_make(rr_v3(-1, -1, 0), rr_v3(1, 1, 0)),
        ray_make(rr_v3(-1, -1, 0.5), rr_v3(1, 1, 0)),  ray_make(rr_v3(-1, 2, 0.5), rr_v3(1, -1, 0)),
    };
    for (size_t i = 0; i < sizeof edge_rays / sizeof edge_rays[0]; i++) {
        rt_csg_spans(s, NULL, cube, edge_rays[i], -INFINITY, INFINITY, &sp);
        rt_csg_spans(s, acc, cube, edge_rays[i], -INFINITY, INFINITY, &sp2);
        spans_well_formed(&sp);
        assert_int_equal(sp.n, sp2.n);
        assert_true(sp.n <= 1);
        for (int k = 0; k < sp.n; k++) {
            assert_true(sp.s[k].in.t == sp2.s[k].in.t && sp.s[k].out.t == sp2.s[k].out.t);
            rr_vec3 m = rr_ray_at(edge_rays[i], 0.5 * (sp.s[k].in.t + sp.s[k].out.t));
            assert_true(m.x >= 0 && m.x <= 1 && m.y >= 0 && m.y <= 1 && m.z >= 0 && m.z <= 1);
        }
    }
    /* Rays through every vertex in random directions (starting there, so that
     * they pass exactly through it): the span is the analytic one, or none
     * when the ray only touches the corner. */
    rr_rng rng = rr_rng_make(5, 0);
    int crossing = 0, touching = 0;
    for (int i = 0; i < 4000; i++) {
        int c = i % 8;
        rr_vec3 v = rr_v3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        rr_vec3 d = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5);
        rr_ray ray = ray_make(v, d); /* exactly through v, at t = 0 */
        rt_csg_spans(s, NULL, cube, ray, -INFINITY, INFINITY, &sp);
        spans_well_formed(&sp);
        double t0, t1;
        if (convex_span(s, cube, ray, &t0, &t1) && t1 - t0 > 1e-9) {
            crossing++;
            expect_spans(&sp, 1, (double[]){t0, t1}, 1e-12);
        } else {
            touching++;
            if (sp.n != 0)
                fail_msg("vertex %d dir (%.17g, %.17g, %.17g): %d spans [%.17g, %.17g] where the ray only touches", c,
                         d.x, d.y, d.z, sp.n, sp.s[0].in.t, sp.s[0].out.t);
        }
        rt_csg_spans(s, acc, cube, ray, -INFINITY, INFINITY, &sp2);
        assert_int_equal(sp.n, sp2.n);
    }
    assert_true(crossing > 500 && touching > 500);
    /* Membership at and near vertices. */
    assert_true(rt_csg_contains(s, NULL, cube, rr_v3(0.5, 0.5, 0.5)));
    assert_true(rt_csg_contains(s, acc, cube, rr_v3(0.999, 0.001, 0.5)));
    assert_false(rt_csg_contains(s, acc, cube, rr_v3(1.001, 0.5, 0.5)));
    assert_false(rt_csg_contains(s, NULL, cube, rr_v3(2, 2, 2)));
    (void)obj;
    rt_accel_destroy(acc);
    scene_destroy(s);
}

static void mesh_sphere_vertices(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t m = uv_sphere_mesh(s, rr_v3(0.1, -0.2, 0.3), 1.0, 24, 12, 0);
    add_solid(s, m, 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rr_rng rng = rr_rng_make(9, 0);
    rt_spans sp, sp2;
    int crossing = 0;
    for (int i = 0; i < 3000; i++) {
        /* A vertex of the mesh (the poles have the largest fans). */
        size_t vi = (size_t)(rr_rng_u32(&rng) % s->ncsg_verts);
        rr_vec3 v = s->csg_verts[vi];
        rr_vec3 d = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5);
        if (i % 3 == 0) /* axis-aligned directions too: rays through both poles */
            d = rr_v3(0, 0, i % 2 ? 1 : -1);
        rr_ray ray = ray_make(v, d); /* exactly through v, at t = 0 */
        rt_csg_spans(s, NULL, m, ray, -INFINITY, INFINITY, &sp);
        rt_csg_spans(s, acc, m, ray, -INFINITY, INFINITY, &sp2);
        spans_well_formed(&sp);
        double t0, t1;
        if (convex_span(s, m, ray, &t0, &t1) && t1 - t0 > 1e-9) {
            crossing++;
            expect_spans(&sp, 1, (double[]){t0, t1}, 1e-11);
        } else {
            assert_int_equal(sp.n, 0);
        }
        assert_int_equal(sp.n, sp2.n);
        for (int k = 0; k < sp.n; k++)
            assert_true(sp.s[k].in.t == sp2.s[k].in.t && sp.s[k].out.t == sp2.s[k].out.t &&
                        sp.s[k].in.surface == sp2.s[k].in.surface && sp.s[k].out.surface == sp2.s[k].out.surface);
    }
    assert_true(crossing > 1000);
    /* Rays from outside aimed at a vertex: they pass within rounding of it,
     * where the edge functions of the fan are within rounding of zero and
     * only exact signs keep the fan consistent (exactly one crossing). */
    crossing = 0;
    for (int i = 0; i < 20000; i++) {
        rr_vec3 v = s->csg_verts[rr_rng_u32(&rng) % s->ncsg_verts];
        rr_vec3 o = rr_v3(6 * rr_rng_uniform(&rng) - 3, 6 * rr_rng_uniform(&rng) - 3, 6 * rr_rng_uniform(&rng) - 3);
        rr_ray ray = ray_make(o, rr_v3_sub(v, o));
        rt_csg_spans(s, NULL, m, ray, -INFINITY, INFINITY, &sp);
        rt_csg_spans(s, acc, m, ray, -INFINITY, INFINITY, &sp2);
        spans_well_formed(&sp);
        assert_int_equal(sp.n, sp2.n);
        double t0, t1;
        if (convex_span(s, m, ray, &t0, &t1) && t1 - t0 > 1e-6) {
            crossing++;
            expect_spans(&sp, 1, (double[]){t0, t1}, 1e-9);
        } else {
            assert_true(sp.n == 0 || (sp.n == 1 && sp.s[0].out.t - sp.s[0].in.t < 1e-6));
        }
    }
    assert_true(crossing > 5000);
    /* Rays starting on an edge (up to the rounding of the point): the edge
     * function of that edge is within rounding of zero, so its sign needs
     * the exact evaluation to agree between the two triangles' views. */
    crossing = 0;
    const scene_csg_node *mn = &s->csg[m];
    for (int i = 0; i < 20000; i++) {
        const uint32_t *tri = s->csg_tris[mn->tri_first + rr_rng_u32(&rng) % mn->tri_count];
        int k = (int)(rr_rng_u32(&rng) % 3);
        rr_vec3 A = s->csg_verts[tri[k]], B = s->csg_verts[tri[(k + 1) % 3]];
        rr_vec3 o = rr_v3_madd(A, rr_v3_sub(B, A), rr_rng_uniform(&rng));
        rr_vec3 d = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5);
        rr_ray ray = ray_make(o, d);
        rt_csg_spans(s, NULL, m, ray, -INFINITY, INFINITY, &sp);
        rt_csg_spans(s, acc, m, ray, -INFINITY, INFINITY, &sp2);
        spans_well_formed(&sp);
        assert_int_equal(sp.n, sp2.n);
        double t0, t1;
        if (convex_span(s, m, ray, &t0, &t1) && t1 - t0 > 1e-6) {
            crossing++;
            expect_spans(&sp, 1, (double[]){t0, t1}, 1e-9);
        } else {
            assert_true(sp.n == 0 || (sp.n == 1 && sp.s[0].out.t - sp.s[0].in.t < 1e-6));
        }
    }
    assert_true(crossing > 5000);
    /* Through both poles exactly (vertices shared by 24 triangles). */
    rr_ray ray = ray_make(rr_v3(0.1, -0.2, 5), rr_v3(0, 0, -1));
    rt_csg_spans(s, acc, m, ray, 0, INFINITY, &sp);
    expect_spans(&sp, 1, (double[]){3.7, 5.7}, 1e-14);
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* The tie-break's sign convention: a fan of 6 triangles around a centre vertex
 * in the plane z = 0 (normal +z) over a huge triangle at z = -1 (normal -z).
 * A ray from above through the centre or along a spoke must cross exactly
 * one fan triangle: then it enters at t = 2 and leaves through the big
 * triangle (one span); missing the fan gives no span, crossing it twice
 * leaves the winding at 1 after the big triangle (a span to tmax). */
static void mesh_tie_break_fan(void **state)
{
    (void)state;
    scene *s = scene_new();
    /* Dyadic coordinates, so that the points on the spokes below are exact. */
    rr_vec3 v[10] = {rr_v3(0, 0, 0),        rr_v3(1, 0, 0),         rr_v3(0.5, 0.75, 0),    rr_v3(-0.5, 0.75, 0),
                     rr_v3(-1, 0, 0),       rr_v3(-0.5, -0.75, 0),  rr_v3(0.5, -0.75, 0),   rr_v3(-1000, -1000, -1),
                     rr_v3(-1000, 3000, -1), rr_v3(3000, -1000, -1)};
    uint32_t t[7][3];
    for (int i = 0; i < 6; i++)
        t[i][0] = 0, t[i][1] = (uint32_t)(1 + i), t[i][2] = (uint32_t)(1 + (i + 1) % 6);
    t[6][0] = 7, t[6][1] = 8, t[6][2] = 9;
    uint32_t fan = mesh_leaf(s, v, 10, (const uint32_t(*)[3])t, 7, 0);
    rr_rng rng = rr_rng_make(3, 0);
    for (int i = 0; i < 3000; i++) {
        /* The ray starts exactly at the centre or on a spoke (the fan is
         * crossed at t = 0), and goes down. */
        rr_vec3 p = v[0];
        rr_vec3 spoke = v[1 + i % 6];
        if (i % 2)
            p = rr_v3_scale(spoke, (double)(1 + rr_rng_u32(&rng) % 15) / 16.0);
        rr_vec3 d = rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5, -rr_rng_uniform(&rng) - 0.05);
        if (i % 5 == 0)
            d = rr_v3(0, 0, -1);
        if (i % 7 == 0) /* in the vertical plane of a spoke: along the edge, seen from the ray */
            d = rr_v3(spoke.x, spoke.y, -0.5);
        if (i % 11 == 0)
            d = rr_v3(-spoke.x, -spoke.y, -0.25);
        rt_spans sp;
        /* From above: enters the fan at 0, leaves through the big triangle. */
        rt_csg_spans(s, NULL, fan, ray_make(p, d), -1e9, 1e9, &sp);
        expect_spans(&sp, 1, (double[]){0, -1 / d.z}, 1e-9);
        /* From below: enters the big triangle, leaves through the fan at 0. */
        rt_csg_spans(s, NULL, fan, ray_make(p, rr_v3_neg(d)), -1e9, 1e9, &sp);
        expect_spans(&sp, 1, (double[]){1 / d.z, 0}, 1e-9);
    }
    scene_destroy(s);
}

static void mesh_minus_sphere_spans(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t cube = cube_mesh(s, rr_v3(-1, -1, -1), rr_v3(1, 1, 1), 1);
    uint32_t ball = sphere_leaf(s, rr_v3(0, 0, 0), 0.5, 2);
    uint32_t root = op_node(s, SCENE_CSG_DIFFERENCE, cube, ball);
    uint32_t obj = add_solid(s, root, 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rt_spans sp;
    rt_csg_spans(s, acc, root, ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 0, INFINITY, &sp);
    expect_spans(&sp, 2, (double[]){4, 4.5, 5.5, 6}, 1e-15);
    assert_int_equal(sp.s[0].in.leaf, cube);
    assert_true(sp.s[0].in.surface >= 0);
    assert_int_equal(sp.s[0].out.leaf, ball);
    /* From inside the hollow: the first hit is the hollow's wall, seen from
     * inside the removed ball, i.e. the solid's outside: a front face, normal
     * towards the centre, the ball's material. */
    rt_hit h;
    assert_true(rt_solid_closest(s, acc, obj, ray_make(rr_v3(0, 0, 0), rr_v3(0, 1, 0)), 0, INFINITY, &h));
    assert_near(h.t, 0.5, 1e-15);
    assert_true(h.front);
    assert_near(h.normal.y, -1, 1e-15);
    assert_int_equal(h.material, 2);
    /* The cube's face: its material and face normal. */
    assert_true(rt_solid_closest(s, acc, obj, ray_make(rr_v3(0.2, 5, 0.7), rr_v3(0, -1, 0)), 0, INFINITY, &h));
    assert_near(h.t, 4, 1e-15);
    assert_near(h.normal.y, 1, 1e-15);
    assert_int_equal(h.material, 1);
    assert_true(rt_csg_contains(s, acc, root, rr_v3(0.9, 0.9, 0.9)));
    assert_false(rt_csg_contains(s, acc, root, rr_v3(0.1, 0.1, 0.1)));
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* ---- the scene BVH against the reference, random rays ---- */

static void accel_matches_reference(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t a = sphere_leaf(s, rr_v3(-0.5, 0, 0), 1, 1);
    uint32_t b = sphere_leaf(s, rr_v3(0.5, 0, 0), 1, 2);
    add_solid(s, op_node(s, SCENE_CSG_INTERSECTION, a, b), 0);
    uint32_t c = cube_mesh(s, rr_v3(2, -1, -1), rr_v3(4, 1, 1), 3);
    uint32_t d = sphere_leaf(s, rr_v3(3, 1, 0), 0.7, 0);
    add_solid(s, op_node(s, SCENE_CSG_DIFFERENCE, c, d), 1);
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[2][2] = 1, q[1][1] = -0.25;
    uint32_t cone = quadric_leaf(s, q, rr_v3(-1, 0, -1), rr_v3(1, 2, 1), 2);
    rr_xform x = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {0, -3, 0}};
    leaf_transform(s, cone, x);
    add_solid(s, cone, 0);
    uint32_t m = uv_sphere_mesh(s, rr_v3(-3, 0, 0), 0.8, 16, 8, 1);
    uint32_t e = box_leaf(s, rr_v3(-3, -1, -1), rr_v3(-2, 1, 1), 2);
    add_solid(s, op_node(s, SCENE_CSG_UNION, m, e), 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rr_rng rng = rr_rng_make(42, 0);
    int hits = 0;
    for (int i = 0; i < 20000; i++) {
        rr_vec3 o = rr_v3(12 * rr_rng_uniform(&rng) - 6, 12 * rr_rng_uniform(&rng) - 6, 12 * rr_rng_uniform(&rng) - 6);
        rr_vec3 t = rr_v3(8 * rr_rng_uniform(&rng) - 4, 4 * rr_rng_uniform(&rng) - 2, 2 * rr_rng_uniform(&rng) - 1);
        rr_ray r = ray_make(o, rr_v3_sub(t, o));
        rt_hit h1, h2;
        int f1 = rt_ref_closest(s, r, 1e-9, INFINITY, &h1);
        int f2 = rt_accel_closest(acc, r, 1e-9, INFINITY, &h2);
        assert_int_equal(f1, f2);
        if (!f1)
            continue;
        hits++;
        assert_true(h1.t == h2.t);
        assert_int_equal(h1.object, h2.object);
        assert_int_equal(h1.part, h2.part);
        assert_int_equal(h1.material, h2.material);
        assert_int_equal(h1.front, h2.front);
        assert_near(rr_v3_dot(h1.normal, h2.normal), 1, 1e-12);
        assert_near(rr_v3_len(h1.normal), 1, 1e-12);
        assert_true(rr_v3_dot(h1.normal, r.d) <= 0);
        /* Any-hit agrees on occlusion. */
        assert_true(rt_accel_occluded(acc, r, 1e-9, INFINITY));
    }
    assert_true(hits > 5000);
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* Point membership against the analytic solid, random points. */
static void contains_random(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t cube = uv_sphere_mesh(s, rr_v3(0, 0, 0), 1, 32, 16, 0);
    double q[4][4];
    q_zero(q);
    q[0][0] = 1, q[1][1] = 1, q[3][3] = -0.16; /* cylinder radius 0.4 along z */
    uint32_t cyl = quadric_leaf(s, q, rr_v3(-0.4, -0.4, -2), rr_v3(0.4, 0.4, 2), 0);
    uint32_t root = op_node(s, SCENE_CSG_DIFFERENCE, cube, cyl);
    add_solid(s, root, 0);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rr_rng rng = rr_rng_make(1, 0);
    int inside = 0;
    for (int i = 0; i < 20000; i++) {
        rr_vec3 p = rr_v3(2.4 * rr_rng_uniform(&rng) - 1.2, 2.4 * rr_rng_uniform(&rng) - 1.2,
                          2.4 * rr_rng_uniform(&rng) - 1.2);
        double r = rr_v3_len(p), rc = sqrt(p.x * p.x + p.y * p.y);
        /* The mesh is inscribed in the ball; skip the thin shell between. */
        if (fabs(r - 1) < 0.05 || fabs(rc - 0.4) < 1e-9)
            continue;
        int want = r < 1 && rc > 0.4;
        int got = rt_csg_contains(s, acc, root, p);
        assert_int_equal(got, want);
        assert_int_equal(rt_csg_contains(s, NULL, root, p), want);
        inside += want;
    }
    assert_true(inside > 1000);
    /* Points exactly on mesh vertices' rays: the fixed direction of the test
     * may pass through vertices; the tie-break keeps it right (the centre). */
    assert_false(rt_csg_contains(s, acc, root, rr_v3(0, 0, 0)));
    assert_true(rt_csg_contains(s, acc, root, rr_v3(0.7, 0, 0)));
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* More crossings than a list holds: the nearest are kept. A union of 100
 * disjoint small boxes along x. */
static void span_overflow_keeps_nearest(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t root = box_leaf(s, rr_v3(0, 0, 0), rr_v3(0.5, 1, 1), 0);
    for (int i = 1; i < 100; i++)
        root = op_node(s, SCENE_CSG_UNION, root, box_leaf(s, rr_v3(i, 0, 0), rr_v3(i + 0.5, 1, 1), 0));
    rt_spans sp;
    rt_csg_spans(s, NULL, root, ray_make(rr_v3(-1, 0.5, 0.5), rr_v3(1, 0, 0)), 0, INFINITY, &sp);
    /* The tree is 100 deep here (more than the loader allows); fine for a test. */
    assert_int_equal(sp.n, RT_SPAN_MAX);
    spans_well_formed(&sp);
    assert_near(sp.s[0].in.t, 1, 0);
    assert_near(sp.s[RT_SPAN_MAX - 1].in.t, RT_SPAN_MAX, 0);
    scene_destroy(s);
}

/* Bad indices, objects that are not solids, degenerate rays: nothing. */
static void bad_inputs(void **state)
{
    (void)state;
    scene *s = scene_new();
    uint32_t leaf = sphere_leaf(s, rr_v3(0, 0, 0), 1, 0);
    add_solid(s, leaf, 0);
    rt_spans sp;
    rt_hit h;
    rr_ray ray = ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0));
    rt_solid_spans(s, NULL, 1, ray, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    assert_false(rt_solid_closest(s, NULL, 1, ray, 0, INFINITY, &h));
    assert_false(rt_solid_closest(NULL, NULL, 0, ray, 0, INFINITY, &h));
    rt_csg_spans(NULL, NULL, 0, ray, 0, INFINITY, &sp);
    assert_int_equal(sp.n, 0);
    rt_csg_spans(s, NULL, 0, ray, 5, 1, &sp); /* tmin > tmax */
    assert_int_equal(sp.n, 0);
    rt_csg_spans(s, NULL, 0, ray_make(rr_v3(0, 0, 0), rr_v3(0, 0, 0)), -1, 1, &sp);
    assert_int_equal(sp.n, 0);
    rt_csg_spans(s, NULL, 0, ray_make(rr_v3(NAN, 0, 0), rr_v3(1, 0, 0)), -1, 1, &sp);
    assert_int_equal(sp.n, 0);
    /* A non-solid object. */
    s->objects[0].kind = SCENE_OBJ_SPHERE;
    assert_false(rt_solid_closest(s, NULL, 0, ray, 0, INFINITY, &h));
    s->objects[0].kind = SCENE_OBJ_CSG;
    assert_true(rt_solid_closest(s, NULL, 0, ray, 0, INFINITY, &h));
    scene_destroy(s);
}

/* ---- scenes from JSON (scene/scene_csg.c) ---- */

#define CSG_CAM "{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}"

static scene *load_objects(const char *objects)
{
    static char buf[8192];
    snprintf(buf, sizeof buf,
             "{\"format\":\"radray-scene/1\",\"camera\":" CSG_CAM ",\"materials\":{\"a\":{},\"b\":{\"diffuse\":[0.5,"
             "0.1,0.1]}},\"objects\":[%s]}",
             objects);
    scene *s = NULL;
    rr_error err = {0};
    if (scene_load_string(buf, "csg.json", RR_TEST_DATA "/scenes", NULL, &s, &err) != RR_OK)
        fail_msg("%s\n%s", err.msg, buf);
    return s;
}

/* Spans of object 0 along a ray against the closed form, and the closest
 * hit's normal (when want_n is not NULL). */
static void json_case(const char *objects, rr_ray ray, int n, const double *t, const rr_vec3 *want_n)
{
    scene *s = load_objects(objects);
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rt_spans sp;
    rt_solid_spans(s, acc, 0, ray, -INFINITY, INFINITY, &sp);
    expect_spans(&sp, n, t, 1e-12);
    if (want_n) {
        rt_hit h;
        assert_true(rt_accel_closest(acc, ray, 0, INFINITY, &h));
        assert_near(h.t, t[0], 1e-12);
        assert_near(h.normal.x, want_n->x, 1e-12);
        assert_near(h.normal.y, want_n->y, 1e-12);
        assert_near(h.normal.z, want_n->z, 1e-12);
    }
    rt_accel_destroy(acc);
    scene_destroy(s);
}

static void json_named_shapes(void **state)
{
    (void)state;
    rr_vec3 n;
    /* Ellipsoid radii (2, 1, 0.5) moved to (1, 2, 3). */
    n = rr_v3(-1, 0, 0);
    json_case("{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[2,1,0.5],\"material\":\"a\","
              "\"transform\":[{\"translate\":[1,2,3]}]}",
              ray_make(rr_v3(-5, 2.6, 3), rr_v3(1, 0, 0)), 1, (double[]){6 - 1.6, 6 + 1.6}, NULL);
    json_case("{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[2,1,0.5],\"material\":\"a\","
              "\"transform\":[{\"translate\":[1,2,3]}]}",
              ray_make(rr_v3(-5, 2, 3), rr_v3(1, 0, 0)), 1, (double[]){4, 8}, &n);
    /* Cylinder r 0.5, h 2, turned onto the x axis (y -> -x): caps at x = +-1,
     * the body y^2 + z^2 <= 0.25. */
    const char *cyl = "{\"type\":\"quadric\",\"shape\":\"cylinder\",\"radius\":0.5,\"height\":2,\"material\":\"a\","
                      "\"transform\":[{\"rotate\":{\"axis\":[0,0,1],\"degrees\":90}}]}";
    json_case(cyl, ray_make(rr_v3(-5, 0.1, 0.2), rr_v3(1, 0, 0)), 1, (double[]){4, 6}, &n);
    n = rr_v3(0, -1, 0);
    json_case(cyl, ray_make(rr_v3(0.3, -5, 0), rr_v3(0, 1, 0)), 1, (double[]){4.5, 5.5}, &n);
    n = rr_v3(0, -0.6, -0.8);
    json_case(cyl, ray_make(rr_v3(0.3, -0.3, -5), rr_v3(0, 0, 1)), 1, (double[]){4.6, 5.4}, &n);
    /* Cone r 1 at h 2, moved down by 1: at y = 0 the radius is 0.5. */
    json_case("{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":2,\"material\":\"a\","
              "\"transform\":[{\"translate\":[0,-1,0]}]}",
              ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 1, (double[]){4.5, 5.5}, NULL);
    /* Base cap from below... the apex from above: down the axis from the cap
     * (y = 1) to the apex plane (y = -1). */
    n = rr_v3(0, 1, 0);
    json_case("{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":1,\"height\":2,\"material\":\"a\","
              "\"transform\":[{\"translate\":[0,-1,0]}]}",
              ray_make(rr_v3(0, 5, 0), rr_v3(0, -1, 0)), 1, (double[]){4, 6}, &n);
    /* Paraboloid r 2 at h 1: x^2 + z^2 <= 4y; at y = 0.25 the radius is 1. */
    json_case("{\"type\":\"quadric\",\"shape\":\"paraboloid\",\"radius\":2,\"height\":1,\"material\":\"a\"}",
              ray_make(rr_v3(-5, 0.25, 0), rr_v3(1, 0, 0)), 1, (double[]){4, 6}, NULL);
    /* Upside down (mirrored by a scale -1 on y) and raised by 1: the vertex at
     * y = 1, opening down; at y = 0.75 the radius is 1. */
    n = rr_v3(-1, 0, 0);
    n = rr_v3_norm(rr_v3(-2, 4, 0)); /* gradient of x^2 + z^2 + 4(y - 1) at (-1, 0.75, 0) */
    json_case("{\"type\":\"quadric\",\"shape\":\"paraboloid\",\"radius\":2,\"height\":1,\"material\":\"a\","
              "\"transform\":[{\"scale\":[1,-1,1]},{\"translate\":[0,1,0]}]}",
              ray_make(rr_v3(-5, 0.75, 0), rr_v3(1, 0, 0)), 1, (double[]){4, 6}, &n);
    /* Hyperboloid: waist 0.5, end radius 1, height 2. */
    json_case("{\"type\":\"quadric\",\"shape\":\"hyperboloid\",\"radius\":0.5,\"end_radius\":1,\"height\":2,"
              "\"material\":\"a\"}",
              ray_make(rr_v3(-5, 0.8, 0), rr_v3(1, 0, 0)), 1, (double[]){5 - sqrt(0.73), 5 + sqrt(0.73)}, NULL);
    json_case("{\"type\":\"quadric\",\"shape\":\"hyperboloid\",\"radius\":0.5,\"end_radius\":1,\"height\":2,"
              "\"material\":\"a\"}",
              ray_make(rr_v3(0.6, -3, 0), rr_v3(0, 1, 0)), 2,
              (double[]){2, 3 - sqrt(0.11 / 0.75), 3 + sqrt(0.11 / 0.75), 4}, NULL);
    /* General: the half-space x + y <= 1 in the clip box [-2, 2]^3. */
    n = rr_v3(-1, 0, 0);
    json_case("{\"type\":\"quadric\",\"shape\":\"general\",\"q\":[[0,0,0,0.5],[0,0,0,0.5],[0,0,0,0],[0.5,0.5,0,-1]],"
              "\"clip\":{\"min\":[-2,-2,-2],\"max\":[2,2,2]},\"material\":\"a\"}",
              ray_make(rr_v3(-5, 0.25, 0), rr_v3(1, 0, 0)), 1, (double[]){3, 5.75}, &n);
    n = rr_v3(sqrt(0.5), sqrt(0.5), 0);
    json_case("{\"type\":\"quadric\",\"shape\":\"general\",\"q\":[[0,0,0,0.5],[0,0,0,0.5],[0,0,0,0],[0.5,0.5,0,-1]],"
              "\"clip\":{\"min\":[-2,-2,-2],\"max\":[2,2,2]},\"material\":\"a\"}",
              ray_make(rr_v3(5, 0.25, 0), rr_v3(-1, 0, 0)), 1, (double[]){4.25, 7}, &n);
    /* A sphere inside a csg, scaled non-uniformly: an ellipsoid. */
    n = rr_v3(-1, 0, 0);
    json_case("{\"type\":\"csg\",\"op\":\"union\",\"material\":\"a\",\"children\":["
              "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1,\"transform\":[{\"scale\":[2,1,1]}]},"
              "{\"type\":\"box\",\"min\":[10,10,10],\"max\":[11,11,11]}]}",
              ray_make(rr_v3(-5, 0, 0), rr_v3(1, 0, 0)), 1, (double[]){3, 7}, &n);
}

/* Mesh leaf from a file minus a sphere: spans, flipped normal and the
 * sphere's material where the bite is hit. */
static void json_mesh_minus_sphere(void **state)
{
    (void)state;
    /* Tetrahedron x, y, z >= 0, x + y + z <= 2 (tetra.obj scaled by 2) minus
     * the ball of radius 0.5 at the origin. */
    scene *s = load_objects("{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"a\",\"children\":["
                            "{\"type\":\"mesh\",\"file\":\"meshes/tetra.obj\",\"transform\":[{\"scale\":2}]},"
                            "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.5,\"material\":\"b\"}]}");
    rt_accel *acc = NULL;
    rr_error err = {0};
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rr_ray ray = ray_make(rr_v3(-5, 0.2, 0.2), rr_v3(1, 0, 0));
    double xs = sqrt(0.25 - 0.08);
    rt_spans sp, sp2;
    rt_solid_spans(s, acc, 0, ray, 0, INFINITY, &sp);
    rt_solid_spans(s, NULL, 0, ray, 0, INFINITY, &sp2);
    expect_spans(&sp, 1, (double[]){5 + xs, 6.6}, 1e-14);
    expect_spans(&sp2, 1, (double[]){5 + xs, 6.6}, 1e-14);
    rt_hit h;
    assert_true(rt_accel_closest(acc, ray, 0, INFINITY, &h));
    assert_near(h.t, 5 + xs, 1e-14);
    assert_string_equal(s->materials[h.material].name, "b");
    rr_vec3 want = rr_v3_scale(h.point, -2); /* into the removed ball's centre */
    assert_near(h.normal.x, want.x, 1e-12);
    assert_near(h.normal.y, want.y, 1e-12);
    assert_near(h.normal.z, want.z, 1e-12);
    assert_true(h.front);
    /* The slanted face from the other side: the mesh's face normal. */
    ray = ray_make(rr_v3(5, 0.2, 0.2), rr_v3(-1, 0, 0));
    assert_true(rt_accel_closest(acc, ray, 0, INFINITY, &h));
    assert_near(h.t, 3.4, 1e-14);
    assert_string_equal(s->materials[h.material].name, "a");
    assert_near(h.normal.x, 1 / sqrt(3), 1e-14);
    assert_near(h.normal.y, 1 / sqrt(3), 1e-14);
    assert_true(rt_csg_contains(s, acc, s->objects[0].csg_root, rr_v3(0.5, 0.5, 0.5)));
    assert_false(rt_csg_contains(s, acc, s->objects[0].csg_root, rr_v3(0.2, 0.2, 0.2)));
    assert_false(rt_csg_contains(s, acc, s->objects[0].csg_root, rr_v3(1, 1, 1)));
    rt_accel_destroy(acc);
    scene_destroy(s);
}

/* The documented solids example (notes/scene-format.md): the BVH agrees with
 * the reference on random rays, spans with and without the mesh BVHs agree. */
static void json_documented_example(void **state)
{
    (void)state;
    rr_error err = {0};
    scene *s = test_doc_scene("### Solids example", "solids.json");
    rt_accel *acc = NULL;
    assert_int_equal(rt_accel_build(s, &acc, &err), RR_OK);
    rr_rng rng = rr_rng_make(77, 0);
    int solid_hits = 0;
    for (int i = 0; i < 20000; i++) {
        rr_vec3 o = rr_v3(16 * rr_rng_uniform(&rng) - 8, 8 * rr_rng_uniform(&rng), 16 * rr_rng_uniform(&rng) - 8);
        rr_vec3 t = rr_v3(7 * rr_rng_uniform(&rng) - 3.5, 3 * rr_rng_uniform(&rng), 6 * rr_rng_uniform(&rng) - 2);
        rr_ray r = ray_make(o, rr_v3_sub(t, o));
        rt_hit a, b;
        int fa = rt_ref_closest(s, r, 1e-9, INFINITY, &a);
        int fb = rt_accel_closest(acc, r, 1e-9, INFINITY, &b);
        assert_int_equal(fa, fb);
        if (!fa)
            continue;
        /* Triangles: the lecture's test and the watertight one round differently. */
        if (a.tri >= 0 || b.tri >= 0) {
            assert_near(a.t, b.t, 1e-9 * a.t);
            continue;
        }
        if (a.t != b.t)
            fail_msg("ray %d: reference t %.17g (object %u), BVH t %.17g (object %u)", i, a.t, a.object, b.t,
                     b.object);
        assert_int_equal(a.object, b.object);
        assert_int_equal(a.part, b.part);
        assert_int_equal(a.material, b.material);
        solid_hits++;
        for (uint32_t k = 0; k < s->nobjects; k++) {
            if (s->objects[k].kind != SCENE_OBJ_CSG)
                continue;
            rt_spans s1, s2;
            rt_solid_spans(s, acc, k, r, 0, INFINITY, &s1);
            rt_solid_spans(s, NULL, k, r, 0, INFINITY, &s2);
            spans_well_formed(&s1);
            assert_int_equal(s1.n, s2.n);
            for (int j = 0; j < s1.n; j++)
                assert_true(s1.s[j].in.t == s2.s[j].in.t && s1.s[j].out.t == s2.s[j].out.t);
        }
    }
    assert_true(solid_hits > 1000);
    rt_accel_destroy(acc);
    scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sphere_closed_form),
        cmocka_unit_test(transformed_leaf),
        cmocka_unit_test(quadric_ellipsoid),
        cmocka_unit_test(quadric_cylinder),
        cmocka_unit_test(quadric_cone),
        cmocka_unit_test(quadric_paraboloid),
        cmocka_unit_test(quadric_hyperboloid),
        cmocka_unit_test(quadric_general),
        cmocka_unit_test(box_leaf_faces),
        cmocka_unit_test(csg_sphere_minus_sphere),
        cmocka_unit_test(csg_lens_and_union),
        cmocka_unit_test(csg_volumes),
        cmocka_unit_test(mesh_cube_vertices_and_edges),
        cmocka_unit_test(mesh_sphere_vertices),
        cmocka_unit_test(mesh_tie_break_fan),
        cmocka_unit_test(mesh_minus_sphere_spans),
        cmocka_unit_test(accel_matches_reference),
        cmocka_unit_test(contains_random),
        cmocka_unit_test(span_overflow_keeps_nearest),
        cmocka_unit_test(bad_inputs),
        cmocka_unit_test(json_named_shapes),
        cmocka_unit_test(json_mesh_minus_sphere),
        cmocka_unit_test(json_documented_example),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
