/* test_bvh.c - white-box tests of the wide BVH (raytrace/rt_wide.h, the
 * private header): SIMD, scalar and exact box tests agree and never cull a
 * box the ray touches; the leaf packets' triangles against the reference; both
 * node widths give the same hits; the any-hit walk against the ordered one;
 * exact ties between a triangle and another primitive; the float rounding
 * helpers. (The BVH against the lecture's reference and its watertightness:
 * test_raytrace.c; the packet walks: test_packet.c; the build:
 * test_bvh_build.c.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "rr_rng.h"
#include "rt.h"
#include "rt_wide.h" /* private header of raytrace/ */
#include "test_bvh_util.h"
#include "test_scenes.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

/* ---- the wide BVH's box tests (raytrace/rt_wide.h) ---- */

/* Exact slab test in long double: does the ray meet the box with some t in
 * [tmin, tmax]? *entry gets the entry distance. Origin on a slab plane of a
 * parallel axis counts as inside (as in the BVH). */
static int slab_exact(const float lo[3], const float hi[3], rr_ray r, double tmin, double tmax, long double *entry)
{
    const double o[3] = {r.o.x, r.o.y, r.o.z}, d[3] = {r.d.x, r.d.y, r.d.z};
    long double t0 = tmin, t1 = tmax;
    for (int k = 0; k < 3; k++) {
        if (!(lo[k] <= hi[k]))
            return 0;
        if (d[k] == 0.0) {
            if (o[k] < lo[k] || o[k] > hi[k])
                return 0;
            continue;
        }
        long double ta = ((long double)lo[k] - o[k]) / d[k], tb = ((long double)hi[k] - o[k]) / d[k];
        if (ta > tb) {
            long double t = ta;
            ta = tb;
            tb = t;
        }
        if (ta > t0)
            t0 = ta;
        if (tb < t1)
            t1 = tb;
    }
    *entry = t0;
    return t0 <= t1;
}

static float rand_coord(rr_rng *rng)
{
    /* Mostly ordinary values, sometimes small integers (planes a ray can lie in). */
    return rr_rng_uniform(rng) < 0.2 ? (float)(int)(8 * rr_rng_uniform(rng) - 4) : (float)(8 * rr_rng_uniform(rng) - 4);
}

/* A random node of `width` boxes (b[2k][i], b[2k+1][i]: box i's slab k; 10 %
 * empty) and a ray: aimed exactly at a corner, an edge point or a face point
 * of box *lane (kind 0, 1, 2) or random (kind 3), and one time in five
 * parallel to an axis with a +0 or -0 component, its origin sometimes on that
 * axis's plane of the box. Returns 0 for a zero direction (skip it). */
static int random_box_case(rr_rng *rng, int width, float b[6][16], rr_ray *ray, int *lane_out, int *kind_out,
                           double *tmax)
{
    for (int i = 0; i < width; i++) {
        int empty = rr_rng_uniform(rng) < 0.1;
        for (int k = 0; k < 3; k++) {
            float a = rand_coord(rng), c = rr_rng_uniform(rng) < 0.1 ? a : rand_coord(rng);
            b[2 * k][i] = empty ? INFINITY : fminf(a, c);
            b[2 * k + 1][i] = empty ? -INFINITY : fmaxf(a, c);
        }
    }
    rr_ray r;
    r.o = rr_v3(rand_coord(rng), rand_coord(rng), rand_coord(rng));
    int lane = (int)rr_rng_below(rng, (uint32_t)width), kind = (int)rr_rng_below(rng, 4);
    if (kind < 3 && b[0][lane] <= b[1][lane]) {
        double t[3];
        for (int k = 0; k < 3; k++) {
            int side = (int)rr_rng_below(rng, 2);
            double u = k < kind ? rr_rng_uniform(rng) : (double)side;
            t[k] = b[2 * k][lane] + u * ((double)b[2 * k + 1][lane] - b[2 * k][lane]);
        }
        r.d = rr_v3_sub(rr_v3(t[0], t[1], t[2]), r.o);
    } else {
        r.d = rr_v3(2 * rr_rng_uniform(rng) - 1, 2 * rr_rng_uniform(rng) - 1, 2 * rr_rng_uniform(rng) - 1);
    }
    if (rr_rng_uniform(rng) < 0.2) { /* parallel to an axis, with +0 or -0 */
        int k = (int)rr_rng_below(rng, 3);
        double z = rr_rng_uniform(rng) < 0.5 ? 0.0 : -0.0;
        r.d = k == 0 ? rr_v3(z, r.d.y, r.d.z) : (k == 1 ? rr_v3(r.d.x, z, r.d.z) : rr_v3(r.d.x, r.d.y, z));
        if (rr_rng_uniform(rng) < 0.5 && b[0][lane] <= b[1][lane]) /* origin on that axis's plane of a box */
            r.o = k == 0 ? rr_v3(b[0][lane], r.o.y, r.o.z)
                         : (k == 1 ? rr_v3(r.o.x, b[3][lane], r.o.z) : rr_v3(r.o.x, r.o.y, b[4][lane]));
    }
    *ray = r;
    *lane_out = lane;
    *kind_out = kind;
    *tmax = rr_rng_uniform(rng) < 0.5 ? INFINITY : 0.5 + 3 * rr_rng_uniform(rng);
    return rr_v3_len2(r.d) > 0.0;
}

