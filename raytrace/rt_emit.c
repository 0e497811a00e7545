/* rt_emit.c - the lights as sources of particles (rt.h, "emission"): the
 * emitters' power weights, the pick table, one particle per call, and the
 * defined power of point and directional lights. */
#include <stdlib.h>
#include <string.h>

#include "rt_light_internal.h"

static double scene_radius(const scene *s)
{
    double r = 0.5 * rr_v3_len(rr_v3_sub(s->bbox_max, s->bbox_min));
    return r > 0.0 && isfinite(r) ? r : rt_scene_scale(s);
}

/* Power weight of a real emitter for rt_lights_emit (rt.h). */
static double emit_weight(const rt_lights *L, const light *l)
{
    double e = rr_rgb_mean(l->radiance);
    switch (l->kind) {
    case LK_POINT:
        return 4.0 * RR_PI * e;
    case LK_DIRECTIONAL:
        return RR_PI * L->scene_r * L->scene_r * e;
    case LK_TRIANGLE:
        return RR_PI * e * l->area;
    default:
        return RR_PI * l->weight; /* 4 pi r^2 times the (largest) radiance */
    }
}

rr_status rt__lights_build_emitters(rt_lights *L, rr_error *err)
{
    const scene *s = L->s;
    L->scene_c = rr_v3_scale(rr_v3_add(s->bbox_min, s->bbox_max), 0.5);
    L->scene_r = scene_radius(s);
    size_t n = L->ndelta + L->nreal;
    L->emit_delta = malloc((L->ndelta ? L->ndelta : 1) * sizeof *L->emit_delta);
    L->ecdf = malloc((n ? n : 1) * sizeof *L->ecdf);
    if (!L->emit_delta || !L->ecdf)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
    for (size_t i = 0; i < L->ndelta; i++)
        if (L->delta[i].nchain == 0)
            L->emit_delta[L->nemit_delta++] = (uint32_t)i;
    double total = 0.0;
    size_t k = 0;
    for (size_t i = 0; i < L->nemit_delta; i++, k++) {
        double w = emit_weight(L, &L->delta[L->emit_delta[i]]);
        total += w > 0.0 && isfinite(w) ? w : 0.0;
        L->ecdf[k] = total;
    }
    for (size_t i = 0; i < L->nreal; i++, k++) {
        double w = emit_weight(L, &L->area[i]);
        total += w > 0.0 && isfinite(w) ? w : 0.0;
        L->ecdf[k] = total;
    }
    for (size_t i = 0; i < k; i++)
        L->ecdf[i] = total > 0.0 ? L->ecdf[i] / total : 0.0;
    return RR_OK;
}

rr_rgb rt_light_power(const scene *s, size_t l)
{
    const scene_light *sl = &s->lights[l];
    double R = scene_radius(s);
    return rr_rgb_scale(sl->intensity, sl->type == SCENE_LIGHT_DIRECTIONAL ? RR_PI * R * R : 4.0 * RR_PI);
}

/* ---- emission: lights as sources of particles (rt.h) ---- */

rr_vec3 rt_cosine_dir(rr_vec3 N, double u1, double u2)
{
    double r = sqrt(u1), phi = 2.0 * RR_PI * u2;
    double x = r * cos(phi), y = r * sin(phi), z = sqrt(fmax(0.0, 1.0 - u1));
    double sign = copysign(1.0, N.z);
    double a = -1.0 / (sign + N.z), b = N.x * N.y * a;
    rr_vec3 T = rr_v3(1.0 + sign * N.x * N.x * a, sign * b, -sign * N.x);
    rr_vec3 B = rr_v3(b, sign + N.y * N.y * a, -N.y);
    return rr_v3_add(rr_v3_add(rr_v3_scale(T, x), rr_v3_scale(B, y)), rr_v3_scale(N, z));
}

size_t rt_lights_emitter_count(const rt_lights *L) { return L ? L->nemit_delta + L->nreal : 0; }

static rr_vec3 uniform_sphere_dir(double u1, double u2)
{
    double z = 1.0 - 2.0 * u1, r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2.0 * RR_PI * u2;
    return rr_v3(r * cos(phi), r * sin(phi), z);
}

/* A point on the disk of radius r about c facing unit w: c + r sqrt(u1) (cos, sin)(2 pi u2). */
static rr_vec3 disk_point(rr_vec3 c, rr_vec3 w, double r, double u1, double u2)
{
    rr_vec3 d = rt_cosine_dir(w, u1, u2); /* its tangential part is uniform on the unit disk */
    return rr_v3_add(c, rr_v3_scale(rr_v3_madd(d, w, -rr_v3_dot(d, w)), r));
}

/* A random line through the light sphere (c, R) of solid i (uniform in the
 * measure of lines: direction w uniform, point uniform on the disk facing
 * it, pdf 1 / (4 pi * pi R^2)); its crossings out of the solid along w on an
 * emissive leaf are emission points. The ray runs against w from outside the
 * sphere, so those crossings are where its spans begin. One of them is
 * chosen with u[5], its weight times their count. */
