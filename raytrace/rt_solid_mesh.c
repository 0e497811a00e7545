/* rt_solid_mesh.c - mesh leaves of solids: where a ray is inside a closed
 * triangle mesh, decided so that no ray ever gets the wrong parity, and the
 * small per-leaf BVHs that make it fast.
 *
 * Inside test. A mesh leaf is inside where the winding number of the ray is
 * positive: walking the sorted crossings from t = -inf, a crossing of a
 * front-facing triangle (the ray enters through the outward side) adds 1, a
 * back-facing one subtracts 1. This is only right if the ray crosses the
 * surface a consistent number of times, also when it passes exactly through a
 * vertex or along an edge. So the crossing test is
 *  - watertight (Woop, Benthin, Wald 2013): the ray is sheared to +z and the
 *    vertices projected to 2D once per vertex, so triangles sharing an edge see
 *    the same 2D points;
 *  - exact in its signs: the edge function E(P, Q) = Px Qy - Py Qx (the
 *    origin's side of the 2D edge P -> Q) is evaluated in double with an error
 *    bound and, when the bound cannot decide, exactly (fma products and an
 *    exact sum, Shewchuk's expansions). E(Q, P) = -E(P, Q) holds exactly in
 *    both paths, so two triangles sharing an edge always disagree on it;
 *  - symbolically perturbed where E is exactly zero: the ray is taken as
 *    moved to (eps, eps^2) in the sheared 2D plane, which turns E into
 *    E - eps dy + eps^2 dx with (dx, dy) = Q - P, so a zero E takes the sign
 *    -sign(dy), or sign(dx) when dy = 0. That is one consistent move of the ray
 *    for every triangle: a ray through a vertex crosses exactly one triangle of
 *    the fan around it (or none, when it only touches), and a ray in the plane
 *    of a face passes just above or just below it, consistently for all the
 *    faces around.
 * Then a triangle is crossed when its three edge signs agree; it is front
 * facing when they are negative (seen from the ray, the outward side is
 * counter-clockwise, which in the sheared frame of Woop's test is a negative
 * signed area; tested in test_csg.c). t comes from the (double) barycentric
 * weights as in Woop's test.
 *
 * Crossings at the same t are ordered entering first, so touching the mesh at
 * one point gives a zero-length span (dropped) and passing through a saddle
 * vertex no gap. The winding number before tmin is counted (from the
 * crossings before tmin, or as minus the sum of those after it: a closed
 * mesh's crossings sum to zero exactly, so either gives the same spans, and
 * the walk takes the side with less of the mesh's box); only crossings in
 * (tmin, tmax) are kept, at most XING_MAX, the nearest (by t, then entering
 * first, then triangle index: a total order, so the BVH and the brute-force
 * loop keep the same ones and give the same spans). When more occur, the span
 * open after the last kept crossing is closed at the nearest dropped one.
 *
 * Limits: the exact sign assumes no underflow in the 2D products (vertex
 * coordinates relative to the ray origin above ~1e-150 in magnitude, or 0).
 */
#include <stdlib.h>
#include <string.h>

#include "rt_kernel.h"
#include "rt_solid_internal.h"

#define XING_MAX (2 * RT_SPAN_MAX)
#define MESH_STACK 64
#define NO_ROOT UINT32_MAX

/* ---- the ray in Woop's sheared frame: rt__ray_prepare's (kx, ky, kz, Sx,
 * Sy, Sz), the set-up every query of raytrace shares ---- */

typedef struct p2 {
    double x, y, z;
} p2;

/* A vertex in the sheared frame; a pure function of the vertex and the ray, so
 * every triangle that shares the vertex sees the same 2D point. */
static p2 project(const rt_ray_pre *m, rr_vec3 v)
{
    rr_vec3 a = rr_v3_sub(v, m->ray.o);
    p2 r;
    r.z = rr_v3_get(a, m->kz);
    r.x = rr_v3_get(a, m->kx) - m->Sx * r.z;
    r.y = rr_v3_get(a, m->ky) - m->Sy * r.z;
    return r;
}

/* ---- exact sign of the edge function ---- */

static void two_sum(double a, double b, double *x, double *y)
{
    *x = a + b;
    double bv = *x - a, av = *x - bv;
    *y = (a - av) + (b - bv);
}

/* Sign of the exact sum of n doubles (n <= 4): grow a nonoverlapping
 * expansion (Shewchuk 1997, Grow-Expansion with zero elimination); its largest
 * component carries the sign of the sum. */