/* Checks box i of b against the exact slab test: a box the ray meets in
 * [tmin, tmax] is in the mask, with dist within the contract's factor of its
 * entry. Returns whether the box is met (exactly). */
static int box_lane_conservative(const float b[6][16], int i, rr_ray r, double tmin, double tmax, unsigned mask,
                                 const float *dist)
{
    float lo[3] = {b[0][i], b[2][i], b[4][i]}, hi[3] = {b[1][i], b[3][i], b[5][i]};
    long double entry;
    if (!slab_exact(lo, hi, r, tmin, tmax, &entry))
        return 0;
    assert_true(mask >> i & 1); /* never culled */
    assert_true((long double)dist[i] <= entry * (1 + (long double)RT_BOX_GROW) + 1e-30L);
    return 1;
}

/* The scalar, SSE and double versions (4 wide; the 8-wide AVX2 test is
 * checked through whole queries, bvh_widths_agree, the 16-wide one below)
 * agree on random nodes and rays, and none culls a box the ray touches (rays
 * aimed exactly at box corners, edges and faces, directions with +0 and -0
 * components, origins on box planes). */
static void wide_box_tests_agree_and_conservative(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(2024, 8);
    int touched = 0, checked = 0;
    for (int it = 0; it < 200000; it++) {
        float b[6][16];
        rr_ray r;
        int lane, kind;
        double tmin = 0.0, tmax;
        if (!random_box_case(&rng, RT_W, b, &r, &lane, &kind, &tmax))
            continue;
        rt_wn n;
        memset(&n, 0, sizeof n);
        for (int i = 0; i < RT_W; i++) {
            for (int k = 0; k < 6; k++)
                n.b[k][i] = b[k][i];
            n.child[i] = (uint32_t)i;
        }
        rt_ray_pre p;
        rt__ray_prepare(r, &p);
        assert_false(p.box_double);
        float ds[RT_W], dd[RT_W];
        unsigned ms = rt__box4_scalar(&n, &p, rt__f_down(tmin), rt__f_up(tmax), ds);
        unsigned md = rt__box4_double(&n, &p, tmin, tmax, dd);
#if RT_BOX_SIMD
        float df[RT_W];
        rt_boxray br;
        rt__boxray_init(&p, &br);
        unsigned mf = rt__box4_fast(&n, &br, rt__f_down(tmin), rt__f_up(tmax), df);
        assert_int_equal(mf, ms);
        for (int i = 0; i < RT_W; i++)
            if (ms >> i & 1)
                assert_memory_equal(&df[i], &ds[i], sizeof(float));
#endif
        for (int i = 0; i < RT_W; i++) {
            int met = box_lane_conservative(b, i, r, tmin, tmax, ms, ds);
            box_lane_conservative(b, i, r, tmin, tmax, md, dd);
            checked += met;
            touched += met && i == lane && kind < 3;
        }
    }
    assert_true(touched > 50000);
    assert_true(checked > 150000);
}

/* The 8- and 16-wide walks' box tests (AVX2; AVX-512 with fused
 * multiply-adds on o / d rounded outward, rt_wide.h rt__boxray_init) never
 * cull a box the ray touches, keep its entry within the contract, and cull
 * most of the boxes the ray misses (else a mask of all lanes would pass);
 * in the 16-wide walk, rays with a zero direction component take the double
 * test. Widths the CPU lacks are skipped (the 4-wide test is above). */
static void wide_simd_box_tests_conservative(void **state)
{
    (void)state;
    typedef unsigned (*box_test_fn)(const void *, rr_ray, double, double, float *, int *);
    int widths[2] = {0, 0};
    box_test_fn fns[2] = {NULL, NULL};
#if RT_HAVE_W8
    widths[0] = 8;
    fns[0] = rt__box8_test;
#endif
#if RT_HAVE_W16
    widths[1] = 16;
    fns[1] = rt__box16_test;
#endif
    int tested = 0;
    for (int w = 0; w < 2; w++) {
        int width = widths[w];
        if (!width || !rt__bvh_width_ok(width))
            continue;
        tested++;
        rr_rng rng = rr_rng_make(2026, (uint64_t)width);
        long touched = 0, checked = 0, missed = 0, culled = 0, fast_rays = 0, skipped = 0;
        for (int it = 0; it < 100000; it++) {
            float b[6][16];
            rr_ray r;
            int lane, kind;
            double tmax;
            if (!random_box_case(&rng, width, b, &r, &lane, &kind, &tmax)) {
                skipped++;
                continue;
            }
            union {
#if RT_HAVE_W8
                rt_wnode8 n8;
#endif
#if RT_HAVE_W16
                rt_wnode16 n16;
#endif
                char any;
            } node;
            memset(&node, 0, sizeof node);
            for (int k = 0; k < 6; k++)
                for (int i = 0; i < width; i++) {
#if RT_HAVE_W8
                    if (width == 8)
                        node.n8.b[k][i] = b[k][i];
#endif
#if RT_HAVE_W16
                    if (width == 16)
                        node.n16.b[k][i] = b[k][i];
#endif
                }
            float dist[16];
            int fast;
            unsigned m = fns[w](&node, r, 0.0, tmax, dist, &fast);
            int zero_d = r.d.x == 0.0 || r.d.y == 0.0 || r.d.z == 0.0;
            assert_int_equal(fast, width == 16 ? !zero_d : 1);
            fast_rays += fast;
            for (int i = 0; i < width; i++) {
                int met = box_lane_conservative(b, i, r, 0.0, tmax, m, dist);
                checked += met;
                touched += met && i == lane && kind < 3;
                if (!met && fast && b[0][i] <= b[1][i]) {
                    missed++;
                    culled += !(m >> i & 1);
                }
            }
        }
        assert_true(touched > 25000);
        assert_true(checked > 50000 * (long)width / 8);
        assert_true(fast_rays > 70000);
        assert_true(width == 16 || fast_rays == 100000 - skipped);
        assert_true(culled > 0.99 * (double)missed);
    }
    if (!tested)
        skip();
}

