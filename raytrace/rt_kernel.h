/* rt_kernel.h - private to raytrace/: what every ray query shares whatever
 * the node width: the watertight triangle kernel (Woop, Benthin, Wald 2013)
 * on the per-ray set-up of rt__ray_prepare, the leaf packets' float test
 * (rt__pk_cand) and exact triangle test and hit fill, and the float rounding
 * helpers of the slab tests
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

/* ---- the per-ray set-up (rt__ray_prepare = rt__ray_prepare_box, then rt__ray_prepare_tri) ---- */

#if defined(RT_SIMD) && RT_SIMD >= 1
#include <emmintrin.h>
#endif

#if defined(RT_SIMD) && RT_SIMD >= 1
/* The per-axis part of rt__ray_prepare_box in SSE2, three axes at once and
 * without branches (for incoherent rays the selections by the direction's
 * signs were mispredicted): the same values as the scalar loop below. The
 * origin rounded up and down (rt__f_up, rt__f_down: the float nearest o,
 * stepped one ulp by its bit pattern when the rounding went the wrong way),
 * the near and far origins picked by the sign bits, 1/d in double and float,
 * and whether the float slab test can take the ray. */
static inline void rt__prepare_axes(const double d[3], const double o[3], rt_ray_pre *p, const int origins)
{
    __m128d d01 = _mm_loadu_pd(d), d2 = _mm_load_sd(d + 2);
    __m128d o01 = _mm_loadu_pd(o), o2 = _mm_load_sd(o + 2);
    const __m128d one = _mm_set1_pd(1.0);
    __m128d inv01 = _mm_div_pd(one, d01), inv2 = _mm_div_sd(one, d2);
    _mm_storeu_pd(p->inv, inv01);
    _mm_store_sd(p->inv + 2, inv2);
    _mm_storeu_ps(p->inv_f, _mm_movelh_ps(_mm_cvtpd_ps(inv01), _mm_cvtpd_ps(inv2)));
    if (origins) {
        __m128 f = _mm_movelh_ps(_mm_cvtpd_ps(o01), _mm_cvtpd_ps(o2));
        __m128d f01 = _mm_cvtps_pd(f), f2 = _mm_cvtps_pd(_mm_movehl_ps(f, f));
        /* f < o and f > o per axis, the 64-bit masks packed into 32-bit lanes. */
        __m128i lt = _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(_mm_cmplt_pd(f01, o01)),
                                                     _mm_castpd_ps(_mm_cmplt_pd(f2, o2)), _MM_SHUFFLE(2, 0, 2, 0)));
        __m128i gt = _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(_mm_cmpgt_pd(f01, o01)),
                                                     _mm_castpd_ps(_mm_cmpgt_pd(f2, o2)), _MM_SHUFFLE(2, 0, 2, 0)));
        __m128i u = _mm_castps_si128(f);
        /* +1 for a float with the sign bit clear, -1 with it set: one ulp up in
         * value for lt, down for gt (rt__f_up's step). */
        __m128i dir = _mm_or_si128(_mm_srai_epi32(u, 31), _mm_set1_epi32(1));
        __m128i up = _mm_add_epi32(u, _mm_and_si128(lt, dir)), down = _mm_sub_epi32(u, _mm_and_si128(gt, dir));
        /* The direction's sign bits (converting to float keeps them, -0 too). */
        __m128i neg = _mm_srai_epi32(_mm_castps_si128(_mm_movelh_ps(_mm_cvtpd_ps(d01), _mm_cvtpd_ps(d2))), 31);
        __m128i near = _mm_or_si128(_mm_and_si128(neg, down), _mm_andnot_si128(neg, up));
        __m128i far = _mm_or_si128(_mm_and_si128(neg, up), _mm_andnot_si128(neg, down));
        _mm_storeu_ps(p->org_near, _mm_castsi128_ps(near));
        _mm_storeu_ps(p->org_far, _mm_castsi128_ps(far));
    }
    int nm = _mm_movemask_pd(d01) | _mm_movemask_pd(d2) << 2;
    for (int i = 0; i < 3; i++) {
        p->neg[i] = (nm >> i) & 1;
        p->near_row[i] = 2 * i + p->neg[i];
    }
    /* In range: |o| < 1e30, and |d| = 0 or 1e-30 < |d| < 1e30. */
    const __m128d absm = _mm_castsi128_pd(_mm_set1_epi64x(0x7fffffffffffffffLL));
    const __m128d big = _mm_set1_pd(1e30), small = _mm_set1_pd(1e-30), zero = _mm_setzero_pd();
    __m128d a01 = _mm_and_pd(d01, absm), a2 = _mm_and_pd(d2, absm);
    __m128d ok01 = _mm_and_pd(_mm_cmplt_pd(_mm_and_pd(o01, absm), big),
                              _mm_or_pd(_mm_cmpeq_pd(a01, zero),
                                        _mm_and_pd(_mm_cmpgt_pd(a01, small), _mm_cmplt_pd(a01, big))));
    __m128d ok2 = _mm_and_pd(_mm_cmplt_sd(_mm_and_pd(o2, absm), big),
                             _mm_or_pd(_mm_cmpeq_sd(a2, zero), _mm_and_pd(_mm_cmpgt_sd(a2, small), _mm_cmplt_sd(a2, big))));
    p->box_double = (_mm_movemask_pd(ok01) & 3) != 3 || (_mm_movemask_pd(ok2) & 1) != 1;
}
#else
static inline void rt__prepare_axes(const double d[3], const double o[3], rt_ray_pre *p, const int origins)
{
    (void)origins;
    int bad = 0;
    for (int i = 0; i < 3; i++) {
        p->inv[i] = 1.0 / d[i]; /* +-inf for a zero component: the slab tests handle it */
        /* The sign bit, not d < 0: for d = -0, 1/d = -inf and the near plane is
         * the upper one (with d < 0 a ray parallel to a slab with d = -0 missed
         * every box whose slab it lies in). */
        p->neg[i] = signbit(d[i]) ? 1 : 0;
        p->near_row[i] = 2 * i + p->neg[i];
        float up = rt__f_up(o[i]), down = rt__f_down(o[i]);
        p->org_near[i] = p->neg[i] ? down : up;
        p->org_far[i] = p->neg[i] ? up : down;
        p->inv_f[i] = (float)p->inv[i];
        double ad = fabs(d[i]);
        int in_range = (fabs(o[i]) < 1e30) & ((ad == 0.0) | ((ad > 1e-30) & (ad < 1e30)));
        bad |= !in_range;
    }
    p->box_double = bad;
}
#endif

