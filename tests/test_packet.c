/* test_packet.c - the packet walks (raytrace/rt_packet.h,
 * rt_packet_occl.h): every ray of a packet gets the answer of the single
 * walk, bit for bit, at every node width, through the frusta, the 16-ray
 * tests and the per-ray fallbacks. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rt.h"
#include "test_bvh_util.h"
#include "test_scenes.h"

/* rt_accel_closest_n gives every ray of a packet rt_accel_closest's hit, bit
 * for bit, at every width: packets from one origin, narrow (the 16-wide
 * walk's frustum, which lets whole packets through untested) and wide, from
 * scattered origins, with axis-parallel directions (the double box test),
 * tmin < 0 and finite tmax mixed in, and counts that are not a multiple of
 * RT_PACKET_MAX (the call splits them). On a UV sphere of shared edges and
 * vertices too, where ties between triangles decide the hit. */
static void packet_walk_matches_single(void **state)
{
    (void)state;
    rr_error err;
    int ws[3], nw = widths_available(ws);
    static const int sizes[] = {1, 7, 16, 64, 100, 200};
    enum { MAXN = 200 };
    for (int pass = 0; pass < 4; pass++) {
        rr_rng rng = rr_rng_make(91, (uint64_t)pass);
        char *json = pass != 2 ? random_scene(&rng, 600, 8) : uv_sphere_scene(40, 64, "\"auto\"");
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "packets", "", NULL, &s, &err), RR_OK);
        free(json);
        if (pass == 1 || pass == 2)
            verts_to_float(s);
        /* Pass 3: the scene far from the world origin, double vertices (their
         * float copies' rounding then dwarfs the triangles' own float bound). */
        const rr_vec3 off = pass == 3 ? rr_v3(1000.0, -500.0, 250.0) : rr_v3(0, 0, 0);
        move_scene(s, off);
        for (int wi = 0; wi < nw; wi++) {
            rt_accel *a = NULL;
            assert_int_equal(rt__accel_build_width(s, ws[wi], &a, &err), RR_OK);
            long hits = 0, rays = 0;
            for (int q = 0; q < 600; q++) {
                int n = sizes[q % 6], kind = (q / 6) % 6;
                rr_ray r[MAXN];
                rt_hit h[MAXN];
                unsigned char f[MAXN];
                rr_vec3 o = rr_v3_scale(random_unit(&rng), 1.5 + rr_rng_uniform(&rng));
                rr_vec3 c = random_point(&rng, pass < 2 ? 1.0 : 0.6);
                double spread = kind == 0 ? 1e-3 : kind == 1 ? 0.05 : 0.8;
                for (int i = 0; i < n; i++) {
                    r[i].o = kind == 3 ? random_point(&rng, 2.0) : o;
                    r[i].d = rr_v3_sub(rr_v3_add(c, rr_v3_scale(random_point(&rng, 1.0), spread)), r[i].o);
                    if (kind == 4 && i % 5 == 0)
                        r[i].d.y = i % 10 ? 0.0 : -0.0; /* the double box test for this ray */
                    if (kind == 5) {
                        /* Through a vertex or an edge's midpoint: edge
                         * functions exactly 0, where the float tests' error
                         * bounds decide (and the ties between triangles). */
                        const scene_tri *t = &s->tris[rr_rng_below(&rng, (uint32_t)s->ntris)];
                        rr_vec3 p = rr_v3_sub(s->verts[t->v[0]], off);
                        if (i % 2)
                            p = rr_v3_scale(rr_v3_add(p, rr_v3_sub(s->verts[t->v[1]], off)), 0.5);
                        r[i].d = rr_v3_sub(p, o);
                    }
                }
                for (int i = 0; i < n; i++)
                    r[i].o = rr_v3_add(r[i].o, off);
                double tmin = q % 13 == 0 ? -0.25 : q % 2 ? 1e-9 : 0.0;
                double tmax = q % 4 == 0 ? 1.0 + 2.0 * rr_rng_uniform(&rng) : INFINITY;
                memset(h, 0, sizeof h);
                int nh = rt_accel_closest_n(a, r, n, tmin, tmax, h, f), count = 0;
                for (int i = 0; i < n; i++) {
                    rt_hit g;
                    memset(&g, 0, sizeof g);
                    int fg = rt_accel_closest(a, r[i], tmin, tmax, &g);
                    if (!same_hit(f[i], &h[i], fg, &g))
                        fprintf(stderr, "width %d packet %d ray %d: %d %d tri %lld %lld t %.17g %.17g\n", ws[wi], q,
                                i, f[i], fg, (long long)h[i].tri, (long long)g.tri, h[i].t, g.t);
                    assert_true(same_hit(f[i], &h[i], fg, &g));
                    count += fg;
                }
                assert_int_equal(nh, count);
                hits += count;
                rays += n;
            }
            /* Neither all misses nor all hits: the packets meet the scene. */
            assert_true(hits > rays / 10 && hits < rays - rays / 20);
            rt_accel_destroy(a);
        }
        scene_destroy(s);
    }
}

