/* rt_solid.c - solids: ray spans of the analytic leaves (sphere, quadric,
 * box), CSG combination of span lists (Roth 1982), the closest hit, point
 * membership and leaf normals. Mesh leaves live in rt_solid_mesh.c.
 *
 * Span lists. Every list is sorted, its spans are disjoint and never touch
 * (rt__spans_push merges touching spans), and every span has positive length:
 * a ray tangent to a leaf (a sphere touched at one point, a box touched along
 * an edge) gives no span at all, the same for every leaf kind and in every
 * combination, so a tangent ray never reports a hit. Leaves clip their spans
 * to [tmin, tmax] before combining: the booleans commute with clipping, and
 * clipping first keeps the lists short. An end moved by clipping lies at
 * exactly tmin or tmax, and the closest hit only reports ends strictly inside
 * (tmin, tmax), so such an artificial end is never reported.
 *
 * Limits. A list holds RT_SPAN_MAX spans; more are cut, the farthest first
 * (so the nearest surfaces, the ones closest-hit queries ask for, stay exact;
 * beyond the cut the solid may be incomplete). Recursion is as deep as the CSG
 * tree (the loader bounds it) and each level keeps two lists on the stack
 * (2 x ~3 KiB).
 */
#include <float.h>
#include <string.h>

#include "rt_solid_internal.h"

void rt__spans_push(rt_spans *l, rt_span_end a, rt_span_end b)
{
    if (!(a.t < b.t))
        return;
    if (l->n > 0 && a.t <= l->s[l->n - 1].out.t) {
        if (b.t > l->s[l->n - 1].out.t)
            l->s[l->n - 1].out = b;
        return;
    }
    if (l->n == RT_SPAN_MAX)
        return;
    l->s[l->n].in = a;
    l->s[l->n].out = b;
    l->n++;
}

/* Clips [a, b] to [tmin, tmax] and appends it. */
static void push_clipped(rt_spans *l, rt_span_end a, rt_span_end b, double tmin, double tmax)
{
    if (a.t < tmin)
        a.t = tmin;
    if (b.t > tmax)
        b.t = tmax;
    rt__spans_push(l, a, b);
}

/* ---- leaves ---- */

/* Sphere |p - c|^2 <= r^2 in the local frame (Ray Tracing Gems, ch. 7): the
 * discriminant from the squared distance of the centre to the line, which has
 * no cancellation for distant rays, and the roots from q = -(b + sign(b)
 * sqrt(disc)) and the product of the roots, so neither root is the difference
 * of two close numbers. A tangent (disc <= 0) is no span. */
static void sphere_spans(const scene_csg_node *n, uint32_t leaf, rr_ray lr, double tmin, double tmax, rt_spans *out)
{
    double a = rr_v3_dot(lr.d, lr.d);
    if (!(a > 0.0))
        return;
    rr_vec3 oc = rr_v3_sub(lr.o, n->center);
    double b = rr_v3_dot(lr.d, oc); /* half the textbook b */
    rr_vec3 q = rr_v3_madd(oc, lr.d, -b / a);
    double r2 = n->radius * n->radius;
    double h = r2 - rr_v3_dot(q, q);
    if (!(h > 0.0))
        return;
    double c = rr_v3_dot(oc, oc) - r2;
    double qq = -b - copysign(sqrt(a * h), b);
    if (qq == 0.0)
        return;
    double t0 = c / qq, t1 = qq / a;
    if (t0 > t1) {
        double t = t0;
        t0 = t1;
        t1 = t;
    }
    push_clipped(out, rt__span_end(t0, leaf, -1), rt__span_end(t1, leaf, -1), tmin, tmax);
}

/* Slab test of the line o + s d against the box [lo, hi]: the parameter
 * interval and the faces (0..5 = -x,+x,-y,+y,-z,+z) where it enters and leaves.
 * Returns 0 when the line misses the box or only touches it. */
