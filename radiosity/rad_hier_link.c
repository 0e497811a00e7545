/* rad_hier_link.c - the hierarchical pass's links between two elements
 * (rad_hier.c): the quadrature points, the shadow rays and the point-to-
 * polygon factor of a link, its visibility and how much the factor varies
 * over the receiver (rad_hier.c's header has the transport; links from
 * clusters are in rad_hier_cluster.c). */
#include <math.h>
#include <string.h>

#include "rad_ff_internal.h"
#include "rad_hier_ctx.h"
#include "rad_pass_internal.h"

/* The quadrature rules of an element (barycentrics b, weights w summing to
 * 1): FIXED, the 4 points of k_pts; SMOOTH, the 7-point rule of degree 5
 * (Dunavant 1985) over the whole element, for near pairs whose centres are
 * further apart than their radii; NEAR, that rule on each of its 4
 * children (el_split's order), for the nearer pairs and for points whose
 * burial is held (hel.nbur bit k for point k). They replaced the
 * centroids of 36 similar sub-triangles, whose error falls only as 1 / M
 * along a shared edge: over 6000 random facing pairs with centres closer
 * than twice their radii, against 8100 points (test_hier
 * test_near_pair_rules), the largest relative error of the mean factor was, for
 * centre distance over the radii's sum in [0, 1), [1, 1.2), [1.2, 1.45),
 * [1.45, 2): 36 points 4.8, 1.6, 1.1, 0.7 %; SMOOTH -, 0.65, 0.28, 0.08 %;
 * NEAR 4.2, 0.07, 0.008, 0.003 %. Near pairs were 41 M of room.json's
 * point-to-polygon factors (1.1 M evaluations), 10 % of its pass. */
enum { RULE_FIXED, RULE_NEAR, RULE_SMOOTH };
#define NEAR_N 28
_Static_assert(NEAR_N <= 64, "hel.nbur holds a bit per near-pair point");
static const double d7_b[7][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3},
                                  {0.059715871789770, 0.470142064105115, 0.470142064105115},
                                  {0.470142064105115, 0.059715871789770, 0.470142064105115},
                                  {0.470142064105115, 0.470142064105115, 0.059715871789770},
                                  {0.797426985353087, 0.101286507323456, 0.101286507323456},
                                  {0.101286507323456, 0.797426985353087, 0.101286507323456},
                                  {0.101286507323456, 0.101286507323456, 0.797426985353087}};
static const double d7_w[7] = {0.225,
                               0.132394152788506, 0.132394152788506, 0.132394152788506,
                               0.125939180544827, 0.125939180544827, 0.125939180544827};
/* The children's corners in the parent's barycentrics (el_split's order):
 * A, B, C, then the middle one (mBC, mCA, mAB). */
static const double ch[4][3][3] = {{{1, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}},
                                   {{0.5, 0.5, 0}, {0, 1, 0}, {0, 0.5, 0.5}},
                                   {{0.5, 0, 0.5}, {0, 0.5, 0.5}, {0, 0, 1}},
                                   {{0, 0.5, 0.5}, {0.5, 0, 0.5}, {0.5, 0.5, 0}}};

static int quad_points(int rule, const hel *e, double (*b)[3], double *w)
{
    if (rule == RULE_FIXED) { /* e's fixed points (el_kpt) */
        for (int k = 0; k < 4; k++) {
            el_kpt(e, k, b[k]);
            w[k] = 0.25;
        }
        return 4;
    }
    if (rule == RULE_SMOOTH) {
        memcpy(b, d7_b, sizeof d7_b);
        memcpy(w, d7_w, sizeof d7_w);
        return 7;
    }
    int n = 0;
    for (int q = 0; q < 4; q++)
        for (int k = 0; k < 7; k++, n++) {
            for (int a = 0; a < 3; a++)
                b[n][a] = d7_b[k][0] * ch[q][0][a] + d7_b[k][1] * ch[q][1][a] + d7_b[k][2] * ch[q][2][a];
            w[n] = 0.25 * d7_w[k];
        }
    return n;
}

int rad__hier_near_rule(int smooth, double (*b)[3], double *w)
{
    return quad_points(smooth ? RULE_SMOOTH : RULE_NEAR, NULL, b, w);
}

uint64_t rad__hier_near_buried(const hctx *c, const hel *e)
{
    double b[NEAR_N][3], w[NEAR_N];
    int np = quad_points(RULE_NEAR, NULL, b, w);
    uint64_t m = 0;
    for (int k = 0; k < np; k++)
        if (rad__hier_point_buried(c, e, tri_at(e->c, b[k][0], b[k][1], b[k][2])))
            m |= (uint64_t)1 << k;
    return m;
}

