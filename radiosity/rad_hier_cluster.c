/* rad_hier_cluster.c - the clusters of the hierarchical pass (rad_hier.c):
 * their bounding-volume hierarchy over the roots, what a cluster shows and
 * sends towards a direction (by normal buckets), the shadow rays
 * between an element and a cluster, and the geometry of a link from a
 * cluster (rad_hier.c's header has the formulas and why). */
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"

/* Node x's area as seen from direction u (towards the viewer): what a
 * cluster shows of itself that way, by its normal buckets (nbuckets), an
 * element's exactly, both by node_uarea (a mirror's share left out: its
 * light goes on by way of it). These two weigh a shadow ray's draw (node_sample) only,
 * so they leave out a curved bucket's shortfall: the draw needs to favour
 * what faces u, and the square roots cost the 8-bunny room 16 % of its
 * pass. */
static double node_proj_area(const hctx *c, uint32_t x, rr_vec3 u)
{
    if (x & CLB) {
        const hcf *f = &c->cf[CL(x)];
        return nbf_proj(f->Av, f->As, (f->mask >> 7) & 63u, u, 1);
    }
    const hroot *t = &c->rt[x]; /* a root (the cluster tree's leaves are the roots) */
    return rr_max(0.0, rr_v3_dot(t->n, u)) * (t->area * t->om); /* fmax is a libm call here */
}

/* The power node x sends towards u (by its current sources, all channels):
 * what a cluster's shadow rays are drawn by, so that its visibility is that
 * of its power. */
static double node_proj_power(const hctx *c, uint32_t x, rr_vec3 u)
{
    if (x & CLB) {
        const hcf *f = &c->cf[CL(x)];
        return nbf_proj(f->Dv, f->Ds, (f->mask >> 1) & 63u, u, 1);
    }
    const hroot *t = &c->rt[x]; /* a root */
    return rr_max(0.0, rr_v3_dot(t->n, u)) * t->area * t->ssum;
}

/* Node x's area (node_uarea) by normal bucket, added to nb. */
static void node_area_nb(const hctx *c, uint32_t x, nbuckets *nb)
{
    if (x & CLB)
        nb_add(nb, &c->cl[CL(x)].An);
    else
        nb_add_surface(nb, el_normal(c, x), node_uarea(c, x));
}

typedef struct ritem {
    uint32_t e;
    double key;
} ritem;

static int cmp_ritem(const void *a, const void *b)
{
    const ritem *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->e < y->e ? -1 : (x->e > y->e);
}

static int ritem_less(const ritem *x, const ritem *y) { return cmp_ritem(x, y) < 0; }

static void ritem_swap(ritem *a, ritem *b)
{
    ritem t = *a;
    *a = *b;
    *b = t;
}

/* Puts the k smallest items (by key, then element: a total order) in
 * it[0..k) and the rest after them: a quickselect with a median-of-three
 * pivot, O(n) on average. The halves are the same sets that a full sort
 * gave, so the same tree; sorting every level took O(n log^2 n), seconds
 * for the 1M-triangle room's roots, with no place to stop for Ctrl-C. */
static void ritem_select(ritem *it, size_t n, size_t k)
{
    size_t lo = 0, hi = n; /* the k-th lies in [lo, hi) */
    while (hi - lo > 2) {
        size_t mid = lo + (hi - lo) / 2;
        if (ritem_less(&it[mid], &it[lo]))
            ritem_swap(&it[mid], &it[lo]);
        if (ritem_less(&it[hi - 1], &it[lo]))
            ritem_swap(&it[hi - 1], &it[lo]);
        if (ritem_less(&it[hi - 1], &it[mid]))
            ritem_swap(&it[hi - 1], &it[mid]);
        ritem pivot = it[mid];
        /* Hoare partition of [lo, hi) around the pivot (distinct items) */
        size_t i = lo, j = hi - 1;
        for (;;) {
            while (ritem_less(&it[i], &pivot))
                i++;
            while (ritem_less(&pivot, &it[j]))
                j--;
            if (i >= j)
                break;
            ritem_swap(&it[i], &it[j]);
            i++;
            j--;
        }
        /* [lo, j] <= pivot <= [j + 1, hi) */
        if (k <= j)
            hi = j + 1;
        else
            lo = j + 1;
    }
    if (hi - lo == 2 && ritem_less(&it[lo + 1], &it[lo]))
        ritem_swap(&it[lo], &it[lo + 1]);
}

/* The cluster tree over the roots it[0 .. n), its top numbered id and the
 * rest in depth-first order (a subtree of m roots holds m - 1 clusters, so
 * the second child's number is id + n / 2 whatever builds the first), the
 * halves of large nodes as tasks: the same tree for any thread count. */
#define CLUSTER_TASK 32768 /* roots below which a node's halves are built on one thread */
static uint32_t cluster_build(hctx *c, ritem *it, size_t n, uint32_t id)
{
    if (n == 1)
        return it[0].e;
    if (n >= 4096 && interrupted(c))
        return NONE; /* the caller says interrupted */
    rr_vec3 lo = rr_v3(INFINITY, INFINITY, INFINITY), hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            lo = rr_v3_min(lo, c->el[it[i].e].c[k]);
            hi = rr_v3_max(hi, c->el[it[i].e].c[k]);
        }
    rr_vec3 d = rr_v3_sub(hi, lo);
    int axis = d.x >= d.y && d.x >= d.z ? 0 : (d.y >= d.z ? 1 : 2);
    for (size_t i = 0; i < n; i++) {
        rr_vec3 m = c->el[it[i].e].ctr;
        it[i].key = axis == 0 ? m.x : (axis == 1 ? m.y : m.z);
    }
    ritem_select(it, n, n / 2);
    uint32_t a, b;
