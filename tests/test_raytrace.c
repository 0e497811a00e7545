/* test_raytrace.c - the lecture's reference geometry, sphere hits, brute-force
 * front-most hits and the preview renderer's determinism. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "rt.h"
#include "test_scenes.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static void orientation(void **state)
{
    (void)state;
    rr_vec3 A = rr_v3(0, 0, 0), B = rr_v3(1, 0, 0), C = rr_v3(0, 1, 0);
    /* AB x AC = +z: D above the plane is on the positive side. */
    assert_true(rt_orient(A, B, C, rr_v3(0.2, 0.2, 1)));
    assert_false(rt_orient(A, B, C, rr_v3(0.2, 0.2, -1)));
    assert_false(rt_orient(A, B, C, rr_v3(5, 5, 0))); /* coplanar: not > 0 */
    assert_true(rt_front_facing(A, B, C, rr_v3(3, -7, 2)));
    assert_false(rt_front_facing(A, C, B, rr_v3(3, -7, 2)));
}

static void lecture_hit_and_depth(void **state)
{
    (void)state;
    /* Triangle in the plane z = -2, counter-clockwise seen from E at the origin. */
    rr_vec3 A = rr_v3(-1, -1, -2), B = rr_v3(1, -1, -2), C = rr_v3(0, 1, -2);
    rr_vec3 E = rr_v3(0, 0, 0);
    assert_true(rt_front_facing(A, B, C, E));
    rr_vec3 P = rr_v3(0, 0, -1); /* screen at distance 1 */
    assert_true(rt_ray_hits_tri(E, P, A, B, C));
    assert_near(rt_dist_along_ray(E, P, A, B, C), 2.0, 1e-15);
    /* Through a point outside the triangle. */
    assert_false(rt_ray_hits_tri(E, rr_v3(0.9, 0.9, -1), A, B, C));
    /* P behind E: the ray points away. */
    assert_false(rt_ray_hits_tri(E, rr_v3(0, 0, 1), A, B, C));
    /* Oblique ray: H = E + t EP with EP = (0.05, 0.1, -0.5): plane z=-2 at t=4,
     * H = (0.2, 0.4, -2), inside ABC. */
    P = rr_v3(0.05, 0.1, -0.5);
    assert_true(rt_ray_hits_tri(E, P, A, B, C));
    assert_near(rt_dist_along_ray(E, P, A, B, C), 4.0, 1e-14);
}

/* Independent check: Moller-Trumbore barycentrics in the test itself. */
static int mt_hit(rr_vec3 o, rr_vec3 d, rr_vec3 A, rr_vec3 B, rr_vec3 C, double *t, double *margin)
{
    rr_vec3 e1 = rr_v3_sub(B, A), e2 = rr_v3_sub(C, A);
    rr_vec3 p = rr_v3_cross(d, e2);
    double det = rr_v3_dot(e1, p);
    *t = 0;
    *margin = 0;
    if (fabs(det) < 1e-300)
        return 0;
    rr_vec3 s = rr_v3_sub(o, A);
    double u = rr_v3_dot(s, p) / det;
    rr_vec3 q = rr_v3_cross(s, e1);
    double v = rr_v3_dot(d, q) / det;
    *t = rr_v3_dot(e2, q) / det;
    *margin = fmin(fmin(u, v), 1 - u - v);
    return *margin > 0 && *t > 0;
}

static void lecture_vs_moller_trumbore_random(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(2024, 1);
    int agree = 0, hits = 0, n = 20000;
    for (int i = 0; i < n; i++) {
        rr_vec3 v[5];
        for (int k = 0; k < 5; k++)
            v[k] = rr_v3(4 * rr_rng_uniform(&rng) - 2, 4 * rr_rng_uniform(&rng) - 2, 4 * rr_rng_uniform(&rng) - 2);
        rr_vec3 E = v[3], P = v[4], A = v[0], B = v[1], C = v[2];
        if (!rt_front_facing(A, B, C, E)) {
            rr_vec3 t = B;
            B = C;
            C = t;
        }
        double t = 0, margin = 0;
        int ref = mt_hit(E, rr_v3_sub(P, E), A, B, C, &t, &margin);
        int lec = rt_ray_hits_tri(E, P, A, B, C);
        /* Rays within 1e-9 (barycentric) of an edge may legitimately differ. */
        if (fabs(margin) < 1e-9) {
            agree++;
            continue;
        }
        if (lec == ref)
            agree++;
        if (lec && ref) {
            hits++;
            assert_near(rt_dist_along_ray(E, P, A, B, C), t, 1e-9 * fmax(1.0, fabs(t)));
        }
    }
    assert_int_equal(agree, n);
    assert_true(hits > 500); /* the test did exercise hits */
}

