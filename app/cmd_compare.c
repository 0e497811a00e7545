/* cmd_compare.c - `radray compare SCENE`: renders a scene in several modes (or
 * one render split into its layers) and composes one labelled figure: the
 * panels side by side, difference images against a reference mode, and a
 * table of mean radiance per scene object. The radiosity pass runs once and
 * is shared by every mode that needs it. */
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "app.h"
#include "figure.h"
#include "img.h"
#include "rad.h"
#include "rt.h"
#include "scene.h"

static const char compare_usage[] =
    "usage: radray compare SCENE [options]\n"
    "\n"
    "Renders SCENE in several modes and writes one labelled figure: the renders side\n"
    "by side (tone-mapped like the PNG preview) with their render times, a row of\n"
    "difference images |mode - reference| (mean over RGB, on a colour scale), and a\n"
    "table of the mean radiance of the scene objects (over the pixels that each\n"
    "fills whole; the 16 largest) with the difference relative to the reference.\n"
    "The table and the output path are also printed on stdout. The radiosity pass\n"
    "runs once, shared by the radiosity and hybrid modes, and its time is reported\n"
    "apart from the render times.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE      the figure: .png, .pdf or .svg (default out/<scene>-compare.png)\n"
    "      --modes LIST       comma-separated modes from whitted, secondary, radiosity,\n"
    "                         hybrid, direct (default: the first four, in that order)\n"
    "      --reference MODE   the mode the others are compared to (default: secondary\n"
    "                         when compared, else the last mode)\n"
    "      --reference FILE.exr  an image of the same size made by any renderer, shown as\n"
    "                         the last panel and compared to every mode\n"
    "      --stats FILE       .json or .csv: relMSE, MARE (mean absolute relative error),\n"
    "                         bias (mean signed relative error), each with its standard error,\n"
    "                         per mode over the image and over each object, and SSIM per image\n"
    "                         (relMSE and SSIM are also in the panels' captions)\n"
    "      --layers LIST      instead of modes: panels for the layers of one render,\n"
    "                         from ambient, diffuse, specular, mirror, indirect, emission,\n"
    "                         radiosity, beauty (e.g. ambient,diffuse,specular,radiosity for\n"
    "                         the lecture's shading panels). The layers come from the hybrid\n"
    "                         render, except ambient (from the whitted render: only Whitted\n"
    "                         has the lecture's ambient term) and radiosity (the radiosity\n"
    "                         display). No difference row: layers are parts, not estimates.\n"
    "      --width N          image width in pixels; the height keeps the aspect ratio\n"
    "      --spp N            samples per pixel of every mode but secondary (render.spp)\n"
    "      --spp-of MODE=N    samples per pixel of one mode (repeatable), e.g. --spp-of hybrid=16\n"
    "      --secondary-spp N  samples per pixel of the secondary mode (default 16 x spp):\n"
    "                         secondary rays are Monte Carlo, and at the spp that suffices\n"
    "                         for anti-aliasing their noise would fill the difference images\n"
    "      --exposure EV      display exposure in stops (render.exposure)\n"
    "      --seed N, --threads N, --filter box|tent, --patch-area A, --patch-edge L,\n"
    "      --solver S, --ff METHOD, --ff-samples N   as for render\n"
    "      --convergence FILE  .png or .svg: each mode's relMSE against the reference at 1, 2,\n"
    "                         4, ... spp up to its own, against render time (the radiosity\n"
    "                         pass included), on log-log axes: when the hybrid pays\n"
    "      --radiosity-cache FILE  reuse the radiosity solution saved in FILE (made there\n"
    "                         when missing), as render does\n"
    "      --set KEY=VALUE    override any scene value by its JSON path (repeatable),\n"
    "                         e.g. --set render.threads=2\n"
    "  -q, --quiet            print nothing but errors\n"
    "  -h, --help             show this help\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error, 2 usage error or bad input, 130 interrupted (Ctrl-C:\n"
    "no figure is written), 143 terminated (SIGTERM).\n";

enum { MAX_PANELS = 8, MAX_ROWS = 16, MAX_MODES = 16 };

/* The layers --layers offers and their film index (-1: the beauty image). */
static const char *const layer_names[] = {"ambient",  "diffuse",   "specular", "mirror", "indirect",
                                          "emission", "radiosity", "beauty",   NULL};
