/* rad_vis.c - the exact visible form factor from a point to a polygon behind
 * triangles (rad_ff_internal.h, rad__ff_visible).
 *
 * The light that reaches x from polygon P is the factor of the part of P
 * that x sees. Each occluding triangle is cut to the pyramid from x over P
 * and to the slab the segments from x to P cross (in front of x's tangent
 * plane, above P's plane and below x's height over it), projected from x
 * onto P's plane (a convex polygon on P: every point of the cut triangle
 * lies nearer the plane than x; corners that coincide there merged), and
 * cut out of what is left of P, which stays a set of convex pieces (a convex
 * piece minus a convex polygon is the piece's parts outside each of the
 * polygon's edges in turn). The factor is the sum of the pieces' contour
 * integrals (rad_ff_point_polygon): where nothing is cut out, P's own,
 * bit for bit. Back faces of objects that cull them do not occlude, as for
 * a shadow ray (rt_accel_occluded). The hierarchical pass's estimate reads
 * it for element links between flat surfaces (rad_hier_link.c): its shadow
 * rays' noise was what two seeds still differed by on Cornell's back wall
 * (notes/radiosity.md, "Exact visibility in the estimate"). */
#include <math.h>
#include <string.h>

#include "rad.h"
#include "rad_ff_internal.h"

#define PIECE_VERTS 16 /* a piece of P: P's up to 4 corners, cut by projected triangles of up to 5 */

typedef struct piece {
    double u[PIECE_VERTS], v[PIECE_VERTS];
    int n;
} piece;

/* Polygon (pu, pv, n) cut to the side a u + b v + c >= 0 of a line, into q;
 * returns q's vertex count (0 when nothing is left, -1 past PIECE_VERTS). */
static int cut_line(const double *pu, const double *pv, int n, double a, double b, double c, piece *q)
{
    q->n = 0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        double di = a * pu[i] + b * pv[i] + c, dj = a * pu[j] + b * pv[j] + c;
        if (di >= 0) {
            if (q->n >= PIECE_VERTS)
                return -1;
            q->u[q->n] = pu[i];
            q->v[q->n++] = pv[i];
        }
        if ((di >= 0) != (dj >= 0)) {
            double t = di / (di - dj);
            if (q->n >= PIECE_VERTS)
                return -1;
            q->u[q->n] = pu[i] + t * (pu[j] - pu[i]);
            q->v[q->n++] = pv[i] + t * (pv[j] - pv[i]);
        }
    }
    return q->n;
}

/* Twice the signed area of a 2-D polygon (positive counter-clockwise). */
static double area2(const double *u, const double *v, int n)
{
    double s = 0.0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        s += u[i] * v[j] - u[j] * v[i];
    }
    return s;
}

/* Reverses the order of a 2-D polygon's corners (to counter-clockwise). */
static void reverse(double *u, double *v, int n)
{
    for (int i = 0; i < n / 2; i++) {
        double tu = u[i], tv = v[i];
        u[i] = u[n - 1 - i];
        v[i] = v[n - 1 - i];
        u[n - 1 - i] = tu;
        v[n - 1 - i] = tv;
    }
}

/* The line through edge i of a counter-clockwise polygon (u, v, n) as
 * l[0] u + l[1] v + l[2], positive on its inside (to the edge's left). */
static void edge_line(const double *u, const double *v, int n, int i, double l[3])
{
    int j = (i + 1) % n;
    l[0] = -(v[j] - v[i]);
    l[1] = u[j] - u[i];
    l[2] = -(l[0] * u[i] + l[1] * v[i]);
}

/* Polygon in (up to 10 corners after the cuts of a triangle) cut to the
 * side n . p >= d of a plane; returns the corner count. */
static int cut_plane(const rr_vec3 *in, int n, rr_vec3 nrm, double d, rr_vec3 *out)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        double di = rr_v3_dot(nrm, in[i]) - d, dj = rr_v3_dot(nrm, in[j]) - d;
        if (di >= 0)
            out[m++] = in[i];
        if ((di >= 0) != (dj >= 0))
            out[m++] = rr_v3_madd(in[i], rr_v3_sub(in[j], in[i]), di / (di - dj));
    }
    return m;
}

