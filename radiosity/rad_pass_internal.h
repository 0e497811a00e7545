/* rad_pass_internal.h - private to radiosity/: the one constructor of a
 * rad_solution, shared by the pass (rad_pass.c) and the cache (rad_cache.c). */
#ifndef RAD_PASS_INTERNAL_H
#define RAD_PASS_INTERNAL_H

#include "rad.h"

/* An empty solution for s with its rt_field set up; NULL when out of memory. */
rad_solution *rad__solution_new(const scene *s);

#endif