static int exact_sign(const double *v, int n)
{
    double e[8];
    int m = 0;
    for (int i = 0; i < n; i++) {
        double q = v[i];
        int k = 0;
        for (int j = 0; j < m; j++) {
            double hi, lo;
            two_sum(q, e[j], &hi, &lo);
            if (lo != 0.0)
                e[k++] = lo;
            q = hi;
        }
        if (q != 0.0 || k == 0)
            e[k++] = q;
        m = k;
    }
    for (int j = m - 1; j >= 0; j--)
        if (e[j] != 0.0)
            return e[j] > 0.0 ? 1 : -1;
    return 0;
}

/* Sign of E(P, Q) = Px Qy - Py Qx, exact, with the symbolic tie-break. Also
 * returns the double value (for the barycentric weights) and whether E is
 * exactly zero (the ray passes exactly through the edge's line). */
static int edge_sign(p2 P, p2 Q, double *value, int *zero)
{
    double a = P.x * Q.y, b = P.y * Q.x;
    double e = a - b;
    *value = e;
    *zero = 0;
    /* |fl(a - b) - E| <= ~2u (|a| + |b|), u = 2^-53: beyond that the sign of e
     * is the sign of E. The bound is symmetric in P and Q, so both triangles
     * of an edge take the same path. */
    if (fabs(e) > 3.0e-16 * (fabs(a) + fabs(b)))
        return e > 0.0 ? 1 : -1;
    double v[4] = {a, -b, fma(P.x, Q.y, -a), -fma(P.y, Q.x, -b)};
    int sg = exact_sign(v, 4);
    if (sg != 0)
        return sg;
    *zero = 1;
    double dx = Q.x - P.x, dy = Q.y - P.y; /* the sign of a rounded difference is exact */
    if (dy != 0.0)
        return dy > 0.0 ? -1 : 1;
    if (dx != 0.0)
        return dx > 0.0 ? 1 : -1;
    return 0; /* P == Q: a degenerate edge is crossed by no ray */
}

/* z where the ray meets segment PQ (the ray passes exactly through its line),
 * computed from the endpoints in the order of their vertex indices, so that
 * both triangles sharing the edge get the same t. */
static double edge_z(p2 P, uint32_t ip, p2 Q, uint32_t iq)
{
    if (iq < ip) {
        p2 t = P;
        P = Q;
        Q = t;
    }
    double dx = Q.x - P.x, dy = Q.y - P.y;
    double l = -(P.x * dx + P.y * dy) / (dx * dx + dy * dy);
    return P.z + l * (Q.z - P.z);
}

/* Does the ray cross triangle ABC (vertex indices ia, ib, ic)? Returns +1
 * (entering: the ray meets its counter-clockwise, outward side), -1 (leaving)
 * or 0, and t. Where the ray passes exactly through a vertex or an edge, t
 * is computed from that vertex or edge alone, so every triangle around it
 * reports the same t (a ray touching a corner enters and leaves at exactly
 * the same t: a zero-length span, dropped). */
static int tri_cross(const rt_ray_pre *m, rr_vec3 A, rr_vec3 B, rr_vec3 C, uint32_t ia, uint32_t ib, uint32_t ic,
                     double *t)
{
    p2 a = project(m, A), b = project(m, B), c = project(m, C);
    double e0, e1, e2;
    int z0, z1, z2;
    int s0 = edge_sign(b, c, &e0, &z0);
    if (s0 == 0)
        return 0;
    int s1 = edge_sign(c, a, &e1, &z1);
    if (s1 != s0)
        return 0;
    int s2 = edge_sign(a, b, &e2, &z2);
    if (s2 != s0)
        return 0;
    double z;
    if (z0 + z1 + z2 >= 2) {
        z = !z0 ? a.z : (!z1 ? b.z : c.z); /* at the vertex the two zero edges share */
    } else if (z0) {
        z = edge_z(b, ib, c, ic);
    } else if (z1) {
        z = edge_z(c, ic, a, ia);
    } else if (z2) {
        z = edge_z(a, ia, b, ib);
    } else {
        double det = e0 + e1 + e2;
        if (det != 0.0)
            *t = m->Sz * (e0 * a.z + e1 * b.z + e2 * c.z) / det;
        else /* edge-on in double although the exact signs agree: any point of it will do */
            *t = m->Sz * (a.z + b.z + c.z) / 3.0;
        return s0 < 0 ? 1 : -1;
    }
    *t = m->Sz * z;
    return s0 < 0 ? 1 : -1;
}

