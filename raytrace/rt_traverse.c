/* rt_traverse.c - ray queries through the BVH: closest hit and any hit.
 *
 * Both walk the same nodes with the same per-primitive kernels; the only
 * difference is that the any-hit query returns at the first occluder. */
#include "rt_internal.h"

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p)
{
    p->ray = ray;
    double d[3] = {ray.d.x, ray.d.y, ray.d.z};
    /* kz: the dimension where the direction is largest, so the shear is stable. */
    int kz = fabs(d[0]) > fabs(d[1]) ? (fabs(d[0]) > fabs(d[2]) ? 0 : 2) : (fabs(d[1]) > fabs(d[2]) ? 1 : 2);
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (d[kz] < 0.0) { /* keep the winding: swap x and y when looking down -z */
        int t = kx;
        kx = ky;
        ky = t;
    }
    p->kx = kx;
    p->ky = ky;
    p->kz = kz;
    p->Sx = d[kx] / d[kz];
    p->Sy = d[ky] / d[kz];
    p->Sz = 1.0 / d[kz];
    for (int i = 0; i < 3; i++) {
        p->inv[i] = 1.0 / d[i]; /* +-inf for a zero component: the slab test handles it */
        p->neg[i] = d[i] < 0.0;
    }
}

static double comp(rr_vec3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

int rt__tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax, double *t,
                int *front)
{
    rr_vec3 o = p->ray.o;
    rr_vec3 a = rr_v3_sub(A, o), b = rr_v3_sub(B, o), c = rr_v3_sub(C, o);
    double az = comp(a, p->kz), bz = comp(b, p->kz), cz = comp(c, p->kz);
    double ax = comp(a, p->kx) - p->Sx * az, ay = comp(a, p->ky) - p->Sy * az;
    double bx = comp(b, p->kx) - p->Sx * bz, by = comp(b, p->ky) - p->Sy * bz;
    double cx = comp(c, p->kx) - p->Sx * cz, cy = comp(c, p->ky) - p->Sy * cz;
    double U = cx * by - cy * bx;
    double V = ax * cy - ay * cx;
    double W = bx * ay - by * ax;
    if (U == 0.0 || V == 0.0 || W == 0.0) {
        /* On an edge or vertex in double: decide with more bits, so that the
         * two triangles sharing the edge see the same (exact) sign. */
        long double lU = (long double)cx * by - (long double)cy * bx;
        long double lV = (long double)ax * cy - (long double)ay * cx;
        long double lW = (long double)bx * ay - (long double)by * ax;
        U = (double)lU;
        V = (double)lV;
        W = (double)lW;
    }
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0))
        return 0;
    double det = U + V + W;
    if (det == 0.0)
        return 0;
    int is_front = det > 0.0;
    if (cull && !is_front)
        return 0;
    double T = p->Sz * (U * az + V * bz + W * cz);
    double tt = T / det;
    if (!(tt > tmin && tt < tmax))
        return 0;
    *t = tt;
    *front = is_front;
    return 1;
}

/* Slab test against a node box; returns the entry distance or INFINITY. */
static double node_entry(const rt_node *n, const rt_ray_pre *p, double tmin, double tmax)
{
    const double o[3] = {p->ray.o.x, p->ray.o.y, p->ray.o.z};
    double t0 = tmin, t1 = tmax;
    for (int i = 0; i < 3; i++) {
        double lo = (double)(p->neg[i] ? n->hi[i] : n->lo[i]);
        double hi = (double)(p->neg[i] ? n->lo[i] : n->hi[i]);
        double ta = (lo - o[i]) * p->inv[i];
        double tb = (hi - o[i]) * p->inv[i];
        /* 0 * inf = NaN when the origin lies on a slab plane of an axis the
         * ray is parallel to: treat as "inside that slab". */
        if (ta != ta)
            ta = -INFINITY;
        if (tb != tb)
            tb = INFINITY;
        if (ta > t0)
            t0 = ta;
        /* Widen the exit a little (Ize 2013: 1 + 2 gamma(3)) so rounding in the
         * slab arithmetic can never cull a box the ray really touches. */
        tb *= 1.0 + 6.7e-16;
        if (tb < t1)
            t1 = tb;
    }
    return t0 <= t1 ? t0 : INFINITY;
}

/* Shared walk: any != 0 returns at the first hit. */
static int traverse(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int any)
{
    if (a->nnodes == 0)
        return 0;
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    uint32_t stack[RT_BVH_STACK];
    int sp = 0;
    uint32_t cur = 0;
    int found = 0;
    double best = tmax;
    if (node_entry(&a->nodes[0], &p, tmin, best) == INFINITY)
        return 0;
    for (;;) {
        const rt_node *n = &a->nodes[cur];
        if (n->count) {
            for (uint32_t i = 0; i < n->count; i++) {
                if (rt__prim_hit(a, a->prims[n->index + i], &p, tmin, &best, any ? NULL : hit)) {
                    found = 1;
                    if (any)
                        return 1;
                }
            }
        } else {
            /* Near child first (by the ray's direction on the split axis). */
            uint32_t first = cur + 1, second = n->index;
            if (p.neg[n->axis]) {
                uint32_t t = first;
                first = second;
                second = t;
            }
            double t1 = node_entry(&a->nodes[first], &p, tmin, best);
            double t2 = node_entry(&a->nodes[second], &p, tmin, best);
            if (t1 != INFINITY && t2 != INFINITY) {
                if (t2 < t1) {
                    uint32_t t = first;
                    first = second;
                    second = t;
                }
                RR_CHECK(sp < RT_BVH_STACK);
                stack[sp++] = second;
                cur = first;
                continue;
            }
            if (t1 != INFINITY) {
                cur = first;
                continue;
            }
            if (t2 != INFINITY) {
                cur = second;
                continue;
            }
        }
        /* Pop, skipping nodes that are now farther than the best hit. */
        for (;;) {
            if (sp == 0)
                goto out;
            cur = stack[--sp];
            if (node_entry(&a->nodes[cur], &p, tmin, best) != INFINITY)
                break;
        }
    }
out:
    if (found && hit)
        hit->point = rr_ray_at(ray, hit->t);
    return found;
}

int rt_accel_closest(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit)
{
    return traverse(a, ray, tmin, tmax, hit, 0);
}

int rt_accel_occluded(const rt_accel *a, rr_ray ray, double tmin, double tmax)
{
    return traverse(a, ray, tmin, tmax, NULL, 1);
}