/* Regression: a ray parallel to two axes with direction components -0 (as
 * from negating or scaling a zero) hits. The binary BVH took d < 0 for the
 * near plane while 1/-0 = -inf, and so missed every box around the ray. */
static void bvh_negative_zero_direction(void **state)
{
    (void)state;
    const char *json = "{\"format\":\"radray-scene/"
                       "1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                       "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                       "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                       "{\"type\":\"triangles\",\"material\":\"a\",\"vertices\":[[-1,-1,0],[1,-"
                       "1,0],[0,1,0],"
                       "[-1,-1,2],[1,-1,2],[0,1,2.5]],\"indices\":[[0,1,2],[3,4,5]]}]}";
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "negzero", "", NULL, &s, &err), RR_OK);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    const double zs[2] = {0.0, -0.0};
    /* Inside the boxes' x and y slabs; on the plane x = -1 (outside both
     * triangles); on the plane y = -1, through the triangles' bottom edges. */
    const rr_vec3 os[3] = {rr_v3(0.2, 0.3, 5), rr_v3(-1, -0.5, 5), rr_v3(0, -1, 5)};
    int on_edge = -1;
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++)
            for (int k = 0; k < 3; k++) {
                rr_ray r = {os[k], rr_v3(zs[i], zs[j], -1)};
                rt_hit h, h2;
                int f = rt_accel_closest(a, r, 0, INFINITY, &h);
                assert_int_equal(rt_accel_occluded(a, r, 0, INFINITY), f);
                if (k == 0) {
                    assert_true(f);
                    assert_int_equal(h.tri, 1); /* the near one (z = 2..2.5) */
                    assert_true(rt_ref_closest(s, r, 0, INFINITY, &h2));
                    assert_int_equal(h2.tri, 1);
                    assert_near(h.t, h2.t, 1e-12);
                } else if (k == 1) {
                    assert_false(f);
                } else {
                    /* Exactly on an edge: the watertight test counts it (the
                     * lecture's strict test does not); the same for +0 and -0. */
                    if (on_edge < 0)
                        on_edge = f;
                    assert_int_equal(f, on_edge);
                }
            }
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* bvh_matches_reference_random, on float vertices (the fast path, mixed with
 * spheres in the same leaves). */
static void bvh_fast_path_matches_reference_random(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(7, 4);
    char *json = random_scene(&rng, 400, 6);
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "random", "", NULL, &s, &err), RR_OK);
    free(json);
    verts_to_float(s);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    int hits = 0, spheres = 0, n = 20000, edge_cases = 0;
    for (int i = 0; i < n; i++) {
        rr_ray r;
        r.o = random_point(&rng, 2.0);
        r.d = rr_v3_sub(random_point(&rng, 1.0), r.o);
        rt_hit h1, h2;
        int f1 = rt_ref_closest(s, r, 1e-9, INFINITY, &h1);
        int f2 = rt_accel_closest(a, r, 1e-9, INFINITY, &h2);
        if (f1 != f2 || (f1 && h1.tri != h2.tri)) {
            edge_cases++;
            continue;
        }
        assert_int_equal(rt_accel_occluded(a, r, 1e-9, INFINITY), f2);
        if (f1) {
            hits++;
            spheres += h2.tri < 0;
            assert_int_equal(h1.object, h2.object);
            assert_int_equal(h1.material, h2.material);
            assert_int_equal(h1.part, h2.part);
            assert_near(h1.t, h2.t, 1e-9 * fmax(1.0, h1.t));
            assert_int_equal(h1.front, h2.front);
            assert_near(rr_v3_dot(h1.normal, h2.normal), 1.0, 1e-9);
            assert_near(rr_v3_len(rr_v3_sub(h2.point, rr_ray_at(r, h2.t))), 0.0, 1e-12);
        }
    }
    assert_true(edge_cases <= 2);
    assert_true(hits > n / 4);
    assert_true(spheres > 100);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* bvh_matches_reference_large and bvh_watertight_million_rays on float
 * vertices (the fast path). */
/* An exact tie between a triangle and another primitive goes to the
 * triangle, as in rt_ref_closest, whatever order the walk meets them in:
 * spheres of radius 1 standing on a floor that faces down, rays from below
 * up through each sphere's lowest point meet the floor and the sphere both
 * at t = 1 exactly. Every width, single rays and packets. */
