/* rad_ff_matrix.c - the form-factor matrix after estimation (rad_ff.c):
 * storage, reciprocity and row balancing.
 *
 * Row sums: a raw Monte Carlo ray puts weight 1 into its landings at most
 * (a mirror keeps none of what lands on it and sends its share m on), so a
 * raw row's effective sum sum_j F_ij (1 - m_j) is <= 1 exactly (1 in a closed
 * room without mirrors). Averaging F_ij with A_j F_ji / A_i (below) spreads
 * the noise of the transposed entries into the rows: up to 1.11 with 256 rays
 * per patch in the Cornell box, 1.04 with 1024 in a closed cube, which made
 * the energy ledger's "escaped" share negative and created energy in a
 * furnace. Monte Carlo rows are therefore balanced after the averaging
 * (balance_rows): A_i F_ij := s_i s_j A_i F_ij, which keeps reciprocity, with
 * s chosen so that each row's effective sum is the raw row's again (within
 * 1e-9 where such an s exists; never above 1 in any case). Quadrature rows
 * are left as averaged: their raw sums are not bounded by 1 (quadrature
 * error), so there is no exact target to restore.
 *
 * The reciprocal matrix: F_ij := A_j (F_ij + F_ji) / (A_i + A_j) over the
 * union of the two patterns, so A_i F_ij = A_j F_ji (to rounding) and the
 * solved system conserves energy. It is the inverse-variance mean of the two
 * estimates of G_ij = A_i F_ij: from i's n rays, G_ij's variance is about
 * A_i G_ij / n (a binomial count of rays of weight A_i / n), from j's A_j
 * G_ij / n, so the weights are 1 / A_i and 1 / A_j. For patches of one size
 * it is the plain mean (F_ij + F_ji) / 2; for a leaf's patch beside a wall's
 * a thousand times larger it is nearly the leaf's own estimate. The plain
 * mean, used before, gave half of a small patch's row to the large patches'
 * few rays that happen to land on it (mostly none, sometimes a spike of
 * A_j / (n A_i)), and the row balancing below skewed what was left:
 * interior.json's plant took in 20 % too little, 32 DISAGREE lines of its
 * `energy --check` against 5 (notes/radiosity.md, "Reciprocity by inverse
 * variance"). Serial: the same bits for any thread count.
 */
#include <stdlib.h>
#include <string.h>

#include "rad.h"
#include "rad_ff_internal.h"

void rad__ff_free(rad_ff *F)
{
    if (!F)
        return;
    free(F->rowptr);
    free(F->col);
    free(F->val);
    free(F->open);
    free(F);
}

void rad_ff_destroy(rad_ff *F) { rad__ff_free(F); }

rad_ff *rad__ff_alloc(size_t n, size_t nnz)
{
    rad_ff *F = calloc(1, sizeof *F);
    if (!F)
        return NULL;
    F->n = n;
    F->rowptr = calloc(n + 1, sizeof *F->rowptr);
    F->col = malloc((nnz ? nnz : 1) * sizeof *F->col);
    F->val = malloc((nnz ? nnz : 1) * sizeof *F->val);
    F->open = malloc((n ? n : 1) * sizeof *F->open);
    if (!F->rowptr || !F->col || !F->val || !F->open) {
        rad__ff_free(F);
        return NULL;
    }
    for (size_t i = 0; i < n; i++)
        F->open[i] = 1.0;
    return F;
}

/* The open area A_i open_i of patch i (rad.h: buried parts). */
static double open_area(const rad_patches *P, const rad_ff *F, size_t i) { return P->p[i].area * F->open[i]; }

/* F_ij := A_j (F_ij + F_ji) / (A_i + A_j) over the union of the patterns of F
 * and its transpose, A the open areas. Columns of F are sorted per row; the
 * transpose built by counting keeps them sorted too, so each new row is a
 * merge. */
