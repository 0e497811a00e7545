/* ig.c - the integrator table and its one entry point (ig.h). */
#include <stdio.h>
#include <string.h>

#include "ig.h"
#include "rr_clock.h"

#define L(x) (1u << RT_LAYER_##x)

/* What each row writes: every ray-traced row sees emitters (and the
 * background) and mirrors; the display sees the background as emission. */
const ig_integrator ig_table[] = {
    {"whitted", "the lecture's ray tracer: direct light, Phong, mirrors and the ambient term a*A*rho",
     RT_INDIRECT_AMBIENT, 0, 0, L(EMISSION) | L(AMBIENT) | L(DIFFUSE) | L(SPECULAR) | L(MIRROR), 1},
    {"secondary", "the ray tracer with Monte Carlo secondary rays for the interreflection (the reference)",
     RT_INDIRECT_SECONDARY, 0, 0, L(EMISSION) | L(DIFFUSE) | L(SPECULAR) | L(MIRROR) | L(INDIRECT), 1},
    {"radiosity", "the radiosity solution alone, Gouraud-shaded, and what mirrors show of it", RT_INDIRECT_NONE, 1,
     1, L(EMISSION) | L(MIRROR) | L(RADIOSITY), 1},
    {"hybrid", "the ray tracer with the radiosity pass's interreflection (the two-pass method)",
     RT_INDIRECT_RADIOSITY, 0, 1, L(EMISSION) | L(DIFFUSE) | L(SPECULAR) | L(MIRROR) | L(INDIRECT), 1},
    {"direct", "the ray tracer's emission and direct light only, no interreflection", RT_INDIRECT_NONE, 0, 0,
     L(EMISSION) | L(DIFFUSE) | L(SPECULAR) | L(MIRROR), 0},
};

#undef L

size_t ig_count(void) { return sizeof ig_table / sizeof ig_table[0]; }

const ig_integrator *ig_find(const char *name)
{
    for (size_t i = 0; name && i < ig_count(); i++)
        if (!strcmp(name, ig_table[i].name))
            return &ig_table[i];
    return NULL;
}

const ig_integrator *ig_with_indirect(rt_indirect k)
{
    for (size_t i = 0; i < ig_count(); i++)
        if (!ig_table[i].shows_field && ig_table[i].indirect == k)
            return &ig_table[i];
    return NULL;
}

const ig_integrator *ig_default(void) { return ig_find("hybrid"); }

const char *ig_names(char *buf, size_t n)
{
    size_t k = 0, count = ig_count();
    buf[0] = '\0';
    for (size_t i = 0; i < count && k < n; i++)
        k += (size_t)snprintf(buf + k, n - k, "%s%s", i == 0 ? "" : i + 1 == count ? " or " : ", ",
                              ig_table[i].name);
    return buf;
}

int ig_uses_pass(const ig_integrator *ig, const scene *sc)
{
    return ig->shows_field || (ig->uses_field && rt_scene_emits(sc));
}

void ig_session_init(ig_session *s, const scene *sc, const rt_accel *a)
{
    memset(s, 0, sizeof *s);
    s->sc = sc;
    s->accel = a;
    s->pass.use_scene_choices = 1;
    s->pass.ff.seed = sc->settings.seed;
    s->pass.ff.threads = sc->settings.threads;
}

void ig_session_free(ig_session *s)
{
    if (!s)
        return;
    rad_solution_destroy(s->sol);
    s->sol = NULL;
}

rr_status ig_session_field(ig_session *s, rr_error *err)
{
    if (s->sol)
        return RR_OK;
    double t0 = rr_now_seconds();
    rad_pass_opts po = s->pass;
    if (!po.ff.interrupt)
        po.ff.interrupt = s->interrupt;
    po.ff.dist = s->dist;
    rr_status st = rad_pass_run_cached(s->sc, s->accel, &po, s->cache_path, &s->sol_cached, &s->sol, err);
    s->seconds_pass = rr_now_seconds() - t0;
    return st;
}

rr_status ig_render(ig_session *s, const ig_integrator *ig, const ig_render_opts *o, rt_film *film,
                    double *seconds, rr_error *err)
{
    const scene *sc = s->sc;
    double t0 = rr_now_seconds();
    rt_render_opts ro;
    memset(&ro, 0, sizeof ro);
    ro.spp = sc->settings.spp;
    ro.seed = sc->settings.seed;
    ro.threads = sc->settings.threads;
    ro.max_depth = sc->settings.max_depth;
    ro.light_samples = sc->settings.light_samples;
    ro.indirect = ig->indirect;
    ro.show_field = ig->shows_field;
    ro.interrupt = s->interrupt;
    ro.dist = s->dist;
    if (o) {
        ro.filter = o->filter;
        ro.progress = o->progress;
        ro.progress_user = o->progress_user;
        ro.rays = o->rays;
    }
    if (ig_uses_pass(ig, sc)) {
        rr_status st = ig_session_field(s, err);
        if (st != RR_OK)
            return st;
        ro.field = rad_solution_field(s->sol);
    } else if (ro.indirect == RT_INDIRECT_RADIOSITY) {
        ro.indirect = RT_INDIRECT_NONE; /* nothing emits: there is no interreflection to compute */
    }
    rr_status st = rt_render(sc, s->accel, &ro, film, err);
    if (seconds)
        *seconds = rr_now_seconds() - t0;
    return st;
}
