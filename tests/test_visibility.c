/* test_visibility.c - the exact visible form factor (radiosity/rad_vis.c,
 * rad__ff_visible) against closed forms and against Monte Carlo with an
 * independent segment-triangle test. The BVH query that finds its
 * occluders is tested in test_bvh.c (bvh_tris_in_box_matches_brute_force). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>

#include "rad.h"
#include "rad_ff_internal.h"
#include "test_ff_util.h"

/* Square [x0, x1] x [y0, y1] at height z as two triangles, facing down
 * (counter-clockwise seen from below) or up. */
static void square_tris(double x0, double x1, double y0, double y1, double z, int down, rr_vec3 t[2][3])
{
    rr_vec3 a = rr_v3(x0, y0, z), b = rr_v3(x1, y0, z), c = rr_v3(x1, y1, z), d = rr_v3(x0, y1, z);
    rr_vec3 q[2][3] = {{a, c, b}, {a, d, c}};
    for (int i = 0; i < 2; i++)
        for (int k = 0; k < 3; k++)
            t[i][k] = down ? q[i][k] : q[i][2 - k];
}

/* The factor from the origin (normal +z) to rectangle [x0, x1] x [y0, y1] at
 * height 1, x0, y0 >= 0, by corner_parallel. */
static double rect_ff(double x0, double x1, double y0, double y1)
{
    double c11 = corner_parallel(x1, y1, 1), c01 = x0 > 0 ? corner_parallel(x0, y1, 1) : 0.0;
    double c10 = y0 > 0 ? corner_parallel(x1, y0, 1) : 0.0, c00 = x0 > 0 && y0 > 0 ? corner_parallel(x0, y0, 1) : 0.0;
    return c11 - c01 - c10 + c00;
}

/* rad__ff_visible against closed forms: the visible part of a 2 x 2 square
 * at height 1 above the origin is a union of rectangles with a corner over
 * it, behind squares at height 0.5 (shadows twice their size) and a wall
 * through the slab. */
