/* test_world.h - a scene, its BVH and an integrator session, rendered as
 * `radray render` renders (header-only; for the tests that compare modes:
 * test_transport.c, test_import.c). Include after cmocka.h. */
#ifndef TEST_WORLD_H
#define TEST_WORLD_H

#include <string.h>

#include "ig.h"

typedef struct world {
    scene *s;
    rt_accel *a;
    ig_session ses; /* the radiosity pass, shared by the renders of one world */
} world;

/* Takes s (freed by world_free); form-factor seed 3. */
static inline void world_open(world *w, scene *s)
{
    memset(w, 0, sizeof *w);
    w->s = s;
    assert_int_equal(rt_accel_build(s, &w->a, NULL), RR_OK);
    ig_session_init(&w->ses, s, w->a);
    w->ses.pass.ff.seed = 3;
}

static inline void world_free(world *w)
{
    ig_session_free(&w->ses);
    rt_accel_destroy(w->a);
    scene_destroy(w->s);
}

/* One render by integrator ig at spp, seed 7, into a new film. */
static inline void world_render(world *w, const ig_integrator *ig, int spp, rt_film *film)
{
    w->s->settings.spp = spp;
    w->s->settings.seed = 7;
    assert_int_equal(rt_film_init(film, w->s->view.width, w->s->view.height, NULL), RR_OK);
    rr_error err;
    if (ig_render(&w->ses, ig, NULL, film, NULL, &err) != RR_OK)
        fail_msg("%s", err.msg);
}

#endif
