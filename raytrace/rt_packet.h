/* rt_packet.h - private to raytrace/: the packet walk (RT_WALKN,
 * rt_accel_closest_n) of one node width, and the set-up, frustum and
 * 16-ray tests it shares with the packet any-hit walk (rt_packet_occl.h).
 * Included by rt_wide.h, inside its RT_WALK part, when the file defines
 * RT_WALKN: it uses that width's box tests (rt__box4_fast,
 * rt__box4_double, rt_boxops), the leaf code of the single walk (rt_best,
 * rt__lane_closest, rt__leaf_closest) and rt__leaf_mask. Not to be
 * included on its own. */
#ifndef RT_W
#error "rt_packet.h is included by rt_wide.h"
#endif

/* ---- the packet walk (rt_accel_closest_n) ----
 *
 * Up to RT_PACKET_MAX rays walk the tree together: each node is fetched once
 * for the packet and tested against every ray still active in it (the
 * per-ray test above, with that ray's own best hit), and a child goes on the
 * stack with the mask of the rays that entered it and the least of their
 * entry distances. Children are visited in the order of that least entry.
 * Popping drops the rays whose best hit now lies before the entry (their
 * own entry is no nearer than the least). A leaf is tested ray by ray with
 * the single walk's leaf code (rt__leaf_closest).
 *
 * Each ray therefore meets every leaf whose boxes down from the root it
 * enters within its best hit, as in RT_WALK, and keeps the best hit by the
 * same tie rules, which do not depend on the order the leaves are met in:
 * the same hit as RT_WALK for every ray, bit for bit (test_packet checks it).
 * What it saves: a node's box planes are loaded once per packet instead of
 * once per ray, and the rays' tests are independent of each other, so the
 * processor overlaps them (one ray's walk is a chain of dependent loads). It
 * pays for coherent rays (camera rays of a tile); for incoherent ones the
 * masks thin out and the per-ray work is the same or more (a packet of
 * sparse camera rays, 15 triangles to a pixel, was 0.83x one ray at a time:
 * notes/performance.md). Closest hit, culling back faces as the object asks
 * (rt_accel_closest's query).
 *
 * On 16-wide nodes, a packet whose rays share their origin (a pinhole
 * camera's) takes three faster paths, each described where it is defined:
 * a frustum test per node for the whole packet (rt__box_frustum), inner
 * children passed the packet untested, the rays of each child found 16 at a
 * time at nodes with leaf children (rt__box_rays), and leaves that test 16
 * rays per triangle (rt__pkt_tri_cand) instead of one ray per 4 triangles. */
/* The largest |component| of d (no NaN here), by comparisons: fmax is a
 * libm call in this build, and was a fifth of a short packet walk. */
static inline double rt__abs_max3(rr_vec3 d)
{
    double ax = d.x < 0.0 ? -d.x : d.x, ay = d.y < 0.0 ? -d.y : d.y, az = d.z < 0.0 ? -d.z : d.z;
    double m = ax > ay ? ax : ay;
    return az > m ? az : m;
}

typedef struct rt_pkt_ray {
    rt_ray_pre p;
    rt_pkray pr;
    rt_best b;
    int tri_ready, exact_only;
} rt_pkt_ray;

/* A ray's triangle set-up, at its first leaf: for the exact test and for
 * the per-ray float test (rt__pk_cand). */
static inline void rt__pkt_ready(const rt_accel *a, rt_pkt_ray *s)
{
    if (!s->tri_ready) {
        rt__ray_prepare_tri(&s->p);
        rt__pkray_init(&s->p, a->vmax, s->exact_only, &s->pr);
        s->tri_ready = 1;
    }
}

/* For the lanes `slow` of leaf packet k, which the 16-ray test does not take
 * (other primitives, lanes whose bound overflows): lanes[i] = the rays of
 * act that the per-ray float test rt__pk_cand keeps for lane i, as the
 * single walk's leaf code would. (Keeping every ray for such lanes, as the
 * walks first did for double-vertex triangles too, sent all of a packet's
 * rays to the exact test: packets were 1.5x slower than single rays in a
 * room of 273 transformed bunnies.) */
/* The used lanes of leaf packet k that the 16-ray test cannot take: not a
 * triangle, or (ok, from rt__pkt_normals) a bound out of range. */
static inline unsigned rt__pkt_slow_mask(const rt_pk *k, int ok)
{
    unsigned slow = 0;
    for (int i = 0; i < RT_PK; i++)
        if (k->ref[i] && ((k->ref[i] & RT_REF_LANE) == RT_REF_PRIM || !(ok >> i & 1)))
            slow |= 1u << i;
    return slow;
}

