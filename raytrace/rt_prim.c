/* rt_prim.c - the primitives the BVH holds: which ones a scene has, their
 * bounds, and the one intersection function every query calls.
 *
 * Kinds (rt_prim_kind): scene triangles, analytic spheres, and solids (the
 * CSG trees and standalone quadrics of rt_solid.c, one primitive per object).
 * Adding a kind means a case in each of the three functions below and nothing
 * in the BVH.
 */
#include "rt_internal.h"

size_t rt__prim_count(const scene *s)
{
    size_t n = s->ntris;
    for (size_t i = 0; i < s->nobjects; i++)
        n += s->objects[i].kind == SCENE_OBJ_SPHERE || s->objects[i].kind == SCENE_OBJ_CSG;
    return n;
}

void rt__prim_list(const scene *s, rt_prim *out)
{
    size_t k = 0;
    for (size_t i = 0; i < s->ntris; i++, k++) {
        out[k].kind = RT_PRIM_TRIANGLE;
        out[k].index = (uint32_t)i;
    }
    for (size_t i = 0; i < s->nobjects; i++) {
        if (s->objects[i].kind == SCENE_OBJ_SPHERE) {
            out[k].kind = RT_PRIM_SPHERE;
            out[k].index = (uint32_t)i;
            k++;
        } else if (s->objects[i].kind == SCENE_OBJ_CSG) {
            out[k].kind = RT_PRIM_SOLID;
            out[k].index = (uint32_t)i;
            k++;
        }
    }
}

void rt__prim_bounds(const scene *s, rt_prim p, rr_vec3 *lo, rr_vec3 *hi)
{
    if (p.kind == RT_PRIM_TRIANGLE) {
        const scene_tri *t = &s->tris[p.index];
        *lo = *hi = s->verts[t->v[0]];
        for (int k = 1; k < 3; k++) {
            *lo = rr_v3_min(*lo, s->verts[t->v[k]]);
            *hi = rr_v3_max(*hi, s->verts[t->v[k]]);
        }
    } else if (p.kind == RT_PRIM_SPHERE) {
        const scene_object *o = &s->objects[p.index];
        rr_vec3 r = rr_v3(o->radius, o->radius, o->radius);
        *lo = rr_v3_sub(o->center, r);
        *hi = rr_v3_add(o->center, r);
    } else {
        const scene_csg_node *root = &s->csg[s->objects[p.index].csg_root];
        *lo = root->bbox_lo;
        *hi = root->bbox_hi;
    }
}

int rt__prim_hit(const rt_accel *a, rt_prim pr, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit)
{
    const scene *s = a->scene;
    double t;
    int front;
    if (pr.kind == RT_PRIM_TRIANGLE) {
        const scene_tri *tr = &s->tris[pr.index];
        int cull = s->objects[tr->object].cull_backfaces;
        if (!rt__tri_hit(p, s->verts[tr->v[0]], s->verts[tr->v[1]], s->verts[tr->v[2]], cull, tmin, *tmax, &t,
                         &front))
            return 0;
        if (hit) {
            rr_vec3 n = scene_tri_normal(s, pr.index);
            hit->tri = (int64_t)pr.index;
            hit->part = -1;
            hit->object = tr->object;
            hit->material = tr->material;
            hit->normal = front ? n : rr_v3_neg(n);
        }
    } else if (pr.kind == RT_PRIM_SPHERE) {
        const scene_object *o = &s->objects[pr.index];
        if (!rt_sphere_hit(o->center, o->radius, p->ray, tmin, *tmax, &t))
            return 0;
        rr_vec3 n = rr_v3_scale(rr_v3_sub(rr_ray_at(p->ray, t), o->center), 1.0 / o->radius);
        front = rr_v3_dot(n, p->ray.d) < 0.0;
        if (!front && o->cull_backfaces)
            return 0;
        if (hit) {
            hit->tri = -1;
            hit->part = -1;
            hit->object = pr.index;
            hit->material = o->material;
            hit->normal = front ? n : rr_v3_neg(n);
        }
    } else {
        rt_hit h;
        if (!rt_solid_closest(s, a, pr.index, p->ray, tmin, *tmax, &h))
            return 0;
        t = h.t;
        front = h.front;
        if (hit)
            *hit = h;
    }
    if (hit) {
        hit->t = t;
        hit->front = front;
    }
    *tmax = t;
    return 1;
}
