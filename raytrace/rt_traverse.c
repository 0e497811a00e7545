/* rt_traverse.c - ray queries through the wide BVH: closest hit, any hit,
 * and closest and any hit for packets of rays (rt_accel_closest_n,
 * rt_accel_occluded_n).
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
#define RT_WALKN rt__walkn4
#define RT_OCCLN rt__occln4
#include "rt_wide.h"

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p)
{
    rt__ray_prepare_box(ray, p, 1);
    rt__ray_prepare_tri(p);
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

int rt_accel_closest_n(const rt_accel *a, const rr_ray *rays, int n, double tmin, double tmax, rt_hit *hits,
                       unsigned char *found)
{
    int nhit = 0;
    for (int i = 0; i < n; i += RT_PACKET_MAX) {
        int m = n - i < RT_PACKET_MAX ? n - i : RT_PACKET_MAX;
        t_counts.closest += (uint64_t)m;
#if RT_HAVE_W8
#if RT_HAVE_W16
        if (a->width == 16) {
            nhit += rt__walkn16(a, rays + i, m, tmin, tmax, hits + i, found + i);
            continue;
        }
#endif
        if (a->width == 8) {
            nhit += rt__walkn8(a, rays + i, m, tmin, tmax, hits + i, found + i);
            continue;
        }
#endif
        nhit += rt__walkn4(a, rays + i, m, tmin, tmax, hits + i, found + i);
    }
    return nhit;
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

int rt_accel_occluded_n(const rt_accel *a, const rr_ray *rays, int n, double tmin, double tmax, unsigned char *occ)
{
    int nocc = 0;
    for (int i = 0; i < n; i += RT_PACKET_MAX) {
        int m = n - i < RT_PACKET_MAX ? n - i : RT_PACKET_MAX;
        t_counts.occluded += (uint64_t)m;
#if RT_HAVE_W8
#if RT_HAVE_W16
        if (a->width == 16) {
            nocc += rt__occln16(a, rays + i, m, tmin, tmax, occ + i);
            continue;
        }
#endif
        if (a->width == 8) {
            nocc += rt__occln8(a, rays + i, m, tmin, tmax, occ + i);
            continue;
        }
#endif
        nocc += rt__occln4(a, rays + i, m, tmin, tmax, occ + i);
    }
    return nocc;
}
