/* test_hier_util.h - the radiosity pass as test_hier.c and
 * test_hier_cornell.c run it. */
#ifndef TEST_HIER_UTIL_H
#define TEST_HIER_UTIL_H

#include <string.h>

#include "rad.h"

/* The pass with the scene's choices (either method) and the given seed. */
static inline rad_solution *pass_seed(const scene *s, rt_accel **a, uint64_t seed)
{
    rr_error err;
    assert_int_equal(rt_accel_build(s, a, NULL), RR_OK);
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    po.ff.seed = seed;
    rad_solution *sol = NULL;
    if (rad_pass_run(s, *a, &po, &sol, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return sol;
}

/* The same with seed 0. */
static inline rad_solution *pass(const scene *s, rt_accel **a) { return pass_seed(s, a, 0); }

/* The pass, which must have been the hierarchical one. */
static inline rad_solution *run(const scene *s, rt_accel **a)
{
    rad_solution *sol = pass(s, a);
    assert_non_null(sol->P->roots);
    return sol;
}

#endif
