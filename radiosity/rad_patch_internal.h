/* rad_patch_internal.h - private to radiosity/: the shared-vertex map (used by
 * rad_patch.c and by the hierarchical leaves, rad_leaves.c) and the solids'
 * tessellation (rad_solid.c) used by rad_patch.c. */
#ifndef RAD_PATCH_INTERNAL_H
#define RAD_PATCH_INTERNAL_H

#include "rad.h"

/* Open-addressing map (a, b, k) -> vertex index, growing as it fills. */
typedef struct rad__edge_map {
    uint64_t *key; /* 0 = empty */
    uint32_t (*abk)[3];
    uint32_t *val;
    size_t cap, count;
} rad__edge_map;

/* Room for about n entries before it first grows. Returns 0, or -1 when out of memory. */
int rad__edge_map_init(rad__edge_map *m, size_t n);
void rad__edge_map_free(rad__edge_map *m);
/* The value stored for (a, b, k); stores val when there is none and returns
 * it. UINT32_MAX when out of memory. */
uint32_t rad__edge_get(rad__edge_map *m, uint32_t a, uint32_t b, uint32_t k, uint32_t val);
/* The value stored for (a, b, k), or UINT32_MAX when there is none. */
uint32_t rad__edge_find(const rad__edge_map *m, uint32_t a, uint32_t b, uint32_t k);

/* A solid's tessellation before it is copied into the patches: vertices,
 * outward counter-clockwise triangles (marching triangles, and the mesh
 * leaves' own), and the grid (cell_first relative to the first triangle). */
typedef struct rad__solid_mesh {
    rr_vec3 *verts;
    size_t nverts;
    uint32_t (*tris)[3];
    size_t ntris;
    rad_solid_grid grid;
    unsigned char *own; /* per triangle, 1: a piece of a mesh leaf's own triangle (NULL: none is) */
    double *scale;      /* per triangle: the true area it stands for over its own (rad_solid.c) */
    uint32_t *leaf;     /* per triangle: the leaf (scene->csg) it is a piece of, UINT32_MAX for a
                           marching triangle (NULL: all are) */
} rad__solid_mesh;

rr_status rad__solid_tessellate(const scene *s, const rt_accel *a, uint32_t obj, const rad_patch_opts *o,
                                rad__solid_mesh *out, rr_error *err);
void rad__solid_mesh_free(rad__solid_mesh *m);

/* Nearest patch of solid obj to p (UINT32_MAX when it has none). */
uint32_t rad__solid_locate(const rad_patches *P, uint32_t obj, rr_vec3 p);

/* Moves x, a point on a facet of solid obj with facet normal n, onto the
 * solid's surface along n; *ns the outward surface normal there (or n), *leaf
 * the leaf whose surface it is. Returns 0 (and x, n) when no surface is
 * within two cells. leaf may be NULL. */
int rad__solid_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t obj, rr_vec3 x, rr_vec3 n,
                       rr_vec3 *xs, rr_vec3 *ns, uint32_t *leaf);

#endif
