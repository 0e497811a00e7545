/* rt_light.c - the one light interface: every emitter of a scene, and its
 * virtual images in planar mirrors, for the ray tracer and the radiosity pass
 * (the same table emits particles for the light tracer: rt_emit.c).
 *
 * Lights.
 *  - delta lights: point and directional lights (no area: evaluated one by
 *    one, never sampled at random);
 *  - area lights: emissive triangles (uniform by area), emissive spheres and
 *    solids (CSG trees or quadrics with an emissive leaf): directions sampled
 *    uniformly in the cone of their bounding sphere, and the closest hit along
 *    the direction decides (so the emissive part of any solid is found without
 *    knowing its area, and the estimate stays unbiased). Area lights are
 *    picked with probability proportional to their power (area times mean
 *    radiance; a bounding sphere's area for curved ones).
 *
 * Virtual images (Radiance's "virtual light sources"). A planar mirror plane
 * q reflects a light into an image behind it; a chain of planes c[0], c[1],
 * ..., c[k-1] (c[0] the first the light meets) gives the image R_c[k-1] ...
 * R_c[0] (light). Seen from a point x, an image is a light like any other,
 * except that the straight segment from x to it is folded back into k legs:
 * x -> mirror c[k-1] -> ... -> mirror c[0] -> light. Each leg is traced
 * (closest hit), must meet its mirror plane's own triangles first, and
 * multiplies by that mirror's reflectance; so the images are clipped to the
 * finite mirrors and shadowed on every leg. Chains are made up to the depth
 * given at build time (render.max_depth), shortest first, pruned where no
 * light can pass (the source, or the previous mirror, on neither side of the
 * next plane), at most RT_VIRTUAL_PER_LIGHT per light.
 *
 * Mirror planes: coplanar triangles of one object with a mirror reflectance.
 * Curved mirrors (spheres, solids, triangles of a curved mesh beyond
 * RT_MIRROR_PLANES_MAX planes) have no images: light that reaches a diffuse
 * surface through them is found by BSDF sampling only.
 */
#include <stdlib.h>
#include <string.h>

#include "rt_light_internal.h"

/* ---- the shadow-ray rule ---- */

int rt_visible(const rt_accel *a, double scale, rr_vec3 x, rr_vec3 n, rr_vec3 y)
{
    rr_vec3 d = rr_v3_sub(y, x);
    rr_vec3 o = rt_offset_origin(scale, x, n, d);
    rr_ray r = {o, rr_v3_sub(y, o)};
    return !rt_accel_occluded(a, r, 0.0, RT_SHADOW_END);
}

int rt_visible_dir(const rt_accel *a, double scale, rr_vec3 x, rr_vec3 n, rr_vec3 dir)
{
    rr_ray r = {rt_offset_origin(scale, x, n, dir), dir};
    return !rt_accel_occluded(a, r, 0.0, INFINITY);
}

/* ---- geometry ---- */

static rr_vec3 reflect_point(const mplane *q, rr_vec3 x)
{
    return rr_v3_madd(x, q->n, -2.0 * (rr_v3_dot(q->n, x) - q->d));
}

static rr_vec3 reflect_dir(const mplane *q, rr_vec3 v) { return rr_v3_madd(v, q->n, -2.0 * rr_v3_dot(q->n, v)); }

static double plane_dist(const mplane *q, rr_vec3 x) { return rr_v3_dot(q->n, x) - q->d; }

/* Which sides of plane q a set of points reaches: bit 1 above, bit 2 below. */
static int sides_of_points(const mplane *q, const rr_vec3 *v, size_t n, double tol)
{
    int s = 0;
    for (size_t i = 0; i < n; i++) {
        double t = plane_dist(q, v[i]);
        s |= t > tol ? 1 : t < -tol ? 2 : 0;
    }
    return s;
}

int rt_scene_emits(const scene *s)
{
    if (s->nlights > 0 || s->nemissive > 0)
        return 1;
    for (size_t i = 0; i < s->nobjects; i++) {
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)i);
        if (k != RT_PRIM_TRIANGLE && rt_prims[k].emission(s, (uint32_t)i) > 0)
            return 1;
    }
    return 0;
}