/* ---- crossing buffer ---- */

typedef struct xing {
    double t;
    int32_t tri;
    int32_t dir; /* +1 entering, -1 leaving */
} xing;

/* What a walk collects: the crossings in (tmin, tmax), and the winding
 * number before tmin from the crossings before it (X_BEFORE), or as minus
 * the sum of those after it (X_AFTER: every crossing's dir is summed into
 * after; the crossings of a closed mesh sum to zero, exactly, since the
 * signs are exact); or only that sum (X_COUNT). */
enum { X_BEFORE, X_AFTER, X_COUNT };

typedef struct xbuf {
    double tmin, tmax;
    int before; /* X_BEFORE: sum of dir over the crossings with t <= tmin */
    int mode;
    int after; /* X_AFTER, X_COUNT: sum of dir over the crossings with t > tmin */
    int n;
    int dropped;
    xing drop; /* the nearest dropped crossing */
    xing x[XING_MAX];
} xbuf;

/* The total order: t, entering first, triangle. */
static int xing_less(const xing *a, const xing *b)
{
    if (a->t != b->t)
        return a->t < b->t;
    if (a->dir != b->dir)
        return a->dir > b->dir;
    return a->tri < b->tri;
}

static int xing_cmp(const void *pa, const void *pb)
{
    const xing *a = pa, *b = pb;
    return xing_less(a, b) ? -1 : (xing_less(b, a) ? 1 : 0);
}

static void xbuf_drop(xbuf *b, xing x)
{
    if (!b->dropped || xing_less(&x, &b->drop))
        b->drop = x;
    b->dropped = 1;
}

static void xbuf_add(xbuf *b, xing x)
{
    if (b->mode != X_BEFORE) {
        if (!(x.t > b->tmin)) /* also NaN */
            return;
        b->after += x.dir;
        if (b->mode == X_COUNT || !(x.t < b->tmax))
            return;
    } else {
        if (!(x.t < b->tmax)) /* also NaN */
            return;
        if (x.t <= b->tmin) {
            b->before += x.dir;
            return;
        }
    }
    if (b->n < XING_MAX) {
        b->x[b->n++] = x;
        return;
    }
    int far = 0;
    for (int i = 1; i < b->n; i++)
        if (xing_less(&b->x[far], &b->x[i]))
            far = i;
    if (xing_less(&x, &b->x[far])) {
        xbuf_drop(b, b->x[far]);
        b->x[far] = x;
    } else {
        xbuf_drop(b, x);
    }
}

/* ---- per-leaf BVH: the scene BVH's binary builder (rt__bvh_build_binary),
 * walked as a binary tree ---- */

struct rt_solid_accel {
    size_t ncsg;
    uint32_t *root; /* per CSG node: its BVH root in nodes, or NO_ROOT */
    rt_node *nodes; /* every leaf's tree, inner: right child at index (absolute); leaf: first entry in tris */
    size_t nnodes;
    uint32_t *tris; /* csg_tris indices in leaf order */
};

size_t rt__solids_bytes(const struct rt_solid_accel *sa)
{
    if (!sa)
        return 0;
    size_t ntris = 0;
    for (size_t k = 0; k < sa->nnodes; k++)
        ntris += sa->nodes[k].count;
    return sizeof *sa + sa->ncsg * sizeof *sa->root + sa->nnodes * sizeof *sa->nodes + ntris * sizeof *sa->tris;
}

void rt__solids_destroy(struct rt_solid_accel *sa)
{
    if (!sa)
        return;
    free(sa->root);
    free(sa->nodes);
    free(sa->tris);
    free(sa);
}

/* The tree of mesh leaf n (its triangles' entries at sa->tris[first..]),
 * appended to sa->nodes (room for 2 tri_count nodes). Boxes are padded so
 * that the slab test, which rounds, never misses a triangle that a ray
 * touches at a vertex lying on the box. Returns its root, or NO_ROOT when out
 * of memory. */
