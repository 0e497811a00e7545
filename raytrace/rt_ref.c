/* rt_ref.c - the lecture's reference geometry and the brute-force front-most hit.
 *
 * Literal on purpose: each function is one line of the lecture. The fast path
 * (BVH, watertight test) is tested against these. */
#include "rt.h"

int rt_orient(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 D)
{
    rr_vec3 AB = rr_v3_sub(B, A), AC = rr_v3_sub(C, A), AD = rr_v3_sub(D, A);
    return rr_v3_dot(rr_v3_cross(AB, AC), AD) > 0.0;
}

int rt_front_facing(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 E) { return rt_orient(A, B, C, E); }

int rt_ray_hits_tri(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C)
{
    return rt_orient(P, B, C, E) && rt_orient(A, P, C, E) && rt_orient(A, B, P, E);
}

double rt_dist_along_ray(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C)
{
    rr_vec3 N = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
    return rr_v3_dot(N, rr_v3_sub(A, E)) / rr_v3_dot(N, rr_v3_sub(P, E));
}

int rt_sphere_hit(rr_vec3 center, double radius, rr_ray ray, double tmin, double tmax, double *t)
{
    double a = rr_v3_dot(ray.d, ray.d);
    if (!(a > 0.0))
        return 0;
    rr_vec3 oc = rr_v3_sub(ray.o, center);
    double b = rr_v3_dot(ray.d, oc); /* half the usual b */
    double c = rr_v3_dot(oc, oc) - radius * radius;
    /* Discriminant from the distance of the centre to the line (q), not from
     * b^2 - ac: for a far sphere b^2 and ac are huge and nearly equal, and their
     * difference loses every significant digit. */
    rr_vec3 q = rr_v3_madd(oc, ray.d, -b / a);
    double h = radius * radius - rr_v3_dot(q, q);
    /* A tangent (h = 0) touches the sphere in one point: no hit, the rule of
     * the solids' sphere leaf (rt_solid.c) and mesh leaves (a zero-length
     * span), so that a sphere and the same sphere as a CSG leaf agree. NaN
     * (a degenerate ray) is no hit either. */
    if (!(h > 0.0))
        return 0;
    /* Citardauquan form: the root of larger magnitude from -b -/+ sqrt, the
     * other one from the product of roots c/a, so no subtraction of close
     * numbers happens (|qq| >= sqrt(a h) > 0). */
    double qq = -b - copysign(sqrt(a * h), b);
    double t0 = c / qq, t1 = qq / a;
    if (t0 > t1) {
        double tmp = t0;
        t0 = t1;
        t1 = tmp;
    }
    if (t0 > tmin && t0 < tmax) {
        *t = t0;
        return 1;
    }
    if (t1 > tmin && t1 < tmax) {
        *t = t1;
        return 1;
    }
    return 0;
}

int rt_ref_closest(const scene *s, rr_ray ray, double tmin, double tmax, rt_hit *hit)
{
    rr_vec3 E = ray.o, P = rr_v3_add(ray.o, ray.d);
    int found = 0;
    double best = tmax;
    for (size_t i = 0; i < s->ntris; i++) {
        const scene_tri *tr = &s->tris[i];
        rr_vec3 A = s->verts[tr->v[0]], B = s->verts[tr->v[1]], C = s->verts[tr->v[2]];
        int front = rt_front_facing(A, B, C, E);
        if (!front && s->objects[tr->object].cull_backfaces)
            continue;
        /* Seen from behind, the triangle is clockwise from E: test it as ACB. */
        int hits = front ? rt_ray_hits_tri(E, P, A, B, C) : rt_ray_hits_tri(E, P, A, C, B);
        if (!hits)
            continue;
        double t = rt_dist_along_ray(E, P, A, B, C);
        if (!(t > tmin && t < best))
            continue;
        best = t;
        found = 1;
        rr_vec3 n = scene_tri_normal(s, i);
        hit->t = t;
        hit->tri = (int64_t)i;
        hit->part = -1;
        hit->object = tr->object;
        hit->material = tr->material;
        hit->front = front;
        hit->normal = front ? n : rr_v3_neg(n);
    }
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_object *o = &s->objects[i];
        double t;
        if (o->kind != SCENE_OBJ_SPHERE || !rt_sphere_hit(o->center, o->radius, ray, tmin, best, &t))
            continue;
        rr_vec3 p = rr_ray_at(ray, t);
        rr_vec3 n = rr_v3_scale(rr_v3_sub(p, o->center), 1.0 / o->radius);
        int front = rr_v3_dot(n, ray.d) < 0.0;
        if (!front && o->cull_backfaces)
            continue;
        best = t;
        found = 1;
        hit->t = t;
        hit->tri = -1;
        hit->part = -1;
        hit->object = (uint32_t)i;
        hit->material = o->material;
        hit->front = front;
        hit->normal = front ? n : rr_v3_neg(n);
    }
    /* Solids have no lecture form: their own span code is the reference. */
    for (size_t i = 0; i < s->nobjects; i++) {
        rt_hit h;
        if (s->objects[i].kind != SCENE_OBJ_CSG || !rt_solid_closest(s, NULL, (uint32_t)i, ray, tmin, best, &h))
            continue;
        best = h.t;
        found = 1;
        *hit = h;
    }
    if (found)
        hit->point = rr_ray_at(ray, hit->t);
    return found;
}

rr_rgb rt_reflected_intensity(rr_vec3 E, rr_vec3 H, rr_vec3 N, rr_vec3 L, const scene_material *m, rr_rgb A,
                              rr_rgb light)
{
    rr_vec3 V = rr_v3_norm(rr_v3_sub(E, H)); /* V = HE / |HE| */
    rr_rgb d = rr_rgb_make(0, 0, 0), s = rr_rgb_make(0, 0, 0);
    rt_phong(N, L, V, m, light, &d, &s);
    rr_rgb a = rr_rgb_scale(rr_rgb_mul(m->diffuse, A), m->ambient);
    return rr_rgb_add(a, rr_rgb_add(d, s));
}

int rt_object_encloses(const scene *s, uint32_t obj, rr_vec3 p)
{
    const scene_object *o = &s->objects[obj];
    if (!scene_object_closed(s, obj))
        return 0;
    rt_prim_kind k = rt_prim_kind_of(s, obj);
    if (k != RT_PRIM_TRIANGLE)
        return rt_prims[k].encloses(s, obj, p);
    /* Parity of the crossings of a ray from p (a direction no axis-aligned
     * model lines up with), each triangle by the lecture's test from its
     * side. A ray through an edge or a corner may count wrong: a diagnostic. */
    rr_vec3 P = rr_v3_add(p, rr_v3(0.5773502691896258, 0.5772502691896258, 0.5774502691896258));
    int crossings = 0;
    for (size_t t = o->tri_first; t < o->tri_first + o->tri_count; t++) {
        rr_vec3 A = s->verts[s->tris[t].v[0]], B = s->verts[s->tris[t].v[1]], C = s->verts[s->tris[t].v[2]];
        int hit = rt_front_facing(A, B, C, p) ? rt_ray_hits_tri(p, P, A, B, C) : rt_ray_hits_tri(p, P, A, C, B);
        crossings += hit && rt_dist_along_ray(p, P, A, B, C) > 0.0;
    }
    return crossings & 1;
}