static int box_slab(rr_vec3 o, rr_vec3 d, rr_vec3 lo, rr_vec3 hi, double *s0, int *f0, double *s1, int *f1)
{
    double in = -INFINITY, out = INFINITY;
    int fin = 0, fout = 1;
    for (int i = 0; i < 3; i++) {
        double oi = rr_v3_get(o, i), di = rr_v3_get(d, i), l = rr_v3_get(lo, i), h = rr_v3_get(hi, i);
        if (di == 0.0) {
            /* Parallel: a line in a face plane only touches the box (no span,
             * like a tangent). */
            if (!(oi > l && oi < h))
                return 0;
            continue;
        }
        double sa = (l - oi) / di, sb = (h - oi) / di;
        int fa = 2 * i, fb = 2 * i + 1;
        if (sa > sb) {
            double t = sa;
            sa = sb;
            sb = t;
            fa = 2 * i + 1;
            fb = 2 * i;
        }
        if (sa > in) {
            in = sa;
            fin = fa;
        }
        if (sb < out) {
            out = sb;
            fout = fb;
        }
    }
    if (!(in < out))
        return 0;
    *s0 = in;
    *s1 = out;
    *f0 = fin;
    *f1 = fout;
    return 1;
}

static void box_spans(const scene_csg_node *n, uint32_t leaf, rr_ray lr, double tmin, double tmax, rt_spans *out)
{
    double s0, s1;
    int f0, f1;
    if (!box_slab(lr.o, lr.d, n->clip_lo, n->clip_hi, &s0, &f0, &s1, &f1))
        return;
    push_clipped(out, rt__span_end(s0, leaf, f0), rt__span_end(s1, leaf, f1), tmin, tmax);
}

/* Q x for x = (p, w). */
static void quad_apply(const double q[4][4], rr_vec3 p, double w, double r[4])
{
    for (int i = 0; i < 4; i++)
        r[i] = q[i][0] * p.x + q[i][1] * p.y + q[i][2] * p.z + q[i][3] * w;
}

/* One interval [a, b] (either may be infinite) where the quadric is <= 0,
 * intersected with the box interval [s0, s1]; ends on the quadric get
 * surface -1, ends on the box its face (a tie goes to the quadric, whose
 * normal is the surface's own). Parameters are relative to t0. */
static void quadric_piece(uint32_t leaf, double t0, double a, double b, double s0, int f0, double s1, int f1,
                          double tmin, double tmax, rt_spans *out)
{
    rt_span_end e0 = a >= s0 ? rt__span_end(t0 + a, leaf, -1) : rt__span_end(t0 + s0, leaf, f0);
    rt_span_end e1 = b <= s1 ? rt__span_end(t0 + b, leaf, -1) : rt__span_end(t0 + s1, leaf, f1);
    if (!(fmax(a, s0) < fmin(b, s1)))
        return;
    push_clipped(out, e0, e1, tmin, tmax);
}

/* Quadric x^T Q x <= 0 inside the clip box. Along the line, f(s) = A s^2 +
 * 2 B s + C.
 *
 * Far rays: f is evaluated around the point of the line nearest the clip box
 * centre (the line is re-parameterised there, t = t0 + s), so C is not the
 * small difference of huge terms for a ray that starts far away.
 * Roots: the discriminant B^2 - A C with Kahan's fma correction, then q =
 * -(B + sign(B) sqrt(disc)), roots q / A and C / q (no cancellation).
 * Which side is inside: A > 0: between the roots; A < 0: outside them (two
 * half-infinite intervals). When A is tiny the root q / A is huge (or
 * infinite) and the two cases describe the same half-line inside the box, so
 * nothing jumps as A changes sign; only A == 0 exactly (a ray parallel to a
 * cylinder's axis or to a cone's generator) needs the linear case. No real
 * roots: everything (A < 0) or nothing (A > 0); a double root is a tangent
 * (nothing) for A > 0. */
