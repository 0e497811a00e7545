/* rad_solve.c - the radiosity system B = E + rho F B, per patch and channel.
 *
 * Two solvers:
 *
 * Direct (CHOLMOD). Multiplying patch i's equation by A_i / rho_i gives
 *     (A_i / rho_i) B_i - sum_j A_i F_ij B_j = (A_i / rho_i) E_i,
 * whose matrix M = diag(A / rho) - G, G_ij = A_i F_ij, is symmetric when F is
 * reciprocal (A_i F_ij = A_j F_ji). We use G := (G + G^T) / 2 so that the
 * small non-reciprocity of Monte Carlo estimates cannot break the symmetry
 * CHOLMOD needs (rad_ff makes F reciprocal by default, and then this changes
 * nothing). M is positive definite: it is symmetric with a positive diagonal
 * and strictly diagonally dominant, since sum_j G_ij = A_i sum_j F_ij <= A_i
 * < A_i / rho_i. Patches with rho_i = 0 in a channel would have an infinite
 * diagonal, and patches of area 0 (wholly buried, rad.h) a zero row: there
 * B_i = E_i is known, so they are eliminated and their terms
 * G_ij E_j move to the right-hand side of the others. The pattern of M depends
 * only on which patches are unknown, so it is analysed (ordering + symbolic
 * factorisation) once per distinct unknown set, usually once for all three
 * channels; channels with identical reflectances (grey materials) share one
 * numeric factorisation and are solved as columns of one right-hand side.
 *
 * Iterative (Gauss-Seidel on B = E + K B with K = diag(rho) F, all channels
 * at once, from B = E). It converges because I - K is strictly diagonally
 * dominant by rows: sum_j K_ij = rho_i sum_j F_ij <= rho_i < 1, F's rows
 * summing to at most 1 (the fraction of what leaves patch i that lands
 * anywhere). For such matrices each Gauss-Seidel sweep contracts the error by
 * at least max_i rho_i sum_j F_ij in the max norm. Since K >= 0 and the start
 * E lies below the solution (the Neumann series B = sum_k K^k E), the iterates
 * rise monotonically towards it. A reflectance >= 1 (allowed for tests only)
 * voids that argument: then the sweep limit or the divergence check stops it.
 *
 * Residual, both solvers: max over patches and channels of
 * |E_i + rho_i (F B)_i - B_i|, divided by the largest radiosity.
 */
#include <float.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <cholmod.h>

#include "rad_solve_internal.h"

#define RAD_DEFAULT_MAX_ITERATIONS 10000
/* Auto switches to Gauss-Seidel above this many patches. Form factors from
 * rays connect each patch to ~100-1000 others scattered over the scene, a
 * graph with no small separators, so the Cholesky factor fills in to nearly
 * dense: n^2/2 entries and n^3/3 flops per distinct channel. Measured on
 * random reciprocal closed systems with 200 entries per row, rho in
 * [0.3, 0.8] and three different channels (2 cores, reference BLAS): direct
 * 0.18 s at 1k patches, 1.2 s at 2k, 19 s at 4k, 431 s at 16k with grey
 * reflectances (one factorisation; ~20 min coloured); Gauss-Seidel to 1e-9
 * took 17 sweeps and 0.003, 0.007, 0.016 and 0.10 s. Up to 2000 patches the
 * factor is ~30 MB and the exact answer costs about a second; beyond that the
 * direct solver only loses. */
#define RAD_DEFAULT_AUTO_DIRECT_MAX 2000

static int rgb_nonneg_finite(rr_rgb v) { return rr_rgb_isfinite(v) && v.r >= 0.0 && v.g >= 0.0 && v.b >= 0.0; }