static uint32_t build_leaf_tree(const scene *s, const scene_csg_node *n, struct rt_solid_accel *sa, size_t first,
                                rt_bref *refs)
{
    double ext = 0.0, big = 0.0;
    rr_vec3 lo = rr_v3(INFINITY, INFINITY, INFINITY), hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t j = 0; j < n->tri_count; j++) {
        const uint32_t *v = s->csg_tris[n->tri_first + j];
        rr_vec3 A = s->csg_verts[v[0]], B = s->csg_verts[v[1]], C = s->csg_verts[v[2]];
        rr_vec3 tlo = rr_v3_min(A, rr_v3_min(B, C)), thi = rr_v3_max(A, rr_v3_max(B, C));
        rt__bref_set(&refs[j], tlo, thi, (uint32_t)j);
        lo = rr_v3_min(lo, tlo);
        hi = rr_v3_max(hi, thi);
    }
    for (int k = 0; k < 3; k++) {
        ext = fmax(ext, rr_v3_get(hi, k) - rr_v3_get(lo, k));
        big = fmax(big, fmax(fabs(rr_v3_get(hi, k)), fabs(rr_v3_get(lo, k))));
    }
    double pad = 1e-9 * ext + 1e-12 * big;
    rt_node *nodes = NULL;
    size_t nn = 0;
    if (rt__bvh_build_binary(refs, n->tri_count, 1, 0, &nodes, &nn))
        return NO_ROOT;
    uint32_t base = (uint32_t)sa->nnodes;
    for (size_t k = 0; k < nn; k++) {
        rt_node nd = nodes[k];
        for (int a = 0; a < 3; a++) {
            nd.lo[a] = rt__f_down((double)nd.lo[a] - pad);
            nd.hi[a] = rt__f_up((double)nd.hi[a] + pad);
        }
        nd.index += nd.count ? (uint32_t)first : base;
        sa->nodes[sa->nnodes++] = nd;
    }
    free(nodes);
    for (size_t j = 0; j < n->tri_count; j++)
        sa->tris[first + j] = (uint32_t)n->tri_first + rt__bref_item(&refs[j]);
    return base;
}

rr_status rt__solids_build(const scene *s, struct rt_solid_accel **out, rr_error *err)
{
    *out = NULL;
    size_t total = 0, most = 0;
    for (size_t i = 0; i < s->ncsg; i++)
        if (s->csg[i].op == SCENE_CSG_LEAF && s->csg[i].solid == SCENE_SOLID_MESH) {
            total += s->csg[i].tri_count;
            most = s->csg[i].tri_count > most ? s->csg[i].tri_count : most;
        }
    if (total == 0)
        return RR_OK;
    if (total >= UINT32_MAX / 2)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: %zu mesh-leaf triangles in solids exceed the limit", s->path,
                            total);
    struct rt_solid_accel *sa = calloc(1, sizeof *sa);
    rt_bref *refs = malloc(most * sizeof *refs);
    if (!sa || !refs)
        goto nomem;
    sa->ncsg = s->ncsg;
    sa->root = malloc(s->ncsg * sizeof *sa->root);
    sa->tris = malloc(total * sizeof *sa->tris);
    sa->nodes = malloc(2 * total * sizeof *sa->nodes);
    if (!sa->root || !sa->tris || !sa->nodes)
        goto nomem;
    size_t first = 0;
    for (size_t i = 0; i < s->ncsg; i++) {
        const scene_csg_node *n = &s->csg[i];
        sa->root[i] = NO_ROOT;
        if (n->op != SCENE_CSG_LEAF || n->solid != SCENE_SOLID_MESH || n->tri_count == 0)
            continue;
        if ((sa->root[i] = build_leaf_tree(s, n, sa, first, refs)) == NO_ROOT)
            goto nomem;
        first += n->tri_count;
    }
    free(refs);
    *out = sa;
    return RR_OK;
nomem:
    free(refs);
    rt__solids_destroy(sa);
    return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory building the BVHs of %zu mesh-leaf triangles",
                        s->path, total);
}

/* Slab test of a (padded) node box over (tlo, thi), widened for rounding. */
static int node_hit(const rt_node *nd, const rt_slab_ray *r, double tlo, double thi)
{
    return rt__box_overlap(r, rr_v3(nd->lo[0], nd->lo[1], nd->lo[2]), rr_v3(nd->hi[0], nd->hi[1], nd->hi[2]), tlo, thi);
}

static void cross_tri(const scene *s, const rt_ray_pre *m, uint32_t tri, xbuf *b)
{
    const uint32_t *v = s->csg_tris[tri];
    double t;
    int dir = tri_cross(m, s->csg_verts[v[0]], s->csg_verts[v[1]], s->csg_verts[v[2]], v[0], v[1], v[2], &t);
    if (dir) {
        xing x = {t, (int32_t)tri, dir};
        xbuf_add(b, x);
    }
}

