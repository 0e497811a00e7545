/* bench_rays.c - reproducible ray-throughput benchmark of the BVH (radray-bench).
 *
 *   radray-bench [--quick] [--threads LIST] [--scene NAME] [--seed N] [--light-size F]
 *
 * Two procedural scenes are generated in-process from a fixed recipe and seed
 * (see make_room / make_mesh1m in bench_scenes.c and bench/README.md), written as binary
 * PLY into a temporary folder and loaded through the real scene path
 * (scene_load_string with a {"type":"mesh","file":...} object), so the
 * benchmark measures exactly the triangles and the BVH the renderer would see.
 *
 * Per scene it reports the generation and load times, the BVH build time
 * (median of 3 builds at each thread count), the node count and the memory per triangle, then
 * Mrays/s (median of 5 repetitions) for five workloads, each at 1 thread and
 * at all threads:
 *   primary  coherent pinhole-camera rays, closest hit
 *   diffuse  one cosine-weighted direction from every primary hit, closest hit
 *   shadow   from every primary hit to a point light, any hit
 *   packets  primary again, in 8 x 8 pixel packets (rt_accel_closest_n)
 *   shadowpk shadow again, each 8 x 8 tile's rays as a packet (rt_accel_occluded_n)
 * Rays are generated once, untimed, into arrays (each ray from its own RNG
 * stream, so they do not depend on the thread count); the timed loop is an
 * OpenMP dynamic loop over the array, and a checksum of the hits keeps the
 * work from being optimised away and shows that every thread count saw the
 * same hits.
 *
 * Not a ctest test: timings belong in a benchmark, never in unit tests.
 */
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
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
#define BENCH_MAX_THREAD_CONFIGS 8

/* ----------------------------------------------------------------- timing */

typedef struct trace_result {
    double seconds;
    size_t hits;
    uint64_t checksum;
} trace_result;

static trace_result trace_closest(const rt_accel *a, const ray_set *rs, int threads)
{
    size_t hits = 0;
    uint64_t sum = 0;
    const long n = (long)rs->n;
    const rr_ray *rays = rs->rays;
    const double tmax = rs->tmax;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : hits, sum)
    for (long i = 0; i < n; i++) {
        rt_hit h;
        if (rt_accel_closest(a, rays[i], 0.0, tmax, &h)) {
            hits++;
            sum += rr_hash64(((uint64_t)i << 32) ^ (uint64_t)h.tri);
        }
    }
    trace_result r = {now_s() - t0, hits, sum};
    return r;
}

/* A set in packets: the rays of each BENCH_TILE x BENCH_TILE pixel tile
 * (bench_tile_order) through rt_accel_closest_n, or rt_accel_occluded_n
 * (shadow). The same answers as trace_closest and trace_occluded, so the
 * same checksums. */
#define BENCH_TILE 8
static trace_result trace_packets(const rt_accel *a, const ray_set *rs, const tile_order *to, int shadow, int threads)
{
    size_t hits = 0;
    uint64_t sum = 0;
    const long nt = (long)to->ntiles;
    const rr_ray *rays = rs->rays;
    const double tmax = rs->tmax;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads) reduction(+ : hits, sum)
    for (long t = 0; t < nt; t++) {
        rr_ray r[BENCH_TILE * BENCH_TILE];
        rt_hit h[BENCH_TILE * BENCH_TILE];
        unsigned char f[BENCH_TILE * BENCH_TILE];
        const uint32_t *idx = to->idx + to->start[t];
        int m = (int)(to->start[t + 1] - to->start[t]);
        if (m == 0)
            continue;
        for (int k = 0; k < m; k++)
            r[k] = rays[idx[k]];
        if (shadow) {
            hits += (size_t)rt_accel_occluded_n(a, r, m, 0.0, tmax, f);
            for (int k = 0; k < m; k++)
                if (f[k])
                    sum += rr_hash64((uint64_t)idx[k]);
        } else {
            hits += (size_t)rt_accel_closest_n(a, r, m, 0.0, tmax, h, f);
            for (int k = 0; k < m; k++)
                if (f[k])
                    sum += rr_hash64(((uint64_t)idx[k] << 32) ^ (uint64_t)h[k].tri);
        }
    }
    trace_result r = {now_s() - t0, hits, sum};
    return r;
}

static trace_result trace_occluded(const rt_accel *a, const ray_set *rs, int threads)
{
    size_t hits = 0;
    uint64_t sum = 0;
    const long n = (long)rs->n;
    const rr_ray *rays = rs->rays;
    const double tmax = rs->tmax;
    double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : hits, sum)
    for (long i = 0; i < n; i++) {
        if (rt_accel_occluded(a, rays[i], 0.0, tmax)) {
            hits++;
            sum += rr_hash64((uint64_t)i);
        }
    }
    trace_result r = {now_s() - t0, hits, sum};
    return r;
}

/* ------------------------------------------------------------------ main */

