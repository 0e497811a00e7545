/* rt_kernel.h - private to raytrace/: what every ray query shares whatever
 * the node width: the watertight triangle kernel (Woop, Benthin, Wald 2013)
 * on the per-ray set-up of rt__ray_prepare, the leaf records' triangle test
 * and hit fill, and the float rounding helpers of the slab tests
 * (RT_BOX_GROW; the slab tests themselves are in rt_wide.h).
 *
 * It is the same source in every translation unit that includes it
 * (rt_traverse.c, and rt_bvh_avx2.c compiled with -mavx2 but not -mfma), so
 * the double arithmetic of the triangle test is the same operation for
 * operation (no contraction into FMA): both widths give the same hits bit for
 * bit. The solids' mesh leaves (rt_solid_mesh.c) use the same ray set-up but
 * their own crossing test, which must decide parity exactly (exact signs and
 * a symbolic tie-break) where this kernel only needs the nearest hit.
 */
#ifndef RT_KERNEL_H
#define RT_KERNEL_H

#include <float.h>
#include <string.h>

#include "rt_internal.h"

/* 1 + RT_BOX_GROW >= (1 + g3) / (1 - g3) with g3 = 3 * 2^-24 / (1 - 3 * 2^-24)
 * (about 1 + 3.6e-7), with room to spare. */
#define RT_BOX_GROW 4.8e-7f

/* Float nearest to x rounded up / down (x a double; NaN stays NaN). One ulp
 * step by the bit pattern (floats of one sign are ordered as integers), which
 * is nextafterf without the library call, and without a branch: whether
 * the rounding to float went up or down is a coin toss, and a branch on it
 * was mispredicted about half the time (the per-ray setup, rt__ray_prepare,
 * rounds six of them). */
static inline float rt__f_up(double x)
{
    /* f < x steps f up: u + 1 for f >= +0 (+0 becomes FLT_TRUE_MIN), u - 1
     * below (-inf becomes -FLT_MAX). f is never -0 then (a positive x does
     * not round to -0), so the sign bit picks the direction. */
    float f = (float)x;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    uint32_t step = 1u - ((u >> 31) << 1);
    u += step & (0u - (uint32_t)((double)f < x));
    memcpy(&f, &u, sizeof f);
    return f;
}
static inline float rt__f_down(double x)
{
    return -rt__f_up(-x); /* rounding to nearest is symmetric */
}

/* ---- the triangle kernel of the walks (rt__tri_hit is the same function) ---- */

