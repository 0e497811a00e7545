/* pipeline.c - what every rendering subcommand shares: the modes (presets of
 * the indirect term), the radiosity pass run at most once per scene, and one
 * render of one mode into a film. */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "app.h"

const char *const app_mode_names[] = {"whitted", "secondary", "radiosity", "hybrid", NULL};
const char *const app_indirect_names[] = {"none", "ambient", "secondary", "radiosity", NULL};

int app_pick(const char *name, const char *const *names)
{
    for (int i = 0; names[i]; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

static double now_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static rr_rgb radiosity_hook(void *user, const rt_hit *hit)
{
    const app_pipeline *p = user;
    return rad_radiance_at(p->sol, p->sc, hit);
}

static rr_rgb indirect_hook(void *user, const rt_hit *hit, rr_rgb rho)
{
    const app_pipeline *p = user;
    return rad_indirect_at(p->sol, p->sc, hit, rho);
}

rt_indirect app_mode_indirect(int mode, int indirect_override)
{
    static const rt_indirect preset[APP_MODE_COUNT] = {RT_INDIRECT_AMBIENT, RT_INDIRECT_SECONDARY, RT_INDIRECT_NONE,
                                                       RT_INDIRECT_RADIOSITY};
    return indirect_override >= 0 ? (rt_indirect)indirect_override : preset[mode];
}

static int scene_emits(const scene *sc)
{
    if (sc->nlights > 0 || sc->nemissive > 0)
        return 1;
    for (size_t i = 0; i < sc->nobjects; i++)
        if (rr_rgb_max(sc->materials[sc->objects[i].material].emission) > 0)
            return 1;
    return 0;
}

rr_status app_pipeline_radiosity(app_pipeline *p, rr_error *err)
{
    if (p->sol)
        return RR_OK;
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    po.ff.seed = p->sc->settings.seed;
    po.ff.threads = p->sc->settings.threads;
    int cached = 0;
    rr_status st = rad_pass_run_cached(p->sc, p->accel, &po, p->cache_path, &cached, &p->sol, err);
    if (st != RR_OK)
        return st;
    if (cached && !p->quiet)
        fprintf(stderr, "radiosity: %zu patches, solution read from %s\n", p->sol->P->n, p->cache_path);
    else if (!p->quiet)
        fprintf(stderr,
                "radiosity: %zu patches, %zu form factors (%.2f s), %s solver %d iteration(s), residual %.2g (%.2f s)\n",
                p->sol->P->n, p->sol->nnz, p->sol->seconds_ff,
                p->sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative", p->sol->stats.iterations,
                p->sol->stats.residual, p->sol->seconds_solve);
    return RR_OK;
}

rr_status app_render_mode(app_pipeline *p, int mode, int indirect_override, int filter, rt_film *film,
                          double *seconds, void (*progress)(void *, int, int), void *progress_user, rr_error *err)
{
    const scene *sc = p->sc;
    double t0 = now_seconds();
    rt_render_opts ro;
    memset(&ro, 0, sizeof ro);
    ro.spp = sc->settings.spp;
    ro.seed = sc->settings.seed;
    ro.threads = sc->settings.threads;
    ro.max_depth = sc->settings.max_depth;
    ro.light_samples = sc->settings.light_samples;
    ro.indirect = app_mode_indirect(mode, indirect_override);
    ro.filter = (rt_filter)filter;
    ro.progress = progress;
    ro.progress_user = progress_user;
    int need = mode == APP_MODE_RADIOSITY || ro.indirect == RT_INDIRECT_RADIOSITY;
    if (need && mode != APP_MODE_RADIOSITY && !scene_emits(sc)) {
        /* Nothing emits: there is no interreflection to compute. */
        need = 0;
        ro.indirect = RT_INDIRECT_NONE;
    }
    if (need) {
        rr_status st = app_pipeline_radiosity(p, err);
        if (st != RR_OK)
            return st;
        if (mode == APP_MODE_RADIOSITY)
            ro.radiosity = radiosity_hook;
        ro.radiosity_indirect = indirect_hook;
        ro.radiosity_user = p;
    }
    rr_status st = rt_render(sc, p->accel, &ro, film, err);
    if (seconds)
        *seconds = now_seconds() - t0;
    return st;
}
