/* rt_wide.h - private to raytrace/: the slab test of one wide node against a
 * ray (all children at once), the shared triangle kernel, and the walk of
 * the wide BVH, for one node width per translation unit.
 *
 * A file defines RT_W (4 or 8; 4 if not) and, to get the walk, RT_WALK (the
 * function's name), then includes this header: rt_traverse.c instantiates
 * rt__walk4, rt_bvh_avx2.c (compiled for AVX2) rt__walk8. The width-
 * independent part (triangle kernel, rounding helpers) is the same source in
 * both, and the 8-wide file is compiled with -mavx2 but not -mfma, so the
 * double arithmetic of the triangle test is the same operation for operation
 * (no contraction into FMA): both widths give the same hits bit for bit.
 *
 * Versions of the box test, one contract (tests/test_raytrace.c checks that
 * they agree and that none culls a box the ray touches):
 *   rt__box4_scalar  float, plain C (the portable fallback, RADRAY_SIMD=OFF)
 *   rt__box4_simd    float, SSE2 4 wide (RT_W 4, RT_SIMD >= 1) or AVX 8 wide
 *                    (RT_W 8)
 *   rt__box4_double  double, for the rays the float test cannot take
 *                    (rt_ray_pre.box_double), and as the reference in tests
 * rt__box4_fast, on operands prepared once per ray (rt_boxray), is the one
 * the walk calls. "box4" is historical: every version tests RT_W children.
 *
 * Contract: returns a bit mask of the children whose box the ray meets within
 * [tmin, tmax], up to rounding and always erring on the side of "meets" (a box
 * the ray touches in that interval is never culled). For the children in the
 * mask, dist[i] <= (exact entry distance) * (1 + RT_BOX_GROW), so a child
 * taken from the stack whose dist exceeds the best hit's t times
 * (1 + RT_BOX_GROW) cannot hold a nearer hit and is skipped.
 *
 * Why the float test is conservative (Ize 2013, "Robust BVH ray traversal",
 * JCGT 2(2)): the box planes are floats rounded outward at build time. The
 * double origin is rounded to float twice, towards each slab's near plane
 * (org_near) and towards its far plane (org_far), so that plane - origin is
 * never smaller than the exact value on the far side and never larger on the
 * near side, whatever the direction's sign. What remains are three roundings
 * (the difference, 1/d, the product), each of relative size at most 2^-24 and
 * sign-preserving: an entry distance comes out at most (1 + g3) too large, an
 * exit at most (1 - g3) too small, g3 = 3u/(1-3u). Scaling the exit by
 * (1 + g3)/(1 - g3) < 1 + RT_BOX_GROW therefore keeps every box whose exact
 * entry <= exit. tmin is rounded down and tmax up (callers pass them so).
 *
 * Zero direction components: 1/+-0 = +-inf, and (plane - origin) * inf is
 * +-inf, or NaN when the origin lies on the plane. MINPS/MAXPS return their
 * second operand when either is NaN, so with the running bound as the second
 * operand a NaN slab does not restrict the interval ("inside that slab"), as
 * in the double test; the scalar version writes the same comparisons. The
 * empty lanes (lo = +inf, hi = -inf) give entry +inf, exit -inf for every
 * direction, never NaN: always missed.
 */
#ifndef RT_WIDE_H
#define RT_WIDE_H

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
                        (r->flags & RT_REC_CULL) != 0, tmin, tmax, tie, t, front);
}

static inline rr_vec3 rt__rec_vert(const rt_rec *r, int k)
{
    return rr_v3((double)r->v[k][0], (double)r->v[k][1], (double)r->v[k][2]);
}

/* Fills hit for the fast triangle of record r met with `front` at t, as
 * rt__prim_hit does (the normal by the formula of scene_tri_normal, on the
 * same doubles). */
static inline void rt__tri_fill(const rt_rec *r, int front, double t, rt_hit *hit)
{
    rr_vec3 A = rt__rec_vert(r, 0);
    rr_vec3 n = rr_v3_norm(rr_v3_cross(rr_v3_sub(rt__rec_vert(r, 1), A), rr_v3_sub(rt__rec_vert(r, 2), A)));
    hit->tri = (int64_t)r->index;
    hit->part = -1;
    hit->object = r->flags >> RT_REC_OBJ_SHIFT;
    hit->material = r->material;
    hit->normal = front ? n : rr_v3_neg(n);
    hit->t = t;
    hit->front = front;
}