/* Element <- element: the mean over r's quadrature points x of the exact
 * point-to-polygon factor of s clipped to r's front (Lambert's contour
 * integral), times the visibility. Pairs closer than twice their radii
 * (where F_point varies fastest, with a log-singular gradient along a shared
 * edge) take 36 points instead of 4: with 4, the row sums of a closed cube
 * fell 10 % short. Visibility: one shadow ray from each of the 4 points of
 * k_pts to a point of the clipped polygon; with 4 quadrature points each
 * point's factor counts only if its ray passed, with 36 the mean factor is
 * scaled by the share of the 4 rays that passed (36 rays per near pair were
 * 84 % of room.json's pairs and most of its pass time). The rays start at
 * r's open points only (a buried point gathers nothing that r's open part
 * gets: shelf boards under books were +20..41 %), and one that ends on a
 * buried part of s does not pass (s's cover hides it). *dF is the largest
 * minus the smallest point factor without visibility (the refinement's
 * tests must not read the rays that the transport is estimated from: see
 * rad_hier.c, "Decide, then estimate"); v counts the rays cast, passed, and cast
 * to open parts of s (which alone decide the partial-visibility split, as
 * for clusters: rad_hier_cluster.c, visibility). */
typedef struct vis_count {
    int seen, pass, open;
    int rot; /* the strata's rotation, drawn with the link's first ray */
    /* weigh: a near pair whose receiver reads points of its own (el_kpt) or
     * whose source is partly buried: the rays' ends are drawn by the point
     * factor's density (toward_s), not by area. By area, the 4 rays from a
     * lamp body's top, 3 mm under a ceiling element of 0.8 m2, ended far
     * off and left through the slot's mouth, and the link read the covered
     * ceiling straight above as seen. */
    int weigh;
    int unit; /* weigh: the rays that passed, dark ends included (the B = 1 gather's visibility) */
    int per;  /* rays from each point: 1 while refining, more in the estimate (rad_hier_rounds.c) */
    /* exact: a far link's visibility in the estimate, without rays: the
     * triangles between r and s (exact_occluders), each point's visible
     * factor (rad__ff_visible), its share counted as VIS_ONE rays */
    const rr_vec3 (*occ)[3];
    const unsigned char *cull;
    int nocc, exact;
} vis_count;

/* The sphere a root lies on, when its patch faces out of it (an analytic
 * sphere seen from outside); NULL otherwise. */
static const scene_object *outward_sphere(const hctx *c, uint32_t root, rr_vec3 xs, rr_vec3 ns)
{
    if (c->rt[root].flat) /* a flat root's, read without its patch */
        return NULL;
    const rad_patch *p = &c->R->p[root];
    if (p->tri >= 0 || rt_prim_kind_of(c->s, p->object) != RT_PRIM_SPHERE)
        return NULL;
    const scene_object *ob = &c->s->objects[p->object];
    return rr_v3_dot(ns, rr_v3_sub(xs, ob->center)) > 0 ? ob : NULL;
}

/* The parameters u0 <= u1 where x + u d meets sphere ob; 0 when it misses. */
static int sphere_meets(const scene_object *ob, rr_vec3 x, rr_vec3 d, double *u0, double *u1)
{
    rr_vec3 m = rr_v3_sub(x, ob->center);
    double a = rr_v3_len2(d), b = rr_v3_dot(m, d), cc = rr_v3_len2(m) - ob->radius * ob->radius;
    double disc = b * b - a * cc;
    if (!(a > 0) || !(disc > 0))
        return 0;
    *u0 = (-b - sqrt(disc)) / a;
    *u1 = (-b + sqrt(disc)) / a;
    return 1;
}

