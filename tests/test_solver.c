/* test_solver.c - radiosity solvers (direct CHOLMOD, Gauss-Seidel) and the
 * energy ledger, on hand-built patch sets and form-factor matrices with known
 * answers: no geometry, no ray casting. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <signal.h>

#include <stdlib.h>
#include <string.h>

#include "rad.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

/* ---- hand-built systems ---- */

typedef struct sys {
    rad_patches P;
    rad_ff F;
} sys;

static sys *sys_new(size_t n)
{
    sys *S = calloc(1, sizeof *S);
    assert_non_null(S);
    S->P.n = n;
    S->P.p = calloc(n ? n : 1, sizeof *S->P.p);
    S->F.n = n;
    S->F.rowptr = calloc(n + 1, sizeof *S->F.rowptr);
    assert_non_null(S->P.p);
    assert_non_null(S->F.rowptr);
    for (size_t i = 0; i < n; i++) {
        S->P.p[i].area = 1.0;
        S->P.p[i].normal = rr_v3(0, 0, 1);
        S->P.p[i].tri = (int64_t)i;
    }
    return S;
}

static void sys_free(sys *S)
{
    free(S->P.p);
    free(S->F.rowptr);
    free(S->F.col);
    free(S->F.val);
    free(S);
}

/* F from a dense row-major n x n matrix (zeros not stored). */
static void sys_set_dense(sys *S, const double *f)
{
    size_t n = S->P.n, nz = 0;
    for (size_t k = 0; k < n * n; k++)
        nz += f[k] != 0.0;
    S->F.col = malloc((nz ? nz : 1) * sizeof *S->F.col);
    S->F.val = malloc((nz ? nz : 1) * sizeof *S->F.val);
    nz = 0;
    for (size_t i = 0; i < n; i++) {
        S->F.rowptr[i] = nz;
        for (size_t j = 0; j < n; j++)
            if (f[i * n + j] != 0.0) {
                S->F.col[nz] = (uint32_t)j;
                S->F.val[nz++] = f[i * n + j];
            }
    }
    S->F.rowptr[n] = nz;
}

/* A "well-mixed" enclosure: F_ij = A_j / A_total for every j (i included).
 * Rows sum to 1 (closed) and A_i F_ij = A_i A_j / A_total is reciprocal.
 * Then H = sum_j F_ij B_j is the same for every patch, and summing
 * A_i B_i = A_i E_i + rho_i A_i H gives H = Ebar / (1 - rhobar) with the
 * area-weighted means Ebar, rhobar: B_i = E_i + rho_i H, per channel. */
static sys *well_mixed(size_t n, rr_rng *rng)
{
    sys *S = sys_new(n);
    double total = 0.0;
    for (size_t i = 0; i < n; i++) {
        S->P.p[i].area = 0.5 + 2.0 * rr_rng_uniform(rng);
        S->P.p[i].object = (uint32_t)(i % 3);
        total += S->P.p[i].area;
    }
    double *f = malloc(n * n * sizeof *f);
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++)
            f[i * n + j] = S->P.p[j].area / total;
    sys_set_dense(S, f);
    free(f);
    return S;
}

static double chan(rr_rgb v, int c) { return c == 0 ? v.r : (c == 1 ? v.g : v.b); }
static double *chan_ptr(rr_rgb *v, int c) { return c == 0 ? &v->r : (c == 1 ? &v->g : &v->b); }

static rr_rgb well_mixed_answer(const sys *S, size_t i)
{
    double at = 0.0, e[3] = {0, 0, 0}, r[3] = {0, 0, 0};
    for (size_t j = 0; j < S->P.n; j++) {
        const rad_patch *p = &S->P.p[j];
        at += p->area;
        for (int c = 0; c < 3; c++) {
            e[c] += p->area * chan(p->emission, c);
            r[c] += p->area * chan(p->rho, c);
        }
    }
    double b[3];
    for (int c = 0; c < 3; c++)
        b[c] = chan(S->P.p[i].emission, c) + chan(S->P.p[i].rho, c) * (e[c] / at) / (1.0 - r[c] / at);
    return rr_rgb_make(b[0], b[1], b[2]);
}

