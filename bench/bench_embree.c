/* bench_embree.c - radray's BVH side by side with Embree 3 (radray-bench-embree).
 *
 *   radray-bench-embree [--quick] [--scene NAME] [--seed N]
 *
 * Optional (cmake -DRADRAY_EMBREE=ON, needs libembree-dev). Same scenes and
 * same rays as radray-bench (bench_scenes.c): the triangles of the loaded scene
 * go into one Embree RTC_GEOMETRY_TYPE_TRIANGLE geometry (vertices converted to
 * float in a shared buffer, indices in a shared uint32 buffer, primID = radray's
 * triangle index), and every workload is traced through both, one after the
 * other, in this process: radray with rt_accel_closest / rt_accel_occluded,
 * Embree with rtcIntersect1 / rtcOccluded1, one ray at a time, each in the same
 * OpenMP loop (schedule(dynamic, 1024)) at 1 thread and at all threads. A
 * fourth workload, "packets", traces the primary rays again as packets:
 * radray's rt_accel_closest_n on 8 x 8 pixel tiles against Embree's
 * rtcIntersect16 on 4 x 4 tiles (and, on a line below, against Embree's
 * rtcIntersect1 figure of the primary row). A fifth, "shadowpk", does the
 * same with the shadow rays (rt_accel_occluded_n against rtcOccluded16, and
 * below against the shadow row's rtcOccluded1).
 *
 * Reported per scene: BVH build time of both (median of 3; radray at 1
 * thread and at all threads, render.threads 1 and 0; Embree on a "threads=1"
 * device and on a default device, which builds with all of TBB's threads), then per workload and thread count the
 * Mrays/s of both (median of 5), the ratio radray / Embree, and agreement of
 * the two: same hit/miss, and for rays both hit, the same triangle and
 * |t_radray - t_embree| <= 1e-4 t.
 *
 * Embree takes float rays: the double rays are rounded to float once, before
 * the timed loops (untimed for both), with tnear = 0 for primary rays and a
 * small scene-scaled tnear for the secondary ones (see to_embree_ray).
 */
#include <embree3/rtcore.h>
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench_scenes.h"
#include "rr_core.h"
#include "rt.h"
#include "scene.h"

#ifndef RADRAY_BUILD_TYPE
#define RADRAY_BUILD_TYPE "unknown"
#endif

#define BENCH_SEED 20240601u
#define BENCH_BUILD_REPS 3
#define BENCH_TRACE_REPS 5

static void embree_error(void *user, enum RTCError code, const char *str)
{
    (void)user;
    fprintf(stderr, "radray-bench-embree: Embree error %d: %s\n", (int)code, str ? str : "");
    exit(1);
}

static RTCDevice new_device(const char *config)
{
    RTCDevice d = rtcNewDevice(config);
    if (!d) {
        fprintf(stderr, "radray-bench-embree: rtcNewDevice failed (error %d)\n", (int)rtcGetDeviceError(NULL));
        exit(1);
    }
    rtcSetDeviceErrorFunction(d, embree_error, NULL);
    return d;
}

/* The scene's triangles as Embree wants them: float xyz (+ 1 float of padding
 * after the last vertex, which Embree may read with a 16-byte load) and uint32
 * index triples in radray's triangle order. */
typedef struct embree_mesh {
    float *verts;
    uint32_t *idx;
    size_t nverts, ntris;
} embree_mesh;

static embree_mesh mesh_from_scene(const scene *s)
{
    embree_mesh m;
    m.nverts = s->nverts;
    m.ntris = s->ntris;
    m.verts = xmalloc((3 * s->nverts + 4) * sizeof(float));
    m.idx = xmalloc(3 * s->ntris * sizeof(uint32_t));
    for (size_t i = 0; i < s->nverts; i++) {
        m.verts[3 * i + 0] = (float)s->verts[i].x;
        m.verts[3 * i + 1] = (float)s->verts[i].y;
        m.verts[3 * i + 2] = (float)s->verts[i].z;
    }
    memset(m.verts + 3 * s->nverts, 0, 4 * sizeof(float));
    for (size_t i = 0; i < s->ntris; i++)
        for (int k = 0; k < 3; k++)
            m.idx[3 * i + k] = s->tris[i].v[k];
    return m;
}

