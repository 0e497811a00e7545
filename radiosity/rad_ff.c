/* rad_ff.c - form factors between patches, with visibility from the BVH.
 *
 * Two estimators of F_ij = 1/A_i  int_i int_j  V cos(ti) cos(tj) / (pi r^2):
 *
 *  - Quadrature (RAD_FF_QUADRATURE): the inner integral over patch j is done
 *    exactly by Lambert's contour integral (rad_ff_point_polygon) at `samples`
 *    stratified points x_k of patch i, times a visibility estimate V(x_k, j).
 *    Visibility: ONE shadow ray per (k, j), from x_k to a point in stratum
 *    pi(k) (pi: a random permutation per row) of the part of j in front of
 *    i's plane. Over the k samples the rays fan out over all the strata, so V
 *    is an area-weighted visible fraction that costs no more rays than there
 *    are quadrature points. Where nothing is in the way (the common case:
 *    walls of a room) every ray is unoccluded and the result is the
 *    quadrature of an exact inner integral; fully hidden pairs give exactly
 *    0; only partially hidden pairs carry noise (and the small bias of
 *    weighting visibility by area instead of by cos cos / r^2, which vanishes
 *    as patches shrink). Rays to j's centroid would make partial occlusion
 *    all-or-nothing per point, with aliasing along shadow edges, and save
 *    nothing: the ray count is the same.
 *    Near pairs (neighbours across an edge, where the integrand's gradient is
 *    log-singular) get a finer point set, see RAD_FF_NEAR.
 *
 *  - Monte Carlo (RAD_FF_MONTE_CARLO): `samples` rays per patch, origins
 *    uniform over the patch and directions cosine-weighted, stratified jointly
 *    in 4-D (see mc_row), F_ij = (rays whose first hit is the front of j) /
 *    samples. Extended form factors (Wallace, Cohen & Greenberg 1987): a ray
 *    that meets a mirror (mirror reflectance > 0, either side) lands there
 *    AND goes on, reflected, with its weight times the mirror's mean
 *    reflectance, up to mirror_depth reflections; F_ij then sums the weights
 *    of the landings on j, so light that leaves i and reaches j by way of
 *    mirrors is in F_ij (and the system stays reciprocal: mirror paths are
 *    reversible). Quadrature does not do this: it has no rays to reflect
 *    (the pass warns when a scene with mirrors asks for it).
 *    Hits on the BACK side of a surface are dropped: patches are
 *    one-sided (they emit and receive on their normal side), the back of an
 *    open quad has no patch, so such a ray's share counts as escaped
 *    (1 - sum_j F_ij, the energy ledger's "escaped" column).
 *
 * Spheres: their patches are flat facets inscribed in the analytic sphere the
 * ray tracer intersects, so a ray from (or to) a point of a facet would start
 * (end) inside the sphere. Ray ends on sphere patches are therefore moved
 * radially onto the sphere and offset along its normal there; the contour
 * integral still uses the facets, and scales a factor to a facet by the area
 * its patch stands for (rad__facet_scale: the sphere's or the solid's true area,
 * which Monte Carlo rays see; rad_patch.c). Before that scale, quadrature saw
 * a sphere's patches with the facets' area (a few percent less for coarse
 * tessellations) and scenes/csg.json's solids 4-6 % dark.
 *
 * Row sums and reciprocity: the raw rows are made reciprocal and (Monte
 * Carlo) balanced afterwards, rad_ff_matrix.c.
 *
 * Both run rows in parallel (OpenMP, dynamic), each row from its own RNG
 * stream rr_rng_make(seed, i): the result is bit-identical for any thread
 * count (the balancing is serial). Rows are sorted by column. Unless o->raw,
 * the estimates are then made reciprocal, F_ij := A_j (F_ij + F_ji) /
 * (A_i + A_j), over the union of the two patterns, so A_i F_ij = A_j F_ji (to
 * rounding) and the solved system conserves energy; Monte Carlo ones are
 * then balanced as above.
 */
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rad.h"
#include "rad_ff_internal.h"

typedef struct ff_ctx {
    const scene *s;
    const rt_accel *a;
    const rad_patches *P;
    int samples;
    uint32_t near_samples; /* quadrature points for near pairs (>= samples) */
    uint64_t seed;
    int mirror_depth; /* Monte Carlo: reflections followed off mirrors */
    double ext;       /* scene extent: the length scale of ray offsets */
    double plane_tol; /* distances to a plane below this count as "on it" */
} ff_ctx;

/* One finished row, before the CSR is assembled. */
typedef struct ff_row {
    uint32_t *col;
    double *val;
    size_t n;
    double open; /* the open fraction of the patch (rad.h: buried parts) */
} ff_row;

/* A weighted hit: patch j, weight w. */
typedef struct wh {
    uint32_t j;
    double w;
} wh;

/* Per-thread scratch, sized once per thread. */
typedef struct ff_scratch {
    rr_vec3 *x;     /* quadrature points of the current row (base, then near) */
    rr_vec3 *xo;    /* and the shadow rays' origins for them */
    uint32_t *perm; /* stratum pairing (quadrature: base, then near) */
    double *tuv;    /* quadrature: shadow-ray targets (base, then near) */
    uint32_t *hits; /* Monte Carlo: patch hit by each ray (and by its reflections off mirrors) */
    double *hw;     /* and the weight of each hit (1, or the product of the mirrors' reflectances) */
    wh *pairs;      /* for sorting weighted hits (scenes with mirrors) */
    uint32_t *col;  /* the row being built */
    double *val;
    uint32_t open;  /* Monte Carlo: the row's rays that started in the open */
} ff_scratch;