#endif /* RT_WIDE_H */

/* ---- one width: RT_W (this part is read once per translation unit) ---- */
#ifndef RT_WIDE_W_DONE
#define RT_WIDE_W_DONE

#ifndef RT_W
#define RT_W 4
#endif
#if RT_W == 8
#if !RT_HAVE_W8 || !defined(__AVX2__)
#error "rt_wide.h: RT_W 8 needs RT_SIMD >= 2 and a file compiled for AVX2"
#endif
typedef rt_wnode8 rt_wn;
#define RT_BOX_SIMD 2 /* AVX, 8 lanes */
#include <immintrin.h>
#elif RT_W == 4
typedef rt_wnode4 rt_wn;
#if defined(RT_SIMD) && RT_SIMD >= 1
#define RT_BOX_SIMD 1 /* SSE2, 4 lanes */
#include <emmintrin.h>
#else
#define RT_BOX_SIMD 0
#endif
#else
#error "rt_wide.h: RT_W must be 4 or 8"
#endif

static inline unsigned rt__box4_scalar(const rt_wn *n, const rt_ray_pre *p, float tmin, float tmax,
                                       float dist[RT_W])
{
    unsigned mask = 0;
    for (int i = 0; i < RT_W; i++) {
        float t0 = tmin, t1 = INFINITY;
        for (int k = 0; k < 3; k++) {
            float ta = (n->b[p->near_row[k]][i] - p->org_near[k]) * p->inv_f[k];
            float tb = (n->b[p->near_row[k] ^ 1][i] - p->org_far[k]) * p->inv_f[k];
            t0 = ta > t0 ? ta : t0; /* NaN: keeps t0, like MAXPS(ta, t0) */
            t1 = tb < t1 ? tb : t1;
        }
        t1 *= 1.0f + RT_BOX_GROW;
        t1 = tmax < t1 ? tmax : t1;
        dist[i] = t0;
        mask |= (unsigned)(t0 <= t1) << i;
    }
    return mask;
}

#if RT_BOX_SIMD == 2
/* 8 wide, AVX: the SSE code on 256-bit registers (VMINPS/VMAXPS have the same
 * NaN rule). */
static inline unsigned rt__box4_simd(const rt_wn *n, const rt_ray_pre *p, float tmin, float tmax,
                                     float dist[RT_W])
{
    __m256 t0 = _mm256_set1_ps(tmin), t1 = _mm256_set1_ps(INFINITY);
    for (int k = 0; k < 3; k++) {
        int row = p->near_row[k];
        __m256 inv = _mm256_set1_ps(p->inv_f[k]);
        __m256 ta = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[row]), _mm256_set1_ps(p->org_near[k])), inv);
        __m256 tb = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[row ^ 1]), _mm256_set1_ps(p->org_far[k])), inv);
        t0 = _mm256_max_ps(ta, t0);
        t1 = _mm256_min_ps(tb, t1);
    }
    t1 = _mm256_min_ps(_mm256_set1_ps(tmax), _mm256_mul_ps(t1, _mm256_set1_ps(1.0f + RT_BOX_GROW)));
    _mm256_storeu_ps(dist, t0);
    return (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(t0, t1, _CMP_LE_OQ));
}
#elif RT_BOX_SIMD == 1
#define rt__box4_simd rt__box4_sse
static inline unsigned rt__box4_sse(const rt_wn *n, const rt_ray_pre *p, float tmin, float tmax,
                                    float dist[RT_W])
{
    const int nx = p->near_row[0], ny = p->near_row[1], nz = p->near_row[2];
    __m128 tx0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nx]), _mm_set1_ps(p->org_near[0])), _mm_set1_ps(p->inv_f[0]));
    __m128 ty0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[ny]), _mm_set1_ps(p->org_near[1])), _mm_set1_ps(p->inv_f[1]));
    __m128 tz0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nz]), _mm_set1_ps(p->org_near[2])), _mm_set1_ps(p->inv_f[2]));
    __m128 tx1 =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nx ^ 1]), _mm_set1_ps(p->org_far[0])), _mm_set1_ps(p->inv_f[0]));
    __m128 ty1 =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[ny ^ 1]), _mm_set1_ps(p->org_far[1])), _mm_set1_ps(p->inv_f[1]));
    __m128 tz1 =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nz ^ 1]), _mm_set1_ps(p->org_far[2])), _mm_set1_ps(p->inv_f[2]));
    /* Running bound second: a NaN slab leaves it as it is. */
    __m128 t0 = _mm_max_ps(tz0, _mm_max_ps(ty0, _mm_max_ps(tx0, _mm_set1_ps(tmin))));
    __m128 t1 = _mm_min_ps(tz1, _mm_min_ps(ty1, _mm_min_ps(tx1, _mm_set1_ps(INFINITY))));
    t1 = _mm_min_ps(_mm_set1_ps(tmax), _mm_mul_ps(t1, _mm_set1_ps(1.0f + RT_BOX_GROW)));
    _mm_storeu_ps(dist, t0);
    return (unsigned)_mm_movemask_ps(_mm_cmple_ps(t0, t1));
}
#endif