static inline void rt__pkt_slow_lanes(const rt_accel *a, const rt_pk *k, unsigned slow, uint64_t act, rt_pkt_ray *st,
                                      uint64_t lanes[RT_PK])
{
    for (int i = 0; i < RT_PK; i++)
        lanes[i] = 0;
    for (uint64_t m = act; m; m &= m - 1) {
        int r = __builtin_ctzll(m);
        rt__pkt_ready(a, &st[r]);
        for (unsigned c = rt__pk_cand(k, &st[r].pr) & slow; c; c &= c - 1)
            lanes[__builtin_ctz(c)] |= (uint64_t)1 << r;
    }
}

#if RT_BOX_SIMD == 3
/* A shared-origin packet's frustum test (rays from one point, as a pinhole
 * camera's): one slab test for the whole packet, with 1/d per axis as the
 * interval [ilo, ihi] of the rays' inv_f. Requires every ray to have the
 * same org_near, org_far and rows and the float box test (rt__boxray_init
 * 1). It returns every child that some ray's sub-and-multiply test
 * (RT_BOX_SIMD 2's form, conservative by the header's argument) enters:
 * per axis that test computes fl(a inv) with a = fl(plane - org), the same
 * a for every ray of the packet, and fl(a x) is monotonic in x, so its
 * least entry and greatest exit over the rays are min and max of
 * fl(a ilo), fl(a ihi); taking the packet's greatest cull as tmax, a child
 * no ray can enter fails. No NaN: inv is finite and nonzero, the planes
 * finite or (empty lanes) infinite. */
typedef struct rt_frustum {
    __m512 on[3], of[3], ilo[3], ihi[3];
    int row[3];
} rt_frustum;

static inline unsigned rt__box_frustum(const rt_wn *n, const rt_frustum *f, float tmin, float tmax, float dist[RT_W])
{
    __m512 t0 = _mm512_set1_ps(tmin), t1 = _mm512_set1_ps(INFINITY);
    for (int k = 0; k < 3; k++) {
        __m512 a = _mm512_sub_ps(_mm512_load_ps(n->b[f->row[k]]), f->on[k]);
        __m512 b = _mm512_sub_ps(_mm512_load_ps(n->b[f->row[k] ^ 1]), f->of[k]);
        t0 = _mm512_max_ps(t0, _mm512_min_ps(_mm512_mul_ps(a, f->ilo[k]), _mm512_mul_ps(a, f->ihi[k])));
        t1 = _mm512_min_ps(t1, _mm512_max_ps(_mm512_mul_ps(b, f->ilo[k]), _mm512_mul_ps(b, f->ihi[k])));
    }
    t1 = _mm512_min_ps(_mm512_set1_ps(tmax), _mm512_mul_ps(t1, _mm512_set1_ps(1.0f + RT_BOX_GROW)));
    _mm512_storeu_ps(dist, t0);
    return (unsigned)_mm512_cmp_ps_mask(t0, t1, _CMP_LE_OQ);
}
#endif

#if RT_BOX_SIMD == 3
/* The float test of a leaf packet's triangles against the rays of a packet
 * that share one origin O exactly, 16 rays at a time (the per-ray
 * rt__pk_cand tests 4 triangles against one ray). With a = A - O, b, c the
 * vertices from the origin, the watertight test's edge functions are
 * U = d.(c x b) / |d_kz|, V = d.(a x c) / |d_kz|, W = d.(b x a) / |d_kz|
 * exactly (the shear and the axis swap for d_kz < 0 cancel; checked
 * numerically, and by test_packet through the walk), so their signs are
 * those of T = d.n for the three edge normals n, computed once per triangle
 * in double and rounded to float. A ray is dropped for a triangle, as
 * rt__pk_cand drops it, when one T is below -E and another above E, or all
 * three below -E and the triangle culls back faces, with
 *   E = 8u S + 2^-40 R^2 D + 1e-37,  S = |dx||nx| + |dy||ny| + |dz||nz|,
 * u = 2^-24, R = the largest |coordinate| of a, b, c, D = the packet's
 * largest |direction component|. 8u S covers the float side (the roundings
 * of n and d to float: 2u S; three fused operations: 3u S; E's own), 2^-40
 * R^2 D (8192 u_d R^2 D) the double side: n's roundings (about 30 u_d R^2
 * D in T) and the double test's own error on U, V, W (about 64 u_d R^2
 * in U, so 64 u_d R^2 D in T), 1e-37 the underflow of tiny products. A
 * dropped ray's exact U, V, W then have the signs the estimate says, and
 * the double test rejects the triangle too (for the same reason as in
 * rt__pk_cand, the long-double recomputation at zeros cannot change
 * that). Triangles with double vertices (RT_REF_DBL) take the same test,
 * their normals from the double copy (rt__pkt_normals). Lanes with R >=
 * 1e15 or R^2 D >= 1e30 (float overflow) and other primitives go to the
 * per-ray float test (rt__pkt_slow_lanes). */
