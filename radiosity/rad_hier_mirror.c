/* rad_hier_mirror.c - the hierarchical pass's links by way of planar mirrors
 * (rad_hier.c, "Mirrors"): the mirrors as ways, and the test that keeps a
 * way's walk to the pairs its mirror can pass light between. */
#include <stdlib.h>

#include "rad_hier_ctx.h"

int rad__hier_ways(hctx *c, const rt_lights *M)
{
    size_t np = rt_lights_mirror_planes(M);
    c->M = M;
    c->nimg = 0;
    if (np == 0)
        return 0;
    c->img = malloc(np * sizeof *c->img);
    if (!c->img)
        return -1;
    for (size_t k = 0; k < np && c->nimg < WAYS_MAX; k++) {
        rt_mirror_plane p = rt_lights_plane(M, k);
        if (!(p.reflectance > 0) || p.nverts == 0)
            continue;
        himg *g = &c->img[c->nimg++];
        g->n = p.n;
        g->d = p.d;
        g->rho = p.reflectance;
        g->plane = (uint32_t)k;
        /* axes in the plane: u across the normal's smallest component */
        rr_vec3 a = fabs(p.n.x) <= fabs(p.n.y) && fabs(p.n.x) <= fabs(p.n.z) ? rr_v3(1, 0, 0)
                    : fabs(p.n.y) <= fabs(p.n.z)                             ? rr_v3(0, 1, 0)
                                                                             : rr_v3(0, 0, 1);
        g->u = rr_v3_norm(rr_v3_cross(p.n, a));
        g->v = rr_v3_cross(p.n, g->u);
        g->o = rr_v3_scale(p.n, p.d);
        g->u0 = g->v0 = INFINITY;
        g->u1 = g->v1 = -INFINITY;
        for (size_t i = 0; i < p.nverts; i++) {
            rr_vec3 q = rr_v3_sub(p.verts[i], g->o);
            double u = rr_v3_dot(q, g->u), v = rr_v3_dot(q, g->v);
            g->u0 = rr_min(g->u0, u);
            g->u1 = rr_max(g->u1, u);
            g->v0 = rr_min(g->v0, v);
            g->v1 = rr_max(g->v1, v);
        }
    }
    return 0;
}

/* Which sides of plane g node x reaches beyond tol: bit 1 above, bit 2 below. */
static int node_sides(const hctx *c, uint32_t x, const himg *g)
{
    rr_vec3 pts[8];
    int n, s = 0;
    node_points(c, x, pts, &n);
    for (int k = 0; k < n; k++) {
        double t = rr_v3_dot(g->n, pts[k]) - g->d;
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

/* A point p of a segment from a point of s's bounding sphere to one of r's
 * image's lies within max(R_s, R_r) of the point of the centres' segment at
 * the same parameter, so where p is on the plane that point is within R of
 * it, and p's place in the plane within R of that point's. */
int rad__hier_way_culled(const hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    const himg *g = &c->img[w - 1];
    if (!(node_sides(c, r, g) & node_sides(c, s, g)))
        return 1;
    rr_vec3 cs = node_ctr(c, s), cr = way_point(c, w, node_ctr(c, r));
    double R = rr_max(node_radius(c, r), node_radius(c, s));
    double ds = rr_v3_dot(g->n, cs) - g->d, k = rr_v3_dot(g->n, cr) - g->d - ds;
    double t0 = 0.0, t1 = 1.0;
    if (fabs(k) < 1e-300) {
        if (fabs(ds) > R)
            return 1;
    } else {
        double a = (-R - ds) / k, b = (R - ds) / k;
        t0 = rr_max(0.0, rr_min(a, b));
        t1 = rr_min(1.0, rr_max(a, b));
        if (t0 > t1)
            return 1;
    }
    rr_vec3 p0 = rr_v3_sub(rr_v3_madd(cs, rr_v3_sub(cr, cs), t0), g->o);
    rr_vec3 p1 = rr_v3_sub(rr_v3_madd(cs, rr_v3_sub(cr, cs), t1), g->o);
    return !segment_meets_box(rr_v3_dot(p0, g->u), rr_v3_dot(p0, g->v), rr_v3_dot(p1, g->u), rr_v3_dot(p1, g->v),
                              g->u0 - R, g->u1 + R, g->v0 - R, g->v1 + R);
}
