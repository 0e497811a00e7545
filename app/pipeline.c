/* pipeline.c - what every rendering subcommand shares around the integrator
 * table (integrator/ig.h): signals, progress lines, the radiosity pass's
 * options and summary, resource limits. */
#include <ctype.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>

#include "app.h"

const char *const app_indirect_names[] = {"none", "ambient", "secondary", "radiosity", NULL};

int app_pick(const char *name, const char *const *names)
{
    for (int i = 0; names[i]; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

const char *app_option_key(const char *option)
{
    static const char *const keys[][2] = {
        {"spp", "render.spp"},           {"seed", "render.seed"},
        {"threads", "render.threads"},   {"exposure", "render.exposure"},
        {"half", "render.half_float"},   {"patch-area", "radiosity.patch_area"},
        {"patch-edge", "radiosity.patch_edge"}, {"solver", "radiosity.solver"},
        {"ff", "radiosity.form_factors"}, {"ff-samples", "radiosity.ff_samples"},
    };
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        if (!strcmp(option, keys[i][0]))
            return keys[i][1];
    return NULL;
}

/* Options that choose how the flat method computes and solves (--solver,
 * --ff, --ff-samples, or --set of their keys), given for a scene that takes
 * the hierarchical one: said once, since they change nothing there. */
static void warn_flat_only(const scene *s, const scene_load_opts *lo)
{
    static const char *const flat_keys[] = {"radiosity.solver", "radiosity.form_factors", "radiosity.ff_samples"};
    if (s->radiosity.method != SCENE_RAD_HIERARCHICAL)
        return;
    for (size_t i = 0; i < lo->noverrides; i++)
        for (size_t k = 0; k < sizeof flat_keys / sizeof flat_keys[0]; k++) {
            size_t n = strlen(flat_keys[k]);
            if (!strncmp(lo->overrides[i], flat_keys[k], n) && lo->overrides[i][n] == '=') {
                rr_warn(&lo->warn,
                        "%s: %s applies to the flat radiosity method; this scene takes the hierarchical one (the "
                        "default), which it does not change: add --set radiosity.method=flat",
                        s->path, flat_keys[k]);
                return;
            }
        }
}

rr_status app_scene_load(const char *path, const scene_load_opts *lo, scene **out, rr_error *err)
{
    rr_status st = scene_load(path, lo, out, err);
    if (st == RR_OK)
        warn_flat_only(*out, lo);
    if (st == RR_OK || !err)
        return st;
    /* A message "<path>: <key>..." about a key an override set is about the
     * command line, not the file: say so, and which override it was. */
    size_t np = strlen(path);
    if (strncmp(err->msg, path, np) != 0 || strncmp(err->msg + np, ": ", 2) != 0)
        return st;
    const char *where = err->msg + np + 2;
    for (size_t i = 0; i < lo->noverrides; i++) {
        const char *ov = lo->overrides[i], *eq = strchr(ov, '=');
        size_t nk = eq ? (size_t)(eq - ov) : strlen(ov);
        char c = where[nk];
        if (strncmp(where, ov, nk) != 0 || (c != ':' && c != '[' && c != '.'))
            continue;
        char msg[sizeof err->msg];
        snprintf(msg, sizeof msg, "the command line (%s, from --set or an option): %s", ov, where);
        snprintf(err->msg, sizeof err->msg, "%s", msg);
        break;
    }
    return st;
}

int app_ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

volatile sig_atomic_t app_stop;

static void on_stop(int sig) { app_stop = sig; }

void app_signals_catch(app_signals *saved)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND; /* a second signal ends the process the default way */
    app_stop = 0;
    saved->have_int = sigaction(SIGINT, &sa, &saved->old_int) == 0;
    saved->have_term = sigaction(SIGTERM, &sa, &saved->old_term) == 0;
}

void app_signals_restore(const app_signals *saved)
{
    if (saved->have_int)
        sigaction(SIGINT, &saved->old_int, NULL);
    if (saved->have_term)
        sigaction(SIGTERM, &saved->old_term, NULL);
}

void app_pass_progress(void *user, size_t done, size_t total)
{
    app_progress *p = user;
    int pct = (int)(100.0 * (double)done / (double)total);
    if (!p->enabled || (pct == p->last && done != total))
        return;
    p->last = pct;
    double t = rr_now_seconds() - p->t0, left = done > 0 ? t * ((double)total / (double)done - 1.0) : 0.0;
    fprintf(stderr, "\r%s %3d%% %6.1f s, %5.1f s left", p->what, pct, t, left);
    if (done == total)
        fputs("\r\033[K", stderr); /* the summary line follows */
    fflush(stderr);
}

void app_radiosity_opts(const scene *sc, const volatile sig_atomic_t *interrupt, app_progress *prog,
                        rad_pass_opts *po)
{
    memset(po, 0, sizeof *po);
    po->use_scene_choices = 1;
    po->warn = app_warn_sink();
    po->ff.seed = sc->settings.seed;
    po->ff.threads = sc->settings.threads;
    po->ff.interrupt = interrupt;
    if (prog && prog->enabled) {
        po->ff.progress = app_pass_progress;
        po->ff.progress_user = prog;
    }
}

void app_session_init(ig_session *s, const scene *sc, const rt_accel *a, const char *cache_path)
{
    ig_session_init(s, sc, a);
    app_radiosity_opts(sc, &app_stop, NULL, &s->pass);
    s->interrupt = &app_stop;
    s->cache_path = cache_path;
}

rr_status app_session_field(ig_session *s, int quiet, rr_error *err)
{
    if (s->sol)
        return RR_OK;
    app_progress prog = {!quiet && isatty(STDERR_FILENO), -1, rr_now_seconds(), "radiosity: form factors"};
    if (prog.enabled) {
        s->pass.ff.progress = app_pass_progress;
        s->pass.ff.progress_user = &prog;
    }
    rr_status st = ig_session_field(s, err);
    s->pass.ff.progress = NULL; /* prog ends here */
    s->pass.ff.progress_user = NULL;
    if (st != RR_OK)
        return st;
    const rad_solution *sol = s->sol;
    if (quiet)
        return RR_OK;
    if (s->sol_cached) {
        fprintf(stderr, "radiosity: %zu patches, solution read from %s\n", sol->P->n, s->cache_path);
    } else if (sol->links) {
        fprintf(stderr,
                "radiosity: %zu leaves, %zu links (hierarchical, %d rounds; refinement %.2f s), Jacobi %d sweep(s) in "
                "the last solve, residual %.2g (solves %.2f s)\n",
                sol->P->n, sol->links, sol->refine_rounds, sol->seconds_ff, sol->stats.iterations, sol->stats.residual,
                sol->seconds_solve);
        if (sol->receiving_clusters)
            fprintf(stderr, "radiosity: %zu receiving leaf clusters took their small surfaces' links as one "
                            "(radiosity.receiving_clusters)\n",
                    sol->receiving_clusters);
    } else {
        fprintf(stderr,
                "radiosity: %zu patches, %zu form factors (%.2f s), %s solver %d iteration(s), residual %.2g (%.2f s)\n",
                sol->P->n, sol->nnz, sol->seconds_ff, sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative",
                sol->stats.iterations, sol->stats.residual, sol->seconds_solve);
    }
    return RR_OK;
}

/* ---- resource limits ---- */

size_t app_default_max_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || psize <= 0)
        return SIZE_MAX;
    double half = (double)pages * (double)psize / 2.0;
    return half >= (double)SIZE_MAX ? SIZE_MAX : (size_t)half;
}

