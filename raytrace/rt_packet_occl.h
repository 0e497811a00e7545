/* rt_packet_occl.h - private to raytrace/: the packet any-hit walk
 * (RT_OCCLN, rt_accel_occluded_n) of one node width. Included by rt_wide.h
 * after rt_packet.h, inside its RT_WALK part, when the file defines
 * RT_OCCLN: it uses rt_packet.h's set-up, frustum and 16-ray tests and
 * rt_wide.h's box tests and lane test (rt__lane_any). Not to be included on
 * its own. */
#ifndef RT_W
#error "rt_packet_occl.h is included by rt_wide.h"
#endif

/* ---- the packet any-hit walk (rt_accel_occluded_n) ----
 *
 * RT_OCCL for up to RT_PACKET_MAX rays together, in its order-free form:
 * at each node the rays that enter each child are found (per ray, or by
 * the frustum and 16 rays at a time, below), the leaf children are tested
 * at once for their rays, and the inner children go on the stack with
 * their rays. A ray leaves the packet at its first occluder (done), and
 * the walk ends when every ray has one. Each ray meets every leaf whose
 * boxes down from the root it enters (and, through the frustum path's
 * untested inner children, possibly more; an exact hit lies in every box
 * around it, which the single walk's conservative box test enters), and
 * the lanes are tested by RT_OCCL's own code (rt__lane_any): the same
 * answer as rt_accel_occluded for every ray (test_packet checks it).
 *
 * On 16-wide nodes a packet takes the frustum path of RT_WALKN when its
 * rays share their origin (a point light's rays to surface points), or
 * when they share their end point o + d and tmax <= 1: the shadow rays of
 * a tile towards one point light or one light sample. Such segments
 * o + t d, t in [tmin, tmax], are e - s d with e = o + d and s = 1 - t in
 * [1 - tmax, 1 - tmin], within [0, 1]: rays from the common end point P
 * with directions -d, once every e is within Delta of P per axis. So the
 * frustum is set up for those reversed rays (rt_frustum from P, 1/-d as
 * the interval), with P moved by Delta towards each slab's near plane
 * and away from its far one, which tests every box grown by Delta: a box
 * that a segment meets, grown by Delta, is met by the reversed ray at the
 * same s. Every ray still takes its own per-ray box test (rt__box_rays) at
 * nodes with leaf children. */

typedef struct rt_occ_entry {
    uint64_t rays;
    uint32_t ref;
} rt_occ_entry;

#if RT_BOX_SIMD == 3
/* The float nearest x on the side of +inf (up) or -inf; x is a double that
 * may itself be rounded, so it is first moved by its own rounding error. */
static inline float rt__f_out(double x, int up)
{
    double pad = fabs(x) * 0x1p-52 + 0x1p-1074;
    return up ? rt__f_up(x + pad) : rt__f_down(x - pad);
}

/* The reversed frustum of a packet of rays that share their end point
 * o + d (see above), from P, the centre of the end points' bounding box,
 * with Delta its half-size (plus the sums' rounding) per axis. 0 when the
 * end points are further apart than a part in 2^30 of their size: rays to
 * different points of an area light. For those a frustum grown by the
 * light's size did not pay (bench shadow rays to points of a square of 2 %
 * and 5 % of the scene: 0.92x and 0.69-0.99x the per-ray packet walk,
 * notes/performance.md), nor would the leaves' 16-ray test, whose bound
 * grows with Delta; nor when the rays' rows differ. rows and inv as the
 * per-ray operands give them. */
