/* rad_energy.c - where the emitted power went: per object and in total.
 *
 * With H_i = sum_j F_ij B_j the irradiance gathered by patch i, the power
 * arriving at patch i is A_i H_i; a fraction rho_i of it is reflected, the
 * rest absorbed. Point and directional lights (the first shot H0_i, rad_pass.c)
 * add A_i H0_i to what arrives; their rows emit their power and escape what
 * lands on no patch front (the patches' own emission is then E_i, and B_i =
 * E_i + rho_i (H_i + H0_i); the derivation below holds with H_i + H0_i for H_i
 * and the lights' power for the first shot's share of the emission). What
 * leaves patch i and lands on no patch, B_i A_i (1 - sum_j F_ij), escapes
 * through the openings of the scene (or ends on a back face).
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
#include <math.h>
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

/* The ledger; emitted (per patch, E_i of its own emission) and first_shot
 * (H0_i) may be NULL: then p->emission is the emission and there is no first
 * shot. Light rows (nl of them, power[l], landed[l]) go after the objects. */
typedef struct ledger_in {
    const scene *s;
    const rad_patches *P;
    const rad_ff *F;
    const rr_rgb *B, *emitted, *first_shot;
    /* In place of F (hierarchical solutions): per patch the gathered
     * irradiance H_i and, per channel, the share of what leaves it that the
     * links deliver, sum_j F_ji (1 - m_j) read from its side (rad.h). */
    const rr_rgb *H;
    const rr_rgb *fsum;
    size_t nl;
    const rr_rgb *power, *landed;
} ledger_in;

static rad_energy_row patch_row(const ledger_in *in, size_t i)
{
    const rad_patches *P = in->P;
    const rad_ff *F = in->F;
    const rad_patch *p = &P->p[i];
    rr_rgb h = in->first_shot ? in->first_shot[i] : rr_rgb_make(0, 0, 0);
    rr_rgb fsum = rr_rgb_make(0, 0, 0);
    if (!F) {
        h = rr_rgb_add(h, in->H[i]);
        fsum = in->fsum[i];
    } else {
        double f = 0.0;
        for (size_t k = F->rowptr[i]; k < F->rowptr[i + 1]; k++) {
            h = rr_rgb_add(h, rr_rgb_scale(in->B[F->col[k]], F->val[k]));
            f += F->val[k] * (1.0 - P->p[F->col[k]].mirror);
        }
        fsum = rr_rgb_make(f, f, f);
    }
    rr_rgb incident = rr_rgb_scale(h, p->area);
    double m = p->mirror;
    rr_rgb absorb = rr_rgb_make(1.0 - p->rho.r - m, 1.0 - p->rho.g - m, 1.0 - p->rho.b - m);
    rad_energy_row r = {
        .object = p->object,
        .light = -1,
        .area = p->area,
        .emitted = rr_rgb_scale(in->emitted ? in->emitted[i] : p->emission, p->area),
        .incident = incident,
        .reflected = rr_rgb_mul(p->rho, incident),
        .mirrored = rr_rgb_scale(incident, m),
        .absorbed = rr_rgb_mul(absorb, incident),
        .escaped = F ? rr_rgb_scale(in->B[i], p->area * (1.0 - fsum.g)) /* fsum's channels are one */
                     : rr_rgb_make(in->B[i].r * p->area * (1.0 - fsum.r), in->B[i].g * p->area * (1.0 - fsum.g),
                                   in->B[i].b * p->area * (1.0 - fsum.b)),
    };
    return r;
}