rr_status rad_system_check(const rad_patches *P, const rad_ff *F, rr_error *err)
{
    if (!P || !F)
        return rr_error_set(err, RR_ERR_INVALID, "missing patches or form factors");
    if (P->n == 0)
        return rr_error_set(err, RR_ERR_INVALID, "there are no patches: the scene has no surface to light");
    if (F->n != P->n)
        return rr_error_set(err, RR_ERR_INVALID, "the form factors are for %zu patches, but there are %zu",
                            F->n, P->n);
    if (!F->rowptr || F->rowptr[0] != 0)
        return rr_error_set(err, RR_ERR_INVALID, "form factor rows do not start at 0");
    for (size_t i = 0; i < P->n; i++) {
        const rad_patch *p = &P->p[i];
        /* 0 is a patch wholly buried under another surface (rad.h): it
         * neither gathers nor sends, B = E. */
        if (!isfinite(p->area) || p->area < 0.0)
            return rr_error_set(err, RR_ERR_INVALID, "patch %zu (object %u) has area %g, expected >= 0", i,
                                (unsigned)p->object, p->area);
        if (!rgb_nonneg_finite(p->emission))
            return rr_error_set(err, RR_ERR_INVALID,
                                "patch %zu (object %u) has a negative or non-finite emission (%g, %g, %g)",
                                i, (unsigned)p->object, p->emission.r, p->emission.g, p->emission.b);
        if (!rgb_nonneg_finite(p->rho))
            return rr_error_set(err, RR_ERR_INVALID,
                                "patch %zu (object %u) has a negative or non-finite reflectance (%g, %g, %g)",
                                i, (unsigned)p->object, p->rho.r, p->rho.g, p->rho.b);
        if (F->rowptr[i + 1] < F->rowptr[i])
            return rr_error_set(err, RR_ERR_INVALID, "form factor row %zu has a negative length", i);
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
            if (F->col[k] >= P->n)
                return rr_error_set(err, RR_ERR_INVALID,
                                    "form factor row %zu names patch %u, but there are %zu", i,
                                    (unsigned)F->col[k], P->n);
            if (!isfinite(F->val[k]) || F->val[k] < 0.0)
                return rr_error_set(err, RR_ERR_INVALID,
                                    "form factor F[%zu][%u] = %g is not a finite non-negative number", i,
                                    (unsigned)F->col[k], F->val[k]);
        }
    }
    return RR_OK;
}

rr_status rad_reflectance_check(const rad_patches *P, int allow_rho_ge_1, rr_error *err)
{
    for (size_t i = 0; i < P->n && !allow_rho_ge_1; i++) {
        const rad_patch *p = &P->p[i];
        for (int c = 0; c < 3; c++) {
            double rho = rad_rgb_get(p->rho, c);
            if (rho >= 1.0)
                return rr_error_set(err, RR_ERR_INVALID,
                                    "patch %zu (object %u) has reflectance >= 1 in channel %c (%.4g): the "
                                    "radiosity system has no physical solution (a surface cannot reflect more than "
                                    "it receives)",
                                    i, (unsigned)p->object, rad_channel_name(c), rho);
        }
    }
    return RR_OK;
}

/* The physical conditions for a unique non-negative solution. */
static rr_status check_physics(const rad_patches *P, int allow_rho_ge_1, rr_error *err)
{
    rr_status st = rad_reflectance_check(P, allow_rho_ge_1, err);
    if (st != RR_OK)
        return st;
    int emits = 0;
    for (size_t i = 0; i < P->n; i++)
        if (rr_rgb_max(P->p[i].emission) > 0.0)
            emits = 1;
    if (!emits)
        return rr_error_set(err, RR_ERR_INVALID,
                            "no patch emits light and no point or directional light reaches a patch's front: "
                            "give a material a non-zero \"emission\", or aim a light at the front faces");
    return RR_OK;
}

/* Max relative residual (see the top comment); +inf if anything is not finite. */
static double residual(const rad_patches *P, const rad_ff *F, const rr_rgb *X)
{
    double rmax = 0.0, bmax = 0.0;
    int bad = 0;
    const long n = (long)P->n;
#pragma omp parallel for schedule(static) reduction(max : rmax, bmax) reduction(| : bad)
    for (long i = 0; i < n; i++) {
        rr_rgb s = {0, 0, 0};
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++)
            s = rr_rgb_add(s, rr_rgb_scale(X[F->col[k]], F->val[k]));
        const rad_patch *p = &P->p[i];
        rr_rgb r = rr_rgb_add(p->emission, rr_rgb_mul(p->rho, s));
        double d = fmax(fabs(r.r - X[i].r), fmax(fabs(r.g - X[i].g), fabs(r.b - X[i].b)));
        if (!isfinite(d) || !rr_rgb_isfinite(X[i]))
            bad = 1;
        else {
            rmax = fmax(rmax, d);
            bmax = fmax(bmax, rr_rgb_max(X[i]));
        }
    }
    return bad ? INFINITY : rmax / fmax(bmax, DBL_MIN);
}

