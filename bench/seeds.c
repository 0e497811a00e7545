/* seeds.c - radray-seeds: how much the radiosity pass's solution moves with
 * its seed, per leaf (issue #13: "two seeds give radiosity values within
 * 0.5 % per leaf on the Cornell back wall").
 *
 *   build/radray-seeds SCENE OBJECT [--seeds A,B] [--set KEY=VALUE ...]
 *
 * Runs the scene's radiosity pass (its own method and settings, through
 * rad_pass_run as `radray render` runs it) with render.seed A and with B
 * (default 1 and 2), and compares, for every leaf patch of the object named
 * OBJECT in the first solution, its radiosity (the sum of its three
 * channels) with that of the leaf of the second solution that holds its
 * centroid: |B_A / B_B - 1|. Prints the leaves compared, the median, 90th and
 * 99th percentiles and the largest difference, and the share of leaves
 * within 0.5 %; for hierarchical solutions, the same figures on common cells
 * (common_cells below). Exit status 2 on bad arguments or a scene that does
 * not load, 1 when the object has no leaf. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rad.h"

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : (x > y);
}

static rad_solution *solve(const char *path, const char *const *over, size_t nover, unsigned long long seed,
                           scene **out_s, rt_accel **out_a)
{
    const char *all[64];
    char sd[64];
    snprintf(sd, sizeof sd, "render.seed=%llu", seed);
    size_t n = 0;
    for (size_t i = 0; i < nover && n < 63; i++)
        all[n++] = over[i];
    all[n++] = sd;
    scene_load_opts lo;
    memset(&lo, 0, sizeof lo);
    lo.overrides = all;
    lo.noverrides = n;
    rr_error err;
    scene *s = NULL;
    rt_accel *a = NULL;
    rad_solution *sol = NULL;
    if (scene_load(path, &lo, &s, &err) != RR_OK || rt_accel_build(s, &a, &err) != RR_OK) {
        fprintf(stderr, "radray-seeds: %s\n", err.msg);
        exit(2);
    }
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    po.ff.seed = s->settings.seed;
    if (rad_pass_run(s, a, &po, &sol, &err) != RR_OK) {
        fprintf(stderr, "radray-seeds: %s\n", err.msg);
        exit(2);
    }
    *out_s = s;
    *out_a = a;
    return sol;
}

/* Whether p lies in patch k's triangle (its plane's projection, with a
 * little slack for the shared edges). */
static int holds(const rad_patches *P, size_t k, rr_vec3 p)
{
    const rad_patch *t = &P->p[k];
    rr_vec3 a = P->verts[t->v[0]], b = P->verts[t->v[1]], c = P->verts[t->v[2]];
    rr_vec3 n = rr_v3_cross(rr_v3_sub(b, a), rr_v3_sub(c, a));
    double nn = rr_v3_dot(n, n);
    if (!(nn > 0))
        return 0;
    double u = rr_v3_dot(rr_v3_cross(rr_v3_sub(c, b), rr_v3_sub(p, b)), n) / nn;
    double v = rr_v3_dot(rr_v3_cross(rr_v3_sub(a, c), rr_v3_sub(p, c)), n) / nn;
    double w = 1.0 - u - v;
    const double e = -1e-9;
    return u >= e && v >= e && w >= e;
}

/* The area-weighted mean radiosity (summed channels) and the area of the
 * leaves under tree entry e of a hierarchical solution. */
static void subtree(const rad_solution *x, uint32_t e, double *power, double *area)
{
    const rad_patches *P = x->P;
    if (e & RAD_QT_LEAF) {
        uint32_t k = e & ~RAD_QT_LEAF;
        *power += P->p[k].area * (x->B[k].r + x->B[k].g + x->B[k].b);
        *area += P->p[k].area;
        return;
    }
    for (int c = 0; c < 4; c++)
        subtree(x, P->qt[4 * (size_t)e + c], power, area);
}

/* Two hierarchical solutions' trees over the same roots, walked together:
 * where both split, into the children; where either is a leaf, one cell:
 * both solutions' mean over the same triangle (the coarser of the two
 * leaves), |mean_A / mean_B - 1| into d. */
static void common_cells(const rad_solution *x, const rad_solution *y, uint32_t ex, uint32_t ey, double *d, size_t *n,
                         size_t cap)
{
    if (!(ex & RAD_QT_LEAF) && !(ey & RAD_QT_LEAF)) {
        for (int c = 0; c < 4; c++)
            common_cells(x, y, x->P->qt[4 * (size_t)ex + c], y->P->qt[4 * (size_t)ey + c], d, n, cap);
        return;
    }
    double px = 0, ax = 0, py = 0, ay = 0;
    subtree(x, ex, &px, &ax);
    subtree(y, ey, &py, &ay);
    if (ax > 0 && ay > 0 && py > 0 && *n < cap)
        d[(*n)++] = fabs((px / ax) / (py / ay) - 1.0);
}

