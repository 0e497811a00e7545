/* rt_wide.h - private to raytrace/: the slab test of one wide node against a
 * ray (all children at once) and the walk of the wide BVH, for one node width
 * per translation unit (the width-independent kernel is rt_kernel.h).
 *
 * A file defines RT_W (4, 8 or 16; 4 if not) and, to get the walks, RT_WALK
 * (the closest-hit walk's name), RT_OCCL (the any-hit walk), RT_WALKN and
 * RT_OCCLN (the packet walks, rt_accel_closest_n and rt_accel_occluded_n,
 * in rt_packet.h and rt_packet_occl.h), then includes this header: rt_traverse.c instantiates
 * rt__walk4 / rt__occl4 / rt__walkn4 / rt__occln4, rt_bvh_avx2.c (compiled
 * for AVX2) the 8-wide ones, rt_bvh_avx512.c (compiled for AVX-512F) the
 * 16-wide ones. The packet walks' frustum and 16-ray tests exist on 16-wide
 * nodes only; the other widths walk packets with per-ray tests.
 *
 * Versions of the box test, one contract (tests/test_bvh.c checks that they
 * agree and that none culls a box the ray touches):
 *   rt__box4_fast    float, on operands prepared once per ray (rt_boxray):
 *                    the one the walk calls; AVX-512 16 lanes (RT_W 16), AVX
 *                    8 lanes (RT_W 8), SSE2 4 lanes (RT_W 4, RT_SIMD >= 1),
 *                    else rt__box4_scalar
 *   rt__box4_scalar  float, plain C (the portable fallback, RADRAY_SIMD=OFF,
 *                    and the reference the SIMD versions must equal)
 *   rt__box4_double  double, for the rays the float test cannot take
 *                    (rt_ray_pre.box_double)
 * "box4" is historical: every version tests RT_W children.
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
 * The 16-wide version computes plane * inv - c in one fused multiply-add
 * per plane instead of (plane - origin) * inv, with c = o inv_f padded
 * outward per side (rt__boxray_init: cn >= o inv_f >= cf exactly). Then
 * plane inv_f - cn <= (plane - o) inv_f <= plane inv_f - cf before the one
 * rounding of the FMA, and (plane - o) inv_f is the exact distance times
 * (1 + delta), |delta| <= u: an entry comes out at most (1 + u)^2 too large,
 * an exit at most (1 - u)^2 too small, inside the same RT_BOX_GROW. It needs
 * a finite inv_f and |c| < 1e37: rays with a zero direction component take
 * rt__box4_double in that walk. (On 8-wide AVX2 nodes the fused form was
 * measured at 0.92-1.02x the speed, notes/performance.md: not used there.)
 *
 * Zero direction components: 1/+-0 = +-inf, and (plane - origin) * inf is
 * +-inf, or NaN when the origin lies on the plane. MINPS/MAXPS return their
 * second operand when either is NaN, so with the running bound as the second
 * operand a NaN slab does not restrict the interval ("inside that slab"), as
 * in the double test; the scalar version writes the same comparisons. The
 * empty lanes (lo = +inf, hi = -inf) give entry +inf, exit -inf for every
 * direction, never NaN: always missed.
 */
#include "rt_kernel.h"

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
#elif RT_W == 16
#if !RT_HAVE_W16 || !defined(__AVX512F__)
#error "rt_wide.h: RT_W 16 needs RT_HAVE_W16 and a file compiled for AVX-512F"
#endif
typedef rt_wnode16 rt_wn;
#define RT_BOX_SIMD 3 /* AVX-512, 16 lanes */
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
#error "rt_wide.h: RT_W must be 4, 8 or 16"
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

/* The per-ray operands of the float test in the form the selected version
 * wants them (for SSE: broadcast once per ray, kept in registers during the
 * walk, instead of once per node). */
typedef struct rt_boxray {
#if RT_BOX_SIMD == 3
    __m512 cn[3], cf[3], inv[3]; /* o inv padded up (near) and down (far), inv */
    int row[3];
#elif RT_BOX_SIMD == 2
    __m256 on[3], of[3], inv[3];
    int row[3];
#elif RT_BOX_SIMD == 1
    __m128 on[3], of[3], inv[3];
    int row[3];
#else
    const rt_ray_pre *p;
#endif
} rt_boxray;

/* The same operands as floats, one broadcast away (a packet's rays keep
 * theirs in this form: RT_WALKN): a, b are cn, cf (16-wide) or the origin
 * rounded towards the near and far planes (org_near, org_far). */
typedef struct rt_boxops {
    float a[3], b[3], inv[3];
    int row[3];
} rt_boxops;