static void sphere_hits(void **state)
{
    (void)state;
    double t;
    rr_ray r = {rr_v3(0, 0, 10), rr_v3(0, 0, -1)};
    /* From outside: entry at 10 - 1. */
    assert_true(rt_sphere_hit(rr_v3(0, 0, 0), 1.0, r, 0, INFINITY, &t));
    assert_near(t, 9.0, 1e-12);
    /* From inside: the exit. */
    r.o = rr_v3(0, 0, 0.5);
    assert_true(rt_sphere_hit(rr_v3(0, 0, 0), 1.0, r, 0, INFINITY, &t));
    assert_near(t, 1.5, 1e-12);
    /* Miss, and sphere behind the origin. */
    r.o = rr_v3(0, 2, 10);
    assert_false(rt_sphere_hit(rr_v3(0, 0, 0), 1.0, r, 0, INFINITY, &t));
    r.o = rr_v3(0, 0, -10);
    assert_false(rt_sphere_hit(rr_v3(0, 0, 0), 1.0, r, 0, INFINITY, &t));
    /* Far away small sphere: no cancellation (b^2 - ac would lose it all). */
    r.o = rr_v3(0, 0, 0);
    r.d = rr_v3(0, 0, 1);
    assert_true(rt_sphere_hit(rr_v3(0, 0, 1e9), 1e-3, r, 0, INFINITY, &t));
    assert_near(t, 1e9 - 1e-3, 1e-6);
    /* Unnormalised direction: t scales. */
    r.d = rr_v3(0, 0, 4);
    assert_true(rt_sphere_hit(rr_v3(0, 0, 8), 1.0, r, 0, INFINITY, &t));
    assert_near(t, 7.0 / 4.0, 1e-12);
}

static const char *k_scene =
    "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
    "\"U\":[0,1,0],\"s\":0.25,\"w\":4,\"h\":3},"
    "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]},\"b\":{\"diffuse\":[0.2,0.4,0.6]}},"
    "\"objects\":["
    "{\"name\":\"wall\",\"type\":\"quad\",\"material\":\"a\",\"vertices\":[[-3,-3,-1],[3,-3,-1],[3,3,-1],[-3,3,-1]]},"
    "{\"name\":\"ball\",\"type\":\"sphere\",\"material\":\"b\",\"center\":[0,0,0],\"radius\":0.5}],"
    "\"render\":{\"spp\":4,\"seed\":9}}";

static void closest_hit_brute_force(void **state)
{
    (void)state;
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(k_scene, "test", "", NULL, &s, &err), RR_OK);
    rt_hit h;
    /* Straight down the axis: the sphere (t = 4.5) is in front of the wall (t = 6). */
    rr_ray r = {rr_v3(0, 0, 5), rr_v3(0, 0, -1)};
    assert_true(rt_ref_closest(s, r, 0, INFINITY, &h));
    assert_int_equal(h.tri, -1);
    assert_near(h.t, 4.5, 1e-12);
    assert_near(h.normal.z, 1.0, 1e-12);
    /* Beside the sphere: the wall, front side. (Not at (2, 2): that is on the
     * quad's diagonal, where the lecture's strict tests see neither triangle:
     * the reason the fast path uses a watertight test.) */
    r.o = rr_v3(2, 1, 5);
    assert_true(rt_ref_closest(s, r, 0, INFINITY, &h));
    assert_true(h.tri >= 0);
    assert_near(h.t, 6.0, 1e-12);
    assert_true(h.front);
    /* From behind the open quad: it is not culled, and the normal faces the ray. */
    r.o = rr_v3(2, 1, -5);
    r.d = rr_v3(0, 0, 1);
    assert_true(rt_ref_closest(s, r, 0, INFINITY, &h));
    assert_false(h.front);
    assert_near(h.normal.z, -1.0, 1e-12);
    /* Nothing out there. */
    r.o = rr_v3(10, 10, 5);
    r.d = rr_v3(0, 0, -1);
    assert_false(rt_ref_closest(s, r, 0, INFINITY, &h));
    scene_destroy(s);
}

static rt_render_opts default_opts(void)
{
    rt_render_opts o;
    memset(&o, 0, sizeof o);
    o.spp = 1;
    o.seed = 9;
    o.threads = 1;
    o.max_depth = 5;
    o.light_samples = 4;
    o.indirect = RT_INDIRECT_AMBIENT;
    return o;
}

/* The lecture's shading against hand-computed values: a light of irradiance pi
 * straight down the view axis onto the sphere's pole gives (rho/pi) pi (N.L) =
 * rho; the wall behind the sphere is in its shadow; beside it, the wall gets
 * rho_a, plus its ambient term a * A * rho. */
/* A two-sided query from inside a closed box whose bottom lies flush on a
 * floor: the ray leaves through the box's bottom, where it meets the floor's
 * front at the same t. The box's back face must come first (rt.h), or a
 * point under the box looks open to the burial rule (rad.h: buried parts):
 * the floor, listed first, won the exact tie before. From above the box the
 * query still meets the box's top, front side, and the floor beside it. */
static void two_sided_flush_faces(void **state)
{
    (void)state;
    const char *json =
        "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,3,5],\"O\":[0,2.8,4],"
        "\"U\":[0,1,0],\"s\":0.25,\"w\":4,\"h\":3},\"materials\":{\"a\":{\"diffuse\":0.5}},\"objects\":["
        "{\"name\":\"floor\",\"type\":\"quad\",\"material\":\"a\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]]},"
        "{\"name\":\"box\",\"type\":\"box\",\"material\":\"a\",\"min\":[-1,0,-1],\"max\":[1,0.5,1]}]}";
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "flush", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    rt_hit h;
    const rr_vec3 dirs[] = {rr_v3(0, -1, 0), rr_v3(0.05, -1, 0.03), rr_v3(-0.3, -1, 0.2)};
    for (int k = 0; k < 3; k++) {
        rr_ray r = {rr_v3(0.1, 0.25, 0.2), rr_v3_norm(dirs[k])};
        assert_true(rt_accel_closest_two_sided(a, r, 0.0, INFINITY, &h));
        assert_int_equal(h.object, 1);
        assert_false(h.front);
        assert_near(h.point.y, 0.0, 1e-9);
    }
    rr_ray top = {rr_v3(0.1, 2, 0.2), rr_v3(0, -1, 0)};
    assert_true(rt_accel_closest_two_sided(a, top, 0.0, INFINITY, &h));
    assert_int_equal(h.object, 1);
    assert_true(h.front);
    assert_near(h.t, 1.5, 1e-12);
    rr_ray beside = {rr_v3(2, 2, 0.2), rr_v3(0, -1, 0)};
    assert_true(rt_accel_closest_two_sided(a, beside, 0.0, INFINITY, &h));
    assert_int_equal(h.object, 0);
    assert_true(h.front);
    rt_accel_destroy(a);
    scene_destroy(s);
}

