/* rad_hier_rlc.c - the receiving leaf clusters: which they are
 * (rad__hier_mark_rlc), what their tables hold, and their side of the
 * hierarchical pass's solve (rad_hier.c, "Receiving leaf clusters"; their
 * links' evaluation is rad_hier_cluster.c's rad__hier_eval_rlc).
 *
 * A receiving leaf cluster x's links in each direction bucket (the cube
 * face the direction to the source points to, in four by the signs of the
 * other two components: rlc_dir_bucket, 24) are read by every root under
 * x as one source in the direction d_b of the sum of their light (sum v u /
 * |sum v u|, v = link_g times what the source sent as the solve started, by
 * geometry alone where the sources are dark), with the spread m_b = |sum v
 * u| / sum v: a root of normal n takes of the bucket's light S_b (the links'
 * irradiance for a surface facing their sources) the share w_b(n) = m_b
 * max(0, n . d_b) + (1 - m_b) (1 - |n . d_b|) / 2 (the spread's part as
 * nbf_proj spreads a curved bucket's shortfall). Linear in the sources
 * within a solve, so what x's roots take in of a bucket's unit irradiance,
 * sum A w_b, is what the links deliver: the ledger balances (column_sums).
 * d_b, m_b and that take are made at each solve's start
 * (rad__hier_rlc_prepare, from rad__hier_groups); by geometry alone, the
 * bunny in the middle of the 8-bunny room came out 12.7 % dark (a lamp's
 * direction read as its dim ceiling's). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"

typedef struct rlc_geo {
    float d[RLC_BUCKETS]; /* d_b, packed (dir_pack): the 1M room holds one per receiving cluster node */
    float m[RLC_BUCKETS];
    float k[RLC_BUCKETS]; /* take / take_o (rlc_take): what a root's share by its openness is scaled by; 0: not by it */
    double take[RLC_BUCKETS];
} rlc_geo;

/* Per root in the walk's order (hctx.rn): its normal and its openness
 * (rlc_open; 1 for roots under no receiving cluster). */
struct rlc_root {
    rr_vec3 n;
    double o;
};

static double rlc_w(const float d[3], double m, rr_vec3 n)
{
    double c = n.x * d[0] + n.y * d[1] + n.z * d[2];
    return m * (c > 0 ? c : 0.0) + 0.5 * (1.0 - m) * (1.0 - fabs(c));
}

/* What the roots under x (from position p on: hctx.rdfs) take of the unit
 * irradiance of each of the nb buckets (direction d[i], spread m[i]),
 * added to take[i], as the ledger counts it: by their open area (a root
 * partly buried, the bottom of a bunny standing in a thin gap over the
 * floor, absorbs over that alone); take_o[i] the same by their openness.
 * One walk for all the buckets; returns the position after x's roots. */
static size_t rlc_take(const hctx *c, uint32_t x, const float (*d)[3], const float *m, int nb, double *take,
                       double *take_o, size_t p)
{
    if (x & CLB) {
        p = rlc_take(c, c->cf[CL(x)].child[0], d, m, nb, take, take_o, p);
        return rlc_take(c, c->cf[CL(x)].child[1], d, m, nb, take, take_o, p);
    }
    double a = node_uarea(c, x) * c->el[x].open;
    const struct rlc_root *t = &c->rn[p];
    RR_CHECK(c->rdfs[p] == x);
    for (int i = 0; i < nb; i++) {
        double w = a * rlc_w(d[i], m[i], t->n);
        take[i] += w;
        take_o[i] += w * t->o;
    }
    return p + 1;
}

/* The openness of root x, under a receiving leaf cluster (under[y]: root y
 * is under one): the share of RLC_OPEN_RAYS cosine-drawn directions from
 * its centre that do not meet a root under a receiving cluster within
 * RLC_OPEN_REACH of their radius. A
 * cluster's link reads its visibility at points of the roots that face the
 * source, averaged; its roots then share what it brings by their openness
 * as well as by their normals, so that the inside of a vase (its walls face
 * in, seen by the room only through its neck) does not take the light its
 * outside sees: by normals alone, interior.py's vase's inner wall took in
 * 1.7 times the light tracer's count, its outer wall 5 % short. Any
 * receiving cluster's roots, not only x's top's: a vase is cut into several
 * tops, and a plant's stems are shaded by its leaves, another object's.
 * Large surfaces (a floor under a bunny) do not count: what they send is
 * light from that side, not shade. RLC_OPEN_FIRST directions first (2 x 4
 * strata of the cosine disc): where all leave (most roots of a convex
 * object) it is 1, else 24 more (4 x 6). The same directions for every
 * root: neighbours that see alike read alike, no noise from root to root. */
