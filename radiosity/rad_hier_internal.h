/* rad_hier_internal.h - private to radiosity/: the leaves of a hierarchical
 * solution as a patch set (rad_leaves.c), made by the solver (rad_hier.c) from
 * the tree's split bits, so that a tree can also be stored as bits and built
 * again; the solver's entry point for the pass (rad_pass.c). */
#ifndef RAD_HIER_INTERNAL_H
#define RAD_HIER_INTERNAL_H

#include "rad.h"

/* The quadtree as split bits, breadth first: the roots in order, then the
 * children of every split node in the order they were reached; 1 = the node
 * has four children (corner A, B, C, middle, in that order), 0 = leaf. Leaves
 * are numbered in the same order. */
typedef struct rad_split_bits {
    uint8_t *bit; /* one byte per node (0 or 1) */
    size_t n;
} rad_split_bits;

/* The patch set of the leaves of roots split as bits says (rad.h,
 * rad_patches.roots): takes ownership of roots (also on failure). RR_ERR_INVALID
 * when bits does not describe a tree over roots. */
rr_status rad__hier_leaves(rad_patches *roots, const rad_split_bits *bits, rad_patches **out, rr_error *err);

/* The split bits of a hierarchical patch set (for the cache); -1 when out of memory. */
int rad__hier_bits(const rad_patches *P, rad_split_bits *bits);

/* Per-vertex values from per-patch ones: the area-weighted mean of the patches
 * around each vertex, then `sweeps` sweeps of back-projection (each patch's
 * value less the mean of its vertex values, added back to its vertices,
 * area-weighted, clamped at 0), which bring the Gouraud-shaded surface's mean
 * over each patch towards the patch's value (RAD_HIND_SWEEPS); in a
 * hierarchical set, a vertex in the middle of a leaf's edge (a T-vertex) then
 * takes the value interpolated along that edge, so that the Gouraud-shaded
 * surface has no cracks. */
rr_status rad__to_vertices(const rad_patches *P, const rr_rgb *per_patch, int sweeps, rr_rgb *per_vertex);

/* The roots' patch limits for s given o: the scene's primitives at 16 times
 * the flat method's patch area (and 4 times its edge). */
rad_patch_opts rad__hier_root_limits(const scene *s, const rad_pass_opts *o);

/* The smallest element area the hierarchical pass splits to for s given o. */
double rad__hier_min_area(const scene *s, const rad_pass_opts *o);

/* The bytes a hierarchical pass holds with that many links, elements and
 * clusters: the links, each element with its source value and receiver
 * group and (at the output, beside them) its share of the leaves' patch set,
 * about 3 of 4 elements being leaves, and the clusters. The pass stops
 * refining where this reaches rad_hier_opts.max_bytes; the process's peak
 * is about this over what it held before the pass (realloc grows the large
 * arrays by remapping: pages never written are not resident). */
double rad__hier_bytes(double links, double elements, double clusters);

/* The hierarchical pass (rad_hier.c): fills sol (P, B, emitted, first_shot,
 * light_landed, vertex_B, vertex_Hind, hier_H, hier_fsum, stats) for scene s. */
struct rad_solution;
rr_status rad__hier_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, struct rad_solution *sol,
                        rr_error *err);

#endif