static void quadric_spans(const scene_csg_node *n, uint32_t leaf, rr_ray lr, double tmin, double tmax,
                          rt_spans *out)
{
    double dd = rr_v3_dot(lr.d, lr.d);
    if (!(dd > 0.0))
        return;
    rr_vec3 cen = rr_v3_scale(rr_v3_add(n->clip_lo, n->clip_hi), 0.5);
    double t0 = rr_v3_dot(rr_v3_sub(cen, lr.o), lr.d) / dd;
    rr_vec3 p = rr_ray_at(lr, t0);
    double s0, s1;
    int f0, f1;
    if (!box_slab(p, lr.d, n->clip_lo, n->clip_hi, &s0, &f0, &s1, &f1))
        return;
    double qx[4], qd[4];
    quad_apply(n->q, p, 1.0, qx);
    quad_apply(n->q, lr.d, 0.0, qd);
    double A = qd[0] * lr.d.x + qd[1] * lr.d.y + qd[2] * lr.d.z;
    double B = qx[0] * lr.d.x + qx[1] * lr.d.y + qx[2] * lr.d.z;
    double C = qx[0] * p.x + qx[1] * p.y + qx[2] * p.z + qx[3];
    if (A == 0.0) {
        if (B == 0.0) {
            if (C <= 0.0)
                quadric_piece(leaf, t0, -INFINITY, INFINITY, s0, f0, s1, f1, tmin, tmax, out);
            return;
        }
        double r = -C / (2.0 * B);
        if (B > 0.0)
            quadric_piece(leaf, t0, -INFINITY, r, s0, f0, s1, f1, tmin, tmax, out);
        else
            quadric_piece(leaf, t0, r, INFINITY, s0, f0, s1, f1, tmin, tmax, out);
        return;
    }
    double w = A * C;
    double disc = fma(B, B, -w) + fma(-A, C, w); /* Kahan: B^2 - AC with the rounding of AC added back */
    if (!(disc > 0.0)) {
        if (A < 0.0)
            quadric_piece(leaf, t0, -INFINITY, INFINITY, s0, f0, s1, f1, tmin, tmax, out);
        return;
    }
    double q = -(B + copysign(sqrt(disc), B));
    double r0 = q / A, r1 = C / q;
    if (r0 > r1) {
        double t = r0;
        r0 = r1;
        r1 = t;
    }
    if (A > 0.0) {
        quadric_piece(leaf, t0, r0, r1, s0, f0, s1, f1, tmin, tmax, out);
    } else {
        quadric_piece(leaf, t0, -INFINITY, r0, s0, f0, s1, f1, tmin, tmax, out);
        quadric_piece(leaf, t0, r1, INFINITY, s0, f0, s1, f1, tmin, tmax, out);
    }
}

static void leaf_spans(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_ray ray, double tmin,
                       double tmax, rt_spans *out)
{
    const scene_csg_node *n = &s->csg[leaf];
    if (n->solid == SCENE_SOLID_MESH) {
        rt__mesh_spans(s, sa, leaf, ray, tmin, tmax, out);
        return;
    }
    /* Local ray: the same t, the direction not normalised. */
    rr_ray lr;
    lr.o = rr_xform_point(&n->to_local, ray.o);
    lr.d = rr_xform_vector(&n->to_local, ray.d);
    switch (n->solid) {
    case SCENE_SOLID_SPHERE: sphere_spans(n, leaf, lr, tmin, tmax, out); break;
    case SCENE_SOLID_QUADRIC: quadric_spans(n, leaf, lr, tmin, tmax, out); break;
    case SCENE_SOLID_BOX: box_spans(n, leaf, lr, tmin, tmax, out); break;
    default: break;
    }
}

/* ---- CSG ---- */

typedef struct csg_ctx {
    const scene *s;
    const struct rt_solid_accel *sa;
    rr_ray ray;
    rt_slab_ray slab; /* the ray's, for rt__box_overlap */
} csg_ctx;

rt_slab_ray rt__slab_prepare(rr_ray r)
{
    rt_slab_ray q;
    for (int i = 0; i < 3; i++) {
        double d = rr_v3_get(r.d, i);
        q.o[i] = rr_v3_get(r.o, i);
        q.zero[i] = d == 0.0;
        q.inv[i] = d == 0.0 ? 0.0 : 1.0 / d;
    }
    return q;
}

