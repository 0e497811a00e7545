/* rr_core.h - radray's core: what every other module builds on.
 *
 * Offers (each in its own small header, all included here):
 *   rr_math.h   rr_vec3, rr_rgb, rr_ray, rr_xform: by-value types, static inline ops
 *   rr_error.h  rr_status result codes, rr_error messages, rr_warn sinks, RR_CHECK
 *   rr_rng.h    PCG32 with independent streams (thread-count independent sampling)
 *   rr_image.h  rr_image: float linear RGB film
 *   rr_view.h   rr_view: the lecture's view (E, O, s, w, h, U) and look-at cameras
 *   rr_file.h   atomic output files, path helpers
 *   rr_clock.h  the monotonic wall clock
 *   rr_dist.h   rr_dist: work lists and reductions over several processes (MPI)
 *
 * Depends on nothing but libc and libm. No globals: nothing here keeps state
 * between calls.
 */
#ifndef RR_CORE_H
#define RR_CORE_H

#include "rr_clock.h"
#include "rr_dist.h"
#include "rr_error.h"
#include "rr_file.h"
#include "rr_image.h"
#include "rr_math.h"
#include "rr_rng.h"
#include "rr_view.h"

#endif