int app_parse_size(const char *s, size_t *out)
{
    if (!s || !isdigit((unsigned char)s[0]))
        return -1;
    char *end;
    double v = strtod(s, &end);
    double mult = 1.0;
    switch (toupper((unsigned char)*end)) {
    case 'K': mult = 1024.0; end++; break;
    case 'M': mult = 1024.0 * 1024.0; end++; break;
    case 'G': mult = 1024.0 * 1024.0 * 1024.0; end++; break;
    case 'T': mult = 1024.0 * 1024.0 * 1024.0 * 1024.0; end++; break;
    default: break;
    }
    if (mult > 1.0 && (end[0] == 'i' || end[0] == 'I') && (end[1] == 'B' || end[1] == 'b'))
        end += 2;
    else if (end[0] == 'B' || end[0] == 'b')
        end++;
    v *= mult;
    if (*end != '\0' || !isfinite(v) || v < 1.0)
        return -1;
    *out = v >= (double)SIZE_MAX ? SIZE_MAX : (size_t)v;
    return 0;
}

/* 334000 -> "334,000"; counts beyond 10^15 in scientific notation. */
static const char *count_text(double v, char *buf, size_t n)
{
    if (!(v < 1e15)) {
        snprintf(buf, n, "%.3g", v);
        return buf;
    }
    char digits[32];
    snprintf(digits, sizeof digits, "%.0f", v);
    size_t len = strlen(digits), k = 0;
    for (size_t i = 0; i < len && k + 2 < n; i++) {
        if (i > 0 && (len - i) % 3 == 0)
            buf[k++] = ',';
        buf[k++] = digits[i];
    }
    buf[k] = '\0';
    return buf;
}