/* One Gauss-Seidel sweep. A self form factor F_ii (non-planar patches) is
 * solved for exactly: B_i (1 - rho_i F_ii) = E_i + rho_i sum_{j != i} F_ij B_j. */
static void gs_sweep(const rad_patches *P, const rad_ff *F, rr_rgb *X)
{
    for (size_t i = 0; i < P->n; i++) {
        double s[3] = {0, 0, 0}, fii = 0.0;
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
            uint32_t j = F->col[k];
            double f = F->val[k];
            if (j == i) {
                fii += f;
                continue;
            }
            s[0] += f * X[j].r;
            s[1] += f * X[j].g;
            s[2] += f * X[j].b;
        }
        const rad_patch *p = &P->p[i];
        double out[3];
        for (int c = 0; c < 3; c++) {
            double rho = rad_rgb_get(p->rho, c), e = rad_rgb_get(p->emission, c);
            double den = 1.0 - rho * fii;
            /* den <= 0 only with reflectance >= 1 (tests): plain update then. */
            out[c] = den > 0.0 ? (e + rho * s[c]) / den : e + rho * (s[c] + fii * rad_rgb_get(X[i], c));
        }
        X[i] = rr_rgb_make(out[0], out[1], out[2]);
    }
}

static rr_status solve_iterative(const rad_patches *P, const rad_ff *F, double tol, int maxit,
                                 const volatile sig_atomic_t *interrupt, rr_rgb *X, rad_solve_stats *st, rr_error *err)
{
    for (size_t i = 0; i < P->n; i++)
        X[i] = P->p[i].emission;
    int cap = 64;
    st->history = malloc((size_t)cap * sizeof *st->history);
    if (!st->history)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the residual history");
    double r = INFINITY;
    for (int it = 1; it <= maxit; it++) {
        if (interrupt && *interrupt)
            return rr_error_set(err, RR_ERR_INTERRUPTED, "interrupted in the solve, after %d sweeps",
                                it - 1);
        gs_sweep(P, F, X);
        r = residual(P, F, X);
        if (st->nhistory == cap) {
            double *h = realloc(st->history, 2 * (size_t)cap * sizeof *h);
            if (!h)
                return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the residual history");
            st->history = h;
            cap *= 2;
        }
        st->history[st->nhistory++] = r;
        st->iterations = it;
        st->residual = r;
        if (!isfinite(r) || r > 1e100)
            return rr_error_set(err, RR_ERR_INVALID,
                                "Gauss-Seidel diverged after %d sweeps (residual %g): some reflectance "
                                "times its form-factor row sum reaches 1",
                                it, r);
        if (r < tol)
            return RR_OK;
    }
    return rr_error_set(err, RR_ERR_LIMIT,
                        "Gauss-Seidel did not converge in %d sweeps (residual %.3g, tolerance %.3g): "
                        "raise max_iterations or the tolerance",
                        maxit, r, tol);
}

/* ---- direct solver ---- */

static rr_status chol_fail(const cholmod_common *c, const char *what, rr_error *err)
{
    if (c->status == CHOLMOD_OUT_OF_MEMORY)
        return rr_error_set(err, RR_ERR_NOMEM,
                            "out of memory in the direct solver (%s): use the iterative solver", what);
    if (c->status == CHOLMOD_TOO_LARGE)
        return rr_error_set(err, RR_ERR_LIMIT, "the system is too large for the direct solver (%s)", what);
    return rr_error_set(err, RR_ERR_INTERNAL, "CHOLMOD failed in %s (status %d)", what, c->status);
}

static int same_unknowns(const rad_patches *P, int a, int b)
{
    for (size_t i = 0; i < P->n; i++)
        if ((rad_rgb_get(P->p[i].rho, a) > 0.0) != (rad_rgb_get(P->p[i].rho, b) > 0.0))
            return 0;
    return 1;
}

static int same_rho(const rad_patches *P, int a, int b)
{
    for (size_t i = 0; i < P->n; i++)
        if (rad_rgb_get(P->p[i].rho, a) != rad_rgb_get(P->p[i].rho, b))
            return 0;
    return 1;
}