/* A random sparse open system: symmetric weights W_ij on ~deg random
 * neighbours per patch, F_ij = s W_ij / A_i (reciprocal by construction),
 * scaled so that the largest row sum is 0.97. */
static sys *random_system(size_t n, int deg, uint64_t seed)
{
    rr_rng rng = rr_rng_make(seed, 1);
    sys *S = sys_new(n);
    size_t cap = n * (size_t)deg * 2 + n;
    uint32_t *ti = malloc(cap * sizeof *ti), *tj = malloc(cap * sizeof *tj);
    double *tw = malloc(cap * sizeof *tw);
    size_t nt = 0;
    for (size_t i = 0; i < n; i++) {
        rad_patch *p = &S->P.p[i];
        p->area = 0.2 + rr_rng_uniform(&rng);
        p->rho = rr_rgb_make(0.9 * rr_rng_uniform(&rng), 0.9 * rr_rng_uniform(&rng), 0.9 * rr_rng_uniform(&rng));
        if (rr_rng_uniform(&rng) < 0.1)
            p->emission = rr_rgb_make(rr_rng_uniform(&rng), 2.0 * rr_rng_uniform(&rng), 1.0);
        p->object = (uint32_t)(i % 4);
        for (int k = 0; k < deg / 2; k++) {
            uint32_t j = rr_rng_below(&rng, (uint32_t)n);
            if (j == i)
                continue;
            double w = rr_rng_uniform(&rng);
            ti[nt] = (uint32_t)i, tj[nt] = j, tw[nt++] = w;
            ti[nt] = j, tj[nt] = (uint32_t)i, tw[nt++] = w;
        }
    }
    S->P.p[0].emission = rr_rgb_make(1, 1, 1);
    /* CSR by counting; duplicates stay separate entries (allowed). */
    for (size_t k = 0; k < nt; k++)
        S->F.rowptr[ti[k] + 1]++;
    for (size_t i = 0; i < n; i++)
        S->F.rowptr[i + 1] += S->F.rowptr[i];
    S->F.col = malloc((nt ? nt : 1) * sizeof *S->F.col);
    S->F.val = malloc((nt ? nt : 1) * sizeof *S->F.val);
    size_t *fill = calloc(n, sizeof *fill);
    double *rowsum = calloc(n, sizeof *rowsum);
    for (size_t k = 0; k < nt; k++) {
        size_t at = S->F.rowptr[ti[k]] + fill[ti[k]]++;
        S->F.col[at] = tj[k];
        S->F.val[at] = tw[k] / S->P.p[ti[k]].area;
        rowsum[ti[k]] += S->F.val[at];
    }
    double mx = 0.0;
    for (size_t i = 0; i < n; i++)
        mx = fmax(mx, rowsum[i]);
    for (size_t k = 0; k < nt; k++)
        S->F.val[k] *= 0.97 / mx;
    free(fill);
    free(rowsum);
    free(ti);
    free(tj);
    free(tw);
    return S;
}

static rr_rgb *solve_ok(const sys *S, rad_solver solver, double tol, rad_solve_stats *st)
{
    rad_solve_opts o = {solver, tol, 0, 0, 0, NULL};
    rr_rgb *B = malloc(S->P.n * sizeof *B);
    rr_error err = {0};
    rad_solve_stats local;
    rr_status rc = rad_solve(&S->P, &S->F, &o, B, st ? st : &local, &err);
    if (rc != RR_OK)
        fail_msg("rad_solve: %s", err.msg);
    if (!st)
        free(local.history);
    return B;
}

static double max_rel_diff(const rr_rgb *a, const rr_rgb *b, size_t n)
{
    double d = 0.0, m = 0.0;
    for (size_t i = 0; i < n; i++) {
        d = fmax(d, fmax(fabs(a[i].r - b[i].r), fmax(fabs(a[i].g - b[i].g), fabs(a[i].b - b[i].b))));
        m = fmax(m, rr_rgb_max(a[i]));
    }
    return d / m;
}