/* The per-ray operands of the float test in the form the selected version
 * wants them (for SSE: broadcast once per ray, kept in registers during the
 * walk, instead of once per node). */
typedef struct rt_boxray {
#if RT_BOX_SIMD == 2
    __m256 on[3], of[3], inv[3];
    int row[3];
#elif RT_BOX_SIMD == 1
    __m128 on[3], of[3], inv[3];
    int row[3];
#else
    const rt_ray_pre *p;
#endif
} rt_boxray;

static inline void rt__boxray_init(const rt_ray_pre *p, rt_boxray *br)
{
#if RT_BOX_SIMD == 2
    for (int k = 0; k < 3; k++) {
        br->on[k] = _mm256_set1_ps(p->org_near[k]);
        br->of[k] = _mm256_set1_ps(p->org_far[k]);
        br->inv[k] = _mm256_set1_ps(p->inv_f[k]);
        br->row[k] = p->near_row[k];
    }
#elif RT_BOX_SIMD == 1
    for (int k = 0; k < 3; k++) {
        br->on[k] = _mm_set1_ps(p->org_near[k]);
        br->of[k] = _mm_set1_ps(p->org_far[k]);
        br->inv[k] = _mm_set1_ps(p->inv_f[k]);
        br->row[k] = p->near_row[k];
    }
#else
    br->p = p;
#endif
}

/* The selected test on prepared operands; same results as rt__box4_simd
 * (or rt__box4_scalar when there is no SIMD). */
static inline unsigned rt__box4_fast(const rt_wn *n, const rt_boxray *br, float tmin, float tmax,
                                     float dist[RT_W])
{
#if RT_BOX_SIMD == 2
    const int nx = br->row[0], ny = br->row[1], nz = br->row[2];
    __m256 tx0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[nx]), br->on[0]), br->inv[0]);
    __m256 ty0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[ny]), br->on[1]), br->inv[1]);
    __m256 tz0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[nz]), br->on[2]), br->inv[2]);
    __m256 tx1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[nx ^ 1]), br->of[0]), br->inv[0]);
    __m256 ty1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[ny ^ 1]), br->of[1]), br->inv[1]);
    __m256 tz1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->b[nz ^ 1]), br->of[2]), br->inv[2]);
    __m256 t0 = _mm256_max_ps(tz0, _mm256_max_ps(ty0, _mm256_max_ps(tx0, _mm256_set1_ps(tmin))));
    __m256 t1 = _mm256_min_ps(tz1, _mm256_min_ps(ty1, _mm256_min_ps(tx1, _mm256_set1_ps(INFINITY))));
    t1 = _mm256_min_ps(_mm256_set1_ps(tmax), _mm256_mul_ps(t1, _mm256_set1_ps(1.0f + RT_BOX_GROW)));
    _mm256_storeu_ps(dist, t0);
    return (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(t0, t1, _CMP_LE_OQ));