static void bvh_triangle_wins_tie_with_primitive(void **state)
{
    (void)state;
    enum { NS = 48 };
    char *json = malloc(96 * NS + 512);
    assert_non_null(json);
    int at = sprintf(json, "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                           "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                           "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                           "{\"type\": \"quad\", \"material\": \"a\", \"vertices\": [[-40, 0, -40], [40, 0, -40], "
                           "[40, 0, 40], [-40, 0, 40]]}");
    rr_ray rays[NS];
    for (int i = 0; i < NS; i++) {
        int x = -33 + 3 * (i % 8), z = 2 + 5 * (i / 8); /* x < 0 < z: off the quad's diagonal x = z */
        at += sprintf(json + at,
                      ", {\"type\": \"sphere\", \"material\": \"a\", \"center\": [%d, 1, %d], \"radius\": 1}", x, z);
        rays[i] = (rr_ray){rr_v3(x, -1, z), rr_v3(0, 1, 0)};
    }
    sprintf(json + at, "]}");
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load_string(json, "tie", "", NULL, &s, &err), RR_OK);
    free(json);
    int ws[3], nw = widths_available(ws);
    for (int wi = 0; wi < nw; wi++) {
        rt_accel *a = NULL;
        assert_int_equal(rt__accel_build_width(s, ws[wi], &a, &err), RR_OK);
        rt_hit hn[NS];
        unsigned char found[NS];
        assert_int_equal(rt_accel_closest_n(a, rays, NS, 0.0, INFINITY, hn, found), NS);
        for (int i = 0; i < NS; i++) {
            rt_hit h1, h2;
            assert_true(rt_ref_closest(s, rays[i], 0.0, INFINITY, &h1));
            assert_true(rt_accel_closest(a, rays[i], 0.0, INFINITY, &h2));
            assert_true(h1.t == 1.0 && h2.t == 1.0 && hn[i].t == 1.0);
            assert_int_equal(h1.object, 0);
            assert_int_equal(h2.object, 0);
            assert_int_equal(hn[i].object, 0);
        }
        rt_accel_destroy(a);
    }
    scene_destroy(s);
}

static void bvh_fast_path_large_and_watertight(void **state)
{
    (void)state;
    for (int pass = 0; pass < 2; pass++) {
        char *json = pass == 0 ? uv_sphere_scene(60, 90, "\"auto\"") : uv_sphere_scene(40, 64, "false");
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "uv-sphere", "", NULL, &s, NULL), RR_OK);
        free(json);
        verts_to_float(s);
        rt_accel *a = NULL;
        assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
        int bad = 0, hits = 0, N = pass == 0 ? 100000 : 1000000;
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : bad, hits)
        for (int i = 0; i < N; i++) {
            rr_rng rng = rr_rng_make(79 + (uint64_t)pass, (uint64_t)i);
            rr_ray r;
            rt_hit h1, h2;
            if (pass == 0) {
                r.o = rr_v3_scale(random_unit(&rng), 1.5 + 2 * rr_rng_uniform(&rng));
                r.d = rr_v3_sub(rr_v3_scale(random_unit(&rng), 1.1 * rr_rng_uniform(&rng)), r.o);
                int f1 = rt_ref_closest(s, r, 0, INFINITY, &h1), f2 = rt_accel_closest(a, r, 0, INFINITY, &h2);
                bad += f1 != f2 || (f1 && (h1.tri != h2.tri || fabs(h1.t - h2.t) > 1e-9 * h1.t));
                hits += f2;
            } else {
                r.o = rr_v3_scale(random_unit(&rng), 0.95 * cbrt(rr_rng_uniform(&rng)));
                if (i % 4 == 0)
                    r.d = rr_v3_sub(s->verts[rr_rng_below(&rng, (uint32_t)s->nverts)], r.o);
                else
                    r.d = random_unit(&rng);
                bad += !rt_accel_closest(a, r, 0, INFINITY, &h2);
                hits++;
            }
        }
        assert_true(bad <= (pass == 0 ? 5 : 0));
        assert_true(hits > N / 2);
        rt_accel_destroy(a);
        scene_destroy(s);
    }
}

/* Every node width of this build (4 wide; 8 wide where the build and the CPU
 * have the AVX2 walk; 16 wide where they have the AVX-512 walk) gives the
 * same hits bit for bit: same triangle or sphere, t, normal, point and
 * occlusion, on random scenes with double and with float vertices (the
 * leaf-record fast path) and on a UV sphere with rays aimed at its vertices.
 * The nodes are 64-byte aligned (aligned SIMD loads). RADRAY_BVH_WIDTH=4 or
 * 8 selects that width. */

/* rt__walkN of width w (the ordered walk, any-hit mode). */
static int walk_any(const rt_accel *a, int w, rr_ray r, double tmin, double tmax)
{
#if RT_HAVE_W16
    if (w == 16)
        return rt__walk16(a, r, tmin, tmax, NULL, 1);
#endif
#if RT_HAVE_W8
    if (w == 8)
        return rt__walk8(a, r, tmin, tmax, NULL, 1);
#endif
    return w == 4 ? rt__walk4(a, r, tmin, tmax, NULL, 1) : -1;
}