#define RLC_OPEN_LEAST 1e-3 /* a bucket's take by openness under this share of its take: read by normals alone */
#define RLC_OPEN_REACH 2.0 /* x the receiving clusters' largest radius: how far a ray may meet a shade */
#define RLC_OPEN_FIRST 8
#define RLC_OPEN_RAYS 32
static double rlc_open(const hctx *c, uint32_t x, const unsigned char *under)
{
    rr_vec3 xs, n;
    root_surface(c, x, c->rt[x].ctr, &xs, &n);
    double reach = RLC_OPEN_REACH * c->rlc_radius;
    int open = 0;
    for (int i = 0; i < RLC_OPEN_RAYS; i++) {
        if (i == RLC_OPEN_FIRST && open == i)
            return 1.0;
        int nu = i < RLC_OPEN_FIRST ? 2 : 4, j = i < RLC_OPEN_FIRST ? i : i - RLC_OPEN_FIRST;
        int nv = i < RLC_OPEN_FIRST ? 4 : 6;
        rr_vec3 dir = rt_cosine_dir(n, (j % nu + 0.5) / nu, (j / nu + 0.5) / nv);
        rr_ray ray = {rt_offset_origin(c->ext, xs, n, dir), dir};
        rt_hit h;
        int self = 0;
        if (rt_accel_closest_two_sided(c->a, ray, 0.0, reach, &h)) {
            uint32_t q = rad_patch_locate(c->R, c->s, h.tri, h.object, rr_ray_at(ray, h.t));
            self = q < c->R->n && under[q];
        }
        open += !self;
    }
    return open / (double)RLC_OPEN_RAYS;
}

/* c->rdfs, rpos, rn (hctx), and room for rH and rf: a walk down a
 * receiving cluster then reads and writes along these arrays, where by the
 * roots' own numbers each root's normal and light were a cache miss (a
 * third of rlc_push's samples in the 81-bunny room). The openness of the
 * roots under receiving clusters (rlc_open), in parallel. -1 when out of
 * memory, 1 when interrupted. */
static int rlc_order(hctx *c)
{
    size_t nr = c->R->n, p = 0, top = 0;
    uint32_t *stack = malloc((c->ncl + 2) * 2 * sizeof *stack);
    unsigned char *under = malloc(nr ? nr : 1);
    c->rdfs = malloc((nr ? nr : 1) * sizeof *c->rdfs);
    c->rpos = malloc((c->ncl ? c->ncl : 1) * sizeof *c->rpos);
    c->rn = malloc((nr ? nr : 1) * sizeof *c->rn);
    c->rH = malloc((nr ? nr : 1) * sizeof *c->rH);
    c->rf = malloc(nr ? nr : 1);
    if (!stack || !under || !c->rdfs || !c->rpos || !c->rn || !c->rH || !c->rf) {
        free(stack);
        free(under);
        free(c->rdfs);
        free(c->rpos);
        free(c->rn);
        free(c->rH);
        free(c->rf);
        c->rdfs = c->rpos = NULL;
        c->rn = NULL;
        c->rH = NULL;
        c->rf = NULL;
        return -1;
    }
    stack[top++] = c->top; /* pairs: the node, 1 where a receiving cluster is above it or is it */
    stack[top++] = 0;
    while (top > 0) {
        uint32_t t = stack[--top], x = stack[--top];
        if (!(x & CLB)) {
            c->rdfs[p] = x;
            under[x] = (unsigned char)t;
            c->rn[p++].n = c->rt[x].n;
            continue;
        }
        t = t || c->rlc[CL(x)] == 2;
        c->rpos[CL(x)] = (uint32_t)p;
        stack[top++] = c->cf[CL(x)].child[1];
        stack[top++] = t;
        stack[top++] = c->cf[CL(x)].child[0]; /* first */
        stack[top++] = t;
    }
    free(stack);
    RR_CHECK(p == nr);
#pragma omp parallel
    {
        rt_ray_counts before = rt_ray_counts_of_thread();
#pragma omp for schedule(dynamic, 256)
        for (long q = 0; q < (long)nr; q++) {
            uint32_t x = c->rdfs[q];
            c->rn[q].o = !under[x] || interrupted(c) ? 1.0 : rlc_open(c, x, under);
        }
        rt_ray_counts_add_since(&c->rays, before);
    }
    free(under);
    return interrupted(c) ? 1 : 0;
}

/* Whether every root under x is too small to split (and no mirror); marks
 * rlc[k] = 1 for the clusters of such roots within the radius. */
static int rlc_small(hctx *c, uint32_t x, double radius)
{
    if (!(x & CLB))
        return !splittable(c, x) && !(c->R->p[c->el[x].root].mirror > 0);
    const hcl *k = &c->cl[CL(x)];
    int a = rlc_small(c, k->child[0], radius), b = rlc_small(c, k->child[1], radius);
    c->rlc[CL(x)] = a && b && k->radius <= radius;
    return a && b;
}