void rad__hier_sphere_end(const hctx *c, uint32_t yr, rr_vec3 x, rr_vec3 *y, rr_vec3 *ny)
{
    double u0, u1;
    const scene_object *oy = outward_sphere(c, yr, *y, *ny);
    rr_vec3 d = rr_v3_sub(*y, x);
    if (oy && sphere_meets(oy, x, d, &u0, &u1) && u0 > 0 && u0 < 1) { /* meets the source's sphere first there */
        *y = rr_v3_madd(x, d, u0);
        *ny = rr_v3_norm(rr_v3_sub(*y, oy->center));
        return;
    }
    /* A solid's curved piece: where the segment enters the solid close
     * before y (rad_hier_ctx.h). */
    const rad_patch *p = &c->R->p[yr];
    if (c->rt[yr].flat || p->tri >= 0 || rt_prim_kind_of(c->s, p->object) != RT_PRIM_SOLID)
        return;
    double len = rr_v3_len(d), near = 2.0 * sqrt(p->area);
    if (!(len > 0))
        return;
    rt_spans sp;
    rr_ray ray = {x, d};
    rt_solid_spans(c->s, c->a, p->object, ray, 0.0, 1.0, &sp);
    if (sp.n > 0 && sp.s[0].in.t > 0 && sp.s[0].in.t < 1.0 && (1.0 - sp.s[0].in.t) * len < near) {
        const rt_span_end *e = &sp.s[0].in;
        *y = rr_v3_madd(x, d, e->t);
        rr_vec3 m = rt_csg_leaf_normal(c->s, e->leaf, e->surface, *y);
        *ny = e->flip ? rr_v3_neg(m) : m;
    }
}

/* Whether p (in the plane of the convex polygon poly, normal m) lies in it. */
static int in_poly(const rr_vec3 *poly, int nv, rr_vec3 m, rr_vec3 p)
{
    for (int i = 0; i < nv; i++) {
        rr_vec3 a = poly[i], b = poly[(i + 1) % nv];
        if (rr_v3_dot(rr_v3_cross(rr_v3_sub(b, a), rr_v3_sub(p, a)), m) < 0.0)
            return 0;
    }
    return 1;
}

/* A point of poly (s clipped to r's front) drawn from x by the point
 * factor's density: a cosine-distributed direction about r's normal, met
 * with s's plane inside poly (vis_count.weigh), into *y; up to 16 tries,
 * else *y is left as it is (drawn by area: s then takes a small share of
 * x's view, whose visibility matters little). */
static void toward_s(const rview *rv, rr_vec3 x, const rr_vec3 *poly, int nv, rr_rng *rng, rr_vec3 *y)
{
    rr_vec3 m = rr_v3_cross(rr_v3_sub(poly[1], poly[0]), rr_v3_sub(poly[2], poly[0]));
    double ml = rr_v3_len(m);
    if (!(ml > 0))
        return;
    m = rr_v3_scale(m, 1.0 / ml);
    for (int t = 0; t < 16; t++) {
        double u1 = rr_rng_uniform(rng), u2 = rr_rng_uniform(rng);
        rr_vec3 d = rad_ff_cosine_dir(rv->n, u1, u2);
        double den = rr_v3_dot(m, d);
        if (!(fabs(den) > 1e-12))
            continue;
        double h = rr_v3_dot(m, rr_v3_sub(poly[0], x)) / den;
        if (!(h > 0))
            continue;
        rr_vec3 p = rr_v3_madd(x, d, h);
        if (in_poly(poly, nv, m, p)) {
            *y = p;
            return;
        }
    }
}