static void assert_rgb_rel(rr_rgb a, rr_rgb b, double tol)
{
    double s = fmax(rr_rgb_max(b), 1e-300);
    assert_near(a.r / s, b.r / s, tol);
    assert_near(a.g / s, b.g / s, tol);
    assert_near(a.b / s, b.b / s, tol);
}

/* ---- solver tests ---- */

/* Uniform E and rho in a closed enclosure: B = E / (1 - rho), whatever F. */
static void white_furnace(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(7, 0);
    sys *S = well_mixed(40, &rng);
    rr_rgb rho[2] = {{0.8, 0.8, 0.8}, {0.3, 0.6, 0.95}}; /* grey (one factorisation) and coloured */
    for (int v = 0; v < 2; v++) {
        for (size_t i = 0; i < S->P.n; i++) {
            S->P.p[i].rho = rho[v];
            S->P.p[i].emission = rr_rgb_make(1.0, 2.0, 0.5);
        }
        rr_rgb want = rr_rgb_make(1.0 / (1 - rho[v].r), 2.0 / (1 - rho[v].g), 0.5 / (1 - rho[v].b));
        for (int solver = RAD_SOLVER_DIRECT; solver <= RAD_SOLVER_ITERATIVE; solver++) {
            rr_rgb *B = solve_ok(S, (rad_solver)solver, 0, NULL);
            for (size_t i = 0; i < S->P.n; i++)
                assert_rgb_rel(B[i], want, 1e-6);
            free(B);
        }
    }
    sys_free(S);
}

/* Non-uniform emission and reflectance (some black) in the well-mixed
 * enclosure: the closed form B_i = E_i + rho_i Ebar / (1 - rhobar). */
static void well_mixed_closed_form(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(11, 0);
    sys *S = well_mixed(60, &rng);
    for (size_t i = 0; i < S->P.n; i++) {
        rad_patch *p = &S->P.p[i];
        p->rho = rr_rgb_make(0.9 * rr_rng_uniform(&rng), 0.7, 0.5 * rr_rng_uniform(&rng));
        if (i % 7 == 0)
            p->emission = rr_rgb_make(3.0, 1.0, 2.0 * rr_rng_uniform(&rng));
        if (i % 5 == 1)
            p->rho.g = 0.0; /* black in G only: the channels differ in unknowns */
    }
    for (int solver = RAD_SOLVER_DIRECT; solver <= RAD_SOLVER_ITERATIVE; solver++) {
        rr_rgb *B = solve_ok(S, (rad_solver)solver, 1e-12, NULL);
        for (size_t i = 0; i < S->P.n; i++)
            assert_rgb_rel(B[i], well_mixed_answer(S, i), solver == RAD_SOLVER_DIRECT ? 1e-12 : 1e-9);
        free(B);
    }
    sys_free(S);
}

/* Two patches seeing each other (and the outside): by hand,
 * B1 = E1 + r1 F12 B2, B2 = E2 + r2 F21 B1, so
 * B1 = (E1 + r1 F12 E2) / (1 - r1 r2 F12 F21), B2 likewise. */
