/* test_csg_mesh.c - solids, continued (test_csg.c has the analytic leaves and
 * the CSG combinations): mesh leaves (parity for rays through vertices and
 * along edges, the per-leaf BVH against brute force), the scene BVH with
 * solids against the reference, point membership, span overflow, bad inputs
 * and scenes from JSON (scene/scene_csg.c). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "test_csg_util.h"
#include "test_scenes.h"

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

/* The spans of closed convex mesh leaf m along ray, with and without its BVH,
 * against the convex reference: one span where the line crosses, nothing (or
 * a zero-length touch) where it does not. Returns 1 when it crosses. */
static int convex_ray_agrees(const scene *s, const rt_accel *acc, uint32_t m, rr_ray ray)
{
    rt_spans sp, sp2;
    rt_csg_spans(s, NULL, m, ray, -INFINITY, INFINITY, &sp);
    rt_csg_spans(s, acc, m, ray, -INFINITY, INFINITY, &sp2);
    spans_well_formed(&sp);
    assert_int_equal(sp.n, sp2.n);
    double t0, t1;
    if (convex_span(s, m, ray, &t0, &t1) && t1 - t0 > 1e-6) {
        expect_spans(&sp, 1, (double[]){t0, t1}, 1e-9);
        return 1;
    }
    assert_true(sp.n == 0 || (sp.n == 1 && sp.s[0].out.t - sp.s[0].in.t < 1e-6));
    return 0;
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
        crossing += convex_ray_agrees(s, acc, m, ray);
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
        crossing += convex_ray_agrees(s, acc, m, ray);
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