static void bvh_widths_agree(void **state)
{
    (void)state;
    rr_error err;
    assert_int_equal(rt__bvh_width_ok(4), 1);
    assert_int_equal(rt__bvh_width_ok(3), 0);
    assert_int_equal(rt__bvh_width_ok(32), 0);
    int ws[3], nw = widths_available(ws);
    int w = rt__bvh_width_default(), widest = ws[nw - 1];
    const char *env = getenv("RADRAY_BVH_WIDTH");
    if (env && strcmp(env, "4") == 0)
        assert_int_equal(w, 4);
    else if (env && strcmp(env, "8") == 0 && rt__bvh_width_ok(8))
        assert_int_equal(w, 8);
    else
        assert_int_equal(w, widest); /* the widest available by default */
    /* Each scene against each wider width (on a CPU without AVX2: 4 against 4). */
    for (int round = 0; round < 3 * (nw > 1 ? nw - 1 : 1); round++) {
        const int pass = round % 3, w2 = ws[nw == 1 ? 0 : 1 + round / 3];
        rr_rng rng = rr_rng_make(31, (uint64_t)pass);
        char *json = pass < 2 ? random_scene(&rng, 600, 8) : uv_sphere_scene(50, 80, "\"auto\"");
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "widths", "", NULL, &s, &err), RR_OK);
        free(json);
        if (pass >= 1)
            verts_to_float(s);
        rt_accel *a4 = NULL, *aw = NULL, *bad = NULL;
        assert_int_equal(rt__accel_build_width(s, 4, &a4, &err), RR_OK);
        assert_int_equal(rt__accel_build_width(s, w2, &aw, &err), RR_OK);
        assert_int_equal(rt__accel_build_width(s, 5, &bad, &err), RR_ERR_INVALID);
        assert_null(bad);
        assert_int_equal(a4->width, 4);
        assert_int_equal(aw->width, w2);
        /* Every triangle has a packet lane of its own: float copies once
         * the vertices are floats, else double copies (pass 0). */
        size_t nfast = 0, ndbl = 0;
        for (size_t q = 0; q < a4->npks; q++) {
            for (int i = 0; i < RT_PK; i++) {
                nfast += (a4->pks[q].ref[i] & RT_REF_LANE) == RT_REF_FAST;
                ndbl += (a4->pks[q].ref[i] & RT_REF_LANE) == RT_REF_DBL;
            }
        }
        assert_int_equal(nfast + ndbl, s->ntris);
        assert_int_equal(a4->nprims, rt_prim_total(s));
        assert_int_equal(a4->ndverts, ndbl ? a4->npks * RT_PK : 0);
        if (pass >= 1)
            assert_int_equal(nfast, s->ntris);
        else
            assert_true(ndbl > s->ntris / 2);
        assert_int_equal((uintptr_t)a4->wnodes % 64, 0);
        assert_int_equal((uintptr_t)aw->wnodes % 64, 0);
        int hits = 0, n = 200000;
        for (int i = 0; i < n; i++) {
            rr_ray r;
            if (pass < 2) {
                r.o = random_point(&rng, 2.0);
                r.d = rr_v3_sub(random_point(&rng, 1.0), r.o);
            } else {
                r.o = rr_v3_scale(random_unit(&rng), i % 2 ? 0.9 : 1.5 + 2 * rr_rng_uniform(&rng));
                r.d = i % 3 == 0 ? rr_v3_sub(s->verts[rr_rng_below(&rng, (uint32_t)s->nverts)], r.o)
                                 : rr_v3_sub(rr_v3_scale(random_unit(&rng), 1.1 * rr_rng_uniform(&rng)), r.o);
            }
            double tmax = i % 4 == 0 ? 0.5 + rr_rng_uniform(&rng) : INFINITY;
            rt_hit h1, h2;
            memset(&h1, 0, sizeof h1);
            memset(&h2, 0, sizeof h2);
            int f1 = rt_accel_closest(a4, r, 1e-9, tmax, &h1), f2 = rt_accel_closest(aw, r, 1e-9, tmax, &h2);
            if (!same_hit(f1, &h1, f2, &h2))
                fprintf(stderr, "pass %d ray %d: %d %d tri %lld %lld t %.17g %.17g\n", pass, i, f1, f2,
                        (long long)h1.tri, (long long)h2.tri, h1.t, h2.t);
            assert_true(same_hit(f1, &h1, f2, &h2));
            assert_int_equal(rt_accel_occluded(a4, r, 1e-9, tmax), f1);
            assert_int_equal(rt_accel_occluded(aw, r, 1e-9, tmax), f2);
            hits += f1;
        }
        assert_true(hits > n / 5);
        rt_accel_destroy(a4);
        rt_accel_destroy(aw);
        scene_destroy(s);
    }
}

/* The any-hit walk (rt__occlN, rt_accel_occluded) answers as the ordered walk
 * with any = 1 (rt__walkN) for every width, on random rays and segments,
 * tmin < 0 (the double box test), tmax 0, negative and NaN included; and it
 * answers whether a closest hit exists. */