static void two_patches(void **state)
{
    (void)state;
    sys *S = sys_new(2);
    S->P.p[0].area = 2.0;
    S->P.p[1].area = 0.5;
    double F12 = 0.2, F21 = 2.0 * 0.2 / 0.5; /* reciprocity: A1 F12 = A2 F21 */
    double f[4] = {0, F12, F21, 0};
    sys_set_dense(S, f);
    S->P.p[0].rho = rr_rgb_make(0.5, 0.9, 0.0);
    S->P.p[1].rho = rr_rgb_make(0.7, 0.2, 0.6);
    S->P.p[0].emission = rr_rgb_make(1.0, 2.0, 3.0);
    S->P.p[1].emission = rr_rgb_make(0.0, 0.5, 0.0);
    rr_rgb want[2];
    for (int c = 0; c < 3; c++) {
        double r1 = chan(S->P.p[0].rho, c), r2 = chan(S->P.p[1].rho, c);
        double e1 = chan(S->P.p[0].emission, c), e2 = chan(S->P.p[1].emission, c);
        double den = 1.0 - r1 * r2 * F12 * F21;
        *chan_ptr(&want[0], c) = (e1 + r1 * F12 * e2) / den;
        *chan_ptr(&want[1], c) = (e2 + r2 * F21 * e1) / den;
    }
    for (int solver = RAD_SOLVER_DIRECT; solver <= RAD_SOLVER_ITERATIVE; solver++) {
        rr_rgb *B = solve_ok(S, (rad_solver)solver, 1e-13, NULL);
        assert_rgb_rel(B[0], want[0], 1e-12);
        assert_rgb_rel(B[1], want[1], 1e-12);
        free(B);
    }
    sys_free(S);
}

/* A wholly buried patch (area 0, no row, in no row: rad.h) keeps B = E in
 * both solvers and leaves the others as the two-patch closed form has them. */
static void buried_patch(void **state)
{
    (void)state;
    sys *S = sys_new(3);
    S->P.p[0].area = 2.0;
    S->P.p[1].area = 0.5;
    S->P.p[2].area = 0.0;
    double F12 = 0.2, F21 = 2.0 * 0.2 / 0.5;
    double f[9] = {0, F12, 0, F21, 0, 0, 0, 0, 0};
    sys_set_dense(S, f);
    for (int k = 0; k < 3; k++)
        S->P.p[k].rho = rr_rgb_make(0.5, 0.7, 0.3);
    S->P.p[0].emission = rr_rgb_make(1.0, 2.0, 3.0);
    S->P.p[2].emission = rr_rgb_make(0.25, 0.5, 0.75);
    for (int solver = RAD_SOLVER_DIRECT; solver <= RAD_SOLVER_ITERATIVE; solver++) {
        rr_rgb *B = solve_ok(S, (rad_solver)solver, 1e-13, NULL);
        for (int c = 0; c < 3; c++) {
            double r = chan(S->P.p[0].rho, c), e1 = chan(S->P.p[0].emission, c);
            double den = 1.0 - r * r * F12 * F21;
            assert_true(fabs(chan(B[0], c) - e1 / den) < 1e-12 * e1 / den);
            assert_true(fabs(chan(B[1], c) - r * F21 * e1 / den) < 1e-12 * e1 / den);
            assert_true(chan(B[2], c) == chan(S->P.p[2].emission, c));
        }
        free(B);
    }
    sys_free(S);
}

/* Patches black in some channels are eliminated from the direct system:
 * they must keep B = E and the rest must match Gauss-Seidel. */
static void black_patches_eliminated(void **state)
{
    (void)state;
    sys *S = random_system(300, 40, 3);
    for (size_t i = 0; i < S->P.n; i++) {
        if (i % 3 == 0)
            S->P.p[i].rho.r = 0.0;
        if (i % 4 == 0)
            S->P.p[i].rho = rr_rgb_make(0, 0, 0);
        if (i % 8 == 0)
            S->P.p[i].emission = rr_rgb_make(0.5, 0.25, 1.0);
    }
    rr_rgb *Bd = solve_ok(S, RAD_SOLVER_DIRECT, 0, NULL);
    rr_rgb *Bi = solve_ok(S, RAD_SOLVER_ITERATIVE, 1e-12, NULL);
    assert_true(max_rel_diff(Bd, Bi, S->P.n) < 1e-9);
    for (size_t i = 0; i < S->P.n; i += 4) {
        assert_true(Bd[i].r == S->P.p[i].emission.r);
        assert_true(Bd[i].b == S->P.p[i].emission.b);
    }
    free(Bd);
    free(Bi);
    sys_free(S);
}

/* Direct and iterative agree on a random reciprocal system; both report
 * tiny residuals. */