/* ---- the exact point-to-polygon factor ---- */

/* atan2(y, x) for y >= 0 (an angle in [0, pi]) without libm's call, which
 * was 7 % of room.json's pass: the argument reduced to t = min / max of |x|
 * and y in [0, 1], t above tan(pi / 8) to u = (t - 1) / (t + 1), and
 * atan(u) = u + u^3 P(u^2) for |u| <= tan(pi / 8), P of degree 10 fitted by
 * weighted least squares on Chebyshev nodes in 50-digit arithmetic: its
 * relative error there is 1.6e-18 (in double, a few ulps of the angle,
 * which test_formfactor `angle_against_atan2` checks). */
static inline double angle(double y, double x)
{
    static const double P[11] = {-0.33333333333333198,  0.19999999999953702,   -0.14285714280197631,
                                 0.11111110783240968,   -0.090908977473078439, 0.076920599922309554,
                                 -0.066631013264111569, 0.0584786909516933,    -0.050392146539881055,
                                 0.038062345399453391,  -0.01790489678766605};
    double ax = fabs(x);
    int swap = y > ax;
    double num = swap ? ax : y, den = swap ? y : ax;
    int big = num > 0.41421356237309503 * den;
    double nn = big ? num - den : num, dd = big ? num + den : den;
    double u = dd > 0.0 ? nn / dd : 0.0, z = u * u, z2 = z * z, z4 = z2 * z2;
    /* P(z) by Estrin's scheme: a third of Horner's chain of dependent steps */
    double p = (P[0] + P[1] * z) + (P[2] + P[3] * z) * z2 +
               ((P[4] + P[5] * z) + (P[6] + P[7] * z) * z2) * z4 + ((P[8] + P[9] * z) + P[10] * z2) * (z4 * z4);
    double a = u + u * z * p + (big ? RR_PI / 4 : 0.0);
    a = swap ? RR_PI / 2 - a : a;
    return x < 0.0 ? RR_PI - a : a;
}

double rad__ff_angle(double y, double x) { return angle(y, x); }

/* The angle and the edge plane's normal depend only on directions: the
 * vectors from p scaled by one factor, 1 / their largest component, keep
 * far or tiny polygons from overflowing or underflowing the cross products
 * (unit vectors cost a square root and a division each). That factor, or 0
 * where there is none (p on every vertex, or not finite). */
static double poly_scale(rr_vec3 p, const rr_vec3 *poly, int nv)
{
    double m = 0.0;
    for (int k = 0; k < nv; k++) {
        rr_vec3 d = rr_v3_sub(poly[k], p);
        m = rr_max(m, rr_max(fabs(d.x), rr_max(fabs(d.y), fabs(d.z))));
    }
    return m > 0.0 && isfinite(m) ? 1.0 / m : 0.0;
}

double rad_ff_point_polygon(rr_vec3 p, rr_vec3 n, const rr_vec3 *poly, int nv)
{
    double im = nv < 3 ? 0.0 : poly_scale(p, poly, nv), sum = 0.0;
    if (!(im > 0.0))
        return 0.0;
    rr_vec3 first = rr_v3_scale(rr_v3_sub(poly[0], p), im), a = first;
    for (int k = 0; k < nv; k++) {
        rr_vec3 b = k + 1 < nv ? rr_v3_scale(rr_v3_sub(poly[k + 1], p), im) : first;
        rr_vec3 c = rr_v3_cross(a, b);
        double cl = rr_v3_len(c);
        /* A degenerate edge (repeated vertex, or p on the edge's line) spans no
         * solid angle seen from p: skip it rather than divide by zero. atan2 of
         * |a x b| and a.b is accurate for tiny and for near-pi angles alike,
         * where acos(a.b) loses half the digits. */
        if (cl > 0.0)
            sum += angle(cl, rr_v3_dot(a, b)) * (rr_v3_dot(n, c) / cl);
        a = b;
    }
    /* For a planar polygon in front of p the sum is +-2 pi F, the sign given by
     * the winding as seen from p; either winding means the same surface. */
    return fabs(sum) / (2.0 * RR_PI);
}

rr_vec3 rad_ff_point_polygon_vec(rr_vec3 p, const rr_vec3 *poly, int nv)
{
    rr_vec3 v = rr_v3(0, 0, 0), ctr = rr_v3(0, 0, 0);
    double im = nv < 3 ? 0.0 : poly_scale(p, poly, nv);
    if (!(im > 0.0))
        return v;
    for (int k = 0; k < nv; k++)
        ctr = rr_v3_add(ctr, rr_v3_sub(poly[k], p));
    rr_vec3 first = rr_v3_scale(rr_v3_sub(poly[0], p), im), a = first;
    for (int k = 0; k < nv; k++) {
        rr_vec3 b = k + 1 < nv ? rr_v3_scale(rr_v3_sub(poly[k + 1], p), im) : first;
        rr_vec3 c = rr_v3_cross(a, b);
        double cl = rr_v3_len(c);
        if (cl > 0.0)
            v = rr_v3_add(v, rr_v3_scale(c, angle(cl, rr_v3_dot(a, b)) / cl));
        a = b;
    }
    v = rr_v3_scale(v, 1.0 / (2.0 * RR_PI));
    return rr_v3_dot(v, ctr) < 0.0 ? rr_v3_neg(v) : v; /* towards the polygon, whatever its winding */
}

/* ---- ray ends ---- */

static rr_vec3 patch_point(const rad_patches *P, const rad_patch *q, double u, double v)
{
    rr_vec3 A = P->verts[q->v[0]], B = P->verts[q->v[1]], C = P->verts[q->v[2]];
    return rr_v3_add(A, rr_v3_add(rr_v3_scale(rr_v3_sub(B, A), u), rr_v3_scale(rr_v3_sub(C, A), v)));
}