/* The slab tests' part of rt__ray_prepare: p->ray, 1/d, the sign rows,
 * box_double, cull_mask; with origins != 0 also the origin rounded towards
 * the near and far planes (org_near, org_far: the sub-and-multiply slab
 * tests; the 16-wide fused one does not read them). */
static inline void rt__ray_prepare_box(rr_ray ray, rt_ray_pre *p, const int origins)
{
    p->ray = ray;
    double d[3] = {ray.d.x, ray.d.y, ray.d.z};
    double o[3] = {ray.o.x, ray.o.y, ray.o.z};
    p->cull_mask = RT_REF_CULL;
    rt__prepare_axes(d, o, p, origins);
}

/* The triangle test's part of rt__ray_prepare (after rt__ray_prepare_box:
 * it reads p->ray and p->inv): the single-ray walks call it at their start
 * (its divisions overlap the box operands' chain), the packet walks at a
 * ray's first leaf (rt_packet.h). */
static inline void rt__ray_prepare_tri(rt_ray_pre *p)
{
    const double d[3] = {p->ray.d.x, p->ray.d.y, p->ray.d.z};
    const double o[3] = {p->ray.o.x, p->ray.o.y, p->ray.o.z};
    /* kz: the dimension where the direction is largest, so the shear is
     * stable; kx, ky the next two, swapped when looking down -z to keep the
     * winding. By table, not by branches: for incoherent rays the branches
     * were mispredicted often enough to make this set-up a tenth of a
     * diffuse ray's time. */
    static const signed char kz_of[8] = {2, 1, 2, 1, 2, 2, 0, 0}; /* [x>y, x>z, y>z] */
    static const signed char kxy_of[3][2][2] = {{{1, 2}, {2, 1}}, {{2, 0}, {0, 2}}, {{0, 1}, {1, 0}}};
    double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]);
    int kz = kz_of[(ax > ay) << 2 | (ax > az) << 1 | (ay > az)];
    int down_z = d[kz] < 0.0;
    int kx = kxy_of[kz][down_z][0], ky = kxy_of[kz][down_z][1];
    p->kx = kx;
    p->ky = ky;
    p->kz = kz;
    p->Sx = d[kx] / d[kz];
    p->Sy = d[ky] / d[kz];
    p->Sz = p->inv[kz]; /* 1 / d[kz], the same division */
    p->ok[0] = o[kx];
    p->ok[1] = o[ky];
    p->ok[2] = o[kz];
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