#pragma omp task shared(a) if (n >= CLUSTER_TASK)
    a = cluster_build(c, it, n / 2, id + 1);
    b = cluster_build(c, it + n / 2, n - n / 2, id + (uint32_t)(n / 2));
#pragma omp taskwait
    if (a == NONE || b == NONE)
        return NONE;
    hcl *k = &c->cl[id];
    k->lo = lo;
    k->hi = hi;
    k->ctr = rr_v3_scale(rr_v3_add(lo, hi), 0.5);
    k->radius = 0.5 * rr_v3_len(d);
    k->child[0] = a;
    k->child[1] = b;
    k->area = node_area(c, a) + node_area(c, b);
    k->uarea = node_uarea(c, a) + node_uarea(c, b);
    rr_vec3 ca = a & CLB ? c->cl[CL(a)].ac : c->el[a].ctr, cb = b & CLB ? c->cl[CL(b)].ac : c->el[b].ctr;
    k->ac = k->uarea > 0 ? rr_v3_scale(rr_v3_add(rr_v3_scale(ca, node_uarea(c, a)), rr_v3_scale(cb, node_uarea(c, b))),
                                       1.0 / k->uarea)
                         : k->ctr;
    k->pc = k->ac;
    k->rho_max = fmax(node_rho(c, a), node_rho(c, b));
    memset(&k->An, 0, sizeof k->An);
    node_area_nb(c, a, &k->An);
    node_area_nb(c, b, &k->An);
    double m = 0.0;
    for (int q = 0; q < 6; q++)
        m += rr_v3_len(k->An.v[q]);
    k->flat = k->uarea > 0 ? m / k->uarea : 1.0;
    return id | CLB;
}

uint32_t rad__hier_clusters(hctx *c)
{
    size_t nr = c->R->n;
    ritem *it = malloc((nr ? nr : 1) * sizeof *it);
    if (!it || nr == 0) {
        free(it);
        return NONE;
    }
    for (size_t i = 0; i < nr; i++)
        it[i].e = (uint32_t)i;
    uint32_t top = NONE;
#pragma omp parallel
#pragma omp single
    top = cluster_build(c, it, nr, 0);
    c->ncl = nr - 1;
    free(it);
    return top;
}

/* ---- shadow rays ---- */

/* Whether cluster node x sends nothing at all: then neither do its
 * children (their sources are not negative), and a draw by power falls back
 * to area at every level below. */
static int cl_dark(const hctx *c, uint32_t x)
{
    rr_rgb P = c->cl[CL(x)].P;
    return !(P.r + P.g + P.b > 0);
}

/* A point on the surfaces of node x for a shadow ray: element points are the
 * element's fixed points (el_kpt) when fixed, else random. A cluster's come from a
 * root drawn, level by level, by the power it sends towards u
 * (node_proj_power) when by_power, else by the area it shows that way
 * (node_proj_area; surfaces facing away, whose share the cluster's intensity
 * already leaves out, are not drawn: drawn by plain area, a solid block's far
 * faces halved its light). xs on the true surface, ns its normal, *root its
 * element's root (when root is not NULL). Returns
 * whether a random point lies on a buried part of its element. */
static int node_sample(const hctx *c, uint32_t x, int k, int fixed, int by_power, rr_vec3 u, rr_rng *rng,
                       rr_vec3 *xs, rr_vec3 *ns, uint32_t *root)
{
    if (by_power && (x & CLB) && cl_dark(c, x))
        by_power = 0; /* the same draws, without the power's projections */
    while (x & CLB) {
        const hcf *q = &c->cf[CL(x)];
        double a0 = 0.0, a1 = 0.0;
        if (by_power) {
            a0 = node_proj_power(c, q->child[0], u);
            a1 = node_proj_power(c, q->child[1], u);
            if (!(a0 + a1 > 0) && cl_dark(c, x))
                by_power = 0;
        }
        if (!(a0 + a1 > 0)) { /* no power towards u (or by area): by the area shown */
            a0 = node_proj_area(c, q->child[0], u);
            a1 = node_proj_area(c, q->child[1], u);
        }
        if (!(a0 + a1 > 0)) { /* nothing faces u: by area */
            a0 = node_area(c, q->child[0]);
            a1 = c->cl[CL(x)].area - a0;
        }
        x = rr_rng_uniform(rng) * (a0 + a1) < a0 ? q->child[0] : q->child[1];
    }
    const hel *e = &c->el[x];
    double b[3];
    if (fixed)
        el_kpt(e, k, b);
    rr_vec3 p = fixed ? tri_at(e->c, b[0], b[1], b[2]) : tri_random(e->c, rng);
    root_surface(c, e->root, p, xs, ns);
    if (root)
        *root = e->root;
    return !fixed && e->open < 1.0 && rad__hier_buried(c, e, *xs, *ns);
}