static int rt__frustum_end(const rr_ray *rays, int nr, const rt_boxops *ops, rt_frustum *f, double P[3],
                           double *delta_max)
{
    for (int r = 1; r < nr; r++)
        for (int k = 0; k < 3; k++)
            if (ops[r].row[k] != ops[0].row[k])
                return 0;
    double elo[3], ehi[3], pad[3] = {0.0, 0.0, 0.0}, size = 0.0, dm = 0.0;
    float lo[3], hi[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = hi[k] = ops[0].inv[k];
        elo[k] = ehi[k] = (&rays[0].o.x)[k] + (&rays[0].d.x)[k];
    }
    /* Comparisons, not fmax (rt__abs_max3). */
    for (int r = 0; r < nr; r++) {
        const double *o = &rays[r].o.x, *d = &rays[r].d.x;
        for (int k = 0; k < 3; k++) {
            double e = o[k] + d[k];
            double ae = e < 0.0 ? -e : e, ad = d[k] < 0.0 ? -d[k] : d[k];
            elo[k] = e < elo[k] ? e : elo[k];
            ehi[k] = e > ehi[k] ? e : ehi[k];
            /* the sum's rounding: u |e| */
            pad[k] = ae > pad[k] ? ae : pad[k];
            size = ae > size ? ae : size;
            dm = ad > dm ? ad : dm;
            lo[k] = ops[r].inv[k] < lo[k] ? ops[r].inv[k] : lo[k];
            hi[k] = ops[r].inv[k] > hi[k] ? ops[r].inv[k] : hi[k];
        }
    }
    size = dm > size ? dm : size;
    *delta_max = 0.0;
    double delta[3];
    for (int k = 0; k < 3; k++) {
        P[k] = 0.5 * (elo[k] + ehi[k]);
        /* |exact o + d - P| <= half the box, + the sums' rounding (u |e|)
         * and that of P and of the half (u |P| each, |P| <= max |e|): 2^-50
         * max |e| covers them. */
        delta[k] = 0.5 * (ehi[k] - elo[k]) * (1.0 + 0x1p-50) + pad[k] * 0x1p-50;
        if (!(delta[k] <= size * 0x1p-30 + 1e-300))
            return 0;
        *delta_max = delta[k] > *delta_max ? delta[k] : *delta_max;
    }
    for (int k = 0; k < 3; k++) {
        /* The reversed rays' direction on axis k is -d: positive where the
         * rays' near row is the upper plane (d < 0). */
        const int row = ops[0].row[k], pos = row & 1;
        f->row[k] = row ^ 1;
        f->ilo[k] = _mm512_set1_ps(-hi[k]);
        f->ihi[k] = _mm512_set1_ps(-lo[k]);
        /* Near side: P moved away from the near plane (the entry comes out
         * no later than the grown box's); far side: towards it. */
        f->on[k] = _mm512_set1_ps(rt__f_out(pos ? P[k] + delta[k] : P[k] - delta[k], pos));
        f->of[k] = _mm512_set1_ps(rt__f_out(pos ? P[k] - delta[k] : P[k] + delta[k], !pos));
    }
    return 1;
}
#endif