static void visible_closed_forms(void **state)
{
    (void)state;
    rr_vec3 x = rr_v3(0, 0, 0), n = rr_v3(0, 0, 1);
    rr_vec3 src[4] = {rr_v3(0, 0, 1), rr_v3(2, 0, 1), rr_v3(2, 2, 1), rr_v3(0, 2, 1)};
    double whole = rad_ff_point_polygon(x, n, src, 4), tol = 1e-9;
    rr_vec3 occ[4][3];
    unsigned char cull[4] = {0, 0, 0, 0};
    int hidden = -1;
    /* nothing in the way, or only what lies outside the slab or the pyramid:
     * the polygon's own factor, bit for bit */
    assert_true(rad__ff_visible(x, n, src, 4, NULL, NULL, 0, tol, &hidden) == whole && hidden == 0);
    square_tris(-1, 0.5, -1, 0.5, 1.5, 1, occ);         /* above the source */
    square_tris(-3, -2, -3, -2, 0.5, 1, occ + 2);      /* beside the pyramid */
    assert_true(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])occ, cull, 4, tol, &hidden) == whole && hidden == 0);
    /* one square: its shadow [0, 1]^2 out of [0, 2]^2 */
    square_tris(-1, 0.5, -1, 0.5, 0.5, 1, occ);
    double want = rect_ff(0, 2, 0, 2) - rect_ff(0, 1, 0, 1);
    assert_near(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])occ, cull, 2, tol, &hidden), want, 1e-12);
    assert_int_equal(hidden, 1);
    /* seen from its back: a culling object's does not occlude, another's does */
    square_tris(-1, 0.5, -1, 0.5, 0.5, 0, occ);
    cull[0] = cull[1] = 1;
    assert_true(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])occ, cull, 2, tol, &hidden) == whole && hidden == 0);
    cull[0] = cull[1] = 0;
    assert_near(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])occ, cull, 2, tol, &hidden), want, 1e-12);
    /* two overlapping squares: shadows [0, 1]^2 and [0, 0.5] x [0, 2] */
    square_tris(-1, 0.5, -1, 0.5, 0.5, 1, occ);
    square_tris(-1, 0.25, -1, 1, 0.5, 1, occ + 2);
    want = rect_ff(0, 2, 0, 2) - rect_ff(0, 1, 0, 1) - rect_ff(0, 0.5, 1, 2);
    assert_near(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])occ, cull, 4, tol, &hidden), want, 1e-12);
    /* a wall x = 0.25 from below the point's plane to above the source:
     * only [0, 0.25] x [0, 2] is seen (its shadow's far edge lies near
     * infinity: huge projected coordinates) */
    rr_vec3 w0 = rr_v3(0.25, -5, -1), w1 = rr_v3(0.25, 5, -1), w2 = rr_v3(0.25, 5, 2), w3 = rr_v3(0.25, -5, 2);
    rr_vec3 wall[2][3] = {{w0, w1, w2}, {w0, w2, w3}};
    assert_near(rad__ff_visible(x, n, src, 4, (const rr_vec3(*)[3])wall, NULL, 2, tol, &hidden), rect_ff(0, 0.25, 0, 2),
                1e-8);
    /* a wall y = 0.5 standing on the point's tangent plane, between it and
     * the square [0, 2] x [1, 2]: every segment meets it (at z <= 0.5), so
     * nothing is seen. Its foot projects to infinity from the point (the
     * Cornell box's tall block from the floor once hid nothing this way);
     * the same with a triangle whose corner alone touches the plane. */
    rr_vec3 far[4] = {rr_v3(0, 1, 1), rr_v3(2, 1, 1), rr_v3(2, 2, 1), rr_v3(0, 2, 1)};
    rr_vec3 v0 = rr_v3(-5, 0.5, 0), v1 = rr_v3(5, 0.5, 0), v2 = rr_v3(5, 0.5, 2), v3 = rr_v3(-5, 0.5, 2);
    rr_vec3 foot[2][3] = {{v0, v1, v2}, {v0, v2, v3}};
    assert_true(rad__ff_visible(x, n, far, 4, (const rr_vec3(*)[3])foot, NULL, 2, tol, &hidden) == 0.0 && hidden == 1);
    rr_vec3 tip[1][3] = {{rr_v3(1, 0.5, 0), rr_v3(-40, 0.5, 3), rr_v3(40, 0.5, 3)}};
    assert_true(rad__ff_visible(x, n, far, 4, (const rr_vec3(*)[3])tip, NULL, 1, tol, &hidden) == 0.0 && hidden == 1);
    /* Cornell's floor under the ceiling past the tall block's front face
     * (one corner on the floor, the planes parallel; numbers of the
     * scene's OBJ, which are floats): a cut through that corner repeated
     * it, and the zero-length edge read as a line with the source wholly
     * outside it, so the face hid nothing; it hides it all */
    rr_vec3 cx = rr_v3(368.5333251953125, 0, 93.200002034505204), cn = rr_v3(0, 1, 0);
    rr_vec3 cp[3] = {rr_v3(208.5, 548.79998779296875, 559.20001220703125),
                     rr_v3(208.5, 548.79998779296875, 489.30001068115234),
                     rr_v3(278, 548.79998779296875, 489.30001068115234)};
    rr_vec3 face[1][3] = {{rr_v3(265, 0, 296), rr_v3(265, 330, 296), rr_v3(423, 330, 247)}};
    assert_true(rad__ff_visible(cx, cn, cp, 3, (const rr_vec3(*)[3])face, NULL, 1, 1e-6, &hidden) == 0.0 && hidden == 1);
    /* a triangle source (the first half of the square), half of it behind
     * the first square: the part x < 1, y < 1 of the triangle y < x is
     * the triangle (0,0) (1,0) (1,1) */
    rr_vec3 tri[3] = {src[0], src[1], src[2]}, cut[3] = {src[0], rr_v3(1, 0, 1), rr_v3(1, 1, 1)};
    square_tris(-1, 0.5, -1, 0.5, 0.5, 1, occ);
    want = rad_ff_point_polygon(x, n, tri, 3) - rad_ff_point_polygon(x, n, cut, 3);
    assert_near(rad__ff_visible(x, n, tri, 3, (const rr_vec3(*)[3])occ, NULL, 2, tol, &hidden), want, 1e-12);
}

/* Whether segment o -> o + d (0 < t < 1) meets triangle t (Moller-Trumbore,
 * both faces): the independent check of rad__ff_visible below. */