static inline uint64_t rt__pkt_tri_cand(const float n[9], float e0, int cull, uint64_t act, const float *dx,
                                        const float *dy, const float *dz)
{
    const __m512 ux = _mm512_set1_ps(n[0]), uy = _mm512_set1_ps(n[1]), uz = _mm512_set1_ps(n[2]);
    const __m512 vx = _mm512_set1_ps(n[3]), vy = _mm512_set1_ps(n[4]), vz = _mm512_set1_ps(n[5]);
    const __m512 wx = _mm512_set1_ps(n[6]), wy = _mm512_set1_ps(n[7]), wz = _mm512_set1_ps(n[8]);
    const __m512 aux = _mm512_abs_ps(ux), auy = _mm512_abs_ps(uy), auz = _mm512_abs_ps(uz);
    const __m512 avx = _mm512_abs_ps(vx), avy = _mm512_abs_ps(vy), avz = _mm512_abs_ps(vz);
    const __m512 awx = _mm512_abs_ps(wx), awy = _mm512_abs_ps(wy), awz = _mm512_abs_ps(wz);
    const __m512 e = _mm512_set1_ps(e0), k8u = _mm512_set1_ps(8.0f * RT_PK_U);
    uint64_t cand = 0;
    for (int j = 0; j < RT_PACKET_MAX / 16; j++) {
        __mmask16 live = (__mmask16)(act >> (16 * j));
        if (!live)
            continue;
        __m512 x = _mm512_load_ps(dx + 16 * j), y = _mm512_load_ps(dy + 16 * j), z = _mm512_load_ps(dz + 16 * j);
        __m512 ax = _mm512_abs_ps(x), ay = _mm512_abs_ps(y), az = _mm512_abs_ps(z);
        __m512 tu = _mm512_fmadd_ps(z, uz, _mm512_fmadd_ps(y, uy, _mm512_mul_ps(x, ux)));
        __m512 tv = _mm512_fmadd_ps(z, vz, _mm512_fmadd_ps(y, vy, _mm512_mul_ps(x, vx)));
        __m512 tw = _mm512_fmadd_ps(z, wz, _mm512_fmadd_ps(y, wy, _mm512_mul_ps(x, wx)));
        __m512 su = _mm512_fmadd_ps(az, auz, _mm512_fmadd_ps(ay, auy, _mm512_mul_ps(ax, aux)));
        __m512 sv = _mm512_fmadd_ps(az, avz, _mm512_fmadd_ps(ay, avy, _mm512_mul_ps(ax, avx)));
        __m512 sw = _mm512_fmadd_ps(az, awz, _mm512_fmadd_ps(ay, awy, _mm512_mul_ps(ax, awx)));
        __m512 eu = _mm512_fmadd_ps(su, k8u, e), ev = _mm512_fmadd_ps(sv, k8u, e), ew = _mm512_fmadd_ps(sw, k8u, e);
        const __m512 zero = _mm512_setzero_ps();
        __mmask16 nu = _mm512_cmp_ps_mask(_mm512_add_ps(tu, eu), zero, _CMP_LT_OQ);
        __mmask16 nv = _mm512_cmp_ps_mask(_mm512_add_ps(tv, ev), zero, _CMP_LT_OQ);
        __mmask16 nw = _mm512_cmp_ps_mask(_mm512_add_ps(tw, ew), zero, _CMP_LT_OQ);
        __mmask16 pu = _mm512_cmp_ps_mask(tu, eu, _CMP_GT_OQ), pv = _mm512_cmp_ps_mask(tv, ev, _CMP_GT_OQ);
        __mmask16 pw = _mm512_cmp_ps_mask(tw, ew, _CMP_GT_OQ);
        __mmask16 drop = (__mmask16)(((nu | nv | nw) & (pu | pv | pw)) | (cull ? nu & nv & nw : 0));
        cand |= (uint64_t)(live & (__mmask16)~drop) << (16 * j);
    }
    return cand;
}
#endif

#if RT_BOX_SIMD == 3
/* The float box test of child c of n against the active rays of a frustum
 * packet, 16 rays at a time, on the rays' operands in SoA (ray r's cn, cf,
 * inv at [k][r]; rows shared): the per-ray fused test's arithmetic lane
 * for lane (one FMA per plane, the same min and max, none of them NaN: inv
 * is finite, c < 1e37), so the same answer bit for bit. Returns the rays
 * that enter the child. */
