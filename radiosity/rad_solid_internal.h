/* rad_solid_internal.h - private to rad_solid.c and rad_solid_own.c: a
 * solid's tessellation in progress, and what the two files share. */
#ifndef RAD_SOLID_INTERNAL_H
#define RAD_SOLID_INTERNAL_H

#include "rad_patch_internal.h"

typedef struct rad__tess {
    const scene *s;
    const rt_accel *a;
    uint32_t root;
    rr_vec3 lo, cell;
    uint32_t n[3];
    unsigned char *inside; /* (n+1)^3 grid points */
    rad__edge_map map;
    rad__solid_mesh *out;
    size_t cap_v, cap_t;
    int meshes;        /* the solid has mesh leaves */
    int all_own;       /* every leaf has a parametric form (leaf_parametric): no marching tetrahedra */
    /* The surfaces of the solid's other leaves, a group each (area_scales). */
    uint32_t *slot;    /* per node of scene->csg: UINT32_MAX, or the leaf's group */
    uint32_t ngroups;
    uint32_t *vgroup;  /* per vertex: the group of the leaf it lies on, VG_MESH, VG_NONE */
    size_t cap_g;
} rad__tess;

#define VG_MESH (UINT32_MAX - 1) /* on a mesh leaf's surface */
#define VG_NONE UINT32_MAX       /* not found */
#define VG_SEAM 0x40000000u      /* (triangles) group | VG_SEAM: a corner on a mesh leaf too */
#define VG_FACE 0x20000000u      /* (triangles) group | VG_FACE: a piece of a flat face of the leaf */

/* Grows *p (elem bytes each, *cap of them) to hold need. 0, or -1 when out
 * of memory. */
int rad__solid_grow(void **p, size_t *cap, size_t need, size_t elem);
/* The boundary of object obj's solid nearest to x along the line x + t n,
 * |t| < r: 1 and *end, or 0 when there is none. */
int rad__solid_nearest_end(const scene *s, const rt_accel *a, uint32_t obj, rr_vec3 x, rr_vec3 n, double r,
                           rt_span_end *end);
/* The level a mesh leaf's triangle ABC is split to (L x L) under limits o. */
uint32_t rad__solid_mesh_level(rr_vec3 A, rr_vec3 B, rr_vec3 C, const rad_patch_opts *o);
/* Whether leaf nd has a parametric form (rad_solid_own.c; a general quadric
 * has not). */
int rad__solid_leaf_parametric(const scene_csg_node *nd);
/* Replaces the marching triangles on mesh leaves (the first ntris of
 * T->out, cell by cell, their groups in *tgroup) by the leaves' own pieces
 * (every leaf's when T->all_own, else the mesh leaves'), and sorts all into
 * the grid's cells again, *tgroup with them; T->out->leaf gets each
 * triangle's leaf. 0, or -1 when out of memory. */
int rad__solid_own_triangles(rad__tess *T, const rad_patch_opts *o, uint32_t **tgroup);

/* About how many patches rad__solid_own_triangles makes of object obj's
 * solid when every leaf has a parametric form (the pieces of every leaf's
 * surfaces at the limits, counted where own_piece's four sample points lie
 * on the final surface, a piece that a rim crosses as the pieces its splits
 * make, about), cells hmin wide; -1 when a leaf has no parametric form. */
double rad__solid_own_estimate(const scene *s, const rt_accel *a, uint32_t obj, double hmin, const rad_patch_opts *o);
#endif