/* A BVH node pair and an index per primitive. */
#define APP_BVH_BYTES_PER_PRIM 48.0

rr_status app_check_memory(const scene *sc, const ig_integrator *ig, const char *cache_path, int aovs, size_t limit,
                           double *pass_bytes, rr_error *err)
{
    char a[32], b[32], c[32], d[32];
    /* The beauty image and the 7 layers, and the AOV images. */
    double film = (8.0 + aovs) * (double)sc->view.width * (double)sc->view.height * 3.0 * sizeof(float);
    /* Solids count one primitive each, plus their mesh leaves' triangles
     * (which get BVHs of their own). */
    double prims = (double)rt_prim_total(sc) + (double)sc->ncsg_tris;
    double bvh = APP_BVH_BYTES_PER_PRIM * prims;
    double patches = 0, rad = 0;
    if (ig_uses_pass(ig, sc)) {
        rad_pass_opts po;
        memset(&po, 0, sizeof po);
        po.use_scene_choices = 1;
        /* A cache that exists is read instead of computing form factors. */
        int cached = cache_path && access(cache_path, F_OK) == 0;
        rad = rad_pass_memory_estimate(sc, &po, cached, &patches);
    }
    double total = film + bvh + rad;
    if (pass_bytes)
        *pass_bytes = limit == SIZE_MAX ? 0.0 : (double)limit - film - bvh;
    if (total <= (double)limit)
        return RR_OK;
    rr_size_text(total, c, sizeof c);
    rr_size_text((double)limit, d, sizeof d);
    if (rad >= film && rad >= bvh)
        return rr_error_set(err, RR_ERR_LIMIT,
                            "%s: radiosity: %s patches need about %s for patches and form factors (%s in all), "
                            "over the limit of %s (--max-memory); raise --patch-area",
                            sc->path, count_text(patches, a, sizeof a), rr_size_text(rad, b, sizeof b), c, d);
    if (film >= bvh)
        return rr_error_set(err, RR_ERR_LIMIT,
                            "%s: a %d x %d image needs about %s of film (%s in all), over the limit of %s "
                            "(--max-memory); lower --width",
                            sc->path, sc->view.width, sc->view.height, rr_size_text(film, b, sizeof b), c, d);
    return rr_error_set(err, RR_ERR_LIMIT,
                        "%s: %s triangles and spheres need about %s for the BVH (%s in all), over the limit of %s "
                        "(--max-memory)",
                        sc->path, count_text(prims, a, sizeof a), rr_size_text(bvh, b, sizeof b), c, d);
}

size_t app_scrub_film(rt_film *film)
{
    enum { SHOW = 5 };
    int xs[SHOW], ys[SHOW];
    size_t n = rt_film_scrub_nonfinite(film, SHOW, xs, ys);
    if (n == 0)
        return 0;
    char list[256];
    size_t k = 0;
    list[0] = '\0';
    for (size_t i = 0; i < n && i < SHOW; i++)
        k += (size_t)snprintf(list + k, sizeof list - k, "%s(%d, %d)", i ? ", " : "", xs[i], ys[i]);
    fprintf(stderr, "radray: warning: %zu pixel(s) had NaN or infinite values, written as 0: %s%s\n", n, list,
            n > SHOW ? ", ..." : "");
    return n;
}
