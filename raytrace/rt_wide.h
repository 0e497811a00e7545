/* rt_wide.h - private to raytrace/: the slab test of one wide node against a
 * ray, all RT_WIDE children at once.
 *
 * Three versions with one contract (tests/test_raytrace.c checks that they
 * agree and that none culls a box the ray touches):
 *   rt__box4_scalar  float, plain C (the portable fallback, RADRAY_SIMD=OFF)
 *   rt__box4_sse     float, SSE2, 4 wide (x86-64 always has it; RADRAY_SIMD=SSE/AUTO)
 *   rt__box4_simd    the SIMD version of the build's width: rt__box4_sse, or
 *                    8 wide with AVX (RADRAY_SIMD=AVX2, RT_WIDE = 8)
 *   rt__box4_double  double, for the rays the float test cannot take
 *                    (rt_ray_pre.box_double), and as the reference in tests
 * rt__box4_fast, on operands prepared once per ray (rt_boxray), is the one
 * the traversal calls (RT_SIMD, set by CMake, selects it). "box4" is
 * historical: every version tests RT_WIDE children.
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

#if defined(RT_SIMD) && RT_SIMD >= 2
#include <immintrin.h>
#elif defined(RT_SIMD) && RT_SIMD >= 1
#include <emmintrin.h>
#endif

/* 1 + RT_BOX_GROW >= (1 + g3) / (1 - g3) with g3 = 3 * 2^-24 / (1 - 3 * 2^-24)
 * (about 1 + 3.6e-7), with room to spare. */
#define RT_BOX_GROW 4.8e-7f

/* Float nearest to x rounded up / down (x a double; NaN stays NaN). One ulp
 * step by the bit pattern (floats of one sign are ordered as integers), which
 * is nextafterf without the library call. */
static inline float rt__f_step(float f, int up)
{
    if (f == 0.0f)
        return up ? FLT_TRUE_MIN : -FLT_TRUE_MIN;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    u = (up == (f > 0.0f)) ? u + 1 : u - 1;
    memcpy(&f, &u, sizeof f);
    return f;
}
static inline float rt__f_up(double x)
{
    float f = (float)x;
    return (double)f < x ? rt__f_step(f, 1) : f;
}
static inline float rt__f_down(double x)
{
    float f = (float)x;
    return (double)f > x ? rt__f_step(f, 0) : f;
}

static inline unsigned rt__box4_scalar(const rt_wnode *n, const rt_ray_pre *p, float tmin, float tmax,
                                       float dist[RT_WIDE])
{
    unsigned mask = 0;
    for (int i = 0; i < RT_WIDE; i++) {
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

#if defined(RT_SIMD) && RT_SIMD >= 2
/* 8 wide, AVX: the SSE code on 256-bit registers (VMINPS/VMAXPS have the same
 * NaN rule). */
static inline unsigned rt__box4_simd(const rt_wnode *n, const rt_ray_pre *p, float tmin, float tmax,
                                     float dist[RT_WIDE])
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
#elif defined(RT_SIMD) && RT_SIMD >= 1
#define rt__box4_simd rt__box4_sse
static inline unsigned rt__box4_sse(const rt_wnode *n, const rt_ray_pre *p, float tmin, float tmax,
                                    float dist[RT_WIDE])
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
#if defined(RT_SIMD) && RT_SIMD >= 2
    __m256 on[3], of[3], inv[3];
    int row[3];
#elif defined(RT_SIMD) && RT_SIMD >= 1
    __m128 on[3], of[3], inv[3];
    int row[3];
#else
    const rt_ray_pre *p;
#endif
} rt_boxray;

static inline void rt__boxray_init(const rt_ray_pre *p, rt_boxray *br)
{
#if defined(RT_SIMD) && RT_SIMD >= 2
    for (int k = 0; k < 3; k++) {
        br->on[k] = _mm256_set1_ps(p->org_near[k]);
        br->of[k] = _mm256_set1_ps(p->org_far[k]);
        br->inv[k] = _mm256_set1_ps(p->inv_f[k]);
        br->row[k] = p->near_row[k];
    }
#elif defined(RT_SIMD) && RT_SIMD >= 1
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
static inline unsigned rt__box4_fast(const rt_wnode *n, const rt_boxray *br, float tmin, float tmax,
                                     float dist[RT_WIDE])
{
#if defined(RT_SIMD) && RT_SIMD >= 2
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
#elif defined(RT_SIMD) && RT_SIMD >= 1
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
static inline unsigned rt__box4_double(const rt_wnode *n, const rt_ray_pre *p, double tmin, double tmax,
                                       float dist[RT_WIDE])
{
    const double o[3] = {p->ray.o.x, p->ray.o.y, p->ray.o.z};
    unsigned mask = 0;
    for (int i = 0; i < RT_WIDE; i++) {
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


#endif