static void render_direct_light_and_shadow(void **state)
{
    (void)state;
    char json[2048];
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
             "\"U\":[0,1,0],\"s\":0.25,\"w\":4,\"h\":3},"
             "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5],\"ambient\":0.5},\"b\":{\"diffuse\":[0.2,0.4,0.6]}},"
             "\"lights\":[{\"type\":\"directional\",\"direction\":[0,0,1],\"intensity\":%.17g}],"
             "\"objects\":["
             "{\"type\":\"quad\",\"material\":\"a\",\"vertices\":[[-9,-9,-1],[9,-9,-1],[9,9,-1],[-9,9,-1]]},"
             "{\"type\":\"sphere\",\"material\":\"b\",\"center\":[0,0,0],\"radius\":0.5}],"
             "\"render\":{\"ambient\":0.2}}",
             RR_PI);
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "direct", "", NULL, &s, &err), RR_OK);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    rt_film f1, f3;
    assert_int_equal(rt_film_init(&f1, s->view.width, s->view.height, &err), RR_OK);
    assert_int_equal(rt_film_init(&f3, s->view.width, s->view.height, &err), RR_OK);
    rt_render_opts o = default_opts();
    assert_int_equal(rt_render(s, a, &o, &f1, &err), RR_OK);
    rr_rgb pole = rr_image_get(&f1.layer[RT_LAYER_DIFFUSE], 4, 3);
    assert_near(pole.r, 0.2, 1e-6);
    assert_near(pole.g, 0.4, 1e-6);
    assert_near(pole.b, 0.6, 1e-6);
    /* Pixel (4, 2) looks at y = 0.25 on the sphere: N.L = sqrt(1 - 0.25^2/0.25) ... computed exactly. */
    rr_rgb side = rr_image_get(&f1.layer[RT_LAYER_DIFFUSE], 0, 0); /* wall at (-4, 3)*0.25*6/5... lit */
    assert_near(side.r, 0.5, 1e-6);
    assert_near(rr_image_get(&f1.layer[RT_LAYER_AMBIENT], 0, 0).r, 0.5 * 0.2 * 0.5, 1e-6);
    /* The beauty image is the sum of the layers. */
    rr_rgb beauty = rr_image_get(&f1.beauty, 0, 0);
    assert_near(beauty.r, 0.5 + 0.05, 1e-6);
    /* Shadow: a ray grazing past the sphere's rim hits the wall inside the
     * sphere's shadow (|xy| < 0.5 on the wall): check by a shadow query. */
    rr_ray sr = {rr_v3(0.3, 0.0, -0.999), rr_v3(0, 0, 1)};
    assert_true(rt_accel_occluded(a, sr, 0, INFINITY));
    /* Thread count does not change a single bit. */
    o.spp = 4;
    o.indirect = RT_INDIRECT_SECONDARY;
    assert_int_equal(rt_render(s, a, &o, &f1, &err), RR_OK);
    o.threads = 3;
    assert_int_equal(rt_render(s, a, &o, &f3, &err), RR_OK);
    assert_memory_equal(f1.beauty.px, f3.beauty.px, 3 * sizeof(float) * (size_t)s->view.width * s->view.height);
    rt_film_free(&f1);
    rt_film_free(&f3);
    rt_film_free(&f3);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* A closed box, inside faces of reflectance rho and emission E everywhere:
 * radiance is E / (1 - rho) in every direction. The secondary-ray estimator
 * must agree within its statistical error. */