static void direct_matches_iterative(void **state)
{
    (void)state;
    sys *S = random_system(500, 60, 5);
    rad_solve_stats sd, si;
    rr_rgb *Bd = solve_ok(S, RAD_SOLVER_DIRECT, 0, &sd);
    rr_rgb *Bi = solve_ok(S, RAD_SOLVER_ITERATIVE, 0, &si);
    assert_int_equal(sd.used, RAD_SOLVER_DIRECT);
    assert_int_equal(si.used, RAD_SOLVER_ITERATIVE);
    assert_true(max_rel_diff(Bd, Bi, S->P.n) < 1e-6);
    assert_true(sd.residual < 1e-12);
    assert_true(si.residual < 1e-9);
    assert_null(sd.history);
    assert_true(si.nhistory == si.iterations && si.iterations > 1);
    assert_true(sd.seconds >= 0.0 && si.seconds >= 0.0);
    free(si.history);
    free(Bd);
    free(Bi);
    sys_free(S);
}

/* Auto: direct when small, iterative above auto_direct_max; the residual
 * history falls monotonically to below the tolerance. */
static void auto_choice_and_history(void **state)
{
    (void)state;
    sys *S = random_system(200, 30, 9);
    rr_rgb *B = malloc(S->P.n * sizeof *B);
    rad_solve_stats st;
    rr_error err;
    rad_solve_opts o = {RAD_SOLVER_AUTO, 0, 0, 0, 0, NULL};
    assert_int_equal(rad_solve(&S->P, &S->F, &o, B, &st, &err), RR_OK);
    assert_int_equal(st.used, RAD_SOLVER_DIRECT);
    free(st.history);
    o.auto_direct_max = 100;
    o.tolerance = 1e-11;
    assert_int_equal(rad_solve(&S->P, &S->F, &o, B, &st, &err), RR_OK);
    assert_int_equal(st.used, RAD_SOLVER_ITERATIVE);
    assert_int_equal(st.nhistory, st.iterations);
    for (int k = 1; k < st.nhistory; k++)
        assert_true(st.history[k] < st.history[k - 1]);
    assert_true(st.history[st.nhistory - 1] < 1e-11);
    assert_true(st.history[st.nhistory - 2] >= 1e-11);
    assert_true(st.residual == st.history[st.nhistory - 1]);
    free(st.history);
    /* Without opts and stats: defaults, nothing leaks. */
    assert_int_equal(rad_solve(&S->P, &S->F, NULL, B, NULL, &err), RR_OK);
    free(B);
    sys_free(S);
}

static int contains(const char *s, const char *what) { return strstr(s, what) != NULL; }

/* Expects failure with code and a message containing what; B and stats stay untouched. */
static void expect_fail(const sys *S, const rad_solve_opts *o, rr_status code, const char *what)
{
    rr_rgb B[4] = {{-7, -7, -7}, {-7, -7, -7}, {-7, -7, -7}, {-7, -7, -7}};
    rad_solve_stats st;
    memset(&st, 0x5a, sizeof st);
    rad_solve_stats before = st;
    rr_error err = {0};
    assert_true(S->P.n <= 4);
    assert_int_equal(rad_solve(&S->P, &S->F, o, B, &st, &err), code);
    if (!contains(err.msg, what))
        fail_msg("message \"%s\" lacks \"%s\"", err.msg, what);
    assert_true(B[0].r == -7 && B[3].b == -7);
    assert_memory_equal(&st, &before, sizeof st);
}