typedef struct options {
    int quick;
    int threads[BENCH_MAX_THREAD_CONFIGS];
    int nthreads;
    const char *only;
    uint64_t seed;
    double light_size;
} options;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: radray-bench [--quick] [--threads LIST] [--scene NAME] [--seed N] [--light-size F]\n"
            "  --quick         256x256 rays per workload instead of 1024x1024\n"
            "  --threads LIST  comma-separated thread counts (default: 1,<omp_get_max_threads()>)\n"
            "  --scene NAME    run only room-100k, mesh-1m or bunny-1m\n"
            "  --seed N        scene and ray seed (default %u; change it only to test robustness)\n"
            "  --light-size F  shadow rays to points of a square light of side F x the scene's extent\n"
            "                  (default 0: the point light; other checksums then)\n",
            BENCH_SEED);
}

static int parse_threads(const char *s, options *o)
{
    o->nthreads = 0;
    while (*s) {
        char *end;
        errno = 0;
        long v = strtol(s, &end, 10);
        if (end == s || errno || v < 1 || v > 4096 || (*end && *end != ',') ||
            o->nthreads == BENCH_MAX_THREAD_CONFIGS)
            return -1;
        o->threads[o->nthreads++] = (int)v;
        s = *end ? end + 1 : end;
    }
    return o->nthreads ? 0 : -1;
}


static void run_scene(bench_scene *b, const options *o, const char *tmpdir)
{
    int res = o->quick ? 256 : 1024;

    printf("\n== %s: %s\n", b->name, b->recipe);
    double t_write, t_load;
    scene *s = bench_load_scene(b, res, tmpdir, &t_write, &t_load);
    rr_error err;
    double t0;

    /* BVH: median of BENCH_BUILD_REPS builds at each thread count of the
     * list (render.threads, which the build uses); the last one is kept. */
    double t_build[BENCH_MAX_THREAD_CONFIGS];
    rt_accel *a = NULL;
    for (int ti = 0; ti < o->nthreads; ti++) {
        double tb[BENCH_BUILD_REPS];
        s->settings.threads = o->threads[ti];
        for (int r = 0; r < BENCH_BUILD_REPS; r++) {
            rt_accel_destroy(a);
            a = NULL;
            t0 = now_s();
            if (rt_accel_build(s, &a, &err) != RR_OK) {
                fprintf(stderr, "radray-bench: %s\n", err.msg);
                exit(1);
            }
            tb[r] = now_s() - t0;
        }
        t_build[ti] = median(tb, BENCH_BUILD_REPS);
    }
    /* Memory of the BVH: wide nodes and the leaf packets (no analytic
     * spheres or solids in these scenes). */
    rt_accel_stats ast = rt_accel_stats_of(a);
    size_t nodes = ast.nodes;
    double bpt = (double)ast.bytes / (double)s->ntris;

    printf("triangles %zu (vertices %zu), PLY write %.0f ms, scene load %.0f ms\n", s->ntris, s->nverts,
           1e3 * t_write, 1e3 * t_load);
    printf("BVH build (median of %d):", BENCH_BUILD_REPS);
    for (int ti = 0; ti < o->nthreads; ti++)
        printf(" %.0f ms at %d thread%s%s", 1e3 * t_build[ti], o->threads[ti], o->threads[ti] == 1 ? "" : "s",
               ti + 1 < o->nthreads ? "," : "");
    printf("; %zu nodes (%d wide), %.1f bytes/triangle\n", nodes, ast.width, bpt);

    /* Primary rays, and their hits (needed for the other two workloads). */
    ray_set prim, diff, shad;
    bench_make_rays(s, a, b, o->seed, &prim, &diff, &shad);

    /* "packets": the primary rays again, 8 x 8 pixel tiles through
     * rt_accel_closest_n; the same hits, so primary's checksum. "shadowpk":
     * the shadow rays of each 8 x 8 tile through rt_accel_occluded_n (they
     * share their end point, the light), with shadow's checksum. */
    const char *wname[5] = {"primary", "diffuse", "shadow", "packets", "shadowpk"};
    const ray_set *wset[5] = {&prim, &diff, &shad, &prim, &shad};
    tile_order tiles = bench_tile_order(&prim, BENCH_TILE), stiles = bench_tile_order(&shad, BENCH_TILE);
    printf("%-8s %7s %9s %6s %9s %17s  %-16s\n", "workload", "threads", "rays", "hit%", "Mrays/s", "min-max Mrays/s",
           "checksum");
    for (int w = 0; w < 5; w++) {
        for (int ti = 0; ti < o->nthreads; ti++) {
            int th = o->threads[ti];
            double mr[BENCH_TRACE_REPS];
            trace_result tr = {0, 0, 0};
            for (int r = 0; r < BENCH_TRACE_REPS; r++) {
                trace_result x = w == 4   ? trace_packets(a, wset[w], &stiles, 1, th)
                                 : w == 3 ? trace_packets(a, wset[w], &tiles, 0, th)
                                 : w == 2 ? trace_occluded(a, wset[w], th)
                                          : trace_closest(a, wset[w], th);
                if (r > 0 && (x.hits != tr.hits || x.checksum != tr.checksum)) {
                    fprintf(stderr, "radray-bench: %s %s: results differ between repetitions\n", b->name, wname[w]);
                    exit(1);
                }
                tr = x;
                mr[r] = (double)wset[w]->n / x.seconds * 1e-6;
            }
            double lo = mr[0], hi = mr[0];
            for (int r = 1; r < BENCH_TRACE_REPS; r++) {
                lo = fmin(lo, mr[r]);
                hi = fmax(hi, mr[r]);
            }
            double med = median(mr, BENCH_TRACE_REPS);
            char range[64];
            snprintf(range, sizeof range, "%.2f-%.2f", lo, hi);
            printf("%-8s %7d %9zu %6.1f %9.2f %17s  %016" PRIx64 "\n", wname[w], th, wset[w]->n,
                   wset[w]->n ? 100.0 * (double)tr.hits / (double)wset[w]->n : 0.0, med, range, tr.checksum);
            fflush(stdout);
        }
    }
    bench_tile_order_free(&tiles);
    bench_tile_order_free(&stiles);
    ray_set_free(&prim);
    ray_set_free(&diff);
    ray_set_free(&shad);
    rt_accel_destroy(a);
    scene_destroy(s);
}