/* Where a ray starts or ends for point x of patch q, and the normal there
 * (rad_patch_surface: on the analytic surface for spheres and solids). */
static void surface_at(const ff_ctx *c, const rad_patch *q, rr_vec3 x, rr_vec3 *xs, rr_vec3 *ns)
{
    rad_patch_surface(c->P, c->s, c->a, (uint32_t)(q - c->P->p), x, xs, ns);
}

/* Pushed off the surface towards its front by the renderer's one rule
 * (rt_offset_origin), so form-factor rays and shadow rays agree. */
static rr_vec3 offset_front(const ff_ctx *c, rr_vec3 p, rr_vec3 n) { return rt_offset_origin(c->ext, p, n, n); }

/* ---- quadrature ---- */

/* Sutherland-Hodgman: the part of triangle tri on the positive side of the
 * plane (n, p0). Vertices within tol of the plane count as on it (kept), so a
 * shared edge does not produce slivers. A triangle gives at most 4 vertices. */
int rad__clip_front(const rr_vec3 tri[3], rr_vec3 n, rr_vec3 p0, double tol, rr_vec3 out[4])
{
    double d[3];
    for (int k = 0; k < 3; k++)
        d[k] = rr_v3_dot(n, rr_v3_sub(tri[k], p0));
    int m = 0;
    for (int k = 0; k < 3; k++) {
        int k1 = (k + 1) % 3;
        int in0 = d[k] >= -tol, in1 = d[k1] >= -tol;
        if (in0)
            out[m++] = tri[k];
        if (in0 != in1 && fabs(d[k] - d[k1]) > 0.0) {
            double t = d[k] / (d[k] - d[k1]);
            out[m++] = rr_v3_add(tri[k], rr_v3_scale(rr_v3_sub(tri[k1], tri[k]), t));
        }
    }
    return m;
}

static double plane_max_dist(const rad_patches *P, const rad_patch *q, rr_vec3 n, rr_vec3 p0)
{
    double m = -INFINITY;
    for (int k = 0; k < 3; k++)
        m = fmax(m, rr_v3_dot(n, rr_v3_sub(P->verts[q->v[k]], p0)));
    return m;
}

/* Quadrature points of patch i: n stratified points x, the shadow-ray origins
 * xo for them, and for each the (u, v) of its shadow ray's target on the other
 * patch: stratum perm[k] (a random pairing), jittered once per row. */
typedef struct qpoints {
    rr_vec3 *x, *xo;
    uint32_t *perm;
    double *tuv; /* 2 per point */
    uint32_t n;
} qpoints;

static void qpoints_make(const ff_ctx *c, const rad_patch *pi, qpoints *q, rr_rng *rng)
{
    for (uint32_t k = 0; k < q->n; k++) {
        double u, v;
        rad_ff_tri_stratum(k, q->n, rng, &u, &v);
        q->x[k] = patch_point(c->P, pi, u, v);
        rr_vec3 xs, xn;
        surface_at(c, pi, q->x[k], &xs, &xn);
        q->xo[k] = offset_front(c, xs, xn);
    }
    rad_ff_shuffle(q->perm, q->n, rng);
    for (uint32_t k = 0; k < q->n; k++)
        rad_ff_tri_stratum(q->perm[k], q->n, rng, &q->tuv[2 * k], &q->tuv[2 * k + 1]);
}

/* Pairs whose centroids are closer than RAD_FF_NEAR times the sum of their
 * radii get RAD_FF_NEAR_REFINE times the points (at most RAD_FF_NEAR_MAX, and
 * never fewer than the base set). There F_point(x, j) varies fastest across i
 * (with a log-singular gradient along a shared edge), and there are only O(1)
 * such neighbours per patch, so the extra work is O(N) against the O(N^2) of
 * the rest. Measured on the unit cube in 432 patches with 16 points: the mean
 * (L1) error of the entries against a 1024-point reference falls from 1.5% to
 * 0.4%, the reciprocity defect sum |A_i F_ij - A_j F_ji| / sum A_i F_ij from
 * 2.3% to 0.6%, for about twice the time there (less in bigger scenes). The
 * price: a row no longer shares one point set, so an enclosure's raw rows sum
 * to 1 only up to the near pairs' quadrature error (0.8% there, 0.1% with 64
 * points) instead of to rounding; after the reciprocity step neither variant
 * keeps that exactness (2% without refinement, 0.4% with). */
#define RAD_FF_NEAR 2.0
#define RAD_FF_NEAR_REFINE 16u
#define RAD_FF_NEAR_MAX 256u

static double patch_radius(const rad_patches *P, const rad_patch *q)
{
    double r = 0.0;
    for (int k = 0; k < 3; k++)
        r = fmax(r, rr_v3_len(rr_v3_sub(P->verts[q->v[k]], q->centroid)));
    return r;
}

/* The shadow ray's target for point k: (u, v) on the clipped polygon (a
 * triangle, or a quad split into two by area), not on all of j. A target on
 * the part of j behind i's plane would be hidden (it lies behind i, under the
 * box that i is a side of...) and would count against visibility for a part
 * of j that F_point already left out: Cornell's blocks lost 8% of their
 * factor to the floor that way. The quad's triangle is picked by the golden
 * ratio sequence in k, independent of the (u, v) stratum perm[k]. */
