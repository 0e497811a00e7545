/* rt.h - the ray-tracing pass.
 *
 * Offers, today:
 *  - The lecture's reference geometry, kept deliberately literal so that it can
 *    be read next to the lecture notes and so that every fast path has
 *    something to be tested against:
 *      rt_orient          s(A,B,C,D) = (AB x AC) . AD > 0
 *      rt_front_facing    s(A,B,C,E)
 *      rt_ray_hits_tri    s(P,B,C,E) && s(A,P,C,E) && s(A,B,P,E)
 *      rt_dist_along_ray  t = (AB x AC).EA / (AB x AC).EP
 *  - rt_ref_closest: front-most hit over the whole scene by brute force
 *    (every triangle with the lecture's tests, every sphere in closed form).
 *  - rt_render_preview: a flat-shaded image of the front-most hits, used by
 *    `radray render` until the full ray tracer (BVH, lights, shadows, mirrors)
 *    replaces it.
 *
 * The scene is read-only here; rendering is multithreaded with OpenMP over
 * rows, every pixel draws from its own RNG stream (rr_rng_make(seed, pixel)),
 * so the image is bit-identical whatever the thread count.
 */
#ifndef RT_H
#define RT_H

#include "rr_core.h"
#include "scene.h"

/* s(A,B,C,D): 1 when D lies on the side of plane ABC that AB x AC points to. */
int rt_orient(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 D);
/* Triangle ABC is seen from its front from E (counter-clockwise from E). */
int rt_front_facing(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 E);
/* The ray from E through P meets front-facing triangle ABC (the lecture's test;
 * for a back-facing triangle call it with B and C swapped). */
int rt_ray_hits_tri(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C);
/* Parameter t of the hit H = E + t EP with the plane of ABC (t = 1 at P). The
 * plane must not contain the ray direction (the caller checks facing first). */
double rt_dist_along_ray(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C);

/* A ray's front-most hit. */
typedef struct rt_hit {
    double t;          /* along the ray's (unnormalised) direction */
    rr_vec3 point;
    rr_vec3 normal;    /* unit geometric normal, facing the ray's origin */
    uint32_t object;   /* index into scene->objects */
    uint32_t material;
    int64_t tri;       /* triangle index, or -1 for a sphere */
    int front;         /* the ray met the surface's front side */
} rt_hit;

/* Front-most hit with t in (tmin, tmax) among all triangles and spheres, by
 * brute force with the lecture's tests (back faces culled per object). Returns
 * 1 and fills *hit, or 0 when nothing is hit. */
int rt_ref_closest(const scene *s, rr_ray ray, double tmin, double tmax, rt_hit *hit);

/* Ray-sphere hits in closed form, numerically stable (no cancellation for far
 * or grazing rays): the smallest t in (tmin, tmax), or 0 when none. */
int rt_sphere_hit(rr_vec3 center, double radius, rr_ray ray, double tmin, double tmax, double *t);

/* The fast path: a BVH over every triangle and sphere of a scene (binned SAH,
 * flat 32-byte nodes, watertight triangle test). The accel keeps a pointer to
 * the scene, which must outlive it. Queries are thread-safe (read-only). */
typedef struct rt_accel rt_accel;

rr_status rt_accel_build(const scene *s, rt_accel **out, rr_error *err);
void rt_accel_destroy(rt_accel *a); /* NULL is a no-op */
size_t rt_accel_node_count(const rt_accel *a);
/* Same contract as rt_ref_closest (and tested against it). */
int rt_accel_closest(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit);
/* Any hit with t in (tmin, tmax): for shadow rays; stops at the first occluder. */
int rt_accel_occluded(const rt_accel *a, rr_ray ray, double tmin, double tmax);

typedef struct rt_render_opts {
    int spp;          /* samples per pixel (stratified in a sqrt(spp) grid when square) */
    uint64_t seed;
    int threads;      /* 0 = OpenMP default */
    /* Progress, called from one thread at a time with the rows finished so far. */
    void (*progress)(void *user, int rows_done, int rows_total);
    void *progress_user;
} rt_render_opts;

/* Preview render: each pixel averages spp jittered primary rays; a hit shows
 * emission + diffuse * (0.15 + 0.85 |N.V|) (a "headlight" flat shade), a miss
 * shows the scene's background. img must be allocated at the view's size. */
rr_status rt_render_preview(const scene *s, const rt_render_opts *opts, rr_image *img, rr_error *err);

#endif
