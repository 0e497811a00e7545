/* rad_pass_internal.h - private to radiosity/: the one constructor of a
 * rad_solution and its arrays, shared by the pass (rad_pass.c) and the cache
 * (rad_cache.c). */
#ifndef RAD_PASS_INTERNAL_H
#define RAD_PASS_INTERNAL_H

#include "rad.h"

/* Rough bytes per patch: the patch record, its radiosity, emission, first
 * shot and shared vertices (the estimates of rad_pass.c and rad_hier.c). */
#define RAD_PATCH_BYTES (sizeof(rad_patch) + 8.0 * sizeof(rr_rgb) + 2.0 * sizeof(rr_vec3))

/* An empty solution for s with its rt_field set up; NULL when out of memory. */
rad_solution *rad__solution_new(const scene *s);
/* Allocates sol's per-patch arrays (B, emitted, first_shot) and per-vertex
 * ones (vertex_B, vertex_Hind) for sol->P; 0, or -1 when out of memory (what
 * was allocated is freed by rad_solution_destroy). */
int rad__solution_arrays(rad_solution *sol);

/* The method the pass uses for s: o's (or the scene's), except that scenes
 * with mirrors take the flat one (said through warn, which may be NULL). */
rad_method rad__pass_method(const scene *s, const rad_pass_opts *o, const rr_warn_sink *warn);

/* H0, the first shot of point and directional lights, on triangle corner[] of
 * patch k of P (rad_pass.c); see there for landed, weight and spread. */
rr_rgb rad__first_shot(const scene *s, const rt_accel *a, const rt_lights *L, const rad_patches *P, uint32_t k,
                       const rr_vec3 corner[3], rr_rgb *landed, double weight, double *spread);
/* Fills sol->emitted, first_shot and light_landed for the patches sol->P and
 * adds rho H0 to each patch's emission (deterministic for any thread count). */
rr_status rad__first_shots(const scene *s, const rt_accel *a, rad_solution *sol, rr_error *err);

#endif