static int shadow_passes(const hctx *c, const rview *rv, const hel *ey, rr_vec3 x, const rr_vec3 *poly, int nv,
                         uint32_t k, rr_rng *rng, vis_count *v)
{
    rr_vec3 xs, xn, ys, yn;
    int m = 4; /* strata: 4^L, at least the link's 4 points' rays */
    while (m < VIS_RAYS * v->per)
        m *= 4;
    if (v->seen == 0)
        v->rot = (int)(m * rr_rng_uniform(rng)) & (m - 1);
    double a = rr_rng_uniform(rng), b = rr_rng_uniform(rng);
    if (a + b > 1.0) { /* fold the square onto the triangle */
        a = 1.0 - a;
        b = 1.0 - b;
    }
    /* Stratified: s cut into m triangles by halving L times (each into its
     * corners, then the middle one, turned over); the link's rays in turn
     * take stratum (seen + rot) mod m, whose base-4 digits, lowest first,
     * pick the child at each level from the top: consecutive rays (one
     * point's) fall in different quarters, then in different quarters of
     * those, and each ray's end is uniform on s. With m = 4 (one ray a
     * point) the four rays of a link cover the four quarters. */
    static const double off[4][2] = {{0.0, 0.0}, {0.5, 0.0}, {0.0, 0.5}, {0.5, 0.5}};
    int idx = (v->seen + v->rot) & (m - 1), dig[8], nd = 0;
    for (int t = m; t > 1; t /= 4, idx /= 4)
        dig[nd++] = idx & 3;
    for (int d = nd - 1; d >= 0; d--) { /* the deepest level first: into its parent's frame */
        int q = dig[d];
        double sg = q == 3 ? -0.5 : 0.5;
        a = off[q][0] + sg * a;
        b = off[q][1] + sg * b;
    }
    /* A quad (s cut by r's tangent plane) is two triangles, of which
     * rad__poly_point takes one by a golden-ratio sequence in its last
     * argument: with one ray a point (the refinement, whose draws grew the
     * tree) the point's index; in the estimate the ray's, so that a point's
     * rays go to both halves by area (by the point's index they all fell on
     * one half, its share read over half of s: notes/radiosity.md, "Exact
     * visibility in the estimate"). */
    uint32_t seq = v->per > 1 ? (uint32_t)v->seen : k;
    v->seen++;
    rr_vec3 y = rad__poly_point(poly, nv, a, b, seq);
    if (v->weigh)
        toward_s(rv, x, poly, nv, rng, &y);
    root_surface(c, ey->root, y, &ys, &yn);
    /* dark: the ray ends on a buried part of s, or (weigh) in a slot of an s
     * that reads points of its own: such an s straddles the slot's mouth,
     * and its radiosity, the mean over its open points, is mostly its light
     * outside the slot. A dark end does not pass; with weigh the ray is
     * traced all the same, for the B = 1 gather (unit), which must count
     * the surface it ends on as seen: left out, the row-sum scale made up for
     * the dark ceiling over a lamp body's top (notes/radiosity.md, "Slots"). */
    int dark = (ey->open < 1.0 && rad__hier_buried(c, ey, ys, yn)) ||
               (v->weigh && ey->own && rad__hier_in_slot(c, ey, ys, yn));
    if (dark && !v->weigh)
        return 0;
    if (!dark)
        v->open++;
    /* x on r as the source sees it (its image by way of a mirror): the
     * surface point found on the real r */
    root_surface(c, rv->e->root, way_back(c, rv->way, x), &xs, &xn);
    int passed;
    if (rv->way) {
        rad__hier_sphere_end(c, ey->root, way_point(c, rv->way, xs), &ys, &yn);
        passed = way_visible(c, rv->way, xs, xn, ys, yn);
    } else {
        rad__hier_sphere_end(c, ey->root, xs, &ys, &yn);
        rr_vec3 o = rt_offset_origin(c->ext, xs, xn, xn), t = rt_offset_origin(c->ext, ys, yn, yn);
        rr_ray ray = {o, rr_v3_sub(t, o)};
        passed = !rt_accel_occluded(c->a, ray, 0.0, RT_SHADOW_END);
    }
    v->unit += passed;
    if (dark)
        return 0;
    v->pass += passed;
    return passed;
}

/* The share of v->per shadow rays from x that pass (each through the
 * next of the strata, so that 4 from one point cover s). */
static double point_passes(const hctx *c, const rview *rv, const hel *ey, rr_vec3 x, const rr_vec3 *poly, int nv,
                           uint32_t k, rr_rng *rng, vis_count *v)
{
    int n = 0;
    for (int j = 0; j < v->per; j++)
        n += shadow_passes(c, rv, ey, x, poly, nv, k, rng, v);
    return (double)n / v->per;
}

/* The share of the factor f from x to poly that x sees past v's
 * occluders, exactly (rad__ff_visible), counted as VIS_ONE rays of which
 * that share passed; by v->per rays where the visible part has too many
 * pieces. */
static double exact_share(const hctx *c, const rview *rv, const hel *ey, rr_vec3 x, const rr_vec3 *poly, int nv,
                          double f, uint32_t k, rr_rng *rng, vis_count *v)
{
    int hidden;
    double fv = rad__ff_visible(x, rv->n, poly, nv, v->occ, v->cull, v->nocc, c->plane_tol, &hidden);
    double share;
    if (fv < 0) {
        vis_count w = *v;
        w.seen = w.pass = w.open = 0;
        share = point_passes(c, rv, ey, x, poly, nv, k, rng, &w);
    } else {
        share = hidden ? rr_min(1.0, fv / f) : 1.0;
    }
    int p = (int)lround(share * VIS_ONE);
    v->seen += VIS_ONE;
    v->open += VIS_ONE;
    v->pass += p;
    v->unit += p;
    return share;
}

/* Which child of an element (el_split's order: the corners A, B, C, then
 * the middle) holds the point of barycentrics b. */
static int child_of(const double b[3]) { return b[0] > 0.5 ? 0 : b[1] > 0.5 ? 1 : b[2] > 0.5 ? 2 : 3; }