/* Every crossing of the line with the leaf's triangles with t < b->tmax. */
static void collect(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_ray ray, xbuf *b)
{
    const scene_csg_node *n = &s->csg[leaf];
    rt_ray_pre m;
    rt__ray_prepare(ray, &m);
    if (!sa || leaf >= sa->ncsg || sa->root[leaf] == NO_ROOT) {
        for (size_t t = n->tri_first; t < n->tri_first + n->tri_count; t++)
            cross_tri(s, &m, (uint32_t)t, b);
        return;
    }
    rt_slab_ray sr = rt__slab_prepare(ray);
    uint32_t stack[MESH_STACK];
    int sp = 0;
    stack[sp++] = sa->root[leaf];
    while (sp > 0) {
        uint32_t id = stack[--sp];
        const rt_node *nd = &sa->nodes[id];
        if (!node_hit(nd, &sr, b->mode == X_BEFORE ? -INFINITY : b->tmin, b->mode == X_AFTER ? INFINITY : b->tmax))
            continue;
        if (nd->count) {
            for (uint32_t i = 0; i < nd->count; i++)
                cross_tri(s, &m, sa->tris[nd->index + i], b);
        } else {
            RR_CHECK(sp + 2 <= MESH_STACK);
            stack[sp++] = nd->index;
            stack[sp++] = id + 1;
        }
    }
}

void rt__mesh_spans(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_ray ray, double tmin,
                    double tmax, rt_spans *out)
{
    const scene_csg_node *n = &s->csg[leaf];
    if (n->tri_count == 0 || !(rr_v3_len2(ray.d) > 0.0))
        return;
    xbuf b;
    b.tmin = tmin;
    b.tmax = tmax;
    b.before = 0;
    b.mode = X_BEFORE;
    b.after = 0;
    b.n = 0;
    b.dropped = 0;
    /* The winding number at tmin from whichever side of (tmin, tmax) has
     * less of the leaf's box along the line: a ray leaving a mesh's surface
     * need not walk the mesh behind it (the same spans either way). The
     * brute-force reference always counts from before. */
    if (sa && leaf < sa->ncsg && sa->root[leaf] != NO_ROOT) {
        double t0 = -INFINITY, t1 = INFINITY;
        for (int i = 0; i < 3; i++) {
            double o = rr_v3_get(ray.o, i), d = rr_v3_get(ray.d, i);
            if (d == 0.0)
                continue;
            double ta = (rr_v3_get(n->bbox_lo, i) - o) / d, tb = (rr_v3_get(n->bbox_hi, i) - o) / d;
            t0 = fmax(t0, fmin(ta, tb));
            t1 = fmin(t1, fmax(ta, tb));
        }
        double behind = fmin(tmin, t1) - t0, beyond = t1 - fmax(tmax, t0);
        if (t0 <= t1 && !(behind <= beyond))
            b.mode = X_AFTER;
    }
    collect(s, sa, leaf, ray, &b);
    if (b.mode == X_AFTER)
        b.before = -b.after;
    qsort(b.x, (size_t)b.n, sizeof b.x[0], xing_cmp);
    /* Artificial ends at tmin / tmax name a real triangle of the leaf, so their
     * normal is defined; they are never reported (see rt_solid.c). */
    int32_t any = (int32_t)n->tri_first;
    int w = b.before;
    rt_span_end start = rt__span_end(tmin, leaf, any);
    for (int i = 0; i < b.n; i++) {
        int w1 = w + b.x[i].dir;
        if (w <= 0 && w1 > 0)
            start = rt__span_end(b.x[i].t, leaf, b.x[i].tri);
        else if (w > 0 && w1 <= 0)
            rt__spans_push(out, start, rt__span_end(b.x[i].t, leaf, b.x[i].tri));
        w = w1;
    }
    if (w > 0)
        rt__spans_push(out, start, b.dropped ? rt__span_end(b.drop.t, leaf, b.drop.tri) : rt__span_end(tmax, leaf, any));
}

int rt__mesh_contains(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_vec3 p)
{
    const scene_csg_node *n = &s->csg[leaf];
    if (n->tri_count == 0)
        return 0;
    /* Winding number at p = minus the sum over the crossings after p (the
     * crossings of a closed mesh sum to zero). A direction of no special
     * alignment (the tie-break makes any direction correct; this one just
     * keeps t well conditioned for axis-aligned meshes). */
    rr_ray r = {p, rr_v3(0.5227513, 0.6123725, 0.5929461)};
    xbuf b;
    b.tmin = 0.0;
    b.tmax = INFINITY;
    b.mode = X_COUNT;
    b.after = 0;
    collect(s, sa, leaf, r, &b);
    return -b.after > 0;
}