static void bad_inputs(void **state)
{
    (void)state;
    sys *S = sys_new(2);
    double f[4] = {0, 0.5, 0.5, 0};
    sys_set_dense(S, f);
    S->P.p[0].emission = rr_rgb_make(1, 1, 1);
    S->P.p[0].rho = rr_rgb_make(0.5, 0.5, 0.5);
    S->P.p[1].rho = rr_rgb_make(0.5, 1.0, 0.5);
    S->P.p[1].object = 3;
    rad_solve_opts o = {RAD_SOLVER_AUTO, 0, 0, 0, 0, NULL};
    expect_fail(S, &o, RR_ERR_INVALID, "patch 1 (object 3) has reflectance >= 1 in channel G");
    expect_fail(S, &o, RR_ERR_INVALID, "no physical solution");

    /* Reflectance 1 allowed (tests only): this open pair still has the
     * solution B1 = E / (1 - 1/4), B2 = B1 / 2, with both solvers. */
    o.allow_rho_ge_1 = 1;
    S->P.p[0].rho = S->P.p[1].rho = rr_rgb_make(1, 1, 1);
    for (int solver = RAD_SOLVER_DIRECT; solver <= RAD_SOLVER_ITERATIVE; solver++) {
        o.solver = (rad_solver)solver;
        rr_rgb B[2];
        rad_solve_stats st;
        rr_error err;
        assert_int_equal(rad_solve(&S->P, &S->F, &o, B, &st, &err), RR_OK);
        assert_near(B[0].g, 4.0 / 3.0, 1e-8);
        assert_near(B[1].g, 2.0 / 3.0, 1e-8);
        free(st.history);
    }
    /* Reflectance 2 with F = 0.9 both ways: the matrix is indefinite, CHOLMOD
     * says so, and Gauss-Seidel diverges. */
    S->P.p[0].rho = S->P.p[1].rho = rr_rgb_make(2, 2, 2);
    S->F.val[0] = S->F.val[1] = 0.9;
    o.solver = RAD_SOLVER_DIRECT;
    expect_fail(S, &o, RR_ERR_INVALID, "not positive definite");
    o.solver = RAD_SOLVER_ITERATIVE;
    expect_fail(S, &o, RR_ERR_INVALID, "diverged");
    /* Reflectance 1 in a closed pair: B grows without bound, never converges. */
    S->P.p[0].rho = S->P.p[1].rho = rr_rgb_make(1, 1, 1);
    S->F.val[0] = S->F.val[1] = 1.0;
    o.max_iterations = 50;
    expect_fail(S, &o, RR_ERR_LIMIT, "did not converge in 50 sweeps");
    o = (rad_solve_opts){RAD_SOLVER_AUTO, 0, 0, 0, 0, NULL};
    S->P.p[0].rho = S->P.p[1].rho = rr_rgb_make(0.5, 0.5, 0.5);
    S->F.val[0] = S->F.val[1] = 0.5;
    /* Interrupted (Ctrl-C): the iterative solver stops before its next sweep. */
    volatile sig_atomic_t stop = 1;
    o.solver = RAD_SOLVER_ITERATIVE;
    o.interrupt = &stop;
    expect_fail(S, &o, RR_ERR_INTERRUPTED, "interrupted in the solve, after 0 sweeps");
    stop = 0;
    {
        rr_rgb B[2];
        rad_solve_stats st;
        assert_int_equal(rad_solve(&S->P, &S->F, &o, B, &st, NULL), RR_OK);
        free(st.history);
    }
    o = (rad_solve_opts){RAD_SOLVER_AUTO, 0, 0, 0, 0, NULL};

    /* No emitter. */
    S->P.p[0].emission = rr_rgb_make(0, 0, 0);
    expect_fail(S, &o, RR_ERR_INVALID, "no patch emits light");
    S->P.p[0].emission = rr_rgb_make(0, 0, 1);
    /* Malformed numbers. */
    S->F.val[1] = NAN;
    expect_fail(S, &o, RR_ERR_INVALID, "F[1][0]");
    S->F.val[1] = -0.1;
    expect_fail(S, &o, RR_ERR_INVALID, "not a finite non-negative");
    S->F.val[1] = 0.5;
    S->F.col[1] = 2;
    expect_fail(S, &o, RR_ERR_INVALID, "names patch 2");
    S->F.col[1] = 0;
    S->P.p[1].rho.b = -0.5;
    expect_fail(S, &o, RR_ERR_INVALID, "negative or non-finite reflectance");
    S->P.p[1].rho.b = 0.5;
    S->P.p[1].emission.r = NAN;
    expect_fail(S, &o, RR_ERR_INVALID, "emission");
    S->P.p[1].emission.r = 0.0;
    S->P.p[0].area = -1.0;
    expect_fail(S, &o, RR_ERR_INVALID, "area -1");
    S->P.p[0].area = NAN;
    expect_fail(S, &o, RR_ERR_INVALID, "area nan");
    S->P.p[0].area = 1.0;
    o.solver = (rad_solver)7;
    expect_fail(S, &o, RR_ERR_INVALID, "unknown solver");
    o.solver = RAD_SOLVER_AUTO;
    S->F.n = 3;
    expect_fail(S, &o, RR_ERR_INVALID, "for 3 patches, but there are 2");
    S->F.n = 2;
    /* Still fine after all that. */
    rr_rgb B[2];
    assert_int_equal(rad_solve(&S->P, &S->F, &o, B, NULL, NULL), RR_OK);
    assert_near(B[0].b, 1.0 / (1.0 - 0.0625), 1e-12);
    sys_free(S);

    /* No patches at all. */
    sys *Z = sys_new(0);
    expect_fail(Z, &o, RR_ERR_INVALID, "no patches");
    sys_free(Z);
}

