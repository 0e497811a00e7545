/* rt_mirror.c - the light table's planar mirrors for the radiosity pass's
 * links by way of mirrors (rt.h, "mirror planes"): what a scene's mirrors
 * are, and a plane's geometry (the shadow-ray rule folded at mirrors,
 * rt_lights_via_mirrors, is rt_light.c's, beside the images' own). */
#include <stdlib.h>
#include <string.h>

#include "rt_light_internal.h"

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
    rt_mirror_plane p = {q->n, q->d, q->reflectance, q->verts, q->nverts, q->object};
    return p;
}