static RTCScene embree_build(RTCDevice dev, const embree_mesh *m)
{
    RTCScene sc = rtcNewScene(dev);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m->verts, 0, 3 * sizeof(float),
                               m->nverts);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m->idx, 0, 3 * sizeof(uint32_t),
                               m->ntris);
    rtcCommitGeometry(g);
    rtcAttachGeometry(sc, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(sc);
    return sc;
}

/* Median build time of BENCH_BUILD_REPS builds on dev; keeps the last scene
 * when keep is not NULL. */
static double embree_build_time(RTCDevice dev, const embree_mesh *m, RTCScene *keep)
{
    double tb[BENCH_BUILD_REPS];
    RTCScene sc = NULL;
    for (int r = 0; r < BENCH_BUILD_REPS; r++) {
        if (sc)
            rtcReleaseScene(sc);
        double t0 = now_s();
        sc = embree_build(dev, m);
        tb[r] = now_s() - t0;
    }
    if (keep)
        *keep = sc;
    else
        rtcReleaseScene(sc);
    return median(tb, BENCH_BUILD_REPS);
}

/* tnear: 0 for primary rays (as radray's tmin); for the rays that start on a
 * surface (secondary), rounding the nudged double origin to float puts it back
 * on (or behind) the surface, and Embree would find the surface it starts on,
 * so they skip a distance of 1e-5 * (max |origin coordinate| + scene extent),
 * the usual float epsilon (radray's double rays need only the 1e-9 nudge). */
static struct RTCRay to_embree_ray(rr_ray r, double tmax, double extent, int secondary)
{
    struct RTCRay e;
    double m = fmax(fabs(r.o.x), fmax(fabs(r.o.y), fabs(r.o.z)));
    e.org_x = (float)r.o.x;
    e.org_y = (float)r.o.y;
    e.org_z = (float)r.o.z;
    e.tnear = secondary ? (float)(1e-5 * (m + extent) / sqrt(rr_v3_dot(r.d, r.d))) : 0.0f;
    e.dir_x = (float)r.d.x;
    e.dir_y = (float)r.d.y;
    e.dir_z = (float)r.d.z;
    e.time = 0.0f;
    e.tfar = (float)tmax;
    e.mask = 0xFFFFFFFFu;
    e.id = 0;
    e.flags = 0;
    return e;
}

/* One traced result per ray, for the agreement check. */
typedef struct result {
    int hit;
    int64_t prim;
    double t;
} result;

/* Trace the whole set once; when out is not NULL, store every ray's result.
 * Returns the wall time. shadow: any hit (occluded). */
static double trace_radray(const rt_accel *a, const ray_set *rs, int shadow, int threads, result *out, size_t *nhits)
{
    const long n = (long)rs->n;
    const rr_ray *rays = rs->rays;
    const double tmax = rs->tmax;
    size_t hits = 0;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : hits)
    for (long i = 0; i < n; i++) {
        result r = {0, -1, 0.0};
        if (shadow) {
            r.hit = rt_accel_occluded(a, rays[i], 0.0, tmax);
        } else {
            rt_hit h;
            r.hit = rt_accel_closest(a, rays[i], 0.0, tmax, &h);
            if (r.hit) {
                r.prim = h.tri;
                r.t = h.t;
            }
        }
        hits += (size_t)r.hit;
        if (out)
            out[i] = r;
    }
    double dt = now_s() - t0;
    *nhits = hits;
    return dt;
}

static double trace_embree(RTCScene sc, const struct RTCRay *rays, size_t count, int shadow, int threads, result *out,
                           size_t *nhits)
{
    const long n = (long)count;
    size_t hits = 0;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : hits)
    for (long i = 0; i < n; i++) {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        result r = {0, -1, 0.0};
        if (shadow) {
            struct RTCRay ray = rays[i];
            rtcOccluded1(sc, &ctx, &ray);
            r.hit = ray.tfar < 0.0f; /* set to -inf when occluded */
        } else {
            struct RTCRayHit rh;
            rh.ray = rays[i];
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(sc, &ctx, &rh);
            if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
                r.hit = 1;
                r.prim = rh.hit.primID;
                r.t = rh.ray.tfar;
            }
        }
        hits += (size_t)r.hit;
        if (out)
            out[i] = r;
    }
    double dt = now_s() - t0;
    *nhits = hits;
    return dt;
}