static inline uint64_t rt__box_rays(const rt_wn *n, int c, const int row[3], const float (*cn)[RT_PACKET_MAX],
                                    const float (*cf)[RT_PACKET_MAX], const float (*inv)[RT_PACKET_MAX],
                                    const float *cull, float tmin, uint64_t act)
{
    const __m512 px0 = _mm512_set1_ps(n->b[row[0]][c]), px1 = _mm512_set1_ps(n->b[row[0] ^ 1][c]);
    const __m512 py0 = _mm512_set1_ps(n->b[row[1]][c]), py1 = _mm512_set1_ps(n->b[row[1] ^ 1][c]);
    const __m512 pz0 = _mm512_set1_ps(n->b[row[2]][c]), pz1 = _mm512_set1_ps(n->b[row[2] ^ 1][c]);
    const __m512 lo = _mm512_set1_ps(tmin), grow = _mm512_set1_ps(1.0f + RT_BOX_GROW);
    uint64_t in = 0;
    for (int j = 0; j < RT_PACKET_MAX / 16; j++) {
        __mmask16 live = (__mmask16)(act >> (16 * j));
        if (!live)
            continue;
        const int o = 16 * j;
        __m512 ix = _mm512_load_ps(inv[0] + o), iy = _mm512_load_ps(inv[1] + o), iz = _mm512_load_ps(inv[2] + o);
        __m512 tx0 = _mm512_fmsub_ps(px0, ix, _mm512_load_ps(cn[0] + o));
        __m512 ty0 = _mm512_fmsub_ps(py0, iy, _mm512_load_ps(cn[1] + o));
        __m512 tz0 = _mm512_fmsub_ps(pz0, iz, _mm512_load_ps(cn[2] + o));
        __m512 tx1 = _mm512_fmsub_ps(px1, ix, _mm512_load_ps(cf[0] + o));
        __m512 ty1 = _mm512_fmsub_ps(py1, iy, _mm512_load_ps(cf[1] + o));
        __m512 tz1 = _mm512_fmsub_ps(pz1, iz, _mm512_load_ps(cf[2] + o));
        __m512 t0 = _mm512_max_ps(_mm512_max_ps(tx0, ty0), _mm512_max_ps(tz0, lo));
        __m512 t1 = _mm512_min_ps(_mm512_min_ps(tx1, ty1), tz1);
        t1 = _mm512_min_ps(_mm512_load_ps(cull + o), _mm512_mul_ps(t1, grow));
        in |= (uint64_t)_mm512_mask_cmp_ps_mask(live, t0, t1, _CMP_LE_OQ) << o;
    }
    return in;
}

/* The greatest of cull[0 .. RT_PACKET_MAX) (the entries past the packet's
 * rays are 0): one chain of 64 scalar compares was 4 % of the walk. */
static inline float rt__max_cull(const float *cull)
{
    __m512 m = _mm512_load_ps(cull);
    for (int j = 1; j < RT_PACKET_MAX / 16; j++)
        m = _mm512_max_ps(m, _mm512_load_ps(cull + 16 * j));
    return _mm512_reduce_max_ps(m);
}
#endif

#if RT_BOX_SIMD == 3
/* The edge normals of leaf packet k's 4 lanes for rt__pkt_tri_cand, with
 * the vertices taken from the point (px, py, pz): nf[c][lane] (c x b, a x c,
 * b x a, rounded to float) and the bound e0[lane] = 2^-40 R^2 D
 * + 16 delta R D + 1e-37 (rt__pkt_tri_cand's E without its float part),
 * R = rpad + the largest |coordinate| of the vertices from the point, D =
 * dmax. rpad and delta are 0 for rays from that point. For rays that end
 * within delta (per axis) of it (RT_OCCLN), U of ray (o, d) is the same as
 * from the end point e = o + d (d.((c - d) x (b - d)) = d.(c x b)), so the
 * normals from the point are off by at most 4 R delta per component (16 R
 * delta D in T, with room), and the double test's own error is that of
 * vertices within R + D + delta of o: rpad = D + delta. Returns the lanes
 * whose bound is representable (bit i: lane i). */