#elif RT_BOX_SIMD == 1
    const int nx = br->row[0], ny = br->row[1], nz = br->row[2];
    __m128 tx0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nx]), br->on[0]), br->inv[0]);
    __m128 ty0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[ny]), br->on[1]), br->inv[1]);
    __m128 tz0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nz]), br->on[2]), br->inv[2]);
    __m128 tx1 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nx ^ 1]), br->of[0]), br->inv[0]);
    __m128 ty1 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[ny ^ 1]), br->of[1]), br->inv[1]);
    __m128 tz1 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n->b[nz ^ 1]), br->of[2]), br->inv[2]);
    __m128 t0 = _mm_max_ps(tz0, _mm_max_ps(ty0, _mm_max_ps(tx0, _mm_set1_ps(tmin))));
    __m128 t1 = _mm_min_ps(tz1, _mm_min_ps(ty1, _mm_min_ps(tx1, _mm_set1_ps(INFINITY))));
    t1 = _mm_min_ps(_mm_set1_ps(tmax), _mm_mul_ps(t1, _mm_set1_ps(1.0f + RT_BOX_GROW)));
    _mm_storeu_ps(dist, t0);
    return (unsigned)_mm_movemask_ps(_mm_cmple_ps(t0, t1));
#else
    return rt__box4_scalar(n, br->p, tmin, tmax, dist);
#endif
}

/* The double test (the binary BVH's node_entry, for each lane): exact up to
 * the double roundings, which the exit widening by (1 + 2 g3 in double)
 * covers. dist is the entry rounded down to float. */
static inline unsigned rt__box4_double(const rt_wn *n, const rt_ray_pre *p, double tmin, double tmax,
                                       float dist[RT_W])
{
    const double o[3] = {p->ray.o.x, p->ray.o.y, p->ray.o.z};
    unsigned mask = 0;
    for (int i = 0; i < RT_W; i++) {
        double t0 = tmin, t1 = tmax;
        for (int k = 0; k < 3; k++) {
            double ta = ((double)n->b[2 * k + p->neg[k]][i] - o[k]) * p->inv[k];
            double tb = ((double)n->b[2 * k + 1 - p->neg[k]][i] - o[k]) * p->inv[k];
            if (ta != ta)
                ta = -INFINITY;
            if (tb != tb)
                tb = INFINITY;
            if (ta > t0)
                t0 = ta;
            tb *= 1.0 + 6.7e-16;
            if (tb < t1)
                t1 = tb;
        }
        dist[i] = rt__f_down(t0);
        mask |= (unsigned)(t0 <= t1) << i;
    }
    return mask;
}

#ifdef RT_WALK
/* ---- the walk ----
 *
 * Ordered traversal: the children a ray enters are visited nearest entry
 * first; the others go on the stack with their entry distance, and an entry
 * taken from the stack that lies beyond the best hit so far is dropped without
 * touching its node. Triangles are tested from the leaf records (rt_rec, a
 * private copy of the vertices), other primitives through rt__prim_hit. */
typedef struct rt_stack_entry {
    uint32_t ref;
    float dist;
} rt_stack_entry;

