/* rad_hier_mirror.c - the hierarchical pass's links by way of planar mirrors
 * (rad_hier.c, "Mirrors"): the chains of mirrors as ways, and the test that
 * keeps a way's walk to the pairs its mirrors can pass light between. */
#include <stdlib.h>

#include "rad_hier_ctx.h"

/* The reflection in plane n . x = d. */
static rr_xform reflection(rr_vec3 n, double d)
{
    const double v[3] = {n.x, n.y, n.z};
    rr_xform h;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            h.m[i][j] = (i == j) - 2.0 * v[i] * v[j];
    h.t = rr_v3_scale(n, 2.0 * d);
    return h;
}

static hwin window_of(const rt_mirror_plane *p)
{
    hwin g;
    g.n = p->n;
    g.d = p->d;
    /* axes in the plane: u across the normal's smallest component */
    rr_vec3 a = fabs(p->n.x) <= fabs(p->n.y) && fabs(p->n.x) <= fabs(p->n.z) ? rr_v3(1, 0, 0)
                : fabs(p->n.y) <= fabs(p->n.z)                               ? rr_v3(0, 1, 0)
                                                                             : rr_v3(0, 0, 1);
    g.u = rr_v3_norm(rr_v3_cross(p->n, a));
    g.v = rr_v3_cross(p->n, g.u);
    g.o = rr_v3_scale(p->n, p->d);
    g.u0 = g.v0 = INFINITY;
    g.u1 = g.v1 = -INFINITY;
    for (size_t i = 0; i < p->nverts; i++) {
        rr_vec3 q = rr_v3_sub(p->verts[i], g.o);
        double u = rr_v3_dot(q, g.u), v = rr_v3_dot(q, g.v);
        g.u0 = rr_min(g.u0, u);
        g.u1 = rr_max(g.u1, u);
        g.v0 = rr_min(g.v0, v);
        g.v1 = rr_max(g.v1, v);
    }
    return g;
}

/* Whether some corner of plane p's mirror lies off plane q (either side). */
static int reaches_off(const rt_mirror_plane *q, const rt_mirror_plane *p, double tol)
{
    for (size_t i = 0; i < p->nverts; i++)
        if (fabs(rr_v3_dot(q->n, p->verts[i]) - q->d) > tol)
            return 1;
    return 0;
}

/* Whether light can go from mirror plane a to mirror plane b. Mirrors
 * reflect on both sides, so some of each must lie off the other's plane;
 * but the back of a closed object's surface faces its sealed inside, where
 * no light is: there the other must reach the front. A framed mirror made
 * as a closed box (scenes/interior.json: 6 planes) gave chains of up to 5
 * of its faces by way of its inside, 514 of them past WAYS_MAX (127) and
 * left out with a warning; now its 6 planes are its only ways. */
static int passes_light(const hctx *c, const rt_mirror_plane *a, const rt_mirror_plane *b, double tol)
{
    if (!reaches_off(a, b, tol) || !reaches_off(b, a, tol))
        return 0;
    const rt_mirror_plane *pair[2][2] = {{a, b}, {b, a}};
    for (int k = 0; k < 2; k++) {
        const rt_mirror_plane *q = pair[k][0], *p = pair[k][1];
        if (!scene_object_closed(c->s, q->object))
            continue;
        int front = 0;
        for (size_t i = 0; i < p->nverts && !front; i++)
            front = rr_v3_dot(q->n, p->verts[i]) - q->d > tol;
        if (!front)
            return 0;
    }
    return 1;
}

/* The maps of way g from its planes (g->n, g->plane, g->win set). */
static void way_maps(himg *g, const rt_mirror_plane *pl)
{
    g->Tk[0] = rr_xform_identity();
    for (int k = 1; k < g->n; k++) {
        rr_xform r = reflection(pl[g->plane[k - 1]].n, pl[g->plane[k - 1]].d);
        g->Tk[k] = rr_xform_compose(&r, &g->Tk[k - 1]);
    }
    rr_xform last = reflection(pl[g->plane[g->n - 1]].n, pl[g->plane[g->n - 1]].d);
    g->T = rr_xform_compose(&last, &g->Tk[g->n - 1]);
    for (int i = 0; i < 3; i++) /* a rigid map's inverse: the transposed matrix */
        for (int j = 0; j < 3; j++)
            g->Ti.m[i][j] = g->T.m[j][i];
    g->Ti.t = rr_v3_neg(rr_xform_vector(&g->Ti, g->T.t));
    rr_xform y = rr_xform_identity();
    for (int k = g->n - 1; k >= 0; k--) {
        rr_xform r = reflection(pl[g->plane[k]].n, pl[g->plane[k]].d);
        y = rr_xform_compose(&r, &y);
        g->Yk[k] = y;
    }
}