static inline int rt__pkt_normals(const rt_accel *a, const rt_pk *k, double px, double py, double pz, double dmax,
                                  double rpad, double delta, float nf[9][4], float e0[4])
{
    const __m256d ox = _mm256_set1_pd(px), oy = _mm256_set1_pd(py), oz = _mm256_set1_pd(pz);
    const __m256d absm = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    __m256d va[9];
    for (int c = 0; c < 9; c++)
        va[c] = _mm256_cvtps_pd(_mm_load_ps(k->v[c]));
    /* Double-vertex lanes (RT_REF_DBL): the normals from the double copy
     * the exact test reads (v holds them rounded to float, and a bound for
     * that rounding, D V (2^-19 R + 2^-43 V), kept nothing: for a bunny's
     * small triangles 10 m from a light it exceeds T itself). */
    unsigned dl = 0;
    for (int i = 0; i < RT_PK; i++)
        dl |= (unsigned)((k->ref[i] & RT_REF_LANE) == RT_REF_DBL) << i;
    if (dl) {
        double t[9][4];
        for (int c = 0; c < 9; c++)
            _mm256_storeu_pd(t[c], va[c]);
        for (; dl; dl &= dl - 1) {
            const int i = __builtin_ctz(dl);
            const double *dv = rt__pk_dverts(a, k, i);
            for (int c = 0; c < 9; c++)
                t[c][i] = dv[c];
        }
        for (int c = 0; c < 9; c++)
            va[c] = _mm256_loadu_pd(t[c]);
    }
    __m256d ax = _mm256_sub_pd(va[0], ox), ay = _mm256_sub_pd(va[1], oy), az = _mm256_sub_pd(va[2], oz);
    __m256d bx = _mm256_sub_pd(va[3], ox), by = _mm256_sub_pd(va[4], oy), bz = _mm256_sub_pd(va[5], oz);
    __m256d cx = _mm256_sub_pd(va[6], ox), cy = _mm256_sub_pd(va[7], oy), cz = _mm256_sub_pd(va[8], oz);
    __m256d nd[9] = {
        _mm256_sub_pd(_mm256_mul_pd(cy, bz), _mm256_mul_pd(cz, by)), /* c x b */
        _mm256_sub_pd(_mm256_mul_pd(cz, bx), _mm256_mul_pd(cx, bz)),
        _mm256_sub_pd(_mm256_mul_pd(cx, by), _mm256_mul_pd(cy, bx)),
        _mm256_sub_pd(_mm256_mul_pd(ay, cz), _mm256_mul_pd(az, cy)), /* a x c */
        _mm256_sub_pd(_mm256_mul_pd(az, cx), _mm256_mul_pd(ax, cz)),
        _mm256_sub_pd(_mm256_mul_pd(ax, cy), _mm256_mul_pd(ay, cx)),
        _mm256_sub_pd(_mm256_mul_pd(by, az), _mm256_mul_pd(bz, ay)), /* b x a */
        _mm256_sub_pd(_mm256_mul_pd(bz, ax), _mm256_mul_pd(bx, az)),
        _mm256_sub_pd(_mm256_mul_pd(bx, ay), _mm256_mul_pd(by, ax)),
    };
    __m256d R = _mm256_max_pd(_mm256_max_pd(_mm256_and_pd(ax, absm), _mm256_and_pd(ay, absm)),
                              _mm256_and_pd(az, absm));
    R = _mm256_max_pd(R, _mm256_max_pd(_mm256_max_pd(_mm256_and_pd(bx, absm), _mm256_and_pd(by, absm)),
                                       _mm256_and_pd(bz, absm)));
    R = _mm256_max_pd(R, _mm256_max_pd(_mm256_max_pd(_mm256_and_pd(cx, absm), _mm256_and_pd(cy, absm)),
                                       _mm256_and_pd(cz, absm)));
    R = _mm256_add_pd(R, _mm256_set1_pd(rpad));
    __m256d r2d = _mm256_mul_pd(_mm256_mul_pd(R, R), _mm256_set1_pd(dmax));
    int ok = _mm256_movemask_pd(_mm256_and_pd(_mm256_cmp_pd(R, _mm256_set1_pd(1e15), _CMP_LT_OQ),
                                              _mm256_cmp_pd(r2d, _mm256_set1_pd(1e30), _CMP_LT_OQ)));
    for (int c = 0; c < 9; c++)
        _mm_storeu_ps(nf[c], _mm256_cvtpd_ps(nd[c]));
    /* 2^-40 R^2 D, one part in 2^20 more for the rounding to float, + 1e-37
     * (+ 16 delta R D, 0 for rays from the point: bits unchanged). */
    __m256d e = _mm256_add_pd(_mm256_mul_pd(r2d, _mm256_set1_pd(0x1.00001p-40)), _mm256_set1_pd(1e-37));
    e = _mm256_add_pd(e, _mm256_mul_pd(R, _mm256_set1_pd(16.0 * 1.00001 * delta * dmax)));
    _mm_storeu_ps(e0, _mm256_cvtpd_ps(e));
    return ok;
}
#endif

/* A leaf takes the 16-ray test only for more than this many active rays:
 * for fewer, each triangle's normals in double cost more than the per-ray
 * float test of its packet saves (bunny-1m's packets meet a leaf with about
 * 5 rays). `bench/bench-pair.sh 3 --threads 1`, 8 against 0: packets /
 * primary up 21 % on bunny-1m and 10 % on mesh-1m, shadowpk / shadow up
 * 4 % and 3 %; 16 against 8 on bunny-1m: packets the same, shadowpk 8 %
 * down. */
#ifndef RT_PKT_TRI16_MIN
#define RT_PKT_TRI16_MIN 8
#endif

/* ---- the packet walks' shared set-up ---- */

/* Each ray's box set-up (rt_boxops) and walk state; returns the rays whose
 * boxes take the double test (bit r: ray r). */
static inline uint64_t rt__pkt_rays_init(const rr_ray *rays, int nr, double tmin, double tmax, rt_pkt_ray *st,
                                         rt_boxops *ops)
{
    uint64_t dbl = 0;
    for (int r = 0; r < nr; r++) {
        rt_pkt_ray *s = &st[r];
        rt__ray_prepare_box(rays[r], &s->p, 1);
        if (!(tmin >= 0.0))
            s->p.box_double = 1;
        s->exact_only = s->p.box_double;
        s->tri_ready = 0;
        if (!rt__boxops_init(&s->p, &ops[r]))
            s->p.box_double = 1;
        dbl |= (uint64_t)s->p.box_double << r;
        rt__best_init(&s->b, tmax);
    }
    return dbl;
}