/* ---- building ---- */

rr_status rt__lights_build_planes(rt_lights *L, rr_error *err)
{
    const scene *s = L->s;
    L->tri_plane = malloc((s->ntris ? s->ntris : 1) * sizeof *L->tri_plane);
    if (!L->tri_plane)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the mirror planes");
    double tol = 1e-9 * L->scale;
    size_t cap = 0;
    for (size_t t = 0; t < s->ntris; t++) {
        L->tri_plane[t] = -1;
        const scene_tri *tr = &s->tris[t];
        if (!(rr_rgb_max(s->materials[tr->material].mirror) > 0.0))
            continue;
        rr_vec3 n = scene_tri_normal(s, t);
        double d = rr_v3_dot(n, s->verts[tr->v[0]]);
        size_t k = 0;
        for (; k < L->nplanes; k++) {
            const mplane *q = &L->planes[k];
            if (q->object == tr->object && rr_v3_dot(q->n, n) > 1.0 - 1e-9 && fabs(q->d - d) <= tol)
                break;
        }
        if (k == L->nplanes) {
            if (L->nplanes == RT_MIRROR_PLANES_MAX)
                continue; /* a curved mirror mesh: no images for the rest */
            if (L->nplanes == cap) {
                size_t nc = cap ? 2 * cap : 8;
                mplane *np = realloc(L->planes, nc * sizeof *np);
                if (!np)
                    return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the mirror planes");
                L->planes = np;
                cap = nc;
            }
            mplane *q = &L->planes[L->nplanes++];
            memset(q, 0, sizeof *q);
            q->n = n;
            q->d = d;
            q->object = tr->object;
            q->reflectance = rr_rgb_mean(s->materials[tr->material].mirror);
        }
        mplane *q = &L->planes[k];
        rr_vec3 *nv = realloc(q->verts, (q->nverts + 3) * sizeof *nv);
        if (!nv)
            return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the mirror planes");
        q->verts = nv;
        for (int e = 0; e < 3; e++)
            q->verts[q->nverts++] = s->verts[tr->v[e]];
        L->tri_plane[t] = (int32_t)k;
    }
    return RR_OK;
}

/* Which sides of plane q the light l (a real one or an image) can send light
 * from (bits as in sides_of_points); 0: none. */
static int source_sides(const rt_lights *L, const light *l, const mplane *q)
{
    double tol = 1e-9 * L->scale;
    switch (l->kind) {
    case LK_POINT: return sides_of_points(q, &l->p, 1, tol);
    case LK_DIRECTIONAL: {
        double c = rr_v3_dot(q->n, l->p);
        return c > 1e-12 ? 1 : c < -1e-12 ? 2 : 0;
    }
    case LK_TRIANGLE: return sides_of_points(q, l->tv, 3, tol);
    case LK_SPHERE: {
        double t = plane_dist(q, l->p);
        return t > l->r ? 1 : t < -l->r ? 2 : 3;
    }
    }
    return 0;
}

/* l reflected in plane q: the image one more mirror away. */
static light image_of(const rt_lights *L, const light *l, uint32_t qi)
{
    const mplane *q = &L->planes[qi];
    light v = *l;
    v.chain[v.nchain++] = qi;
    v.vfirst = v.vcount = 0;
    if (l->kind == LK_DIRECTIONAL)
        v.p = reflect_dir(q, l->p);
    else
        v.p = reflect_point(q, l->p);
    for (int e = 0; e < 3; e++)
        v.tv[e] = reflect_point(q, l->tv[e]);
    v.tn = reflect_dir(q, l->tn);
    v.weight = l->weight * q->reflectance;
    return v;
}

