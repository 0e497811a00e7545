/* ig.h - the integrators: one row per rendering mode, one entry point.
 *
 * An integrator is what turns the scene into an image (pbrt's Integrator,
 * as a table). Every row says what it counts, so that no light is counted
 * twice or dropped:
 *   - hybrid     emission, direct light with shadow rays, Phong, mirrors (the
 *                ray tracer) + diffuse interreflection from the radiosity pass
 *                (its indirect part only, rt_field.indirect)
 *   - whitted    the same with the lecture's ambient term a*A*rho instead
 *   - secondary  the same with Monte Carlo secondary rays instead (the
 *                unbiased reference)
 *   - radiosity  the radiosity solution itself (B/pi, emission and direct
 *                light included), Gouraud-shaded, and what mirrors show of it
 *   - direct     the ray tracer's emission and direct light only
 * The rows are data (ig.c); ig_render is the one entry point that `render`,
 * `compare`, the energy check and the tests call. The radiosity pass runs at
 * most once per session (ig_session_field) and reaches the ray tracer only as
 * its rt_field.
 *
 * Adding an integrator: a row in ig.c; when it needs a new kind of indirect
 * term, that term in rt.h (rt_indirect) and rt_render.c (shade_surface).
 *
 * Module: integrator (prefix ig_), above radiosity, below app.
 */
#ifndef IG_H
#define IG_H

#include <signal.h>
#include <stddef.h>

#include "rad.h"
#include "rt.h"
#include "scene.h"

typedef struct ig_integrator {
    const char *name;     /* its --mode name */
    const char *summary;  /* one line: what the image shows */
    rt_indirect indirect; /* the ray tracer's diffuse-interreflection term */
    int shows_field;      /* the image is the radiosity solution (the display) */
    int uses_field;       /* needs the radiosity pass (run only when the scene emits) */
    unsigned layers;      /* film layers it can write (1u << RT_LAYER_*); the others stay 0 */
    int in_figures;       /* among `compare`'s panels when --modes is not given */
} ig_integrator;

/* The rows, in the order `compare` shows them; ig_count() of them. */
extern const ig_integrator ig_table[];
size_t ig_count(void);
/* The row named name, or NULL. */
const ig_integrator *ig_find(const char *name);
/* The ray-traced row whose indirect term is k (ambient: whitted, secondary,
 * radiosity: hybrid, none: direct): what `--indirect K` selects. */
const ig_integrator *ig_with_indirect(rt_indirect k);
/* The names joined for a message: "hybrid, whitted, ... or direct". */
const char *ig_names(char *buf, size_t n);
/* The default mode (hybrid). */
const ig_integrator *ig_default(void);

/* Whether ig runs the radiosity pass on sc: it uses the field and sc has
 * something that emits (rt_scene_emits; the display runs it regardless). */
int ig_uses_pass(const ig_integrator *ig, const scene *sc);

/* One scene, its BVH and the radiosity pass, shared by every render of it. */
typedef struct ig_session {
    const scene *sc;      /* not owned; its settings give spp, seed, threads, max_depth, light_samples */
    const rt_accel *accel; /* built over sc, not owned */
    rad_pass_opts pass;   /* the radiosity pass's options (ig_session_init: the scene's choices) */
    const char *cache_path; /* reuse or save the solution there (--radiosity-cache); NULL: none */
    const volatile sig_atomic_t *interrupt; /* checked by the pass and the renders; NULL: none */
    rad_solution *sol;    /* made by the first render that needs it, or by ig_session_field */
    int sol_cached;       /* sol was read from cache_path */
    double seconds_pass;  /* wall time of the pass (or of reading the cache) */
    rr_dist *dist;        /* several processes share the pass and the renders (rr_dist.h); NULL: one */
} ig_session;

/* A session over sc and a (both must outlive it): the pass takes the scene's
 * radiosity choices, seed and threads; no cache, no interrupt. */
void ig_session_init(ig_session *s, const scene *sc, const rt_accel *a);
/* Frees the solution (NULL and a second call are harmless). */
void ig_session_free(ig_session *s);
/* Runs the radiosity pass (or reads the cache) once; a no-op when done.
 * Interrupts stop its form factors within a row (RR_ERR_INTERRUPTED). */
rr_status ig_session_field(ig_session *s, rr_error *err);

typedef struct ig_render_opts {
    rt_filter filter; /* box (the default) or tent */
    /* Progress of the ray-tracing pass in tiles (rt_render_opts.progress). */
    void (*progress)(void *user, int done, int total);
    void *progress_user;
    rt_ray_counts *rays; /* when set: the rays the render traced */
} ig_render_opts;

/* Renders ig into film (sized to the view), with the scene's render
 * settings; runs the radiosity pass first when ig_uses_pass says so. A
 * field-using ray-traced row on a scene where nothing emits renders with no
 * indirect term (there is no interreflection to compute). o may be NULL.
 * *seconds (may be NULL) = wall time, the pass included when this call ran it. */
rr_status ig_render(ig_session *s, const ig_integrator *ig, const ig_render_opts *o, rt_film *film,
                    double *seconds, rr_error *err);

#endif