/* Returns 0 when the float test cannot take the ray (the walk then uses
 * rt__box4_double): for the fused form, a zero direction component or
 * |o / d| >= 1e37. */
static inline int rt__boxops_init(const rt_ray_pre *p, rt_boxops *o)
{
    for (int k = 0; k < 3; k++) {
        o->inv[k] = p->inv_f[k];
        o->row[k] = p->near_row[k];
    }
#if RT_BOX_SIMD == 3
    /* c = o inv_f per axis in double (lane 3 unused), padded by 2^-22 |c| +
     * 1e-44 and rounded to float: the pad is more than the rounding to
     * nearest float can take back (2^-24 |c|, or half the smallest
     * subnormal) and than the double product's error, so cn >= o inv_f >= cf
     * exactly. Boxes grow by about 2^-22 |o / d| along the ray: nothing. */
    __m256d c = _mm256_mul_pd(_mm256_loadu_pd(&p->ray.o.x), _mm256_cvtps_pd(_mm_loadu_ps(p->inv_f)));
    __m256d ac = _mm256_andnot_pd(_mm256_set1_pd(-0.0), c);
    __m256d pad = _mm256_add_pd(_mm256_mul_pd(ac, _mm256_set1_pd(0x1p-22)), _mm256_set1_pd(1e-44));
    float cn[4], cf[4];
    _mm_storeu_ps(cn, _mm256_cvtpd_ps(_mm256_add_pd(c, pad)));
    _mm_storeu_ps(cf, _mm256_cvtpd_ps(_mm256_sub_pd(c, pad)));
    for (int k = 0; k < 3; k++) {
        o->a[k] = cn[k];
        o->b[k] = cf[k];
    }
    /* |c| < 1e37 on the three axes: false for NaN, and for inv_f = +-inf (d = 0). */
    return (_mm256_movemask_pd(_mm256_cmp_pd(ac, _mm256_set1_pd(1e37), _CMP_LT_OQ)) & 7) == 7;
#else
    for (int k = 0; k < 3; k++) {
        o->a[k] = p->org_near[k];
        o->b[k] = p->org_far[k];
    }
    return 1;
#endif
}

static inline void rt__boxray_of(const rt_boxops *o, const rt_ray_pre *p, rt_boxray *br)
{
#if RT_BOX_SIMD == 3
    for (int k = 0; k < 3; k++) {
        br->cn[k] = _mm512_set1_ps(o->a[k]);
        br->cf[k] = _mm512_set1_ps(o->b[k]);
        br->inv[k] = _mm512_set1_ps(o->inv[k]);
        br->row[k] = o->row[k];
    }
    (void)p;
#elif RT_BOX_SIMD == 2
    for (int k = 0; k < 3; k++) {
        br->on[k] = _mm256_set1_ps(o->a[k]);
        br->of[k] = _mm256_set1_ps(o->b[k]);
        br->inv[k] = _mm256_set1_ps(o->inv[k]);
        br->row[k] = o->row[k];
    }
    (void)p;
#elif RT_BOX_SIMD == 1
    for (int k = 0; k < 3; k++) {
        br->on[k] = _mm_set1_ps(o->a[k]);
        br->of[k] = _mm_set1_ps(o->b[k]);
        br->inv[k] = _mm_set1_ps(o->inv[k]);
        br->row[k] = o->row[k];
    }
    (void)p;
#else
    (void)o;
    br->p = p;
#endif
}

static inline int rt__boxray_init(const rt_ray_pre *p, rt_boxray *br)
{
    rt_boxops o;
    int ok = rt__boxops_init(p, &o);
    rt__boxray_of(&o, p, br);
    return ok;
}

/* The float test of this SIMD width on prepared operands: AVX 8 lanes, SSE2
 * 4 lanes (VMINPS/VMAXPS and MINPS/MAXPS have the same NaN rule), or
 * rt__box4_scalar when there is no SIMD; the same results as rt__box4_scalar
 * bit for bit (tested), except the 16-wide fused form, which is tested for
 * the contract itself (test_bvh wide_simd_box_tests_conservative). */