/* rt_accel_occluded_n gives every ray rt_accel_occluded's answer, at every
 * width: packets that share an origin, packets that share an end point
 * o + d (shadow rays towards a point: the 16-wide walk's reversed frustum,
 * with tmax just under 1, 1 itself, or less), end points a few ulps apart
 * (the frustum's Delta) or spread over a small light or apart enough to
 * leave the frustum off (the per-ray tests), scattered rays, axis-parallel
 * directions (the double box test), tmin < 0 and tmax < 0 (the closest
 * walk's rule), counts that are not a multiple of RT_PACKET_MAX; triangles
 * with float vertices and with double ones, near the world origin and 1000
 * units from it (where the 16-ray test must read the double copy). */
static void packet_occluded_matches_single(void **state)
{
    (void)state;
    rr_error err;
    int ws[3], nw = widths_available(ws);
    static const int sizes[] = {1, 9, 16, 64, 100, 130};
    enum { MAXN = 130 };
    for (int pass = 0; pass < 4; pass++) {
        rr_rng rng = rr_rng_make(93, (uint64_t)pass);
        char *json = pass != 2 ? random_scene(&rng, 40, 3) : uv_sphere_scene(40, 64, "\"auto\"");
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "packets", "", NULL, &s, &err), RR_OK);
        free(json);
        if (pass == 1 || pass == 2) /* passes 0 and 3: double vertices */
            verts_to_float(s);
        /* Pass 3: far from the world origin, where the double vertices' float
         * copies are off by more than the triangles' own float bound. */
        const rr_vec3 off = pass == 3 ? rr_v3(1000.0, -500.0, 250.0) : rr_v3(0, 0, 0);
        move_scene(s, off);
        for (int wi = 0; wi < nw; wi++) {
            rt_accel *a = NULL;
            assert_int_equal(rt__accel_build_width(s, ws[wi], &a, &err), RR_OK);
            long occl = 0, rays = 0;
            for (int q = 0; q < 840; q++) {
                int n = sizes[q % 6], kind = (q / 6) % 7;
                rr_ray r[MAXN];
                unsigned char f[MAXN];
                rr_vec3 p = random_point(&rng, 1.2); /* the shared point */
                rr_vec3 c = random_point(&rng, 0.8);
                double spread = q % 3 == 0 ? 0.02 : 0.6;
                for (int i = 0; i < n; i++) {
                    rr_vec3 x = rr_v3_add(c, rr_v3_scale(random_point(&rng, 1.0), spread));
                    if (kind == 0) { /* from one origin */
                        r[i].o = p;
                        r[i].d = rr_v3_sub(x, p);
                    } else if (kind <= 3 || kind == 6) { /* to one end point (as nearly as o + d rounds) */
                        rr_vec3 e = p;
                        if (kind == 6) /* to points of a small light: a wider frustum */
                            e = rr_v3_add(p, rr_v3_scale(random_point(&rng, 1.0), 0.05));
                        if (kind == 2) /* a few ulps apart */
                            e = rr_v3_add(p, rr_v3_scale(random_point(&rng, 1.0), 1e-15));
                        if (kind == 3 && i == n / 2) /* one ray elsewhere: no frustum */
                            e = rr_v3_add(p, rr_v3(1.5, 0.0, 0.0));
                        r[i].o = x;
                        r[i].d = rr_v3_sub(e, x);
                        if (kind == 1 && i % 7 == 3)
                            r[i].d.z = 0.0; /* the double box test; this packet takes no frustum */
                    } else if (kind == 4) { /* scattered */
                        r[i].o = random_point(&rng, 2.0);
                        r[i].d = rr_v3_sub(x, r[i].o);
                    } else { /* through a vertex from one end point */
                        const scene_tri *t = &s->tris[rr_rng_below(&rng, (uint32_t)s->ntris)];
                        r[i].o = rr_v3_sub(s->verts[t->v[i % 3]], off);
                        r[i].o = rr_v3_add(p, rr_v3_scale(rr_v3_sub(r[i].o, p), 1.5));
                        r[i].d = rr_v3_sub(p, r[i].o);
                    }
                }
                for (int i = 0; i < n; i++) /* o + d moves with o */
                    r[i].o = rr_v3_add(r[i].o, off);
                double tmin = q % 17 == 0 ? -0.25 : q % 2 ? 1e-9 : 0.0;
                int tk = (q / 36) % 5;
                double tmax = tk == 0 ? 1.0 - 1e-7 : tk == 1 ? 1.0 : tk == 2 ? 0.3 + 0.5 * rr_rng_uniform(&rng)
                                                  : tk == 3 ? INFINITY : (q % 11 == 0 ? -1.0 : 1.0 - 1e-7);
                memset(f, 7, sizeof f);
                int no = rt_accel_occluded_n(a, r, n, tmin, tmax, f), count = 0;
                for (int i = 0; i < n; i++) {
                    int g = rt_accel_occluded(a, r[i], tmin, tmax);
                    if (f[i] != g)
                        fprintf(stderr, "width %d packet %d (kind %d) ray %d: %d %d\n", ws[wi], q, kind, i, f[i], g);
                    assert_int_equal(f[i], g);
                    count += g;
                }
                assert_int_equal(no, count);
                occl += count;
                rays += n;
            }
            /* Neither all clear nor all occluded. */
            assert_true(occl > rays / 10 && occl < rays - rays / 10);
            rt_accel_destroy(a);
        }
        scene_destroy(s);
    }
}