static void rgb_set(rr_rgb *v, int c, double x)
{
    if (c == 0)
        v->r = x;
    else if (c == 1)
        v->g = x;
    else
        v->b = x;
}

/* Memory the factor may take: half the physical memory (as for images). */
static double memory_budget(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? 0.5 * (double)pages * (double)size : 8e9;
}

/* Shared state of one direct solve. */
typedef struct direct {
    const rad_patches *P;
    const rad_ff *F;
    cholmod_common *cc;
    SuiteSparse_long *loc; /* n: row of patch i in M, or -1 if eliminated */
    size_t *glob;          /* m: patch of row l */
    double *fii;           /* n: self form factor */
    size_t m;
} direct;

/* Factorises M for channel ch (with the pattern in A, analysis in L) and solves
 * the channels cols[0..ncols) that share its reflectances. */
static rr_status direct_channels(direct *d, cholmod_sparse *A, cholmod_factor *L, const SuiteSparse_long *dpos,
                                 const int *cols, int ncols, rr_rgb *X, rr_error *err)
{
    const rad_patches *P = d->P;
    const rad_ff *F = d->F;
    int ch = cols[0];
    double *Ax = A->x;
    for (size_t l = 0; l < d->m; l++) {
        const rad_patch *p = &P->p[d->glob[l]];
        Ax[dpos[l]] = p->area / rad_rgb_get(p->rho, ch) - p->area * d->fii[d->glob[l]];
    }
    if (!cholmod_l_factorize(A, L, d->cc))
        return chol_fail(d->cc, "factorize", err);
    if (d->cc->status == CHOLMOD_NOT_POSDEF || L->minor < d->m) {
        const SuiteSparse_long *perm = L->Perm;
        size_t bad = L->minor < d->m ? d->glob[perm ? (size_t)perm[L->minor] : L->minor] : 0;
        return rr_error_set(err, RR_ERR_INVALID,
                            "the system is not positive definite (channel %c, near patch %zu, object %u): "
                            "a reflectance times its form-factor row sum reaches 1, or the form factors are far "
                            "from reciprocal",
                            rad_channel_name(ch), bad, (unsigned)P->p[bad].object);
    }
    cholmod_dense *R = cholmod_l_zeros(d->m, (size_t)ncols, CHOLMOD_REAL, d->cc);
    if (!R)
        return chol_fail(d->cc, "right-hand side", err);
    double *Rx = R->x;
    for (int t = 0; t < ncols; t++) {
        double *col = Rx + (size_t)t * R->d;
        for (size_t l = 0; l < d->m; l++) {
            const rad_patch *p = &P->p[d->glob[l]];
            col[l] = p->area / rad_rgb_get(p->rho, ch) * rad_rgb_get(p->emission, cols[t]);
        }
        /* Known radiosities of eliminated patches: each stored F_ij is half of
         * the symmetrised G_ij and half of G_ji. */
        for (size_t i = 0; i < P->n; i++) {
            SuiteSparse_long li = d->loc[i];
            for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
                SuiteSparse_long lj = d->loc[F->col[k]];
                double g = 0.5 * P->p[i].area * F->val[k];
                if (li >= 0 && lj < 0)
                    col[li] += g * rad_rgb_get(P->p[F->col[k]].emission, cols[t]);
                else if (li < 0 && lj >= 0)
                    col[lj] += g * rad_rgb_get(P->p[i].emission, cols[t]);
            }
        }
    }
    cholmod_dense *S = cholmod_l_solve(CHOLMOD_A, L, R, d->cc);
    cholmod_l_free_dense(&R, d->cc);
    if (!S)
        return chol_fail(d->cc, "solve", err);
    const double *Sx = S->x;
    for (int t = 0; t < ncols; t++)
        for (size_t l = 0; l < d->m; l++)
            rgb_set(&X[d->glob[l]], cols[t], Sx[l + (size_t)t * S->d]);
    cholmod_l_free_dense(&S, d->cc);
    return RR_OK;
}

/* Solves the channels chans[0..nch) that share one set of unknowns (patches
 * with rho > 0): builds M's pattern once, analyses it once. */