/* Whether some near-pair point of e is open (e has open area). */
static int near_open(const hel *e)
{
    const uint64_t all = NEAR_N >= 64 ? ~0ULL : (1ULL << NEAR_N) - 1;
    return e->open > 0 && (e->nbur & all) != all;
}

/* The centres of r and s are closer than the sum of their radii (the
 * SMOOTH rule's limit). */
static int closer_than_radii(const rview *rv, const hel *es)
{
    return rr_v3_len(rr_v3_sub(rv->ctr, es->ctr)) < rv->e->radius + es->radius;
}

/* Whether triangle t (centroid g, size: the largest distance from g to a
 * corner) lies closer to s's plane (through yc, normal ny) than its size,
 * and within its size of s (radius ys): where the point factor to s peaks
 * (along an edge shared with s it grows as -log of the distance). */
static int near_plane(const rr_vec3 t[3], rr_vec3 ny, rr_vec3 yc, double ys)
{
    rr_vec3 g = rr_v3_scale(rr_v3_add(rr_v3_add(t[0], t[1]), t[2]), 1.0 / 3.0);
    double size = rr_max(rr_v3_len(rr_v3_sub(t[0], g)),
                         rr_max(rr_v3_len(rr_v3_sub(t[1], g)), rr_v3_len(rr_v3_sub(t[2], g))));
    return fabs(rr_v3_dot(ny, rr_v3_sub(g, yc))) < size && rr_v3_len(rr_v3_sub(g, yc)) < size + ys;
}

/* The mean over triangle t of the unoccluded point factor to poly (s's
 * front part), by the 7-point rule on each of t's four children, or on
 * their children where they lie near s's plane (near_plane), down `depth`
 * levels. side_ff takes it for a near pair's children near s's plane, where
 * the rule on the children alone read the peak short: interior.json's
 * window pane, whose glazing bars stand 1 mm in front of it, took in 4 %
 * more than the light tracer counts, a pane with its frame alone 3.2 % less
 * (notes/radiosity.md, "Near pairs by a finer rule"). */
static double finer_mean(const hctx *c, const rr_vec3 t[3], rr_vec3 nx, const rr_vec3 *poly, int nv, rr_vec3 ny,
                         rr_vec3 yc, double ys, int depth)
{
    rr_vec3 m01 = rr_v3_scale(rr_v3_add(t[0], t[1]), 0.5), m12 = rr_v3_scale(rr_v3_add(t[1], t[2]), 0.5),
            m20 = rr_v3_scale(rr_v3_add(t[2], t[0]), 0.5);
    rr_vec3 kid[4][3] = {{t[0], m01, m20}, {m01, t[1], m12}, {m20, m12, t[2]}, {m12, m20, m01}}; /* ch's order */
    double sum = 0.0;
    for (int q = 0; q < 4; q++) {
        if (depth > 1 && near_plane(kid[q], ny, yc, ys)) {
            sum += 0.25 * finer_mean(c, kid[q], nx, poly, nv, ny, yc, ys, depth - 1);
            continue;
        }
        for (int k = 0; k < 7; k++) {
            rr_vec3 x = tri_at(kid[q], d7_b[k][0], d7_b[k][1], d7_b[k][2]);
            sum += 0.25 * d7_w[k] *
                   (rr_v3_dot(ny, rr_v3_sub(x, yc)) > c->plane_tol ? rad_ff_point_polygon(x, nx, poly, nv) : 0.0);
        }
    }
    return sum;
}

