/* test_bvh_util.h - helpers of the BVH's white-box tests (test_bvh.c,
 * test_packet.c): scene edits and the widths this build walks. */
#ifndef TEST_BVH_UTIL_H
#define TEST_BVH_UTIL_H

#include <string.h>

#include "rt.h"
#include "rt_internal.h" /* private header of raytrace/ */
#include "scene.h"

/* Moves every vertex and sphere of s by off (nothing for off = 0), and its
 * bounds. */
static inline void move_scene(scene *s, rr_vec3 off)
{
    if (off.x == 0.0 && off.y == 0.0 && off.z == 0.0)
        return;
    for (size_t i = 0; i < s->nverts; i++)
        s->verts[i] = rr_v3_add(s->verts[i], off);
    for (size_t i = 0; i < s->nobjects; i++)
        if (s->objects[i].kind == SCENE_OBJ_SPHERE)
            s->objects[i].center = rr_v3_add(s->objects[i].center, off);
    s->bbox_min = rr_v3_add(s->bbox_min, off);
    s->bbox_max = rr_v3_add(s->bbox_max, off);
}

/* The same scene with every vertex rounded to float, so the BVH takes its fast
 * path (triangles copied into the leaf packets, rt_internal.h); the scene's
 * other data are not touched (only verts are read by the tests). */
static inline void verts_to_float(scene *s)
{
    /* Through volatile: GCC 12.2 at -O2 (SLP vectorizer) compiles the plain
     * s->verts[i] = rr_v3((float)x, (float)y, (float)z) loop to round z
     * alone, so these tests ran on double vertices (the slow path) unnoticed;
     * bvh_widths_agree now checks that the lanes are fast. */
    for (size_t i = 0; i < s->nverts; i++) {
        volatile float x = (float)s->verts[i].x, y = (float)s->verts[i].y, z = (float)s->verts[i].z;
        s->verts[i] = rr_v3(x, y, z);
    }
}

/* The widths this build and CPU walk: 4, then 8 and 16 where available. */
static inline int widths_available(int w[3])
{
    int n = 0;
    w[n++] = 4;
    if (rt__bvh_width_ok(8))
        w[n++] = 8;
    if (rt__bvh_width_ok(16))
        w[n++] = 16;
    return n;
}

/* The same hit record, bit for bit (or both misses). */
static inline int same_hit(int f1, const rt_hit *h1, int f2, const rt_hit *h2)
{
    if (f1 != f2)
        return 0;
    if (!f1)
        return 1;
    return h1->tri == h2->tri && h1->object == h2->object && h1->material == h2->material && h1->part == h2->part &&
           h1->front == h2->front && memcmp(&h1->t, &h2->t, sizeof h1->t) == 0 &&
           memcmp(&h1->normal, &h2->normal, sizeof h1->normal) == 0 &&
           memcmp(&h1->point, &h2->point, sizeof h1->point) == 0;
}

#endif