static void bvh_occluded_matches_walk(void **state)
{
    (void)state;
    rr_error err;
    int ws[3], nw = widths_available(ws);
    for (int pass = 0; pass < 2; pass++) {
        rr_rng rng = rr_rng_make(77, (uint64_t)pass);
        char *json = random_scene(&rng, 400, 6);
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "occl", "", NULL, &s, &err), RR_OK);
        free(json);
        if (pass == 1)
            verts_to_float(s);
        for (int wi = 0; wi < nw; wi++) {
            const int w = ws[wi];
            rt_accel *a = NULL;
            assert_int_equal(rt__accel_build_width(s, w, &a, &err), RR_OK);
            int occl = 0, n = 40000;
            for (int i = 0; i < n; i++) {
                rr_ray r;
                r.o = random_point(&rng, 2.0);
                r.d = rr_v3_sub(random_point(&rng, 1.0), r.o);
                double tmin = i % 7 == 0 ? -0.5 * rr_rng_uniform(&rng) : (i % 2 ? 1e-9 : 0.0);
                double tmax;
                switch (i % 8) {
                case 0: tmax = INFINITY; break;
                case 1: tmax = 0.0; break;
                case 2: tmax = -0.25 * rr_rng_uniform(&rng); break;
                case 3: tmax = i % 3 ? NAN : 1e-30; break;
                default: tmax = 2.0 * rr_rng_uniform(&rng); break;
                }
                int f = rt_accel_occluded(a, r, tmin, tmax);
                int g = walk_any(a, w, r, tmin, tmax);
                if (f != g)
                    fprintf(stderr, "width %d ray %d: occluded %d walk %d (tmin %g tmax %g)\n", w, i, f, g, tmin,
                            tmax);
                assert_int_equal(f, g);
                if (tmin >= 0.0 && tmax >= 0.0) {
                    rt_hit h;
                    assert_int_equal(rt_accel_closest(a, r, tmin, tmax, &h), f);
                }
                occl += f;
            }
            assert_true(occl > n / 10 && occl < n - n / 10);
            rt_accel_destroy(a);
        }
        scene_destroy(s);
    }
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* rt_accel_tris_in_box against every triangle's box, at every width: the
 * same set of triangles (boxes from a point to larger than the scene), the
 * count cap + 1 past cap, and *other set wherever a sphere's box meets the
 * query's (it may also be set where only a leaf's box does). */
static void bvh_tris_in_box_matches_brute_force(void **state)
{
    (void)state;
    rr_error err;
    int ws[3], nw = widths_available(ws);
    rr_rng rng = rr_rng_make(78, 0);
    char *json = random_scene(&rng, 500, 12);
    scene *s = NULL;
    assert_int_equal(scene_load_string(json, "box", "", NULL, &s, &err), RR_OK);
    free(json);
    uint32_t *got = malloc(s->ntris * sizeof *got), *want = malloc(s->ntris * sizeof *want);
    assert_non_null(got);
    assert_non_null(want);
    for (int wi = 0; wi < nw; wi++) {
        rt_accel *a = NULL;
        assert_int_equal(rt__accel_build_width(s, ws[wi], &a, &err), RR_OK);
        for (int q = 0; q < 300; q++) {
            rr_vec3 c = random_point(&rng, 1.2), h = random_point(&rng, q % 3 == 0 ? 0.02 : q % 3 == 1 ? 0.3 : 1.5);
            rr_vec3 lo = rr_v3_sub(c, rr_v3(fabs(h.x), fabs(h.y), fabs(h.z))), hi = rr_v3_add(c, rr_v3(fabs(h.x), fabs(h.y), fabs(h.z)));
            size_t nwant = 0;
            for (size_t t = 0; t < s->ntris; t++) {
                rr_vec3 A = s->verts[s->tris[t].v[0]], B = s->verts[s->tris[t].v[1]], C = s->verts[s->tris[t].v[2]];
                if (fmin(A.x, fmin(B.x, C.x)) <= hi.x && lo.x <= fmax(A.x, fmax(B.x, C.x)) &&
                    fmin(A.y, fmin(B.y, C.y)) <= hi.y && lo.y <= fmax(A.y, fmax(B.y, C.y)) &&
                    fmin(A.z, fmin(B.z, C.z)) <= hi.z && lo.z <= fmax(A.z, fmax(B.z, C.z)))
                    want[nwant++] = (uint32_t)t;
            }
            int sphere = 0;
            for (size_t o = 0; o < s->nobjects; o++) {
                const scene_object *ob = &s->objects[o];
                if (ob->kind == SCENE_OBJ_SPHERE && ob->center.x - ob->radius <= hi.x && lo.x <= ob->center.x + ob->radius &&
                    ob->center.y - ob->radius <= hi.y && lo.y <= ob->center.y + ob->radius &&
                    ob->center.z - ob->radius <= hi.z && lo.z <= ob->center.z + ob->radius)
                    sphere = 1;
            }
            int other = -1;
            size_t n = rt_accel_tris_in_box(a, lo, hi, got, s->ntris, &other);
            assert_int_equal(n, nwant);
            qsort(got, n, sizeof *got, cmp_u32);
            for (size_t i = 0; i < n; i++)
                assert_int_equal(got[i], want[i]);
            assert_true(other == 0 || other == 1);
            if (sphere)
                assert_int_equal(other, 1);
            if (nwant > 3) /* past a cap: cap + 1, cap of them held */
                assert_int_equal(rt_accel_tris_in_box(a, lo, hi, got, 3, NULL), 4);
        }
        rt_accel_destroy(a);
    }
    free(got);
    free(want);
    scene_destroy(s);
}

