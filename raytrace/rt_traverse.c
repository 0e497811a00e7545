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

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p)
{
    p->ray = ray;
    double d[3] = {ray.d.x, ray.d.y, ray.d.z};
    double o[3] = {ray.o.x, ray.o.y, ray.o.z};
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
    p->box_double = 0;
    p->cull_mask = RT_REC_CULL;
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
        if (!(fabs(o[i]) < 1e30) || (ad != 0.0 && !(ad > 1e-30 && ad < 1e30)))
            p->box_double = 1;
    }
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
