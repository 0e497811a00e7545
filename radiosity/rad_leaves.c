/* rad_leaves.c - the leaves of a hierarchical radiosity solution as a patch
 * set (rad.h, rad_patches.roots): built from the roots and the tree's split
 * bits (by the solver, rad_hier.c, and by the cache), the bits read back, and
 * vertex values without cracks at T-vertices (rad_hier_internal.h).
 *
 * The tree is walked breadth first, so midpoints are made coarse to fine and
 * leaves are numbered in that order; midpoints are shared through the
 * patch builder's vertex map keyed by the edge (rad_patch_internal.h). */
#include <stdlib.h>
#include <string.h>

#include "rad_hier_internal.h"
#include "rad_patch_internal.h"

/* ---- the leaves as a patch set ---- */

rr_status rad__hier_leaves(rad_patches *roots, const rad_split_bits *bits, rad_patches **out, rr_error *err)
{
    rad_patches *P = calloc(1, sizeof *P);
    size_t nr = roots->n, nsplit = 0;
    for (size_t i = 0; i < bits->n; i++)
        nsplit += bits->bit[i] != 0;
    /* A tree of nr roots with nsplit splits has nr + 4 nsplit nodes. */
    if (!P || bits->n != nr + 4 * nsplit) {
        free(P);
        rad_patches_destroy(roots);
        return P ? rr_error_set(err, RR_ERR_INVALID, "radiosity: the element tree does not fit the patches")
                 : rr_error_set(err, RR_ERR_NOMEM, "radiosity: out of memory for the element tree");
    }
    P->roots = roots;
    size_t nleaf = bits->n - nsplit, nv = roots->nverts + 3 * nsplit;
    P->p = malloc((nleaf ? nleaf : 1) * sizeof *P->p);
    P->verts = malloc((nv ? nv : 1) * sizeof *P->verts);
    P->qt = malloc((4 * nsplit + 1) * sizeof *P->qt);
    P->root_qt = malloc((nr ? nr : 1) * sizeof *P->root_qt);
    P->mid = malloc((6 * nsplit + 1) * sizeof *P->mid);
    /* The breadth-first queue: (corner vertices, depth, root, where its entry goes). */
    typedef struct qitem {
        uint32_t v[3], depth, root;
        uint32_t *slot;
    } qitem;
    qitem *q = malloc((bits->n ? bits->n : 1) * sizeof *q);
    rad__edge_map mids;
    int ok = P->p && P->verts && P->qt && P->root_qt && P->mid && q && rad__edge_map_init(&mids, 3 * nsplit) == 0;
    if (!ok) {
        free(q);
        rad_patches_destroy(P);
        return rr_error_set(err, RR_ERR_NOMEM, "radiosity: out of memory for %zu elements", bits->n);
    }
    memcpy(P->verts, roots->verts, roots->nverts * sizeof *P->verts);
    P->nverts = roots->nverts;
    for (size_t r = 0; r < nr; r++)
        q[r] = (qitem){{roots->p[r].v[0], roots->p[r].v[1], roots->p[r].v[2]}, 0, (uint32_t)r, &P->root_qt[r]};
    size_t head = 0, tail = nr;
    for (; head < tail && ok; head++) {
        qitem it = q[head];
        const rad_patch *rp = &roots->p[it.root];
        if (!bits->bit[head]) {
            rad_patch *lp = &P->p[P->n];
            *lp = *rp;
            memcpy(lp->v, it.v, sizeof lp->v);
            lp->area = ldexp(rp->area, -2 * (int)it.depth);
            lp->centroid = rr_v3_scale(
                rr_v3_add(P->verts[it.v[0]], rr_v3_add(P->verts[it.v[1]], P->verts[it.v[2]])), 1.0 / 3.0);
            *it.slot = RAD_QT_LEAF | (uint32_t)P->n++;
            continue;
        }
        uint32_t m[3]; /* midpoints of the edges ab, bc, ca */
        for (int e = 0; e < 3 && ok; e++) {
            uint32_t a = it.v[e], b = it.v[(e + 1) % 3];
            uint32_t v = rad__edge_get(&mids, a < b ? a : b, a < b ? b : a, 0, (uint32_t)P->nverts);
            ok = v != UINT32_MAX;
            if (ok && v == P->nverts) { /* a new midpoint */
                P->nverts++;
                P->verts[v] = rr_v3_scale(rr_v3_add(P->verts[a], P->verts[b]), 0.5);
                P->mid[2 * (v - roots->nverts)] = a;
                P->mid[2 * (v - roots->nverts) + 1] = b;
            }
            m[e] = v;
        }
        uint32_t node = (uint32_t)P->nqt++;
        *it.slot = node;
        const uint32_t ch[4][3] = {
            {it.v[0], m[0], m[2]}, {m[0], it.v[1], m[1]}, {m[2], m[1], it.v[2]}, {m[1], m[2], m[0]}};
        for (int c = 0; c < 4; c++)
            q[tail++] = (qitem){{ch[c][0], ch[c][1], ch[c][2]}, it.depth + 1, it.root, &P->qt[4 * (size_t)node + c]};
    }
    free(q);
    rad__edge_map_free(&mids);
    if (!ok) {
        rad_patches_destroy(P);
        return rr_error_set(err, RR_ERR_NOMEM, "radiosity: out of memory for %zu elements", bits->n);
    }
    *out = P;
    return RR_OK;
}