static double side_ff(const hctx *c, const rview *rv, uint32_t yi, int near, rr_rng *rng, double *dF, vis_count *v,
                      double fk[4])
{
    fk[0] = fk[1] = fk[2] = fk[3] = 0.0;
    const hel *ex = rv->e, *ey = &c->el[yi];
    rr_vec3 nx = rv->n, ny = el_normal(c, yi), poly[4];
    int nv = rad__clip_front(ey->c, nx, rv->ctr, c->plane_tol, poly);
    *dF = 0.0;
    if (nv < 3)
        return 0.0;
    /* which points: the 4 fixed ones, or a near pair's */
    int rule = !near ? RULE_FIXED : ex->open >= 1.0 && !closer_than_radii(rv, ey) ? RULE_SMOOTH : RULE_NEAR;
    if (open_pt(ex, 0) < 0) {
        /* every fixed point of r is buried: its open part (under a glazing
         * bar's edge, say) gathers at the near pair's points that are not */
        if (!near_open(ex))
            return 0.0;
        rule = RULE_NEAR;
    }
    double b[NEAR_N][3], w[NEAR_N], wk[4] = {0, 0, 0, 0};
    int np = quad_points(rule, ex, b, w);
    double sum = 0.0, wsum = 0.0, lo = INFINITY, hi = 0.0;
    for (int k = 0; k < np; k++) {
        rr_vec3 x = tri_at(rv->c, b[k][0], b[k][1], b[k][2]);
        if (rule == RULE_NEAR ? (ex->nbur >> k) & 1 : rule == RULE_FIXED && (ex->bur >> k) & 1)
            continue; /* a buried point of r gathers nothing that its open part gets */
        double f = rr_v3_dot(ny, rr_v3_sub(x, ey->ctr)) > c->plane_tol ? rad_ff_point_polygon(x, nx, poly, nv) : 0.0;
        lo = rr_min(lo, f); /* the spread of the unoccluded factor: what the uneven test reads */
        hi = rr_max(hi, f);
        int q = child_of(b[k]);
        if (rule != RULE_SMOOTH) {
            fk[q] += w[k] * f; /* each child's mean (set_shape): far, one point each */
            wk[q] += w[k];
        } else if (k == 0) {
            fk[3] = f; /* the centroid, k_pts[0]: the middle child's */
            wk[3] = 1.0;
        }
        if (!near && f > 0.0)
            f *= v->exact ? exact_share(c, rv, ey, x, poly, nv, f, (uint32_t)k, rng, v)
                          : point_passes(c, rv, ey, x, poly, nv, (uint32_t)k, rng, v);
        sum += w[k] * f;
        wsum += w[k];
    }
    if (rule == RULE_SMOOTH)
        for (int q = 1; q < 4; q++) {
            /* the corner children's means at their centroids, k_pts: the
             * rule's own points there lie towards the corners, and the
             * shape read from them steepened gradients (Cornell's display:
             * block median 0.75 -> 0.81 % over four seeds) */
            rr_vec3 x = tri_at(rv->c, k_pts[q][0], k_pts[q][1], k_pts[q][2]);
            double f = rr_v3_dot(ny, rr_v3_sub(x, ey->ctr)) > c->plane_tol ? rad_ff_point_polygon(x, nx, poly, nv) : 0.0;
            lo = rr_min(lo, f);
            hi = rr_max(hi, f);
            fk[q - 1] = f;
            wk[q - 1] = 1.0;
        }
    for (int q = 0; q < 4; q++)
        fk[q] = wk[q] > 0 ? fk[q] / wk[q] : 0.0;
    *dF = wsum > 0 ? hi - lo : 0.0;
    if (near && rule == RULE_NEAR && ex->nbur == 0 && !rv->way && wsum > 0) {
        /* every near point open: the children near s's plane again, finer
         * (finer_mean); the others keep the rule's mean */
        double m = 0.0;
        for (int q = 0; q < 4; q++) {
            rr_vec3 t[3];
            for (int k = 0; k < 3; k++)
                t[k] = tri_at(rv->c, ch[q][k][0], ch[q][k][1], ch[q][k][2]);
            if (near_plane(t, ny, ey->ctr, ey->radius))
                fk[q] = finer_mean(c, t, nx, poly, nv, ny, ey->ctr, ey->radius, 1);
            m += 0.25 * fk[q];
        }
        return m;
    }
    return wsum > 0 ? sum / wsum : 0.0;
}

/* A near pair's visibility: one shadow ray from each of r's 4 open fixed
 * points in front of s, to a point of s clipped to r's front. */
static void near_vis(const hctx *c, const rview *rv, uint32_t yi, rr_rng *rng, vis_count *v)
{
    const hel *ex = rv->e, *ey = &c->el[yi];
    rr_vec3 nx = rv->n, ny = el_normal(c, yi), poly[4];
    int nv = rad__clip_front(ey->c, nx, rv->ctr, c->plane_tol, poly);
    if (nv < 3)
        return;
    if (open_pt(ex, 0) < 0) { /* no open fixed point: VIS_RAYS of the open near-pair points, spread */
        double b[NEAR_N][3], w[NEAR_N];
        int np = quad_points(RULE_NEAR, NULL, b, w), idx[NEAR_N], m = 0;
        for (int k = 0; k < np; k++)
            if (!((ex->nbur >> k) & 1))
                idx[m++] = k;
        int n = m < VIS_RAYS ? m : VIS_RAYS;
        for (int j = 0; j < n; j++) {
            int k = idx[j * m / n];
            rr_vec3 x = tri_at(rv->c, b[k][0], b[k][1], b[k][2]);
            if (rr_v3_dot(ny, rr_v3_sub(x, ey->ctr)) > c->plane_tol)
                point_passes(c, rv, ey, x, poly, nv, (uint32_t)k, rng, v);
        }
        return;
    }
    for (int k = 0; k < VIS_RAYS; k++) {
        double b[3];
        el_kpt(ex, k, b);
        rr_vec3 x = tri_at(rv->c, b[0], b[1], b[2]);
        if (!(ex->bur & (1u << k)) && rr_v3_dot(ny, rr_v3_sub(x, ey->ctr)) > c->plane_tol)
            point_passes(c, rv, ey, x, poly, nv, (uint32_t)k, rng, v);
    }
}

