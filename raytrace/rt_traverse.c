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

/* Whether the box [alo, ahi] meets [blo, bhi] (touching counts). */
static int boxes_meet(rr_vec3 alo, rr_vec3 ahi, rr_vec3 blo, rr_vec3 bhi)
{
    return alo.x <= bhi.x && blo.x <= ahi.x && alo.y <= bhi.y && blo.y <= ahi.y && alo.z <= bhi.z && blo.z <= ahi.z;
}

size_t rt_accel_tris_in_box(const rt_accel *a, rr_vec3 lo, rr_vec3 hi, uint32_t *tri, size_t cap, int *other)
{
    if (other)
        *other = 0;
    if (a->nwnodes == 0)
        return 0;
    const scene *s = a->scene;
    const int W = a->width;
    const size_t bytes = rt__wnode_bytes(W);
    size_t n = 0;
    uint32_t stack[RT_STACK_SIZE];
    int sp = 0;
    stack[sp++] = 0; /* the root, an inner node */
    while (sp > 0) {
        const char *node = (const char *)a->wnodes + (size_t)stack[--sp] * bytes;
        const float *b = (const float *)node; /* b[row][i] at row W + i: rows lo x, hi x, lo y, ... */
        const uint32_t *child = (const uint32_t *)(node + 6 * (size_t)W * sizeof(float));
        for (int i = 0; i < W; i++) {
            /* an empty lane's box (lo +inf, hi -inf) meets nothing */
            if (!(b[0 * W + i] <= hi.x && lo.x <= b[1 * W + i] && b[2 * W + i] <= hi.y && lo.y <= b[3 * W + i] &&
                  b[4 * W + i] <= hi.z && lo.z <= b[5 * W + i]))
                continue;
            if (!(child[i] & RT_LEAF)) {
                RR_CHECK(sp < RT_STACK_SIZE);
                stack[sp++] = child[i];
                continue;
            }
            for (const rt_pk *k = &a->pks[child[i] & ~RT_LEAF];; k++) {
                for (int j = 0; j < RT_PK; j++) {
                    uint32_t ref = k->ref[j], kind = ref & RT_REF_LANE;
                    if (kind == RT_REF_PRIM) {
                        if (other)
                            *other = 1; /* the leaf's box meets the query's: enough to say so */
                    } else if (kind != 0) {
                        const scene_tri *t = &s->tris[ref >> RT_REF_SHIFT];
                        rr_vec3 A = s->verts[t->v[0]], B = s->verts[t->v[1]], C = s->verts[t->v[2]];
                        rr_vec3 tlo = rr_v3(rr_min(A.x, rr_min(B.x, C.x)), rr_min(A.y, rr_min(B.y, C.y)),
                                            rr_min(A.z, rr_min(B.z, C.z)));
                        rr_vec3 thi = rr_v3(rr_max(A.x, rr_max(B.x, C.x)), rr_max(A.y, rr_max(B.y, C.y)),
                                            rr_max(A.z, rr_max(B.z, C.z)));
                        if (boxes_meet(tlo, thi, lo, hi)) {
                            if (n == cap)
                                return cap + 1; /* more than cap: the walk stops */
                            tri[n++] = ref >> RT_REF_SHIFT;
                        }
                    }
                }
                if (k->ref[0] & RT_REF_LAST)
                    break;
            }
        }
    }
    return n;
}