static void report(const char *what, double *d, size_t n)
{
    qsort(d, n, sizeof *d, cmp_double);
    size_t within = 0;
    for (size_t i = 0; i < n; i++)
        within += d[i] <= 0.005;
    printf("%s: median %.3f %%, p90 %.3f %%, p99 %.3f %%, max %.3f %%; within 0.5 %%: %.1f %%\n", what,
           100 * d[n / 2], 100 * d[(size_t)(0.9 * (double)(n - 1))], 100 * d[(size_t)(0.99 * (double)(n - 1))],
           100 * d[n - 1], 100.0 * (double)within / (double)n);
}

int main(int argc, char **argv)
{
    const char *over[60];
    size_t nover = 0;
    unsigned long long sa = 1, sb = 2;
    const char *path = NULL, *name = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--seeds") && i + 1 < argc) {
            if (sscanf(argv[++i], "%llu,%llu", &sa, &sb) != 2 || sa == sb) {
                fprintf(stderr, "radray-seeds: --seeds wants two different seeds A,B\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--set") && i + 1 < argc && nover < 60) {
            over[nover++] = argv[++i];
        } else if (!path) {
            path = argv[i];
        } else if (!name) {
            name = argv[i];
        } else {
            path = NULL;
            break;
        }
    }
    if (!path || !name) {
        fprintf(stderr, "usage: radray-seeds SCENE OBJECT [--seeds A,B] [--set KEY=VALUE ...]\n");
        return 2;
    }
    scene *s1, *s2;
    rt_accel *a1, *a2;
    rad_solution *x = solve(path, over, nover, sa, &s1, &a1);
    rad_solution *y = solve(path, over, nover, sb, &s2, &a2);
    long obj = -1;
    for (size_t o = 0; o < s1->nobjects; o++)
        if (!strcmp(s1->objects[o].name, name))
            obj = (long)o;
    if (obj < 0) {
        fprintf(stderr, "radray-seeds: %s: no object named %s\n", path, name);
        return 2;
    }
    const rad_patches *P = x->P, *Q = y->P;
    size_t nq = 0, *qi = malloc(Q->n * sizeof *qi);
    double *d = malloc((P->n + 1) * sizeof *d);
    if (!qi || !d) {
        fprintf(stderr, "radray-seeds: out of memory\n");
        return 2;
    }
    for (size_t k = 0; k < Q->n; k++)
        if (Q->p[k].object == (uint32_t)obj)
            qi[nq++] = k;
    size_t n = 0, same = 0;
    for (size_t k = 0; k < P->n; k++) {
        if (P->p[k].object != (uint32_t)obj)
            continue;
        double bx = x->B[k].r + x->B[k].g + x->B[k].b;
        for (size_t j = 0; j < nq; j++) {
            size_t q = qi[j];
            if (!holds(Q, q, P->p[k].centroid))
                continue;
            double by = y->B[q].r + y->B[q].g + y->B[q].b;
            if (by > 0) {
                d[n++] = fabs(bx / by - 1.0);
                same += fabs(Q->p[q].area - P->p[k].area) <= 1e-9 * P->p[k].area;
            }
            break;
        }
    }
    if (n == 0) {
        fprintf(stderr, "radray-seeds: %s: no leaf of %s to compare\n", path, name);
        return 1;
    }
    qsort(d, n, sizeof *d, cmp_double);
    size_t within = 0;
    for (size_t i = 0; i < n; i++)
        within += d[i] <= 0.005;
    printf("%s, %s, seeds %llu and %llu: %zu leaves (%zu of the same size in both), |B_%llu / B_%llu - 1| median "
           "%.3f %%, p90 %.3f %%, p99 %.3f %%, max %.3f %%; within 0.5 %%: %.1f %% of the leaves\n",
           path, name, sa, sb, n, same, sa, sb, 100 * d[n / 2], 100 * d[(size_t)(0.9 * (double)(n - 1))],
           100 * d[(size_t)(0.99 * (double)(n - 1))], 100 * d[n - 1], 100.0 * (double)within / (double)n);
    /* The same on common cells (hierarchical solutions over the same roots):
     * a leaf that the other seed split further is compared with the mean of
     * the other's leaves inside it, so what differs is the seeds' noise, not
     * the difference between a large leaf's mean and a small one's over a
     * gradient (a penumbra) that the centroid lookup above also counts. */
    const rad_patches *R = P->roots, *S = Q->roots;
    if (R && S && R->n == S->n) {
        size_t nc = 0, cap = P->n + Q->n;
        double *dc = malloc(cap * sizeof *dc);
        if (!dc) {
            fprintf(stderr, "radray-seeds: out of memory\n");
            return 2;
        }
        for (size_t r = 0; r < R->n; r++)
            if (R->p[r].object == (uint32_t)obj)
                common_cells(x, y, P->root_qt[r], Q->root_qt[r], dc, &nc, cap);
        if (nc > 0) {
            char what[128];
            snprintf(what, sizeof what, "common cells (%zu): |mean_%llu / mean_%llu - 1|", nc, sa, sb);
            report(what, dc, nc);
        }
        free(dc);
    }
    free(d);
    free(qi);
    rad_solution_destroy(x);
    rad_solution_destroy(y);
    rt_accel_destroy(a1);
    rt_accel_destroy(a2);
    scene_destroy(s1);
    scene_destroy(s2);
    return 0;
}