static int is_near(const hctx *c, const rview *rv, const hlink *l)
{
    const hel *er = rv->e, *es = &c->el[l->s];
    return rr_v3_len(rr_v3_sub(rv->ctr, es->ctr)) < 2.0 * (er->radius + es->radius);
}

static void set_vis(hlink *l, int near, const vis_count *v)
{
    /* near: the factor is held without visibility, times the share of the
     * rays that passed; far: each point's factor counted only if its ray
     * passed (l->f holds that). */
    l->v = l->va = near && v->seen ? vis_share(v->pass, v->seen) : VIS_ONE;
    if (near && v->weigh && v->seen)
        l->va = vis_share(v->unit, v->seen);
    l->vis = v->open ? vis_share(v->pass, v->open) : (v->seen ? 0 : VIS_ONE);
    link_set_partial(l, v->pass > 0 && v->pass < v->open);
}

/* A sphere's or a solid's facets are chords of it, their patch areas scaled
 * to its true area (rad_patch.c), and the rays meet the true surface: a link
 * from a facet, whose factor is its flat triangle's, is scaled by the same
 * ratio (rad__facet_scale). Without it an emitting sphere, tessellated as
 * coarsely as the roots are, lit the floor under it 13.7 % short
 * (test_transport's sphere lamp with the hierarchical method). */
static double facet_scale(const hctx *c, uint32_t e) { return rad__facet_scale(c->R, &c->R->p[c->el[e].root]); }

/* Link l evaluated whole; far, with occ (nocc >= 0): its visibility exact
 * (exact_share) instead of by rays. */
static void eval_ee(const hctx *c, hlink *l, rr_rng *rng, int per, const rr_vec3 (*occ)[3], const unsigned char *cull,
                    int nocc)
{
    rview rv = rview_of(c, l->r, link_way(l));
    int near = is_near(c, &rv, l);
    vis_count v = {0, 0, 0, 0, 0, 0, per, occ, cull, nocc, nocc >= 0 && !near};
    v.weigh = near && (c->el[l->r].own || c->el[l->s].open < 1.0);
    double dF, fk[4], rho = way_rho(c, rv.way);
    double F = side_ff(c, &rv, l->s, near, rng, &dF, &v, fk) * facet_scale(c, l->s) * rho;
    dF *= rho;
    if (near && F > 0.0)
        near_vis(c, &rv, l->s, rng, &v);
    l->f = l->fa = (float)F;
    /* The factor without visibility shared among r's children as its points
     * fall in them (where none is buried). */
    if ((near ? c->el[l->r].nbur == 0 : c->el[l->r].bur == 0) && !c->el[l->r].own)
        set_shape(l, fk);
    else
        link_clear_shape(l);
    set_vis(l, near, &v);
    l->dF = (float)dF; /* how much the factor varies over r */
}

void rad__hier_eval_ee(const hctx *c, hlink *l, rr_rng *rng, int per) { eval_ee(c, l, rng, per, NULL, NULL, -1); }

/* The triangles that may stand between r and s (their box meets the box
 * of both), into occ and cull (at most EXACT_MAX): their count, or -1 where
 * the link's visibility is left to rays: a way by mirrors, a surface that
 * is not flat (a sphere's or a solid's: the rays meet the true surface), a
 * sphere or a solid in the box, or more than EXACT_MAX triangles. A
 * source's buried parts, dark to its rays, are hidden exactly by what
 * buries them (a closed object's faces, a covering above it); one coplanar
 * with it within plane_tol would count as seen (notes/radiosity.md, "Exact
 * visibility in the estimate"). */