/* Whether light can leave image l (chain so far) towards plane qi. */
static int chain_can_extend(const rt_lights *L, const light *l, uint32_t qi)
{
    const mplane *q = &L->planes[qi];
    if (l->nchain > 0 && l->chain[l->nchain - 1] == qi)
        return 0;
    int side = source_sides(L, l, q);
    if (!side)
        return 0;
    double tol = 1e-9 * L->scale;
    if (l->nchain > 0) {
        /* The light arrives at q from the previous mirror. */
        const mplane *prev = &L->planes[l->chain[l->nchain - 1]];
        return (sides_of_points(q, prev->verts, prev->nverts, tol) & side) != 0;
    }
    if (l->kind == LK_TRIANGLE) {
        /* A triangle emitter radiates from its front: some of the mirror must be there. */
        for (size_t i = 0; i < q->nverts; i++)
            if (rr_v3_dot(l->tn, rr_v3_sub(q->verts[i], l->tv[0])) > tol)
                return 1;
        return 0;
    }
    return 1;
}

/* Appends to *arr (of *n, capacity *cap) every image of base up to depth
 * mirrors, shortest chains first, at most RT_VIRTUAL_PER_LIGHT. */
static rr_status add_images(rt_lights *L, const light *base, int depth, light **arr, size_t *n, size_t *cap,
                            size_t *budget, rr_error *err)
{
    size_t level_lo = *n, made = 0;
    for (int len = 1; len <= depth && len <= RT_CHAIN_MAX; len++) {
        size_t level_hi = *n;
        size_t from_lo = len == 1 ? 0 : level_lo, from_hi = len == 1 ? 1 : level_hi;
        for (size_t k = from_lo; k < from_hi; k++) {
            for (uint32_t q = 0; q < L->nplanes; q++) {
                const light *src = len == 1 ? base : &(*arr)[k];
                if (made >= RT_VIRTUAL_PER_LIGHT || *budget == 0 || !chain_can_extend(L, src, q))
                    continue;
                if (*n == *cap) {
                    size_t nc = *cap ? 2 * *cap : 64;
                    light *na = realloc(*arr, nc * sizeof *na);
                    if (!na)
                        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the mirror images");
                    *arr = na;
                    *cap = nc;
                    src = len == 1 ? base : &(*arr)[k];
                }
                (*arr)[(*n)++] = image_of(L, src, q);
                made++;
                (*budget)--;
            }
        }
        level_lo = level_hi;
        if (*n == level_hi)
            break;
    }
    return RR_OK;
}

static void light_init(light *l, light_kind kind, uint32_t index)
{
    memset(l, 0, sizeof *l);
    l->kind = kind;
    l->index = index;
}

/* The delta lights (point, directional), each followed by its images. */
static rr_status add_delta_lights(rt_lights *L, int depth, size_t *budget, rr_error *err)
{
    const scene *s = L->s;
    size_t dcap = 0;
    rr_status st = RR_OK;
    for (size_t i = 0; i < s->nlights && st == RR_OK; i++) {
        const scene_light *sl = &s->lights[i];
        light l;
        light_init(&l, sl->type == SCENE_LIGHT_DIRECTIONAL ? LK_DIRECTIONAL : LK_POINT, (uint32_t)i);
        l.p = sl->type == SCENE_LIGHT_DIRECTIONAL ? sl->direction : sl->position;
        l.radiance = sl->intensity;
        l.weight = 1.0;
        if (L->ndelta == dcap) {
            dcap = dcap ? 2 * dcap : 16;
            light *nd = realloc(L->delta, dcap * sizeof *nd);
            if (!nd)
                return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
            L->delta = nd;
        }
        L->delta[L->ndelta++] = l;
        st = add_images(L, &l, depth, &L->delta, &L->ndelta, &dcap, budget, err);
    }
    return st;
}

/* An emissive triangle as an area light. */
static void triangle_light(const scene *s, uint32_t t, light *l)
{
    light_init(l, LK_TRIANGLE, t);
    for (int e = 0; e < 3; e++)
        l->tv[e] = s->verts[s->tris[t].v[e]];
    l->tn = scene_tri_normal(s, t);
    l->area = scene_tri_area(s, t);
    l->radiance = s->materials[s->tris[t].material].emission;
    l->weight = l->area * rr_rgb_mean(l->radiance);
    l->p = rr_v3_scale(rr_v3_add(rr_v3_add(l->tv[0], l->tv[1]), l->tv[2]), 1.0 / 3.0);
    for (int e = 0; e < 3; e++)
        l->r = fmax(l->r, rr_v3_len(rr_v3_sub(l->tv[e], l->p)));
}