/* The test on a packet lane's fast triangle (RT_REF_FAST): the same
 * arithmetic as rt__tri_hit_inl (the float vertices are the scene's doubles
 * exactly), with the coordinates loaded in the ray's axis order instead of
 * selected. */
static inline int rt__tri_hit_pk(const rt_ray_pre *p, const rt_pk *k, int i, double tmin, double tmax, int tie,
                                 double *t, int *front)
{
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const double ox = p->ok[0], oy = p->ok[1], oz = p->ok[2];
    return rt__tri_core(p, (double)k->v[kx][i] - ox, (double)k->v[ky][i] - oy, (double)k->v[kz][i] - oz,
                        (double)k->v[3 + kx][i] - ox, (double)k->v[3 + ky][i] - oy, (double)k->v[3 + kz][i] - oz,
                        (double)k->v[6 + kx][i] - ox, (double)k->v[6 + ky][i] - oy, (double)k->v[6 + kz][i] - oz,
                        (k->ref[i] & p->cull_mask) != 0, tmin, tmax, tie, t, front);
}

/* The same on a lane's double copy (RT_REF_DBL): v = A, B, C, xyz each. */
static inline int rt__tri_hit_drec(const rt_ray_pre *p, const double *v, int cull, double tmin, double tmax, int tie,
                                   double *t, int *front)
{
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const double ox = p->ok[0], oy = p->ok[1], oz = p->ok[2];
    return rt__tri_core(p, v[kx] - ox, v[ky] - oy, v[kz] - oz, v[3 + kx] - ox, v[3 + ky] - oy, v[3 + kz] - oz,
                        v[6 + kx] - ox, v[6 + ky] - oy, v[6 + kz] - oz, cull, tmin, tmax, tie, t, front);
}

/* The double copy of lane i of packet k (RT_REF_DBL). */
static inline const double *rt__pk_dverts(const rt_accel *a, const rt_pk *k, int i)
{
    return a->dverts + 9 * ((size_t)(k - a->pks) * RT_PK + (size_t)i);
}

/* Vertex c of a FAST or DBL lane. */
static inline rr_vec3 rt__pk_vert(const rt_accel *a, const rt_pk *k, int i, int c)
{
    if ((k->ref[i] & RT_REF_LANE) == RT_REF_FAST)
        return rr_v3((double)k->v[3 * c][i], (double)k->v[3 * c + 1][i], (double)k->v[3 * c + 2][i]);
    const double *v = rt__pk_dverts(a, k, i) + 3 * c;
    return rr_v3(v[0], v[1], v[2]);
}

/* Fills hit for the FAST or DBL triangle of lane i of packet k met with
 * `front` at t, as rt__prim_hit does (the normal by the formula of
 * scene_tri_normal, on the same doubles). */