rr_vec3 rad__poly_point(const rr_vec3 *poly, int nv, double u, double v, uint32_t k)
{
    int t = 0;
    if (nv == 4) {
        double a1 = rr_v3_len(rr_v3_cross(rr_v3_sub(poly[1], poly[0]), rr_v3_sub(poly[2], poly[0])));
        double a2 = rr_v3_len(rr_v3_cross(rr_v3_sub(poly[2], poly[0]), rr_v3_sub(poly[3], poly[0])));
        double w = fmod(0.5 + 0.6180339887498949 * k, 1.0);
        t = w * (a1 + a2) >= a1;
    }
    rr_vec3 A = poly[0], B = poly[1 + t], C = poly[2 + t];
    return rr_v3_add(A, rr_v3_add(rr_v3_scale(rr_v3_sub(B, A), u), rr_v3_scale(rr_v3_sub(C, A), v)));
}

double rad__facet_scale(const rad_patches *P, const rad_patch *q)
{
    if (q->tri >= 0)
        return 1.0;
    rr_vec3 A = P->verts[q->v[0]], B = P->verts[q->v[1]], C = P->verts[q->v[2]];
    double flat = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
    return flat > 0 ? q->area / flat : 1.0;
}

/* Mean over the points of q of F_point(x, poly) * V(x, j): the estimate of
 * F_ij, poly being j clipped to i's front half-space. */
static double pair_ff(const ff_ctx *c, const rad_patch *pi, const rad_patch *pj, const rr_vec3 *poly, int nv,
                      const qpoints *q)
{
    double sum = 0.0;
    for (uint32_t k = 0; k < q->n; k++) {
        rr_vec3 x = q->x[k];
        /* x behind j's plane sees j's back: nothing (j may straddle i's plane
         * while i straddles j's). */
        if (rr_v3_dot(pj->normal, rr_v3_sub(x, pj->centroid)) <= c->plane_tol)
            continue;
        double f = rad_ff_point_polygon(x, pi->normal, poly, nv);
        if (!(f > 0.0))
            continue;
        rr_vec3 ys, yn;
        surface_at(c, pj, rad__poly_point(poly, nv, q->tuv[2 * k], q->tuv[2 * k + 1], k), &ys, &yn);
        rr_vec3 o = q->xo[k], t = offset_front(c, ys, yn);
        rr_ray r = {o, rr_v3_sub(t, o)};
        /* Stop just short of the target (RT_SHADOW_END, the shadow-ray rule of
         * rt.h): j itself (or its neighbours in its plane) must not count as
         * occluders. */
        if (!rt_accel_occluded(c->a, r, 0.0, RT_SHADOW_END))
            sum += f;
    }
    return sum / q->n * rad__facet_scale(c->P, pj);
}

/* Row i by quadrature into the scratch row; returns its length. */
static size_t quad_row(const ff_ctx *c, uint32_t i, ff_scratch *w)
{
    const rad_patches *P = c->P;
    const rad_patch *pi = &P->p[i];
    if (!(pi->area > 0.0))
        return 0;
    rr_rng rng = rr_rng_make(c->seed, i);
    qpoints base = {w->x, w->xo, w->perm, w->tuv, (uint32_t)c->samples};
    qpoints near = {w->x + base.n, w->xo + base.n, w->perm + base.n, w->tuv + 2 * base.n, c->near_samples};
    int have_near = 0;
    qpoints_make(c, pi, &base, &rng);
    double ri = patch_radius(P, pi);
    size_t m = 0;
    for (uint32_t j = 0; j < P->n; j++) {
        const rad_patch *pj = &P->p[j];
        if (j == i || !(pj->area > 0.0))
            continue;
        /* Cheap culls: j wholly behind (or in) i's plane, or i wholly behind
         * j's plane, exchange nothing. */
        if (plane_max_dist(P, pj, pi->normal, pi->centroid) <= c->plane_tol ||
            plane_max_dist(P, pi, pj->normal, pj->centroid) <= c->plane_tol)
            continue;
        /* Patches are planar, so every x_k has the same tangent plane: clip j
         * against it once. */
        rr_vec3 tri[3] = {P->verts[pj->v[0]], P->verts[pj->v[1]], P->verts[pj->v[2]]}, poly[4];
        int nv = rad__clip_front(tri, pi->normal, pi->centroid, c->plane_tol, poly);
        if (nv < 3)
            continue;
        const qpoints *q = &base;
        if (near.n > base.n &&
            rr_v3_len(rr_v3_sub(pi->centroid, pj->centroid)) < RAD_FF_NEAR * (ri + patch_radius(P, pj))) {
            if (!have_near) { /* made once per row, at its first near pair */
                qpoints_make(c, pi, &near, &rng);
                have_near = 1;
            }
            q = &near;
        }
        double f = pair_ff(c, pi, pj, poly, nv, q);
        if (f > 0.0) {
            w->col[m] = j;
            w->val[m] = f;
            m++;
        }
    }
    return m;
}