/* An emitting per-object primitive (a sphere, a solid) as an area light,
 * sampled through its row's light sphere; 0 when object o does not emit. */
static int object_light(const rt_lights *L, uint32_t o, light *l)
{
    const scene *s = L->s;
    rt_prim_kind k = rt_prim_kind_of(s, o);
    if (k == RT_PRIM_TRIANGLE)
        return 0;
    double e = rt_prims[k].emission(s, o);
    rr_vec3 c;
    double r;
    if (!rt_prims[k].light_sphere(s, o, L->scale, &c, &r) || !(e > 0.0))
        return 0;
    light_init(l, LK_SPHERE, o);
    l->p = c;
    l->r = r;
    l->weight = 4.0 * RR_PI * r * r * e;
    return 1;
}

/* The real area lights (triangles, then the per-object ones), then their
 * images, then the sampling cdf over all of them by weight. */
static rr_status add_area_lights(rt_lights *L, int depth, size_t *budget, rr_error *err)
{
    const scene *s = L->s;
    size_t nreal = s->nemissive;
    for (size_t o = 0; o < s->nobjects; o++) {
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)o);
        nreal += k != RT_PRIM_TRIANGLE && rt_prims[k].emission(s, (uint32_t)o) > 0;
    }
    size_t acap = nreal;
    if (nreal > 0 && !(L->area = malloc(acap * sizeof *L->area)))
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
    for (size_t i = 0; i < s->nemissive; i++) {
        uint32_t t = s->emissive_tris[i];
        triangle_light(s, t, &L->area[L->narea]);
        L->tri_light[t] = (int32_t)L->narea++;
    }
    for (size_t o = 0; o < s->nobjects; o++)
        if (object_light(L, (uint32_t)o, &L->area[L->narea]))
            L->obj_light[o] = (int32_t)L->narea++;
    L->nreal = L->narea;
    rr_status st = RR_OK;
    for (size_t i = 0; st == RR_OK && i < L->nreal && depth > 0; i++) {
        light base = L->area[i];
        size_t before = L->narea;
        st = add_images(L, &base, depth, &L->area, &L->narea, &acap, budget, err);
        L->area[i].vfirst = (uint32_t)before;
        L->area[i].vcount = (uint32_t)(L->narea - before);
    }
    if (st != RR_OK || L->narea == 0)
        return st;
    if (!(L->cdf = malloc(L->narea * sizeof *L->cdf)))
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
    double total = 0.0;
    for (size_t i = 0; i < L->narea; i++) {
        total += L->area[i].weight > 0 ? L->area[i].weight : 0.0;
        L->cdf[i] = total;
    }
    for (size_t i = 0; i < L->narea; i++)
        L->cdf[i] = total > 0 ? L->cdf[i] / total : (double)(i + 1) / (double)L->narea;
    return RR_OK;
}

rr_status rt_lights_build(const scene *s, const rt_accel *a, int max_mirror_depth, rt_lights **out, rr_error *err)
{
    rt_lights *L = calloc(1, sizeof *L);
    if (!L)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
    L->s = s;
    L->a = a;
    L->scale = rt_scene_scale(s);
    for (size_t i = 0; i < s->nmaterials; i++)
        L->has_mirror |= rr_rgb_max(s->materials[i].mirror) > 0.0;
    rr_status st = rt__lights_build_planes(L, err);
    int depth = max_mirror_depth < 0 ? 0 : max_mirror_depth;
    if (L->nplanes == 0)
        depth = 0;
    size_t budget = RT_VIRTUAL_MAX;
    L->tri_light = malloc((s->ntris ? s->ntris : 1) * sizeof *L->tri_light);
    L->obj_light = malloc((s->nobjects ? s->nobjects : 1) * sizeof *L->obj_light);
    if (st == RR_OK && (!L->tri_light || !L->obj_light))
        st = rr_error_set(err, RR_ERR_NOMEM, "out of memory for the light table");
    if (st == RR_OK) {
        for (size_t t = 0; t < s->ntris; t++)
            L->tri_light[t] = -1;
        for (size_t o = 0; o < s->nobjects; o++)
            L->obj_light[o] = -1;
        st = add_delta_lights(L, depth, &budget, err);
    }
    if (st == RR_OK)
        st = add_area_lights(L, depth, &budget, err);
    if (st == RR_OK)
        st = rt__lights_build_emitters(L, err);
    if (st != RR_OK) {
        rt_lights_destroy(L);
        return st;
    }
    *out = L;
    return RR_OK;
}