static inline void rt__tri_fill(const rt_accel *a, const rt_pk *k, int i, int front, double t, rt_hit *hit)
{
    rr_vec3 A = rt__pk_vert(a, k, i, 0);
    rr_vec3 n = rr_v3_norm(rr_v3_cross(rr_v3_sub(rt__pk_vert(a, k, i, 1), A), rr_v3_sub(rt__pk_vert(a, k, i, 2), A)));
    const scene_tri *tri = &a->scene->tris[k->ref[i] >> RT_REF_SHIFT];
    hit->tri = (int64_t)(k->ref[i] >> RT_REF_SHIFT);
    hit->part = -1;
    hit->object = tri->object;
    hit->material = tri->material;
    hit->normal = front ? n : rr_v3_neg(n);
    hit->t = t;
    hit->front = front;
}

/* ---- the packets' float test ----
 *
 * rt__pk_cand returns the lanes of a packet that the exact test must see:
 * every used lane but the triangles that the exact test would certainly
 * reject because their edge functions have opposite signs, or because all
 * three are negative (a back face) and the lane's object culls back faces
 * in this query (ref & rt_ray_pre.cull_mask). It evaluates
 * the watertight test's sheared coordinates and edge functions in float, on
 * the origin and the shear rounded to nearest, and rejects a lane only when
 * one of U, V, W is below -E and another above +E, or (culling) all three
 * below -E, E bounding the float
 * values' distance from the exact ones (and so from the double ones, whose
 * own error is 2^29 times smaller and inside the bound's slack). Every
 * rejection is one the double test makes too (all three negative: the
 * sign test passes, det = U + V + W < 0, the face is culled), and the long-double
 * recomputation at exact zeros cannot happen for it (|U| > E > 0): the hits
 * are the double test's, bit for bit.
 *
 * The bound, u = 2^-24, V >= every |vertex coordinate| (rt_accel.vmax, the
 * double ones for RT_REF_DBL lanes), O = max |origin coordinate| in float,
 * |Sx|, |Sy| <= 1 (kz is the direction's largest axis):
 *   a = v - o in float: off by u|v - o| + u|v| (DBL rounding) + u|o|
 *     (origin rounding) <= 2u (V + O)(1 + u);
 *   Ax = a_x - Sx a_z: twice that, plus u|a_z| for the rounded shear, the
 *     product's and the difference's roundings: in all at most
 *     8u (V + O)(1 + 5u) < Ep := 9u (V + O)  (rt__pkray_init);
 *   U = Cx By - Cy Bx with each input within Ep of exact and M the largest
 *     |Ax|, |Ay|, ..., |Cy| of the lane: off by at most 4 Ep M + 2 Ep^2 (the
 *     inputs) + 4u M^2 (1 + 3u) (two products and a difference);
 *   E = M (4 Ep + 5u M) + 2 Ep^2 + 1e-37 (the last term for products that
 *     underflow, whose error is absolute, at most 2^-150).
 * The slack (9 against 8 (1 + 5u), 5 against 4 (1 + 3u)) covers the roundings
 * of E's own computation and the double test's errors. Rays whose origin
 * and vertices do not satisfy V + O < 1e18 (M^2 would overflow), and those
 * the slab test hands to double (rt_ray_pre.box_double), get Ep = +inf: E is
 * then +inf or NaN, and no lane is rejected. NaN vertices (lanes of other
 * primitives) give NaN edge values, which no comparison rejects.
 *
 * In a packet of 4 it is about 60 SSE instructions. The exact test it saves
 * costs about 30 for a miss (it leaves at the sign test), so the packets pay
 * through the larger leaves they make affordable, not per test
 * (notes/performance.md, "Leaf packets"). */
#if defined(RT_SIMD) && RT_SIMD >= 1
#define RT_PK_SIMD 1
#include <emmintrin.h>
#else
#define RT_PK_SIMD 0
#endif
#define RT_PK_U 5.9604645e-8f /* 2^-24 */