/* A flat n x n grid of small triangles in z = 0 (vertices jittered in x and
 * y, so they are doubles), double-sided, centred on the origin. */
static char *grid_scene(int n, rr_rng *rng)
{
    size_t nv = (size_t)(n + 1) * (n + 1), cap = nv * 80 + (size_t)n * n * 48 + 1024, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                            "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                            "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                            "{\"type\":\"triangles\",\"material\":\"a\",\"cull\":false,\"vertices\":[");
    for (int i = 0; i <= n; i++)
        for (int j = 0; j <= n; j++) {
            double x = -1 + 2.0 * j / n + 0.3 / n * (rr_rng_uniform(rng) - 0.5);
            double y = -1 + 2.0 * i / n + 0.3 / n * (rr_rng_uniform(rng) - 0.5);
            len += (size_t)snprintf(buf + len, cap - len, "%s[%.17g,%.17g,0]", i || j ? "," : "", x, y);
        }
    len += (size_t)snprintf(buf + len, cap - len, "],\"indices\":[");
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            int v = i * (n + 1) + j;
            len += (size_t)snprintf(buf + len, cap - len, "%s[%d,%d,%d],[%d,%d,%d]", i || j ? "," : "", v, v + 1,
                                    v + n + 2, v, v + n + 2, v + n + 1);
        }
    snprintf(buf + len, cap - len, "]}]}");
    return buf;
}