int rt__box_overlap(const rt_slab_ray *r, rr_vec3 lo, rr_vec3 hi, double tmin, double tmax)
{
    double t0 = tmin, t1 = tmax;
    for (int i = 0; i < 3; i++) {
        double l = rr_v3_get(lo, i), h = rr_v3_get(hi, i);
        if (!(l <= h))
            return 0; /* empty box (or NaN) */
        if (r->zero[i]) {
            if (r->o[i] < l || r->o[i] > h)
                return 0;
            continue;
        }
        /* Products by the reciprocal: their rounding (a few ulps) is far
         * inside the widening by 1e-12 of each t, so no box the ray meets is
         * culled (an overflowing reciprocal gives infinities or NaNs, which
         * cull nothing). */
        double ta = (l - r->o[i]) * r->inv[i], tb = (h - r->o[i]) * r->inv[i];
        if (ta > tb) {
            double t = ta;
            ta = tb;
            tb = t;
        }
        ta -= fabs(ta) * 1e-12;
        tb += fabs(tb) * 1e-12;
        if (ta > t0)
            t0 = ta;
        if (tb < t1)
            t1 = tb;
    }
    return t0 <= t1;
}

static int op_inside(scene_csg_op op, int l, int r)
{
    switch (op) {
    case SCENE_CSG_UNION: return l || r;
    case SCENE_CSG_INTERSECTION: return l && r;
    case SCENE_CSG_DIFFERENCE: return l && !r;
    default: return l;
    }
}

/* Roth's merge: walk the ends of both lists in order (ties: entries before
 * exits, so two solids that touch along a face give one span in a union and
 * none in an intersection), track inside/outside of each operand and emit an
 * end wherever the combination changes. Ends taken from the right operand of a
 * difference toggle flip: the subtracted solid's surface faces the other way. */
static void merge(const rt_spans *L, const rt_spans *R, scene_csg_op op, rt_spans *out)
{
    out->n = 0;
    int nl = 2 * L->n, nr = 2 * R->n, i = 0, j = 0;
    int inl = 0, inr = 0, res = 0;
    rt_span_end start = {0};
    while (i < nl || j < nr) {
        int from_right;
        if (i >= nl) {
            from_right = 1;
        } else if (j >= nr) {
            from_right = 0;
        } else {
            const rt_span_end *el = (i & 1) ? &L->s[i >> 1].out : &L->s[i >> 1].in;
            const rt_span_end *er = (j & 1) ? &R->s[j >> 1].out : &R->s[j >> 1].in;
            if (el->t != er->t)
                from_right = er->t < el->t;
            else
                from_right = (j & 1) == 0 && (i & 1) == 1; /* right entry before left exit */
        }
        rt_span_end e;
        int entry;
        if (from_right) {
            e = (j & 1) ? R->s[j >> 1].out : R->s[j >> 1].in;
            entry = (j & 1) == 0;
            inr = entry;
            j++;
            if (op == SCENE_CSG_DIFFERENCE)
                e.flip ^= 1;
        } else {
            e = (i & 1) ? L->s[i >> 1].out : L->s[i >> 1].in;
            entry = (i & 1) == 0;
            inl = entry;
            i++;
        }
        int now = op_inside(op, inl, inr);
        if (now && !res)
            start = e;
        else if (!now && res)
            rt__spans_push(out, start, e);
        res = now;
        /* Nothing more can come in once the operand that must be inside is done. */
        if (!res && i >= nl && op != SCENE_CSG_UNION)
            break;
        if (!res && j >= nr && op == SCENE_CSG_INTERSECTION)
            break;
    }
}

static void copy_spans(rt_spans *dst, const rt_spans *src)
{
    dst->n = src->n;
    memcpy(dst->s, src->s, (size_t)src->n * sizeof src->s[0]);
}