static rr_status direct_unknown_set(direct *d, const int *chans, int nch, rr_rgb *X, rr_error *err)
{
    const rad_patches *P = d->P;
    const rad_ff *F = d->F;
    d->m = 0;
    for (size_t i = 0; i < P->n; i++) {
        if (rad_rgb_get(P->p[i].rho, chans[0]) > 0.0 && P->p[i].area > 0.0) {
            d->glob[d->m] = i;
            d->loc[i] = (SuiteSparse_long)d->m++;
        } else {
            d->loc[i] = -1;
        }
    }
    if (d->m == 0)
        return RR_OK; /* every patch black in these channels: B = E */

    size_t nz = d->m;
    for (size_t i = 0; i < P->n; i++)
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++)
            nz += d->loc[i] >= 0 && d->loc[F->col[k]] >= 0 && F->col[k] != i;
    /* Upper-triangular triplets (stype 1): CHOLMOD transposes lower entries
     * into the upper part and sums duplicates, so adding -A_i F_ij / 2 at
     * (i, j) for every stored entry builds -(G + G^T) / 2 directly. */
    cholmod_triplet *T = cholmod_l_allocate_triplet(d->m, d->m, nz, 1, CHOLMOD_REAL, d->cc);
    if (!T)
        return chol_fail(d->cc, "allocate", err);
    SuiteSparse_long *Ti = T->i, *Tj = T->j;
    double *Tx = T->x;
    size_t t = 0;
    for (size_t l = 0; l < d->m; l++) {
        Ti[t] = Tj[t] = (SuiteSparse_long)l;
        Tx[t++] = 1.0; /* the diagonal, set per channel */
    }
    for (size_t i = 0; i < P->n; i++) {
        SuiteSparse_long li = d->loc[i];
        if (li < 0)
            continue;
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
            SuiteSparse_long lj = d->loc[F->col[k]];
            if (lj < 0 || F->col[k] == i)
                continue;
            Ti[t] = li < lj ? li : lj;
            Tj[t] = li < lj ? lj : li;
            Tx[t++] = -0.5 * P->p[i].area * F->val[k];
        }
    }
    T->nnz = t;
    cholmod_sparse *A = cholmod_l_triplet_to_sparse(T, t, d->cc);
    cholmod_l_free_triplet(&T, d->cc);
    if (!A)
        return chol_fail(d->cc, "assemble", err);

    rr_status st = RR_OK;
    cholmod_factor *L = NULL;
    SuiteSparse_long *dpos = malloc(d->m * sizeof *dpos);
    if (!dpos) {
        st = rr_error_set(err, RR_ERR_NOMEM, "out of memory in the direct solver");
        goto done;
    }
    const SuiteSparse_long *Ap = A->p, *Ai = A->i;
    for (size_t l = 0; l < d->m; l++)
        for (SuiteSparse_long q = Ap[l]; q < Ap[l + 1]; q++)
            if (Ai[q] == (SuiteSparse_long)l)
                dpos[l] = q;

    L = cholmod_l_analyze(A, d->cc);
    if (!L) {
        st = chol_fail(d->cc, "analyze", err);
        goto done;
    }
    /* Refuse what would not fit before CHOLMOD tries (fill-in makes the
     * factor of a scene-sized system nearly dense). */
    double need = d->cc->lnz * (double)(sizeof(double) + sizeof(SuiteSparse_long));
    if (need > memory_budget()) {
        st = rr_error_set(err, RR_ERR_LIMIT,
                          "the direct solver would need %.1f GiB for %zu patches: use the iterative "
                          "solver",
                          need / (1024.0 * 1024.0 * 1024.0), d->m);
        goto done;
    }
    int solved[3] = {0, 0, 0};
    for (int a = 0; a < nch && st == RR_OK; a++) {
        if (solved[a])
            continue;
        int cols[3], ncols = 0;
        for (int b = a; b < nch; b++)
            if (!solved[b] && same_rho(P, chans[a], chans[b])) {
                cols[ncols++] = chans[b];
                solved[b] = 1;
            }
        st = direct_channels(d, A, L, dpos, cols, ncols, X, err);
    }
done:
    free(dpos);
    cholmod_l_free_factor(&L, d->cc);
    cholmod_l_free_sparse(&A, d->cc);
    return st;
}

