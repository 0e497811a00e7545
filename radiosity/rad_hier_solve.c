/* rad_hier_solve.c - solving on a fixed hierarchy of the hierarchical pass
 * (rad_hier.c): source values up the trees and clusters, every link's
 * transport into its receiver, irradiance down to the leaves, and the Jacobi
 * sweeps of those to the tolerance, then the solution as the leaves' patch
 * set (rad_hier_ctx.h has the interface and rad_hier.c's header the
 * formulas). Sums run in a fixed order: the same bits for any thread count. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"
#include "rad_hier_internal.h"
#include "rad_pass_internal.h"


/* Leaf values -> interior means (elements); power up the clusters. An
 * interior element's value is the mean over the open area of its leaves
 * (*open: that area; *all_open: every leaf under it wholly open, where it
 * is the plain mean of its children, bit for bit as before): its links'
 * shadow rays count its buried parts as hidden, so what it sends is the
 * radiosity of its open part. By plain area, its buried leaves (which
 * gather nothing) pulled it down: a closed room's wall around a mirror
 * mounted on it delivered 4 % less than it reflected, and the room lost
 * 0.65 % of its power (notes/radiosity.md, "The ledger read from the
 * sources"). */
static rr_rgb pull_el(hctx *c, uint32_t x, double *open, int *all_open)
{
    hel *e = &c->el[x];
    if (e->child == NONE) {
        *open = e->area * e->open;
        *all_open = e->open == 1.0;
        return e->src;
    }
    rr_rgb m = rr_rgb_make(0, 0, 0), mo = m;
    double wo = 0.0;
    int all = 1;
    for (uint32_t k = 0; k < 4; k++) {
        double w;
        int a;
        rr_rgb v = pull_el(c, e->child + k, &w, &a);
        m = rr_rgb_add(m, v);
        mo = rr_rgb_add(mo, rr_rgb_scale(v, w));
        wo += w;
        all &= a;
    }
    e->src = all || !(wo > 0) ? rr_rgb_scale(m, 0.25) : rr_rgb_scale(mo, 1.0 / wo);
    *open = wo;
    *all_open = all;
    return e->src;
}

#define PULL_SPLIT 6 /* pull_all's subtrees: 64 */

/* Power, directional power (per normal bucket, rad_hier_ctx.h) and power
 * centroid (pc) of node x's current sources; an element's power times
 * normal added to Dn. A cluster at depth PULL_SPLIT (x at depth) is read
 * as it stands: pull_all pulled it. */

static rr_rgb pull_cl(hctx *c, uint32_t x, nbuckets *Dn, int depth)
{
    if (!(x & CLB)) {
        rr_rgb P = rr_rgb_scale(c->el[x].src, c->el[x].area);
        nb_add_surface(Dn, el_normal(c, x), P.r + P.g + P.b);
        return P;
    }
    hcl *k = &c->cl[CL(x)];
    if (depth == PULL_SPLIT) { /* pulled already (pull_all) */
        nb_add(Dn, &k->Dn);
        return k->P;
    }
    memset(&k->Dn, 0, sizeof k->Dn);
    rr_rgb P0 = pull_cl(c, k->child[0], &k->Dn, depth + 1), P1 = pull_cl(c, k->child[1], &k->Dn, depth + 1);
    k->P = rr_rgb_add(P0, P1);
    /* The power centroid (the area centroid where there is no power). */
    double w0 = P0.r + P0.g + P0.b, w1 = P1.r + P1.g + P1.b;
    rr_vec3 c0 = k->child[0] & CLB ? c->cl[CL(k->child[0])].pc : c->el[k->child[0]].ctr;
    rr_vec3 c1 = k->child[1] & CLB ? c->cl[CL(k->child[1])].pc : c->el[k->child[1]].ctr;
    k->pc = w0 + w1 > 0 ? rr_v3_scale(rr_v3_add(rr_v3_scale(c0, w0), rr_v3_scale(c1, w1)), 1.0 / (w0 + w1)) : k->ac;
    nb_add(Dn, &k->Dn);
    return k->P;
}

/* The clusters' pull (pull_cl) over the whole tree: the subtrees at depth
 * PULL_SPLIT in parallel, then the levels above them on one thread, which
 * read those subtrees' sums as they stand. Every node sums its two children
 * in the same order as one walk from the top does: the same bits. Serial,
 * the pull was a fifth of the 81-bunny room's solve. */
