/* app.h - the radray command line (private to app/).
 *
 * Exit codes, the same for every subcommand:
 *   0  success
 *   1  runtime error (a render or a write failed after the input was accepted)
 *   2  usage error or bad input (bad options, unreadable or invalid scene or
 *      mesh, an output path that cannot be written)
 */
#ifndef APP_H
#define APP_H

#include <signal.h>
#include <stdio.h>
#include <stddef.h>

#include "ig.h"
#include "img.h"
#include "rad.h"
#include "rr_core.h"
#include "rt.h"
#include "scene.h"

enum { APP_EXIT_OK = 0, APP_EXIT_RUNTIME = 1, APP_EXIT_USAGE = 2 };
/* `render` and `energy`: interrupted by SIGINT (128 + 2, the shells'
 * convention); render wrote the finished tiles to OUT.partial.exr. */
enum { APP_EXIT_INTERRUPTED = 130 };
/* The same for SIGTERM (128 + 15). */
enum { APP_EXIT_TERMINATED = 143 };

/* ---- mpi.c: several ranks (mpirun), notes/distributed.md ---- */

/* MPI_Init_thread (built with RADRAY_MPI), else nothing; 0 on success. */
int app_mpi_init(int *argc, char ***argv);
void app_mpi_finalize(void);
int app_mpi_rank(void);  /* 0 without MPI */
int app_mpi_ranks(void); /* 1 without MPI */
/* The work lists and merges of rr_dist.h over the ranks; NULL for one. */
rr_dist *app_mpi_dist(void);
/* On a rank other than 0: keeps msg (NULL: nothing) instead of printing
 * it and returns 1; on rank 0 returns 0 (print it). */
int app_mpi_muted(const char *msg);
/* Every rank's exit code so far -> the largest (all ranks call it once,
 * before any collective work); a rank that failed where rank 0 did not
 * prints its kept message. */
int app_mpi_agree(int rc);
/* After agreement: a failure (rc != 0) on this rank ends the whole job. */
void app_mpi_abort(int rc);
/* Bytes this rank put into merges and gathers so far (its buffers; an
 * allreduce moves about twice that over the network). */
double app_mpi_traffic(void);

int app_cmd_render(int argc, char **argv);
int app_cmd_info(int argc, char **argv);
int app_cmd_energy(int argc, char **argv);
int app_cmd_compare(int argc, char **argv);

/* ---- pipeline.c: shared by render, compare and energy ---- */

/* scene_load; when the error is about a key that one of lo's overrides
 * set (--set KEY=VALUE, or an option such as --spp), the message blames the
 * command line and names the override instead of the scene file. */
rr_status app_scene_load(const char *path, const scene_load_opts *lo, scene **out, rr_error *err);

/* The names of rt_indirect's values (--indirect), NULL-terminated. */
extern const char *const app_indirect_names[];
/* Index of name in a NULL-terminated list, or -1. */
int app_pick(const char *name, const char *const *names);
/* The scene key a shorthand option sets (its long name without "--", e.g.
 * "spp" -> "render.spp", "ff" -> "radiosity.form_factors"), or NULL: the
 * one table of them for render and compare. */
const char *app_option_key(const char *option);

/* Ctrl-C and SIGTERM: the handler only sets app_stop to the signal's number
 * (read by the passes before every pixel, row or particle); the second one
 * ends the process the default way. Restore the old handlers when done. */
extern volatile sig_atomic_t app_stop;
typedef struct app_signals {
    struct sigaction old_int, old_term;
    int have_int, have_term;
} app_signals;
void app_signals_catch(app_signals *saved);
void app_signals_restore(const app_signals *saved);

/* A progress line on stderr ("what  45%  12.3 s, 15.0 s left"), drawn only
 * when enabled (a terminal, not --quiet), one update per percent. */
typedef struct app_progress {
    int enabled, last;
    double t0;
    const char *what;
} app_progress;
void app_pass_progress(void *user, size_t done, size_t total);
/* The radiosity pass's options every command uses: the scene's choices, its
 * seed and threads, warnings on stderr, the interrupt flag, and prog (may be
 * NULL) as the form factors' progress line. */
void app_radiosity_opts(const scene *sc, const volatile sig_atomic_t *interrupt, app_progress *prog,
                        rad_pass_opts *po);
/* A session (integrator/ig.h) as every command uses it: the pass options of
 * app_radiosity_opts (no progress line), app_stop as the interrupt, and
 * cache_path (may be NULL). */