static inline double rt__comp(rr_vec3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

/* The watertight test on the vertices relative to the origin, already in the
 * ray's axis order (kx, ky, kz). Bitwise | instead of || in the sign tests:
 * the same result with fewer branches. A hit needs tmin < t < tmax, or
 * t == tmax when tie is set (the walk's tie-break, below). */
static inline int rt__tri_core(const rt_ray_pre *p, double akx, double aky, double az, double bkx, double bky,
                               double bz, double ckx, double cky, double cz, int cull, double tmin, double tmax,
                               int tie, double *t, int *front)
{
    double ax = akx - p->Sx * az, ay = aky - p->Sy * az;
    double bx = bkx - p->Sx * bz, by = bky - p->Sy * bz;
    double cx = ckx - p->Sx * cz, cy = cky - p->Sy * cz;
    double U = cx * by - cy * bx;
    double V = ax * cy - ay * cx;
    double W = bx * ay - by * ax;
    if ((U == 0.0) | (V == 0.0) | (W == 0.0)) {
        /* On an edge or vertex in double: decide with more bits, so that the
         * two triangles sharing the edge see the same (exact) sign. */
        long double lU = (long double)cx * by - (long double)cy * bx;
        long double lV = (long double)ax * cy - (long double)ay * cx;
        long double lW = (long double)bx * ay - (long double)by * ax;
        U = (double)lU;
        V = (double)lV;
        W = (double)lW;
    }
    if (((U < 0.0) | (V < 0.0) | (W < 0.0)) & ((U > 0.0) | (V > 0.0) | (W > 0.0)))
        return 0;
    double det = U + V + W;
    if (det == 0.0)
        return 0;
    int is_front = det > 0.0;
    if (cull && !is_front)
        return 0;
    double T = p->Sz * (U * az + V * bz + W * cz);
    double tt = T / det;
    if (!(tt > tmin && (tt < tmax || (tie && tt == tmax))))
        return 0;
    *t = tt;
    *front = is_front;
    return 1;
}

static inline int rt__tri_hit_inl(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin,
                                  double tmax, double *t, int *front)
{
    rr_vec3 o = p->ray.o;
    rr_vec3 a = rr_v3_sub(A, o), b = rr_v3_sub(B, o), c = rr_v3_sub(C, o);
    return rt__tri_core(p, rt__comp(a, p->kx), rt__comp(a, p->ky), rt__comp(a, p->kz), rt__comp(b, p->kx),
                        rt__comp(b, p->ky), rt__comp(b, p->kz), rt__comp(c, p->kx), rt__comp(c, p->ky),
                        rt__comp(c, p->kz), cull, tmin, tmax, 0, t, front);
}

/* The test on a leaf record's fast triangle: the same arithmetic (the float
 * vertices are the scene's doubles exactly), with the coordinates loaded in
 * the ray's axis order instead of selected. */
static inline int rt__tri_hit_rec(const rt_ray_pre *p, const rt_rec *r, double tmin, double tmax, int tie,
                                  double *t, int *front)
{
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const double ox = p->ok[0], oy = p->ok[1], oz = p->ok[2];
    return rt__tri_core(p, (double)r->v[0][kx] - ox, (double)r->v[0][ky] - oy, (double)r->v[0][kz] - oz,
                        (double)r->v[1][kx] - ox, (double)r->v[1][ky] - oy, (double)r->v[1][kz] - oz,
                        (double)r->v[2][kx] - ox, (double)r->v[2][ky] - oy, (double)r->v[2][kz] - oz,
                        (r->flags & p->cull_mask) != 0, tmin, tmax, tie, t, front);
}

/* The same on a record's double copy (RT_REC_DBL): v = A, B, C, xyz each. */
static inline int rt__tri_hit_drec(const rt_ray_pre *p, const double *v, int cull, double tmin, double tmax, int tie,
                                   double *t, int *front)
{
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const double ox = p->ok[0], oy = p->ok[1], oz = p->ok[2];
    return rt__tri_core(p, v[kx] - ox, v[ky] - oy, v[kz] - oz, v[3 + kx] - ox, v[3 + ky] - oy, v[3 + kz] - oz,
                        v[6 + kx] - ox, v[6 + ky] - oy, v[6 + kz] - oz, cull, tmin, tmax, tie, t, front);
}

/* Vertex k of a FAST or DBL record (dverts: the accel's double copies). */
static inline rr_vec3 rt__rec_vert(const rt_rec *r, const double *dverts, int k)
{
    if (r->flags & RT_REC_FAST)
        return rr_v3((double)r->v[k][0], (double)r->v[k][1], (double)r->v[k][2]);
    const double *v = dverts + 9 * (size_t)r->dv + 3 * k;
    return rr_v3(v[0], v[1], v[2]);
}

/* Fills hit for the FAST or DBL triangle of record r met with `front` at t,
 * as rt__prim_hit does (the normal by the formula of scene_tri_normal, on
 * the same doubles). */
static inline void rt__tri_fill(const rt_rec *r, const double *dverts, int front, double t, rt_hit *hit)
{
    rr_vec3 A = rt__rec_vert(r, dverts, 0);
    rr_vec3 n = rr_v3_norm(
        rr_v3_cross(rr_v3_sub(rt__rec_vert(r, dverts, 1), A), rr_v3_sub(rt__rec_vert(r, dverts, 2), A)));
    hit->tri = (int64_t)r->index;
    hit->part = -1;
    hit->object = r->flags >> RT_REC_OBJ_SHIFT;
    hit->material = r->material;
    hit->normal = front ? n : rr_v3_neg(n);
    hit->t = t;
    hit->front = front;
}

#endif /* RT_KERNEL_H */