/* ---- Monte Carlo ---- */

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Whether the origin of ray r, on a surface of normal n, lies inside a
 * space closed by back faces (under a box standing on the floor): r met a
 * back face first, and so do four probes close to the tangent plane (sine of
 * elevation RAD_FF_PROBE_SIN), at right angles in azimuth. A point under a
 * one-sided sheet (a table top) is not: some probe passes the sheet's edge,
 * unless the sheet reaches out ~4 times its height on every side. The probes,
 * like the rays' first legs, see back faces that the objects cull.
 * With gap > 0 the probes must instead each meet a surface, either side,
 * less than gap above the tangent plane (so within gap / RAD_FF_PROBE_SIN:
 * short rays): the origin lies in a slot (rad__ff_buried's thin gaps). */
/* The probes' azimuths: unit tangents of normal n's plane, t1 along r.d. */
static void probe_axes(rr_ray r, rr_vec3 n, rr_vec3 *t1, rr_vec3 *t2)
{
    rr_vec3 t = rr_v3_madd(r.d, n, -rr_v3_dot(r.d, n));
    if (rr_v3_len2(t) < 1e-12)
        t = rr_v3_cross(n, fabs(n.x) < 0.9 ? rr_v3(1, 0, 0) : rr_v3(0, 1, 0));
    *t1 = rr_v3_norm(t);
    *t2 = rr_v3_cross(n, *t1);
}

#define RAD_FF_PROBE_SIN 0.25
static int enclosed(const rt_accel *a, rr_ray r, rr_vec3 n, double gap)
{
    const double sn = RAD_FF_PROBE_SIN;
    rr_vec3 t1, t2;
    probe_axes(r, n, &t1, &t2);
    double cs = sqrt(1.0 - sn * sn);
    for (int k = 0; k < 4; k++) {
        rr_vec3 t = k < 2 ? t1 : t2;
        rr_ray p = {r.o, rr_v3_norm(rr_v3_madd(rr_v3_scale(n, sn), t, k % 2 ? -cs : cs))};
        rt_hit h;
        if (!rt_accel_closest_two_sided(a, p, 0.0, gap > 0 ? gap / sn : INFINITY, &h))
            return 0;
        if (gap > 0 ? !(h.t * rr_v3_dot(p.d, n) < gap) : h.front)
            return 0;
    }
    return 1;
}

/* For a point at the bottom of a slot w wide (rad__ff_buried): whether its
 * own side goes on round it too (enclosed() finds that the other side
 * does): four probes from 0.9 w over it, sloping down at RAD_FF_PROBE_SIN,
 * each meet a surface w / 2 or more below their start. Beside a taller book
 * a short one's side ends at the mouth, and its band was buried
 * (notes/radiosity.md, "Slots"). */
static int own_side_goes_on(const rt_accel *a, rr_ray r, rr_vec3 n, double w)
{
    rr_vec3 t1, t2;
    probe_axes(r, n, &t1, &t2);
    const double sn = RAD_FF_PROBE_SIN, cs = sqrt(1.0 - sn * sn);
    rr_vec3 o = rr_v3_madd(r.o, n, 0.9 * w);
    for (int k = 0; k < 4; k++) {
        rr_vec3 t = k < 2 ? t1 : t2;
        rr_ray p = {o, rr_v3_norm(rr_v3_madd(rr_v3_scale(n, -sn), t, k % 2 ? -cs : cs))};
        rt_hit h;
        if (!rt_accel_closest_two_sided(a, p, 0.0, w / sn, &h))
            return 0;
        if (!(h.t * sn > 0.5 * w)) /* met a surface (the other side's) well above this one */
            return 0;
    }
    return 1;
}

int rad__ff_buried(const scene *s, const rt_accel *a, rr_ray r, rr_vec3 n, const rt_hit *h, double bury, double gap,
                   int sides)
{
    if (!h->front)
        return s->objects[h->object].cull_backfaces || h->t < bury || enclosed(a, r, n, 0.0);
    /* A thin gap (rad_ff_internal.h): the front of a surface that does not
     * emit at a height w under gap above the tangent plane, and surfaces
     * under 2 w on every side (a slot about w wide around the point; a
     * point of the floor under a low overhang is not in one). */
    double w = h->t * rr_v3_dot(r.d, n);
    return gap > 0 && w < gap && !(rr_rgb_max(s->materials[h->material].emission) > 0) &&
                   enclosed(a, r, n, 2.0 * w + 0.01 * gap) && (!sides || own_side_goes_on(a, r, n, w))
               ? RAD_BURIED_SLOT
               : 0;
}

int rad__ff_point_buried(const scene *s, const rt_accel *a, rr_ray r, rr_vec3 n, double bury, double gap, int sides)
{
    rt_hit h;
    return rt_accel_closest_two_sided(a, r, 0.0, INFINITY, &h) ? rad__ff_buried(s, a, r, n, &h, bury, gap, sides) : 0;
}

/* Row i by Monte Carlo: the patches hit, in w->hits[0 .. return).
 * Whether a ray hits j depends on origin and direction jointly, so the rays
 * are stratified in 4-D: the first g^2 = (q^2)^2 rays (q = floor(ns^(1/4)))
 * take every pair (origin stratum a, direction stratum b) of q^2 x q^2
 * strata once; stratifying the two 2-D marginals and pairing them at random
 * would leave most of the binomial variance in place. The remaining
 * ns - g^2 rays are stratified per marginal and paired by a permutation. */
static size_t mc_row(const ff_ctx *c, uint32_t i, ff_scratch *w)
{
    const rad_patches *P = c->P;
    const rad_patch *pi = &P->p[i];
    uint32_t ns = (uint32_t)c->samples, q = rad_ff_isqrt(rad_ff_isqrt(ns)), g = q * q, rest = ns - g * g;
    w->open = ns;
    if (!(pi->area > 0.0))
        return 0;
    rr_rng rng = rr_rng_make(c->seed, i);
    rad_ff_shuffle(w->perm, rest, &rng);
    double bury = RAD_FF_BURY * sqrt(pi->area), gap = rr_rgb_max(pi->emission) > 0 ? 0.0 : bury;
    size_t m = 0;
    w->open = 0;
    for (uint32_t k = 0; k < ns; k++) {
        double u1, u2, v1, v2;
        if (k < g * g) {
            rad_ff_tri_stratum(k / g, g, &rng, &u1, &u2);
            rad_ff_square_stratum(k % g, g, &rng, &v1, &v2);
        } else {
            rad_ff_tri_stratum(k - g * g, rest, &rng, &u1, &u2);
            rad_ff_square_stratum(w->perm[k - g * g], rest, &rng, &v1, &v2);
        }
        rr_vec3 xs, xn;
        surface_at(c, pi, patch_point(P, pi, u1, u2), &xs, &xn);
        rr_ray r = {offset_front(c, xs, xn), rad_ff_cosine_dir(xn, v1, v2)};
        double weight = 1.0;
        w->open++;
        for (int bounce = 0;; bounce++) {
            rt_hit h;
            /* The first leg sees culled back faces too: a ray from under a
             * closed box (a shelf board's end against its side panel) meets
             * the box's back face first, and the culled query would let it
             * pass through the box and gather light there is none of. From
             * outside, a closed box shows a front face first, so such a hit
             * means the origin is inside: buried at any distance. */
            int hit = bounce == 0 ? rt_accel_closest_two_sided(c->a, r, 0.0, INFINITY, &h)
                                  : rt_accel_closest(c->a, r, 0.0, INFINITY, &h);
            if (!hit)
                break; /* escaped */
            if (bounce == 0 && rad__ff_buried(c->s, c->a, r, xn, &h, bury, gap, 0)) {
                w->open--; /* started under a surface: not counted (rad.h) */
                break;
            }
            /* Back side: no patch receives there (one-sided patches); counted
             * as escaped. A planar patch cannot see itself; a hit on i is
             * rounding (or, after a mirror, a patch seeing itself in it). */
            const scene_material *mat = &c->s->materials[h.material];
            uint32_t j = h.front ? rad_patch_locate(P, c->s, h.tri, h.object, h.point) : UINT32_MAX;
            if (j < P->n && (j != i || bounce > 0)) {
                w->hits[m] = j;
                w->hw[m++] = weight;
            }
            /* Extended form factors: the ray goes on off a mirror (either
             * side), carrying the mirror's reflectance. */
            double rm = rr_rgb_mean(mat->mirror);
            if (!(rm > 0.0) || bounce >= c->mirror_depth)
                break;
            weight *= rm;
            rr_vec3 R = rr_v3_madd(r.d, h.normal, -2.0 * rr_v3_dot(r.d, h.normal));
            r.o = rt_offset_origin(c->ext, h.point, h.normal, R);
            r.d = R;
        }
    }
    return m;
}

/* Hits -> (col, summed weight / samples), sorted by column, into w->col /
 * w->val. Hits and weights are sorted together (by column, then weight, so
 * the sums are the same whatever order the rays came in). */
static int cmp_wh(const void *a, const void *b)
{
    const wh *x = a, *y = b;
    if (x->j != y->j)
        return (x->j > y->j) - (x->j < y->j);
    return (x->w > y->w) - (x->w < y->w);
}

static size_t mc_compress(ff_scratch *w, size_t nh)
{
    int weighted = 0;
    for (size_t k = 0; k < nh && !weighted; k++)
        weighted = w->hw[k] != 1.0;
    if (!weighted) {
        qsort(w->hits, nh, sizeof *w->hits, cmp_u32);
    } else {
        /* Scenes with mirrors: hits and weights sorted as pairs. */
        for (size_t k = 0; k < nh; k++)
            w->pairs[k] = (wh){w->hits[k], w->hw[k]};
        qsort(w->pairs, nh, sizeof *w->pairs, cmp_wh);
        for (size_t k = 0; k < nh; k++) {
            w->hits[k] = w->pairs[k].j;
            w->hw[k] = w->pairs[k].w;
        }
    }
    size_t m = 0;
    for (size_t a = 0; a < nh;) {
        size_t b = a;
        double sum = 0.0;
        while (b < nh && w->hits[b] == w->hits[a])
            sum += w->hw[b++];
        w->col[m] = w->hits[a];
        w->val[m] = sum / w->open; /* hits of open rays (rad.h: buried parts) */
        m++;
        a = b;
    }
    return m;
}

/* ---- assembly ---- */

/* ---- per-thread scratch ---- */

static void scratch_free(ff_scratch *w)
{
    free(w->perm);
    free(w->x);
    free(w->xo);
    free(w->tuv);
    free(w->hits);
    free(w->hw);
    free(w->pairs);
    free(w->col);
    free(w->val);
}

/* Sized for one row of n patches by method m; 0 when out of memory (what was
 * allocated is still in *w, for scratch_free). */
static int scratch_alloc(ff_scratch *w, const ff_ctx *c, rad_ff_method m, size_t n)
{
    size_t ns = (size_t)c->samples;
    memset(w, 0, sizeof *w);
    if (m == RAD_FF_QUADRATURE) {
        size_t nq = ns + c->near_samples;
        w->perm = malloc(nq * sizeof *w->perm);
        w->x = malloc(nq * sizeof *w->x);
        w->xo = malloc(nq * sizeof *w->xo);
        w->tuv = malloc(2 * nq * sizeof *w->tuv);
        w->col = malloc((n ? n : 1) * sizeof *w->col);
        w->val = malloc((n ? n : 1) * sizeof *w->val);
        return w->perm && w->x && w->xo && w->tuv && w->col && w->val;
    }
    size_t nh = ns * (size_t)(1 + c->mirror_depth);
    w->perm = malloc(ns * sizeof *w->perm);
    w->hits = malloc(nh * sizeof *w->hits);
    w->hw = malloc(nh * sizeof *w->hw);
    w->col = malloc(nh * sizeof *w->col);
    w->val = malloc(nh * sizeof *w->val);
    w->pairs = c->mirror_depth > 0 ? malloc(nh * sizeof *w->pairs) : NULL;
    return w->perm && w->hits && w->hw && w->col && w->val && (c->mirror_depth == 0 || w->pairs);
}

/* One more row done: progress every 64 rows and at the end, one thread at a time. */
static void report_row(const rad_ff_opts *o, size_t *done, size_t n)
{
    if (!o->progress)
        return;
    size_t now;
#pragma omp atomic capture
    now = ++*done;
    if (now % 64 == 0 || now == n) {
#pragma omp critical(rad_ff_progress)
        o->progress(o->progress_user, now, n);
    }
}

/* The rows this rank computed, as one block: per row its index, length,
 * columns and values; then every rank's blocks, unpacked into rows. The
 * block starts with this rank's failure code, so that all ranks agree on
 * whether the pass failed (max over ranks). */
static rr_status exchange_rows(rr_dist *dist, ff_row *rows, size_t n, int *failed, rr_error *err)
{
    /* A row is sent when this rank made it: it has entries or an open part
     * (a row without either, a wholly buried patch's, is the same as none). */
    size_t bytes = sizeof(uint64_t) * 2;
    for (size_t i = 0; i < n; i++)
        if (rows[i].n || rows[i].open != 0.0)
            bytes += 3 * sizeof(uint64_t) + rows[i].n * (sizeof(uint32_t) + sizeof(double));
    unsigned char *mine = malloc(bytes), *p = mine;
    if (!mine)
        return rr_error_set(err, RR_ERR_NOMEM, "radiosity: out of memory for the form-factor exchange");
    uint64_t head[2] = {(uint64_t)*failed, 0};
    for (size_t i = 0; i < n; i++)
        head[1] += rows[i].n || rows[i].open != 0.0;
    memcpy(p, head, sizeof head), p += sizeof head;
    for (size_t i = 0; i < n; i++) {
        if (!rows[i].n && rows[i].open == 0.0)
            continue;
        uint64_t h[3] = {(uint64_t)i, (uint64_t)rows[i].n, 0};
        memcpy(&h[2], &rows[i].open, sizeof(double));
        memcpy(p, h, sizeof h), p += sizeof h;
        memcpy(p, rows[i].col, rows[i].n * sizeof(uint32_t)), p += rows[i].n * sizeof(uint32_t);
        memcpy(p, rows[i].val, rows[i].n * sizeof(double)), p += rows[i].n * sizeof(double);
    }
    void *all = NULL;
    size_t total = 0;
    rr_status st = dist->gather(dist, mine, bytes, &all, &total, err);
    free(mine);
    if (st != RR_OK)
        return st;
    const unsigned char *q = all, *end = q + total;
    while (st == RR_OK && q + sizeof head <= end) {
        memcpy(head, q, sizeof head), q += sizeof head;
        if ((int)head[0] > *failed)
            *failed = (int)head[0];
        for (uint64_t r = 0; r < head[1] && st == RR_OK; r++) {
            uint64_t h[3];
            if ((size_t)(end - q) < sizeof h) {
                st = rr_error_set(err, RR_ERR_INTERNAL, "radiosity: a rank sent a malformed form-factor row");
                break;
            }
            memcpy(h, q, sizeof h), q += sizeof h;
            size_t i = (size_t)h[0], m = (size_t)h[1];
            if (i >= n || (size_t)(end - q) < m * (sizeof(uint32_t) + sizeof(double))) {
                st = rr_error_set(err, RR_ERR_INTERNAL, "radiosity: a rank sent a malformed form-factor row");
                break;
            }
            if (rows[i].n == 0 && rows[i].open == 0.0) { /* another rank's row */
                memcpy(&rows[i].open, &h[2], sizeof(double));
                rows[i].col = malloc((m ? m : 1) * sizeof *rows[i].col);
                rows[i].val = malloc((m ? m : 1) * sizeof *rows[i].val);
                if (!rows[i].col || !rows[i].val) {
                    st = rr_error_set(err, RR_ERR_NOMEM, "radiosity: out of memory for the form factors");
                    break;
                }
                memcpy(rows[i].col, q, m * sizeof(uint32_t));
                memcpy(rows[i].val, q + m * sizeof(uint32_t), m * sizeof(double));
                rows[i].n = m;
            }
            q += m * (sizeof(uint32_t) + sizeof(double));
        }
    }
    free(all);
    return st;
}

static void ctx_init(ff_ctx *c, const scene *s, const rt_accel *a, const rad_patches *P, const rad_ff_opts *o)
{
    c->s = s;
    c->a = a;
    c->P = P;
    c->samples = o->samples;
    c->seed = o->seed;
    c->mirror_depth = o->method == RAD_FF_MONTE_CARLO && o->mirror_depth > 0 ? o->mirror_depth : 0;
    /* Near pairs: RAD_FF_NEAR_REFINE times the points, but no more than
     * RAD_FF_NEAR_MAX (nor fewer than the base set): past a few hundred
     * points the near-field error is already below the far-field one. */
    c->near_samples = (uint32_t)o->samples;
    if (c->near_samples < RAD_FF_NEAR_MAX)
        c->near_samples = c->near_samples * RAD_FF_NEAR_REFINE < RAD_FF_NEAR_MAX ? c->near_samples * RAD_FF_NEAR_REFINE
                                                                                 : RAD_FF_NEAR_MAX;
    c->ext = rt_scene_scale(s);
    rr_vec3 bmax = rr_v3_max(rr_v3(fabs(s->bbox_min.x), fabs(s->bbox_min.y), fabs(s->bbox_min.z)),
                             rr_v3(fabs(s->bbox_max.x), fabs(s->bbox_max.y), fabs(s->bbox_max.z)));
    double mabs = fmax(bmax.x, fmax(bmax.y, bmax.z));
    /* Coplanar patches differ from their common plane by rounding of the
     * vertex coordinates only; anything nearer than this is "in" the plane. */
    c->plane_tol = 1e-9 * ((isfinite(mabs) ? mabs : 0.0) + c->ext);
}

static void rows_free(ff_row *rows, size_t n)
{
    for (size_t i = 0; rows && i < n; i++) {
        free(rows[i].col);
        free(rows[i].val);
    }
    free(rows);
}

/* Row i into rows[i]; 0, or 1 when out of memory. */
static int one_row(const ff_ctx *c, const rad_ff_opts *o, ff_scratch *w, size_t i, ff_row *rows)
{
    size_t m = o->method == RAD_FF_QUADRATURE ? quad_row(c, (uint32_t)i, w)
                                              : mc_compress(w, mc_row(c, (uint32_t)i, w));
    ff_row *r = &rows[i];
    r->n = m;
    r->open = o->method == RAD_FF_QUADRATURE ? 1.0 : (double)w->open / (double)c->samples;
    if (m == 0)
        return 0;
    r->col = malloc(m * sizeof *r->col);
    r->val = malloc(m * sizeof *r->val);
    if (!r->col || !r->val)
        return 1;
    memcpy(r->col, w->col, m * sizeof *r->col);
    memcpy(r->val, w->val, m * sizeof *r->val);
    return 0;
}

/* Every row this process takes (all of them, or those of o->dist's list)
 * into rows; *failed 1 when out of memory, 2 when interrupted. */
static void compute_rows(const ff_ctx *c, const rad_ff_opts *o, size_t n, ff_row *rows, int *failed)
{
    size_t done = 0;
    long long next_row = 0;
    int nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
    rt_ray_counts total = {0, 0};
#pragma omp parallel num_threads(nthreads)
    {
        rt_ray_counts before = rt_ray_counts_of_thread();
        ff_scratch w;
        int ok = scratch_alloc(&w, c, o->method, n);
        if (!ok) {
#pragma omp atomic write
            *failed = 1;
        }
        long long i;
        while ((i = rr_dist_take(o->dist, &next_row, (long long)n)) >= 0) {
            int stop;
#pragma omp atomic read
            stop = *failed;
            if (!stop && o->interrupt && *o->interrupt) {
#pragma omp atomic write
                *failed = 2;
                stop = 2;
            }
            if (stop || !ok)
                continue;
            if (one_row(c, o, &w, (size_t)i, rows)) {
#pragma omp atomic write
                *failed = 1;
                continue;
            }
            report_row(o, &done, n);
        }
        scratch_free(&w);
        rt_ray_counts_add_since(&total, before);
    }
    if (o->rays)
        *o->rays = total;
}

/* The rows as one CSR matrix (NULL when out of memory). */
static rad_ff *assemble(const ff_row *rows, size_t n)
{
    size_t nnz = 0;
    for (size_t i = 0; i < n; i++)
        nnz += rows[i].n;
    rad_ff *F = rad__ff_alloc(n, nnz);
    if (!F)
        return NULL;
    size_t e = 0;
    for (size_t i = 0; i < n; i++) {
        if (rows[i].n) {
            memcpy(F->col + e, rows[i].col, rows[i].n * sizeof *F->col);
            memcpy(F->val + e, rows[i].val, rows[i].n * sizeof *F->val);
        }
        F->open[i] = rows[i].open;
        e += rows[i].n;
        F->rowptr[i + 1] = e;
    }
    return F;
}

rr_status rad_ff_compute(const scene *s, const rt_accel *a, const rad_patches *P, const rad_ff_opts *o, rad_ff **out,
                         rr_error *err)
{
    if (!o || o->samples < 1 || (o->method != RAD_FF_MONTE_CARLO && o->method != RAD_FF_QUADRATURE) || o->threads < 0)
        return rr_error_set(err, RR_ERR_INVALID,
                            "%s: radiosity: form factors need a known method, samples >= 1 and threads >= 0 "
                            "(got method %d, %d samples, %d threads)",
                            s->path, o ? (int)o->method : -1, o ? o->samples : 0, o ? o->threads : 0);
    if (P->n > UINT32_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: radiosity: %zu patches is more than 2^32", s->path, P->n);
    ff_ctx c;
    ctx_init(&c, s, a, P, o);
    size_t n = P->n;
    ff_row *rows = calloc(n ? n : 1, sizeof *rows);
    if (!rows)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for form factors", s->path);
    int failed = 0; /* 1: out of memory, 2: interrupted */
    rr_dist *dist = o->dist;
    rr_status st = dist ? dist->begin(dist, (long long)n, err) : RR_OK;
    if (st == RR_OK)
        compute_rows(&c, o, n, rows, &failed);
    /* Over several ranks every rank learns every row; a failure anywhere
     * fails everywhere (the exchange carries it). */
    if (st == RR_OK && dist && (st = dist->end(dist, err)) == RR_OK)
        st = exchange_rows(dist, rows, n, &failed, err);
    if (st == RR_OK && failed == 2)
        st = rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (form factors)", s->path);
    if (st != RR_OK) {
        rows_free(rows, n);
        return st;
    }
    rad_ff *F = failed ? NULL : assemble(rows, n);
    rows_free(rows, n);
    F = rad__ff_finish(P, F, o);
    if (!F)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for form factors (%zu patches)", s->path,
                            n);
    /* Reciprocity and row balancing are serial (seconds on 100k patches): an
     * interrupt that came during them stops the pass here. */
    if (o->interrupt && *o->interrupt) {
        rad_ff_destroy(F);
        return rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (form factors)", s->path);
    }
    *out = F;
    return RR_OK;
}