int main(int argc, char **argv)
{
    options o = {0};
    o.seed = BENCH_SEED;
    int maxt = omp_get_max_threads();
    o.threads[o.nthreads++] = 1;
    if (maxt > 1)
        o.threads[o.nthreads++] = maxt;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick")) {
            o.quick = 1;
        } else if (!strcmp(argv[i], "--threads") && i + 1 < argc) {
            if (parse_threads(argv[++i], &o)) {
                fprintf(stderr, "radray-bench: bad --threads '%s' (want e.g. 1,2,4)\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(argv[i], "--scene") && i + 1 < argc) {
            o.only = argv[++i];
            if (strcmp(o.only, "room-100k") && strcmp(o.only, "mesh-1m") && strcmp(o.only, "bunny-1m")) {
                fprintf(stderr, "radray-bench: unknown scene '%s' (room-100k, mesh-1m or bunny-1m)\n", o.only);
                return 2;
            }
        } else if (!strcmp(argv[i], "--seed") && i + 1 < argc) {
            char *end;
            errno = 0;
            unsigned long long v = strtoull(argv[++i], &end, 10);
            if (end == argv[i] || *end || errno) {
                fprintf(stderr, "radray-bench: bad --seed '%s'\n", argv[i]);
                return 2;
            }
            o.seed = (uint64_t)v;
        } else if (!strcmp(argv[i], "--light-size") && i + 1 < argc) {
            char *end;
            o.light_size = strtod(argv[++i], &end);
            if (end == argv[i] || *end || !(o.light_size >= 0.0 && o.light_size <= 1.0)) {
                fprintf(stderr, "radray-bench: bad --light-size '%s' (want 0 .. 1)\n", argv[i]);
                return 2;
            }
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
        fprintf(stderr, "radray-bench: the PLY writer assumes a little-endian host\n");
        return 1;
    }

    char cpu[256];
    cpu_model(cpu, sizeof cpu);
    printf("radray-bench: ray throughput of the BVH (rt_accel_closest / rt_accel_occluded)\n");
    printf("machine: %ld online CPUs (nproc), omp_get_max_threads %d, CPU \"%s\"\n", sysconf(_SC_NPROCESSORS_ONLN),
           maxt, cpu);
#if defined(__VERSION__)
    printf("build: %s, compiler %s\n", RADRAY_BUILD_TYPE, __VERSION__);
#else
    printf("build: %s\n", RADRAY_BUILD_TYPE);
#endif
    printf("rays: %dx%d primary per scene, seed %" PRIu64 ", Mrays/s = median of %d runs, BVH build = median of %d\n",
           o.quick ? 256 : 1024, o.quick ? 256 : 1024, o.seed, BENCH_TRACE_REPS, BENCH_BUILD_REPS);

    const char *tmp = getenv("TMPDIR");
    char tmpdir[4096];
    int tn = snprintf(tmpdir, sizeof tmpdir, "%s/radray-bench-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (tn < 0 || (size_t)tn >= sizeof tmpdir || !mkdtemp(tmpdir)) {
        fprintf(stderr, "radray-bench: cannot create a temporary folder %s: %s\n", tmpdir, strerror(errno));
        return 1;
    }
    double t_all = now_s();
    for (int k = 0; k < 3; k++) {
        bench_scene b;
        memset(&b, 0, sizeof b);
        if (k == 0)
            make_room(&b, o.seed);
        else if (k == 1)
            make_mesh1m(&b, o.seed);
        else
            make_bunny1m(&b, RR_SOURCE_DIR "/scenes/meshes/bunny.ply");
        if (o.only && strcmp(o.only, b.name)) {
            soup_free(&b.mesh);
            continue;
        }
        b.light_size = o.light_size;
        run_scene(&b, &o, tmpdir);
    }
    rmdir(tmpdir);
    printf("\ntotal %.1f s\n", now_s() - t_all);
    return 0;
}