#define EXACT_MAX 64
static int exact_occluders(const hctx *c, const hlink *l, rr_vec3 (*occ)[3], unsigned char *cull)
{
    const hel *er = &c->el[l->r], *es = &c->el[l->s];
    if (link_way(l) || !c->rt[er->root].flat || !c->rt[es->root].flat)
        return -1;
    rr_vec3 lo = er->c[0], hi = er->c[0];
    for (int k = 0; k < 6; k++) {
        rr_vec3 p = k < 3 ? er->c[k] : es->c[k - 3];
        lo = rr_v3(rr_min(lo.x, p.x), rr_min(lo.y, p.y), rr_min(lo.z, p.z));
        hi = rr_v3(rr_max(hi.x, p.x), rr_max(hi.y, p.y), rr_max(hi.z, p.z));
    }
    uint32_t tri[EXACT_MAX];
    int other;
    size_t n = rt_accel_tris_in_box(c->a, lo, hi, tri, EXACT_MAX, &other);
    if (other || n > EXACT_MAX)
        return -1;
    /* kept: the triangles with a corner in front of both r's and s's planes
     * (beyond plane_tol; r and s are flat), and, of objects that cull back
     * faces, whose front some corner of r sees */
    const scene *s = c->s;
    rr_vec3 nr = el_normal(c, l->r), ns = el_normal(c, l->s);
    double dr = rr_v3_dot(nr, er->ctr) + c->plane_tol, ds = rr_v3_dot(ns, es->ctr) + c->plane_tol;
    int m = 0;
    for (size_t i = 0; i < n; i++) {
        const scene_tri *t = &s->tris[tri[i]];
        rr_vec3 A = s->verts[t->v[0]], B = s->verts[t->v[1]], C = s->verts[t->v[2]];
        if (!(rr_v3_dot(nr, A) > dr || rr_v3_dot(nr, B) > dr || rr_v3_dot(nr, C) > dr) ||
            !(rr_v3_dot(ns, A) > ds || rr_v3_dot(ns, B) > ds || rr_v3_dot(ns, C) > ds))
            continue;
        int culls = s->objects[t->object].cull_backfaces != 0;
        if (culls) {
            rr_vec3 tn = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
            int front = 0;
            for (int k = 0; k < 3 && !front; k++)
                front = rr_v3_dot(tn, rr_v3_sub(er->c[k], A)) > 0;
            if (!front)
                continue;
        }
        occ[m][0] = A;
        occ[m][1] = B;
        occ[m][2] = C;
        cull[m++] = (unsigned char)culls;
    }
    return m;
}

void rad__hier_revis_ee(const hctx *c, hlink *l, rr_rng *rng, int per)
{
    rview rv = rview_of(c, l->r, link_way(l));
    if (!is_near(c, &rv, l)) {
        rr_vec3 occ[EXACT_MAX][3];
        unsigned char cull[EXACT_MAX];
        int nocc = exact_occluders(c, l, occ, cull);
        if (nocc < 0) {
            rad__hier_eval_ee(c, l, rng, per);
            return;
        }
        eval_ee(c, l, rng, per, (const rr_vec3(*)[3])occ, cull, nocc);
        return;
    }
    vis_count v = {0, 0, 0, 0, 0, 0, per, NULL, NULL, 0, 0};
    v.weigh = c->el[l->r].own || c->el[l->s].open < 1.0;
    if (l->f > 0.0f)
        near_vis(c, &rv, l->s, rng, &v);
    set_vis(l, 1, &v);
}

double rad__hier_root_ff(const hctx *c, rr_vec3 x, rr_vec3 n, uint32_t s)
{
    const hel *es = &c->el[s];
    if (!(rr_v3_dot(el_normal(c, s), rr_v3_sub(x, es->ctr)) > c->plane_tol))
        return 0.0;
    rr_vec3 poly[4];
    int nv = rad__clip_front(es->c, n, x, c->plane_tol, poly);
    return nv < 3 ? 0.0 : rad_ff_point_polygon(x, n, poly, nv) * facet_scale(c, s);
}

rr_vec3 rad__hier_rlc_vec(const hctx *c, rr_vec3 x, rr_vec3 u, uint32_t s)
{
    const hel *es = &c->el[s];
    if (!(rr_v3_dot(el_normal(c, s), rr_v3_sub(x, es->ctr)) > c->plane_tol))
        return rr_v3(0, 0, 0);
    rr_vec3 poly[4];
    int nv = rad__clip_front(es->c, u, x, c->plane_tol, poly);
    return nv < 3 ? rr_v3(0, 0, 0) : rr_v3_scale(rad_ff_point_polygon_vec(x, poly, nv), facet_scale(c, s));
}