/* Visibility between an element r and a cluster s by VIS_RAYS shadow rays
 * (counts added to what the arguments hold, zero on entry): pass[1], that of
 * s's power (what the link carries), of the 3 rays drawn by the power s
 * sends r; pass[0], that of its area (what the row sums, B = 1, read), of
 * the one drawn by the area s shows r; *partial when some of the rays passed
 * and some not. One estimate for both lost a
 * third of a room's lamp light (the ceiling above the lamp, hidden by it and
 * in its clusters, took half the area-drawn rays) or, by power alone, scaled
 * every leaf down 10 % (the row sums counted that hidden ceiling as seen).
 * Both from all rays (the balance heuristic) was unbiased per link but not
 * over the links kept, those whose rays all passed: room.json's floor +4 %;
 * with the split read from all rays, the row sums of the kept links came out
 * high. The rays start at r's open points; a ray that ends on a buried part
 * of s (rad__hier_buried) does not pass, but the partial-visibility split
 * reads only those to open parts: a cover's shadow does not move with r, and
 * re-drawing it for r's children kept mostly the links whose rays missed it
 * (a window pane under its glazing bars sent +7 %): *open_p power rays
 * ended in the open, *pass_p of them passed. */
/* Draws of a cluster's shadow-ray end until it lies on a surface facing the
 * receiver (visibility below). Measured (48 px, radiosity display against
 * the direct light): the floor under a sphere lamp -2.7 -> -0.1 % at the
 * default patch area, -12.3 -> -3.2 % at patch_area 0.0005, whose sphere has
 * ~100 facets in its clusters; the furnace room's mean 0.9927 -> 0.9948 (with
 * the six-direction split that the normal buckets replaced). */
#define BACK_DRAWS 4

/* Point y lies on way w's mirror: what a way's shadow ray must not end on,
 * as no light leaves the mirror by way of itself (drawn again, as an end
 * turned away is; without it the rays that the area draw put on a mirror
 * in the source cluster marked links partly visible, and their leaves lost
 * the row-sum scale: a furnace with a mirror face was 0.5 % off there). */
static int on_way_plane(const hctx *c, unsigned w, rr_vec3 y)
{
    if (!w)
        return 0;
    const himg *g = &c->img[w - 1];
    const hwin *m = &g->win[g->n - 1]; /* the mirror the light leaves the source for */
    return fabs(rr_v3_dot(m->n, y) - m->d) <= 1e-7 * c->ext;
}

/* A shadow ray's end y (normal ny) faces x; by way of a mirror, by more
 * than rounding (a face coplanar with x's image: its points come off the
 * true surface a hair to either side) and not on the mirror. */
static int end_faces(const hctx *c, unsigned w, rr_vec3 ny, rr_vec3 x, rr_vec3 y)
{
    rr_vec3 d = rr_v3_sub(x, y);
    if (!w)
        return rr_v3_dot(ny, d) > 0.0;
    return rr_v3_dot(ny, d) > 1e-9 * rr_v3_len(d) && !on_way_plane(c, w, y);
}

static void visibility(const hctx *c, const rview *rv, uint32_t r, uint32_t s, rr_rng *rng, int pass[2], int *open_p,
                       int *pass_p, int *partial)
{
    enum { NA = 1, NP = VIS_RAYS - 1 }; /* rays drawn by area, by power */
    int nopen = 0;
    if (open_pt(rv->e, 0) < 0)
        return; /* every fixed point of r is buried: it gathers nothing */
    rr_vec3 u = rr_v3_norm(rr_v3_sub(node_ctr(c, s), rv->ctr)); /* from r (as s sees it) towards s */
    for (int k = 0; k < NA + NP; k++) {
        int by_power = k >= NA;
        rr_vec3 xr, nxr, y, ny;
        uint32_t yroot;
        node_sample(c, r, open_pt(rv->e, k), 1, 0, u, rng, &xr, &nxr, NULL);
        rr_vec3 x = way_point(c, rv->way, xr), nx = way_dir(c, rv->way, nxr); /* as s sees it */
        /* A cluster's bucket can give power towards r to surfaces turned
         * away from it (a curved cluster's), and a walk that finds no child
         * facing r draws by area: an end on such a surface, behind the
         * source's own silhouette, is drawn again (BACK_DRAWS times at most) */
        int buried = 0;
        for (int t = 0; t < BACK_DRAWS; t++) {
            buried = node_sample(c, s, k % 4, 0, by_power, rr_v3_neg(u), rng, &y, &ny, &yroot);
            if (end_faces(c, rv->way, ny, x, y))
                break;
        }
        if (buried)
            continue; /* ends under a cover: blocked */
        if (rv->way && !end_faces(c, rv->way, ny, x, y)) {
            /* By way of a mirror, an end still turned away from r's image
             * (on a face coplanar with it, whose image is too) sends it
             * nothing: not a blocked path, and its ray would graze the
             * mirror's edge. Counted as passing, so that it does not mark
             * the link partly visible (a furnace with a mirror face lost
             * the row-sum scale on a quarter of its leaves). */
            pass[by_power]++;
            nopen++;
            *open_p += by_power;
            *pass_p += by_power;
            continue;
        }
        rad__hier_sphere_end(c, yroot, x, &y, &ny);
        int passed;
        if (rv->way) {
            passed = way_visible(c, rv->way, xr, nxr, y, ny);
        } else {
            rr_vec3 d = rr_v3_sub(y, x);
            rr_vec3 o = rt_offset_origin(c->ext, x, nx, d), t = rt_offset_origin(c->ext, y, ny, rr_v3_neg(d));
            rr_ray ray = {o, rr_v3_sub(t, o)};
            passed = !rt_accel_occluded(c->a, ray, 0.0, RT_SHADOW_END);
        }
        pass[by_power] += passed;
        nopen++;
        *open_p += by_power;
        *pass_p += by_power && passed;
    }
    *partial = pass[0] + pass[1] > 0 && pass[0] + pass[1] < nopen;
}