#if RT_BOX_SIMD == 3
/* The frustum of rays that share their float origins and rows (a pinhole
 * camera's, a point's): 0 when they do not. Only for rays that all take
 * the float box test. */
static inline int rt__frustum_origin(const rt_pkt_ray *st, const rt_boxops *ops, int nr, rt_frustum *f)
{
    for (int r = 1; r < nr; r++)
        for (int k = 0; k < 3; k++)
            if (st[r].p.org_near[k] != st[0].p.org_near[k] || st[r].p.org_far[k] != st[0].p.org_far[k] ||
                ops[r].row[k] != ops[0].row[k])
                return 0;
    for (int k = 0; k < 3; k++) {
        float lo = ops[0].inv[k], hi = lo;
        for (int r = 1; r < nr; r++) {
            lo = ops[r].inv[k] < lo ? ops[r].inv[k] : lo;
            hi = ops[r].inv[k] > hi ? ops[r].inv[k] : hi;
        }
        f->on[k] = _mm512_set1_ps(st[0].p.org_near[k]);
        f->of[k] = _mm512_set1_ps(st[0].p.org_far[k]);
        f->ilo[k] = _mm512_set1_ps(lo);
        f->ihi[k] = _mm512_set1_ps(hi);
        f->row[k] = ops[0].row[k];
    }
    return 1;
}

/* The rays' box operands in SoA for rt__box_rays (entries past nr repeat
 * ray 0's, never read as active). */
static inline void rt__pkt_soa(const rt_boxops *ops, int nr, float (*cn)[RT_PACKET_MAX], float (*cf)[RT_PACKET_MAX],
                               float (*inv)[RT_PACKET_MAX])
{
    for (int r = 0; r < RT_PACKET_MAX; r++)
        for (int k = 0; k < 3; k++) {
            const rt_boxops *q = &ops[r < nr ? r : 0];
            cn[k][r] = q->a[k];
            cf[k][r] = q->b[k];
            inv[k][r] = q->inv[k];
        }
}

/* 1 when every ray has ray 0's origin, bit for bit (the 16-ray leaf test
 * from that origin). */
static inline int rt__pkt_one_origin(const rr_ray *rays, int nr)
{
    for (int r = 1; r < nr; r++)
        if (memcmp(&rays[r].o, &rays[0].o, sizeof rays[0].o) != 0)
            return 0;
    return 1;
}

/* The directions in float SoA for rt__pkt_tri_cand; returns D, the largest
 * |direction component|. */
static inline double rt__pkt_dirs(const rr_ray *rays, int nr, float *dx, float *dy, float *dz)
{
    double dmax = 0.0;
    for (int r = 0; r < RT_PACKET_MAX; r++) {
        rr_vec3 d = r < nr ? rays[r].d : rays[0].d;
        dx[r] = (float)d.x;
        dy[r] = (float)d.y;
        dz[r] = (float)d.z;
        double m = rt__abs_max3(d);
        dmax = m > dmax ? m : dmax;
    }
    return dmax;
}
#endif

#if RT_BOX_SIMD == 3
/* The rays of act that lane i of leaf packet k may hit: the 16-ray test's
 * (normals nf, bound e0 from rt__pkt_normals), or for a lane it cannot take
 * (slow) the per-ray float test's (lanes, from rt__pkt_slow_lanes). */
static inline uint64_t rt__pkt_lane_cand(const rt_pk *k, int i, unsigned slow, const uint64_t *lanes,
                                         const float nf[9][4], const float *e0, uint64_t act, const float *dx,
                                         const float *dy, const float *dz)
{
    if (slow >> i & 1)
        return act & lanes[i];
    float n9[9];
    for (int c = 0; c < 9; c++)
        n9[c] = nf[c][i];
    return rt__pkt_tri_cand(n9, e0[i], (k->ref[i] & RT_REF_CULL) != 0, act, dx, dy, dz);
}

#endif

typedef struct rt_pkt_entry {
    uint64_t rays;
    uint32_t ref;
    float dist;
} rt_pkt_entry;

/* Child c into ch[0 .. m), kept sorted by descending d; returns m + 1. */
static inline int rt__pkt_insert(int *ch, int m, int c, const float *d)
{
    int j = m;
    while (j > 0 && d[ch[j - 1]] < d[c]) {
        ch[j] = ch[j - 1];
        j--;
    }
    ch[j] = c;
    return m + 1;
}

/* Pushes the children ch[0 .. m - 1) of n (farthest first) with their rays
 * and entries, and returns the nearest, ch[m - 1], with its rays in *act. */
