/* rt_traverse.c - ray queries through the wide BVH: closest hit and any hit.
 *
 * Both walk the same nodes with the same per-primitive kernels; the only
 * difference is that the any-hit query returns at the first occluder.
 *
 * Ordered traversal: the children a ray enters are visited nearest entry
 * first; the others go on the stack with their entry distance, and an entry
 * taken from the stack that lies beyond the best hit so far is dropped without
 * touching its node. Triangles are tested from the leaf records (rt_rec, a
 * private copy of the vertices), other primitives through rt__prim_hit. */
#include <float.h>

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

static double comp(rr_vec3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

/* The test on the vertices relative to the origin, already in the ray's axis
 * order (kx, ky, kz). Bitwise | instead of || in the sign tests: the same
 * result with fewer branches. */
static inline int tri_core(const rt_ray_pre *p, double akx, double aky, double az, double bkx, double bky, double bz,
                           double ckx, double cky, double cz, int cull, double tmin, double tmax, double *t,
                           int *front)
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
    if (!(tt > tmin && tt < tmax))
        return 0;
    *t = tt;
    *front = is_front;
    return 1;
}

static inline int tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax,
                          double *t, int *front)
{
    rr_vec3 o = p->ray.o;
    rr_vec3 a = rr_v3_sub(A, o), b = rr_v3_sub(B, o), c = rr_v3_sub(C, o);
    return tri_core(p, comp(a, p->kx), comp(a, p->ky), comp(a, p->kz), comp(b, p->kx), comp(b, p->ky),
                    comp(b, p->kz), comp(c, p->kx), comp(c, p->ky), comp(c, p->kz), cull, tmin, tmax, t, front);
}

/* tri_hit on a leaf record's fast triangle: the same arithmetic (the float
 * vertices are the scene's doubles exactly), with the coordinates loaded in
 * the ray's axis order instead of selected. */
static inline int tri_hit_rec(const rt_ray_pre *p, const rt_rec *r, double tmin, double tmax, double *t, int *front)
{
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const double ox = p->ok[0], oy = p->ok[1], oz = p->ok[2];
    return tri_core(p, (double)r->v[0][kx] - ox, (double)r->v[0][ky] - oy, (double)r->v[0][kz] - oz,
                    (double)r->v[1][kx] - ox, (double)r->v[1][ky] - oy, (double)r->v[1][kz] - oz,
                    (double)r->v[2][kx] - ox, (double)r->v[2][ky] - oy, (double)r->v[2][kz] - oz,
                    (r->flags & RT_REC_CULL) != 0, tmin, tmax, t, front);
}

int rt__tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax, double *t,
                int *front)
{
    return tri_hit(p, A, B, C, cull, tmin, tmax, t, front);
}

static inline rr_vec3 rec_vert(const rt_rec *r, int k)
{
    return rr_v3((double)r->v[k][0], (double)r->v[k][1], (double)r->v[k][2]);
}

/* Fills hit for the fast triangle of record r met with `front` at t, as
 * rt__prim_hit does (the normal by the formula of scene_tri_normal, on the
 * same doubles). */
static void tri_fill(const rt_rec *r, int front, double t, rt_hit *hit)
{
    rr_vec3 A = rec_vert(r, 0);
    rr_vec3 n = rr_v3_norm(rr_v3_cross(rr_v3_sub(rec_vert(r, 1), A), rr_v3_sub(rec_vert(r, 2), A)));
    hit->tri = (int64_t)r->index;
    hit->part = -1;
    hit->object = r->flags >> RT_REC_OBJ_SHIFT;
    hit->material = r->material;
    hit->normal = front ? n : rr_v3_neg(n);
    hit->t = t;
    hit->front = front;
}

typedef struct stack_entry {
    uint32_t ref;
    float dist;
} stack_entry;

/* Shared walk: any != 0 returns at the first hit. */
static int traverse(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int any)
{
    if (a->nwnodes == 0)
        return 0;
    rt_ray_pre p;
    rt__ray_prepare(ray, &p);
    if (!(tmin >= 0.0))
        p.box_double = 1;
    rt_boxray br;
    rt__boxray_init(&p, &br);
    const float grow = 1.0f + RT_BOX_GROW;
    const float tmin_f = rt__f_down(tmin);
    stack_entry stack[RT_STACK_SIZE];
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
            const rt_wnode *n = &a->wnodes[cur];
            float dist[RT_WIDE];
            unsigned mask = p.box_double ? rt__box4_double(n, &p, tmin, best, dist)
                                         : rt__box4_fast(n, &br, tmin_f, best_f, dist);
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
                uint32_t ref[RT_WIDE] = {ri, rk};
                float d[RT_WIDE] = {di, dk};
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
                    if (tri_hit_rec(&p, r, tmin, best, &t, &front)) {
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
            tri_fill(tri_best, tri_front, best, hit);
        hit->point = rr_ray_at(ray, hit->t);
    }
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