double rad__ff_visible(rr_vec3 x, rr_vec3 nx, const rr_vec3 *poly, int nv, const rr_vec3 (*occ)[3],
                       const unsigned char *cull, int nocc, double tol, int *hidden)
{
    *hidden = 0;
    if (nv < 3)
        return 0.0;
    /* P's plane, its normal towards x, and 2-D axes in it */
    rr_vec3 p0 = poly[0], m = rr_v3_cross(rr_v3_sub(poly[1], p0), rr_v3_sub(poly[2], p0));
    double ml = rr_v3_len(m);
    if (!(ml > 0))
        return 0.0;
    m = rr_v3_scale(m, 1.0 / ml);
    double h = rr_v3_dot(m, rr_v3_sub(x, p0));
    if (h < 0) {
        m = rr_v3_neg(m);
        h = -h;
    }
    if (!(h > tol))
        return 0.0;
    rr_vec3 e1 = rr_v3_norm(rr_v3_sub(poly[1], p0)), e2 = rr_v3_cross(m, e1);
    enum { MAX_PIECES = 48 };
    piece buf[2][MAX_PIECES], *pc = buf[0], *next = buf[1];
    int np = 1;
    pc[0].n = nv;
    for (int i = 0; i < nv; i++) {
        rr_vec3 d = rr_v3_sub(poly[i], p0);
        pc[0].u[i] = rr_v3_dot(d, e1);
        pc[0].v[i] = rr_v3_dot(d, e2);
    }
    if (area2(pc[0].u, pc[0].v, nv) < 0) /* counter-clockwise about m */
        reverse(pc[0].u, pc[0].v, nv);
    double full = fabs(area2(pc[0].u, pc[0].v, nv)), tiny = 1e-12 * full, merge = 1e-9 * sqrt(full);
    /* the pyramid from x over P: a triangle wholly outside one of its sides
     * (the plane through x and an edge of P) casts nothing on P */
    rr_vec3 side[4];
    double sgn = rr_v3_dot(rr_v3_cross(rr_v3_sub(poly[0], x), rr_v3_sub(poly[1], x)), rr_v3_sub(poly[2], x)) > 0 ? 1 : -1;
    for (int i = 0; i < nv; i++)
        side[i] = rr_v3_scale(rr_v3_cross(rr_v3_sub(poly[i], x), rr_v3_sub(poly[(i + 1) % nv], x)), sgn);
    for (int t = 0; t < nocc && np > 0; t++) {
        const rr_vec3 *T = occ[t];
        rr_vec3 tn = rr_v3_cross(rr_v3_sub(T[1], T[0]), rr_v3_sub(T[2], T[0]));
        if (cull && cull[t] && !(rr_v3_dot(tn, rr_v3_sub(x, T[0])) > 0))
            continue; /* x sees its back, which a culling object's shadow ray passes */
        int outside = 0;
        for (int i = 0; i < nv && !outside; i++)
            outside = rr_v3_dot(side[i], rr_v3_sub(T[0], x)) <= 0 && rr_v3_dot(side[i], rr_v3_sub(T[1], x)) <= 0 &&
                      rr_v3_dot(side[i], rr_v3_sub(T[2], x)) <= 0;
        if (outside)
            continue;
        /* the part of T in the pyramid from x over P (its shadow on P's
         * plane is then the shadow's part on P: projected points stay
         * within P, where a part near x's tangent plane would project
         * towards infinity) and between P's plane and x's height over it */
        rr_vec3 a[16], b[16];
        int k = cut_plane(T, 3, nx, rr_v3_dot(nx, x) + tol, a);
        for (int i = 0; i < nv && k >= 3; i++) {
            k = cut_plane(a, k, side[i], rr_v3_dot(side[i], x), b);
            memcpy(a, b, (size_t)k * sizeof *a);
        }
        k = k >= 3 ? cut_plane(a, k, m, rr_v3_dot(m, p0) + tol, b) : 0;
        k = k >= 3 ? cut_plane(b, k, rr_v3_neg(m), -(rr_v3_dot(m, p0) + h - tol), a) : 0;
        if (k < 3)
            continue;
        /* projected from x onto P's plane, corners that coincide there
         * merged (a cut through a corner repeats it: a zero-length edge
         * would read as a line that P lies wholly outside) */
        double qu[16], qv[16], ulo = INFINITY, uhi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
        int kq = 0;
        for (int i = 0; i < k; i++) {
            double hv = rr_v3_dot(m, rr_v3_sub(a[i], p0));
            rr_vec3 y = rr_v3_madd(x, rr_v3_sub(a[i], x), h / (h - hv));
            rr_vec3 d = rr_v3_sub(y, p0);
            double u = rr_v3_dot(d, e1), v = rr_v3_dot(d, e2);
            if (kq > 0 && fabs(u - qu[kq - 1]) <= merge && fabs(v - qv[kq - 1]) <= merge)
                continue;
            qu[kq] = u;
            qv[kq++] = v;
        }
        while (kq > 1 && fabs(qu[kq - 1] - qu[0]) <= merge && fabs(qv[kq - 1] - qv[0]) <= merge)
            kq--;
        k = kq;
        if (k < 3)
            continue;
        for (int i = 0; i < k; i++) {
            ulo = fmin(ulo, qu[i]);
            uhi = fmax(uhi, qu[i]);
            vlo = fmin(vlo, qv[i]);
            vhi = fmax(vhi, qv[i]);
        }
        double qa = area2(qu, qv, k);
        if (!(fabs(qa) > tiny))
            continue;
        if (qa < 0)
            reverse(qu, qv, k);
        /* each piece minus the projection, into next */
        int nn = 0;
        for (int p = 0; p < np; p++) {
            const piece *cur = &pc[p];
            double plo = INFINITY, phi = -INFINITY, pvlo = INFINITY, pvhi = -INFINITY;
            for (int i = 0; i < cur->n; i++) {
                plo = fmin(plo, cur->u[i]);
                phi = fmax(phi, cur->u[i]);
                pvlo = fmin(pvlo, cur->v[i]);
                pvhi = fmax(pvhi, cur->v[i]);
            }
            int apart = plo >= uhi || ulo >= phi || pvlo >= vhi || vlo >= pvhi;
            /* or wholly outside one of the projection's edges (its inside
             * to the left: counter-clockwise) */
            for (int i = 0; i < k && !apart; i++) {
                double l[3];
                edge_line(qu, qv, k, i, l);
                int all = 1;
                for (int q = 0; q < cur->n && all; q++)
                    all = l[0] * cur->u[q] + l[1] * cur->v[q] + l[2] <= 0;
                apart = all;
            }
            if (apart) {
                if (nn >= MAX_PIECES)
                    return -1.0;
                next[nn++] = *cur;
                continue;
            }
            *hidden = 1;
            piece rest = *cur, in, outp;
            for (int i = 0; i < k && rest.n >= 3; i++) {
                double l[3];
                edge_line(qu, qv, k, i, l);
                if (cut_line(rest.u, rest.v, rest.n, -l[0], -l[1], -l[2], &outp) < 0 ||
                    cut_line(rest.u, rest.v, rest.n, l[0], l[1], l[2], &in) < 0)
                    return -1.0;
                if (outp.n >= 3 && fabs(area2(outp.u, outp.v, outp.n)) > tiny) {
                    if (nn >= MAX_PIECES)
                        return -1.0;
                    next[nn++] = outp;
                }
                rest = in;
            }
        }
        piece *t_ = pc; /* next holds what is left of P */
        pc = next;
        next = t_;
        np = nn;
    }
    if (!*hidden)
        return rad_ff_point_polygon(x, nx, poly, nv); /* nothing cut out: P's own factor, bit for bit */
    double F = 0.0;
    for (int p = 0; p < np; p++) {
        rr_vec3 q[PIECE_VERTS];
        for (int i = 0; i < pc[p].n; i++)
            q[i] = rr_v3_add(p0, rr_v3_add(rr_v3_scale(e1, pc[p].u[i]), rr_v3_scale(e2, pc[p].v[i])));
        F += rad_ff_point_polygon(x, nx, q, pc[p].n);
    }
    return F;
}
