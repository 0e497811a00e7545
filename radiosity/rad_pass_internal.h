/* rad_pass_internal.h - private to radiosity/: the one constructor of a
 * rad_solution and its arrays, shared by the pass (rad_pass.c) and the cache
 * (rad_cache.c). */
#ifndef RAD_PASS_INTERNAL_H
#define RAD_PASS_INTERNAL_H

#include "rad.h"

/* An empty solution for s with its rt_field set up; NULL when out of memory. */
rad_solution *rad__solution_new(const scene *s);
/* Allocates sol's per-patch arrays (B, emitted, first_shot) and per-vertex
 * ones (vertex_B, vertex_Hind) for sol->P; 0, or -1 when out of memory (what
 * was allocated is freed by rad_solution_destroy). */
int rad__solution_arrays(rad_solution *sol);

#endif