static void white_furnace(void **state)
{
    (void)state;
    const double rho = 0.6, E = 1.0, expect = E / (1.0 - rho);
    char json[4096];
    size_t len = 0;
    len += (size_t)snprintf(json + len, sizeof json - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0.1,0.2,0.3],"
                            "\"O\":[0.1,0.2,-0.7],\"U\":[0,1,0],\"s\":0.3,\"w\":5,\"h\":5},"
                            "\"materials\":{\"f\":{\"diffuse\":[%g,%g,%g],\"emission\":[%g,%g,%g]}},"
                            "\"objects\":[",
                            rho, rho, rho, E, E, E);
    len = test_inward_cube(json, sizeof json, len, "f");
    snprintf(json + len, sizeof json - len, "]}");
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "furnace", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    rt_film f;
    assert_int_equal(rt_film_init(&f, s->view.width, s->view.height, &err), RR_OK);
    rt_render_opts o = default_opts();
    o.spp = 16;
    o.light_samples = 1;
    o.indirect = RT_INDIRECT_SECONDARY;
    o.threads = 2;
    assert_int_equal(rt_render(s, a, &o, &f, &err), RR_OK);
    int n = f.beauty.width * f.beauty.height;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; i++) {
        double v = f.beauty.px[3 * i + 1];
        sum += v;
        sum2 += v * v;
    }
    double mean = sum / n, sd = sqrt(fmax(0.0, sum2 / n - mean * mean)), se = sd / sqrt((double)n);
    /* Pixels are independent estimates: 4 standard errors is a 1 in 15000 false alarm. */
    if (fabs(mean - expect) > 4.0 * se + 1e-9)
        fail_msg("furnace: mean %.5f, expected %.5f, standard error %.5f", mean, expect, se);
    assert_true(se < 0.05 * expect); /* and the test has power */
    /* Without the indirect term only the first two orders remain: E + rho E. */
    o.indirect = RT_INDIRECT_NONE;
    assert_int_equal(rt_render(s, a, &o, &f, &err), RR_OK);
    sum = 0;
    for (int i = 0; i < n; i++)
        sum += f.beauty.px[3 * i + 1];
    assert_near(sum / n, E + rho * E, 0.05);
    rt_film_free(&f);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The BVH path agrees with the lecture's brute force on every random ray: same
 * hit or miss, same primitive, same t to 1e-9 relative. */
static void bvh_matches_reference_random(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(7, 3);
    char *json = random_scene(&rng, 400, 6);
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "random", "", NULL, &s, &err), RR_OK);
    free(json);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    assert_true(rt_accel_node_count(a) > 3);
    int hits = 0, n = 20000, edge_cases = 0;
    for (int i = 0; i < n; i++) {
        rr_ray r;
        r.o = random_point(&rng, 2.0);
        r.d = rr_v3_sub(random_point(&rng, 1.0), r.o);
        rt_hit h1, h2;
        int f1 = rt_ref_closest(s, r, 1e-9, INFINITY, &h1);
        int f2 = rt_accel_closest(a, r, 1e-9, INFINITY, &h2);
        if (f1 != f2 || (f1 && h1.tri != h2.tri)) {
            /* Only allowed where the reference's strict tests and the watertight
             * test legitimately differ: a ray within rounding of an edge. */
            edge_cases++;
            continue;
        }
        assert_int_equal(rt_accel_occluded(a, r, 1e-9, INFINITY), f2);
        if (f1) {
            hits++;
            assert_int_equal(h1.object, h2.object);
            assert_near(h1.t, h2.t, 1e-9 * fmax(1.0, h1.t));
            assert_int_equal(h1.front, h2.front);
            assert_near(rr_v3_dot(h1.normal, h2.normal), 1.0, 1e-9);
            /* Shadow segment shorter than the hit: not occluded by it. */
            assert_false(rt_accel_occluded(a, r, 1e-9, h2.t * (1 - 1e-9)) &&
                         !rt_ref_closest(s, r, 1e-9, h2.t * (1 - 1e-9), &h1));
        }
    }
    assert_true(edge_cases <= 2);
    assert_true(hits > n / 4);
    rt_accel_destroy(a);
    rt_accel_destroy(NULL);
    scene_destroy(s);
}

/* Watertightness: a 16 x 16 grid of quads (512 triangles sharing edges and
 * vertices); rays aimed exactly at shared vertices and at points on shared
 * edges must all hit. */
static void bvh_watertight_shared_edges(void **state)
{
    (void)state;
    enum { G = 16 };
    size_t cap = 64 * (G + 1) * (G + 1) + 40 * 2 * G * G + 1024, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                            "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                            "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                            "{\"type\":\"triangles\",\"material\":\"a\",\"vertices\":[");
    /* Irregular spacing so that vertices are not round numbers. */
    double coord[G + 1];
    for (int i = 0; i <= G; i++)
        coord[i] = -1.0 + 2.0 * i / G + (i > 0 && i < G ? 0.013 * sin(7.3 * i) : 0.0);
    for (int y = 0; y <= G; y++)
        for (int x = 0; x <= G; x++)
            len += (size_t)snprintf(buf + len, cap - len, "%s[%.17g,%.17g,%.17g]", x || y ? "," : "", coord[x],
                                    coord[y], 0.1 * coord[x] * coord[y]);
    len += (size_t)snprintf(buf + len, cap - len, "],\"indices\":[");
    for (int y = 0; y < G; y++)
        for (int x = 0; x < G; x++) {
            int v = y * (G + 1) + x;
            len += (size_t)snprintf(buf + len, cap - len, "%s[%d,%d,%d],[%d,%d,%d]", x || y ? "," : "", v, v + 1,
                                    v + G + 2, v, v + G + 2, v + G + 1);
        }
    snprintf(buf + len, cap - len, "]}]}");
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(buf, "grid", "", NULL, &s, &err), RR_OK);
    free(buf);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    rr_rng rng = rr_rng_make(11, 0);
    int misses = 0, n = 0;
    for (int y = 1; y < G; y++)
        for (int x = 1; x < G; x++) {
            rr_vec3 v = s->verts[y * (G + 1) + x];
            rr_vec3 right = s->verts[y * (G + 1) + x + 1], diag = s->verts[(y + 1) * (G + 1) + x + 1];
            rr_vec3 targets[3] = {v, rr_v3_add(v, rr_v3_scale(rr_v3_sub(right, v), rr_rng_uniform(&rng))),
                                  rr_v3_add(v, rr_v3_scale(rr_v3_sub(diag, v), rr_rng_uniform(&rng)))};
            for (int k = 0; k < 3; k++)
                for (int rep = 0; rep < 4; rep++) {
                    rr_ray r;
                    r.o = rr_v3_add(targets[k], rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5,
                                                      rep % 2 ? 2.0 : -2.0));
                    r.d = rr_v3_sub(targets[k], r.o);
                    rt_hit h;
                    n++;
                    misses += !rt_accel_closest(a, r, 0, INFINITY, &h);
                    misses += !rt_accel_occluded(a, r, 0, INFINITY);
                }
        }
    assert_int_equal(misses, 0);
    assert_true(n > 2000);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* ReflectedIntensity against hand-computed values: N = z, L = (0, .6, .8),
 * E placed so that V = (0, -.6, .8): then R = 2(N.L)N - L = V, (R.V)^k = 1. */