int rad__hier_ways(hctx *c, const rt_lights *M, int depth, size_t *dropped)
{
    size_t np = rt_lights_mirror_planes(M);
    c->M = M;
    c->nimg = 0;
    *dropped = 0;
    if (np == 0 || depth < 1)
        return 0;
    rt_mirror_plane *pl = malloc(np * sizeof *pl);
    c->img = malloc(WAYS_MAX * sizeof *c->img);
    if (!pl || !c->img) {
        free(pl);
        return -1;
    }
    for (size_t k = 0; k < np; k++)
        pl[k] = rt_lights_plane(M, k);
    double tol = c->plane_tol;
    /* shortest first: the ways of length L + 1 extend those of length L at
     * the source's end by a mirror that the last one can see */
    size_t lo = 0;
    for (size_t k = 0; k < np; k++) {
        if (!(pl[k].reflectance > 0) || pl[k].nverts == 0)
            continue;
        if (c->nimg == WAYS_MAX) {
            (*dropped)++;
            continue;
        }
        himg *g = &c->img[c->nimg++];
        g->n = 1;
        g->plane[0] = (uint32_t)k;
    }
    for (int len = 2; len <= depth && len <= RT_CHAIN_MAX; len++) {
        size_t hi = c->nimg;
        for (size_t i = lo; i < hi; i++)
            for (size_t k = 0; k < np; k++) {
                uint32_t last = c->img[i].plane[len - 2];
                if (k == last || !(pl[k].reflectance > 0) || pl[k].nverts == 0 ||
                    !passes_light(c, &pl[last], &pl[k], tol))
                    continue;
                if (c->nimg == WAYS_MAX) {
                    (*dropped)++;
                    continue;
                }
                himg *g = &c->img[c->nimg++];
                *g = c->img[i];
                g->plane[g->n++] = (uint32_t)k;
            }
        lo = hi;
    }
    for (unsigned w = 0; w < c->nimg; w++) {
        himg *g = &c->img[w];
        g->rho = 1.0;
        for (int k = 0; k < g->n; k++) {
            g->rho *= pl[g->plane[k]].reflectance;
            g->win[k] = window_of(&pl[g->plane[k]]);
        }
        way_maps(g, pl);
    }
    free(pl);
    return 0;
}

/* Which sides of window g node x reaches beyond tol, seen through map f
 * (NULL: itself): bit 1 above, bit 2 below. */
static int node_sides(const hctx *c, uint32_t x, const rr_xform *f, const hwin *g)
{
    rr_vec3 pts[8];
    int n, s = 0;
    node_points(c, x, pts, &n);
    for (int k = 0; k < n; k++) {
        double t = rr_v3_dot(g->n, f ? rr_xform_point(f, pts[k]) : pts[k]) - g->d;
        s |= t > c->plane_tol ? 1 : t < -c->plane_tol ? 2 : 0;
    }
    return s;
}

/* Liang-Barsky: whether the 2-D segment (x0, y0) -> (x1, y1) meets the box
 * [bx0, bx1] x [by0, by1]. */
static int segment_meets_box(double x0, double y0, double x1, double y1, double bx0, double bx1, double by0,
                             double by1)
{
    double t0 = 0.0, t1 = 1.0;
    const double p[4] = {-(x1 - x0), x1 - x0, -(y1 - y0), y1 - y0};
    const double q[4] = {x0 - bx0, bx1 - x0, y0 - by0, by1 - y0};
    for (int i = 0; i < 4; i++) {
        if (p[i] == 0.0) {
            if (q[i] < 0.0)
                return 0;
            continue;
        }
        double t = q[i] / p[i];
        if (p[i] < 0.0)
            t0 = rr_max(t0, t);
        else
            t1 = rr_min(t1, t);
        if (t0 > t1)
            return 0;
    }
    return 1;
}

/* Whether some segment between the balls (a, R) and (b, R) passes through
 * window g: a point p of such a segment lies within R of the point of the
 * centres' segment at the same parameter, so where p is on the plane that
 * point is within R of it, and p's place in the plane within R of that
 * point's. */
static int balls_see_through(const hwin *g, rr_vec3 a, rr_vec3 b, double R)
{
    double da = rr_v3_dot(g->n, a) - g->d, k = rr_v3_dot(g->n, b) - g->d - da;
    double t0 = 0.0, t1 = 1.0;
    if (fabs(k) < 1e-300) {
        if (fabs(da) > R)
            return 0;
    } else {
        double lo = (-R - da) / k, hi = (R - da) / k;
        t0 = rr_max(0.0, rr_min(lo, hi));
        t1 = rr_min(1.0, rr_max(lo, hi));
        if (t0 > t1)
            return 0;
    }
    rr_vec3 p0 = rr_v3_sub(rr_v3_madd(a, rr_v3_sub(b, a), t0), g->o);
    rr_vec3 p1 = rr_v3_sub(rr_v3_madd(a, rr_v3_sub(b, a), t1), g->o);
    return segment_meets_box(rr_v3_dot(p0, g->u), rr_v3_dot(p0, g->v), rr_v3_dot(p1, g->u), rr_v3_dot(p1, g->v),
                             g->u0 - R, g->u1 + R, g->v0 - R, g->v1 + R);
}

/* At mirror k of the way, the light arrives from the source's image in the
 * mirrors after it (Y_{k+1}) and leaves for the receiver's image in those
 * before it (T_k): the two must reach a common side of its plane, and the
 * straight segment from T_k(r) to the source's image in mirror k and after
 * (Y_k) must pass through it. */
int rad__hier_way_culled(const hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    const himg *g = &c->img[w - 1];
    double R = rr_max(node_radius(c, r), node_radius(c, s));
    rr_vec3 cr = node_ctr(c, r), cs = node_ctr(c, s);
    for (int k = 0; k < g->n; k++) {
        const hwin *m = &g->win[k];
        const rr_xform *tk = k ? &g->Tk[k] : NULL, *yk1 = k + 1 < g->n ? &g->Yk[k + 1] : NULL;
        if (!(node_sides(c, r, tk, m) & node_sides(c, s, yk1, m)))
            return 1;
        if (!balls_see_through(m, tk ? rr_xform_point(tk, cr) : cr, rr_xform_point(&g->Yk[k], cs), R))
            return 1;
    }
    return 0;
}