/* ---- geometry ---- */

/* cos_r / (d^2 + A / pi) from point x (normal nr) towards point p: nr.d /
 * (L (L^2 + A / pi)), one square root and one division. */
static double geo_term(rr_vec3 x, rr_vec3 nr, rr_vec3 p, double A)
{
    rr_vec3 d = rr_v3_sub(p, x);
    double L2 = rr_v3_len2(d), nd = rr_v3_dot(nr, d);
    return nd > 0.0 && L2 > 0.0 ? nd / (sqrt(L2) * (L2 + A / RR_PI)) : 0.0;
}

/* A cluster node's term cos_r I(u) / d^2 from x (normal nr) towards its
 * point p, I its buckets' projection towards u = (x - p) / |x - p| (power:
 * Dn; area: An); 0 behind x. Times pi (the caller divides once). The
 * projection of a flat node's buckets is linear in u, so that there
 * cos_r I(u) / d^2 = (nr.d) I(-d) / L^4, with no square root: the links'
 * geometry was 17 % of room.json's pass, mostly its square roots and
 * divisions. A curved bucket's shortfall reads the unit u. */
static inline double cl_term(const hcf *f, int area, rr_vec3 x, rr_vec3 nr, rr_vec3 p)
{
    rr_vec3 d = rr_v3_sub(p, x);
    double nd = rr_v3_dot(nr, d), L2 = rr_v3_len2(d);
    if (!(nd > 0.0) || !(L2 > 0.0))
        return 0.0;
    unsigned bits = (f->mask >> (area ? 7 : 1)) & 63u;
    const float(*v)[3] = area ? f->Av : f->Dv;
    const float *sb = area ? f->As : f->Ds;
    if (f->mask & 1u)
        return nd * nbf_proj(v, sb, bits, rr_v3_neg(d), 1) / (L2 * L2);
    double iL = 1.0 / sqrt(L2);
    return nd * iL * iL * iL * nbf_proj(v, sb, bits, rr_v3_scale(d, -iL), 0);
}

/* The transport of element r <- cluster s per unit of s's power, for s's
 * current sources (*geo) and for B = 1 (*geo_a, per unit of its area): the
 * irradiance at r's centre summed over s's nodes, each read at the centroid
 * of its power (of its area for B = 1) with the power (area) it turns
 * towards r, cos_r I_n / d^2 for a cluster node and cos_r I_n / (d^2 + A_n /
 * pi) for an element (A_n the area it shows r: a disc of that area seen on
 * its axis is exact, and near elements saturate as form factors do instead
 * of growing as 1 / d^2), scaled by the mean of that term over r's 4 points
 * against its centre. The nodes: s's tree CL_LEVELS levels down, and
 * further (up to CL_NODES) where a node is wide for its distance (radius >
 * CL_THETA d) or its sphere crosses r's plane. Measured against the exact
 * unoccluded irradiance at r's centre (the contour integral over every
 * element of s; every thousandth cluster link of room.json as a furnace,
 * receivers wholly open): the sum over those links was 2.0 % low with 3
 * levels and the disc on every node (4.5 % for nodes of radius 0.45 d, 5-10
 * % where they cross r's plane: a centroid below r's horizon reads 0 though
 * part of the node is above it); deeper nodes, 0.9 % low; no disc on
 * clusters, 0.5 % low. A cluster's surfaces spread in depth, where reading
 * 1 / d^2 at the centroid is itself low by about (R / d)^2: the disc's
 * saturation, of the same order, counted it twice. A root wide for its
 * distance or crossing r's plane is read by its polygon's point factor
 * instead (root_exact).
 * Read once at the centre of s's box instead, a lamp in a cluster with the
 * ceiling around it was read as if spread over the whole box, and moving
 * that one point within an admissible cluster moved a room's light by 10 %;
 * read as a share of s's intensity towards one point, a cluster of a floor
 * and a ceiling sent nothing to the floor beside it (-2.4 % on the floor of
 * two facing plates). *spread is how much the term towards s's power
 * centroid varies over r's corners against its centre (the uneven test).
 * Without area_too (the kept links' geometry read again, rad__hier_regeo)
 * only *geo and fk are computed (*geo_a too where s sends nothing, *geo
 * being it there): the same *geo, in about half the time. */
#define CL_LEVELS 3    /* levels of its tree that every cluster link reads */
#define CL_THETA 0.15  /* and deeper where a node's radius exceeds this share of its distance */
#define CL_NODES 32    /* the most nodes it reads */

/* The nodes cluster_geo reads of cluster s from point xr (normal nr): s's
 * tree CL_LEVELS levels down, and further (up to CL_NODES) where a node is
 * wide for its distance or its sphere crosses xr's plane. Returns how many
 * (fr[0 ..)). */
static int cluster_frontier(const hctx *c, uint32_t s, rr_vec3 xr, rr_vec3 nr, uint32_t fr[CL_NODES])
{
    fr[0] = s;
    int nf = 1;
    for (int lev = 0;; lev++) {
        uint32_t nx[CL_NODES];
        int nn = 0, grew = 0;
        for (int i = 0; i < nf; i++) {
            uint32_t n = fr[i];
            int wide = 0;
            if (n & CLB) {
                const hcf *f = &c->cf[CL(n)];
                rr_vec3 d = rr_v3_sub(cf_v3(f->ctr), xr);
                double R = f->radius;
                wide = lev < CL_LEVELS || R * R > CL_THETA * CL_THETA * rr_v3_len2(d) || fabs(rr_v3_dot(nr, d)) < R;
            }
            if (wide && nn + (nf - i) + 1 <= CL_NODES) {
                nx[nn++] = c->cf[CL(n)].child[0];
                nx[nn++] = c->cf[CL(n)].child[1];
                grew = 1;
            } else {
                nx[nn++] = n;
            }
        }
        memcpy(fr, nx, (size_t)nn * sizeof *nx);
        nf = nn;
        if (!grew)
            return nf;
    }
}