/* A set in packets: radray's rt_accel_closest_n / rt_accel_occluded_n
 * (shadow) over the rays of each 8 x 8 pixel tile, Embree's rtcIntersect16
 * / rtcOccluded16 over each 4 x 4 tile's (bench_tile_order); results stored
 * by the rays' own index. */
static double trace_radray_pk(const rt_accel *a, const ray_set *rs, const tile_order *to, int shadow, int threads,
                              result *out, size_t *nhits)
{
    const long nt = (long)to->ntiles;
    size_t hits = 0;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads) reduction(+ : hits)
    for (long t = 0; t < nt; t++) {
        rr_ray r[64];
        rt_hit h[64];
        unsigned char f[64];
        const uint32_t *idx = to->idx + to->start[t];
        int m = (int)(to->start[t + 1] - to->start[t]);
        if (m == 0)
            continue;
        for (int k = 0; k < m; k++)
            r[k] = rs->rays[idx[k]];
        hits += (size_t)(shadow ? rt_accel_occluded_n(a, r, m, 0.0, rs->tmax, f)
                                : rt_accel_closest_n(a, r, m, 0.0, rs->tmax, h, f));
        if (out)
            for (int k = 0; k < m; k++) {
                result x = {f[k], f[k] && !shadow ? (int64_t)h[k].tri : -1, f[k] && !shadow ? h[k].t : 0.0};
                out[idx[k]] = x;
            }
    }
    double dt = now_s() - t0;
    *nhits = hits;
    return dt;
}

static double trace_embree16(RTCScene sc, const struct RTCRay *rays, const tile_order *to, int shadow, int threads,
                             result *out, size_t *nhits)
{
    const long nt = (long)to->ntiles;
    size_t hits = 0;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads) reduction(+ : hits)
    for (long t = 0; t < nt; t++) {
        const uint32_t *idx = to->idx + to->start[t];
        int m = (int)(to->start[t + 1] - to->start[t]);
        if (m == 0)
            continue;
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTC_ALIGN(64) struct RTCRayHit16 rh;
        RTC_ALIGN(64) int valid[16];
        for (int k = 0; k < 16; k++) {
            const struct RTCRay *r = &rays[idx[k < m ? k : 0]];
            valid[k] = k < m ? -1 : 0;
            rh.ray.org_x[k] = r->org_x;
            rh.ray.org_y[k] = r->org_y;
            rh.ray.org_z[k] = r->org_z;
            rh.ray.dir_x[k] = r->dir_x;
            rh.ray.dir_y[k] = r->dir_y;
            rh.ray.dir_z[k] = r->dir_z;
            rh.ray.tnear[k] = r->tnear;
            rh.ray.tfar[k] = r->tfar;
            rh.ray.time[k] = 0.0f;
            rh.ray.mask[k] = r->mask;
            rh.ray.id[k] = 0;
            rh.ray.flags[k] = 0;
            rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        if (shadow)
            rtcOccluded16(valid, sc, &ctx, &rh.ray);
        else
            rtcIntersect16(valid, sc, &ctx, &rh);
        for (int k = 0; k < m; k++) {
            result x = {0, -1, 0.0};
            if (shadow) {
                x.hit = rh.ray.tfar[k] < 0.0f; /* set to -inf when occluded */
            } else if (rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID) {
                x.hit = 1;
                x.prim = rh.hit.primID[k];
                x.t = rh.ray.tfar[k];
            }
            hits += (size_t)x.hit;
            if (out)
                out[idx[k]] = x;
        }
    }
    double dt = now_s() - t0;
    *nhits = hits;
    return dt;
}

typedef struct agreement {
    size_t n, same_hitmiss, both_hit, same_prim, same_t, all;
} agreement;