static const int layer_index[] = {RT_LAYER_AMBIENT,  RT_LAYER_DIFFUSE,   RT_LAYER_SPECULAR, RT_LAYER_MIRROR,
                                  RT_LAYER_INDIRECT, RT_LAYER_EMISSION, RT_LAYER_RADIOSITY, -1};

/* The integrator (row of ig_table) whose render holds layer l: the default
 * mode when it writes it, else the first row that does. */
static int layer_mode(int l)
{
    int def = (int)(ig_default() - ig_table);
    if (layer_index[l] < 0 || ig_default()->layers & (1u << layer_index[l]))
        return def;
    for (size_t m = 0; m < ig_count(); m++)
        if (ig_table[m].layers & (1u << layer_index[l]))
            return (int)m;
    return def;
}

/* The integrators' names, NULL-terminated, for parse_list. */
static const char *mode_names[MAX_MODES + 1];

/* Parses a comma-separated list of names into out[] (indices into names).
 * Returns the count, or -1 after a one-line error naming the bad item. */
static int parse_list(const char *arg, const char *opt, const char *what, const char *const *names, int *out)
{
    char allowed[256] = "";
    for (int i = 0; names[i]; i++)
        snprintf(allowed + strlen(allowed), sizeof allowed - strlen(allowed), "%s%s", i ? ", " : "", names[i]);
    int n = 0;
    const char *p = arg;
    for (;;) {
        size_t len = strcspn(p, ",");
        char item[64];
        snprintf(item, sizeof item, "%.*s", (int)(len < 63 ? len : 63), p);
        int k = app_pick(item, names);
        if (k < 0) {
            app_error("%s: unknown %s '%s' (expected %s)", opt, what, item, allowed);
            return -1;
        }
        for (int j = 0; j < n; j++)
            if (out[j] == k) {
                app_error("%s: %s '%s' is listed twice", opt, what, item);
                return -1;
            }
        if (n >= MAX_PANELS) {
            app_error("%s: at most %d items", opt, MAX_PANELS);
            return -1;
        }
        out[n++] = k;
        if (!p[len])
            return n;
        p += len + 1;
    }
}

/* A failed pass or render: bad input (a scene the pass cannot take), an
 * interrupt (Ctrl-C, SIGTERM: no figure is written), or a runtime error. */
static int exit_code(rr_status st)
{
    if (st == RR_ERR_INTERRUPTED)
        return app_stop == SIGTERM ? APP_EXIT_TERMINATED : APP_EXIT_INTERRUPTED;
    return st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
}

/* One run of compare: the options, then what the renders leave for the figure. */
typedef struct job {
    const char *out, *ref_name, *scene_path;
    const char *ref_file;   /* --reference FILE.exr: an image made by any renderer */
    const char *stats_path; /* --stats FILE.json / FILE.csv */
    const char *conv_path;  /* --convergence FILE.png / FILE.svg */
    const char *cache_path; /* --radiosity-cache */
    int filter;             /* --filter */
    int quiet, nmodes, nlayers, modes[MAX_PANELS], layers[MAX_PANELS];
    long width, secondary_spp;
    long spp_mode[MAX_MODES]; /* --spp-of MODE=N (0: the default) */
    char **sets;
    size_t nsets;
    char out_default[4200];
    int npanels, ref; /* ref: panel index of the reference, -1 for layers */
    scene *sc;
    rt_accel *accel;
    ig_session ses;
    rt_film film;
    rr_image img[MAX_PANELS]; /* what each panel shows, linear */
    app_metrics whole[MAX_PANELS]; /* each estimate against the reference, whole image */
    double ssim[MAX_PANELS];
    double secs[MAX_MODES], pass_secs;
    int spp_of[MAX_MODES];
    char pass_users[64];      /* the modes that use the radiosity pass */
} job;

enum {
    OPT_MODES = 256,
    OPT_REFERENCE,
    OPT_LAYERS,
    OPT_WIDTH,
    OPT_SECONDARY_SPP,
    OPT_SET,
    OPT_STATS,
    OPT_CACHE,
    OPT_FILTER,
    OPT_CONVERGENCE,
    OPT_SPP_OF,
    OPT_KEY /* an option that sets a scene key (app_option_key) */
};

static int settle_panels(job *j);