/* Whether a cluster's walk reads root n from point xr (normal nr) by the
 * point factor of its polygon's part in front of xr, as an element link
 * reads it (rad__hier_root_ff), rather than as a disc at its centroid: where
 * it is wide for its distance (radius over ROOT_THETA of it) or xr's plane
 * cuts its sphere. As a disc, a window pane's root 0.9 m from a leaf, cut
 * by the leaf's top's plane, was read a quarter short, and the leaf took in
 * 0.915 of the light tracer's count (notes/radiosity.md, "Roots in a
 * cluster's frontier"). Narrower roots keep the disc: its error falls as
 * the square of that ratio (room.json's pass: +7 % with every root read
 * exactly, +4.5 % so). */
#define ROOT_THETA 0.1
static int root_exact(const hctx *c, uint32_t n, rr_vec3 xr, rr_vec3 nr)
{
    rr_vec3 d = rr_v3_sub(c->rt[n].ctr, xr);
    double R = c->el[n].radius;
    return R * R > ROOT_THETA * ROOT_THETA * rr_v3_len2(d) || fabs(rr_v3_dot(nr, d)) < R;
}

/* The sums of cluster_geo: cluster s's terms from point xr (normal nr)
 * over its nodes, times pi: *Tp of its current power, *Ta (by_area) of its
 * area. */
static void cluster_sums(const hctx *c, uint32_t s, rr_vec3 xr, rr_vec3 nr, double P, int by_area, double *Tp_out,
                         double *Ta_out)
{
    uint32_t fr[CL_NODES];
    int nf = cluster_frontier(c, s, xr, nr, fr);
    double Tp = 0.0, Ta = 0.0; /* times pi */
    for (int i = 0; i < nf; i++) {
        uint32_t n = fr[i];
        if (n & CLB) {
            /* a cluster's power term reads only what it sends, its area
             * term only what it shows */
            const hcf *q = &c->cf[CL(n)];
            if (P > 0) /* where s sends nothing, none of its nodes does */
                Tp += cl_term(q, 0, xr, nr, cf_v3(q->pc));
            if (by_area)
                Ta += cl_term(q, 1, xr, nr, cf_v3(q->ac));
            continue;
        }
        const hroot *t = &c->rt[n];
        double w;
        if (root_exact(c, n, xr, nr)) {
            w = RR_PI * rad__hier_root_ff(c, xr, nr, n);
        } else { /* a disc at its centroid (its two centroids are one point), saturating at A / pi */
            rr_vec3 d = rr_v3_sub(t->ctr, xr);
            double nd = rr_v3_dot(nr, d), L2 = rr_v3_len2(d);
            if (!(nd > 0.0) || !(L2 > 0.0))
                continue;
            double iL = 1.0 / sqrt(L2);
            double Ap = rr_max(0.0, rr_v3_dot(t->n, rr_v3_scale(d, -iL))) * t->area;
            w = nd * iL * Ap / (L2 + Ap / RR_PI);
        }
        Tp += w * t->ssum;
        if (by_area)
            Ta += w * t->om; /* as node_uarea */
    }
    *Tp_out = Tp;
    *Ta_out = Ta;
}

/* The irradiance vector at x of cluster s's current power (times pi): over
 * cluster_sums's nodes (chosen as for a receiver of normal nr), each node's
 * intensity towards x over d^2 along the direction to it, the nodes behind
 * x's plane for nr left out. A receiving leaf cluster's link reads it, so
 * that its roots, of other normals than nr, read the nodes' spread of
 * directions (rad__hier_eval_rlc). */
static rr_vec3 cluster_vec(const hctx *c, uint32_t s, rr_vec3 xr, rr_vec3 nr, int area_too, rr_vec3 *area)
{
    uint32_t fr[CL_NODES];
    int nf = cluster_frontier(c, s, xr, nr, fr);
    rr_vec3 V = rr_v3(0, 0, 0), Va = V;
    for (int i = 0; i < nf; i++) {
        uint32_t n = fr[i];
        for (int k = 0; k < 1 + area_too; k++) { /* the power's terms, then (area_too) the area's */
            if (!(n & CLB) && root_exact(c, n, xr, nr)) { /* as in cluster_sums */
                rr_vec3 v = rr_v3_scale(rad__hier_rlc_vec(c, xr, nr, n), RR_PI * (k ? c->rt[n].om : c->rt[n].ssum));
                if (k)
                    Va = rr_v3_add(Va, v);
                else
                    V = rr_v3_add(V, v);
                continue;
            }
            rr_vec3 p = n & CLB ? cf_v3(k ? c->cf[CL(n)].ac : c->cf[CL(n)].pc) : c->rt[n].ctr, d = rr_v3_sub(p, xr);
            double L2 = rr_v3_len2(d);
            if (!(rr_v3_dot(nr, d) > 0.0) || !(L2 > 0.0))
                continue;
            double iL = 1.0 / sqrt(L2);
            rr_vec3 u = rr_v3_scale(d, iL);
            double t;
            if (n & CLB) {
                const hcf *q = &c->cf[CL(n)];
                t = (k ? nbf_proj(q->Av, q->As, (q->mask >> 7) & 63u, rr_v3_neg(u), (int)(q->mask & 1u))
                       : nbf_proj(q->Dv, q->Ds, (q->mask >> 1) & 63u, rr_v3_neg(u), (int)(q->mask & 1u))) /
                    L2;
            } else {
                const hroot *e = &c->rt[n]; /* a root */
                double Ap = rr_max(0.0, rr_v3_dot(e->n, rr_v3_neg(u))) * e->area;
                t = Ap / (L2 + Ap / RR_PI) * (k ? e->om : e->ssum); /* as node_uarea */
            }
            if (k)
                Va = rr_v3_add(Va, rr_v3_scale(u, t));
            else
                V = rr_v3_add(V, rr_v3_scale(u, t));
        }
    }
    if (area)
        *area = Va;
    return V;
}

