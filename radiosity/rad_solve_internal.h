/* rad_solve_internal.h - checks shared by the solver (rad_solve.c) and the
 * energy ledger (rad_energy.c). Not part of the public API (rad.h). */
#ifndef RAD_SOLVE_INTERNAL_H
#define RAD_SOLVE_INTERNAL_H

#include "rad.h"

/* Checks that F is a well-formed CSR matrix for P: same n, rowptr starting at
 * 0 and non-decreasing, columns < n, values finite and >= 0; and that every
 * patch has a finite positive area and finite, non-negative emission and
 * reflectance. The reflectance < 1 rule is rad_solve's (the ledger accepts any
 * solved system). Fails with RR_ERR_INVALID naming the first offending row. */
rr_status rad_system_check(const rad_patches *P, const rad_ff *F, rr_error *err);

/* Every patch's reflectance below 1 in every channel (unless allowed, for
 * tests): the radiosity pass has no physical solution otherwise. Both
 * methods check it before any work (rad_solve; rad_hier.c on its roots).
 * Fails with RR_ERR_INVALID naming the first patch, its object and channel. */
rr_status rad_reflectance_check(const rad_patches *P, int allow_rho_ge_1, rr_error *err);

/* Component c (0 = R, 1 = G, 2 = B) of a colour, and its letter. */
static inline double rad_rgb_get(rr_rgb v, int c) { return c == 0 ? v.r : (c == 1 ? v.g : v.b); }
static inline char rad_channel_name(int c) { return "RGB"[c]; }

#endif