static rr_status ledger(const ledger_in *in, rad_energy_row **rows, size_t *nrows, rr_error *err)
{
    const scene *s = in->s;
    const rad_patches *P = in->P;
    if (!rows || !nrows || !in->B)
        return rr_error_set(err, RR_ERR_INVALID, "energy ledger: missing radiosities or output");
    *rows = NULL;
    *nrows = 0;
    rr_status st = in->F ? rad_system_check(P, in->F, err)
                         : (in->H && in->fsum ? RR_OK
                                              : rr_error_set(err, RR_ERR_INVALID, "missing form factors"));
    if (st != RR_OK) {
        rr_error_prefix(err, "energy ledger");
        return st;
    }
    /* Objects: the scene's, or (without a scene) as many as the patches name. */
    size_t nobj = 0;
    for (size_t i = 0; i < P->n; i++) {
        if (!rr_rgb_isfinite(in->B[i]))
            return rr_error_set(err, RR_ERR_INVALID, "energy ledger: patch %zu has a non-finite radiosity", i);
        if ((size_t)P->p[i].object + 1 > nobj)
            nobj = (size_t)P->p[i].object + 1;
    }
    if (s && nobj > s->nobjects)
        return rr_error_set(err, RR_ERR_INVALID, "energy ledger: a patch belongs to object %zu, but the scene has %zu",
                            nobj - 1, s->nobjects);

    rad_energy_row *acc = calloc(nobj ? nobj : 1, sizeof *acc);
    unsigned char *used = calloc(nobj ? nobj : 1, 1);
    rad_energy_row *out = NULL;
    size_t n = 1 + in->nl;
    if (acc && used) {
        for (size_t i = 0; i < P->n; i++) {
            rad_energy_row r = patch_row(in, i);
            row_add(&acc[P->p[i].object], &r);
            used[P->p[i].object] = 1;
        }
        for (size_t o = 0; o < nobj; o++)
            n += used[o];
        out = calloc(n, sizeof *out);
    }
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
        out[k].object = (int64_t)o;
        out[k].light = -1;
        if (s)
            snprintf(out[k].name, sizeof out[k].name, "%s", s->objects[o].name);
        else
            snprintf(out[k].name, sizeof out[k].name, "objects[%zu]", o);
        row_add(total, &out[k]);
        k++;
    }
    for (size_t l = 0; l < in->nl; l++, k++) {
        rad_energy_row *r = &out[k];
        r->object = -1;
        r->light = (int64_t)l;
        snprintf(r->name, sizeof r->name, "%s", s->lights[l].name);
        r->emitted = in->power[l];
        r->escaped = rr_rgb_add(in->power[l], rr_rgb_scale(in->landed[l], -1.0));
        row_add(total, r);
    }
    snprintf(total->name, sizeof total->name, "total");
    total->object = total->light = -1;
    free(acc);
    free(used);
    *rows = out;
    *nrows = n;
    return RR_OK;
}

rr_status rad_energy(const scene *s, const rad_patches *P, const rad_ff *F, const rr_rgb *B, rad_energy_row **rows,
                     size_t *nrows, rr_error *err)
{
    ledger_in in = {.s = s, .P = P, .F = F, .B = B};
    return ledger(&in, rows, nrows, err);
}

rr_status rad_energy_solution(const struct rad_solution *sol, rad_energy_row **rows, size_t *nrows, rr_error *err)
{
    if (!sol || (!sol->F && !(sol->hier_H && sol->hier_fsum)))
        return rr_error_set(err, RR_ERR_INVALID,
                            "energy ledger: the solution has no form factors (read from a cache?)");
    const scene *s = sol->scene;
    size_t nl = s && sol->light_landed ? s->nlights : 0;
    rr_rgb *power = calloc(nl ? nl : 1, sizeof *power);
    if (!power)
        return rr_error_set(err, RR_ERR_NOMEM, "energy ledger: out of memory");
    for (size_t l = 0; l < nl; l++)
        power[l] = rt_light_power(s, l);
    ledger_in in = {.s = s, .P = sol->P, .F = sol->F, .B = sol->B, .emitted = sol->emitted,
                    .first_shot = sol->first_shot, .H = sol->hier_H, .fsum = sol->hier_fsum, .nl = nl, .power = power, .landed = sol->light_landed};
    rr_status st = ledger(&in, rows, nrows, err);
    free(power);
    return st;
}