static agreement compare(const result *ra, const result *rb, size_t n)
{
    agreement g = {n, 0, 0, 0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        if (ra[i].hit != rb[i].hit)
            continue;
        g.same_hitmiss++;
        if (!ra[i].hit) {
            g.all++;
            continue;
        }
        g.both_hit++;
        int sp = ra[i].prim == rb[i].prim;
        int st = fabs(ra[i].t - rb[i].t) <= 1e-4 * fabs(ra[i].t);
        g.same_prim += (size_t)sp;
        g.same_t += (size_t)st;
        g.all += (size_t)(sp && st);
    }
    return g;
}

static double pct(size_t a, size_t b)
{
    return b ? 100.0 * (double)a / (double)b : 100.0;
}

static double mrays(size_t n, double *sec)
{
    double mr[BENCH_TRACE_REPS];
    for (int r = 0; r < BENCH_TRACE_REPS; r++)
        mr[r] = (double)n / sec[r] * 1e-6;
    return median(mr, BENCH_TRACE_REPS);
}

static void run_scene(bench_scene *b, int res, uint64_t seed, const int *threads, int nthreads, const char *tmpdir)
{
    printf("\n== %s: %s\n", b->name, b->recipe);
    double t_write, t_load;
    scene *s = bench_load_scene(b, res, tmpdir, &t_write, &t_load);
    rr_error err;

    /* radray's build at 1 thread and at all (render.threads); the last kept. */
    double t_radray_at[2];
    rt_accel *a = NULL;
    for (int ti = 0; ti < 2; ti++) {
        double tb[BENCH_BUILD_REPS];
        s->settings.threads = ti == 0 ? 1 : 0;
        for (int r = 0; r < BENCH_BUILD_REPS; r++) {
            rt_accel_destroy(a);
            a = NULL;
            double t0 = now_s();
            if (rt_accel_build(s, &a, &err) != RR_OK) {
                fprintf(stderr, "radray-bench-embree: %s\n", err.msg);
                exit(1);
            }
            tb[r] = now_s() - t0;
        }
        t_radray_at[ti] = median(tb, BENCH_BUILD_REPS);
    }
    double t_radray = t_radray_at[0];

    double t0 = now_s();
    embree_mesh m = mesh_from_scene(s);
    double t_conv = now_s() - t0;
    RTCDevice dev1 = new_device("threads=1");
    double t_emb1 = embree_build_time(dev1, &m, NULL);
    rtcReleaseDevice(dev1);
    RTCDevice dev = new_device(NULL);
    RTCScene sc = NULL;
    double t_embn = embree_build_time(dev, &m, &sc);

    printf("triangles %zu (vertices %zu)\n", s->ntris, s->nverts);
    printf("BVH build (median of %d): radray %.1f ms (1 thread), %.1f ms (all threads); Embree %.1f ms (threads=1), "
           "%.1f ms (all threads, TBB); float conversion %.0f ms (untimed)\n",
           BENCH_BUILD_REPS, 1e3 * t_radray, 1e3 * t_radray_at[1], 1e3 * t_emb1, 1e3 * t_embn, 1e3 * t_conv);
    printf("build ratios: radray / Embree at 1 thread %.2fx; radray all threads over 1 thread %.2fx\n",
           t_radray / t_emb1, t_radray / t_radray_at[1]);

    ray_set prim, diff, shad;
    bench_make_rays(s, a, b, seed, &prim, &diff, &shad);

    rr_vec3 ext = rr_v3_sub(s->bbox_max, s->bbox_min);
    double extent = fmax(ext.x, fmax(ext.y, ext.z));
    /* "packets": the primary rays again, radray's rt_accel_closest_n on
     * 8 x 8 tiles against Embree's rtcIntersect16 on 4 x 4 tiles;
     * "shadowpk": the shadow rays the same way (rt_accel_occluded_n,
     * rtcOccluded16). */
    const char *wname[5] = {"primary", "diffuse", "shadow", "packets", "shadowpk"};
    const ray_set *wset[5] = {&prim, &diff, &shad, &prim, &shad};
    tile_order to8[5], to4[5];
    for (int w = 3; w < 5; w++) {
        to8[w] = bench_tile_order(wset[w], 8);
        to4[w] = bench_tile_order(wset[w], 4);
    }
    double emb1[3][2] = {{0}}; /* Embree's rtcIntersect1 / rtcOccluded1 rates per workload and thread count */
    printf("%-8s %7s %9s %6s %10s %10s %7s %8s %8s %8s %8s\n", "workload", "threads", "rays", "hit%", "radray",
           "Embree", "ratio", "hitmiss%", "prim%", "t%", "agree%");
    for (int w = 0; w < 5; w++) {
        const ray_set *rs = wset[w];
        int shadow = w == 2 || w == 4, pk = w >= 3;
        struct RTCRay *er = xmalloc(rs->n * sizeof *er);
        for (size_t i = 0; i < rs->n; i++)
            er[i] = to_embree_ray(rs->rays[i], rs->tmax, extent, rs != &prim);
        /* Agreement (untimed, all threads). */
        result *ra = xmalloc(rs->n * sizeof *ra), *rb = xmalloc(rs->n * sizeof *rb);
        size_t ha, hb;
        if (pk) {
            trace_radray_pk(a, rs, &to8[w], shadow, omp_get_max_threads(), ra, &ha);
            trace_embree16(sc, er, &to4[w], shadow, omp_get_max_threads(), rb, &hb);
        } else {
            trace_radray(a, rs, shadow, omp_get_max_threads(), ra, &ha);
            trace_embree(sc, er, rs->n, shadow, omp_get_max_threads(), rb, &hb);
        }
        agreement g = compare(ra, rb, rs->n);
        free(ra);
        free(rb);
        for (int ti = 0; ti < nthreads; ti++) {
            int th = threads[ti];
            double sa[BENCH_TRACE_REPS], sb[BENCH_TRACE_REPS];
            size_t h;
            for (int r = 0; r < BENCH_TRACE_REPS; r++)
                sa[r] = pk ? trace_radray_pk(a, rs, &to8[w], shadow, th, NULL, &h)
                           : trace_radray(a, rs, shadow, th, NULL, &h);
            for (int r = 0; r < BENCH_TRACE_REPS; r++)
                sb[r] = pk ? trace_embree16(sc, er, &to4[w], shadow, th, NULL, &h)
                           : trace_embree(sc, er, rs->n, shadow, th, NULL, &h);
            double mra = mrays(rs->n, sa), mrb = mrays(rs->n, sb);
            if (w < 3 && ti < 2)
                emb1[w][ti] = mrb;
            printf("%-8s %7d %9zu %6.1f %10.2f %10.2f %6.2fx %8.3f %8.3f %8.3f %8.3f\n", wname[w], th, rs->n,
                   pct(ha, rs->n), mra, mrb, mra / mrb, pct(g.same_hitmiss, g.n),
                   shadow ? 100.0 : pct(g.same_prim, g.both_hit), shadow ? 100.0 : pct(g.same_t, g.both_hit),
                   pct(g.all, g.n));
            if (pk && ti < 2)
                printf("  (%s: radray %.2f Mrays/s against Embree's %s %.2f: %.2fx)\n", wname[w], mra,
                       shadow ? "rtcOccluded1" : "rtcIntersect1", emb1[shadow ? 2 : 0][ti],
                       mra / emb1[shadow ? 2 : 0][ti]);
            fflush(stdout);
        }
        if (ha != hb)
            printf("  (%s: radray %zu hits, Embree %zu hits)\n", wname[w], ha, hb);
        free(er);
    }
    for (int w = 3; w < 5; w++) {
        bench_tile_order_free(&to8[w]);
        bench_tile_order_free(&to4[w]);
    }
    ray_set_free(&prim);
    ray_set_free(&diff);
    ray_set_free(&shad);
    rtcReleaseScene(sc);
    rtcReleaseDevice(dev);
    free(m.verts);
    free(m.idx);
    rt_accel_destroy(a);
    scene_destroy(s);
}