static void csg_rec(const csg_ctx *c, uint32_t node, double tmin, double tmax, rt_spans *out)
{
    out->n = 0;
    const scene_csg_node *n = &c->s->csg[node];
    if (!rt__box_overlap(&c->slab, n->bbox_lo, n->bbox_hi, tmin, tmax))
        return;
    if (n->op == SCENE_CSG_LEAF) {
        leaf_spans(c->s, c->sa, node, c->ray, tmin, tmax, out);
        return;
    }
    csg_rec(c, n->left, tmin, tmax, out);
    if (out->n == 0 && n->op != SCENE_CSG_UNION)
        return; /* intersection, difference: nothing left of an empty left operand */
    if (n->op != SCENE_CSG_UNION) {
        /* The right operand only matters where the left one is. */
        const scene_csg_node *r = &c->s->csg[n->right];
        if (!rt__box_overlap(&c->slab, r->bbox_lo, r->bbox_hi, out->s[0].in.t, out->s[out->n - 1].out.t)) {
            if (n->op == SCENE_CSG_INTERSECTION)
                out->n = 0;
            return;
        }
    }
    rt_spans right;
    csg_rec(c, n->right, tmin, tmax, &right);
    if (right.n == 0) {
        if (n->op == SCENE_CSG_INTERSECTION)
            out->n = 0;
        return;
    }
    if (out->n == 0) { /* union with an empty left operand */
        copy_spans(out, &right);
        return;
    }
    rt_spans m;
    merge(out, &right, n->op, &m);
    copy_spans(out, &m);
}

void rt_csg_spans(const scene *s, const rt_accel *a, uint32_t node, rr_ray ray, double tmin, double tmax,
                  rt_spans *out)
{
    out->n = 0;
    /* A zero or non-finite ray has no spans (and would make NaN ends). */
    if (!s || node >= s->ncsg || !(tmin <= tmax) || !rr_v3_isfinite(ray.o) || !rr_v3_isfinite(ray.d) ||
        !(rr_v3_len2(ray.d) > 0.0))
        return;
    csg_ctx c;
    c.s = s;
    c.sa = a ? a->solids : NULL;
    c.ray = ray;
    c.slab = rt__slab_prepare(ray);
    csg_rec(&c, node, tmin, tmax, out);
}

void rt_solid_spans(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax,
                    rt_spans *out)
{
    out->n = 0;
    if (!s || obj >= s->nobjects || s->objects[obj].kind != SCENE_OBJ_CSG)
        return;
    rt_csg_spans(s, a, s->objects[obj].csg_root, ray, tmin, tmax, out);
}

/* ---- normals, closest hit ---- */

