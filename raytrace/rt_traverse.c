/* rt_traverse.c - ray queries through the wide BVH: closest hit and any hit.
 *
 * Both walk the same nodes with the same per-primitive kernels; the only
 * difference is that the any-hit query returns at the first occluder. The
 * walk itself is in rt_wide.h, instantiated here for 4-wide nodes
 * (rt__walk4), in rt_bvh_avx2.c for 8-wide nodes (rt__walk8) and in
 * rt_bvh_avx512.c for 16-wide nodes (rt__walk16); the queries take the one
 * of the accel's width. */
#include <float.h>

#define RT_W 4
#define RT_WALK rt__walk4
#define RT_OCCL rt__occl4
#include "rt_wide.h"

#if defined(RT_SIMD) && RT_SIMD >= 1
/* The per-axis part of rt__ray_prepare in SSE2, three axes at once and
 * without branches (for incoherent rays the selections by the direction's
 * signs were mispredicted): the same values as the scalar loop below. The
 * origin rounded up and down (rt__f_up, rt__f_down: the float nearest o,
 * stepped one ulp by its bit pattern when the rounding went the wrong way),
 * the near and far origins picked by the sign bits, 1/d in double and float,
 * and whether the float slab test can take the ray. */
static inline void prepare_axes(const double d[3], const double o[3], rt_ray_pre *p)
{
    __m128d d01 = _mm_loadu_pd(d), d2 = _mm_load_sd(d + 2);
    __m128d o01 = _mm_loadu_pd(o), o2 = _mm_load_sd(o + 2);
    const __m128d one = _mm_set1_pd(1.0);
    __m128d inv01 = _mm_div_pd(one, d01), inv2 = _mm_div_sd(one, d2);
    _mm_storeu_pd(p->inv, inv01);
    _mm_store_sd(p->inv + 2, inv2);
    _mm_storeu_ps(p->inv_f, _mm_movelh_ps(_mm_cvtpd_ps(inv01), _mm_cvtpd_ps(inv2)));
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
static inline void prepare_axes(const double d[3], const double o[3], rt_ray_pre *p)
{
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

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p)
{
    p->ray = ray;
    double d[3] = {ray.d.x, ray.d.y, ray.d.z};
    double o[3] = {ray.o.x, ray.o.y, ray.o.z};
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
    p->cull_mask = RT_REF_CULL;
    prepare_axes(d, o, p);
    p->Sz = p->inv[kz]; /* 1 / d[kz], the same division */
    p->ok[0] = o[kx];
    p->ok[1] = o[ky];
    p->ok[2] = o[kz];
}

int rt__tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax, double *t,
                int *front)
{
    return rt__tri_hit_inl(p, A, B, C, cull, tmin, tmax, t, front);
}

static int walk(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int mode)
{
#if RT_HAVE_W8
#if RT_HAVE_W16
    if (a->width == 16)
        return rt__walk16(a, ray, tmin, tmax, hit, mode);
#endif
    if (a->width == 8)
        return rt__walk8(a, ray, tmin, tmax, hit, mode);
#endif
    return rt__walk4(a, ray, tmin, tmax, hit, mode);
}

/* Rays traced by this thread (rt_ray_counts). */
static _Thread_local rt_ray_counts t_counts;

rt_ray_counts rt_ray_counts_of_thread(void) { return t_counts; }

void rt_ray_counts_add_since(rt_ray_counts *total, rt_ray_counts before)
{
    uint64_t dc = t_counts.closest - before.closest, dn = t_counts.occluded - before.occluded;
#pragma omp atomic
    total->closest += dc;
#pragma omp atomic
    total->occluded += dn;
}

int rt_accel_closest(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit)
{
    t_counts.closest++;
    return walk(a, ray, tmin, tmax, hit, 0);
}

int rt_accel_closest_two_sided(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit)
{
    t_counts.closest++;
    return walk(a, ray, tmin, tmax, hit, RT_WALK_TWO_SIDED);
}

int rt_accel_occluded(const rt_accel *a, rr_ray ray, double tmin, double tmax)
{
    t_counts.occluded++;
#if RT_HAVE_W8
#if RT_HAVE_W16
    if (a->width == 16)
        return rt__occl16(a, ray, tmin, tmax);
#endif
    if (a->width == 8)
        return rt__occl8(a, ray, tmin, tmax);
#endif
    return rt__occl4(a, ray, tmin, tmax);
}