/* ---- energy ledger ---- */

static void check_ledger(const scene *s, const sys *S, const rr_rgb *B, double tol, rad_energy_row **out, size_t *nout)
{
    rad_energy_row *rows = NULL;
    size_t n = 0;
    rr_error err;
    if (rad_energy(s, &S->P, &S->F, B, &rows, &n, &err) != RR_OK)
        fail_msg("rad_energy: %s", err.msg);
    const rad_energy_row *t = &rows[n - 1];
    assert_string_equal(t->name, "total");
    rad_energy_row sum = {0};
    for (size_t k = 0; k + 1 < n; k++) {
        sum.area += rows[k].area;
        for (int c = 0; c < 3; c++) {
            double e = chan(rows[k].emitted, c), a = chan(rows[k].absorbed, c), in = chan(rows[k].incident, c);
            assert_near(chan(rows[k].reflected, c) + a, in, 1e-12 * fmax(in, 1));
            *chan_ptr(&sum.emitted, c) += e;
            *chan_ptr(&sum.absorbed, c) += a;
            *chan_ptr(&sum.escaped, c) += chan(rows[k].escaped, c);
        }
    }
    assert_near(sum.area, t->area, 1e-12 * t->area);
    for (int c = 0; c < 3; c++) {
        double e = chan(t->emitted, c), a = chan(t->absorbed, c), x = chan(t->escaped, c);
        assert_near(chan(sum.emitted, c), e, 1e-12 * e);
        assert_near(chan(sum.absorbed, c), a, 1e-12 * e);
        assert_near(chan(sum.escaped, c), x, 1e-12 * e);
        if (fabs(e - a - x) > tol * e)
            fail_msg("channel %d: emitted %.17g != absorbed %.17g + escaped %.17g", c, e, a, x);
    }
    *out = rows;
    *nout = n;
}

/* Closed enclosure: nothing escapes, all emitted power is absorbed. Rows carry
 * the scene's object names. */