static inline unsigned rt__box4_fast(const rt_wn *n, const rt_boxray *br, float tmin, float tmax,
                                     float dist[RT_W])
{
#if RT_BOX_SIMD == 3
    /* plane inv - c in one fused multiply-add per plane (rt__boxray_init). */
    const int nx = br->row[0], ny = br->row[1], nz = br->row[2];
    __m512 tx0 = _mm512_fmsub_ps(_mm512_load_ps(n->b[nx]), br->inv[0], br->cn[0]);
    __m512 ty0 = _mm512_fmsub_ps(_mm512_load_ps(n->b[ny]), br->inv[1], br->cn[1]);
    __m512 tz0 = _mm512_fmsub_ps(_mm512_load_ps(n->b[nz]), br->inv[2], br->cn[2]);
    __m512 tx1 = _mm512_fmsub_ps(_mm512_load_ps(n->b[nx ^ 1]), br->inv[0], br->cf[0]);
    __m512 ty1 = _mm512_fmsub_ps(_mm512_load_ps(n->b[ny ^ 1]), br->inv[1], br->cf[1]);
    __m512 tz1 = _mm512_fmsub_ps(_mm512_load_ps(n->b[nz ^ 1]), br->inv[2], br->cf[2]);
    __m512 t0 = _mm512_max_ps(_mm512_max_ps(tx0, ty0), _mm512_max_ps(tz0, _mm512_set1_ps(tmin)));
    __m512 t1 = _mm512_min_ps(_mm512_min_ps(tx1, ty1), tz1);
    t1 = _mm512_min_ps(_mm512_set1_ps(tmax), _mm512_mul_ps(t1, _mm512_set1_ps(1.0f + RT_BOX_GROW)));
    _mm512_storeu_ps(dist, t0);
    return (unsigned)_mm512_cmp_ps_mask(t0, t1, _CMP_LE_OQ);
#elif RT_BOX_SIMD == 2
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

#ifdef RT_BOXTEST
/* The walk's box test on one node of this width (an rt_wn), for tests
 * (rt_internal.h): the float test (*fast = 1) or, for the rays it cannot
 * take, the double one (*fast = 0), as the walk chooses. */
unsigned RT_BOXTEST(const void *node, rr_ray ray, double tmin, double tmax, float *dist, int *fast)
{
    const rt_wn *n = node;
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    rt_boxray br;
    *fast = rt__boxray_init(&p, &br) && !p.box_double && tmin >= 0.0;
    return *fast ? rt__box4_fast(n, &br, rt__f_down(tmin), rt__f_up(tmax), dist)
                 : rt__box4_double(n, &p, tmin, tmax, dist);
}
#endif

/* Bit i set: child i is a leaf (RT_LEAF is the sign bit of the reference;
 * empty lanes, RT_EMPTY, also read as leaves, but the ray never enters them). */
static inline unsigned rt__leaf_mask(const rt_wn *n)
{
#if RT_BOX_SIMD == 3
    return (unsigned)_mm512_cmplt_epi32_mask(_mm512_load_si512((const void *)n->child), _mm512_setzero_si512());
#elif RT_BOX_SIMD == 2
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

/* Lane i of packet k (a candidate of the float test) against one ray: 1 at
 * a hit with t in (tmin, tmax), culling back faces as the object asks. The
 * any-hit walks' lane test (RT_OCCL, RT_OCCLN). */
static inline __attribute__((always_inline)) int rt__lane_any(const rt_accel *a, const rt_pk *k, int i,
                                                               const rt_ray_pre *p, double tmin, double tmax)
{
    uint32_t fl = k->ref[i], lk = fl & RT_REF_LANE;
    if (lk != RT_REF_PRIM) {
        double t;
        int front;
        return lk == RT_REF_FAST ? rt__tri_hit_pk(p, k, i, tmin, tmax, 0, &t, &front)
                                 : rt__tri_hit_drec(p, rt__pk_dverts(a, k, i), (fl & RT_REF_CULL) != 0, tmin, tmax, 0,
                                                    &t, &front);
    }
    rt_prim pr_ = {rt_prim_kind_of(a->scene, fl >> RT_REF_SHIFT), fl >> RT_REF_SHIFT};
    double best = tmax;
    return rt__prim_hit(a, pr_, p, tmin, &best, NULL);
}

#ifdef RT_WALK
/* ---- the walk ----
 *
 * Ordered traversal: the children a ray enters are visited nearest entry
 * first; the others go on the stack with their entry distance, and an entry
 * taken from the stack that lies beyond the best hit so far is dropped without
 * touching its node. A leaf's packets go through the float test first
 * (rt__pk_cand); the lanes it keeps get the exact test, triangles from the
 * packet's copy of their vertices, other primitives through rt__prim_hit. */
typedef struct rt_stack_entry {
    uint32_t ref;
    float dist;
} rt_stack_entry;

/* The best hit of one ray so far (RT_WALK's, and each ray's of RT_WALKN). A
 * triangle hit is filled in at the end (one normal instead of one per
 * improving hit): tri != NULL says the best hit is the triangle of lane
 * `lane` of that packet; a primitive's hit is filled as it is found. */
typedef struct rt_best {
    double t;         /* tmax until a hit is found */
    float cull;       /* f_up(t) (1 + RT_BOX_GROW): a box entered beyond it holds no nearer hit */
    const rt_pk *tri;
    int lane, front, back_cull, found;
} rt_best;

static inline void rt__best_init(rt_best *b, double tmax)
{
    memset(b, 0, sizeof *b);
    b->t = tmax;
    b->cull = rt__f_up(tmax) * (1.0f + RT_BOX_GROW);
}

/* Lane i of packet k (a candidate of the float test) against one ray:
 * improves *b (and fills *hit for a primitive); with any, returns 1 at a
 * hit. Inlined into the walks (a call cost primary rays 4 %). */
static inline __attribute__((always_inline)) int rt__lane_closest(const rt_accel *a, const rt_pk *k, int i,
                                                                   const rt_ray_pre *p, double tmin, int any, int two,
                                                                   rt_best *b, rt_hit *hit)
{
    uint32_t fl = k->ref[i], lk = fl & RT_REF_LANE;
    if (lk != RT_REF_PRIM) {
        double t;
        int front;
        /* Exact ties (a ray through a shared edge or vertex) go to the
         * lowest triangle index, as in rt_ref_closest, and a triangle wins
         * a tie with another primitive (rt__prim_hit takes only a t below
         * the best), so the hit does not depend on the order the walk meets
         * them in (the widths' trees differ, and RT_WALKN's order): a solid's
         * cap flush with a floor. */
        int tie = b->tri ? fl >> RT_REF_SHIFT < b->tri->ref[b->lane] >> RT_REF_SHIFT : b->found;
        /* Two-sided: a back face of a culling object a hair beyond a front
         * face wins (RT_TIE_REL), so that a ray leaving a closed box through
         * a face that lies flush with another surface's front (a board
         * standing on the floor) meets the box first, as the burial rule
         * needs. */
        double lim = two && b->tri && b->front ? b->t + fabs(b->t) * RT_TIE_REL : b->t;
        /* Two inline calls, not one helper: gcc did not inline the helper,
         * and primary rays lost 4 % (mesh-1m). */
        int got = lk == RT_REF_FAST ? rt__tri_hit_pk(p, k, i, tmin, lim, tie, &t, &front)
                                    : rt__tri_hit_drec(p, rt__pk_dverts(a, k, i), (fl & p->cull_mask) != 0, tmin, lim,
                                                       tie, &t, &front);
        if (got && t >= b->t && !(t == b->t && tie))
            got = !front && (fl & RT_REF_CULL);
        else if (got && two && b->back_cull && front && t > b->t - fabs(b->t) * RT_TIE_REL)
            got = 0; /* nor does a front face a hair before it */
        if (got) {
            if (any)
                return 1;
            b->found = 1;
            b->t = t;
            b->tri = k;
            b->lane = i;
            b->front = front;
            b->back_cull = !front && (fl & RT_REF_CULL);
            b->cull = rt__f_up(t) * (1.0f + RT_BOX_GROW);
        }
    } else {
        rt_prim pr_ = {rt_prim_kind_of(a->scene, fl >> RT_REF_SHIFT), fl >> RT_REF_SHIFT};
        if (rt__prim_hit(a, pr_, p, tmin, &b->t, any ? NULL : hit)) {
            if (any)
                return 1;
            b->found = 1;
            b->tri = NULL;
            b->back_cull = 0;
            b->cull = rt__f_up(b->t) * (1.0f + RT_BOX_GROW);
        }
    }
    return 0;
}

/* The primitives of the leaf whose first packet is k against one ray
 * (rt__lane_closest on the lanes rt__pk_cand keeps). */
static inline __attribute__((always_inline)) int rt__leaf_closest(const rt_accel *a, const rt_pk *k,
                                                                   const rt_ray_pre *p, const rt_pkray *pr,
                                                                   double tmin, int any, int two, rt_best *b,
                                                                   rt_hit *hit)
{
    for (;; k++) {
        for (unsigned lanes = rt__pk_cand(k, pr); lanes; lanes &= lanes - 1)
            if (rt__lane_closest(a, k, __builtin_ctz(lanes), p, tmin, any, two, b, hit))
                return 1;
        if (k->ref[0] & RT_REF_LAST)
            return 0;
    }
}

/* The hit record of a ray's best hit (found). */
static inline void rt__best_fill(const rt_accel *a, const rt_best *b, rr_ray ray, rt_hit *hit)
{
    if (b->tri)
        rt__tri_fill(a, b->tri, b->lane, b->front, b->t, hit);
    hit->point = rr_ray_at(ray, hit->t);
}

/* The walk of this width (rt_internal.h); mode: RT_WALK_ANY returns at the
 * first hit, RT_WALK_TWO_SIDED culls no back faces. */
int RT_WALK(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int mode)
{
    const int any = mode & RT_WALK_ANY, two = mode & RT_WALK_TWO_SIDED;
    if (a->nwnodes == 0)
        return 0;
    RR_CHECK(a->width == RT_W);
    const rt_wn *wnodes = a->wnodes;
    rt_ray_pre p;
    rt__ray_prepare_box(ray, &p, RT_BOX_SIMD != 3);
    if (!(tmin >= 0.0))
        p.box_double = 1;
    if (mode & RT_WALK_TWO_SIDED)
        p.cull_mask = 0;
    /* The triangles' set-up (rt__ray_prepare_tri, the packets' operands) at
     * once, as in RT_OCCL: its divisions overlap the box operands' chain. */
    rt__ray_prepare_tri(&p);
    rt_pkray pr;
    rt__pkray_init(&p, a->vmax, p.box_double, &pr);
    rt_boxray br;
    if (!rt__boxray_init(&p, &br))
        p.box_double = 1;
    const float tmin_f = rt__f_down(tmin);
    rt_stack_entry stack[RT_STACK_SIZE];
    int sp = 0;
    uint32_t cur = 0; /* the root */
    rt_best b;
    rt__best_init(&b, tmax);
    for (;;) {
        if (!(cur & RT_LEAF)) {
            const rt_wn *n = &wnodes[cur];
            float dist[RT_W];
            /* Boxes are tested up to a little beyond the best hit (cull, not
             * f_up(t)): a box entered exactly at the best t may hold a tie of
             * lower index, and a computed entry can exceed the exact one by
             * the factor 1 + RT_BOX_GROW. */
            unsigned mask = p.box_double ? rt__box4_double(n, &p, tmin, b.t + fabs(b.t) * 1e-15, dist)
                                         : rt__box4_fast(n, &br, tmin_f, b.cull, dist);
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
            if (rt__leaf_closest(a, &a->pks[cur & ~RT_LEAF], &p, &pr, tmin, any, two, &b, hit))
                return 1;
        }
        /* Pop, dropping entries that now lie beyond the best hit. */
        for (;;) {
            if (sp == 0)
                goto out;
            sp--;
            if (!(stack[sp].dist > b.cull)) {
                cur = stack[sp].ref;
                break;
            }
        }
    }
out:
    if (b.found && hit)
        rt__best_fill(a, &b, ray, hit);
    return b.found;
}

#ifdef RT_WALKN
#include "rt_packet.h" /* the packet walk, on this width's box tests and rt__lane_closest */
#endif
#ifdef RT_OCCLN
#include "rt_packet_occl.h" /* the packet any-hit walk, on rt_packet.h's set-up and rt__lane_any */
#endif
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

/* The any-hit walk of this width (rt_internal.h). */
int RT_OCCL(const rt_accel *a, rr_ray ray, double tmin, double tmax)
{
    if (a->nwnodes == 0)
        return 0;
    if (!(tmax >= 0.0))
        return RT_WALK(a, ray, tmin, tmax, NULL, RT_WALK_ANY);
    RR_CHECK(a->width == RT_W);
    const rt_wn *wnodes = a->wnodes;
    rt_ray_pre p;
    rt__ray_prepare_box(ray, &p, RT_BOX_SIMD != 3);
    if (!(tmin >= 0.0))
        p.box_double = 1;
    /* The triangles' set-up at once, as in RT_WALK, not at the first leaf:
     * nearly every shadow ray reaches a leaf, and begun here its divisions
     * overlap the box operands' chain and the root's test instead of
     * holding up the first leaf (notes/performance.md). */
    rt__ray_prepare_tri(&p);
    rt_pkray pr;
    rt__pkray_init(&p, a->vmax, p.box_double, &pr);
    rt_boxray br;
    if (!rt__boxray_init(&p, &br))
        p.box_double = 1;
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
        unsigned leaves = mask & lm;
        for (; leaves; leaves &= leaves - 1) {
            const rt_pk *k = &a->pks[n->child[__builtin_ctz(leaves)] & ~RT_LEAF];
            for (;; k++) {
                for (unsigned lanes = rt__pk_cand(k, &pr); lanes; lanes &= lanes - 1)
                    if (rt__lane_any(a, k, __builtin_ctz(lanes), &p, tmin, tmax))
                        return 1;
                if (k->ref[0] & RT_REF_LAST)
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
