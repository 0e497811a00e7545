/* rt_prim.c - the primitive table (rt.h): one row per kind of primitive the
 * BVH holds, read by the BVH (rt_bvh.c, the walk), the light table
 * (rt_light.c), the light tracer (rt_emit.c), the diagnostics, the radiosity
 * pass and its cache.
 *
 * Kinds (rt_prim_kind): scene triangles, analytic spheres, and solids (the
 * CSG trees and standalone quadrics of rt_solid.c, one primitive per object).
 */
#include "rt_light_internal.h"

/* ---- triangles ---- */

static void tri_bounds(const scene *s, uint32_t i, rr_vec3 *lo, rr_vec3 *hi)
{
    const scene_tri *t = &s->tris[i];
    *lo = *hi = s->verts[t->v[0]];
    for (int k = 1; k < 3; k++) {
        *lo = rr_v3_min(*lo, s->verts[t->v[k]]);
        *hi = rr_v3_max(*hi, s->verts[t->v[k]]);
    }
}

static int tri_hit(const rt_accel *a, uint32_t i, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit)
{
    const scene *s = a->scene;
    const scene_tri *tr = &s->tris[i];
    double t;
    int front;
    int cull = s->objects[tr->object].cull_backfaces && p->cull_mask;
    if (!rt__tri_hit(p, s->verts[tr->v[0]], s->verts[tr->v[1]], s->verts[tr->v[2]], cull, tmin, *tmax, &t, &front))
        return 0;
    if (hit) {
        rr_vec3 n = scene_tri_normal(s, i);
        hit->tri = (int64_t)i;
        hit->part = -1;
        hit->object = tr->object;
        hit->material = tr->material;
        hit->normal = front ? n : rr_v3_neg(n);
        hit->t = t;
        hit->front = front;
    }
    *tmax = t;
    return 1;
}

static double tri_area(const scene *s, uint32_t i) { return scene_tri_area(s, i); }

static double tri_emission(const scene *s, uint32_t i)
{
    return rr_rgb_mean(s->materials[s->tris[i].material].emission);
}

/* ---- analytic spheres ---- */

static void sphere_bounds(const scene *s, uint32_t i, rr_vec3 *lo, rr_vec3 *hi)
{
    const scene_object *o = &s->objects[i];
    rr_vec3 r = rr_v3(o->radius, o->radius, o->radius);
    *lo = rr_v3_sub(o->center, r);
    *hi = rr_v3_add(o->center, r);
}

static int sphere_hit(const rt_accel *a, uint32_t i, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit)
{
    const scene_object *o = &a->scene->objects[i];
    double t;
    if (!rt_sphere_hit(o->center, o->radius, p->ray, tmin, *tmax, &t))
        return 0;
    rr_vec3 n = rr_v3_scale(rr_v3_sub(rr_ray_at(p->ray, t), o->center), 1.0 / o->radius);
    int front = rr_v3_dot(n, p->ray.d) < 0.0;
    if (!front && o->cull_backfaces && p->cull_mask)
        return 0;
    if (hit) {
        hit->tri = -1;
        hit->part = -1;
        hit->object = i;
        hit->material = o->material;
        hit->normal = front ? n : rr_v3_neg(n);
        hit->t = t;
        hit->front = front;
    }
    *tmax = t;
    return 1;
}

static double sphere_area(const scene *s, uint32_t i)
{
    const scene_object *o = &s->objects[i];
    return 4.0 * RR_PI * o->radius * o->radius;
}

static double sphere_emission(const scene *s, uint32_t i)
{
    return rr_rgb_mean(s->materials[s->objects[i].material].emission);
}

static int sphere_light_sphere(const scene *s, uint32_t i, double scale, rr_vec3 *c, double *r)
{
    (void)scale;
    *c = s->objects[i].center;
    *r = s->objects[i].radius;
    return 1;
}

static int sphere_encloses(const scene *s, uint32_t i, rr_vec3 p)
{
    const scene_object *o = &s->objects[i];
    return rr_v3_len2(rr_v3_sub(p, o->center)) < o->radius * o->radius;
}

static void sphere_digest(const scene *s, uint32_t i, void (*add)(void *, const void *, size_t), void *user)
{
    const scene_object *o = &s->objects[i];
    add(user, &o->center.x, sizeof(double));
    add(user, &o->center.y, sizeof(double));
    add(user, &o->center.z, sizeof(double));
    add(user, &o->radius, sizeof(double));
}

/* ---- solids ---- */

static void solid_bounds(const scene *s, uint32_t i, rr_vec3 *lo, rr_vec3 *hi)
{
    const scene_csg_node *root = &s->csg[s->objects[i].csg_root];
    *lo = root->bbox_lo;
    *hi = root->bbox_hi;
}