/* Per-ray operands of rt__pk_cand (broadcast once per ray). */
typedef struct rt_pkray {
#if RT_PK_SIMD
    __m128 o[3], sx, sy, e1, e2; /* e1 = 4 Ep, e2 = 2 Ep^2 + 1e-37 */
    __m128i cull;                /* rt_ray_pre.cull_mask in every lane */
#else
    float o[3], sx, sy, e1, e2;
    uint32_t cull;
#endif
    int kx, ky, kz;
} rt_pkray;

/* exact_only: every lane goes to the exact test (for the rays whose slab
 * test is the double one, rt_ray_pre.box_double). */
static inline void rt__pkray_init(const rt_ray_pre *p, float vmax, int exact_only, rt_pkray *r)
{
    float o[3] = {(float)p->ok[0], (float)p->ok[1], (float)p->ok[2]};
    /* The largest |o| by comparisons (fmaxf is a libm call here); a NaN
     * origin makes vmax + om NaN below either way. */
    float om = fabsf(o[0]), o1 = fabsf(o[1]), o2 = fabsf(o[2]);
    om = o1 > om ? o1 : om;
    om = o2 > om ? o2 : om;
    /* Ep = 9u (vmax + O) and e1 = 4 Ep, e2 = 2 Ep^2 + 1e-37 in float: each
     * operation rounds by at most u = 6e-8 relative, and the factor
     * 1 + 2^-20 (1e-6) more than makes up for the five of them. */
    const float grow = 1.0f + 0x1p-20f;
    float ep = (vmax + om) * (9.0f * RT_PK_U * grow);
    float e1 = 4.0f * ep, e2 = (2.0f * grow) * (ep * ep) + 1e-37f;
    if (exact_only || !(vmax + om < 1e18f)) {
        e1 = INFINITY;
        e2 = INFINITY;
    }
    float sx = (float)p->Sx, sy = (float)p->Sy;
#if RT_PK_SIMD
    for (int k = 0; k < 3; k++)
        r->o[k] = _mm_set1_ps(o[k]);
    r->sx = _mm_set1_ps(sx);
    r->sy = _mm_set1_ps(sy);
    r->e1 = _mm_set1_ps(e1);
    r->e2 = _mm_set1_ps(e2);
    r->cull = _mm_set1_epi32((int)p->cull_mask);
#else
    for (int k = 0; k < 3; k++)
        r->o[k] = o[k];
    r->sx = sx;
    r->sy = sy;
    r->e1 = e1;
    r->e2 = e2;
    r->cull = p->cull_mask;
#endif
    r->kx = p->kx;
    r->ky = p->ky;
    r->kz = p->kz;
}

/* The float test in plain C, lane by lane (RADRAY_SIMD=OFF, and the
 * reference of the SSE version: the same operations). */
static inline unsigned rt__pk_cand_scalar(const rt_pk *k, float o[3], float sx, float sy, float e1, float e2,
                                          uint32_t cull, int kx, int ky, int kz)
{
    unsigned m = 0;
    for (int i = 0; i < RT_PK; i++) {
        float az = k->v[kz][i] - o[2], bz = k->v[3 + kz][i] - o[2], cz = k->v[6 + kz][i] - o[2];
        float ax = (k->v[kx][i] - o[0]) - sx * az, ay = (k->v[ky][i] - o[1]) - sy * az;
        float bx = (k->v[3 + kx][i] - o[0]) - sx * bz, by = (k->v[3 + ky][i] - o[1]) - sy * bz;
        float cx = (k->v[6 + kx][i] - o[0]) - sx * cz, cy = (k->v[6 + ky][i] - o[1]) - sy * cz;
        float U = cx * by - cy * bx, V = ax * cy - ay * cx, W = bx * ay - by * ax;
        float M = fmaxf(fmaxf(fmaxf(fabsf(ax), fabsf(ay)), fmaxf(fabsf(bx), fabsf(by))), fmaxf(fabsf(cx), fabsf(cy)));
        float E = M * (e1 + M * (5.0f * RT_PK_U)) + e2;
        int neg = (U < -E) | (V < -E) | (W < -E), pos = (U > E) | (V > E) | (W > E);
        int back = (U < -E) & (V < -E) & (W < -E) & ((k->ref[i] & cull) != 0);
        m |= (unsigned)((k->ref[i] != 0) & !(neg & pos) & !back) << i;
    }
    return m;
}