void rt_lights_destroy(rt_lights *L)
{
    if (!L)
        return;
    for (size_t k = 0; k < L->nplanes; k++)
        free(L->planes[k].verts);
    free(L->planes);
    free(L->tri_plane);
    free(L->delta);
    free(L->area);
    free(L->cdf);
    free(L->tri_light);
    free(L->obj_light);
    free(L->emit_delta);
    free(L->ecdf);
    free(L);
}

size_t rt_lights_delta_count(const rt_lights *L) { return L ? L->ndelta : 0; }
size_t rt_lights_area_count(const rt_lights *L) { return L ? L->narea : 0; }
size_t rt_lights_image_count(const rt_lights *L)
{
    if (!L)
        return 0;
    size_t n = L->narea - L->nreal;
    for (size_t i = 0; i < L->ndelta; i++)
        n += L->delta[i].nchain > 0;
    return n;
}
size_t rt_lights_mirror_planes(const rt_lights *L) { return L ? L->nplanes : 0; }
uint32_t rt_lights_delta_source(const rt_lights *L, size_t k) { return L->delta[k].index; }


int rt_lights_mirror_plane(const rt_lights *L, const rt_hit *h)
{
    if (!L || h->tri < 0 || (size_t)h->tri >= L->s->ntris)
        return -1;
    return L->tri_plane[h->tri];
}

/* ---- evaluation ---- */

/* Folds the straight segment from x (normal n) along unit dir into the legs
 * of image l: dir must leave on n's side, and each leg must meet the
 * triangles of its mirror plane first.
 * On success *o is a point on the last mirror (or x itself) with *on its
 * plane normal, *d the direction of the last leg, *thru the product of the
 * mirrors' reflectances. */
static int fold_legs(const rt_lights *L, const light *l, rr_vec3 x, rr_vec3 n, rr_vec3 dir, rr_vec3 *o, rr_vec3 *on,
                     rr_vec3 *d, rr_rgb *thru)
{
    if (!(rr_v3_dot(n, dir) > 0.0))
        return 0;
    *o = x;
    *on = n;
    *d = dir;
    *thru = rr_rgb_make(1, 1, 1);
    for (int i = l->nchain - 1; i >= 0; i--) {
        const mplane *q = &L->planes[l->chain[i]];
        rr_ray r = {rt_offset_origin(L->scale, *o, *on, *d), *d};
        rt_hit h;
        if (!rt_accel_closest(L->a, r, 0.0, INFINITY, &h) || h.tri < 0 || L->tri_plane[h.tri] != (int32_t)l->chain[i])
            return 0;
        *thru = rr_rgb_mul(*thru, L->s->materials[h.material].mirror);
        *o = h.point;
        *on = q->n;
        *d = reflect_dir(q, *d);
    }
    return 1;
}

int rt_lights_via_mirrors(const rt_lights *L, const uint32_t *chain, int n, rr_vec3 x, rr_vec3 nx, rr_vec3 y,
                          rr_vec3 ny)
{
    if (n < 1 || n > RT_CHAIN_MAX)
        return 0;
    /* y as a light whose image chain meets chain[n - 1] first: the same
     * folded legs as a light's image, then the last leg to y itself */
    light v;
    memset(&v, 0, sizeof v);
    v.p = y;
    for (int i = n - 1; i >= 0; i--) {
        v.chain[v.nchain++] = chain[i];
        v.p = reflect_point(&L->planes[chain[i]], v.p);
    }
    rr_vec3 o, on, d;
    rr_rgb thru;
    if (!fold_legs(L, &v, x, nx, rr_v3_sub(v.p, x), &o, &on, &d, &thru))
        return 0;
    rr_vec3 o2 = rt_offset_origin(L->scale, o, on, d), t = rt_offset_origin(L->scale, y, ny, rr_v3_neg(d));
    rr_ray r = {o2, rr_v3_sub(t, o2)};
    return !rt_accel_occluded(L->a, r, 0.0, RT_SHADOW_END);
}