static void energy_closed(void **state)
{
    (void)state;
    rr_rng rng = rr_rng_make(13, 0);
    sys *S = well_mixed(30, &rng);
    for (size_t i = 0; i < S->P.n; i++) {
        S->P.p[i].rho = rr_rgb_make(0.5, 0.8, 0.3);
        S->P.p[i].object = i < 10 ? 0 : 2; /* object 1 has no patches: no row */
    }
    S->P.p[3].emission = rr_rgb_make(5, 5, 5);
    scene_object objs[3];
    memset(objs, 0, sizeof objs);
    strcpy(objs[0].name, "walls");
    strcpy(objs[1].name, "ghost");
    strcpy(objs[2].name, "floor");
    scene s;
    memset(&s, 0, sizeof s);
    s.objects = objs;
    s.nobjects = 3;
    rr_rgb *B = solve_ok(S, RAD_SOLVER_DIRECT, 0, NULL);
    rad_energy_row *rows;
    size_t n;
    check_ledger(&s, S, B, 1e-9, &rows, &n);
    assert_int_equal(n, 3);
    assert_string_equal(rows[0].name, "walls");
    assert_string_equal(rows[1].name, "floor");
    assert_near(rows[0].emitted.r, 5.0 * S->P.p[3].area, 1e-12);
    assert_near(rows[1].emitted.r, 0.0, 0.0);
    for (int c = 0; c < 3; c++)
        assert_true(fabs(chan(rows[2].escaped, c)) < 1e-12 * chan(rows[2].emitted, c));
    free(rows);
    /* Gauss-Seidel to 1e-12 balances to about that too. */
    free(B);
    B = solve_ok(S, RAD_SOLVER_ITERATIVE, 1e-12, NULL);
    check_ledger(&s, S, B, 1e-9, &rows, &n);
    free(rows);
    /* A patch naming an object the scene lacks is an error. */
    S->P.p[0].object = 5;
    rr_error err;
    assert_int_equal(rad_energy(&s, &S->P, &S->F, B, &rows, &n, &err), RR_ERR_INVALID);
    assert_true(contains(err.msg, "object 5"));
    free(B);
    sys_free(S);
}

/* Open systems: the hand-solved pair, then a random one. */
static void energy_open(void **state)
{
    (void)state;
    sys *S = sys_new(2);
    double f[4] = {0, 0.25, 0.25, 0};
    sys_set_dense(S, f);
    S->P.p[0].emission = rr_rgb_make(1, 1, 1);
    S->P.p[0].rho = S->P.p[1].rho = rr_rgb_make(0.5, 0.5, 0.5);
    S->P.p[1].object = 1;
    /* B2 = 0.125 B1, B1 = 1 + 0.125 B2: B1 = 64/63, B2 = 8/63. */
    rr_rgb *B = solve_ok(S, RAD_SOLVER_DIRECT, 0, NULL);
    assert_near(B[0].r, 64.0 / 63.0, 1e-14);
    assert_near(B[1].r, 8.0 / 63.0, 1e-14);
    rad_energy_row *rows;
    size_t n;
    check_ledger(NULL, S, B, 1e-12, &rows, &n);
    assert_int_equal(n, 3);
    assert_string_equal(rows[0].name, "objects[0]");
    assert_string_equal(rows[1].name, "objects[1]");
    assert_near(rows[0].incident.g, 0.25 * 8.0 / 63.0, 1e-14);
    assert_near(rows[1].incident.g, 0.25 * 64.0 / 63.0, 1e-14);
    assert_near(rows[1].absorbed.g, 0.125 * 64.0 / 63.0, 1e-14);
    assert_near(rows[0].escaped.b, 0.75 * 64.0 / 63.0, 1e-14);
    assert_near(rows[1].escaped.b, 0.75 * 8.0 / 63.0, 1e-14);
    free(rows);
    free(B);
    sys_free(S);

    S = random_system(400, 50, 21);
    B = solve_ok(S, RAD_SOLVER_DIRECT, 0, NULL);
    check_ledger(NULL, S, B, 1e-9, &rows, &n);
    assert_int_equal(n, 5);
    assert_true(rows[4].escaped.g > 0.01 * rows[4].emitted.g); /* really open */
    free(rows);
    free(B);
    sys_free(S);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(white_furnace),         cmocka_unit_test(well_mixed_closed_form),
        cmocka_unit_test(two_patches),           cmocka_unit_test(buried_patch),
        cmocka_unit_test(black_patches_eliminated),
        cmocka_unit_test(direct_matches_iterative), cmocka_unit_test(auto_choice_and_history),
        cmocka_unit_test(bad_inputs),            cmocka_unit_test(energy_closed),
        cmocka_unit_test(energy_open),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