void app_session_init(ig_session *s, const scene *sc, const rt_accel *a, const char *cache_path);
/* ig_session_field with a progress line for the form factors (unless quiet
 * or not a terminal) and a summary line after it (unless quiet); a no-op
 * when the pass has run. Ctrl-C stops the form factors within a row. */
rr_status app_session_field(ig_session *s, int quiet, rr_error *err);

/* ---- pipeline.c: resource limits and output checks (notes/hardening.md) ---- */

/* The default --max-memory: half the physical memory (SIZE_MAX when unknown). */
size_t app_default_max_memory(void);
/* Parses a size: a positive number with an optional binary suffix K, M, G or T
 * (optionally followed by "B" or "iB"), e.g. 512M, 4G, 1.5GiB, 1000000; 0 on
 * success. */
int app_parse_size(const char *s, size_t *out);
/* Estimates what a render of sc by ig needs (film with aovs AOV images, BVH, and when ig runs the
 * radiosity pass, patches and form factors, fewer when cache_path exists) and
 * fails with RR_ERR_LIMIT and a message giving the estimate, the limit and
 * what to change when it exceeds limit. Counts only: nothing is built.
 * *pass_bytes (may be NULL) gets what the limit leaves the radiosity pass
 * after the film and the BVH (0: no limit), for rad_hier_opts.max_bytes: the
 * hierarchical pass's estimate is only the least it needs (rad.h). */
rr_status app_check_memory(const scene *sc, const ig_integrator *ig, const char *cache_path, int aovs, size_t limit,
                           double *pass_bytes, rr_error *err);
/* Sets every non-finite pixel of the film to 0 (rt_film_scrub_nonfinite) and
 * warns on stderr with the count and the first coordinates. Returns the count. */
size_t app_scrub_film(rt_film *film);

/* ---- metrics.c: image error against a reference (compare --stats) ----
 *
 * Per pixel p and channel c of an estimate x against a reference r, with
 * eps = APP_METRIC_EPS (so that black reference pixels do not dominate):
 *   relMSE  (x - r)^2 / (r^2 + eps)          (pbrt-v4's imgtool uses the same form)
 *   MARE    |x - r| / (|r| + eps)             mean absolute relative error
 *   bias    (x - r) / (|r| + eps)             mean signed relative error
 * each averaged over the channels, then over the pixels; se is the standard
 * error of that mean over the pixels (their spread / sqrt(count)), which is
 * what a Monte Carlo estimate's noise makes of it. SSIM (Wang et al. 2004:
 * 11 x 11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03) is computed on the
 * display luminance the figure shows (x 2^exposure, clamped, sRGB). */
#define APP_METRIC_EPS 0.01
typedef struct app_metric {
    double value, se;
} app_metric;
typedef struct app_metrics {
    app_metric relmse, mare, bias;
    double ssim; /* whole images only; NaN for regions */
    long pixels;
} app_metrics;
/* The metrics of x against r (same size) over the pixels p with
 * region[p] == which (region NULL: every pixel). */
void app_metrics_region(const rr_image *x, const rr_image *r, const int *region, int which, app_metrics *out);
/* Mean SSIM of x against r over the image (NaN when out of memory). */
double app_metric_ssim(const rr_image *x, const rr_image *r, double exposure);

/* ---- study.c: what compare measures against a reference ---- */

/* For each pixel, the object hit by the ray through its centre, or -1 when
 * nothing is hit or a ray through one of its corners hits something else
 * (edge pixels mix surfaces in proportions that depend on the sample count):
 * the regions of compare's per-object table and statistics. malloc'd, NULL
 * when out of memory. */
int *app_pixel_regions(const scene *sc, const rt_accel *a);
/* s as a JSON string on f (quotes, backslashes and control bytes escaped). */
void app_json_string(FILE *f, const char *s);
/* Panels against the reference: img[0..n), img[ref] the reference; whole[i]
 * and ssim[i] the whole-image metrics of the others (computed once). */
typedef struct app_study {
    const scene *sc;
    const rt_accel *accel;
    const rr_image *img;
    const char *const *titles;
    int n, ref;
    const app_metrics *whole;
    const double *ssim;
} app_study;
/* --stats: per panel, over the whole image and over each object that fills
 * enough whole pixels (0.1 % of the image, at least 4), as JSON or CSV by
 * extension, through a temporary file. 0, or -1 after the error. */