static void lecture_reflected_intensity(void **state)
{
    (void)state;
    scene_material m;
    memset(&m, 0, sizeof m);
    m.diffuse = rr_rgb_make(0.5, 0.25, 1.0);
    m.specular = rr_rgb_make(0.3, 0.3, 0.3);
    m.k = 10;
    m.ambient = 0.4;
    rr_vec3 H = rr_v3(1, 2, 3), N = rr_v3(0, 0, 1), L = rr_v3(0, 0.6, 0.8);
    rr_vec3 E = rr_v3_add(H, rr_v3_scale(rr_v3(0, -0.6, 0.8), 7.0));
    rr_rgb A = rr_rgb_make(0.1, 0.2, 0.3), light = rr_rgb_make(2, 2, 2);
    rr_rgb I = rt_reflected_intensity(E, H, N, L, &m, A, light);
    /* a*A*rho + (rho/pi) E (N.L) + s E (R.V)^k */
    assert_near(I.r, 0.4 * 0.1 * 0.5 + 0.5 / RR_PI * 2 * 0.8 + 0.3 * 2, 1e-12);
    assert_near(I.g, 0.4 * 0.2 * 0.25 + 0.25 / RR_PI * 2 * 0.8 + 0.3 * 2, 1e-12);
    /* Rotate V away from R by 60 degrees: (R.V)^k = 0.5^10. */
    rr_vec3 R = rr_v3(0, -0.6, 0.8), X = rr_v3(1, 0, 0);
    rr_vec3 Vr = rr_v3_add(rr_v3_scale(R, 0.5), rr_v3_scale(X, sqrt(0.75)));
    rr_rgb I2 = rt_reflected_intensity(rr_v3_add(H, Vr), H, N, L, &m, rr_rgb_make(0, 0, 0), light);
    assert_near(I2.b, 1.0 / RR_PI * 2 * 0.8 + 0.3 * 2 * pow(0.5, 10), 1e-12);
    /* Light behind the surface: only the ambient term. */
    rr_rgb I3 = rt_reflected_intensity(E, H, N, rr_v3(0, 0.6, -0.8), &m, A, light);
    assert_near(I3.r, 0.4 * 0.1 * 0.5, 1e-15);
}