int RT_OCCLN(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, unsigned char *occ)
{
    RR_CHECK(nr >= 1 && nr <= RT_PACKET_MAX && a->width == RT_W);
    memset(occ, 0, (size_t)nr);
    if (a->nwnodes == 0)
        return 0;
    if (!(tmax >= 0.0)) { /* RT_OCCL's rule: such rays go to RT_WALK */
        int c = 0;
        for (int r = 0; r < nr; r++) {
            occ[r] = (unsigned char)RT_WALK(a, rays[r], tmin, tmax, NULL, RT_WALK_ANY);
            c += occ[r];
        }
        return c;
    }
    const rt_wn *wnodes = a->wnodes;
    rt_pkt_ray st[RT_PACKET_MAX];
    rt_boxops ops[RT_PACKET_MAX];
    const uint64_t dbl = rt__pkt_rays_init(rays, nr, tmin, tmax, st, ops);
    const float tmin_f = rt__f_down(tmin);
    const float cull = rt__f_up(tmax) * (1.0f + RT_BOX_GROW);
    const double tmax_d = tmax + fabs(tmax) * 1e-15;
    const uint64_t all = nr == 64 ? ~(uint64_t)0 : ((uint64_t)1 << nr) - 1;
#if RT_BOX_SIMD == 3
    /* The frustum: one origin, or one end point (tmax <= 1). The leaves'
     * 16-ray test (rt__pkt_tri_cand) from the point P: the shared origin
     * exactly, or the end point within delta. */
    rt_frustum fru;
    float ftmin = tmin_f, ftmax = cull;
    int fr = 0, tri16 = 0, end = 0;
    double P[3] = {rays[0].o.x, rays[0].o.y, rays[0].o.z}, delta = 0.0, rpad = 0.0;
    if (!dbl && rt__frustum_origin(st, ops, nr, &fru)) {
        fr = 1;
        tri16 = rt__pkt_one_origin(rays, nr);
    } else if (!dbl && tmax <= 1.0 && rt__frustum_end(rays, nr, ops, &fru, P, &delta)) {
        /* s in [0, 1] (tmin >= 0 here: dbl is clear); an entry at s <= 1
         * comes out at most 1 + RT_BOX_GROW. */
        fr = tri16 = end = 1;
        ftmin = 0.0f;
        ftmax = 1.0f + RT_BOX_GROW;
    }
    _Alignas(64) float dxs[RT_PACKET_MAX], dys[RT_PACKET_MAX], dzs[RT_PACKET_MAX];
    const double dmax = tri16 ? rt__pkt_dirs(rays, nr, dxs, dys, dzs) : 0.0;
    if (end)
        rpad = dmax + delta; /* the end point: the double test's vertices lie within R + D + delta of o */
    _Alignas(64) float scn[3][RT_PACKET_MAX], scf[3][RT_PACKET_MAX], sinv[3][RT_PACKET_MAX], cullv[RT_PACKET_MAX];
    if (fr) {
        rt__pkt_soa(ops, nr, scn, scf, sinv);
        for (int r = 0; r < RT_PACKET_MAX; r++)
            cullv[r] = cull;
    }
#endif
    rt_occ_entry stack[RT_STACK_SIZE];
    int sp = 0;
    uint32_t cur = 0; /* the root, an inner node */
    uint64_t act = all, done = 0;
    for (;;) {
        const rt_wn *n = &wnodes[cur];
        const unsigned lm = rt__leaf_mask(n);
        uint64_t in[RT_W];
        unsigned any = 0;
#if RT_BOX_SIMD == 3
        if (fr) {
            float fd[RT_W];
            unsigned fm = rt__box_frustum(n, &fru, ftmin, ftmax, fd);
            const int leaves = (fm & lm) != 0;
            for (; fm; fm &= fm - 1) {
                int c = __builtin_ctz(fm);
                in[c] = leaves ? rt__box_rays(n, c, ops[0].row, scn, scf, sinv, cullv, tmin_f, act) : act;
                any |= (unsigned)(in[c] != 0) << c;
            }
        } else
#endif
        {
            for (int c = 0; c < RT_W; c++)
                in[c] = 0;
            for (uint64_t m = act; m; m &= m - 1) {
                int r = __builtin_ctzll(m);
                float dist[RT_W];
                unsigned mask;
                if (dbl >> r & 1) {
                    mask = rt__box4_double(n, &st[r].p, tmin, tmax_d, dist);
                } else {
                    rt_boxray br;
                    rt__boxray_of(&ops[r], &st[r].p, &br);
                    mask = rt__box4_fast(n, &br, tmin_f, cull, dist);
                }
                any |= mask;
                for (; mask; mask &= mask - 1)
                    in[__builtin_ctz(mask)] |= (uint64_t)1 << r;
            }
        }
        /* The leaf children first, for all their rays. */
        for (unsigned leaves = any & lm; leaves; leaves &= leaves - 1) {
            int c = __builtin_ctz(leaves);
            const rt_pk *k0 = &a->pks[n->child[c] & ~RT_LEAF];
#if RT_BOX_SIMD == 3
            if (tri16 && __builtin_popcountll(in[c] & ~done) > RT_PKT_TRI16_MIN) {
                /* 16 rays per triangle, then the exact test for the rays kept. */
                for (const rt_pk *k = k0;; k++) {
                    float nf[9][4], e0[4];
                    int ok = rt__pkt_normals(a, k, P[0], P[1], P[2], dmax, rpad, delta, nf, e0);
                    unsigned slow = rt__pkt_slow_mask(k, ok);
                    uint64_t lanes[RT_PK];
                    if (slow)
                        rt__pkt_slow_lanes(a, k, slow, in[c] & ~done, st, lanes);
                    for (int i = 0; i < RT_PK; i++) {
                        uint32_t fl = k->ref[i];
                        uint64_t cand = in[c] & ~done;
                        if (!fl || !cand)
                            continue;
                        cand = rt__pkt_lane_cand(k, i, slow, lanes, nf, e0, cand, dxs, dys, dzs);
                        for (; cand; cand &= cand - 1) {
                            int r = __builtin_ctzll(cand);
                            rt_pkt_ray *s = &st[r];
                            rt__pkt_ready(a, s);
                            if (rt__lane_any(a, k, i, &s->p, tmin, tmax))
                                done |= (uint64_t)1 << r;
                        }
                    }
                    if ((k->ref[0] & RT_REF_LAST) || !(in[c] & ~done))
                        break;
                }
                continue;
            }
#endif
            for (uint64_t m = in[c] & ~done; m; m &= m - 1) {
                int r = __builtin_ctzll(m);
                rt_pkt_ray *s = &st[r];
                rt__pkt_ready(a, s);
                for (const rt_pk *k = k0;; k++) {
                    unsigned lanes = rt__pk_cand(k, &s->pr);
                    for (; lanes; lanes &= lanes - 1)
                        if (rt__lane_any(a, k, __builtin_ctz(lanes), &s->p, tmin, tmax))
                            break;
                    if (lanes) {
                        done |= (uint64_t)1 << r;
                        break;
                    }
                    if (k->ref[0] & RT_REF_LAST)
                        break;
                }
            }
        }
        if (done == all)
            break;
        /* The inner children: the first is walked next, the others pushed. */
        int next = 0;
        for (unsigned inner = any & ~lm; inner; inner &= inner - 1) {
            int c = __builtin_ctz(inner);
            uint64_t m = in[c] & ~done;
            if (!m)
                continue;
            if (!next) {
                cur = n->child[c];
                act = m;
                next = 1;
                continue;
            }
            RR_CHECK(sp < RT_STACK_SIZE);
            stack[sp].rays = m;
            stack[sp].ref = n->child[c];
            sp++;
        }
        if (next)
            continue;
        for (;;) {
            if (sp == 0)
                goto out;
            sp--;
            act = stack[sp].rays & ~done;
            if (act) {
                cur = stack[sp].ref;
                break;
            }
        }
    }
out:;
    int c = 0;
    for (int r = 0; r < nr; r++) {
        occ[r] = (unsigned char)(done >> r & 1);
        c += occ[r];
    }
    return c;
}