/* --spp-of MODE=N: samples per pixel of one mode; 0, or -1 after the error. */
static int parse_spp_of(job *j, const char *arg)
{
    const char *eq = strchr(arg, '=');
    char name[64];
    long n = 0;
    snprintf(name, sizeof name, "%.*s", eq ? (int)(eq - arg) : 0, arg);
    const ig_integrator *ig = eq ? ig_find(name) : NULL;
    if (!ig || app_parse_int(eq + 1, 1, 1 << 20, &n)) {
        char names[128];
        app_error("--spp-of: expected MODE=N with MODE one of %s and N in [1, %d], got '%s'",
                  ig_names(names, sizeof names), 1 << 20, arg);
        return -1;
    }
    j->spp_mode[ig - ig_table] = n;
    return 0;
}

/* Reads the command line into j; returns -1 to go on, or the exit code. */
static int parse_options(job *j, int argc, char **argv)
{
    static const struct option longopts[] = {
        {"output", required_argument, NULL, 'o'},           {"modes", required_argument, NULL, OPT_MODES},
        {"reference", required_argument, NULL, OPT_REFERENCE}, {"layers", required_argument, NULL, OPT_LAYERS},
        {"width", required_argument, NULL, OPT_WIDTH},      {"spp", required_argument, NULL, OPT_KEY},
        {"secondary-spp", required_argument, NULL, OPT_SECONDARY_SPP},
        {"exposure", required_argument, NULL, OPT_KEY},     {"set", required_argument, NULL, OPT_SET},
        {"seed", required_argument, NULL, OPT_KEY},         {"threads", required_argument, NULL, OPT_KEY},
        {"patch-area", required_argument, NULL, OPT_KEY},   {"patch-edge", required_argument, NULL, OPT_KEY},
        {"solver", required_argument, NULL, OPT_KEY},       {"ff", required_argument, NULL, OPT_KEY},
        {"ff-samples", required_argument, NULL, OPT_KEY},   {"filter", required_argument, NULL, OPT_FILTER},
        {"radiosity-cache", required_argument, NULL, OPT_CACHE}, {"stats", required_argument, NULL, OPT_STATS},
        {"convergence", required_argument, NULL, OPT_CONVERGENCE}, {"spp-of", required_argument, NULL, OPT_SPP_OF},
        {"quiet", no_argument, NULL, 'q'},                  {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}};
    static const char *const filters[] = {"box", "tent", NULL};
    optind = 1;
    opterr = 0;
    int c, li;
    while ((li = -1, c = getopt_long(argc, argv, ":o:qh", longopts, &li)) != -1) {
        const char *key = c == OPT_KEY && li >= 0 ? app_option_key(longopts[li].name) : NULL;
        switch (c) {
        case 'o': j->out = optarg; break;
        case 'q': j->quiet = 1; break;
        case 'h': fputs(compare_usage, stdout); return APP_EXIT_OK;
        case OPT_MODES:
            if ((j->nmodes = parse_list(optarg, "--modes", "mode", mode_names, j->modes)) < 0)
                return APP_EXIT_USAGE;
            break;
        case OPT_LAYERS:
            if ((j->nlayers = parse_list(optarg, "--layers", "layer", layer_names, j->layers)) < 0)
                return APP_EXIT_USAGE;
            break;
        case OPT_REFERENCE:
            if (app_ends_with(optarg, ".exr")) {
                j->ref_file = optarg; /* read once the view's size is known */
                break;
            }
            if (!ig_find(optarg)) {
                char names[128];
                app_error("--reference: unknown mode '%s' (expected %s, or an image FILE.exr)", optarg,
                          ig_names(names, sizeof names));
                return APP_EXIT_USAGE;
            }
            j->ref_name = optarg;
            break;
        case OPT_STATS:
            if (!app_ends_with(optarg, ".json") && !app_ends_with(optarg, ".csv")) {
                app_error("--stats %s: the statistics file must end in .json or .csv", optarg);
                return APP_EXIT_USAGE;
            }
            j->stats_path = optarg;
            break;
        case OPT_CACHE: j->cache_path = optarg; break;
        case OPT_CONVERGENCE:
            if (!app_ends_with(optarg, ".png") && !app_ends_with(optarg, ".svg")) {
                app_error("--convergence %s: the plot must end in .png or .svg", optarg);
                return APP_EXIT_USAGE;
            }
            j->conv_path = optarg;
            break;
        case OPT_FILTER:
            if ((j->filter = app_pick(optarg, filters)) < 0) {
                app_error("--filter: expected box or tent, got '%s'", optarg);
                return APP_EXIT_USAGE;
            }
            break;
        case OPT_WIDTH:
            /* The figure puts several panels side by side on one cairo
             * surface, which is limited to 32767 pixels a side. */
            if (app_parse_int(optarg, 1, 4096, &j->width)) {
                app_error("--width: expected an integer in [1, 4096], got '%s'", optarg);
                return APP_EXIT_USAGE;
            }
            break;
        case OPT_SPP_OF:
            if (parse_spp_of(j, optarg) != 0)
                return APP_EXIT_USAGE;
            break;
        case OPT_SECONDARY_SPP:
            if (app_parse_int(optarg, 1, 1 << 20, &j->secondary_spp)) {
                app_error("--secondary-spp: expected an integer in [1, %d], got '%s'", 1 << 20, optarg);
                return APP_EXIT_USAGE;
            }
            break;
        case OPT_KEY: break;
        case OPT_SET: j->sets[j->nsets++] = strdup(optarg); break;
        case ':':
            app_error("option '%s' needs a value (try 'radray compare --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        default:
            app_error("unknown option '%s' (try 'radray compare --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        }
        if (key) {
            size_t n = strlen(key) + strlen(optarg) + 2;
            if ((j->sets[j->nsets] = malloc(n)))
                snprintf(j->sets[j->nsets], n, "%s=%s", key, optarg);
            j->nsets++;
        }
    }
    for (size_t i = 0; i < j->nsets; i++)
        if (!j->sets[i]) {
            app_error("out of memory");
            return APP_EXIT_RUNTIME;
        }
    if (optind != argc - 1) {
        app_error(optind >= argc ? "compare: missing SCENE (try 'radray compare --help')"
                                 : "compare: expected one SCENE, got extra arguments (try 'radray compare --help')");
        return APP_EXIT_USAGE;
    }
    j->scene_path = argv[optind];
    return settle_panels(j);
}

/* The panels the options ask for: the modes (every row of the table that
 * belongs in figures, by default) or layers, and which one is the
 * reference; -1 to go on, or the exit code. */
static int settle_panels(job *j)
{
    if (j->nlayers && (j->nmodes || j->ref_name || j->ref_file || j->stats_path || j->conv_path)) {
        app_error("--layers: compares the layers of one render; it does not go with --modes, --reference, "
                  "--stats or --convergence");
        return APP_EXIT_USAGE;
    }
    if (!j->nlayers && !j->nmodes)
        for (size_t m = 0; m < ig_count(); m++)
            if (ig_table[m].in_figures)
                j->modes[j->nmodes++] = (int)m;
    j->npanels = j->nlayers ? j->nlayers : j->nmodes;
    j->ref = -1;
    if (j->ref_file) {
        if (j->nmodes + 1 > MAX_PANELS) {
            app_error("--reference: at most %d modes beside an image reference", MAX_PANELS - 1);
            return APP_EXIT_USAGE;
        }
        j->ref = j->npanels++; /* the image is the last panel */
    } else if (!j->nlayers) {
        /* Secondary rays are the unbiased estimate: the natural reference. */
        int want = (int)((j->ref_name ? ig_find(j->ref_name) : ig_find("secondary")) - ig_table);
        for (int i = 0; i < j->nmodes; i++)
            if (j->modes[i] == want)
                j->ref = i;
        if (j->ref < 0 && j->ref_name) {
            app_error("--reference: mode '%s' is not among the compared modes (add it to --modes)", j->ref_name);
            return APP_EXIT_USAGE;
        }
        if (j->ref < 0)
            j->ref = j->nmodes - 1;
    }
    return -1;
}

/* The --reference image into the last panel: an EXR of the view's size
 * (after --width). 0, or -1 after the error. */
static int read_reference(job *j)
{
    rr_error err;
    rr_image im = {0};
    if (rr_file_check_regular(j->ref_file, &err) != RR_OK || img_read_exr(j->ref_file, NULL, &im, &err) != RR_OK) {
        app_error("--reference: %s", err.msg);
        return -1;
    }
    int w = j->sc->view.width, h = j->sc->view.height;
    if (im.width != w || im.height != h) {
        app_error("--reference %s: the image is %d x %d, the renders are %d x %d (give --width %d, or render the "
                  "reference at this size)",
                  j->ref_file, im.width, im.height, w, h, im.width);
        rr_image_free(&im);
        return -1;
    }
    j->img[j->ref] = im;
    return 0;
}

/* Loads the scene and settles the output path; returns -1 to go on, or the
 * exit code. */
static int prepare(job *j)
{
    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = (const char *const *)j->sets;
    lo.noverrides = j->nsets;
    lo.warn = app_warn_sink();
    lo.max_image_bytes = j->width > 0 ? SIZE_MAX : 0; /* --width: the file's resolution is not rendered */
    if (app_scene_load(j->scene_path, &lo, &j->sc, &err) != RR_OK) {
        app_error("%s", err.msg);
        return APP_EXIT_USAGE;
    }
    app_diagnose_scene(j->sc);
    if (j->width > 0) {
        rr_view v;
        if (rr_view_resize(&j->sc->view, (int)j->width, &v, &err) != RR_OK) {
            app_error("--width: %s", err.msg);
            return APP_EXIT_USAGE;
        }
        j->sc->view = v;
    }
    if (!j->out) {
        const char *base = strrchr(j->scene_path, '/');
        base = base ? base + 1 : j->scene_path;
        snprintf(j->out_default, sizeof j->out_default, "out/%.*s-compare.png", (int)strcspn(base, "."), base);
        j->out = j->out_default;
    }
    if (!app_ends_with(j->out, ".png") && !app_ends_with(j->out, ".pdf") && !app_ends_with(j->out, ".svg")) {
        app_error("-o %s: the figure must end in .png, .pdf or .svg", j->out);
        return APP_EXIT_USAGE;
    }
    const char *ins[64], *outs[3] = {j->out, j->stats_path, j->conv_path};
    const char *what[3] = {"-o", "--stats", "--convergence"};
    size_t nin = app_scene_inputs(j->sc, ins, 62);
    ins[nin++] = j->cache_path;
    ins[nin++] = j->ref_file;
    if (app_check_outputs(outs, what, 3, ins, nin))
        return APP_EXIT_USAGE;
    if (j->ref_file && read_reference(j) != 0)
        return APP_EXIT_USAGE;
    if (rt_film_init(&j->film, j->sc->view.width, j->sc->view.height, &err) != RR_OK ||
        rt_accel_build(j->sc, &j->accel, &err) != RR_OK) {
        app_error("%s", err.msg);
        return APP_EXIT_RUNTIME;
    }
    app_diagnose_light(j->sc, j->accel);
    app_session_init(&j->ses, j->sc, j->accel, j->cache_path);
    return -1;
}

/* Renders every mode the panels need (the radiosity pass first, once, timed
 * on its own) and keeps what each panel shows. Returns -1 or the exit code. */
static int render_panels(job *j)
{
    scene *sc = j->sc;
    int W = sc->view.width, H = sc->view.height, base_spp = sc->settings.spp;
    int order[MAX_MODES], nrender = 0;
    if (j->nlayers) {
        /* Each render once, the default mode's first. */
        int def = (int)(ig_default() - ig_table);
        for (int k = -1; k < (int)ig_count(); k++) {
            int m = k < 0 ? def : k;
            if (k == def)
                continue;
            for (int i = 0; i < j->nlayers; i++)
                if (layer_mode(j->layers[i]) == m) {
                    order[nrender++] = m;
                    break;
                }
        }
    } else {
        memcpy(order, j->modes, sizeof(int) * (size_t)j->nmodes);
        nrender = j->nmodes;
    }
    rr_error err;
    for (int r = 0; r < nrender; r++) {
        int m = order[r];
        const ig_integrator *ig = &ig_table[m];
        if (ig_uses_pass(ig, sc)) {
            snprintf(j->pass_users + strlen(j->pass_users), sizeof j->pass_users - strlen(j->pass_users), "%s%s",
                     j->pass_users[0] ? " and " : "", ig->name);
            if (!j->ses.sol) {
                double t0 = rr_now_seconds();
                rr_status st = app_session_field(&j->ses, j->quiet, &err);
                if (st != RR_OK) {
                    app_error("%s", err.msg);
                    /* A scene the pass cannot take is bad input, as in render. */
                    return exit_code(st);
                }
                j->pass_secs = rr_now_seconds() - t0;
            }
        }
        if (j->spp_mode[m])
            sc->settings.spp = (int)j->spp_mode[m];
        else if (ig->indirect == RT_INDIRECT_SECONDARY)
            sc->settings.spp = (int)(j->secondary_spp ? j->secondary_spp : fmin(16.0 * base_spp, 1 << 20));
        j->spp_of[m] = sc->settings.spp;
        ig_render_opts ro = {(rt_filter)j->filter, NULL, NULL, NULL};
        rr_status st = ig_render(&j->ses, ig, &ro, &j->film, &j->secs[m], &err);
        sc->settings.spp = base_spp;
        if (st != RR_OK) {
            app_error("%s", err.msg);
            return exit_code(st);
        }
        if (!j->quiet)
            fprintf(stderr, "compare: %s, %d spp, %.2f s\n", ig->name, j->spp_of[m], j->secs[m]);
        for (int i = 0; i < j->npanels; i++) {
            const rr_image *src = NULL;
            if (!j->nlayers && i < j->nmodes && j->modes[i] == m)
                src = &j->film.beauty;
            else if (j->nlayers && layer_mode(j->layers[i]) == m)
                src = layer_index[j->layers[i]] < 0 ? &j->film.beauty : &j->film.layer[layer_index[j->layers[i]]];
            if (!src)
                continue;
            if (rr_image_init(&j->img[i], W, H, &err) != RR_OK) {
                app_error("%s", err.msg);
                return APP_EXIT_RUNTIME;
            }
            memcpy(j->img[i].px, src->px, sizeof(float) * 3 * (size_t)W * (size_t)H);
        }
    }
    return -1;
}

/* The per-object table's storage. */
typedef struct table_store {
    const char **rows;
    long *pixels;
    double *mean;
} table_store;

static int cmp_long_desc(const void *a, const void *b)
{
    long x = *(const long *)a, y = *(const long *)b;
    return (x < y) - (x > y);
}

/* Fills t. Rows: the objects that fill enough whole pixels for a mean worth
 * reading (0.1% of the image and at least 4 pixels), at most MAX_ROWS of them
 * (those filling the most pixels, so that a furnished room still gives a
 * table one can read), in scene order; then every pixel. Columns: the panels.
 * Returns -1 when out of memory. */
static int region_table(const job *j, table_store *ts, fig_table *t)
{
    const scene *sc = j->sc;
    size_t npx = (size_t)sc->view.width * (size_t)sc->view.height;
    int *region = app_pixel_regions(sc, j->accel);
    long *counts = calloc(sc->nobjects + 1, sizeof *counts);
    ts->rows = calloc(sc->nobjects + 1, sizeof *ts->rows);
    ts->pixels = calloc(sc->nobjects + 1, sizeof *ts->pixels);
    ts->mean = calloc((sc->nobjects + 1) * (size_t)j->npanels, sizeof *ts->mean);
    if (!region || !counts || !ts->rows || !ts->pixels || !ts->mean) {
        free(region);
        free(counts);
        return -1;
    }
    for (size_t p = 0; p < npx; p++)
        if (region[p] >= 0)
            counts[region[p]]++;
    long threshold = (long)fmax(4.0, 0.001 * (double)npx);
    if (sc->nobjects > MAX_ROWS) {
        /* Raise the threshold to the MAX_ROWS-th largest count; ties at it
         * are cut in scene order below. */
        long *sorted = malloc(sizeof *sorted * sc->nobjects);
        if (!sorted) {
            free(region);
            free(counts);
            return -1;
        }
        memcpy(sorted, counts, sizeof *sorted * sc->nobjects);
        qsort(sorted, sc->nobjects, sizeof *sorted, cmp_long_desc);
        threshold = sorted[MAX_ROWS - 1] > threshold ? sorted[MAX_ROWS - 1] : threshold;
        free(sorted);
    }
    int n = 0;
    for (size_t o = 0; o <= sc->nobjects; o++) {
        int whole = o == sc->nobjects;
        if (!whole && (counts[o] < threshold || n >= MAX_ROWS))
            continue;
        ts->rows[n] = whole ? "(all pixels)" : sc->objects[o].name;
        ts->pixels[n] = whole ? (long)npx : counts[o];
        for (int i = 0; i < j->npanels; i++) {
            const float *px = j->img[i].px;
            double sum = 0;
            for (size_t p = 0; p < npx; p++)
                if (whole || region[p] == (int)o)
                    sum += (px[3 * p] + px[3 * p + 1] + px[3 * p + 2]) / 3.0;
            ts->mean[(size_t)n * (size_t)j->npanels + (size_t)i] = sum / (double)ts->pixels[n];
        }
        n++;
    }
    free(region);
    free(counts);
    memset(t, 0, sizeof *t);
    t->nrows = n;
    t->ncols = j->npanels;
    t->rows = ts->rows;
    t->pixels = ts->pixels;
    t->mean = ts->mean;
    t->ref = j->nlayers || j->npanels < 2 ? -1 : j->ref;
    return 0;
}

static void free_job(job *j)
{
    for (int i = 0; i < MAX_PANELS; i++)
        rr_image_free(&j->img[i]);
    rt_film_free(&j->film);
    ig_session_free(&j->ses);
    rt_accel_destroy(j->accel);
    scene_destroy(j->sc);
    for (size_t i = 0; i < j->nsets; i++)
        free(j->sets[i]);
    free(j->sets);
}

/* Titles and captions: the mode (or layer), its samples and time; the image
 * reference by its file name; with a reference, each estimate's relMSE and
 * SSIM against it. */
static void label_panels(const job *j, fig_panel *panels, const char **cols)
{
    for (int i = 0; i < j->npanels; i++) {
        panels[i].img = &j->img[i];
        cols[i] = panels[i].title;
        if (j->ref_file && i == j->ref) {
            const char *b = strrchr(j->ref_file, '/');
            snprintf(panels[i].title, sizeof panels[i].title, "reference");
            snprintf(panels[i].caption, sizeof panels[i].caption, "image %s", b ? b + 1 : j->ref_file);
            continue;
        }
        int m = j->nlayers ? layer_mode(j->layers[i]) : j->modes[i];
        snprintf(panels[i].title, sizeof panels[i].title, "%s",
                 j->nlayers ? layer_names[j->layers[i]] : ig_table[m].name);
        if (j->nlayers) {
            snprintf(panels[i].caption, sizeof panels[i].caption, "%s %s, %d spp, %.2f s", ig_table[m].name,
                     ig_table[m].shows_field ? "display" : "render", j->spp_of[m], j->secs[m]);
            continue;
        }
        int k = snprintf(panels[i].caption, sizeof panels[i].caption, "%d spp, %.2f s", j->spp_of[m], j->secs[m]);
        if (j->ref >= 0 && i != j->ref && j->npanels > 1)
            snprintf(panels[i].caption + k, sizeof panels[i].caption - (size_t)k, ", relMSE %.3g, SSIM %.3f",
                     j->whole[i].relmse.value, j->ssim[i]);
    }
}

/* The estimates against the reference, once for the captions and --stats. */
static void measure_panels(job *j)
{
    for (int i = 0; i < j->npanels; i++) {
        j->ssim[i] = NAN;
        if (j->ref < 0 || i == j->ref || j->nlayers)
            continue;
        app_metrics_region(&j->img[i], &j->img[j->ref], NULL, 0, &j->whole[i]);
        j->ssim[i] = app_metric_ssim(&j->img[i], &j->img[j->ref], j->sc->settings.exposure);
    }
}

/* --stats and --convergence (study.c); -1 to go on, or the exit code. */
static int write_studies(job *j, const fig_panel *panels)
{
    const char *titles[MAX_PANELS];
    for (int i = 0; i < j->npanels; i++)
        titles[i] = panels[i].title;
    if ((j->stats_path || j->conv_path) && (j->ref < 0 || j->npanels < 2)) {
        app_error("%s: it measures the modes against a reference; give two modes or --reference",
                  j->stats_path ? "--stats" : "--convergence");
        return APP_EXIT_USAGE;
    }
    app_study st = {j->sc, j->accel, j->img, titles, j->npanels, j->ref, j->whole, j->ssim};
    if (j->stats_path && app_write_stats(j->stats_path, &st, j->quiet) != 0)
        return APP_EXIT_RUNTIME;
    if (!j->conv_path)
        return -1;
    app_conv_mode cm[MAX_PANELS];
    int n = 0;
    for (int i = 0; i < j->nmodes; i++) {
        if (i == j->ref)
            continue;
        const ig_integrator *ig = &ig_table[j->modes[i]];
        cm[n++] = (app_conv_mode){ig, j->spp_of[j->modes[i]], ig_uses_pass(ig, j->sc) ? j->pass_secs : 0.0};
    }
    rr_error err;
    rr_status s = app_convergence(j->conv_path, &j->ses, j->sc, cm, n, &j->img[j->ref], titles[j->ref], &j->film,
                                  j->quiet, &err);
    if (s == RR_OK)
        return -1;
    app_error("%s", err.msg);
    return exit_code(s);
}

int app_cmd_compare(int argc, char **argv)
{
    static job zero;
    job j = zero;
    float *diff[MAX_PANELS] = {0};
    table_store ts = {0};
    fig_panel panels[MAX_PANELS];
    const char *cols[MAX_PANELS];
    fig_desc d;
    memset(&d, 0, sizeof d);
    int rc = APP_EXIT_RUNTIME;
    app_signals sig = {0};
    if (!(j.sets = calloc((size_t)argc + 1, sizeof *j.sets))) {
        app_error("out of memory");
        goto done;
    }
    for (size_t m = 0; m < ig_count() && m < MAX_MODES; m++)
        mode_names[m] = ig_table[m].name;
    app_signals_catch(&sig);
    if ((rc = parse_options(&j, argc, argv)) >= 0 || (rc = prepare(&j)) >= 0 || (rc = render_panels(&j)) >= 0)
        goto done;
    rc = APP_EXIT_RUNTIME;

    measure_panels(&j);
    label_panels(&j, panels, cols);
    if ((rc = write_studies(&j, panels)) >= 0)
        goto done;
    rc = APP_EXIT_RUNTIME;
    if (region_table(&j, &ts, &d.table) != 0) {
        app_error("out of memory");
        goto done;
    }
    d.table.cols = cols;
    if (d.table.ref >= 0)
        snprintf(d.table.title, sizeof d.table.title,
                 "Mean radiance per object (mean of RGB over the pixels it fills); in brackets: relative to %s",
                 panels[j.ref].title);
    else
        snprintf(d.table.title, sizeof d.table.title, "Mean radiance per object (mean of RGB over the pixels it fills)");

    const scene *sc = j.sc;
    const char *base = strrchr(j.scene_path, '/');
    base = base ? base + 1 : j.scene_path;
    snprintf(d.title, sizeof d.title, "%s: %s", sc->name[0] ? sc->name : base,
             j.nlayers ? "the layers of one render" : "modes compared");
    char pass[160] = "no radiosity pass";
    if (j.ses.sol)
        snprintf(pass, sizeof pass, "radiosity pass %zu patches, %.2f s, shared by %s", j.ses.sol->P->n, j.pass_secs,
                 j.pass_users);
    snprintf(d.subtitle, sizeof d.subtitle, "%s, %d x %d px, exposure %+g EV; %s", base, sc->view.width,
             sc->view.height, sc->settings.exposure, pass);
    d.width = sc->view.width;
    d.height = sc->view.height;
    d.exposure = sc->settings.exposure;
    d.npanels = j.npanels;
    d.panels = panels;
    d.ref = j.ref;
    if (d.table.ref >= 0) {
        if (fig_make_diffs(j.img, j.npanels, j.ref, diff, &d.diff_top, &d.diff_clipped) != 0) {
            app_error("out of memory");
            goto done;
        }
        d.diff = (const float *const *)diff;
    }
    rr_error err;
    /* Missing folders are made now, when the figure is written, never earlier. */
    if (rr_file_make_parent_dirs(j.out, &err) != RR_OK || fig_write(j.out, &d, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    if (!j.quiet) {
        fig_print_table(stdout, &d.table);
        printf("wrote %s (%s)\n", j.out, pass);
    }
    rc = APP_EXIT_OK;
done:
    app_signals_restore(&sig);
    for (int i = 0; i < MAX_PANELS; i++)
        free(diff[i]);
    free(ts.rows);
    free(ts.pixels);
    free(ts.mean);
    free_job(&j);
    return rc;
}