/* The cheap test before any ray: the straight segment from x to image l
 * (at y, or towards direction y for a directional one) crosses its first
 * mirror's plane. */
static int crosses_first_plane(const rt_lights *L, const light *l, rr_vec3 x, rr_vec3 y, int directional)
{
    if (l->nchain == 0)
        return 1;
    const mplane *q = &L->planes[l->chain[l->nchain - 1]];
    double a = plane_dist(q, x);
    double b = directional ? rr_v3_dot(q->n, y) : plane_dist(q, y);
    return (a > 0 && b < 0) || (a < 0 && b > 0);
}

int rt_lights_delta(const rt_lights *L, size_t k, rr_vec3 x, rr_vec3 n, rt_light_sample *out)
{
    const light *l = &L->delta[k];
    const scene_light *sl = &L->s->lights[l->index];
    rr_vec3 dir;
    double r2 = INFINITY;
    if (l->kind == LK_DIRECTIONAL) {
        dir = l->p;
        if (!crosses_first_plane(L, l, x, dir, 1))
            return 0;
    } else {
        rr_vec3 w = rr_v3_sub(l->p, x);
        r2 = rr_v3_len2(w);
        if (!(r2 > 0.0) || !crosses_first_plane(L, l, x, l->p, 0))
            return 0;
        dir = rr_v3_scale(w, 1.0 / sqrt(r2));
    }
    rr_vec3 o, on, d;
    rr_rgb thru;
    if (!fold_legs(L, l, x, n, dir, &o, &on, &d, &thru))
        return 0;
    int vis = l->kind == LK_DIRECTIONAL ? rt_visible_dir(L->a, L->scale, o, on, d)
                                        : rt_visible(L->a, L->scale, o, on, sl->position);
    if (!vis)
        return 0;
    out->L = dir;
    out->E = rr_rgb_scale(rr_rgb_mul(thru, l->radiance), l->kind == LK_DIRECTIONAL ? 1.0 : 1.0 / r2);
    out->pdf = 0.0;
    out->dist = sqrt(r2);
    out->image = l->nchain > 0;
    return 1;
}