/* The highest of them marked 2 (rlc_top: the gather's walks start there). */
static void rlc_top(hctx *c, uint32_t x, int above)
{
    if (!(x & CLB))
        return;
    int here = c->rlc[CL(x)] != 0;
    if (here && !above)
        c->rlc[CL(x)] = 2;
    rlc_top(c, c->cl[CL(x)].child[0], above || here);
    rlc_top(c, c->cl[CL(x)].child[1], above || here);
}

int rad__hier_mark_rlc(hctx *c, double radius)
{
    free(c->rlc);
    c->rlc = calloc(c->ncl ? c->ncl : 1, 1);
    c->nrlc = 0;
    if (!c->rlc)
        return -1;
    rlc_small(c, c->top, radius);
    rlc_top(c, c->top, 0);
    for (size_t i = 0; i < c->ncl; i++)
        c->nrlc += c->rlc[i] == 2;
    if (c->nrlc == 0) {
        free(c->rlc);
        c->rlc = NULL;
    }
    c->rlc_bytes = rad__hier_rlc_bytes(c);
    return 0;
}

double rad__hier_rlc_bytes(const hctx *c)
{
    if (!c->rlc)
        return 0.0;
    size_t marked = 0;
    for (size_t k = 0; k < c->ncl; k++)
        marked += c->rlc[k] != 0;
    double per_cluster = 1.0 + (double)(sizeof *c->rgi + sizeof *c->rpos);
    double per_root = (double)(sizeof *c->rdfs + sizeof *c->rn + sizeof *c->rH + sizeof *c->rf) + 1.0; /* + under */
    return (double)marked * (double)sizeof(rlc_geo) + (double)c->ncl * per_cluster + (double)c->R->n * per_root;
}

int rad__hier_rlc_prepare(hctx *c, const size_t *grp, size_t ngrp)
{
    free(c->rg);
    c->rg = NULL;
    size_t g0 = ngrp;
    while (g0 > 0 && (c->ln[grp[g0 - 1]].r & CLB))
        g0--;
    c->rg0 = g0;
    if (!c->rgi && !(c->rgi = malloc((c->ncl ? c->ncl : 1) * sizeof *c->rgi)))
        return -1;
    int st;
    if (!c->rdfs && (st = rlc_order(c)) != 0)
        return st < 0 ? -1 : 0; /* interrupted: the caller sees it */
    for (size_t k = 0; k < c->ncl; k++)
        c->rgi[k] = NONE;
    if (g0 == ngrp)
        return 0;
    c->rg = malloc((ngrp - g0) * sizeof *c->rg);
    if (!c->rg)
        return -1;
    for (size_t g = g0; g < ngrp; g++)
        c->rgi[CL(c->ln[grp[g]].r)] = (uint32_t)(g - g0);
#pragma omp parallel for schedule(dynamic, 16)
    for (long g = (long)g0; g < (long)ngrp; g++) {
        rlc_geo *q = &c->rg[g - (long)g0];
        double V[RLC_BUCKETS][3] = {{0}}, S[RLC_BUCKETS] = {0};
        for (size_t j = grp[g]; j < grp[g + 1]; j++) {
            const hlink *l = &c->ln[j];
            rr_vec3 u = dir_unpack(l->dF);
            int b = rlc_bucket(l);
            /* by the light it brings as the sources now stand (a lamp's
             * direction, not its dim ceiling's), by geometry where they are dark */
            rr_rgb v = l->s & CLB ? c->cl[CL(l->s)].P : c->el[l->s].src;
            double w = (link_g(l) > 0 ? link_g(l) : link_ga(l)) * (v.r + v.g + v.b + 1e-30);
            V[b][0] += w * u.x;
            V[b][1] += w * u.y;
            V[b][2] += w * u.z;
            S[b] += w;
        }
        float d[RLC_BUCKETS][3], m[RLC_BUCKETS];
        double take[RLC_BUCKETS] = {0}, take_o[RLC_BUCKETS] = {0};
        int used[RLC_BUCKETS], nb = 0;
        for (int b = 0; b < RLC_BUCKETS; b++) {
            double L = sqrt(V[b][0] * V[b][0] + V[b][1] * V[b][1] + V[b][2] * V[b][2]);
            rr_vec3 u = L > 0 ? rr_v3_scale(rr_v3(V[b][0], V[b][1], V[b][2]), 1.0 / L) : rr_v3(0, 0, 1);
            q->d[b] = dir_pack(u);
            q->m[b] = S[b] > 0 ? (float)rr_min(1.0, L / S[b]) : 1.0f;
            q->take[b] = 0.0;
            q->k[b] = 0.0f;
            if (!(S[b] > 0))
                continue;
            u = dir_unpack(q->d[b]); /* the gather reads it so */
            d[nb][0] = (float)u.x;
            d[nb][1] = (float)u.y;
            d[nb][2] = (float)u.z;
            m[nb] = q->m[b];
            used[nb++] = b;
        }
        uint32_t r = c->ln[grp[g]].r;
        rlc_take(c, r, (const float(*)[3])d, m, nb, take, take_o, c->rpos[CL(r)]);
        for (int i = 0; i < nb; i++) { /* by openness where some of it is open (else by normals alone) */
            q->take[used[i]] = take[i];
            q->k[used[i]] = take_o[i] > RLC_OPEN_LEAST * take[i] ? (float)(take[i] / take_o[i]) : 0.0f;
        }
    }
    return 0;
}