rr_vec3 rt_csg_leaf_normal(const scene *s, uint32_t leaf, int32_t surface, rr_vec3 p)
{
    const scene_csg_node *n = &s->csg[leaf];
    if (n->solid == SCENE_SOLID_MESH) {
        if (surface < 0 || (size_t)surface >= s->ncsg_tris)
            return rr_v3(0, 0, 0);
        const uint32_t *t = s->csg_tris[surface];
        rr_vec3 A = s->csg_verts[t[0]], B = s->csg_verts[t[1]], C = s->csg_verts[t[2]];
        return rr_v3_norm(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
    }
    rr_vec3 lp = rr_xform_point(&n->to_local, p);
    rr_vec3 ln;
    if (surface >= 0 && surface < 6) {
        double sign = (surface & 1) ? 1.0 : -1.0;
        int axis = surface / 2;
        ln = rr_v3(axis == 0 ? sign : 0.0, axis == 1 ? sign : 0.0, axis == 2 ? sign : 0.0);
    } else if (n->solid == SCENE_SOLID_SPHERE) {
        ln = rr_v3_sub(lp, n->center);
    } else if (n->solid == SCENE_SOLID_QUADRIC) {
        double g[4];
        quad_apply(n->q, lp, 1.0, g); /* the gradient is 2 (Q x)[0..2]; the factor does not matter */
        ln = rr_v3(g[0], g[1], g[2]);
    } else {
        return rr_v3(0, 0, 0);
    }
    /* Normals transform with the inverse transpose of to_world's linear part,
     * which is the transpose of to_local's. */
    const double(*m)[3] = n->to_local.m;
    rr_vec3 w = rr_v3(m[0][0] * ln.x + m[1][0] * ln.y + m[2][0] * ln.z, m[0][1] * ln.x + m[1][1] * ln.y + m[2][1] * ln.z,
                      m[0][2] * ln.x + m[1][2] * ln.y + m[2][2] * ln.z);
    return rr_v3_norm(w);
}

int rt_solid_closest(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax,
                     rt_hit *hit)
{
    if (!s || obj >= s->nobjects || s->objects[obj].kind != SCENE_OBJ_CSG)
        return 0;
    return rt__solid_closest(s, a, obj, ray, tmin, tmax, s->objects[obj].cull_backfaces, hit);
}

int rt__solid_closest(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax, int cull,
                      rt_hit *hit)
{
    rt_spans sp;
    rt_solid_spans(s, a, obj, ray, tmin, tmax, &sp);
    for (int i = 0; i < sp.n; i++) {
        const rt_span *x = &sp.s[i];
        rt_span_end e;
        int front;
        if (x->in.t > tmin && x->in.t < tmax) {
            e = x->in; /* the ray meets the solid from outside */
            front = 1;
        } else if (x->out.t > tmin && x->out.t < tmax && !cull) {
            e = x->out; /* the ray starts inside and leaves */
            front = 0;
        } else {
            continue;
        }
        rr_vec3 p = rr_ray_at(ray, e.t);
        rr_vec3 nrm = rt_csg_leaf_normal(s, e.leaf, e.surface, p);
        if (e.flip)
            nrm = rr_v3_neg(nrm);
        if (!(rr_v3_len2(nrm) > 0.0)) /* no gradient there (a cone's apex): face the ray */
            nrm = rr_v3_norm(rr_v3_neg(ray.d));
        if (rr_v3_dot(nrm, ray.d) > 0.0)
            nrm = rr_v3_neg(nrm);
        hit->t = e.t;
        hit->point = p;
        hit->normal = nrm;
        hit->object = obj;
        hit->material = s->csg[e.leaf].material;
        hit->tri = -1;
        hit->part = (int64_t)e.leaf;
        hit->front = front;
        return 1;
    }
    return 0;
}

/* ---- membership ---- */

static int leaf_contains(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_vec3 p)
{
    const scene_csg_node *n = &s->csg[leaf];
    if (n->solid == SCENE_SOLID_MESH)
        return rt__mesh_contains(s, sa, leaf, p);
    rr_vec3 lp = rr_xform_point(&n->to_local, p);
    if (n->solid == SCENE_SOLID_SPHERE)
        return rr_v3_len2(rr_v3_sub(lp, n->center)) <= n->radius * n->radius;
    if (!(lp.x >= n->clip_lo.x && lp.x <= n->clip_hi.x && lp.y >= n->clip_lo.y && lp.y <= n->clip_hi.y &&
          lp.z >= n->clip_lo.z && lp.z <= n->clip_hi.z))
        return 0;
    if (n->solid == SCENE_SOLID_BOX)
        return 1;
    double g[4];
    quad_apply(n->q, lp, 1.0, g);
    return g[0] * lp.x + g[1] * lp.y + g[2] * lp.z + g[3] <= 0.0;
}

static int contains_rec(const scene *s, const struct rt_solid_accel *sa, uint32_t node, rr_vec3 p)
{
    const scene_csg_node *n = &s->csg[node];
    if (!(p.x >= n->bbox_lo.x && p.x <= n->bbox_hi.x && p.y >= n->bbox_lo.y && p.y <= n->bbox_hi.y &&
          p.z >= n->bbox_lo.z && p.z <= n->bbox_hi.z))
        return 0;
    switch (n->op) {
    case SCENE_CSG_LEAF: return leaf_contains(s, sa, node, p);
    case SCENE_CSG_UNION: return contains_rec(s, sa, n->left, p) || contains_rec(s, sa, n->right, p);
    case SCENE_CSG_INTERSECTION: return contains_rec(s, sa, n->left, p) && contains_rec(s, sa, n->right, p);
    case SCENE_CSG_DIFFERENCE: return contains_rec(s, sa, n->left, p) && !contains_rec(s, sa, n->right, p);
    default: return 0;
    }
}

int rt_csg_contains(const scene *s, const rt_accel *a, uint32_t node, rr_vec3 p)
{
    if (!s || node >= s->ncsg)
        return 0;
    return contains_rec(s, a ? a->solids : NULL, node, p);
}