static void cluster_geo(const hctx *c, const rview *rv, uint32_t s, int area_too, double *geo, double *geo_a,
                        double *spread, double fk[4])
{
    const hcl *k = &c->cl[CL(s)];
    rr_vec3 xr = rv->ctr, nr = rv->n;
    double P = k->P.r + k->P.g + k->P.b;
    /* *geo_a and *spread are what a new link needs; *geo alone reads them
     * only where s sends nothing */
    int by_area = area_too || !(P > 0);
    double Tp, Ta;
    cluster_sums(c, s, xr, nr, P, by_area, &Tp, &Ta);
    Tp /= RR_PI;
    Ta /= RR_PI;
    /* Over the receiver: its 4 points against its centre, and its corners
     * (the uneven test), towards s's centroids as a whole. */
    double A = k->area, mp = 0.0, ma = 0.0;
    double p0 = geo_term(xr, nr, k->pc, A), a0 = by_area ? geo_term(xr, nr, k->ac, A) : 0.0;
    int nq = 0;
    for (int q = 0; q < 4; q++) {
        if (rv->e->bur & (1u << q))
            continue; /* over r's open points */
        double bq[3];
        el_kpt(rv->e, q, bq);
        rr_vec3 xq = tri_at(rv->c, bq[0], bq[1], bq[2]);
        double gq = geo_term(xq, nr, k->pc, A);
        fk[q == 0 ? 3 : q - 1] = gq; /* k_pts[q]: the centroid of child q - 1, k_pts[0] of the middle one */
        mp += gq;
        if (by_area)
            ma += geo_term(xq, nr, k->ac, A);
        nq++;
    }
    mp = nq ? mp / nq : 0.0;
    ma = nq ? ma / nq : 0.0;
    *geo_a = k->uarea > 0 && by_area ? Ta / k->uarea * (a0 > 0 ? ma / a0 : 1.0) : 0.0;
    *geo = P > 0 ? Tp / P * (p0 > 0 ? mp / p0 : 1.0) : *geo_a;
    *spread = 0.0;
    if (area_too && p0 > 0) {
        double lo = p0, hi = p0;
        for (int q = 0; q < 3; q++) {
            double g = geo_term(rv->c[q], nr, k->pc, A);
            lo = rr_min(lo, g);
            hi = rr_max(hi, g);
        }
        *spread = (hi - lo) / p0;
    }
}

static void cluster_vis(const hctx *c, const rview *rv, hlink *l, rr_rng *rng)
{
    int pass[2] = {0, 0}, open_p = 0, pass_p = 0, partial = 0;
    if (l->f > 0.0f || l->fa > 0.0f)
        visibility(c, rv, l->r, l->s, rng, pass, &open_p, &pass_p, &partial);
    l->v = vis_share(pass[1], VIS_RAYS - 1);
    l->va = vis_share(pass[0], 1);
    l->vis = vis_share(pass_p, open_p);
    link_set_partial(l, partial);
}

void rad__hier_eval_cluster(const hctx *c, hlink *l, rr_rng *rng)
{
    double geo, geo_a, spread, fk[4];
    rview rv = rview_of(c, l->r, link_way(l));
    double rho = way_rho(c, rv.way);
    cluster_geo(c, &rv, l->s, 1, &geo, &geo_a, &spread, fk);
    geo *= rho;
    geo_a *= rho;
    l->f = (float)geo;
    l->fa = (float)geo_a;
    if (c->el[l->r].bur == 0 && !c->el[l->r].own)
        set_shape(l, fk);
    else
        link_clear_shape(l);
    cluster_vis(c, &rv, l, rng);
    /* How much the factor per unit radiosity of s (geo_a A_s) varies over r,
     * without visibility (rad_hier.c, "Decide, then estimate"), for the
     * uneven test: without it, links from clusters were never split for a
     * gradient across r. */
    l->dF = (float)(geo_a * c->cl[CL(l->s)].uarea * spread);
}

void rad__hier_revis_cluster(const hctx *c, hlink *l, rr_rng *rng)
{
    rview rv = rview_of(c, l->r, link_way(l));
    cluster_vis(c, &rv, l, rng);
}

/* The kept cluster links' geometry for the sources as solved (their
 * visibility stays): read with the power of the round that made them, a
 * ceiling dark in the first round kept its area centroid when it shone,
 * and the light it sent a floor came out 4.6 % low. Links that carry
 * under min_power without visibility keep theirs. */
