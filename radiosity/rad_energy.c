/* rad_energy.c - where the emitted power went: per object and in total.
 *
 * With H_i = sum_j F_ij B_j the irradiance gathered by patch i, the power
 * arriving at patch i is A_i H_i; a fraction rho_i of it is reflected, the
 * rest absorbed. What leaves patch i and lands on no patch, B_i A_i (1 -
 * sum_j F_ij), escapes through the openings of the scene.
 *
 * Why the total balances. Sum the radiosity equation B_i = E_i + rho_i H_i
 * times A_i over all patches:
 *     sum_i A_i B_i = sum_i A_i E_i + sum_i rho_i A_i H_i.           (1)
 * With reciprocity A_i F_ij = A_j F_ji, the power arriving everywhere is
 *     sum_i A_i H_i = sum_i sum_j A_j F_ji B_j = sum_j A_j B_j sum_i F_ji
 *                   = sum_j A_j B_j - escaped,                       (2)
 * i.e. what leaves all patches either lands on one or escapes. Putting (2)
 * into (1):
 *     emitted = sum_i A_i B_i - sum_i rho_i A_i H_i
 *             = escaped + sum_i (1 - rho_i) A_i H_i = escaped + absorbed.
 *
 * Mirrors (extended form factors, rad_ff.c): a form-factor ray goes on from
 * a mirror patch j with weight rho_mirror_j, and lands again; F_ij counts
 * every landing, so the power that ends at j (absorbed there, or re-emitted
 * diffusely in B_j) is (1 - rho_mirror_j) of what arrives, and the rest is
 * the "mirrored" column. (2) becomes
 *     sum_i (1 - m_i) A_i H_i = sum_j A_j B_j - escaped,
 * escaped = sum_j A_j B_j (1 - sum_i F_ji (1 - m_i)), and so
 *     emitted = escaped + sum_i (1 - m_i - rho_i) A_i H_i = escaped + absorbed.
 * A solver residual r_i = E_i + rho_i H_i - B_i leaves an imbalance of
 * sum_i A_i r_i, and non-reciprocal form factors one of the size of their
 * non-reciprocity; rad_ff makes them reciprocal by default. Escaped power is
 * not clamped at 0: a reciprocal F whose row sums slightly exceed 1 gives a
 * slightly negative value, and clamping would break the balance.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rad_solve_internal.h"

static void row_add(rad_energy_row *t, const rad_energy_row *r)
{
    t->area += r->area;
    t->emitted = rr_rgb_add(t->emitted, r->emitted);
    t->incident = rr_rgb_add(t->incident, r->incident);
    t->reflected = rr_rgb_add(t->reflected, r->reflected);
    t->mirrored = rr_rgb_add(t->mirrored, r->mirrored);
    t->absorbed = rr_rgb_add(t->absorbed, r->absorbed);
    t->escaped = rr_rgb_add(t->escaped, r->escaped);
}

rr_status rad_energy(const scene *s, const rad_patches *P, const rad_ff *F, const rr_rgb *B, rad_energy_row **rows,
                     size_t *nrows, rr_error *err)
{
    if (!rows || !nrows || !B)
        return rr_error_set(err, RR_ERR_INVALID, "energy ledger: missing radiosities or output");
    rr_status st = rad_system_check(P, F, err);
    if (st != RR_OK)
        return st;
    /* Objects: the scene's, or (without a scene) as many as the patches name. */
    size_t nobj = 0;
    for (size_t i = 0; i < P->n; i++) {
        if (!rr_rgb_isfinite(B[i]))
            return rr_error_set(err, RR_ERR_INVALID, "energy ledger: patch %zu has a non-finite radiosity", i);
        if ((size_t)P->p[i].object + 1 > nobj)
            nobj = (size_t)P->p[i].object + 1;
    }
    if (s && nobj > s->nobjects)
        return rr_error_set(err, RR_ERR_INVALID, "energy ledger: a patch belongs to object %zu, but the scene has %zu",
                            nobj - 1, s->nobjects);

    rad_energy_row *acc = calloc(nobj, sizeof *acc);
    unsigned char *used = calloc(nobj, 1);
    if (!acc || !used) {
        free(acc);
        free(used);
        return rr_error_set(err, RR_ERR_NOMEM, "energy ledger: out of memory");
    }
    for (size_t i = 0; i < P->n; i++) {
        const rad_patch *p = &P->p[i];
        rr_rgb h = {0, 0, 0};
        double fsum = 0.0;
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
            h = rr_rgb_add(h, rr_rgb_scale(B[F->col[k]], F->val[k]));
            fsum += F->val[k] * (1.0 - P->p[F->col[k]].mirror);
        }
        rr_rgb incident = rr_rgb_scale(h, p->area);
        double m = p->mirror;
        rr_rgb absorb = rr_rgb_make(1.0 - p->rho.r - m, 1.0 - p->rho.g - m, 1.0 - p->rho.b - m);
        rad_energy_row r = {
            .area = p->area,
            .emitted = rr_rgb_scale(p->emission, p->area),
            .incident = incident,
            .reflected = rr_rgb_mul(p->rho, incident),
            .mirrored = rr_rgb_scale(incident, m),
            .absorbed = rr_rgb_mul(absorb, incident),
            .escaped = rr_rgb_scale(B[i], p->area * (1.0 - fsum)),
        };
        row_add(&acc[p->object], &r);
        used[p->object] = 1;
    }

    size_t n = 1;
    for (size_t o = 0; o < nobj; o++)
        n += used[o];
    rad_energy_row *out = calloc(n, sizeof *out);
    if (!out) {
        free(acc);
        free(used);
        return rr_error_set(err, RR_ERR_NOMEM, "energy ledger: out of memory");
    }
    /* The total is the sum of the rows, so the rows add up to it exactly. */
    rad_energy_row *total = &out[n - 1];
    size_t k = 0;
    for (size_t o = 0; o < nobj; o++) {
        if (!used[o])
            continue;
        out[k] = acc[o];
        if (s)
            snprintf(out[k].name, sizeof out[k].name, "%s", s->objects[o].name);
        else
            snprintf(out[k].name, sizeof out[k].name, "objects[%zu]", o);
        row_add(total, &out[k]);
        k++;
    }
    snprintf(total->name, sizeof total->name, "total");
    free(acc);
    free(used);
    *rows = out;
    *nrows = n;
    return RR_OK;
}