/* The 16-ray leaf test's bound, where any-hit answers hang on it: shadow
 * rays from below a flat grid to one end point above it, each through an
 * inner vertex or an edge's midpoint of the grid, the only surface on the
 * segment. The watertight test gives exactly one of the triangles around
 * such a point the hit, so a triangle the 16-ray test drops wrongly turns
 * an occluded ray clear. Grids at the world origin and 1000 units from it
 * (double vertices). */
static void packet_occluded_through_vertices(void **state)
{
    (void)state;
    rr_error err;
    int ws[3], nw = widths_available(ws);
    enum { N = 24, MAXN = 64 };
    for (int pass = 0; pass < 2; pass++) {
        rr_rng rng = rr_rng_make(95, (uint64_t)pass);
        char *json = grid_scene(N, &rng);
        scene *s = NULL;
        assert_int_equal(scene_load_string(json, "grid", "", NULL, &s, &err), RR_OK);
        free(json);
        const rr_vec3 off = pass ? rr_v3(1000.0, -500.0, 250.0) : rr_v3(0, 0, 0);
        move_scene(s, off);
        for (int wi = 0; wi < nw; wi++) {
            rt_accel *a = NULL;
            assert_int_equal(rt__accel_build_width(s, ws[wi], &a, &err), RR_OK);
            long occl = 0, rays = 0;
            for (int q = 0; q < 300; q++) {
                int n = q % 3 == 0 ? 16 : MAXN;
                rr_ray r[MAXN];
                unsigned char f[MAXN];
                /* The end point above the grid, the points near each other
                 * (a tile's worth) or anywhere. */
                rr_vec3 p = rr_v3_add(off, rr_v3(rr_rng_uniform(&rng) - 0.5, rr_rng_uniform(&rng) - 0.5,
                                                 0.3 + 2.0 * rr_rng_uniform(&rng)));
                int ci = 1 + (int)rr_rng_below(&rng, N - 2), cj = 1 + (int)rr_rng_below(&rng, N - 2);
                int span = q % 2 ? 2 : N - 2;
                for (int i = 0; i < n; i++) {
                    int vi = ci + (int)rr_rng_below(&rng, (uint32_t)span), vj = cj + (int)rr_rng_below(&rng, (uint32_t)span);
                    vi = vi < 1 ? 1 : vi > N - 1 ? N - 1 : vi;
                    vj = vj < 1 ? 1 : vj > N - 1 ? N - 1 : vj;
                    rr_vec3 v = s->verts[(size_t)vi * (N + 1) + (size_t)vj];
                    if (i % 3 == 1) /* an edge's midpoint */
                        v = rr_v3_scale(rr_v3_add(v, s->verts[(size_t)vi * (N + 1) + (size_t)vj + 1]), 0.5);
                    else if (i % 3 == 2) /* a diagonal's */
                        v = rr_v3_scale(rr_v3_add(v, s->verts[(size_t)(vi + 1) * (N + 1) + (size_t)vj + 1]), 0.5);
                    r[i].o = rr_v3_add(v, rr_v3_scale(rr_v3_sub(v, p), 0.5));
                    r[i].d = rr_v3_sub(p, r[i].o);
                }
                int no = rt_accel_occluded_n(a, r, n, 0.0, RT_SHADOW_END, f), count = 0;
                for (int i = 0; i < n; i++) {
                    int g = rt_accel_occluded(a, r[i], 0.0, RT_SHADOW_END);
                    if (f[i] != g)
                        fprintf(stderr, "grid pass %d width %d packet %d ray %d: %d %d\n", pass, ws[wi], q, i, f[i], g);
                    assert_int_equal(f[i], g);
                    count += g;
                }
                assert_int_equal(no, count);
                occl += count;
                rays += n;
            }
            /* The grid is the only surface and every segment crosses it. */
            assert_true(occl == rays);
            rt_accel_destroy(a);
        }
        scene_destroy(s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(packet_walk_matches_single),
        cmocka_unit_test(packet_occluded_matches_single),
        cmocka_unit_test(packet_occluded_through_vertices),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
