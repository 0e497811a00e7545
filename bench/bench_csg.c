/* bench_csg.c - ray throughput on a scene with solids (radray-bench-csg).
 *
 *   radray-bench-csg [SCENE.json] [--width N] [--threads N]
 *
 * Default scene: scenes/csg.json (a lens, a sphere with a bite taken by a
 * cube, a closed 6,912-triangle mesh with a cylindrical hole, in a room of 8
 * triangles), camera resized to --width (default 640). The same three
 * workloads as radray-bench (primary, diffuse, shadow: bench_make_rays, point
 * light under the lamp at (0, 2.9, 0.1)), traced through rt_accel_closest /
 * rt_accel_occluded, each at 1 thread and at N threads (default: all),
 * Mrays/s the median of 5 repetitions. Every workload is also split by what
 * its rays hit first in the scene (a solid, or a triangle / nothing), so the
 * cost of a ray that meets a CSG tree is shown beside that of one that does
 * not. Rays are generated once, untimed.
 *
 * Not a ctest test: timings belong in a benchmark.
 */
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_scenes.h"

#define REPS 5

typedef struct split {
    ray_set all, solid, other;
} split;

/* Splits rs by the first thing each ray hits (closest hit, for every
 * workload, so shadow rays are split by their first occluder too). */
static void split_rays(const scene *s, const rt_accel *a, const ray_set *rs, split *out)
{
    out->all = *rs;
    out->solid.rays = xmalloc((rs->n ? rs->n : 1) * sizeof(rr_ray));
    out->other.rays = xmalloc((rs->n ? rs->n : 1) * sizeof(rr_ray));
    out->solid.n = out->other.n = 0;
    out->solid.tmax = out->other.tmax = rs->tmax;
    for (size_t i = 0; i < rs->n; i++) {
        rt_hit h;
        int solid = rt_accel_closest(a, rs->rays[i], 0.0, rs->tmax, &h) && s->objects[h.object].kind == SCENE_OBJ_CSG;
        ray_set *to = solid ? &out->solid : &out->other;
        to->rays[to->n++] = rs->rays[i];
    }
}

/* Mrays/s of one ray set (median of REPS runs); *hits gets the hit count. */
static double mrays(const rt_accel *a, const ray_set *rs, int any, int threads, size_t *hits)
{
    double t[REPS];
    size_t nh = 0;
    for (int r = 0; r < REPS; r++) {
        nh = 0;
        const long n = (long)rs->n;
        double t0 = now_s();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : nh)
        for (long i = 0; i < n; i++) {
            rt_hit h;
            nh += any ? (size_t)rt_accel_occluded(a, rs->rays[i], 0.0, rs->tmax)
                      : (size_t)rt_accel_closest(a, rs->rays[i], 0.0, rs->tmax, &h);
        }
        t[r] = now_s() - t0;
    }
    *hits = nh;
    double med = median(t, REPS);
    return med > 0 ? (double)rs->n / med * 1e-6 : 0.0;
}

int main(int argc, char **argv)
{
    bench_prog = "radray-bench-csg";
    const char *path = RR_SOURCE_DIR "/scenes/csg.json";
    int width = 640, threads = omp_get_max_threads();
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--width") == 0 && i + 1 < argc) {
            width = atoi(argv[++i]);
        } else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
            threads = atoi(argv[++i]);
        } else if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0) {
            printf("usage: radray-bench-csg [SCENE.json] [--width N] [--threads N]\n");
            return 0;
        } else if (argv[i][0] != '-') {
            path = argv[i];
        } else {
            fprintf(stderr, "radray-bench-csg: unknown option '%s' (try --help)\n", argv[i]);
            return 2;
        }
    }
    if (width < 16 || width > 8192 || threads < 1) {
        fprintf(stderr, "radray-bench-csg: --width must be in [16, 8192] and --threads >= 1\n");
        return 2;
    }
    rr_error err;
    scene *s = NULL;
    if (scene_load(path, NULL, &s, &err) != RR_OK || rr_view_resize(&s->view, width, &s->view, &err) != RR_OK) {
        fprintf(stderr, "radray-bench-csg: %s\n", err.msg);
        scene_destroy(s);
        return 2;
    }
    size_t nsolids = 0;
    for (size_t i = 0; i < s->nobjects; i++)
        nsolids += s->objects[i].kind == SCENE_OBJ_CSG;
    double tb[3];
    rt_accel *a = NULL;
    for (int r = 0; r < 3; r++) {
        rt_accel_destroy(a);
        a = NULL;
        double t0 = now_s();
        if (rt_accel_build(s, &a, &err) != RR_OK) {
            fprintf(stderr, "radray-bench-csg: %s\n", err.msg);
            scene_destroy(s);
            return 1;
        }
        tb[r] = now_s() - t0;
    }
    char cpu[128];
    cpu_model(cpu, sizeof cpu);
    printf("radray-bench-csg: %s, %d x %d rays, %zu triangles, %zu solids (%zu CSG nodes, %zu mesh-leaf triangles)\n",
           path, s->view.width, s->view.height, s->ntris, nsolids, s->ncsg, s->ncsg_tris);
    printf("cpu: %s; BVH build (median of 3, with the mesh leaves' BVHs): %.2f ms\n", cpu, 1e3 * median(tb, 3));
    bench_scene b;
    memset(&b, 0, sizeof b);
    b.light = rr_v3(0, 2.9, 0.1);
    ray_set prim, diff, shad;
    bench_make_rays(s, a, &b, 20240601u, &prim, &diff, &shad);
    const char *names[3] = {"primary", "diffuse", "shadow"};
    ray_set *sets[3] = {&prim, &diff, &shad};
    printf("%-8s %-7s %7s %9s | %9s %9s\n", "workload", "first", "threads", "rays", "Mrays/s", "hit%");
    for (int w = 0; w < 3; w++) {
        split sp;
        split_rays(s, a, sets[w], &sp);
        const ray_set *part[3] = {&sp.all, &sp.solid, &sp.other};
        const char *pname[3] = {"all", "solid", "other"};
        int tc[2] = {1, threads};
        for (int p = 0; p < 3; p++)
            for (int k = 0; k < (threads > 1 ? 2 : 1); k++) {
                size_t hits = 0;
                double m = part[p]->n ? mrays(a, part[p], w == 2, tc[k], &hits) : 0.0;
                printf("%-8s %-7s %7d %9zu | %9.2f %8.1f%%\n", names[w], pname[p], tc[k], part[p]->n, m,
                       part[p]->n ? 100.0 * (double)hits / (double)part[p]->n : 0.0);
            }
        free(sp.solid.rays);
        free(sp.other.rays);
    }
    free(prim.rays);
    free(diff.rays);
    free(shad.rays);
    rt_accel_destroy(a);
    scene_destroy(s);
    return 0;
}