int rad__hier_bits(const rad_patches *P, rad_split_bits *bits)
{
    size_t n = P->roots->n + 4 * P->nqt;
    uint32_t *q = malloc((n ? n : 1) * sizeof *q);
    bits->bit = malloc(n ? n : 1);
    bits->n = n;
    if (!q || !bits->bit) {
        free(q);
        free(bits->bit);
        bits->bit = NULL;
        return -1;
    }
    size_t tail = 0;
    for (size_t r = 0; r < P->roots->n; r++)
        q[tail++] = P->root_qt[r];
    for (size_t head = 0; head < tail; head++) {
        uint32_t e = q[head];
        bits->bit[head] = !(e & RAD_QT_LEAF);
        if (!(e & RAD_QT_LEAF))
            for (int c = 0; c < 4; c++)
                q[tail++] = P->qt[4 * (size_t)e + c];
    }
    free(q);
    return 0;
}

/* rr_rgb with every channel at least 0. */
static rr_rgb nonnegative(rr_rgb c)
{
    return rr_rgb_make(c.r > 0 ? c.r : 0, c.g > 0 ? c.g : 0, c.b > 0 ? c.b : 0);
}

/* One sweep of back-projection: each patch's residual, its value less the
 * mean of its three vertex values (the mean of the Gouraud-shaded surface
 * over it), is added back to its vertices, area-weighted as the means were.
 * acc: P->nverts scratch values. */
static void back_project(const rad_patches *P, const rr_rgb *per_patch, const double *wsum, rr_rgb *acc,
                         rr_rgb *per_vertex)
{
    for (size_t v = 0; v < P->nverts; v++)
        acc[v] = rr_rgb_make(0, 0, 0);
    for (size_t k = 0; k < P->n; k++) {
        const uint32_t *pv = P->p[k].v;
        rr_rgb sum = rr_rgb_add(rr_rgb_add(per_vertex[pv[0]], per_vertex[pv[1]]), per_vertex[pv[2]]);
        rr_rgb residual = rr_rgb_add(per_patch[k], rr_rgb_scale(sum, -1.0 / 3.0));
        for (int e = 0; e < 3; e++)
            acc[pv[e]] = rr_rgb_add(acc[pv[e]], rr_rgb_scale(residual, P->p[k].area));
    }
    for (size_t v = 0; v < P->nverts; v++)
        if (wsum[v] > 0)
            per_vertex[v] = nonnegative(rr_rgb_add(per_vertex[v], rr_rgb_scale(acc[v], 1.0 / wsum[v])));
}

rr_status rad__to_vertices(const rad_patches *P, const rr_rgb *per_patch, int sweeps, rr_rgb *per_vertex)
{
    double *wsum = calloc(P->nverts ? P->nverts : 1, sizeof *wsum);
    rr_rgb *acc = sweeps > 0 ? malloc((P->nverts ? P->nverts : 1) * sizeof *acc) : NULL;
    if (!wsum || (sweeps > 0 && !acc)) {
        free(wsum);
        free(acc);
        return RR_ERR_NOMEM;
    }
    for (size_t v = 0; v < P->nverts; v++)
        per_vertex[v] = rr_rgb_make(0, 0, 0);
    for (size_t k = 0; k < P->n; k++)
        for (int e = 0; e < 3; e++) {
            uint32_t v = P->p[k].v[e];
            per_vertex[v] = rr_rgb_add(per_vertex[v], rr_rgb_scale(per_patch[k], P->p[k].area));
            wsum[v] += P->p[k].area;
        }
    for (size_t v = 0; v < P->nverts; v++)
        if (wsum[v] > 0)
            per_vertex[v] = rr_rgb_scale(per_vertex[v], 1.0 / wsum[v]);
    for (int it = 0; it < sweeps; it++)
        back_project(P, per_patch, wsum, acc, per_vertex);
    free(acc);
    free(wsum);
    if (!P->roots)
        return RR_OK;
    /* T-vertices: a midpoint of an edge that is also a whole edge of some
     * leaf takes the mean of the edge's ends, coarse to fine (midpoints are
     * numbered in that order), so both sides of the edge interpolate alike. */
    rad__edge_map edges;
    if (rad__edge_map_init(&edges, 3 * P->n) != 0)
        return RR_ERR_NOMEM;
    for (size_t k = 0; k < P->n; k++)
        for (int e = 0; e < 3; e++) {
            uint32_t a = P->p[k].v[e], b = P->p[k].v[(e + 1) % 3];
            if (rad__edge_get(&edges, a < b ? a : b, a < b ? b : a, 0, 1) == UINT32_MAX) {
                rad__edge_map_free(&edges);
                return RR_ERR_NOMEM;
            }
        }
    for (size_t v = P->roots->nverts; v < P->nverts; v++) {
        uint32_t a = P->mid[2 * (v - P->roots->nverts)], b = P->mid[2 * (v - P->roots->nverts) + 1];
        if (rad__edge_find(&edges, a < b ? a : b, a < b ? b : a, 0) != UINT32_MAX)
            per_vertex[v] = rr_rgb_scale(rr_rgb_add(per_vertex[a], per_vertex[b]), 0.5);
    }
    rad__edge_map_free(&edges);
    return RR_OK;
}