static int solid_hit(const rt_accel *a, uint32_t i, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit)
{
    rt_hit h;
    const scene *s = a->scene;
    if (s->objects[i].kind != SCENE_OBJ_CSG ||
        !rt__solid_closest(s, a, i, p->ray, tmin, *tmax, s->objects[i].cull_backfaces && p->cull_mask, &h))
        return 0;
    if (hit)
        *hit = h;
    *tmax = h.t;
    return 1;
}

/* A solid's area is known only once tessellated: its bounding box's (an
 * overestimate by at most a few times); 0 for an empty or flat box. */
static double solid_area(const scene *s, uint32_t i)
{
    rr_vec3 d = rr_v3_sub(s->csg[s->objects[i].csg_root].bbox_hi, s->csg[s->objects[i].csg_root].bbox_lo);
    return d.x > 0 && d.y > 0 && d.z > 0 ? 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x) : 0.0;
}

/* Mean emitted radiance of the brightest emissive leaf of solid i. */
static double solid_emission(const scene *s, uint32_t i)
{
    double e = 0.0;
    for (size_t k = 0; k < s->ncsg; k++)
        if (s->csg[k].op == SCENE_CSG_LEAF && s->csg[k].object == i)
            e = fmax(e, rr_rgb_mean(s->materials[s->csg[k].material].emission));
    return e;
}

/* The sphere about its bounding box, a little larger (so that it contains
 * the box after rounding). */
static int solid_light_sphere(const scene *s, uint32_t i, double scale, rr_vec3 *c, double *r)
{
    rr_vec3 lo = s->csg[s->objects[i].csg_root].bbox_lo, hi = s->csg[s->objects[i].csg_root].bbox_hi;
    *c = rr_v3_scale(rr_v3_add(lo, hi), 0.5);
    *r = 0.5 * rr_v3_len(rr_v3_sub(hi, lo)) * (1.0 + 1e-9) + 1e-12 * scale;
    return lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z; /* not an empty solid */
}

static int solid_encloses(const scene *s, uint32_t i, rr_vec3 p)
{
    return rt_csg_contains(s, NULL, s->objects[i].csg_root, p);
}

static void no_digest(const scene *s, uint32_t i, void (*add)(void *, const void *, size_t), void *user)
{
    /* The solids' trees are digested as a whole (rad_cache.c, hash_solids). */
    (void)s;
    (void)i;
    (void)add;
    (void)user;
}

const rt_prim_class rt_prims[RT_PRIM_KINDS] = {
    [RT_PRIM_TRIANGLE] = {"triangle", 0, -1, tri_bounds, tri_hit, tri_area, tri_emission, NULL, NULL, NULL, NULL},
    [RT_PRIM_SPHERE] = {"sphere", 1, SCENE_OBJ_SPHERE, sphere_bounds, sphere_hit, sphere_area, sphere_emission,
                        sphere_light_sphere, rt__emit_sphere, sphere_encloses, sphere_digest},
    [RT_PRIM_SOLID] = {"solid", 1, SCENE_OBJ_CSG, solid_bounds, solid_hit, solid_area, solid_emission,
                       solid_light_sphere, rt__emit_solid, solid_encloses, no_digest},
};

rt_prim_kind rt_prim_kind_of(const scene *s, uint32_t o)
{
    for (int k = 0; k < RT_PRIM_KINDS; k++)
        if (rt_prims[k].per_object && (int)s->objects[o].kind == rt_prims[k].object_kind)
            return (rt_prim_kind)k;
    return RT_PRIM_TRIANGLE;
}

size_t rt_prim_total(const scene *s)
{
    size_t n = s->ntris;
    for (size_t i = 0; i < s->nobjects; i++)
        n += rt_prim_kind_of(s, (uint32_t)i) != RT_PRIM_TRIANGLE;
    return n;
}

size_t rt__prim_count(const scene *s) { return rt_prim_total(s); }

void rt__prim_others(const scene *s, rt_prim *out)
{
    /* Per-object kinds in object order. */
    size_t k = 0;
    for (size_t i = 0; i < s->nobjects; i++) {
        rt_prim_kind kind = rt_prim_kind_of(s, (uint32_t)i);
        if (kind == RT_PRIM_TRIANGLE)
            continue;
        out[k].kind = kind;
        out[k].index = (uint32_t)i;
        k++;
    }
}

void rt__prim_bounds(const scene *s, rt_prim p, rr_vec3 *lo, rr_vec3 *hi) { rt_prims[p.kind].bounds(s, p.index, lo, hi); }

int rt__prim_hit(const rt_accel *a, rt_prim pr, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit)
{
    return rt_prims[pr.kind].hit(a, pr.index, p, tmin, tmax, hit);
}