/* ---- against the particle ledger ---- */

static double mean_se(rr_rgb se) { return (se.r + se.g + se.b) / 3.0; }

static rad_energy_cmp make_cmp(const rad_energy_row *r, int column, double rad, double part, double se,
                               const rad_energy_check_opts *o, double emitted)
{
    rad_energy_cmp c;
    memset(&c, 0, sizeof c);
    snprintf(c.name, sizeof c.name, "%s", r->name);
    c.object = r->object;
    c.light = r->light;
    c.column = column;
    c.rad = rad;
    c.part = part;
    c.se = se;
    double d = fabs(rad - part);
    /* Deterministic estimates (an emitter's power) agree to rounding, not to an SE. */
    if (d <= 1e-9 * fmax(fabs(rad), fabs(part)))
        d = 0.0;
    c.z = se > 0.0 ? d / se : (d > 0.0 ? INFINITY : 0.0);
    c.checked = fmax(fabs(rad), fabs(part)) > o->min_share * emitted;
    c.pass = !c.checked || d <= o->sigmas * se + o->allowance * fmax(fabs(rad), fabs(part));
    return c;
}

rr_status rad_energy_compare(const rad_energy_row *rows, size_t nrows, const rt_particle_ledger *g,
                             const rad_energy_check_opts *opts, rad_energy_cmp **out, size_t *n, size_t *failures,
                             rr_error *err)
{
    rad_energy_check_opts o = opts ? *opts : (rad_energy_check_opts){0, -1, 0};
    if (!(o.sigmas > 0))
        o.sigmas = 4.0;
    if (o.allowance < 0)
        o.allowance = 0.01;
    if (!(o.min_share > 0))
        o.min_share = 0.001;
    if (nrows == 0 || !g || !g->row)
        return rr_error_set(err, RR_ERR_INVALID, "energy check: missing ledger");
    static const int cols[3] = {RT_LEDGER_EMITTED, RT_LEDGER_INCIDENT, RT_LEDGER_ABSORBED};
    rad_energy_cmp *c = calloc(3 * nrows + 1, sizeof *c);
    if (!c)
        return rr_error_set(err, RR_ERR_NOMEM, "energy check: out of memory");
    const rad_energy_row *total = &rows[nrows - 1];
    double emitted = rr_rgb_mean(total->emitted);
    size_t k = 0, bad = 0;
    for (size_t i = 0; i + 1 < nrows; i++) {
        const rad_energy_row *r = &rows[i];
        size_t gi = r->object >= 0 ? (size_t)r->object : g->nobjects + (size_t)r->light;
        if ((r->object >= 0 && (size_t)r->object >= g->nobjects) || (r->light >= 0 && (size_t)r->light >= g->nlights)) {
            free(c);
            return rr_error_set(err, RR_ERR_INVALID, "energy check: row '%s' is not in the particle ledger", r->name);
        }
        const rr_rgb radv[3] = {r->emitted, r->incident, r->absorbed};
        for (int j = 0; j < 3; j++) {
            if (r->light >= 0 && j > 0)
                break; /* a light only emits */
            c[k] = make_cmp(r, cols[j], rr_rgb_mean(radv[j]), rr_rgb_mean(g->row[gi].c[cols[j]]),
                            mean_se(g->se[gi].c[cols[j]]), &o, emitted);
            bad += !c[k++].pass;
        }
    }
    /* Escaped, in total: light that left, or ended on a back face, or was cut. */
    rr_rgb pe = g->unabsorbed, pse = g->unabsorbed_se;
    c[k] = make_cmp(total, -1, rr_rgb_mean(total->escaped), rr_rgb_mean(pe), mean_se(pse), &o, emitted);
    bad += !c[k++].pass;
    *out = c;
    *n = k;
    *failures = bad;
    return RR_OK;
}