int rt__emit_solid(const rt_lights *L, uint32_t i, rr_vec3 c, double R, const double u[6], double pk,
                   rt_emission *out)
{
    const scene *s = L->s;
    rr_vec3 w = uniform_sphere_dir(u[1], u[2]);
    rr_vec3 p = disk_point(c, w, R, u[3], u[4]);
    rr_ray r = {rr_v3_madd(p, w, 2.0 * R), rr_v3_neg(w)};
    rt_spans sp;
    rt_solid_spans(s, L->a, i, r, 0.0, 4.0 * R, &sp);
    int cand[RT_SPAN_MAX], nc = 0;
    for (int i = 0; i < sp.n; i++)
        if (rr_rgb_max(s->materials[s->csg[sp.s[i].in.leaf].material].emission) > 0.0)
            cand[nc++] = i;
    if (nc == 0)
        return 0;
    int k = (int)(u[5] * nc);
    const rt_span_end *e = &sp.s[cand[k < nc ? k : nc - 1]].in;
    rr_vec3 x = rr_v3_madd(r.o, r.d, e->t);
    rr_vec3 n = rt_csg_leaf_normal(s, e->leaf, e->surface, x);
    if (e->flip)
        n = rr_v3_neg(n);
    if (!(rr_v3_dot(n, w) > 0.0))
        return 0;
    double measure = 4.0 * RR_PI * RR_PI * R * R;
    out->ray.o = rt_offset_origin(L->scale, x, n, w);
    out->ray.d = w;
    out->power = rr_rgb_scale(rr_rgb_scale(s->materials[s->csg[e->leaf].material].emission, measure * nc), 1.0 / pk);
    out->object = i;
    return 1;
}

/* Uniform on sphere i's surface, cosine-distributed about the normal. */
int rt__emit_sphere(const rt_lights *L, uint32_t i, rr_vec3 c, double r, const double u[6], double pk,
                    rt_emission *out)
{
    (void)c;
    (void)r;
    const scene *s = L->s;
    const scene_object *ob = &s->objects[i];
    rr_vec3 n = uniform_sphere_dir(u[1], u[2]);
    rr_vec3 x = rr_v3_madd(ob->center, n, ob->radius);
    rr_vec3 d = rt_cosine_dir(n, u[3], u[4]);
    out->ray.o = rt_offset_origin(L->scale, x, n, d);
    out->ray.d = d;
    double area = 4.0 * RR_PI * ob->radius * ob->radius;
    out->power = rr_rgb_scale(s->materials[ob->material].emission, RR_PI * area / pk);
    out->object = i;
    return 1;
}

int rt_lights_emit(const rt_lights *L, const double u[6], rt_emission *out)
{
    size_t n = rt_lights_emitter_count(L);
    if (n == 0 || !(L->ecdf[n - 1] > 0.0))
        return 0;
    size_t lo = 0, hi = n - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (L->ecdf[mid] > u[0])
            hi = mid;
        else
            lo = mid + 1;
    }
    double pk = L->ecdf[lo] - (lo ? L->ecdf[lo - 1] : 0.0);
    if (!(pk > 0.0))
        return 0;
    const scene *s = L->s;
    out->object = UINT32_MAX;
    out->light = UINT32_MAX;
    if (lo < L->nemit_delta) {
        const light *l = &L->delta[L->emit_delta[lo]];
        out->light = l->index;
        if (l->kind == LK_POINT) {
            out->ray.o = l->p;
            out->ray.d = uniform_sphere_dir(u[1], u[2]);
            out->power = rr_rgb_scale(l->radiance, 4.0 * RR_PI / pk);
        } else {
            /* From the disk of the scene's bounding sphere facing the light, outside the scene. */
            rr_vec3 p = disk_point(L->scene_c, l->p, L->scene_r, u[1], u[2]);
            out->ray.o = rr_v3_madd(p, l->p, 2.0 * L->scene_r);
            out->ray.d = rr_v3_neg(l->p);
            out->power = rr_rgb_scale(l->radiance, RR_PI * L->scene_r * L->scene_r / pk);
        }
        return 1;
    }
    const light *l = &L->area[lo - L->nemit_delta];
    if (l->kind == LK_TRIANGLE) {
        double su = sqrt(u[1]), b0 = 1.0 - su, b1 = u[2] * su;
        rr_vec3 x = rr_v3_add(rr_v3_add(rr_v3_scale(l->tv[0], b0), rr_v3_scale(l->tv[1], b1)),
                              rr_v3_scale(l->tv[2], 1.0 - b0 - b1));
        rr_vec3 d = rt_cosine_dir(l->tn, u[3], u[4]);
        out->ray.o = rt_offset_origin(L->scale, x, l->tn, d);
        out->ray.d = d;
        out->power = rr_rgb_scale(l->radiance, RR_PI * l->area / pk);
        out->object = s->tris[l->index].object;
        return 1;
    }
    /* A per-object primitive: its row's emission, through its light sphere. */
    return rt_prims[rt_prim_kind_of(s, l->index)].emit(L, l->index, l->p, l->r, u, pk, out);
}