static inline unsigned rt__pk_cand(const rt_pk *k, const rt_pkray *r)
{
    const int kx = r->kx, ky = r->ky, kz = r->kz;
#if RT_PK_SIMD
    __m128 az = _mm_sub_ps(_mm_load_ps(k->v[kz]), r->o[2]);
    __m128 bz = _mm_sub_ps(_mm_load_ps(k->v[3 + kz]), r->o[2]);
    __m128 cz = _mm_sub_ps(_mm_load_ps(k->v[6 + kz]), r->o[2]);
    __m128 ax = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[kx]), r->o[0]), _mm_mul_ps(r->sx, az));
    __m128 ay = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[ky]), r->o[1]), _mm_mul_ps(r->sy, az));
    __m128 bx = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[3 + kx]), r->o[0]), _mm_mul_ps(r->sx, bz));
    __m128 by = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[3 + ky]), r->o[1]), _mm_mul_ps(r->sy, bz));
    __m128 cx = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[6 + kx]), r->o[0]), _mm_mul_ps(r->sx, cz));
    __m128 cy = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(k->v[6 + ky]), r->o[1]), _mm_mul_ps(r->sy, cz));
    __m128 U = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
    __m128 V = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
    __m128 W = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
    const __m128 abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    __m128 M = _mm_max_ps(_mm_max_ps(_mm_and_ps(ax, abs), _mm_and_ps(ay, abs)),
                          _mm_max_ps(_mm_and_ps(bx, abs), _mm_and_ps(by, abs)));
    M = _mm_max_ps(M, _mm_max_ps(_mm_and_ps(cx, abs), _mm_and_ps(cy, abs)));
    __m128 E = _mm_add_ps(_mm_mul_ps(M, _mm_add_ps(r->e1, _mm_mul_ps(M, _mm_set1_ps(5.0f * RT_PK_U)))), r->e2);
    /* One of U, V, W below -E and another above E: the least below -E and
     * the greatest above E. (MINPS and MAXPS return the second operand when
     * one is NaN; U, V, W are NaN all three or none, since finite vertices
     * within V + O < 1e18 give finite values, so a NaN lane stays NaN.) */
    __m128 lo = _mm_min_ps(_mm_min_ps(U, V), W), hi = _mm_max_ps(_mm_max_ps(U, V), W);
    __m128 nE = _mm_xor_ps(E, _mm_set1_ps(-0.0f));
    __m128 miss = _mm_and_ps(_mm_cmplt_ps(lo, nE), _mm_cmpgt_ps(hi, E));
    /* A back face (all three below -E) of a lane whose object culls them. */
    __m128i ref = _mm_load_si128((const __m128i *)k->ref);
    __m128i keep = _mm_cmpeq_epi32(_mm_and_si128(ref, r->cull), _mm_setzero_si128());
    __m128 back = _mm_andnot_ps(_mm_castsi128_ps(keep), _mm_cmplt_ps(hi, nE));
    __m128i unused = _mm_cmpeq_epi32(ref, _mm_setzero_si128());
    return (unsigned)_mm_movemask_ps(_mm_or_ps(_mm_or_ps(miss, back), _mm_castsi128_ps(unused))) ^ 0xfu;
#else
    float o[3] = {r->o[0], r->o[1], r->o[2]};
    return rt__pk_cand_scalar(k, o, r->sx, r->sy, r->e1, r->e2, r->cull, kx, ky, kz);
#endif
}

#endif /* RT_KERNEL_H */