void rad__hier_regeo(hctx *c, double min_power)
{
#pragma omp parallel for schedule(dynamic, 1024)
    for (long i = 0; i < (long)c->nln; i++) {
        hlink *l = &c->ln[i];
        if (!(l->s & CLB) || isnan(l->f) ||
            (min_power > 0 && rad__hier_link_power(c, l->r, l->s, link_way(l)) < min_power))
            continue;
        if (l->r & CLB) {
            /* into a receiving leaf cluster: RLC_GEO draws nothing of an
             * admissible cluster source; a near one (a near link kept,
             * read at its points) keeps its geometry: read again at 4
             * points, it was half the 1M room's regeo (7 -> 3.5 s), for
             * the bunnies' totals within 0.2 % rms (notes/radiosity.md) */
            if (rad__hier_admissible(c, l->r, l->s, 0))
                rad__hier_eval_rlc(c, l, NULL, RLC_GEO);
            continue;
        }
        double geo, geo_a, spread, fk[4];
        rview rv = rview_of(c, l->r, link_way(l));
        cluster_geo(c, &rv, l->s, 0, &geo, &geo_a, &spread, fk); /* the power's part only */
        l->f = (float)(geo * way_rho(c, rv.way));
        if (c->el[l->r].bur == 0 && !c->el[l->r].own)
            set_shape(l, fk);
    }
}

_Static_assert(sizeof(hcf) == 256, "an hcf is four cache lines");

static void pack3(float o[3], rr_vec3 v)
{
    o[0] = (float)v.x;
    o[1] = (float)v.y;
    o[2] = (float)v.z;
}

void rad__hier_cl_pack(hctx *c)
{
#pragma omp parallel for schedule(static)
    for (long i = 0; i < (long)c->ncl; i++) {
        const hcl *k = &c->cl[i];
        hcf *f = &c->cf[i];
        memset(f, 0, sizeof *f);
        pack3(f->ctr, k->ctr);
        pack3(f->pc, k->pc);
        pack3(f->ac, k->ac);
        f->radius = (float)k->radius;
        f->child[0] = k->child[0];
        f->child[1] = k->child[1];
        f->mask = (unsigned)cl_flat(k);
        for (int b = 0; b < 6; b++) {
            pack3(f->Dv[b], k->Dn.v[b]);
            pack3(f->Av[b], k->An.v[b]);
            f->Ds[b] = (float)k->Dn.s[b];
            f->As[b] = (float)k->An.s[b];
            f->mask |= (k->Dn.s[b] > 0 ? 1u : 0u) << (1 + b) | (k->An.s[b] > 0 ? 1u : 0u) << (7 + b);
        }
    }
}

/* ---- receiving leaf clusters (rad_hier.c, "Receiving leaf clusters") ---- */

/* The direction from receiving leaf cluster r's area centroid towards s's
 * power centroid (s's centre for an element), unit: where its points are
 * drawn to face. */
static rr_vec3 rlc_dir(const hctx *c, uint32_t r, uint32_t s)
{
    rr_vec3 p = s & CLB ? c->cl[CL(s)].pc : c->el[s].ctr;
    return rr_v3_norm(rr_v3_sub(p, c->cl[CL(r)].ac));
}

/* Whether a point of a root under node x may face point p: a flat root's
 * points all face p or all do not (its plane does; within rounding of p
 * lying on it, they may), a curved one's may. */
static int rlc_may_face(const hctx *c, uint32_t x, rr_vec3 p)
{
    if (!(x & CLB)) {
        const hroot *t = &c->rt[x];
        rr_vec3 d = rr_v3_sub(p, t->ctr);
        return !t->flat || rr_v3_dot(t->n, d) > -1e-9 * rr_v3_len(d);
    }
    const hcf *f = &c->cf[CL(x)];
    return rlc_may_face(c, f->child[0], p) || rlc_may_face(c, f->child[1], p);
}

/* Link l into receiving leaf cluster r = l->r from s = l->s: the
 * irradiance a surface facing s receives, per unit of what the gather reads
 * of s (its B, or a cluster's power), and its direction (the irradiance
 * vector's: for an element source the contour integral's vector form at
 * VIS_RAYS points of r's roots that face s, drawn by the area they show it
 * (drawn by plain area and again where they faced away, 8 bunnies came out
 * 1.8 % darker on average, 3.5 % at most, for 8 % of the 81-bunny room's
 * settle);
 * for an admissible cluster, cluster_vec once at r's area centroid, for a
 * near one (a near link kept, rad_hier.c) at each point), and one
 * shadow ray from each of those points to a point of s that faces it (drawn
 * by power for a cluster). The gather reads it per direction bucket with
 * each root's normal (rad_hier_rlc.c, rlc_push). The same for B = 1
 * (fa, va). */
