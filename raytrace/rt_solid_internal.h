/* rt_solid_internal.h - private to rt_solid.c and rt_solid_mesh.c (the solids).
 *
 * rt_solid.c: analytic leaves (sphere, quadric, box), their normals, the CSG
 * combination of span lists, closest hit and point membership.
 * rt_solid_mesh.c: mesh leaves (crossings with a tie-broken watertight test,
 * winding numbers) and their per-leaf BVHs (struct rt_solid_accel). */
#ifndef RT_SOLID_INTERNAL_H
#define RT_SOLID_INTERNAL_H

#include "rt_internal.h"

/* A span end at t on surface `surface` of leaf `leaf` (-1: a clip plane or
 * the ray's own limit), not flipped. */
static inline rt_span_end rt__span_end(double t, uint32_t leaf, int32_t surface)
{
    rt_span_end e;
    e.t = t;
    e.leaf = leaf;
    e.surface = surface;
    e.flip = 0;
    return e;
}

/* Appends the span [a, b] to a sorted list whose last span ends at or before
 * a.t. Zero-length (or NaN) spans are dropped; a span that touches or overlaps
 * the last one is merged into it (so no list ever holds two touching spans:
 * that would show an inner face where two solids meet); when the list is full
 * the span is dropped (lists are filled nearest first, so the nearest
 * RT_SPAN_MAX are kept). */
void rt__spans_push(rt_spans *l, rt_span_end a, rt_span_end b);

/* A ray's operands for rt__box_overlap, prepared once per ray: origin,
 * reciprocal direction, and which components are 0. */
typedef struct rt_slab_ray {
    double o[3], inv[3];
    int zero[3];
} rt_slab_ray;
rt_slab_ray rt__slab_prepare(rr_ray r);

/* Does the ray meet the world box [lo, hi] for some t in [tmin, tmax]? Only a
 * pruning test (CSG node boxes, mesh-leaf BVH nodes), so it errs towards yes:
 * the interval is widened a little. An empty box (lo > hi) is never met. */
int rt__box_overlap(const rt_slab_ray *r, rr_vec3 lo, rr_vec3 hi, double tmin, double tmax);

/* Spans of mesh leaf `leaf` along the world ray, clipped to [tmin, tmax];
 * sa may be NULL (every triangle is tested). */
void rt__mesh_spans(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_ray ray, double tmin,
                    double tmax, rt_spans *out);
/* 1 when world point p is inside mesh leaf `leaf` (winding number > 0). */
int rt__mesh_contains(const scene *s, const struct rt_solid_accel *sa, uint32_t leaf, rr_vec3 p);

#endif