/* The walk of this width (rt_internal.h): any != 0 returns at the first hit. */
int RT_WALK(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int any)
{
    if (a->nwnodes == 0)
        return 0;
    RR_CHECK(a->width == RT_W);
    const rt_wn *wnodes = a->wnodes;
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    if (!(tmin >= 0.0))
        p.box_double = 1;
    rt_boxray br;
    rt__boxray_init(&p, &br);
    const float grow = 1.0f + RT_BOX_GROW;
    const float tmin_f = rt__f_down(tmin);
    rt_stack_entry stack[RT_STACK_SIZE];
    int sp = 0;
    uint32_t cur = 0; /* the root */
    int found = 0;
    /* A triangle hit is filled in at the end (one normal instead of one per
     * improving hit); tri_best != NULL says the best hit is that record's triangle. */
    const rt_rec *tri_best = NULL;
    int tri_front = 0;
    double best = tmax;
    float best_f = rt__f_up(best);
    float cull = best_f * grow;
    for (;;) {
        if (!(cur & RT_LEAF)) {
            const rt_wn *n = &wnodes[cur];
            float dist[RT_W];
            /* Boxes are tested up to a little beyond the best hit (cull, not
             * best_f): a box entered exactly at the best t may hold a tie of
             * lower index, and a computed entry can exceed the exact one by
             * the factor 1 + RT_BOX_GROW. */
            unsigned mask = p.box_double ? rt__box4_double(n, &p, tmin, best + fabs(best) * 1e-15, dist)
                                         : rt__box4_fast(n, &br, tmin_f, cull, dist);
            if (mask) {
                /* One child entered (the common case deep in the tree): go there. */
                int i = __builtin_ctz(mask);
                mask &= mask - 1;
                if (!mask) {
                    cur = n->child[i];
                    continue;
                }
                /* Two: visit the nearer, push the other. */
                int k = __builtin_ctz(mask);
                mask &= mask - 1;
                uint32_t ri = n->child[i], rk = n->child[k];
                float di = dist[i], dk = dist[k];
                if (!mask) {
                    RR_CHECK(sp < RT_STACK_SIZE);
                    if (dk < di) {
                        stack[sp].ref = ri;
                        stack[sp].dist = di;
                        cur = rk;
                    } else {
                        stack[sp].ref = rk;
                        stack[sp].dist = dk;
                        cur = ri;
                    }
                    sp++;
                    continue;
                }
                /* Three or more: sort by descending distance, push all but the
                 * nearest (farthest first). */
                uint32_t ref[RT_W] = {ri, rk};
                float d[RT_W] = {di, dk};
                int m = 2;
                if (dk > di) {
                    ref[0] = rk, ref[1] = ri;
                    d[0] = dk, d[1] = di;
                }
                for (; mask; mask &= mask - 1) {
                    int c = __builtin_ctz(mask);
                    uint32_t r = n->child[c];
                    float dc = dist[c];
                    int j = m++;
                    while (j > 0 && d[j - 1] < dc) {
                        d[j] = d[j - 1];
                        ref[j] = ref[j - 1];
                        j--;
                    }
                    d[j] = dc;
                    ref[j] = r;
                }
                RR_CHECK(sp + m - 1 <= RT_STACK_SIZE);
                for (int j = 0; j < m - 1; j++) {
                    stack[sp].ref = ref[j];
                    stack[sp].dist = d[j];
                    sp++;
                }
                cur = ref[m - 1];
                continue;
            }
        } else {
            const rt_rec *r = &a->recs[cur & ~RT_LEAF];
            for (;; r++) {
                uint32_t fl = r->flags;
#ifdef RT_ABLATE_TRI_COPY /* measurement only: triangles through the scene arrays */
                if (0) {
#else
                if (fl & RT_REC_FAST) {
#endif
                    double t;
                    int front;
                    /* Exact ties (a ray through a shared edge or vertex)
                     * go to the lowest triangle index, as in rt_ref_closest,
                     * so the hit does not depend on the order the walk
                     * meets the triangles in (the two widths' trees differ). */
                    int tie = tri_best && r->index < tri_best->index;
                    if (rt__tri_hit_rec(&p, r, tmin, best, tie, &t, &front)) {
                        if (any)
                            return 1;
                        found = 1;
                        best = t;
                        tri_best = r;
                        tri_front = front;
                        best_f = rt__f_up(best);
                        cull = best_f * grow;
                    }
                } else {
                    rt_prim pr = {fl & RT_REC_KIND, r->index};
                    if (rt__prim_hit(a, pr, &p, tmin, &best, any ? NULL : hit)) {
                        if (any)
                            return 1;
                        found = 1;
                        tri_best = NULL;
                        best_f = rt__f_up(best);
                        cull = best_f * grow;
                    }
                }
                if (fl & RT_REC_LAST)
                    break;
            }
        }
        /* Pop, dropping entries that now lie beyond the best hit. */
        for (;;) {
            if (sp == 0)
                goto out;
            sp--;
            if (!(stack[sp].dist > cull)) {
                cur = stack[sp].ref;
                break;
            }
        }
    }
out:
    if (found && hit) {
        if (tri_best)
            rt__tri_fill(tri_best, tri_front, best, hit);
        hit->point = rr_ray_at(ray, hit->t);
    }
    return found;
}
#endif /* RT_WALK */

#ifdef RT_OCCL
/* ---- the any-hit walk (rt_accel_occluded) ----
 *
 * Visits the same leaves as RT_WALK with any != 0 (below), only in another
 * order, so it returns the same answer: with any != 0 the best t never falls
 * below tmax (the walk returns at the first hit), so, for tmax >= 0, no entry
 * taken from RT_WALK's stack is ever dropped (an entered child's dist is at
 * most cull: the float test bounds the exit by cull itself, the double test
 * by tmax (1 + 1e-15), which f_up(tmax) (1 + RT_BOX_GROW) rounded exceeds):
 * both walks test every primitive of every leaf whose boxes down from the
 * root the ray enters, and answer whether one of them is hit. Other tmax
 * (negative, NaN) go to RT_WALK.
 *
 * What the order-free walk saves: no sort of the entered children and no
 * distances on the stack (refs only, no compare on pop), and the leaves among
 * the entered children are tested at once, before any inner child is
 * descended into (a shadow ray leaving a surface often ends on a nearby
 * occluder), so only inner nodes ever go on the stack. */

/* Bit i set: child i is a leaf (RT_LEAF is the sign bit of the reference;
 * empty lanes, RT_EMPTY, also read as leaves, but the ray never enters them). */
static inline unsigned rt__leaf_mask(const rt_wn *n)
{
#if RT_BOX_SIMD == 2
    return (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_load_si256((const __m256i *)n->child)));
#elif RT_BOX_SIMD == 1
    return (unsigned)_mm_movemask_ps(_mm_castsi128_ps(_mm_load_si128((const __m128i *)n->child)));
#else
    unsigned m = 0;
    for (int i = 0; i < RT_W; i++)
        m |= (n->child[i] >> 31) << i;
    return m;
#endif
}