static inline uint32_t rt__pkt_push(const rt_wn *n, const int *ch, int m, const uint64_t *rays, const float *d,
                                    rt_pkt_entry *stack, int *sp, uint64_t *act)
{
    RR_CHECK(*sp + m - 1 <= RT_STACK_SIZE);
    for (int j = 0; j < m - 1; j++) {
        stack[*sp].rays = rays[ch[j]];
        stack[*sp].ref = n->child[ch[j]];
        stack[*sp].dist = d[ch[j]];
        (*sp)++;
    }
    *act = rays[ch[m - 1]];
    return n->child[ch[m - 1]];
}

int RT_WALKN(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, rt_hit *hits,
             unsigned char *found)
{
    RR_CHECK(nr >= 1 && nr <= RT_PACKET_MAX && a->width == RT_W);
    memset(found, 0, (size_t)nr);
    if (a->nwnodes == 0)
        return 0;
    const rt_wn *wnodes = a->wnodes;
    /* What the box tests read stays small (ops, cull: 52 bytes a ray); the
     * triangles' operands are read at leaves only. */
    rt_pkt_ray st[RT_PACKET_MAX];
    rt_boxops ops[RT_PACKET_MAX];
    _Alignas(64) float cull[RT_PACKET_MAX]; /* st[r].b.cull; 0 past nr */
    /* the rays whose boxes take the double test */
    const uint64_t dbl = rt__pkt_rays_init(rays, nr, tmin, tmax, st, ops);
    for (int r = 0; r < RT_PACKET_MAX; r++)
        cull[r] = r < nr ? st[r].b.cull : 0.0f;
    const float tmin_f = rt__f_down(tmin);
#if RT_BOX_SIMD == 3
    /* The frustum, when the rays share their origin and rows. */
    rt_frustum fru;
    const int fr = !dbl && rt__frustum_origin(st, ops, nr, &fru);
    _Alignas(64) float scn[3][RT_PACKET_MAX], scf[3][RT_PACKET_MAX], sinv[3][RT_PACKET_MAX];
    /* The greatest cull of the packet's rays, as the frustum's tmax (taken
     * over the active rays only at each node, it was 5 % slower). */
    float pcull = INFINITY;
    if (fr) {
        pcull = rt__max_cull(cull);
        rt__pkt_soa(ops, nr, scn, scf, sinv);
    }
    /* One origin exactly: the leaves test 16 rays at a time
     * (rt__pkt_tri_cand), on the directions in float. */
    const int so = fr && rt__pkt_one_origin(rays, nr);
    _Alignas(64) float dxs[RT_PACKET_MAX], dys[RT_PACKET_MAX], dzs[RT_PACKET_MAX];
    const double dmax = so ? rt__pkt_dirs(rays, nr, dxs, dys, dzs) : 0.0;
#endif
    rt_pkt_entry stack[RT_STACK_SIZE];
    int sp = 0;
    uint32_t cur = 0; /* the root */
    uint64_t act = nr == 64 ? ~(uint64_t)0 : ((uint64_t)1 << nr) - 1;
    for (;;) {
        if (!(cur & RT_LEAF)) {
            const rt_wn *n = &wnodes[cur];
#if RT_BOX_SIMD == 3
            /* One child in the frustum: the packet goes on as it is, untested
             * (a ray that misses that child's box is dropped a level down). */
            if (fr) {
                float fd[RT_W];
                unsigned fm = rt__box_frustum(n, &fru, tmin_f, pcull, fd);
                if (!fm)
                    goto pop;
                /* Inner children only: the packet goes into each as it is,
                 * untested (a ray that misses one is dropped a level down);
                 * leaves among them: each child's rays found 16 at a time. */
                const int leaves = (fm & rt__leaf_mask(n)) != 0;
                uint64_t fin[RT_W];
                int ch[RT_W], m = 0;
                for (; fm; fm &= fm - 1) {
                    int c = __builtin_ctz(fm);
                    fin[c] = leaves ? rt__box_rays(n, c, fru.row, scn, scf, sinv, cull, tmin_f, act) : act;
                    if (fin[c])
                        m = rt__pkt_insert(ch, m, c, fd);
                }
                if (!m)
                    goto pop;
                cur = rt__pkt_push(n, ch, m, fin, fd, stack, &sp, &act);
                continue;
            }
#endif
            uint64_t in[RT_W];
            float dmin[RT_W];
            unsigned any = 0;
#if RT_BOX_SIMD == 3
            /* The masks and least entries in registers: two vectors of 8
             * ray masks, one of 16 entries, updated by the lanes entered. */
            __m512i in_lo = _mm512_setzero_si512(), in_hi = _mm512_setzero_si512();
            __m512 dm = _mm512_set1_ps(INFINITY);
#else
            for (int c = 0; c < RT_W; c++) {
                in[c] = 0;
                dmin[c] = INFINITY;
            }
#endif
            for (uint64_t m = act; m; m &= m - 1) {
                int r = __builtin_ctzll(m);
                float dist[RT_W];
                unsigned mask;
                if (dbl >> r & 1) {
                    const rt_pkt_ray *s = &st[r];
                    mask = rt__box4_double(n, &s->p, tmin, s->b.t + fabs(s->b.t) * 1e-15, dist);
                } else {
                    rt_boxray br;
                    rt__boxray_of(&ops[r], &st[r].p, &br);
                    mask = rt__box4_fast(n, &br, tmin_f, cull[r], dist);
                }
                any |= mask;
#if RT_BOX_SIMD == 3
                const __m512i bit = _mm512_set1_epi64((long long)((uint64_t)1 << r));
                in_lo = _mm512_mask_or_epi64(in_lo, (__mmask8)mask, in_lo, bit);
                in_hi = _mm512_mask_or_epi64(in_hi, (__mmask8)(mask >> 8), in_hi, bit);
                dm = _mm512_mask_min_ps(dm, (__mmask16)mask, dm, _mm512_loadu_ps(dist));
#else
                for (; mask; mask &= mask - 1) {
                    int c = __builtin_ctz(mask);
                    in[c] |= (uint64_t)1 << r;
                    dmin[c] = dist[c] < dmin[c] ? dist[c] : dmin[c];
                }
#endif
            }
#if RT_BOX_SIMD == 3
            _mm512_storeu_si512((void *)in, in_lo);
            _mm512_storeu_si512((void *)(in + 8), in_hi);
            _mm512_storeu_ps(dmin, dm);
#endif
            if (any) {
                /* Sort the entered children by descending least entry; push
                 * all but the nearest (farthest first), visit that. */
                int ch[RT_W], m = 0;
                for (; any; any &= any - 1)
                    m = rt__pkt_insert(ch, m, __builtin_ctz(any), dmin);
                cur = rt__pkt_push(n, ch, m, in, dmin, stack, &sp, &act);
                continue;
            }
        } else {
            const rt_pk *k = &a->pks[cur & ~RT_LEAF];
#if RT_BOX_SIMD == 3
            if (so && __builtin_popcountll(act) > RT_PKT_TRI16_MIN) {
                const double ox = rays[0].o.x, oy = rays[0].o.y, oz = rays[0].o.z;
                for (;; k++) {
                    float nf[9][4], e0[4];
                    int ok = rt__pkt_normals(a, k, ox, oy, oz, dmax, 0.0, 0.0, nf, e0);
                    unsigned slow = rt__pkt_slow_mask(k, ok);
                    uint64_t lanes[RT_PK];
                    if (slow)
                        rt__pkt_slow_lanes(a, k, slow, act, st, lanes);
                    for (int i = 0; i < RT_PK; i++) {
                        uint32_t fl = k->ref[i];
                        if (!fl)
                            continue;
                        uint64_t cand = rt__pkt_lane_cand(k, i, slow, lanes, nf, e0, act, dxs, dys, dzs);
                        for (; cand; cand &= cand - 1) {
                            int r = __builtin_ctzll(cand);
                            rt_pkt_ray *s = &st[r];
                            rt__pkt_ready(a, s);
                            rt__lane_closest(a, k, i, &s->p, tmin, 0, 0, &s->b, &hits[r]);
                            cull[r] = s->b.cull;
                        }
                    }
                    if (k->ref[0] & RT_REF_LAST)
                        break;
                }
                pcull = rt__max_cull(cull);
                goto pop;
            }
#endif
            for (uint64_t m = act; m; m &= m - 1) {
                int r = __builtin_ctzll(m);
                rt_pkt_ray *s = &st[r];
                rt__pkt_ready(a, s);
                rt__leaf_closest(a, k, &s->p, &s->pr, tmin, 0, 0, &s->b, &hits[r]);
                cull[r] = s->b.cull;
            }
#if RT_BOX_SIMD == 3
            pcull = rt__max_cull(cull);
#endif
        }
#if RT_BOX_SIMD == 3
    pop:
#endif
        /* Pop, dropping the rays whose best hit lies before the entry. */
        for (;;) {
            if (sp == 0)
                goto out;
            sp--;
            uint64_t keep = 0;
            for (uint64_t m = stack[sp].rays; m; m &= m - 1) {
                int r = __builtin_ctzll(m);
                if (!(stack[sp].dist > cull[r]))
                    keep |= (uint64_t)1 << r;
            }
            if (keep) {
                cur = stack[sp].ref;
                act = keep;
                break;
            }
        }
    }
out:;
    /* The hit triangles' scene records, fetched before they are read: one
     * cache miss per ray, and they now overlap. */
    for (int r = 0; r < nr; r++)
        if (st[r].b.found && st[r].b.tri)
            __builtin_prefetch(&a->scene->tris[st[r].b.tri->ref[st[r].b.lane] >> RT_REF_SHIFT]);
    int nhit = 0;
    for (int r = 0; r < nr; r++)
        if (st[r].b.found) {
            rt__best_fill(a, &st[r].b, rays[r], &hits[r]);
            found[r] = 1;
            nhit++;
        }
    return nhit;
}