static void usage(FILE *f)
{
    fprintf(f,
            "usage: radray-bench-embree [--quick] [--scene NAME] [--seed N]\n"
            "  --quick         256x256 rays per workload instead of 1024x1024\n"
            "  --scene NAME    run only room-100k, mesh-1m or bunny-1m\n"
            "  --seed N        scene and ray seed (default %u)\n"
            "Threads: 1 and omp_get_max_threads() (OMP_NUM_THREADS).\n",
            BENCH_SEED);
}

int main(int argc, char **argv)
{
    bench_prog = "radray-bench-embree";
    int quick = 0;
    const char *only = NULL;
    uint64_t seed = BENCH_SEED;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) {
            quick = 1;
        } else if (!strcmp(argv[i], "--scene") && i + 1 < argc) {
            only = argv[++i];
            if (strcmp(only, "room-100k") && strcmp(only, "mesh-1m") && strcmp(only, "bunny-1m")) {
                fprintf(stderr, "radray-bench-embree: unknown scene '%s' (room-100k, mesh-1m or bunny-1m)\n", only);
                return 2;
            }
        } else if (!strcmp(argv[i], "--seed") && i + 1 < argc) {
            char *end;
            errno = 0;
            unsigned long long v = strtoull(argv[++i], &end, 10);
            if (end == argv[i] || *end || errno) {
                fprintf(stderr, "radray-bench-embree: bad --seed '%s'\n", argv[i]);
                return 2;
            }
            seed = (uint64_t)v;
        } else if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            usage(stdout);
            return 0;
        } else {
            usage(stderr);
            return 2;
        }
    }
    const uint16_t probe = 1;
    if (*(const unsigned char *)&probe != 1) {
        fprintf(stderr, "radray-bench-embree: the PLY writer assumes a little-endian host\n");
        return 1;
    }
    int maxt = omp_get_max_threads();
    int threads[2] = {1, maxt};
    int nthreads = maxt > 1 ? 2 : 1;

    char cpu[256];
    cpu_model(cpu, sizeof cpu);
    printf("radray-bench-embree: radray's BVH against Embree %d.%d.%d, same rays, one ray at a time\n",
           RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH);
    printf("machine: %ld online CPUs (nproc), omp_get_max_threads %d, CPU \"%s\"\n", sysconf(_SC_NPROCESSORS_ONLN),
           maxt, cpu);