void rad__hier_eval_rlc(const hctx *c, hlink *l, rr_rng *rng, int mode)
{
    uint32_t r = l->r, s = l->s;
    rr_vec3 u0 = rlc_dir(c, r, s), ps = s & CLB ? c->cl[CL(s)].pc : c->el[s].ctr;
    const hcl *ks = s & CLB ? &c->cl[CL(s)] : NULL;
    double P = ks ? ks->P.r + ks->P.g + ks->P.b : 0.0;
    double f = 0.0, fa = 0.0;
    rr_vec3 dir = rr_v3(0, 0, 0);
    int n = 0, seen = 0, pass = 0;
    /* a cluster source closer than admissible (a near link that carries
     * little, kept): read at each point, as a near element is (never in
     * RLC_GEO: the regeo leaves such links as they are) */
    int near = ks && !rad__hier_admissible(c, r, s, 0);
    RR_CHECK(!(near && mode == RLC_GEO));
    if (ks && !near) {
        /* A cluster source is admissible: its irradiance vectors (of its
         * power, and for B = 1 of its area; their sizes per unit of each)
         * read once, at r's area centroid, as cluster_geo reads an element
         * receiver's centre. */
        int area = mode != RLC_GEO || !(P > 0);
        rr_vec3 va, v = cluster_vec(c, s, c->cl[CL(r)].ac, u0, area, &va);
        fa = area && ks->uarea > 0 ? rr_v3_len(va) / (RR_PI * ks->uarea) : 0.0;
        f = P > 0 ? rr_v3_len(v) / (RR_PI * P) : fa;
        dir = P > 0 ? v : va;
        if (mode == RLC_GEO) { /* its B = 1 geometry and its visibility stay */
            l->f = (float)f;
            rlc_set_dir(l, rr_v3_len2(dir) > 0 ? rr_v3_norm(dir) : u0);
            return;
        }
        if (!(f > 0.0 || fa > 0.0)) {
            l->f = l->fa = 0.0f;
            l->v = l->va = l->vis = VIS_ONE;
            link_set_partial(l, 0);
            link_clear_shape(l);
            rlc_set_dir(l, u0);
            return;
        }
    }
    rr_vec3 us = rr_v3_len2(dir) > 0 ? rr_v3_norm(dir) : u0; /* towards a cluster source */
    /* Where no root faces s (the light from behind its surfaces, a quarter
     * of the 27-bunny room's links), every draw below would fail, each of
     * them a descent: 64 % of the draws. */
    int faces_s = rlc_may_face(c, r, ps);
    for (int k = 0; k < VIS_RAYS && faces_s; k++) {
        rr_vec3 x, nx, y, ny;
        uint32_t yroot = 0;
        int ok = 0;
        for (int t = 0; t < BACK_DRAWS && !ok; t++) {
            int buried = node_sample(c, r, k, 0, 0, u0, rng, &x, &nx, NULL);
            ok = !buried && rr_v3_dot(nx, rr_v3_sub(ps, x)) > 0.0;
        }
        if (!ok)
            continue; /* no open point of r faces s */
        rr_vec3 u = us;
        if (near) {
            /* read once from r's area centroid, a near cluster's light came
             * out low: 27 bunnies' incident -0.65 % on average and -5.8 % at
             * most against the light tracer once relink no longer split
             * these links (notes/radiosity.md, "Near links kept whole") */
            n++;
            rr_vec3 va, v = cluster_vec(c, s, x, nx, 1, &va);
            double ga = ks->uarea > 0 ? rr_v3_len(va) / (RR_PI * ks->uarea) : 0.0;
            double g = P > 0 ? rr_v3_len(v) / (RR_PI * P) : ga;
            rr_vec3 vd = P > 0 ? v : va;
            f += g;
            fa += ga;
            dir = rr_v3_add(dir, rr_v3_scale(vd, g > 0 ? g / rr_v3_len(vd) : 0.0));
            if (!(g > 0.0))
                continue;
            u = rr_v3_norm(vd);
        }
        if (!ks) {
            /* a near element's light comes from where it lies, not from its
             * centroid: its irradiance vector at the point (a floor element
             * under a bunny, read from its far centroid, gave the bunny's
             * underside a third of its light), s's part in front of the root */
            n++;
            rr_vec3 v = rad__hier_rlc_vec(c, x, nx, s);
            double g = rr_v3_len(v);
            f += g;
            dir = rr_v3_add(dir, v);
            if (!(g > 0.0))
                continue;
            u = rr_v3_scale(v, 1.0 / g);
        }
        int buried = 0, faces = 0;
        for (int t = 0; t < BACK_DRAWS && !faces; t++) {
            if (ks) {
                buried = node_sample(c, s, k % 4, 0, 1, rr_v3_neg(u), rng, &y, &ny, &yroot);
            } else {
                root_surface(c, c->el[s].root, tri_random(c->el[s].c, rng), &y, &ny);
                yroot = c->el[s].root;
                buried = c->el[s].open < 1.0 && rad__hier_buried(c, &c->el[s], y, ny);
            }
            /* the end faces x, and lies in front of x's root: a ray to a
             * point of s behind that root's plane would cross the root's
             * own object, and that root takes nothing from there anyway */
            faces = end_faces(c, 0, ny, x, y) && rr_v3_dot(nx, rr_v3_sub(y, x)) > 0.0;
        }
        if (!faces)
            continue;
        seen++;
        if (buried)
            continue;
        rad__hier_sphere_end(c, yroot, x, &y, &ny);
        rr_vec3 d = rr_v3_sub(y, x);
        rr_vec3 o = rt_offset_origin(c->ext, x, nx, d), t = rt_offset_origin(c->ext, y, ny, rr_v3_neg(d));
        rr_ray ray = {o, rr_v3_sub(t, o)};
        pass += !rt_accel_occluded(c->a, ray, 0.0, RT_SHADOW_END);
    }
    if (!ks) { /* the points' mean */
        f = n ? f / n : 0.0;
        fa = f;
    } else if (near) {
        f = n ? f / n : 0.0;
        fa = n ? fa / n : 0.0;
    }
    l->f = (float)f;
    l->fa = (float)fa;
    l->v = l->va = l->vis = seen ? vis_share(pass, seen) : VIS_ONE;
    link_set_partial(l, pass > 0 && pass < seen);
    link_clear_shape(l);
    rlc_set_dir(l, rr_v3_len2(dir) > 0 ? rr_v3_norm(dir) : u0);
}