/* The any-hit walk of this width (rt_internal.h). */
int RT_OCCL(const rt_accel *a, rr_ray ray, double tmin, double tmax)
{
    if (a->nwnodes == 0)
        return 0;
    if (!(tmax >= 0.0))
        return RT_WALK(a, ray, tmin, tmax, NULL, 1);
    RR_CHECK(a->width == RT_W);
    const rt_wn *wnodes = a->wnodes;
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    if (!(tmin >= 0.0))
        p.box_double = 1;
    rt_boxray br;
    rt__boxray_init(&p, &br);
    const float tmin_f = rt__f_down(tmin);
    const float cull = rt__f_up(tmax) * (1.0f + RT_BOX_GROW);
    const double tmax_d = tmax + fabs(tmax) * 1e-15;
    uint32_t stack[RT_STACK_SIZE];
    int sp = 0;
    uint32_t cur = 0; /* the root, an inner node */
    for (;;) {
        const rt_wn *n = &wnodes[cur];
        float dist[RT_W];
        unsigned mask = p.box_double ? rt__box4_double(n, &p, tmin, tmax_d, dist)
                                     : rt__box4_fast(n, &br, tmin_f, cull, dist);
        unsigned lm = rt__leaf_mask(n);
        for (unsigned leaves = mask & lm; leaves; leaves &= leaves - 1) {
            const rt_rec *r = &a->recs[n->child[__builtin_ctz(leaves)] & ~RT_LEAF];
            for (;; r++) {
                uint32_t fl = r->flags;
                if (fl & RT_REC_FAST) {
                    double t;
                    int front;
                    if (rt__tri_hit_rec(&p, r, tmin, tmax, 0, &t, &front))
                        return 1;
                } else {
                    rt_prim pr = {fl & RT_REC_KIND, r->index};
                    double best = tmax;
                    if (rt__prim_hit(a, pr, &p, tmin, &best, NULL))
                        return 1;
                }
                if (fl & RT_REC_LAST)
                    break;
            }
        }
        unsigned inner = mask & ~lm;
        if (inner) {
            cur = n->child[__builtin_ctz(inner)];
            inner &= inner - 1;
            RR_CHECK(sp + RT_W <= RT_STACK_SIZE);
            for (; inner; inner &= inner - 1)
                stack[sp++] = n->child[__builtin_ctz(inner)];
            continue;
        }
        if (sp == 0)
            return 0;
        cur = stack[--sp];
    }
}
#endif /* RT_OCCL */



#endif /* RT_WIDE_W_DONE */