static rad_ff *make_reciprocal(const rad_patches *P, const rad_ff *F)
{
    size_t n = F->n, nnz = F->rowptr[n];
    rad_ff *T = rad__ff_alloc(n, nnz), *R = NULL;
    size_t *fill = malloc((n ? n : 1) * sizeof *fill);
    if (!T || !fill)
        goto done;
    for (size_t e = 0; e < nnz; e++)
        T->rowptr[F->col[e] + 1]++;
    for (size_t j = 0; j < n; j++)
        T->rowptr[j + 1] += T->rowptr[j];
    memcpy(fill, T->rowptr, n * sizeof *fill);
    for (size_t i = 0; i < n; i++)
        for (size_t e = F->rowptr[i]; e < F->rowptr[i + 1]; e++) {
            size_t d = fill[F->col[e]]++;
            T->col[d] = (uint32_t)i;
            T->val[d] = F->val[e];
        }
    /* Union sizes, then the merged rows. */
    size_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1 && !(R = rad__ff_alloc(n, total)))
            goto done;
        size_t out = 0;
        for (size_t i = 0; i < n; i++) {
            size_t a = F->rowptr[i], ae = F->rowptr[i + 1], b = T->rowptr[i], be = T->rowptr[i + 1];
            double Ai = open_area(P, F, i);
            /* A zero-area patch exchanges nothing (and would divide by 0);
             * nothing reaches a wholly buried one either. */
            while (Ai > 0.0 && (a < ae || b < be)) {
                uint32_t j;
                double fij = 0.0, fji = 0.0;
                if (b >= be || (a < ae && F->col[a] < T->col[b])) {
                    j = F->col[a];
                    fij = F->val[a++];
                } else if (a >= ae || T->col[b] < F->col[a]) {
                    j = T->col[b];
                    fji = T->val[b++];
                } else {
                    j = F->col[a];
                    fij = F->val[a++];
                    fji = T->val[b++];
                }
                double Aj = open_area(P, F, j);
                if (!(Aj > 0.0))
                    continue;
                if (pass == 1) {
                    R->col[out] = j;
                    R->val[out] = Aj * (fij + fji) / (Ai + Aj);
                }
                out++;
            }
            if (pass == 1)
                R->rowptr[i + 1] = out;
        }
        total = out;
    }
    memcpy(R->open, F->open, n * sizeof *R->open);
done:
    rad__ff_free(T);
    free(fill);
    return R;
}

/* ---- row balancing (Monte Carlo) ---- */

/* A raw Monte Carlo ray lands on patches with weights w_1, w_2, ... (1, then
 * times each mirror's reflectance m), and the part w_k (1 - m_j) of a landing
 * on j stays there; the rest goes on. So each ray puts at most 1 in all, and
 * a raw row's EFFECTIVE sum r_i = sum_j F_ij (1 - m_j) is <= 1 exactly; the
 * energy ledger's "escaped" column, B_i A_i (1 - r_i), rests on it. The
 * averaging breaks that bound by the noise of the entries. balance_rows
 * restores it: G_ij = A_i F_ij is symmetric, and G_ij := s_i s_j G_ij keeps
 * it so for any s > 0; s is chosen so that every row's effective sum is r_i
 * again.
 *
 * With u_j = (1 - m_j) s_j the equations s_i sum_j G_ij (1 - m_j) s_j / A_i =
 * r_i are u_i (G u)_i = b_i, symmetric matrix balancing: the stationary
 * points of a convex function of log u. Solving one row exactly for its s_i
 * given the others (a quadratic: a patch may see itself in a mirror, G_ii >
 * 0) is coordinate descent on it: Gauss-Seidel sweeps in row order
 * (deterministic), until every row is within RAD_FF_BALANCE_TOL (a closed
 * box: about 10 sweeps; Cornell 20). Each s_i is kept within a factor
 * RAD_FF_BALANCE_CLAMP of 1: noise moves it by a few percent, and more means
 * the two estimates disagree beyond noise (a row of one or two hits, or
 * thin gaps where ray offsets bias one side), where an exact fit would pull
 * whole neighbourhoods to 0 or infinity. Where no s fits (clamped rows, or a
 * bipartite pattern, two plates facing each other, whose sides' sums of
 * A_i r_i never agree exactly) the sweeps stop at RAD_FF_BALANCE_SWEEPS, and
 * a last pass s_i *= min(1, 1 / c_i), all rows at once (no factor grows, so
 * no row ends above 1), bounds every row by 1 whatever happened. Left alone
 * (s_i = 1): rows of zero area, of raw or averaged effective sum 0 (no hits,
 * or only patches that keep nothing: perfect mirrors). One sweep is O(nnz):
 * 0.09 s for the 80 M entries of scenes/room.json. */