static void collect_split(const hctx *c, uint32_t x, int depth, uint32_t *out, size_t *n)
{
    if (!(x & CLB))
        return;
    if (depth == PULL_SPLIT) {
        out[(*n)++] = x;
        return;
    }
    const hcl *k = &c->cl[CL(x)];
    collect_split(c, k->child[0], depth + 1, out, n);
    collect_split(c, k->child[1], depth + 1, out, n);
}

/* pull_cl's power alone (P), the same sums: what the solve's sweeps read
 * of the clusters (the gather's cluster sources). The buckets and the
 * centroid are for the links' evaluation, made whole once the solve ends. */
static rr_rgb pull_P(hctx *c, uint32_t x, int depth)
{
    if (!(x & CLB))
        return rr_rgb_scale(c->el[x].src, c->el[x].area);
    hcl *k = &c->cl[CL(x)];
    if (depth == PULL_SPLIT)
        return k->P;
    rr_rgb P0 = pull_P(c, k->child[0], depth + 1), P1 = pull_P(c, k->child[1], depth + 1);
    return k->P = rr_rgb_add(P0, P1);
}

static void pull_all(hctx *c, int power_only)
{
    uint32_t sub[1u << PULL_SPLIT];
    size_t n = 0;
    collect_split(c, c->top, 0, sub, &n);
#pragma omp parallel for schedule(dynamic, 1)
    for (long i = 0; i < (long)n; i++) {
        if (power_only) {
            pull_P(c, sub[i], PULL_SPLIT + 1);
            continue;
        }
        nbuckets Dn;
        memset(&Dn, 0, sizeof Dn);
        pull_cl(c, sub[i], &Dn, PULL_SPLIT + 1); /* below the split: to its leaves */
    }
    if (power_only) {
        pull_P(c, c->top, 0);
        return;
    }
    nbuckets Dn;
    memset(&Dn, 0, sizeof Dn);
    pull_cl(c, c->top, &Dn, 0);
}

/* unit: B = 1 but for a mirror's share (1 - its mirror reflectance), so that
 * the gather is each receiver's effective row sum, sum_j F_ij (1 - m_j)
 * with the links by way of mirrors in F (rad_energy.c): what a mirror
 * reflects arrives again by those links. A leaf buried whole (open 0) sends
 * nothing: the ledger and the display give it no area, yet links with a
 * few visible rays carried its B (Cornell: 15 such nodes sent 2e-6 of the
 * power that no open area accounted for, and the ledger's balance was
 * 5.7e-6 off; 1.4e-8 since). What leaves send is their B times the column
 * scale cs (column_scale; B = 1 sources are not scaled). */
static void set_leaf_src(hel *e, int unit, int indirect, const rad_patch *own, rr_rgb cs)
{
    if (!unit && !(e->open > 0))
        e->src = rr_rgb_make(0, 0, 0);
    else if (unit)
        e->src = rr_rgb_make(1.0 - own->mirror, 1.0 - own->mirror, 1.0 - own->mirror);
    else if (indirect)
        e->src = rr_rgb_mul(rr_rgb_add(e->B, rr_rgb_scale(own->emission, -1.0)), cs);
    else
        e->src = rr_rgb_mul(e->B, cs);
}

static void set_src(hctx *c, int unit, int indirect, uint32_t x)
{
    hel *e = &c->el[x];
    if (e->child == NONE) {
        set_leaf_src(e, unit, indirect, &c->R->p[e->root], c->cs);
        return;
    }
    for (uint32_t k = 0; k < 4; k++)
        set_src(c, unit, indirect, e->child + k);
}

static void sources(hctx *c, int unit, int indirect, int power_only)
{
    size_t nr = c->R->n;
    c->unit = unit;
#pragma omp parallel for schedule(dynamic, 64)
    for (long r = 0; r < (long)nr; r++) {
        set_src(c, unit, indirect, (uint32_t)r);
        double w;
        int all;
        rr_rgb v = pull_el(c, (uint32_t)r, &w, &all);
        c->rt[r].ssum = v.r + v.g + v.b;
    }
    pull_all(c, power_only);
}

void rad__hier_sources(hctx *c, int unit, int indirect) { sources(c, unit, indirect, 0); }

/* Room in c->sv for every node's source value; -1 when out of memory. */
static int reserve_sources(hctx *c)
{
    size_t nsv = c->nel + c->ncl;
    if (nsv <= c->capsv)
        return 0;
    rr_rgb *sv = realloc(c->sv, nsv * sizeof *sv);
    if (!sv)
        return -1;
    c->sv = sv;
    c->capsv = nsv;
    return 0;
}

