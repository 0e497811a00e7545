/* test_csg.c - solids (rt_solid.c): leaf spans against closed forms
 * (spheres, every named quadric, boxes), CSG combinations, normals and
 * materials, volumes by ray casting. Mesh leaves, the scene BVH with solids,
 * point membership and scenes from JSON: test_csg_mesh.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "test_csg_util.h"
#include "test_scenes.h"

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
    /* The analytic sphere takes tangents the same way (it used to report a
     * grazing hit there, the CSG leaf none); just inside, both hit. */
    double t;
    assert_false(rt_sphere_hit(c, r, ray, 0, INFINITY, &t));
    ray = ray_make(rr_v3(-5, 4 - 1e-9, 3), rr_v3(1, 0, 0));
    rt_csg_spans(s, NULL, leaf, ray, -INFINITY, INFINITY, &sp);
    assert_int_equal(sp.n, 1);
    assert_true(rt_sphere_hit(c, r, ray, 0, INFINITY, &t));
    assert_near(t, sp.s[0].in.t, 1e-9);

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
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