static int segment_meets(rr_vec3 o, rr_vec3 d, const rr_vec3 t[3])
{
    rr_vec3 e1 = rr_v3_sub(t[1], t[0]), e2 = rr_v3_sub(t[2], t[0]), p = rr_v3_cross(d, e2);
    double det = rr_v3_dot(e1, p);
    if (fabs(det) < 1e-15)
        return 0;
    rr_vec3 s = rr_v3_sub(o, t[0]), q = rr_v3_cross(s, e1);
    double u = rr_v3_dot(s, p) / det, v = rr_v3_dot(d, q) / det, h = rr_v3_dot(e2, q) / det;
    return u >= 0 && v >= 0 && u + v <= 1 && h > 0 && h < 1;
}

/* rad__ff_visible against Monte Carlo: random triangles between a point and
 * a random triangle source; the factor by 40,000 points of the source
 * (16 x 16 strata of the square folded onto it, cos cos / (pi r^2) A / N,
 * visible where the segment meets no triangle), within 4 standard errors
 * of the estimate plus 1e-4 of the factor. */
static void visible_against_rays(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(11, 12);
    int partly = 0;
    for (int trial = 0; trial < 60; trial++) {
        rr_vec3 x = rr_v3(0, 0, 0), n = rr_v3(0, 0, 1), src[3];
        /* every other source parallel to the point's plane (z = 1.1) */
        double zs = 1 + rr_rng_uniform(&rng);
        for (int k = 0; k < 3; k++)
            src[k] = rr_v3(4 * rr_rng_uniform(&rng) - 2, 4 * rr_rng_uniform(&rng) - 2,
                           trial % 2 ? zs + 0.1 : 1 + rr_rng_uniform(&rng));
        rr_vec3 m = rr_v3_norm(rr_v3_cross(rr_v3_sub(src[1], src[0]), rr_v3_sub(src[2], src[0])));
        if (rr_v3_dot(m, rr_v3_sub(x, src[0])) < 0) { /* face the point */
            rr_vec3 t = src[1];
            src[1] = src[2];
            src[2] = t;
            m = rr_v3_neg(m);
        }
        rr_vec3 occ[3][3];
        for (int t = 0; t < 3; t++) {
            rr_vec3 c = rr_v3(2 * rr_rng_uniform(&rng) - 1, 2 * rr_rng_uniform(&rng) - 1, 0.2 + 0.6 * rr_rng_uniform(&rng));
            for (int k = 0; k < 3; k++)
                occ[t][k] = rr_v3_add(c, rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5,
                                               0.6 * (rr_rng_uniform(&rng) - 0.5)));
            if (trial % 4 == 1) /* a corner on the point's plane, as a block on a floor (not binary fractions) */
                occ[t][0].z = 0.0;
        }
        int hidden;
        double got = rad__ff_visible(x, n, src, 3, (const rr_vec3(*)[3])occ, NULL, 3, 1e-9, &hidden);
        assert_true(got >= 0);
        double area = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(src[1], src[0]), rr_v3_sub(src[2], src[0])));
        double sum = 0, sum2 = 0;
        const int N = 40000, S = 16;
        for (int i = 0; i < N; i++) {
            int st = i % (S * S);
            double a = ((st % S) + rr_rng_uniform(&rng)) / S, b = ((st / S) + rr_rng_uniform(&rng)) / S;
            if (a + b > 1) {
                a = 1 - a;
                b = 1 - b;
            }
            rr_vec3 y = rr_v3_add(src[0], rr_v3_add(rr_v3_scale(rr_v3_sub(src[1], src[0]), a),
                                                    rr_v3_scale(rr_v3_sub(src[2], src[0]), b)));
            rr_vec3 d = rr_v3_sub(y, x);
            double r2 = rr_v3_len2(d), g = rr_v3_dot(n, d) * -rr_v3_dot(m, d) / (RR_PI * r2 * r2) * area;
            int seen = 1;
            for (int t = 0; t < 3 && seen; t++)
                seen = !segment_meets(x, d, occ[t]);
            double f = seen ? g : 0.0;
            sum += f;
            sum2 += f * f;
        }
        double mean = sum / N, se = sqrt(fmax(sum2 / N - mean * mean, 0) / N);
        assert_true(fabs(got - mean) <= 4 * se + 1e-4 * mean);
        partly += hidden && got > 0.05 * rad_ff_point_polygon(x, n, src, 3);
    }
    assert_true(partly >= 20); /* the trials test partial shadows, not only whole ones */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(visible_closed_forms),
        cmocka_unit_test(visible_against_rays),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