/* Every link's transport into its receiver (links sorted by receiver). The
 * sources' values are copied first into one dense array (c->sv: elements,
 * then clusters, sized by rad__hier_solve): read through the links from the
 * ~370-byte elements, every link's source was a cache miss of its own (the
 * gather was 13 % of room.json's pass). The same values, so the same bits. */
void rad__hier_gather(hctx *c, const size_t *grp, size_t ngrp)
{
    RR_CHECK(c->capsv >= c->nel + c->ncl);
    rr_rgb *sv = c->sv, *svc = c->sv + c->nel;
#pragma omp parallel for schedule(static)
    for (long i = 0; i < (long)c->nel; i++) {
        c->el[i].H = c->el[i].Hc[0] = c->el[i].Hc[1] = c->el[i].Hc[2] = rr_rgb_make(0, 0, 0);
        if (c->unit)
            c->el[i].partial = 0;
        sv[i] = c->el[i].src;
    }
#pragma omp parallel for schedule(static)
    for (long i = 0; i < (long)c->ncl; i++)
        svc[i] = c->cl[i].P;
#pragma omp parallel for schedule(dynamic, 64)
    for (long gi = 0; gi < (long)ngrp; gi++) {
        if (c->ln[grp[gi]].r & CLB)
            continue; /* a receiving leaf cluster's: below, once the elements' are in */
        rr_rgb H = rr_rgb_make(0, 0, 0), Hc[3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
        int partial = 0;
        hel *e = &c->el[c->ln[grp[gi]].r];
        int inner = e->child != NONE;
        for (size_t j = grp[gi]; j < grp[gi + 1]; j++) {
            const hlink *l = &c->ln[j];
            partial |= link_partial(l);
            rr_rgb v = link_light(c, l);
            H = rr_rgb_add(H, v);
            float d[3];
            if (inner && link_shape(l, d)) {
                Hc[0] = rr_rgb_add(Hc[0], rr_rgb_scale(v, d[0]));
                Hc[1] = rr_rgb_add(Hc[1], rr_rgb_scale(v, d[1]));
                Hc[2] = rr_rgb_add(Hc[2], rr_rgb_scale(v, d[2]));
            }
        }
        e->H = H;
        memcpy(e->Hc, Hc, sizeof Hc);
        if (c->unit)
            e->partial = partial;
    }
    if (c->rlc)
        rad__hier_rlc_gather(c, grp);
}

static rr_rgb mid(rr_rgb a, rr_rgb b) { return rr_rgb_scale(rr_rgb_add(a, b), 0.5); }

/* Hin: the even irradiance from above; D[3]: the linear field's departure
 * from it at x's corners. */
static double push_el(hctx *c, uint32_t x, rr_rgb Hin, const rr_rgb Din[3], int partial, push_mode mode)
{
    hel *e = &c->el[x];
    rr_rgb H = rr_rgb_add(Hin, e->H), D[3];
    for (int k = 0; k < 3; k++)
        D[k] = rr_rgb_add(Din[k], e->Hc[k]);
    partial |= e->partial;
    if (e->child != NONE) {
        /* the children's corners (el_split): A, ab, ca; ab, B, bc; ca, bc, C; bc, ca, ab */
        rr_rgb ab = mid(D[0], D[1]), bc = mid(D[1], D[2]), ca = mid(D[2], D[0]);
        const rr_rgb ch[4][3] = {{D[0], ab, ca}, {ab, D[1], bc}, {ca, bc, D[2]}, {bc, ca, ab}};
        double m = 0.0;
        for (uint32_t k = 0; k < 4; k++)
            m = rr_max(m, push_el(c, e->child + k, H, ch[k], partial, mode));
        return m;
    }
    /* a leaf: the field's mean over it */
    H = rr_rgb_add(H, rr_rgb_scale(rr_rgb_add(D[0], rr_rgb_add(D[1], D[2])), 1.0 / 3.0));
    H = rr_rgb_make(rr_max(H.r, 0.0), rr_max(H.g, 0.0), rr_max(H.b, 0.0));
    if (mode == PUSH_SIGMA) {
        /* Only where every link was wholly visible or wholly hidden: there
         * the row sum's error is the quadrature's, which k removes; a few
         * shadow rays per partly visible link make it noise (9 % RMS per
         * leaf in room.json), and 1 / sigma of noise is biased (+2 %). */
        double sigma = (H.r + H.g + H.b) / 3.0;
        e->k = c->el[e->root].shut && !partial && sigma > 0 ? 1.0 / sigma : 1.0;
        return 0.0;
    }
    H = rr_rgb_scale(H, e->k);
    if (mode == PUSH_KEEP) {
        e->H = H;
        return 0.0;
    }
    rr_rgb B = rr_rgb_add(e->E, rr_rgb_mul(el_rho(c, x), H));
    double d = rr_max(fabs(B.r - e->B.r), rr_max(fabs(B.g - e->B.g), fabs(B.b - e->B.b)));
    e->B = B;
    return d;
}

/* Whether all of element x's leaves with closedness rays are closed. */
static int all_closed(const hctx *c, uint32_t x)
{
    const hel *e = &c->el[x];
    if (e->child == NONE)
        return e->closed || e->land < 0.0f;
    for (uint32_t k = 0; k < 4; k++)
        if (!all_closed(c, e->child + k))
            return 0;
    return 1;
}

/* hel.shut of every root: its leaves' closedness rays, all of them, landed
 * on fronts. A leaf's 16 alone decided k before: where a share f of its
 * hemisphere is open they all land with probability (1 - f)^16, and then
 * 1 / sigma scales its row up by 1 / (1 - f), up to 2.4 % on average at
 * f = 1 / 16 (a box's underside 0.5 over a wide lamp, f 0.036: +1.6 %
 * against the closed form). A root's leaves shoot some hundreds. */
static void roots_shut(hctx *c)
{
#pragma omp parallel for schedule(dynamic, 64)
    for (long r = 0; r < (long)c->R->n; r++)
        c->el[r].shut = c->el[r].child == NONE ? c->el[r].closed : all_closed(c, (uint32_t)r);
}

double rad__hier_push(hctx *c, push_mode mode)
{
    if (mode == PUSH_SIGMA)
        roots_shut(c);
    size_t nr = c->R->n;
    double m = 0.0;
#pragma omp parallel for schedule(dynamic, 64) reduction(max : m)
    for (long r = 0; r < (long)nr; r++) {
        const rr_rgb zero[3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
        double d = push_el(c, (uint32_t)r, rr_rgb_make(0, 0, 0), zero, 0, mode);
        m = d > m ? d : m;
    }
    return m;
}

/* Receiver groups of the sorted links: grp[0..ngrp] (one past the end). */
size_t *rad__hier_groups(hctx *c, size_t *ngrp, int prepare)
{
    size_t *g = malloc((c->nln + 1) * sizeof *g), n = 0;
    if (!g)
        return NULL;
    for (size_t i = 0; i < c->nln; i++)
        if (i == 0 || c->ln[i].r != c->ln[i - 1].r)
            g[n++] = i;
    g[n] = c->nln;
    *ngrp = n;
    if (c->rlc && (prepare || !c->rg) && rad__hier_rlc_prepare(c, g, n) != 0) {
        free(g);
        return NULL;
    }
    return g;
}

/* The power a sweep's change carries: over the leaves, open area x the
 * largest channel of |B - Bprev| (the ledger's balance moves by as much).
 * One thread, in element order: the same sum at any thread count (read only
 * once the largest change passes, a few sweeps a solve). */
static double leaves_change_power(const hctx *c, const rr_rgb *Bprev)
{
    double s = 0.0;
    for (size_t i = 0; i < c->nel; i++) {
        const hel *e = &c->el[i];
        if (e->child == NONE) {
            rr_rgb d = rr_rgb_add(e->B, rr_rgb_scale(Bprev[i], -1.0));
            s += e->area * e->open * rr_max(fabs(d.r), rr_max(fabs(d.g), fabs(d.b)));
        }
    }
    return s;
}

/* The largest channel of any leaf's B; NaN when one is NaN. In parallel
 * (a maximum is the same in any order): serial, it and column_scale were a
 * pass each over the elements per sweep on one thread. */
static double leaves_max_B(const hctx *c)
{
    double m = 0.0;
    int nan = 0;
#pragma omp parallel for schedule(static) reduction(max : m) reduction(| : nan)
    for (long i = 0; i < (long)c->nel; i++)
        if (c->el[i].child == NONE) {
            rr_rgb b = c->el[i].B;
            nan |= isnan(b.r) || isnan(b.g) || isnan(b.b);
            m = rr_max(m, rr_rgb_max(b));
        }
    return nan ? NAN : m;
}

/* What the receivers under element x take in per unit of irradiance, as
 * the ledger counts it: their weight w = open area x k x (1 - mirror
 * reflectance) (what a mirror reflects goes on by its ways), summed over
 * x's leaves (tk[4 x]), and the sums of w times the barycentrics of each
 * leaf's centre in x (tk[4 x + 1 .. 3]), which read a link's linear shape
 * over x exactly (the push carries it to the leaves' centres). */
static void taken(const hctx *c, uint32_t x, double *tk)
{
    const hel *e = &c->el[x];
    double *t = tk + 4 * (size_t)x;
    if (e->child == NONE) {
        t[0] = e->area * e->open * e->k * (1.0 - c->R->p[e->root].mirror);
        t[1] = t[2] = t[3] = t[0] / 3.0;
        return;
    }
    /* the children's corners in x's barycentrics (el_split): A, ab, ca; ab, B, bc; ca, bc, C; bc, ca, ab */
    static const double corner[4][3][3] = {{{1, 0, 0}, {.5, .5, 0}, {.5, 0, .5}},
                                           {{.5, .5, 0}, {0, 1, 0}, {0, .5, .5}},
                                           {{.5, 0, .5}, {0, .5, .5}, {0, 0, 1}},
                                           {{0, .5, .5}, {.5, 0, .5}, {.5, .5, 0}}};
    t[0] = t[1] = t[2] = t[3] = 0.0;
    for (uint32_t k = 0; k < 4; k++) {
        taken(c, e->child + k, tk);
        const double *u = tk + 4 * (size_t)(e->child + k);
        t[0] += u[0];
        for (int q = 0; q < 3; q++)
            for (int a = 0; a < 3; a++)
                t[1 + a] += u[1 + q] * corner[k][q][a];
    }
}

/* The open area under each element (O[x]). */
static double open_area(const hctx *c, uint32_t x, double *O)
{
    const hel *e = &c->el[x];
    if (e->child == NONE)
        return O[x] = e->area * e->open;
    double o = 0.0;
    for (uint32_t k = 0; k < 4; k++)
        o += open_area(c, e->child + k, O);
    return O[x] = o;
}

/* Down from node x: acc, what its ancestors deliver per unit of their power
 * (in a cluster: per unit of the cluster's; from the first element on: per
 * unit of the leaf's power from its open area), into D at the leaves. */
static void columns_down(const hctx *c, uint32_t x, double acc, int in_cluster, const double *d, const double *O,
                         double *D)
{
    if (x & CLB) {
        acc += d[c->nel + CL(x)];
        columns_down(c, c->cl[CL(x)].child[0], acc, 1, d, O, D);
        columns_down(c, c->cl[CL(x)].child[1], acc, 1, d, O, D);
        return;
    }
    const hel *e = &c->el[x];
    double f = O[x] > 0 ? e->area / O[x] : 0.0; /* its power per unit of its leaves' from their open areas */
    acc = (in_cluster ? acc * f : acc) + d[x] * f;
    if (e->child == NONE) {
        D[x] = acc;
        return;
    }
    for (uint32_t k = 0; k < 4; k++)
        columns_down(c, e->child + k, acc, 0, d, O, D);
}

/* Per leaf (D[0 .. nel), leaves only): what the links deliver per unit of
 * what it sends from its open area. A node's power is linear in its
 * leaves' sources (pull_el, pull_cl), so a link's delivery, g x what its
 * receivers take in (taken) x its source's power, splits among the leaves
 * exactly, whatever their B (a cluster's by its roots' shares). -1 when
 * out of memory. */
static int column_sums(const hctx *c, const size_t *grp, size_t ngrp, double *D)
{
    size_t nn = c->nel + c->ncl;
    double *tk = malloc(4 * (c->nel ? c->nel : 1) * sizeof *tk), *d = calloc(nn ? nn : 1, sizeof *d);
    if (!tk || !d) {
        free(tk);
        free(d);
        return -1;
    }
#pragma omp parallel for schedule(dynamic, 64)
    for (long r = 0; r < (long)c->R->n; r++)
        taken(c, (uint32_t)r, tk);
    size_t gi = 0; /* link i's group (receiving leaf clusters') */
    for (size_t i = 0; i < c->nln; i++) { /* serial: the sums in one order */
        const hlink *l = &c->ln[i];
        double w;
        if (l->r & CLB) { /* what its roots take in of its bucket's light, as rlc_gather reads it */
            while (gi + 1 < ngrp && grp[gi + 1] <= i)
                gi++;
            w = rad__hier_rlc_take(c, gi - c->rg0, l);
        } else {
            const double *t = tk + 4 * (size_t)l->r;
            w = t[0];
            float sh[3];
            if (c->el[l->r].child != NONE && link_shape(l, sh)) /* as the gather reads it */
                w += sh[0] * t[1] + sh[1] * t[2] + sh[2] * t[3];
        }
        double g = (double)link_g(l) * w;
        if (l->s & CLB)
            d[c->nel + CL(l->s)] += g;
        else
            d[l->s] += c->el[l->s].area > 0 ? g / c->el[l->s].area : 0.0;
    }
    double *O = tk; /* the open areas, in tk's room */
#pragma omp parallel for schedule(dynamic, 64)
    for (long r = 0; r < (long)c->R->n; r++)
        open_area(c, (uint32_t)r, O);
    columns_down(c, c->top, 0.0, 1, d, O, D);
    free(tk);
    free(d);
    return 0;
}

/* The column scale for the current B: what the links deliver of the
 * leaves' light (B over their open areas) is scaled to what rays from the
 * leaves say lands on surfaces (hel.land), where nearly
 * all of it does (CS_OPEN): there the rays' share is 1 but for a few
 * leaves, and exact, while the links lose (or make) a fraction of a
 * percent where they read a source or a receiver at mixed levels of its
 * tree (notes/radiosity.md, "The column scale"). In an open scene 16 rays
 * per leaf estimate the share too loosely (Cornell: 0.2 % against what the
 * links get right to 0.01 %; a lamp over a board: 15 %). Per channel;
 * summed over CS_BLOCKS runs of elements in parallel, the blocks' sums then
 * in order: the same bits for any thread count. */
#define CS_OPEN 0.01
#define CS_BLOCKS 256 /* partial sums over this many runs of elements: the same sums for any thread count */
static rr_rgb column_scale(const hctx *c, const double *D)
{
    double land[3] = {0, 0, 0}, sent[3] = {0, 0, 0}, all[3] = {0, 0, 0}, part[CS_BLOCKS][9];
    size_t per = (c->nel + CS_BLOCKS - 1) / CS_BLOCKS;
    memset(part, 0, sizeof part);
#pragma omp parallel for schedule(static)
    for (long b = 0; b < CS_BLOCKS; b++) {
        size_t end = (size_t)(b + 1) * per < c->nel ? (size_t)(b + 1) * per : c->nel;
        for (size_t i = (size_t)b * per; i < end; i++) {
            const hel *e = &c->el[i];
            if (e->child != NONE || !(e->open > 0))
                continue;
            /* a leaf with open area but no open fixed point shot no
             * closedness ray: counted as landing (leaving it out, room.json's
             * window pane under its glazing bars sent 0.5 of its 0.38 of
             * power uncounted) */
            double w = e->area * e->open, l = e->land < 0.0f ? 1.0 : e->land;
            const double r[3] = {e->B.r, e->B.g, e->B.b};
            for (int k = 0; k < 3; k++) {
                part[b][k] += w * r[k];
                part[b][3 + k] += w * r[k] * l;
                part[b][6 + k] += w * r[k] * D[i];
            }
        }
    }
    for (int b = 0; b < CS_BLOCKS; b++) /* in block order */
        for (int k = 0; k < 3; k++) {
            all[k] += part[b][k];
            land[k] += part[b][3 + k];
            sent[k] += part[b][6 + k];
        }
    double f[3];
    for (int k = 0; k < 3; k++)
        f[k] = all[k] > 0 && sent[k] > 0 && land[k] >= (1.0 - CS_OPEN) * all[k] ? land[k] / sent[k] : 1.0;
    return rr_rgb_make(f[0], f[1], f[2]);
}

/* r appended to st's history (the --plot of the last solve); -1 when out
 * of memory. */
static int add_history(rad_solve_stats *st, double r)
{
    if ((st->nhistory & (st->nhistory - 1)) == 0) { /* 0, 1, 2, 4, ...: grown at powers of two */
        double *h = realloc(st->history, (size_t)(st->nhistory ? 2 * st->nhistory : 1) * sizeof *h);
        if (!h)
            return -1;
        st->history = h;
    }
    st->history[st->nhistory++] = r;
    return 0;
}

#define EXTRAPOLATE_MAX 0.99 /* no extrapolation where the error decays slower than this per two sweeps */

/* Row sums (k), then Jacobi sweeps to the tolerance. */
rr_status rad__hier_solve(hctx *c, const rad_solve_opts *so, rad_solve_stats *st, rr_error *err)
{
    if (rad__hier_sort_links(c) != 0 || reserve_sources(c) != 0)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    size_t ngrp;
    size_t *grp = rad__hier_groups(c, &ngrp, 1);
    if (!grp)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    rad__hier_sources(c, 1, 0);
    rad__hier_gather(c, grp, ngrp);
    rad__hier_push(c, PUSH_SIGMA);
    double *D = malloc((c->nel ? c->nel : 1) * sizeof *D);
    if (!D || column_sums(c, grp, ngrp, D) != 0) {
        free(D);
        free(grp);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    int maxit = so->max_iterations > 0 ? so->max_iterations : 10000;
    double tol = so->tolerance > 0 ? so->tolerance : RAD_HIER_TOLERANCE;
    /* Two sweeps' history: the leaves' B before the last sweep and before
     * the one before (Bh[it % 2] holds B_{it - 1} during sweep it). */
    rr_rgb *Bh = malloc(2 * (c->nel ? c->nel : 1) * sizeof *Bh);
    if (!Bh) {
        free(D);
        free(grp);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    st->iterations = 0;
    st->tolerance = tol;
    free(st->history); /* the last solve's sweeps are the ones plotted */
    st->history = NULL;
    st->nhistory = 0;
    double dh[4] = {0, 0, 0, 0}; /* the last four sweeps' largest changes, newest last */
    int since = 0;
    for (int it = 0; it < maxit; it++) {
        if (interrupted(c)) {
            free(D);
            free(Bh);
            free(grp);
            return rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (solve)", c->s->path);
        }
        rr_rgb *Bprev = Bh + (size_t)(it % 2) * c->nel;
#pragma omp parallel for schedule(static)
        for (long i = 0; i < (long)c->nel; i++)
            Bprev[i] = c->el[i].B;
        c->cs = c->capped || c->eps > c->eps_asked ? rr_rgb_make(1, 1, 1) : column_scale(c, D);
        sources(c, 0, 0, 1);
        rad__hier_gather(c, grp, ngrp);
        double d = rad__hier_push(c, PUSH_SOLVE), bmax = leaves_max_B(c);
        st->iterations = it + 1;
        st->residual = bmax > 0 ? d / bmax : 0.0;
        if (add_history(st, st->residual) != 0) {
            free(D);
            free(Bh);
            free(grp);
            return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
        }
        if (!isfinite(st->residual) || !isfinite(bmax)) {
            /* a transport that creates light diverges: say so, at once,
             * instead of sweeping to the iteration limit */
            free(D);
            free(Bh);
            free(grp);
            return rr_error_set(err, RR_ERR_INTERNAL,
                                "%s: radiosity: the hierarchical solve diverged at sweep %d (largest radiosity %g); "
                                "use radiosity.method \"flat\"",
                                c->s->path, it + 1, bmax);
        }
        /* the largest change against the largest B, and in the last solve
         * the change's power against the emitted (RAD_HIER_TOLERANCE; the
         * rounds' solves only guide the refinement) */
        if (st->residual < tol &&
            (!c->last_solve || leaves_change_power(c, Bprev) <= RAD_HIER_POWER_SHARE * tol * c->power))
            break;
        memmove(dh, dh + 1, 3 * sizeof *dh);
        dh[3] = d;
        if (++since < 4)
            continue;
        /* The error's decay over two sweeps, twice: where it holds steady,
         * its slowest modes (eigenvalues +-l, which Jacobi's largest change
         * shows as alternating ratios) shrink by q = l^2 per two sweeps, and
         * B_n + q / (1 - q) (B_n - B_{n-2}) removes them. */
        double q = dh[2] > 0 ? dh[3] / dh[1] : 0.0, q1 = dh[0] > 0 ? dh[2] / dh[0] : 0.0;
        if (!(q > 0 && q < EXTRAPOLATE_MAX && fabs(q - q1) < 0.02 * q))
            continue;
        double f = q / (1.0 - q);
        const rr_rgb *B2 = Bh + (size_t)((it + 1) % 2) * c->nel; /* B_{it - 2}, from sweep it - 1's start */
#pragma omp parallel for schedule(static)
        for (long i = 0; i < (long)c->nel; i++) {
            hel *e = &c->el[i];
            if (e->child == NONE)
                e->B = rr_rgb_add(e->B, rr_rgb_scale(rr_rgb_add(e->B, rr_rgb_scale(B2[i], -1.0)), f));
        }
        since = 0;
    }
    if (st->iterations > 0)
        pull_all(c, 0); /* the clusters' buckets and centroids of the last sweep's sources */
    free(D);
    free(Bh);
    free(grp);
    return RR_OK;
}

/* ---- output: the leaves as a patch set, their values ---- */

/* The leaves as sol's patch set (roots: the root patches, owned from here
 * on), their B, and the gathers the ledger and the hybrid read. */
rr_status rad__hier_output(hctx *c, rad_patches *roots, rad_solution *sol, rr_error *err)
{
    /* Split bits in breadth-first order (rad__hier_leaves), and the leaf
     * elements in the order it numbers the leaves. */
    size_t n = c->nel;
    uint32_t *q = malloc((n ? n : 1) * sizeof *q), *leaf = malloc((n ? n : 1) * sizeof *leaf);
    rad_split_bits bits = {malloc(n ? n : 1), 0};
    if (!q || !leaf || !bits.bit) {
        free(q);
        free(leaf);
        free(bits.bit);
        rad_patches_destroy(roots);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    size_t tail = 0, nleaf = 0;
    for (size_t r = 0; r < c->R->n; r++)
        q[tail++] = (uint32_t)r;
    for (size_t head = 0; head < tail; head++) {
        const hel *e = &c->el[q[head]];
        bits.bit[bits.n++] = e->child != NONE;
        if (e->child == NONE)
            leaf[nleaf++] = q[head];
        else
            for (uint32_t k = 0; k < 4; k++)
                q[tail++] = e->child + k;
    }
    free(q);
    rr_status st = rad__hier_leaves(roots, &bits, &sol->P, err);
    free(bits.bit);
    if (st != RR_OK) {
        free(leaf);
        return st;
    }
    RR_CHECK(sol->P->n == nleaf);
    sol->hier_H = malloc((nleaf ? nleaf : 1) * sizeof *sol->hier_H);
    sol->hier_fsum = malloc((nleaf ? nleaf : 1) * sizeof *sol->hier_fsum);
    rr_rgb *Hind = malloc((nleaf ? nleaf : 1) * sizeof *Hind);
    if (rad__solution_arrays(sol) != 0 || !sol->hier_H || !sol->hier_fsum || !Hind) {
        free(leaf);
        free(Hind);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    if ((st = rad__first_shots(c->s, c->a, sol, err)) != RR_OK) {
        free(leaf);
        free(Hind);
        return st;
    }
    /* A leaf's area is its open part's, as in the flat pass (rad_pass.c):
     * the ledger, the vertex means and the display weigh what can be seen. */
    for (size_t i = 0; i < nleaf; i++) {
        sol->B[i] = c->el[leaf[i]].B;
        sol->P->p[i].area *= c->el[leaf[i]].open;
    }
    /* The gathers the ledger and the hybrid read: all that arrives (B), what
     * arrives after a reflection (B - E), and the row sums (B = 1). */
    size_t ngrp;
    size_t *grp = rad__hier_groups(c, &ngrp, 0); /* the last solve's buckets */
    if (!grp) {
        free(leaf);
        free(Hind);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    rad__hier_sources(c, 0, 0);
    rad__hier_gather(c, grp, ngrp);
    rad__hier_push(c, PUSH_KEEP);
    for (size_t i = 0; i < nleaf; i++)
        sol->hier_H[i] = c->el[leaf[i]].H;
    rad__hier_sources(c, 0, 1);
    rad__hier_gather(c, grp, ngrp);
    rad__hier_push(c, PUSH_KEEP);
    for (size_t i = 0; i < nleaf; i++)
        Hind[i] = c->el[leaf[i]].H;
    /* The ledger's escaped column, B A (1 - fsum) (A its open area): fsum,
     * the share of a leaf's B that its links deliver, cs D (column_sums:
     * the total is the gather's; read from each leaf's own row sum, the
     * ledger balanced only where the links are reciprocal, which they are
     * not: Cornell 7.8e-4 off, a closed room with a lamp of reflectance 0
     * 2.6 %). */
    double *D = malloc((c->nel ? c->nel : 1) * sizeof *D);
    if (!D || column_sums(c, grp, ngrp, D) != 0) {
        free(D);
        free(grp);
        free(leaf);
        free(Hind);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
    }
    free(grp);
    for (size_t i = 0; i < nleaf; i++) {
        const hel *e = &c->el[leaf[i]];
        sol->hier_fsum[i] = e->open > 0 ? rr_rgb_scale(c->cs, D[leaf[i]]) : rr_rgb_make(0, 0, 0);
    }
    free(D);
    free(leaf);
    st = rad__to_vertices(sol->P, sol->B, RAD_HIND_SWEEPS, sol->vertex_B) != RR_OK ||
                 rad__to_vertices(sol->P, Hind, RAD_HIND_SWEEPS, sol->vertex_Hind) != RR_OK
             ? rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path)
             : RR_OK;
    free(Hind);
    return st;
}
