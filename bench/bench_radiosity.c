/* bench_radiosity.c - how the radiosity pass grows with the number of patches.
 *
 *   build/radray-bench-radiosity [--max N] [--quick]
 *
 * Scene: scenes/cornell.json. For target patch counts 1k, 4k, 16k, 64k (up to
 * --max) the patch area is set to (surface area / target); each row reports
 * the patch count actually made, the form-factor time and stored entries for
 * the Monte Carlo method (512 rays per patch, the default) and, up to 4k
 * patches, the quadrature method (16 points per patch), then the solve time of
 * each solver that is practical at that size (direct: CHOLMOD, up to 16k;
 * iterative: Gauss-Seidel to 1e-9), and the whole pass end to end. Numbers go
 * to notes/performance.md. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "rad.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void die(const rr_error *e)
{
    fprintf(stderr, "radray-bench-radiosity: %s\n", e->msg);
    exit(1);
}

int main(int argc, char **argv)
{
    long max = 65536;
    int quick = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--max") && i + 1 < argc)
            max = atol(argv[++i]);
        else if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else {
            fprintf(stderr, "usage: radray-bench-radiosity [--max N] [--quick]\n");
            return 2;
        }
    }
    if (quick)
        max = 4096;
    char path[4096];
    snprintf(path, sizeof path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    scene *s = NULL;
    rr_error err;
    if (scene_load(path, NULL, &s, &err) != RR_OK)
        die(&err);
    rt_accel *a = NULL;
    if (rt_accel_build(s, &a, &err) != RR_OK)
        die(&err);
    double total = 0;
    for (size_t t = 0; t < s->ntris; t++)
        total += scene_tri_area(s, t);
    printf("radiosity pass on %s (%zu triangles), Monte Carlo 512 rays/patch, quadrature 16 points/patch\n", path,
           s->ntris);
    printf("%8s %9s | %9s %11s | %9s | %9s %6s | %9s %6s | %9s\n", "target", "patches", "MC ff s", "MC entries",
           "quad ff s", "direct s", "resid", "GS s", "iters", "total s");
    for (long target = 1024; target <= max; target *= 4) {
        rad_patch_opts po = {.max_area = total / (double)target, .max_edge = 1e30, .accel = NULL};
        double t0 = now();
        rad_patches *P = NULL;
        if (rad_patches_build(s, &po, &P, &err) != RR_OK)
            die(&err);
        double t1 = now();
        rad_ff_opts fo = {.method = RAD_FF_MONTE_CARLO, .samples = 512, .seed = 1};
        rad_ff *F = NULL;
        if (rad_ff_compute(s, a, P, &fo, &F, &err) != RR_OK)
            die(&err);
        double t2 = now();
        double tq = -1;
        if (P->n <= 4096) {
            rad_ff_opts qo = {.method = RAD_FF_QUADRATURE, .samples = 16, .seed = 1};
            rad_ff *Q = NULL;
            double q0 = now();
            if (rad_ff_compute(s, a, P, &qo, &Q, &err) != RR_OK)
                die(&err);
            tq = now() - q0;
            rad_ff_destroy(Q);
        }
        rr_rgb *B = malloc(P->n * sizeof *B);
        double td = -1, rd = 0, tg, t3 = 0;
        rad_solve_stats st;
        memset(&st, 0, sizeof st);
        if (P->n <= 16384) {
            rad_solve_opts so = {RAD_SOLVER_DIRECT, 1e-9, 0, 0, 0, NULL};
            double d0 = now();
            if (rad_solve(P, F, &so, B, &st, &err) != RR_OK)
                die(&err);
            td = now() - d0;
            rd = st.residual;
            free(st.history);
        }
        rad_solve_opts go = {RAD_SOLVER_ITERATIVE, 1e-9, 0, 0, 0, NULL};
        memset(&st, 0, sizeof st);
        double g0 = now();
        if (rad_solve(P, F, &go, B, &st, &err) != RR_OK)
            die(&err);
        tg = now() - g0;
        t3 = (t1 - t0) + (t2 - t1) + tg;
        char dbuf[32], qbuf[32];
        snprintf(dbuf, sizeof dbuf, td < 0 ? "-" : "%.3f", td);
        snprintf(qbuf, sizeof qbuf, tq < 0 ? "-" : "%.3f", tq);
        printf("%8ld %9zu | %9.3f %11zu | %9s | %9s %6.0e | %9.3f %6d | %9.3f\n", target, P->n, t2 - t1,
               F->rowptr[F->n], qbuf, dbuf, rd, tg, st.iterations, t3);
        fflush(stdout);
        free(st.history);
        free(B);
        rad_ff_destroy(F);
        rad_patches_destroy(P);
    }
    printf("total = patches + Monte Carlo form factors + Gauss-Seidel (the default 'auto' path for large N)\n");
    rt_accel_destroy(a);
    scene_destroy(s);
    return 0;
}