static scene *load_scene_file(const char *rel)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", RR_SOURCE_DIR, rel);
    scene *s = NULL;
    rr_error err;
    if (scene_load(path, NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

/* Two mirrors at 90 degrees (x = 0 and z = 0): a ray into the corner leaves
 * after exactly 2 reflections with (dx, dz) reversed and dy kept. */
static void mirror_corner_two(void **state)
{
    (void)state;
    scene *s = load_scene_file("scenes/mirror-corner-2.json");
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rr_rng rng = rr_rng_make(5, 5);
    for (int i = 0; i < 1000; i++) {
        rr_ray r;
        r.o = rr_v3(0.4 + 0.4 * rr_rng_uniform(&rng), 1.8 + 0.4 * rr_rng_uniform(&rng),
                    0.4 + 0.4 * rr_rng_uniform(&rng));
        /* Slopes within a factor 2, so both reflections land on the 3 m mirrors. */
        double ax = 0.5 + 0.5 * rr_rng_uniform(&rng), az = 0.5 + 0.5 * rr_rng_uniform(&rng);
        r.d = rr_v3(-ax, 0.1 * (ax + az) * (rr_rng_uniform(&rng) - 0.5), -az);
        rr_ray out;
        int escaped;
        int n = rt_follow_mirrors(a, r, 10, &out, &escaped);
        if (n != 2)
            fail_msg("ray %d: %d reflections", i, n);
        rr_vec3 d0 = rr_v3_norm(r.d), d1 = rr_v3_norm(out.d);
        assert_near(d1.x, -d0.x, 1e-12);
        assert_near(d1.y, d0.y, 1e-12);
        assert_near(d1.z, -d0.z, 1e-12);
    }
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Corner cube: any ray into it comes back antiparallel after exactly 3. */
static void mirror_corner_three(void **state)
{
    (void)state;
    scene *s = load_scene_file("scenes/mirror-corner-3.json");
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rr_rng rng = rr_rng_make(6, 6);
    for (int i = 0; i < 1000; i++) {
        rr_ray r;
        r.o = rr_v3(0.5 + 0.5 * rr_rng_uniform(&rng), 1.6 + 0.4 * rr_rng_uniform(&rng),
                    0.5 + 0.5 * rr_rng_uniform(&rng));
        r.d = rr_v3(-(0.5 + 0.5 * rr_rng_uniform(&rng)), 0.5 + 0.5 * rr_rng_uniform(&rng),
                    -(0.5 + 0.5 * rr_rng_uniform(&rng)));
        rr_ray out;
        int escaped;
        int n = rt_follow_mirrors(a, r, 10, &out, &escaped);
        if (n != 3)
            fail_msg("ray %d: %d reflections", i, n);
        rr_vec3 d0 = rr_v3_norm(r.d), d1 = rr_v3_norm(out.d);
        assert_near(rr_v3_dot(d0, d1), -1.0, 1e-12);
    }
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Regression: a sample that missed everything left stale layer values from the
 * thread's previous pixel, so images depended on the thread count. Many tiles,
 * many misses, every mode: bit-identical for 1 and 2 threads. */
static void render_thread_independent_with_misses(void **state)
{
    (void)state;
    const char *sets[] = {"camera.w=20", "camera.h=17"};
    scene_load_opts lo;
    memset(&lo, 0, sizeof lo);
    lo.overrides = sets;
    lo.noverrides = 2;
    scene *s = NULL;
    assert_int_equal(scene_load_string(k_scene, "misses", "", &lo, &s, NULL), RR_OK);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rt_film f1, f2;
    assert_int_equal(rt_film_init(&f1, s->view.width, s->view.height, NULL), RR_OK);
    assert_int_equal(rt_film_init(&f2, s->view.width, s->view.height, NULL), RR_OK);
    size_t bytes = 3 * sizeof(float) * (size_t)s->view.width * (size_t)s->view.height;
    for (int mode = 0; mode < 3; mode++) {
        rt_render_opts o = default_opts();
        o.spp = 3;
        o.indirect = (rt_indirect)mode;
        o.filter = mode == 2 ? RT_FILTER_TENT : RT_FILTER_BOX;
        o.threads = 1;
        assert_int_equal(rt_render(s, a, &o, &f1, NULL), RR_OK);
        o.threads = 2;
        assert_int_equal(rt_render(s, a, &o, &f2, NULL), RR_OK);
        assert_memory_equal(f1.beauty.px, f2.beauty.px, bytes);
        for (int l = 0; l < RT_LAYER_COUNT; l++)
            assert_memory_equal(f1.layer[l].px, f2.layer[l].px, bytes);
    }
    rt_film_free(&f1);
    rt_film_free(&f2);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The acceptance test of the fast path: 100,000 random rays against a closed
 * 10,680-triangle mesh, BVH versus the lecture's brute force. */
static void bvh_matches_reference_large(void **state)
{
    (void)state;
    char *json = uv_sphere_scene(60, 90, "\"auto\"");
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "uv-sphere", "", NULL, &s, &err), RR_OK);
    free(json);
    assert_true(s->ntris >= 10000);
    assert_true(s->objects[0].report.watertight);
    assert_true(s->objects[0].cull_backfaces);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    enum { N = 100000 };
    int mismatches = 0, hits = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : mismatches, hits)
    for (int i = 0; i < N; i++) {
        rr_rng rng = rr_rng_make(77, (uint64_t)i);
        rr_ray r;
        r.o = rr_v3_scale(random_unit(&rng), 1.5 + 2 * rr_rng_uniform(&rng));
        r.d = rr_v3_sub(rr_v3_scale(random_unit(&rng), 1.1 * rr_rng_uniform(&rng)), r.o);
        rt_hit h1, h2;
        int f1 = rt_ref_closest(s, r, 0, INFINITY, &h1), f2 = rt_accel_closest(a, r, 0, INFINITY, &h2);
        if (f1 != f2 || (f1 && (h1.tri != h2.tri || fabs(h1.t - h2.t) > 1e-9 * h1.t)))
            mismatches++;
        hits += f2;
    }
    /* Disagreement is only possible within rounding of an edge, where the
     * lecture's strict tests see neither triangle: a handful at most. */
    assert_true(mismatches <= 5);
    assert_true(hits > N / 2);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* 1,000,000 random rays from random points inside a closed mesh (no culling)
 * all hit it: nothing slips through an edge or a vertex. */
static void bvh_watertight_million_rays(void **state)
{
    (void)state;
    char *json = uv_sphere_scene(40, 64, "false");
    scene *s = NULL;
    assert_int_equal(scene_load_string(json, "uv-sphere", "", NULL, &s, NULL), RR_OK);
    free(json);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    enum { N = 1000000 };
    int misses = 0;
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : misses)
    for (int i = 0; i < N; i++) {
        rr_rng rng = rr_rng_make(78, (uint64_t)i);
        rr_ray r;
        /* Inside the inscribed radius of the tessellation (cos(pi/40) > 0.99). */
        r.o = rr_v3_scale(random_unit(&rng), 0.95 * cbrt(rr_rng_uniform(&rng)));
        /* Every 4th ray is aimed exactly at a mesh vertex, the hardest case. */
        if (i % 4 == 0)
            r.d = rr_v3_sub(s->verts[rr_rng_below(&rng, (uint32_t)s->nverts)], r.o);
        else
            r.d = random_unit(&rng);
        rt_hit h;
        misses += !rt_accel_closest(a, r, 0, INFINITY, &h);
    }
    assert_int_equal(misses, 0);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Lit(H, L) is robust: a floor lit at a grazing 10 degrees shows no acne (every
 * lit pixel has exactly (rho/pi) E (N.L)), and a wall 1e-4 thick throws a
 * complete shadow (no light leaks through it). */
static void shadows_no_acne_no_leaks(void **state)
{
    (void)state;
    double el = 10.0 * RR_PI / 180.0;
    char json[2048];
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0.00005,0.3,10],"
             "\"O\":[0.00005,0.3,9],\"U\":[0,1,0],\"s\":0.02,\"w\":20,\"h\":20},"
             "\"materials\":{\"f\":{\"diffuse\":[0.5,0.5,0.5]}},"
             "\"lights\":[{\"type\":\"directional\",\"direction\":[%.17g,0,%.17g],\"intensity\":1}],"
             "\"objects\":[{\"type\":\"quad\",\"material\":\"f\",\"vertices\":[[-50,-50,0],[50,-50,0],[50,50,0],"
             "[-50,50,0]]},{\"type\":\"box\",\"material\":\"f\",\"min\":[0,-20,0],\"max\":[0.0001,20,1]}]}",
             cos(el), sin(el));
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "grazing", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rt_film f;
    assert_int_equal(rt_film_init(&f, s->view.width, s->view.height, NULL), RR_OK);
    rt_render_opts o = default_opts();
    assert_int_equal(rt_render(s, a, &o, &f, NULL), RR_OK);
    double lit_value = 0.5 / RR_PI * sin(el);
    int lit = 0, dark = 0;
    for (int row = 0; row < f.beauty.height; row++)
        for (int col = 0; col < f.beauty.width; col++) {
            rt_hit h;
            rr_ray r = rr_view_ray(&s->view, col, row, 0, 0);
            assert_true(rt_accel_closest(a, r, 0, INFINITY, &h));
            double v = rr_image_get(&f.layer[RT_LAYER_DIFFUSE], col, row).r;
            if (h.point.z > 1e-9)
                continue; /* the top of the wall */
            if (h.point.x < 0) {
                assert_near(v, 0.0, 0.0);
                dark++;
            } else {
                assert_near(v, lit_value, 1e-7);
                lit++;
            }
        }
    assert_true(lit > 300 && dark > 300);
    rt_film_free(&f);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Mean of one channel of a layer over a pixel rectangle. */
static double region_mean(const rr_image *im, int x0, int y0, int x1, int y1, int ch)
{
    double sum = 0;
    int n = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++, n++)
            sum += rr_image_at(im, x, y)[ch];
    return sum / n;
}

/* The Cornell box with secondary rays shows colour bleeding: the indirect light
 * on the white back wall is redder next to the red wall (image left) and greener
 * next to the green wall (image right); the Whitted render has no indirect term. */
static void cornell_colour_bleeding(void **state)
{
    (void)state;
    scene *s = load_scene_file("scenes/cornell.json");
    rr_view v;
    assert_int_equal(rr_view_resize(&s->view, 51, &v, NULL), RR_OK);
    s->view = v;
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rt_film f;
    assert_int_equal(rt_film_init(&f, v.width, v.height, NULL), RR_OK);
    rt_render_opts o = default_opts();
    o.spp = 16;
    o.threads = 2;
    o.indirect = RT_INDIRECT_SECONDARY;
    assert_int_equal(rt_render(s, a, &o, &f, NULL), RR_OK);
    /* Back wall, upper part (above the blocks), next to each side wall. */
    const rr_image *ind = &f.layer[RT_LAYER_INDIRECT];
    double lr = region_mean(ind, 12, 10, 16, 22, 0), lg = region_mean(ind, 12, 10, 16, 22, 1);
    double rr = region_mean(ind, 35, 10, 39, 22, 0), rg = region_mean(ind, 35, 10, 39, 22, 1);
    if (!(lr / lg > 1.15 * (rr / rg)))
        fail_msg("no colour bleeding: left R/G %.3f, right R/G %.3f", lr / lg, rr / rg);
    assert_true(lr > 0 && rg > 0);
    o.indirect = RT_INDIRECT_AMBIENT;
    assert_int_equal(rt_render(s, a, &o, &f, NULL), RR_OK);
    assert_near(region_mean(&f.layer[RT_LAYER_INDIRECT], 0, 0, v.width, v.height, 0), 0.0, 0.0);
    rt_film_free(&f);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Supersampling is unbiased for any spp: an emitter whose edge runs through
 * the centres of one pixel row covers half of each of its pixels, and the
 * row's mean comes out half the lit row's, at a square spp (16: a 4 x 4
 * grid, exactly) and at others (5, 8, 32). The grid of ceil(sqrt(spp))
 * columns filled row by row gave 8 spp 0.5625 (its last row held 2
 * samples instead of 3) and 32 spp 0.55. Tolerance: at 8 spp the 4 samples
 * past the 2 x 2 grid are uniform, a standard deviation of 0.0088 for the
 * mean of 201 pixels; 0.03 is 3.4 of them, and half the old bias. */
static void supersampling_unbiased(void **state)
{
    (void)state;
    const char *json = "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,3],"
                       "\"O\":[0,0,2],\"U\":[0,1,0],\"s\":0.01,\"w\":100,\"h\":2},"
                       "\"materials\":{\"lamp\":{\"diffuse\":0,\"emission\":1}},"
                       "\"objects\":[{\"type\":\"triangles\",\"material\":\"lamp\","
                       "\"vertices\":[[-5,-5,0],[5,-5,0],[5,0,0],[-5,0,0]],\"indices\":[[0,1,2],[0,2,3]]}]}";
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "half", "", NULL, &s, &err), RR_OK);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    const int spps[] = {16, 5, 8, 32};
    for (int i = 0; i < 4; i++) {
        rt_film f;
        assert_int_equal(rt_film_init(&f, s->view.width, s->view.height, NULL), RR_OK);
        rt_render_opts o = default_opts();
        o.spp = spps[i];
        o.indirect = RT_INDIRECT_NONE;
        assert_int_equal(rt_render(s, a, &o, &f, NULL), RR_OK);
        const rr_image *im = &f.layer[RT_LAYER_EMISSION];
        double lit = region_mean(im, 0, 3, s->view.width, 4, 0), edge = region_mean(im, 0, 2, s->view.width, 3, 0);
        assert_true(lit > 0.0);
        assert_near(region_mean(im, 0, 1, s->view.width, 2, 0), 0.0, 0.0);
        double tol = spps[i] == 16 ? 1e-12 : 0.03;
        if (!(fabs(edge / lit - 0.5) <= tol))
            fail_msg("%d spp: the half-covered row has %.4f of the lit row's mean", spps[i], edge / lit);
        rt_film_free(&f);
    }
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Sliver triangles: a unit square cut into 200 needle-thin triangles (a fan
 * from one corner, aspect ratios up to ~1e4): every ray through the square
 * hits it, with a finite unit normal, and renders no NaN. */
static void slivers_no_holes_no_nans(void **state)
{
    (void)state;
    enum { K = 100 };
    size_t cap = 64 * (2 * K + 2) + 32 * 2 * K + 1024, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0.5,0.5,3],"
                            "\"O\":[0.5,0.5,2],\"U\":[0,1,0],\"s\":0.05,\"w\":10,\"h\":10},"
                            "\"materials\":{\"a\":{\"diffuse\":0.5}},\"lights\":[{\"type\":\"directional\","
                            "\"direction\":[0.2,0.1,1],\"intensity\":1}],\"objects\":[{\"type\":\"triangles\","
                            "\"material\":\"a\",\"vertices\":[[0,0,0]");
    /* Points along the top and right edges: (i/K, 1) and (1, i/K). */
    for (int i = 0; i <= K; i++)
        len += (size_t)snprintf(buf + len, cap - len, ",[%.17g,1,0]", (double)i / K);
    for (int i = K - 1; i >= 0; i--)
        len += (size_t)snprintf(buf + len, cap - len, ",[1,%.17g,0]", (double)i / K);
    len += (size_t)snprintf(buf + len, cap - len, "],\"indices\":[");
    for (int i = 1; i < 2 * K + 1; i++)
        len += (size_t)snprintf(buf + len, cap - len, "%s[0,%d,%d]", i > 1 ? "," : "", i + 1, i);
    snprintf(buf + len, cap - len, "]}]}");
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(buf, "slivers", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    free(buf);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rr_rng rng = rr_rng_make(12, 0);
    for (int i = 0; i < 100000; i++) {
        rr_vec3 target = rr_v3(1e-9 + (1 - 2e-9) * rr_rng_uniform(&rng), 1e-9 + (1 - 2e-9) * rr_rng_uniform(&rng), 0);
        rr_ray r = {rr_v3(0.5 + rr_rng_uniform(&rng) - 0.5, 0.5, 2), rr_v3(0, 0, 0)};
        r.d = rr_v3_sub(target, r.o);
        rt_hit h;
        if (!rt_accel_closest(a, r, 0, INFINITY, &h))
            fail_msg("ray %d to (%.17g, %.17g) slipped through", i, target.x, target.y);
        assert_true(rr_v3_isfinite(h.normal));
        assert_near(rr_v3_len(h.normal), 1.0, 1e-9);
    }
    rt_film f;
    assert_int_equal(rt_film_init(&f, s->view.width, s->view.height, NULL), RR_OK);
    rt_render_opts o = default_opts();
    o.spp = 4;
    o.indirect = RT_INDIRECT_SECONDARY;
    assert_int_equal(rt_render(s, a, &o, &f, NULL), RR_OK);
    for (int k = 0; k < 3 * f.beauty.width * f.beauty.height; k++)
        assert_true(isfinite(f.beauty.px[k]));
    rt_film_free(&f);
    rt_accel_destroy(a);
    scene_destroy(s);
}


int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(orientation),
        cmocka_unit_test(lecture_hit_and_depth),
        cmocka_unit_test(lecture_vs_moller_trumbore_random),
        cmocka_unit_test(sphere_hits),
        cmocka_unit_test(closest_hit_brute_force),
        cmocka_unit_test(two_sided_flush_faces),
        cmocka_unit_test(render_direct_light_and_shadow),
        cmocka_unit_test(white_furnace),
        cmocka_unit_test(shadows_no_acne_no_leaks),
        cmocka_unit_test(slivers_no_holes_no_nans),
        cmocka_unit_test(render_thread_independent_with_misses),
        cmocka_unit_test(lecture_reflected_intensity),
        cmocka_unit_test(mirror_corner_two),
        cmocka_unit_test(mirror_corner_three),
        cmocka_unit_test(cornell_colour_bleeding),
        cmocka_unit_test(supersampling_unbiased),
        cmocka_unit_test(bvh_matches_reference_random),
        cmocka_unit_test(bvh_watertight_shared_edges),
        cmocka_unit_test(bvh_matches_reference_large),
        cmocka_unit_test(bvh_watertight_million_rays),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