#if defined(__VERSION__)
    printf("build: %s, compiler %s\n", RADRAY_BUILD_TYPE, __VERSION__);
#else
    printf("build: %s\n", RADRAY_BUILD_TYPE);
#endif
    printf("rays: %dx%d primary per scene, seed %" PRIu64 ", Mrays/s = median of %d runs, ratio = radray / Embree\n",
           quick ? 256 : 1024, quick ? 256 : 1024, seed, BENCH_TRACE_REPS);
    printf("agreement: hitmiss%% = same hit/miss; prim%%, t%% = of rays both hit, same triangle, "
           "|dt| <= 1e-4 t; agree%% = all of these\n");

    const char *tmp = getenv("TMPDIR");
    char tmpdir[4096];
    int tn = snprintf(tmpdir, sizeof tmpdir, "%s/radray-bench-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (tn < 0 || (size_t)tn >= sizeof tmpdir || !mkdtemp(tmpdir)) {
        fprintf(stderr, "radray-bench-embree: cannot create a temporary folder %s: %s\n", tmpdir, strerror(errno));
        return 1;
    }
    double t_all = now_s();
    for (int k = 0; k < 3; k++) {
        bench_scene b;
        memset(&b, 0, sizeof b);
        if (k == 0)
            make_room(&b, seed);
        else if (k == 1)
            make_mesh1m(&b, seed);
        else
            make_bunny1m(&b, RR_SOURCE_DIR "/scenes/meshes/bunny.ply");
        if (only && strcmp(only, b.name)) {
            soup_free(&b.mesh);
            continue;
        }
        run_scene(&b, quick ? 256 : 1024, seed, threads, nthreads, tmpdir);
    }
    rmdir(tmpdir);
    printf("\ntotal %.1f s\n", now_s() - t_all);
    return 0;
}
