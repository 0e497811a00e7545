/* rt_mirror.c - the light table's planar mirrors for the radiosity pass's
 * links by way of a mirror (rt.h, "mirror planes"): what a scene's mirrors
 * are, a plane's geometry, and the shadow-ray rule folded at a mirror. */
#include <stdlib.h>
#include <string.h>

#include "rt_light_internal.h"

static double plane_dist(const mplane *q, rr_vec3 x) { return rr_v3_dot(q->n, x) - q->d; }

rt_mirror_kind rt_scene_mirror_kind(const scene *s)
{
    int any = 0;
    for (size_t i = 0; i < s->nobjects; i++)
        if (s->objects[i].kind == SCENE_OBJ_SPHERE && rr_rgb_max(s->materials[s->objects[i].material].mirror) > 0)
            return RT_MIRRORS_CURVED;
    for (size_t i = 0; i < s->ncsg; i++)
        if (s->csg[i].op == SCENE_CSG_LEAF && rr_rgb_max(s->materials[s->csg[i].material].mirror) > 0)
            return RT_MIRRORS_CURVED;
    for (size_t t = 0; t < s->ntris && !any; t++)
        any = rr_rgb_max(s->materials[s->tris[t].material].mirror) > 0;
    if (!any)
        return RT_MIRRORS_NONE;
    rt_lights L;
    memset(&L, 0, sizeof L);
    L.s = s;
    L.scale = rt_scene_scale(s);
    rr_error err;
    rt_mirror_kind kind = RT_MIRRORS_PLANAR;
    if (rt__lights_build_planes(&L, &err) != RR_OK) {
        kind = RT_MIRRORS_CURVED; /* out of memory: say what the table cannot tell */
    } else {
        for (size_t t = 0; t < s->ntris && kind == RT_MIRRORS_PLANAR; t++)
            if (L.tri_plane[t] < 0 && rr_rgb_max(s->materials[s->tris[t].material].mirror) > 0)
                kind = RT_MIRRORS_CURVED; /* past RT_MIRROR_PLANES_MAX planes */
    }
    for (size_t k = 0; k < L.nplanes; k++)
        free(L.planes[k].verts);
    free(L.planes);
    free(L.tri_plane);
    return kind;
}

rt_mirror_plane rt_lights_plane(const rt_lights *L, size_t k)
{
    const mplane *q = &L->planes[k];
    rt_mirror_plane p = {q->n, q->d, q->reflectance, q->verts, q->nverts};
    return p;
}

int rt_lights_via_mirrors(const rt_lights *L, const uint32_t *chain, int n, rr_vec3 x, rr_vec3 nx, rr_vec3 y,
                          rr_vec3 ny)
{
    if (n < 1 || n > RT_CHAIN_MAX)
        return 0;
    /* img[i]: y's image in mirrors chain[i .. n-1] (in chain[n-1] first),
     * the point the leg leaving mirror i-1 (or x) heads for */
    rr_vec3 img[RT_CHAIN_MAX + 1];
    img[n] = y;
    for (int i = n - 1; i >= 0; i--) {
        const mplane *q = &L->planes[chain[i]];
        img[i] = rr_v3_madd(img[i + 1], q->n, -2.0 * plane_dist(q, img[i + 1]));
    }
    rr_vec3 o = x, on = nx;
    rr_vec3 d = rr_v3_sub(img[0], x);
    for (int i = 0; i < n; i++) {
        const mplane *q = &L->planes[chain[i]];
        double a = plane_dist(q, o), b = plane_dist(q, img[i]);
        if (!(a * b < 0.0))
            return 0; /* the leg does not cross the mirror's plane */
        rr_vec3 oo = rt_offset_origin(L->scale, o, on, d);
        rr_ray r = {oo, rr_v3_sub(img[i], oo)};
        rt_hit h;
        if (!rt_accel_closest(L->a, r, 0.0, 1.0, &h) || h.tri < 0 || L->tri_plane[h.tri] != (int32_t)chain[i])
            return 0; /* the leg does not meet this mirror first */
        d = rr_v3_madd(r.d, q->n, -2.0 * rr_v3_dot(q->n, r.d)); /* the reflected leg */
        o = h.point;
        on = a > 0.0 ? q->n : rr_v3_neg(q->n);
    }
    rr_vec3 o2 = rt_offset_origin(L->scale, o, on, d), t = rt_offset_origin(L->scale, y, ny, rr_v3_neg(d));
    rr_ray r2 = {o2, rr_v3_sub(t, o2)};
    return !rt_accel_occluded(L->a, r2, 0.0, RT_SHADOW_END);
}