static rr_status solve_direct(const rad_patches *P, const rad_ff *F, rr_rgb *X, rr_error *err)
{
    cholmod_common cc;
    if (!cholmod_l_start(&cc))
        return rr_error_set(err, RR_ERR_INTERNAL, "CHOLMOD failed to start");
    cc.print = 0;    /* errors come back as rr_error messages, not on stdout */
    cc.final_ll = 1; /* LL' everywhere, so a non-positive pivot is reported */
    direct d = {P, F, &cc, NULL, NULL, NULL, 0};
    rr_status st = RR_OK;
    d.loc = malloc(P->n * sizeof *d.loc);
    d.glob = malloc(P->n * sizeof *d.glob);
    d.fii = calloc(P->n, sizeof *d.fii);
    if (!d.loc || !d.glob || !d.fii) {
        st = rr_error_set(err, RR_ERR_NOMEM, "out of memory in the direct solver");
        goto done;
    }
    for (size_t i = 0; i < P->n; i++) {
        X[i] = P->p[i].emission; /* stays for patches black in a channel */
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++)
            if (F->col[k] == i)
                d.fii[i] += F->val[k];
    }
    int done_ch[3] = {0, 0, 0};
    for (int a = 0; a < 3 && st == RR_OK; a++) {
        if (done_ch[a])
            continue;
        int chans[3], nch = 0;
        for (int b = a; b < 3; b++)
            if (!done_ch[b] && same_unknowns(P, a, b)) {
                chans[nch++] = b;
                done_ch[b] = 1;
            }
        st = direct_unknown_set(&d, chans, nch, X, err);
    }
done:
    free(d.loc);
    free(d.glob);
    free(d.fii);
    cholmod_l_finish(&cc);
    return st;
}

rr_status rad_solve(const rad_patches *P, const rad_ff *F, const rad_solve_opts *o, rr_rgb *B, rad_solve_stats *stats,
                    rr_error *err)
{
    double t0 = rr_now_seconds();
    static const rad_solve_opts defaults = {RAD_SOLVER_AUTO, 0.0, 0, 0, 0, NULL};
    if (!o)
        o = &defaults;
    if (!B)
        return rr_error_set(err, RR_ERR_INVALID, "no output array");
    rr_status st = rad_system_check(P, F, err);
    if (st != RR_OK)
        return st;
    if ((st = check_physics(P, o->allow_rho_ge_1, err)) != RR_OK)
        return st;
    double tol = o->tolerance > 0.0 ? o->tolerance : RAD_FLAT_TOLERANCE;
    int maxit = o->max_iterations > 0 ? o->max_iterations : RAD_DEFAULT_MAX_ITERATIONS;
    size_t direct_max = o->auto_direct_max > 0 ? o->auto_direct_max : RAD_DEFAULT_AUTO_DIRECT_MAX;
    rad_solve_stats s = {0};
    switch (o->solver) {
    case RAD_SOLVER_AUTO: s.used = P->n <= direct_max ? RAD_SOLVER_DIRECT : RAD_SOLVER_ITERATIVE; break;
    case RAD_SOLVER_DIRECT:
    case RAD_SOLVER_ITERATIVE: s.used = o->solver; break;
    default: return rr_error_set(err, RR_ERR_INVALID, "unknown solver %d", (int)o->solver);
    }

    rr_rgb *X = malloc(P->n * sizeof *X);
    if (!X)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for %zu radiosities", P->n);
    if (s.used == RAD_SOLVER_DIRECT) {
        st = solve_direct(P, F, X, err);
        if (st == RR_OK) {
            s.residual = residual(P, F, X);
            if (!isfinite(s.residual))
                st = rr_error_set(err, RR_ERR_INVALID, "the direct solve produced non-finite radiosities");
        }
    } else {
        s.tolerance = tol;
        st = solve_iterative(P, F, tol, maxit, o->interrupt, X, &s, err);
    }
    if (st != RR_OK) {
        free(X);
        free(s.history);
        return st;
    }
    memcpy(B, X, P->n * sizeof *X);
    free(X);
    s.seconds = rr_now_seconds() - t0;
    if (stats)
        *stats = s;
    else
        free(s.history);
    return RR_OK;
}