/* ---- the packets' float test (rt_kernel.h rt__pk_cand) ---- */

/* A double in [-1, 1). */
static double rand_sym(rr_rng *rng) { return 2 * rr_rng_uniform(rng) - 1; }

/* The float test never drops a lane the exact test hits (for any t: tmin
 * -inf, tmax +inf), and its SSE and scalar versions give the same lanes, on
 * packets of triangles at scales from 1e-6 to 1e15 and offsets up to 1e6 of
 * their size, with rays aimed exactly at vertices and at points of edges,
 * a hair inside or outside them, and at random; triangles with vertices
 * that are floats (FAST) and not (DBL: the float test sees them rounded,
 * the exact test the doubles). It must also reject most clear misses (else
 * it would be a test that cannot fail: a mask of every lane passes the
 * first check). Lanes of other primitives (NaN vertices) are always kept,
 * unused lanes (ref 0) never. */
static void pk_float_test_conservative(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(2026, 12);
    const double scales[] = {1e-6, 1e-3, 1.0, 1e3, 1e6, 1e15};
    long kept_hits = 0, misses = 0, rejected = 0, back_dropped = 0;
    for (int trial = 0; trial < 60000; trial++) {
        double sc = scales[trial % 6];
        double off = rr_rng_uniform(&rng) < 0.5 ? 0.0 : sc * 1e3 * rand_sym(&rng);
        int fast = trial % 2;
        rr_vec3 ctr = rr_v3(off, -0.5 * off, 0.25 * off);
        rt_pk k;
        memset(&k, 0, sizeof k);
        double dv[RT_PK][9];
        double vm = 0.0;
        for (int i = 0; i < RT_PK; i++) {
            for (int r = 0; r < 9; r++) {
                double x = (&ctr.x)[r % 3] + sc * rand_sym(&rng);
                if (fast)
                    x = (double)(float)x;
                dv[i][r] = x;
                k.v[r][i] = (float)x;
                vm = fabs(x) > vm ? fabs(x) : vm;
            }
            k.ref[i] = (uint32_t)i << RT_REF_SHIFT | (fast ? RT_REF_FAST : RT_REF_DBL);
            if (rr_rng_uniform(&rng) < 0.5)
                k.ref[i] |= RT_REF_CULL; /* its back face is culled */
        }
        float vmax = rt__f_up(vm * (1.0 + 1e-6));
        /* The ray: from a point some distance away towards a target. */
        int lane = (int)(RT_PK * rr_rng_uniform(&rng));
        const double *t = dv[lane];
        rr_vec3 A = rr_v3(t[0], t[1], t[2]), B = rr_v3(t[3], t[4], t[5]), C = rr_v3(t[6], t[7], t[8]);
        rr_vec3 target;
        int kind = trial % 5;
        double w = rr_rng_uniform(&rng);
        if (kind == 0)
            target = (trial / 5) % 2 ? A : B; /* a vertex */
        else if (kind == 1)
            target = rr_v3_add(A, rr_v3_scale(rr_v3_sub(B, A), w)); /* on edge AB (rounded) */
        else if (kind == 2)                                         /* beside edge BC by a relative hair */
            target = rr_v3_add(rr_v3_add(B, rr_v3_scale(rr_v3_sub(C, B), w)),
                               rr_v3_scale(rr_v3(rand_sym(&rng), rand_sym(&rng), rand_sym(&rng)), sc * 1e-7));
        else
            target = rr_v3_add(ctr, rr_v3(sc * rand_sym(&rng), sc * rand_sym(&rng), sc * rand_sym(&rng)));
        double dist = sc * (rr_rng_uniform(&rng) < 0.3 ? 1e-3 : 10.0) + fabs(off) * rr_rng_uniform(&rng);
        rr_vec3 dir = rr_v3_norm(rr_v3(rand_sym(&rng), rand_sym(&rng), rand_sym(&rng)));
        if (trial % 7 == 0) /* an axis-aligned direction (zero components) */
            dir = rr_v3(0.0, 0.0, trial % 2 ? 1.0 : -1.0);
        rr_ray ray = {rr_v3_sub(target, rr_v3_scale(dir, dist)), dir};
        rt_ray_pre p;
        rt__ray_prepare(ray, &p);
        rt_pkray pr;
        rt__pkray_init(&p, vmax, p.box_double, &pr);
        unsigned m = rt__pk_cand(&k, &pr);
#if RT_PK_SIMD
        /* The SSE lanes are the scalar version's. */
        float o[3] = {(float)p.ok[0], (float)p.ok[1], (float)p.ok[2]};
        assert_int_equal(m, rt__pk_cand_scalar(&k, o, (float)p.Sx, (float)p.Sy, _mm_cvtss_f32(pr.e1),
                                               _mm_cvtss_f32(pr.e2), p.cull_mask, p.kx, p.ky, p.kz));
#endif
        for (int i = 0; i < RT_PK; i++) {
            double tt;
            int front;
            int cull = (k.ref[i] & RT_REF_CULL) != 0;
            int hit = rt__tri_hit_drec(&p, dv[i], cull, -INFINITY, INFINITY, 0, &tt, &front);
            /* A culled back face the float test dropped (it may keep some). */
            if (cull && !hit && rt__tri_hit_drec(&p, dv[i], 0, -INFINITY, INFINITY, 0, &tt, &front))
                back_dropped += !((m >> i) & 1);
            if (hit) {
                if (!((m >> i) & 1))
                    fail_msg("trial %d lane %d: the float test dropped a hit (scale %g, "
                             "offset %g)",
                             trial, i, sc, off);
                kept_hits++;
            } else if (kind >= 3 && sc < 1e15) {
                misses++;
                rejected += !((m >> i) & 1);
            }
        }
    }
    assert_true(kept_hits > 10000); /* the aimed rays hit */
    /* Random rays miss most triangles by far more than the bound. */
    assert_true(rejected > 0.9 * (double)misses);
    /* Culled back faces are dropped too (most are: the aimed ones). */
    assert_true(back_dropped > 1000);

    /* NaN lanes are kept, unused lanes never. */
    rt_pk k;
    memset(&k, 0, sizeof k);
    for (int r = 0; r < 9; r++)
        k.v[r][1] = NAN;
    k.ref[1] = 5u << RT_REF_SHIFT | RT_REF_PRIM;
    rr_ray ray = {rr_v3(0, 0, -1), rr_v3(0, 0, 1)};
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    rt_pkray pr;
    rt__pkray_init(&p, 1.0f, p.box_double, &pr);
    assert_int_equal(rt__pk_cand(&k, &pr), 1u << 1);
}

