/* rt_internal.h - private to raytrace/: BVH layout and the shared kernels. */
#ifndef RT_INTERNAL_H
#define RT_INTERNAL_H

#include "rt.h"

/* Build depth limit = traversal stack size. */
#define RT_BVH_STACK 64

typedef enum rt_prim_kind { RT_PRIM_TRIANGLE = 0, RT_PRIM_SPHERE = 1, RT_PRIM_SOLID = 2 } rt_prim_kind;

/* A primitive: its kind and its index in the scene (triangle index, or object
 * index for spheres and solids). */
typedef struct rt_prim {
    uint32_t kind;
    uint32_t index;
} rt_prim;

/* 32 bytes. Inner node (count == 0): left child is the next node, right child
 * is nodes[index]; leaf: prims[index .. index + count). */
typedef struct rt_node {
    float lo[3], hi[3];
    uint32_t index;
    uint16_t count;
    uint16_t axis;
} rt_node;

struct rt_accel {
    const scene *scene;
    rt_node *nodes;
    size_t nnodes;
    rt_prim *prims;
    size_t nprims;
    struct rt_solid_accel *solids; /* per-mesh-leaf BVHs of the scene's solids (rt_solid.c); NULL if none */
};

/* Per-ray constants of the watertight test (Woop et al. 2013) and the slab test. */
typedef struct rt_ray_pre {
    rr_ray ray;
    int kx, ky, kz;
    double Sx, Sy, Sz;
    double inv[3];
    int neg[3];
} rt_ray_pre;

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p);

/* Watertight ray/triangle test. Returns 1 with *t and *front (1 when the ray
 * meets the counter-clockwise side) for a hit with tmin < t < tmax. cull: reject
 * back faces. */
int rt__tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax, double *t,
                int *front);

/* ---- rt_solid.c: acceleration for the solids' mesh leaves ---- */
rr_status rt__solids_build(const scene *s, struct rt_solid_accel **out, rr_error *err);
void rt__solids_destroy(struct rt_solid_accel *sa); /* NULL is a no-op */

/* ---- rt_prim.c: the primitive interface the BVH is built on ---- */

/* How many primitives the scene has, and the list of them (out has that many). */
size_t rt__prim_count(const scene *s);
void rt__prim_list(const scene *s, rt_prim *out);
/* World-space bounds of one primitive (containing it exactly). */
void rt__prim_bounds(const scene *s, rt_prim p, rr_vec3 *lo, rr_vec3 *hi);
/* Intersects one primitive; on a hit with tmin < t < *tmax fills hit (when not
 * NULL; hit->point is left to the caller) and lowers *tmax. */
int rt__prim_hit(const rt_accel *a, rt_prim pr, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit);

#endif