int app_write_stats(const char *path, const app_study *st, int quiet);
/* One mode of the convergence plot: rendered at 1, 2, 4, ... up to spp, its
 * time plus extra_seconds (the radiosity pass, for the modes that use it). */
typedef struct app_conv_mode {
    const ig_integrator *ig;
    int spp;
    double extra_seconds;
} app_conv_mode;
/* --convergence: each mode's relMSE against ref by time, log-log, plotted to
 * path (and printed unless quiet); renders into film with the session. */
rr_status app_convergence(const char *path, ig_session *ses, scene *sc, const app_conv_mode *modes, int n,
                          const rr_image *ref, const char *ref_title, rt_film *film, int quiet, rr_error *err);

/* ---- diagnose.c: warnings that name the cause of lost light ---- */

/* Warns when nothing can light the scene (nothing emits, black background:
 * a black image), and about every closed triangle object whose faces point
 * outwards and that has an emitter inside (a room built inside out). Returns
 * the count. */
size_t app_diagnose_scene(const scene *s);
/* Warns about every object whose back faces receive more than share of the
 * emitted power in the light tracer's ledger g. Returns the count. */
size_t app_diagnose_ledger(const scene *s, const rt_particle_ledger *g, double share);
/* The same from a quick light trace of APP_DIAGNOSE_PARTICLES particles (a
 * few milliseconds; 1 % of the power is ~15 standard errors), for render,
 * info and compare. */
#define APP_DIAGNOSE_PARTICLES 20000
size_t app_diagnose_light(const scene *s, const rt_accel *a);

/* Prints "radray: <msg>" on stderr. */
void app_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/* Warning sink printing "radray: warning: <msg>" on stderr. */
rr_warn_sink app_warn_sink(void);

/* Writes a log-scale plot of res[0..n) (residual per iteration) to path, PNG
 * or SVG by extension, atomically. 0 on success. */
int app_plot_residuals(const char *path, const double *res, int n, const char *title, rr_error *err);
/* One line of a plot: n points (x[i], y[i]); name for the legend (may be NULL). */
typedef struct app_series {
    const char *name;
    const double *x, *y;
    int n;
} app_series;
/* Lines on a logarithmic y axis (x logarithmic when logx), with a legend,
 * PNG or SVG by extension, atomically. 0 on success. */
int app_plot_lines(const char *path, const app_series *s, int ns, const char *title, const char *xlabel,
                   const char *ylabel, int logx, rr_error *err);

/* s ends with suffix, ignoring case. */
int app_ends_with(const char *s, const char *suffix);
/* ---- output.c: outputs checked before any work, committed together ---- */

/* Refuses an output path before any work is done: it must not be a folder,
 * and the nearest existing folder on its path must let us create files
 * (missing folders are made only when the file is written). Prints the
 * error, returns -1. */
int app_check_writable(const char *path);
/* a and b name one file (the same inode when both exist, else the same
 * normalised absolute path). */
int app_same_file(const char *a, const char *b);
/* The scene's input files: the scene file and every mesh file of its
 * objects (at most cap; returns the count). */
size_t app_scene_inputs(const scene *s, const char **ins, size_t cap);
/* Checks outputs outs[0..nout) (NULL entries skipped; what[i] names the
 * option, e.g. "--png") against each other and against the inputs, then
 * app_check_writable; prints the error and returns -1 on the first problem. */
int app_check_outputs(const char *const *outs, const char *const *what, size_t nout, const char *const *ins,
                      size_t nin);
/* What the EXR carries beyond the film: extra layers (the AOVs, at most
 * RT_AOV_COUNT) and header attributes (what made it). */
typedef struct app_exr_extra {
    const img_layer *layers;
    int nlayers;
    const img_attr *attrs;
    int nattrs;
} app_exr_extra;
/* Writes the film's EXR (beauty + layers + extra, may be NULL) and, when png
 * is set, its sRGB preview as one commit: both to temporaries, then both
 * renamed under a lock on the folder; on any failure neither replaces its old
 * file. */
rr_status app_write_film(const char *exr, const char *png, const rt_film *film, int half, double exposure,
                         const app_exr_extra *extra, rr_error *err);

/* Parses a whole decimal integer in [lo, hi]; 0 on success. */
int app_parse_int(const char *s, long lo, long hi, long *out);

#endif