static size_t pick(const rt_lights *L, double u, double *p)
{
    size_t lo = 0, hi = L->narea - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (L->cdf[mid] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    *p = L->cdf[lo] - (lo ? L->cdf[lo - 1] : 0.0);
    return lo;
}

static double pick_prob(const rt_lights *L, size_t i) { return L->cdf[i] - (i ? L->cdf[i - 1] : 0.0); }

/* Solid angle pdf of the cone of a sphere (centre c, radius r) seen from x;
 * inside it, uniform over all directions. */
static double cone_pdf(rr_vec3 c, double r, rr_vec3 x)
{
    double d2 = rr_v3_len2(rr_v3_sub(c, x));
    if (d2 <= r * r)
        return 1.0 / (4.0 * RR_PI);
    double sin2 = r * r / d2, cosm = sqrt(fmax(0.0, 1.0 - sin2));
    double one_minus = sin2 / (1.0 + cosm); /* 1 - cos_max without cancellation */
    return 1.0 / (2.0 * RR_PI * one_minus);
}

static rr_vec3 cone_sample(rr_vec3 c, double r, rr_vec3 x, double u1, double u2)
{
    rr_vec3 w = rr_v3_sub(c, x);
    double d2 = rr_v3_len2(w);
    double z, phi = 2.0 * RR_PI * u2;
    rr_vec3 N;
    if (d2 <= r * r) {
        z = 1.0 - 2.0 * u1;
        N = rr_v3(0, 0, 1);
    } else {
        double sin2 = r * r / d2, cosm = sqrt(fmax(0.0, 1.0 - sin2));
        z = 1.0 - u1 * (sin2 / (1.0 + cosm));
        N = rr_v3_scale(w, 1.0 / sqrt(d2));
    }
    double sr = sqrt(fmax(0.0, 1.0 - z * z));
    double sign = copysign(1.0, N.z);
    double a = -1.0 / (sign + N.z), b = N.x * N.y * a;
    rr_vec3 T = rr_v3(1.0 + sign * N.x * N.x * a, sign * b, -sign * N.x);
    rr_vec3 B = rr_v3(b, sign + N.y * N.y * a, -N.y);
    return rr_v3_add(rr_v3_add(rr_v3_scale(T, sr * cos(phi)), rr_v3_scale(B, sr * sin(phi))), rr_v3_scale(N, z));
}

int rt_lights_sample(const rt_lights *L, rr_vec3 x, rr_vec3 n, double u0, double u1, double u2, rt_light_sample *out)
{
    if (!L || L->narea == 0)
        return 0;
    double pk;
    size_t li = pick(L, u0, &pk);
    if (!(pk > 0.0))
        return 0;
    const light *l = &L->area[li];
    rr_vec3 dir;
    double pdf, d2 = 0.0;
    rr_vec3 y = rr_v3(0, 0, 0);
    if (l->kind == LK_TRIANGLE) {
        double su = sqrt(u1), b0 = 1.0 - su, b1 = u2 * su;
        rr_vec3 yv = rr_v3_add(rr_v3_add(rr_v3_scale(l->tv[0], b0), rr_v3_scale(l->tv[1], b1)),
                               rr_v3_scale(l->tv[2], 1.0 - b0 - b1));
        rr_vec3 w = rr_v3_sub(yv, x);
        d2 = rr_v3_len2(w);
        if (!(d2 > 0.0))
            return 0;
        dir = rr_v3_scale(w, 1.0 / sqrt(d2));
        double cos_y = -rr_v3_dot(l->tn, dir); /* emitters radiate from their front */
        if (!(cos_y > 0.0) || !crosses_first_plane(L, l, x, yv, 0))
            return 0;
        pdf = pk / l->area * d2 / cos_y;
        /* The point on the real emitter (an image's sample is its reflection). */
        y = yv;
        if (l->nchain > 0) {
            const scene_tri *tr = &L->s->tris[l->index];
            const rr_vec3 *V = L->s->verts;
            y = rr_v3_add(rr_v3_add(rr_v3_scale(V[tr->v[0]], b0), rr_v3_scale(V[tr->v[1]], b1)),
                          rr_v3_scale(V[tr->v[2]], 1.0 - b0 - b1));
        }
    } else {
        dir = cone_sample(l->p, l->r, x, u1, u2);
        pdf = pk * cone_pdf(l->p, l->r, x);
        if (!crosses_first_plane(L, l, x, dir, 1)) /* towards the image's sphere through its first mirror */
            return 0;
    }
    rr_vec3 o, on, d;
    rr_rgb thru;
    if (!fold_legs(L, l, x, n, dir, &o, &on, &d, &thru))
        return 0;
    rr_rgb Le;
    if (l->kind == LK_TRIANGLE) {
        if (!rt_visible(L->a, L->scale, o, on, y))
            return 0;
        Le = l->radiance;
        out->dist = sqrt(d2);
    } else {
        rr_ray r = {rt_offset_origin(L->scale, o, on, d), d};
        rt_hit h;
        if (!rt_accel_closest(L->a, r, 0.0, INFINITY, &h) || h.object != l->index || !h.front)
            return 0;
        Le = L->s->materials[h.material].emission;
        if (!(rr_rgb_max(Le) > 0.0))
            return 0;
        out->dist = NAN;
    }
    out->L = dir;
    out->E = rr_rgb_scale(rr_rgb_mul(thru, Le), 1.0 / pdf);
    out->pdf = pdf;
    out->image = l->nchain > 0;
    return 1;
}

double rt_lights_pdf(const rt_lights *L, const rt_mirror_path *path, const rt_hit *h, rr_vec3 last_dir)
{
    if (!L || L->narea == 0 || path->curved)
        return 0.0;
    int32_t li = h->tri >= 0 ? L->tri_light[h->tri] : L->obj_light[h->object];
    if (li < 0)
        return 0.0;
    const light *l = &L->area[li];
    if (path->n > 0) {
        /* The image whose chain is the path's mirrors in reverse. */
        const light *found = NULL;
        for (uint32_t k = l->vfirst; k < l->vfirst + l->vcount && !found; k++) {
            const light *v = &L->area[k];
            if (v->nchain != path->n)
                continue;
            int same = 1;
            for (int i = 0; i < v->nchain && same; i++)
                same = v->chain[i] == path->plane[path->n - 1 - i];
            if (same)
                found = v;
        }
        if (!found)
            return 0.0;
        li = (int32_t)(found - L->area);
        l = found;
    }
    double pk = pick_prob(L, (size_t)li);
    if (l->kind == LK_TRIANGLE) {
        double cos_y = -rr_v3_dot(scene_tri_normal(L->s, (size_t)h->tri), last_dir);
        if (!(cos_y > 0.0))
            return 0.0;
        return pk / l->area * path->dist * path->dist / cos_y;
    }
    return pk * cone_pdf(l->p, l->r, path->origin);
}

/* ---- BSDF rays that only look for emitters ---- */

/* A real triangle light met from its front: t along r, or 0 (the lecture's
 * tests, rt_ref.c: facing, inside, distance). */
static double tri_hit(const light *l, rr_ray r)
{
    rr_vec3 P = rr_v3_add(r.o, r.d);
    if (!rt_front_facing(l->tv[0], l->tv[1], l->tv[2], r.o) || !rt_ray_hits_tri(r.o, P, l->tv[0], l->tv[1], l->tv[2]))
        return 0.0;
    double t = rt_dist_along_ray(r.o, P, l->tv[0], l->tv[1], l->tv[2]);
    return t > 0.0 ? t : 0.0;
}

int rt_lights_find_emitter(const rt_lights *L, rr_ray r, rt_hit *h)
{
    /* Mirrors (planar or curved) need the full walk. */
    if (!L || L->has_mirror || L->nreal > RT_FIND_EMITTER_MAX)
        return -1;
    double best = INFINITY;
    int found = -1;
    for (size_t i = 0; i < L->nreal; i++) {
        const light *l = &L->area[i];
        if (l->kind == LK_TRIANGLE) {
            double t = tri_hit(l, r);
            if (t > 0.0 && t < best) {
                best = t;
                found = (int)i;
            }
        } else {
            /* A curved emitter's bounding sphere: the exact walk decides. */
            rr_vec3 oc = rr_v3_sub(r.o, l->p);
            double b = rr_v3_dot(oc, r.d), c = rr_v3_len2(oc) - l->r * l->r;
            if (c <= 0.0 || (b < 0.0 && b * b - rr_v3_len2(r.d) * c >= 0.0))
                return -1;
        }
    }
    if (found < 0)
        return 0;
    /* The nearest emitter along the ray; is anything in front of it? */
    if (rt_accel_occluded(L->a, r, 0.0, best * RT_SHADOW_END))
        return 0;
    const light *l = &L->area[found];
    memset(h, 0, sizeof *h);
    h->t = best;
    h->point = rr_v3_madd(r.o, r.d, best);
    h->normal = l->tn;
    h->tri = l->index;
    h->object = L->s->tris[l->index].object;
    h->material = L->s->tris[l->index].material;
    h->part = -1;
    h->front = 1;
    return 1;
}

int rt_lights_near(const rt_lights *L, rr_vec3 x)
{
    if (!L || L->narea == 0)
        return 0;
    if (L->narea > RT_NEAR_MAX)
        return 1;
    for (size_t i = 0; i < L->narea; i++) {
        const light *l = &L->area[i];
        double reach = RT_NEAR_RADII * l->r;
        if (rr_v3_len2(rr_v3_sub(x, l->p)) < reach * reach)
            return 1;
    }
    return 0;
}