/* Down from x: the buckets of its receiving ancestors' links (path[0 ..
 * np), their light S per channel), its own added, read by each root with
 * its normal. The sums in one order (the path from the top): the same bits
 * for any thread count. */
#define RLC_DEPTH 64 /* receiving leaf clusters nested on one path, at most (a cluster tree's depth) */
typedef struct rlc_step {
    int nb; /* the buckets that bring light, in order: their direction, spread, openness scale and light */
    float d[RLC_BUCKETS][3], m[RLC_BUCKETS], k[RLC_BUCKETS];
    double S[RLC_BUCKETS][3];
} rlc_step;

static size_t rlc_push(hctx *c, uint32_t x, rlc_step *path, int np, const size_t *grp, size_t p)
{
    if (!(x & CLB)) { /* a root, at position p */
        if (np == 0)
            return p + 1;
        rr_vec3 n = c->rn[p].n;
        double o = c->rn[p].o, H[3] = {0, 0, 0};
        for (int k = 0; k < np; k++)
            for (int i = 0; i < path[k].nb; i++) {
                float ks = path[k].k[i];
                double w = rlc_w(path[k].d[i], path[k].m[i], n) * (ks > 0 ? ks * o : 1.0);
                for (int ch = 0; ch < 3; ch++)
                    H[ch] += w * path[k].S[i][ch];
            }
        c->rH[p] = rr_rgb_make(H[0], H[1], H[2]);
        c->rf[p] = 1;
        return p + 1;
    }
    uint32_t gi = c->rgi[CL(x)];
    if (gi != NONE) {
        size_t g = c->rg0 + gi;
        RR_CHECK(np < RLC_DEPTH);
        rlc_step *st = &path[np++];
        const rlc_geo *q = &c->rg[gi];
        double S[RLC_BUCKETS][3];
        memset(S, 0, sizeof S);
        for (size_t j = grp[g]; j < grp[g + 1]; j++) {
            const hlink *l = &c->ln[j];
            rr_rgb v = link_light(c, l);
            int b = rlc_bucket(l);
            S[b][0] += v.r;
            S[b][1] += v.g;
            S[b][2] += v.b;
        }
        st->nb = 0;
        for (int b = 0; b < RLC_BUCKETS; b++) {
            if (!(S[b][0] > 0 || S[b][1] > 0 || S[b][2] > 0))
                continue;
            rr_vec3 u = dir_unpack(q->d[b]);
            int i = st->nb++;
            st->d[i][0] = (float)u.x;
            st->d[i][1] = (float)u.y;
            st->d[i][2] = (float)u.z;
            st->m[i] = q->m[b];
            st->k[i] = q->k[b];
            memcpy(st->S[i], S[b], sizeof S[b]);
        }
    }
    const hcf *f = &c->cf[CL(x)];
    p = rlc_push(c, f->child[0], path, np, grp, p);
    return rlc_push(c, f->child[1], path, np, grp, p);
}

void rad__hier_rlc_gather(hctx *c, const size_t *grp)
{
    long nr = (long)c->R->n;
    memset(c->rf, 0, (size_t)nr);
#pragma omp parallel for schedule(dynamic, 16)
    for (long k = 0; k < (long)c->ncl; k++) {
        if (c->rlc[k] != 2)
            continue;
        rlc_step path[RLC_DEPTH];
        rlc_push(c, CLB | (uint32_t)k, path, 0, grp, c->rpos[k]);
    }
    /* added to the elements after the walks, in parallel */
#pragma omp parallel for schedule(static)
    for (long p = 0; p < nr; p++) {
        if (!c->rf[p])
            continue;
        hel *e = &c->el[c->rdfs[p]];
        e->H = rr_rgb_add(e->H, c->rH[p]);
        if (c->unit)
            e->partial = 1; /* no row-sum scale: the buckets' reading is not the quadrature it corrects */
    }
}

double rad__hier_rlc_take(const hctx *c, size_t gi, const hlink *l) { return c->rg[gi].take[rlc_bucket(l)]; }