#define RAD_FF_BALANCE_TOL 1e-9
#define RAD_FF_BALANCE_SWEEPS 50
#define RAD_FF_BALANCE_CLAMP 2.0

/* sum_j F_ij u_j over j != i, and the diagonal entry F_ii (a patch that sees
 * itself in a mirror) into *diag. */
static double row_dot(const rad_ff *F, const double *u, size_t i, double *diag)
{
    double c = 0.0, d = 0.0;
    for (size_t e = F->rowptr[i]; e < F->rowptr[i + 1]; e++) {
        uint32_t j = F->col[e];
        if (j == i)
            d += F->val[e];
        else
            c += F->val[e] * u[j];
    }
    *diag = d;
    return c;
}

/* Gauss-Seidel sweeps on s (w_j = 1 - m_j, u_j = w_j s_j kept up to date);
 * rows with r_i = 0 are left alone. */
static void balance_sweeps(const rad_ff *R, const double *r, const double *w, double *s, double *u)
{
    for (int sweep = 0; sweep < RAD_FF_BALANCE_SWEEPS; sweep++) {
        double worst = 0.0;
        for (size_t i = 0; i < R->n; i++) {
            if (!(r[i] > 0.0))
                continue;
            /* Row i's sum is a s_i^2 + b s_i: solve it for r_i (the stable
             * root; a = 0 gives r_i / b), within the clamp. */
            double d, b = row_dot(R, u, i, &d), a = d * w[i];
            double c = s[i] * (a * s[i] + b), t = 2.0 * r[i] / (b + sqrt(b * b + 4.0 * a * r[i]));
            double sc = fmin(fmax(t, 1.0 / RAD_FF_BALANCE_CLAMP), RAD_FF_BALANCE_CLAMP);
            /* A clamped row is done when its s stays put. */
            worst = fmax(worst, sc == t ? fabs(c - r[i]) / r[i] : fabs(sc - s[i]) / s[i]);
            s[i] = sc;
            u[i] = w[i] * sc;
        }
        if (worst < RAD_FF_BALANCE_TOL)
            break;
    }
}

/* R (reciprocal, from the raw F) rescaled in place; 0 when out of memory. */
static int balance_rows(const rad_patches *P, const rad_ff *F, rad_ff *R)
{
    size_t n = R->n, sz = (n ? n : 1) * sizeof(double);
    double *s = malloc(sz), *r = malloc(sz), *w = malloc(sz), *u = malloc(sz), d, dr;
    int ok = s && r && w && u;
    for (size_t i = 0; ok && i < n; i++) {
        s[i] = 1.0;
        u[i] = w[i] = 1.0 - P->p[i].mirror;
    }
    for (size_t i = 0; ok && i < n; i++) {
        r[i] = row_dot(F, w, i, &d) + d * w[i];
        if (!(open_area(P, R, i) > 0.0) || !(r[i] > 0.0) || !(row_dot(R, w, i, &dr) + dr * w[i] > 0.0))
            r[i] = 0.0; /* left alone */
    }
    if (ok) {
        balance_sweeps(R, r, w, s, u);
        /* The cap, all rows at once (r now holds the factors). */
        for (size_t i = 0; i < n; i++) {
            double c = s[i] * (row_dot(R, u, i, &d) + d * w[i] * s[i]);
            r[i] = c > 1.0 ? 1.0 / c : 1.0;
        }
        for (size_t i = 0; i < n; i++)
            s[i] *= r[i];
        for (size_t i = 0; i < n; i++)
            for (size_t e = R->rowptr[i]; e < R->rowptr[i + 1]; e++)
                R->val[e] *= s[i] * s[R->col[e]]; /* the same product in row j: A_i F_ij = A_j F_ji stays */
    }
    free(s);
    free(r);
    free(w);
    free(u);
    return ok;
}

rad_ff *rad__ff_finish(const rad_patches *P, rad_ff *F, const rad_ff_opts *o)
{
    if (!F || o->raw)
        return F;
    rad_ff *R = make_reciprocal(P, F);
    if (R && o->method == RAD_FF_MONTE_CARLO && !balance_rows(P, F, R)) {
        rad__ff_free(R);
        R = NULL;
    }
    rad__ff_free(F);
    return R;
}