/* rt__f_up / rt__f_down (branch-free) against nextafterf. */
static void f_round_matches_nextafter(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(5, 0);
    const double special[] = {0.0, -0.0, 1e-46, -1e-46, 1e-40, -1e-40, 1.0, -1.0, 0.1, -0.1, (double)FLT_MAX,
                              -(double)FLT_MAX, 3.5e38, -3.5e38, 1e300, -1e300, INFINITY, -INFINITY,
                              (double)FLT_TRUE_MIN, -(double)FLT_TRUE_MIN, 1.0 + 1e-12, -1.0 - 1e-12};
    const int ns = (int)(sizeof special / sizeof special[0]);
    for (int i = 0; i < ns + 200000; i++) {
        double x;
        if (i < ns) {
            x = special[i];
        } else {
            double m = rr_rng_uniform(&rng) * 2.0 - 1.0;
            x = ldexp(m, (int)rr_rng_below(&rng, 300) - 150);
            if (i % 5 == 0)
                x = (double)(float)x; /* exactly a float */
        }
        float f = (float)x;
        float up = (double)f < x ? nextafterf(f, INFINITY) : f;
        float down = (double)f > x ? nextafterf(f, -INFINITY) : f;
        float u = rt__f_up(x), d = rt__f_down(x);
        assert_true(memcmp(&u, &up, sizeof u) == 0 || (u == 0.0f && up == 0.0f));
        assert_true(memcmp(&d, &down, sizeof d) == 0 || (d == 0.0f && down == 0.0f));
        assert_true((double)u >= x && (double)d <= x);
    }
    assert_true(rt__f_up(NAN) != rt__f_up(NAN) && rt__f_down(NAN) != rt__f_down(NAN));
    /* The ray set-up rounds the origin three coordinates at once (SSE2):
     * the same floats, bit for bit. */
    for (int i = 0; i < 3 * (ns + 20000); i++) {
        double x[3];
        for (int k = 0; k < 3; k++) {
            int j = i + k * 7;
            x[k] = j % 3 == 0 && j / 3 < ns
                       ? special[j / 3]
                       : ldexp(rr_rng_uniform(&rng) * 2.0 - 1.0, (int)rr_rng_below(&rng, 300) - 150);
        }
        rr_ray r = {rr_v3(x[0], x[1], x[2]), rr_v3(i % 2 ? 1.0 : -1.0, i % 3 ? 0.5 : -0.5, i % 5 ? -0.25 : 0.25)};
        rt_ray_pre p;
        rt__ray_prepare(r, &p);
        for (int k = 0; k < 3; k++) {
            float u = rt__f_up(x[k]), d = rt__f_down(x[k]);
            float nr = p.neg[k] ? d : u, fr = p.neg[k] ? u : d;
            assert_memory_equal(&p.org_near[k], &nr, sizeof nr);
            assert_memory_equal(&p.org_far[k], &fr, sizeof fr);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(wide_box_tests_agree_and_conservative),
        cmocka_unit_test(wide_simd_box_tests_conservative),
        cmocka_unit_test(bvh_negative_zero_direction),
        cmocka_unit_test(bvh_fast_path_matches_reference_random),
        cmocka_unit_test(bvh_fast_path_large_and_watertight),
        cmocka_unit_test(bvh_triangle_wins_tie_with_primitive),
        cmocka_unit_test(bvh_widths_agree),
        cmocka_unit_test(bvh_occluded_matches_walk),
        cmocka_unit_test(bvh_tris_in_box_matches_brute_force),
        cmocka_unit_test(f_round_matches_nextafter),
        cmocka_unit_test(pk_float_test_conservative),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
