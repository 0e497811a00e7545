/* cmd_render.c - `radray render SCENE`: load, render, write EXR + PNG. */
#include <getopt.h>
#include <sys/resource.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>

#include "app.h"
#include "img.h"
#include "rad.h"
#include "rt.h"
#include "scene.h"

static const char render_usage[] =
    "usage: radray render SCENE [options]\n"
    "\n"
    "Renders SCENE (a radray-scene/1 JSON file) to a linear float OpenEXR image and\n"
    "an sRGB PNG preview beside it.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE.exr  EXR output (default out/<scene file name>.exr, e.g. out/cornell.exr);\n"
    "                         -o FILE.png names the preview instead, the EXR beside it\n"
    "      --png FILE.png     PNG preview path (default: the output with .png)\n"
    "      --no-png           do not write the PNG preview\n"
    "      --width N          image width in pixels; the height keeps the aspect ratio\n"
    "      --spp N            samples per pixel (scene key render.spp)\n"
    "      --seed N           random seed (render.seed)\n"
    "      --threads N        worker threads, 0 = all cores (render.threads)\n"
    "      --exposure EV      PNG preview exposure in stops (render.exposure)\n"
    "      --half             write half-float EXR instead of float (render.half_float)\n"
    "      --mode MODE        hybrid (default): ray-traced direct light, shadows, highlights and\n"
    "                           mirrors, plus diffuse interreflection from the radiosity pass\n"
    "                         whitted: the same with the lecture's ambient term instead\n"
    "                         secondary: interreflection by Monte Carlo secondary rays instead\n"
    "                         radiosity: the radiosity solution alone, Gouraud-shaded\n"
    "                         direct: emission and direct light only, no interreflection\n"
    "      --indirect KIND    what supplies diffuse interreflection, everything else equal:\n"
    "                         radiosity (= --mode hybrid), secondary, ambient (= whitted) or\n"
    "                         none (= direct); overrides --mode\n"
    "      --filter F         pixel filter for supersampling: box (default) or tent\n"
    "      --stats FILE.json  rays traced (closest-hit and any-hit), Mrays/s, the radiosity\n"
    "                         pass (patches, form factors, time per stage), times, peak\n"
    "                         memory (the summary printed at the end, by name)\n"
    "      --aov LIST         extra EXR layers of each pixel's centre ray: albedo (diffuse\n"
    "                         reflectance), normal (unit, facing the ray), depth (distance from\n"
    "                         the eye), object_id (index in the scene's objects, -1: nothing);\n"
    "                         comma-separated, or all\n"
    "      --frames A..B      a walkthrough: frames A to B (or one frame, --frames A) of the\n"
    "                         scene's camera_path, to OUT.0001.exr, OUT.0001.png, ...; one\n"
    "                         radiosity solution (or --radiosity-cache) for all of them\n"
    "      --reproducible     leave the timings out of the EXR header, so that the file's\n"
    "                         bytes depend on the inputs alone (any thread or rank count)\n"
    "radiosity options (override the scene's \"radiosity\" block; the method is hierarchical\n"
    "unless --set radiosity.method=flat, and the flat method's options say so):\n"
    "      --patch-area A     largest patch area (scene units squared; hierarchical: its roots\n"
    "                         are 16 times that, its leaves refined on demand)\n"
    "      --patch-edge L     longest patch edge\n"
    "      --solver S         flat: auto, direct (CHOLMOD) or iterative (Gauss-Seidel)\n"
    "      --ff METHOD        flat: form factors by montecarlo or quadrature\n"
    "      --ff-samples N     flat: rays or sample points per patch\n"
    "      --plot FILE        write the solver's convergence (residual per iteration; hierarchical:\n"
    "                         the last solve's largest change per sweep) as PNG or SVG\n"
    "      --radiosity-cache FILE  reuse the radiosity solution saved in FILE (made there when\n"
    "                         missing); one made for another scene or other settings is refused\n"
    "      --set KEY=VALUE    override any scene value by its JSON path, e.g.\n"
    "                         --set render.spp=16 --set materials.white.diffuse=[0.7,0.7,0.7]\n"
    "                         (repeatable; VALUE is JSON, or a string)\n"
    "      --max-memory SIZE  refuse, before any work, a render estimated to need more memory\n"
    "                         (film, BVH, radiosity patches and form factors) than SIZE,\n"
    "                         e.g. 512M, 4G (default: half the physical memory); the\n"
    "                         hierarchical radiosity pass stays under what is left\n"
    "                         (coarser, with a warning, or exit 2 where it cannot)\n"
    "  -q, --quiet            print nothing but errors (no progress bar, no summary)\n"
    "  -h, --help             show this help\n"
    "\n"
    "The progress bar is drawn on stderr only when it is a terminal.\n"
    "Ctrl-C (SIGINT) stops the render: the finished tiles (the rest black) are written\n"
    "to OUT.partial.exr, never over OUT, and radray exits with 130; a second Ctrl-C\n"
    "ends it at once. SIGTERM does the same (exit 143).\n"
    "OUT.exr and its PNG are replaced together or not at all. An output that names an\n"
    "input (the scene, a mesh, the cache) or another output is refused before any work.\n"
    "Pixels that come out NaN or infinite are written as 0 with a warning naming them.\n"
    "Exit codes: 0 ok, 1 runtime error, 2 usage error or bad input (a render over\n"
    "--max-memory included), 130 interrupted, 143 terminated.\n"
    "Built with MPI (-DRADRAY_MPI=ON), 'mpirun -np N radray render ...' shares the\n"
    "radiosity pass and the tiles (or, with --frames, the frames) over N ranks; the\n"
    "result is the same, byte for byte, as one process (notes/distributed.md).\n";

/* The tile progress of rt_render as the common progress line (with the time left). */
static void draw_progress(void *user, int done, int total) { app_pass_progress(user, (size_t)done, (size_t)total); }


enum {
    OPT_PNG = 256,
    OPT_NO_PNG,
    OPT_WIDTH,
    OPT_SPP,
    OPT_SEED,
    OPT_THREADS,
    OPT_EXPOSURE,
    OPT_HALF,
    OPT_SET,
    OPT_MODE,
    OPT_INDIRECT,
    OPT_FILTER,
    OPT_PATCH_AREA,
    OPT_PATCH_EDGE,
    OPT_SOLVER,
    OPT_FF,
    OPT_FF_SAMPLES,
    OPT_PLOT,
    OPT_CACHE,
    OPT_MAX_MEMORY,
    OPT_AOV,
    OPT_STATS,
    OPT_REPRODUCIBLE,
    OPT_FRAMES
};

/* The command line, parsed. */
typedef struct render_args {
    const char *scene_path, *out_exr, *out_png, *plot, *cache_path, *stats;
    int no_png, quiet, filter;
    int reproducible; /* --reproducible: no timings in the EXR header */
    long frame_first, frame_last; /* --frames A..B of camera_path; 0, 0: one still image */
    unsigned aovs; /* --aov: 1u << RT_AOV_* */
    long width;
    const ig_integrator *ig;
    size_t max_memory;
    char **sets; /* one per --set, plus those the shorthand options expand to */
    size_t nsets;
    char exr_default[4200], png_default[4200], partial[4200];
} render_args;

/* How many AOVs the mask asks for. */
static int aov_count(unsigned mask)
{
    int n = 0;
    for (int k = 0; k < RT_AOV_COUNT; k++)
        n += (mask >> k) & 1u;
    return n;
}

/* --aov LIST: comma-separated AOV names, or "all"; -1, or the exit code. */
static int parse_aovs(render_args *A, const char *arg)
{
    char buf[256];
    snprintf(buf, sizeof buf, "%s", arg);
    for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
        int k = -1;
        for (int i = 0; i < RT_AOV_COUNT; i++)
            if (!strcmp(tok, rt_aov_name(i)))
                k = i;
        if (!strcmp(tok, "all")) {
            A->aovs = (1u << RT_AOV_COUNT) - 1;
            continue;
        }
        if (k < 0) {
            app_error("--aov: unknown AOV '%s' (expected albedo, normal, depth, object_id or all)", tok);
            return APP_EXIT_USAGE;
        }
        A->aovs |= 1u << k;
    }
    if (!A->aovs) {
        app_error("--aov: expected a list such as albedo,normal,depth,object_id (or all), got '%s'", arg);
        return APP_EXIT_USAGE;
    }
    return -1;
}

/* One option into A; returns -1 to go on, or the exit code. */
static int parse_option(render_args *A, int c, const char *arg, const char *name, const char *longname,
                        const ig_integrator **by_indirect)
{
    static const char *const filters[] = {"box", "tent", NULL};
    char names[128];
    switch (c) {
    case 'o': A->out_exr = arg; return -1;
    case OPT_PNG: A->out_png = arg; return -1;
    case OPT_NO_PNG: A->no_png = 1; return -1;
    case OPT_PLOT: A->plot = arg; return -1;
    case OPT_CACHE: A->cache_path = arg; return -1;
    case 'q': A->quiet = 1; return -1;
    case OPT_REPRODUCIBLE: A->reproducible = 1; return -1;
    case OPT_FRAMES: {
        char a[32] = "", *dots;
        snprintf(a, sizeof a, "%s", arg);
        if ((dots = strstr(a, ".."))) {
            *dots = '\0';
            if (!app_parse_int(a, 1, 999999, &A->frame_first) && !app_parse_int(dots + 2, 1, 999999, &A->frame_last) &&
                A->frame_last >= A->frame_first)
                return -1;
        } else if (!app_parse_int(a, 1, 999999, &A->frame_first)) {
            A->frame_last = A->frame_first;
            return -1;
        }
        app_error("--frames: expected A..B (1 <= A <= B) or one frame number, got '%s'", arg);
        return APP_EXIT_USAGE;
    }
    case 'h': fputs(render_usage, stdout); return APP_EXIT_OK;
    case OPT_SET: A->sets[A->nsets++] = strdup(arg); return -1;
    case ':': app_error("option '%s' needs a value (try 'radray render --help')", name); return APP_EXIT_USAGE;
    case OPT_WIDTH:
        if (!app_parse_int(arg, 1, 1 << 21, &A->width))
            return -1;
        app_error("--width: expected an integer in [1, %d], got '%s'", 1 << 21, arg);
        return APP_EXIT_USAGE;
    case OPT_AOV: return parse_aovs(A, arg);
    case OPT_STATS:
        if (app_ends_with(arg, ".json")) {
            A->stats = arg;
            return -1;
        }
        app_error("--stats %s: the statistics file must end in .json", arg);
        return APP_EXIT_USAGE;
    case OPT_MAX_MEMORY:
        if (!app_parse_size(arg, &A->max_memory))
            return -1;
        app_error("--max-memory: expected a size such as 512M or 4G, got '%s'", arg);
        return APP_EXIT_USAGE;
    case OPT_MODE:
        if ((A->ig = ig_find(arg)))
            return -1;
        app_error("--mode: expected %s, got '%s'", ig_names(names, sizeof names), arg);
        return APP_EXIT_USAGE;
    case OPT_INDIRECT: {
        int k = app_pick(arg, app_indirect_names);
        if (k >= 0 && (*by_indirect = ig_with_indirect((rt_indirect)k)))
            return -1;
        app_error("--indirect: expected radiosity, secondary, ambient or none, got '%s'", arg);
        return APP_EXIT_USAGE;
    }
    case OPT_FILTER:
        if ((A->filter = app_pick(arg, filters)) >= 0)
            return -1;
        app_error("--filter: expected box or tent, got '%s'", arg);
        return APP_EXIT_USAGE;
    default: break;
    }
    const char *key = longname ? app_option_key(longname) : NULL;
    if (!key) {
        app_error("unknown option '%s' (try 'radray render --help')", name);
        return APP_EXIT_USAGE;
    }
    const char *val = c == OPT_HALF ? "true" : arg;
    size_t n = strlen(key) + strlen(val) + 2;
    if ((A->sets[A->nsets] = malloc(n)))
        snprintf(A->sets[A->nsets], n, "%s=%s", key, val);
    A->nsets++;
    return -1;
}

/* Reads the command line into A; returns -1 to go on, or the exit code. */
static int parse_args(render_args *A, int argc, char **argv)
{
    static const struct option longopts[] = {
        {"output", required_argument, NULL, 'o'},     {"png", required_argument, NULL, OPT_PNG},
        {"no-png", no_argument, NULL, OPT_NO_PNG},    {"width", required_argument, NULL, OPT_WIDTH},
        {"spp", required_argument, NULL, OPT_SPP},    {"seed", required_argument, NULL, OPT_SEED},
        {"threads", required_argument, NULL, OPT_THREADS}, {"exposure", required_argument, NULL, OPT_EXPOSURE},
        {"half", no_argument, NULL, OPT_HALF},        {"set", required_argument, NULL, OPT_SET},
        {"quiet", no_argument, NULL, 'q'},            {"help", no_argument, NULL, 'h'},
        {"mode", required_argument, NULL, OPT_MODE},  {"indirect", required_argument, NULL, OPT_INDIRECT},
        {"filter", required_argument, NULL, OPT_FILTER},
        {"patch-area", required_argument, NULL, OPT_PATCH_AREA}, {"patch-edge", required_argument, NULL, OPT_PATCH_EDGE},
        {"solver", required_argument, NULL, OPT_SOLVER},  {"ff", required_argument, NULL, OPT_FF},
        {"ff-samples", required_argument, NULL, OPT_FF_SAMPLES}, {"plot", required_argument, NULL, OPT_PLOT},
        {"radiosity-cache", required_argument, NULL, OPT_CACHE},
        {"max-memory", required_argument, NULL, OPT_MAX_MEMORY}, {"aov", required_argument, NULL, OPT_AOV},
        {"stats", required_argument, NULL, OPT_STATS}, {"reproducible", no_argument, NULL, OPT_REPRODUCIBLE},
        {"frames", required_argument, NULL, OPT_FRAMES},
        {NULL, 0, NULL, 0}};
    const ig_integrator *by_indirect = NULL;
    A->ig = ig_default();
    A->filter = RT_FILTER_BOX;
    A->max_memory = app_default_max_memory();
    optind = 1;
    opterr = 0;
    int c, li;
    while ((li = -1, c = getopt_long(argc, argv, ":o:qh", longopts, &li)) != -1) {
        int rc = parse_option(A, c, optarg, argv[optind - 1], li >= 0 ? longopts[li].name : NULL, &by_indirect);
        if (rc >= 0)
            return rc;
    }
    if (by_indirect)
        A->ig = by_indirect;
    for (size_t i = 0; i < A->nsets; i++)
        if (!A->sets[i]) {
            app_error("out of memory");
            return APP_EXIT_RUNTIME;
        }
    if (optind != argc - 1) {
        app_error(optind >= argc ? "render: missing SCENE (try 'radray render --help')"
                                 : "render: expected one SCENE, got extra arguments (try 'radray render --help')");
        return APP_EXIT_USAGE;
    }
    A->scene_path = argv[optind];
    return -1;
}

/* Output names (out/<scene name>.exr by default, the PNG beside the EXR),
 * checked against each other and the inputs; 0, or -1 after the error. */
static int settle_outputs(render_args *A, const scene *sc)
{
    if (!A->out_exr) {
        const char *base = strrchr(A->scene_path, '/');
        base = base ? base + 1 : A->scene_path;
        size_t n = strcspn(base, ".");
        snprintf(A->exr_default, sizeof A->exr_default, "out/%.*s.exr", (int)n, base);
        A->out_exr = A->exr_default;
    }
    if (app_ends_with(A->out_exr, ".png") && !A->out_png && !A->no_png) {
        /* -o FILE.png: that is the preview; the EXR goes beside it. */
        A->out_png = A->out_exr;
        snprintf(A->exr_default, sizeof A->exr_default, "%.*s.exr", (int)(strlen(A->out_exr) - 4), A->out_exr);
        A->out_exr = A->exr_default;
    }
    if (!app_ends_with(A->out_exr, ".exr")) {
        app_error("-o %s: the output must end in .exr (or .png: the preview, with the EXR beside it)", A->out_exr);
        return -1;
    }
    if (!A->out_png && !A->no_png) {
        snprintf(A->png_default, sizeof A->png_default, "%.*s.png", (int)(strlen(A->out_exr) - 4), A->out_exr);
        A->out_png = A->png_default;
    }
    snprintf(A->partial, sizeof A->partial, "%.*s.partial.exr", (int)(strlen(A->out_exr) - 4), A->out_exr);
    const char *ins[64];
    size_t nin = app_scene_inputs(sc, ins, 63);
    ins[nin++] = A->cache_path;
    const char *outs[5] = {A->out_exr, A->no_png ? NULL : A->out_png, A->plot, A->partial, A->stats};
    const char *what[5] = {"-o", "--png", "--plot", "the partial image", "--stats"};
    if (app_check_outputs(outs, what, 5, ins, nin))
        return -1;
    if (A->plot && !A->ig->uses_field) {
        app_error("--plot: the convergence plot belongs to the radiosity pass: use it with --mode radiosity");
        return -1;
    }
    if (A->frame_first) {
        if (sc->npath == 0) {
            app_error("--frames: %s has no camera_path (notes/scene-format.md, \"Walkthroughs\")", sc->path);
            return -1;
        }
        if (A->frame_last > sc->path_frames) {
            app_error("--frames %ld..%ld: camera_path has frames 1..%d", A->frame_first, A->frame_last,
                      sc->path_frames);
            return -1;
        }
        if (A->stats || A->plot) {
            app_error("--frames: --stats and --plot describe one image; render a frame alone for them");
            return -1;
        }
    }
    return 0;
}

/* Loads the scene with the overrides, resized to --width; NULL after the error. */
static scene *load_scene(const render_args *A)
{
    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = (const char *const *)A->sets;
    lo.noverrides = A->nsets;
    lo.warn = app_warn_sink();
    /* With --width the file's resolution is not the one rendered: the film is
     * judged after the resize (app_check_memory), not at load. */
    lo.max_image_bytes = A->width > 0 ? SIZE_MAX : A->max_memory;
    scene *sc = NULL;
    if (app_scene_load(A->scene_path, &lo, &sc, &err) != RR_OK) {
        app_error("%s", err.msg);
        return NULL;
    }
    app_diagnose_scene(sc);
    if (A->width > 0) {
        rr_view v;
        if (rr_view_resize(&sc->view, (int)A->width, &v, &err) != RR_OK) {
            app_error("--width: %s", err.msg);
            scene_destroy(sc);
            return NULL;
        }
        sc->view = v;
    }
    return sc;
}

/* An interrupted render: the finished tiles to A->partial; the exit code. */
static int write_partial(const render_args *A, const scene *sc, rt_film *film, const rr_error *why)
{
    app_scrub_film(film);
    img_layer layers[RT_LAYER_COUNT];
    for (int i = 0; i < RT_LAYER_COUNT; i++) {
        layers[i].name = rt_layer_name(i);
        layers[i].image = &film->layer[i];
    }
    rr_error werr;
    if (img_write_exr(A->partial, &film->beauty, layers, RT_LAYER_COUNT,
                      sc->settings.half_float ? IMG_HALF : IMG_FLOAT, &werr) != RR_OK) {
        app_error("%s; the partial image could not be written either: %s", why->msg, werr.msg);
        return APP_EXIT_RUNTIME;
    }
    app_error("%s; wrote the partial image (unfinished tiles black) to %s", why->msg, A->partial);
    return app_stop == SIGTERM ? APP_EXIT_TERMINATED : APP_EXIT_INTERRUPTED;
}

/* The solver's convergence plot (--plot); 0, or -1 after the error. */
static int write_plot(const render_args *A, const rad_solution *sol)
{
    if (!sol || sol->stats.nhistory <= 0) {
        fprintf(stderr, "radray: warning: --plot: the direct solver has no iterations to plot "
                        "(use --solver iterative)\n");
        return 0;
    }
    char title[128];
    rr_error err;
    if (sol->P->roots) /* hierarchical: its last solve's Jacobi sweeps */
        snprintf(title, sizeof title, "Jacobi sweeps' largest change, %zu leaves (hierarchical)", sol->P->n);
    else
        snprintf(title, sizeof title, "Gauss-Seidel residual, %zu patches", sol->P->n);
    if (app_plot_residuals(A->plot, sol->stats.history, sol->stats.nhistory, title, &err) != 0) {
        app_error("%s", err.msg);
        return -1;
    }
    if (!A->quiet)
        printf("wrote %s (convergence plot)\n", A->plot);
    return 0;
}

/* FNV-1a of the scene file's bytes, as hex (the file that made the image). */
static void file_hash(const char *path, char *buf, size_t n)
{
    char *text = NULL;
    size_t len = 0;
    uint64_t h = 0xcbf29ce484222325ULL;
    if (rr_file_read_all(path, &text, &len, NULL) != RR_OK) {
        snprintf(buf, n, "unknown");
        return;
    }
    for (size_t i = 0; i < len; i++) {
        h ^= (unsigned char)text[i];
        h *= 0x100000001b3ULL;
    }
    free(text);
    snprintf(buf, n, "fnv1a64:%016llx", (unsigned long long)h);
}

/* The EXR (film, AOVs, what made it) and the PNG, as one commit. */
static int write_outputs(const render_args *A, const scene *sc, const ig_session *ses, const rt_film *film,
                         double secs)
{
    rr_error err;
    rr_image aov[RT_AOV_COUNT];
    memset(aov, 0, sizeof aov);
    img_layer layers[RT_AOV_COUNT];
    int nl = 0, rc = APP_EXIT_RUNTIME;
    for (int k = 0; k < RT_AOV_COUNT; k++)
        if (A->aovs & (1u << k)) {
            if (rr_image_init(&aov[k], sc->view.width, sc->view.height, &err) != RR_OK) {
                app_error("%s", err.msg);
                goto done;
            }
            layers[nl].name = rt_aov_name(k);
            layers[nl++].image = &aov[k];
        }
    if (A->aovs)
        rt_render_aovs(sc, ses->accel, A->aovs, aov, sc->settings.threads);
    char spp[32], seed[32], t_all[32], t_pass[32], hash[64], camera[512];
    const rr_view *v = &sc->view;
    snprintf(spp, sizeof spp, "%d", sc->settings.spp);
    snprintf(seed, sizeof seed, "%llu", (unsigned long long)sc->settings.seed);
    snprintf(t_all, sizeof t_all, "%.3f", secs);
    snprintf(t_pass, sizeof t_pass, "%.3f", ses->sol ? ses->seconds_pass : 0.0);
    file_hash(sc->path, hash, sizeof hash);
    snprintf(camera, sizeof camera, "E (%.17g, %.17g, %.17g) O (%.17g, %.17g, %.17g) U (%.17g, %.17g, %.17g) s %.17g, %d x %d",
             v->E.x, v->E.y, v->E.z, v->O.x, v->O.y, v->O.z, v->U.x, v->U.y, v->U.z, v->s, v->width, v->height);
    /* The timings last: --reproducible leaves them out, so that the bytes
     * depend on the inputs alone (any thread or rank count). */
    const img_attr attrs[] = {
        {"radray:version", RADRAY_VERSION}, {"radray:mode", A->ig->name},     {"radray:spp", spp},
        {"radray:seed", seed},              {"radray:scene", sc->path},       {"radray:scene_name", sc->name},
        {"radray:scene_hash", hash},        {"radray:camera", camera},        {"radray:seconds", t_all},
        {"radray:radiosity_seconds", t_pass},
    };
    int nattrs = (int)(sizeof attrs / sizeof attrs[0]) - (A->reproducible ? 2 : 0);
    app_exr_extra extra = {layers, nl, attrs, nattrs};
    if (app_write_film(A->out_exr, A->no_png ? NULL : A->out_png, film, sc->settings.half_float,
                       sc->settings.exposure, &extra, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    rc = APP_EXIT_OK;
done:
    for (int k = 0; k < RT_AOV_COUNT; k++)
        rr_image_free(&aov[k]);
    return rc;
}

static void print_summary(const render_args *A, const scene *sc, const rt_film *film, double secs)
{
    printf("rendered %s: %d x %d, %d spp, mode %s, %.2f s\n", A->scene_path, film->beauty.width,
           film->beauty.height, sc->settings.spp, A->ig->name, secs);
    printf("wrote %s (linear %s RGB; layers", A->out_exr, sc->settings.half_float ? "half" : "float");
    for (int i = 0; i < RT_LAYER_COUNT; i++)
        printf(" %s", rt_layer_name(i));
    for (int k = 0; k < RT_AOV_COUNT; k++)
        if (A->aovs & (1u << k))
            printf(" %s", rt_aov_name(k));
    printf(")\n");
    if (!A->no_png)
        printf("wrote %s (sRGB preview, exposure %+g)\n", A->out_png, sc->settings.exposure);
}

/* What one render did, for the summary and --stats. */
typedef struct render_stats {
    double seconds, seconds_render;
    rt_ray_counts rays;
    double peak_bytes;
} render_stats;

static double peak_rss_bytes(void)
{
    struct rusage ru;
    return getrusage(RUSAGE_SELF, &ru) == 0 ? 1024.0 * (double)ru.ru_maxrss : 0.0; /* Linux: KiB */
}

/* The end-of-render summary: rays per kind and their rate, the radiosity
 * pass (patches, form factors, time per stage), time, peak memory. */
static void print_stats(const ig_session *ses, const render_stats *rs)
{
    char peak[32];
    double n = (double)rs->rays.closest + (double)rs->rays.occluded;
    printf("rays       %.4g M (%.4g M closest-hit, %.4g M any-hit), %.3g Mrays/s, render %.2f s\n",
           n * 1e-6, (double)rs->rays.closest * 1e-6, (double)rs->rays.occluded * 1e-6,
           rs->seconds_render > 0 ? n * 1e-6 / rs->seconds_render : 0.0, rs->seconds_render);
    const rad_solution *sol = ses->sol;
    double mff = sol ? ((double)sol->ff_rays.closest + (double)sol->ff_rays.occluded) * 1e-6 : 0.0;
    if (sol && ses->sol_cached)
        printf("radiosity  %zu patches, read from %s (%.2f s)\n", sol->P->n, ses->cache_path, ses->seconds_pass);
    else if (sol && sol->links)
        printf("radiosity  %zu leaves, %zu links (the pass held %.1f MiB); refinement %.2f s (%.4g M rays, %.3g "
               "Mrays/s), solves %.2f s (Jacobi, %d sweep(s) in the last)\n",
               sol->P->n, sol->links, sol->pass_bytes / 1048576.0, sol->seconds_ff, mff,
               sol->seconds_ff > 0 ? mff / sol->seconds_ff : 0.0, sol->seconds_solve, sol->stats.iterations);
    else if (sol)
        printf("radiosity  %zu patches, %zu form factors; patches %.2f s, form factors %.2f s (%.4g M rays), "
               "solve %.2f s (%s, %d iteration(s))\n",
               sol->P->n, sol->nnz, sol->seconds_patches, sol->seconds_ff, mff, sol->seconds_solve,
               sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative", sol->stats.iterations);
    if (sol && sol->links && !ses->sol_cached)
        printf("           stages: setup %.2f, link %.2f, settle %.2f, regeo %.2f, estimate %.2f, solve %.2f, "
               "output %.2f s\n",
               sol->hier_seconds.setup, sol->hier_seconds.link, sol->hier_seconds.settle, sol->hier_seconds.regeo,
               sol->hier_seconds.estimate, sol->hier_seconds.solve, sol->hier_seconds.output);
    printf("total      %.2f s, peak memory %s\n", rs->seconds, rr_size_text(rs->peak_bytes, peak, sizeof peak));
    if (app_mpi_ranks() > 1) {
        char sent[32];
        printf("mpi        %d ranks; rank 0 put %s into the exchanges (film merges, form-factor rows); rays above are its own\n",
               app_mpi_ranks(), rr_size_text(app_mpi_traffic(), sent, sizeof sent));
    }
}

/* render --stats FILE.json: the summary's numbers, by name. */
static int write_stats(const char *path, const render_args *A, const scene *sc, const ig_session *ses,
                       const render_stats *rs)
{
    char tmp[4200];
    rr_error err;
    FILE *f = NULL;
    if (rr_file_make_parent_dirs(path, &err) != RR_OK || rr_file_tmpname(path, tmp, sizeof tmp, &err) != RR_OK ||
        !(f = fopen(tmp, "w"))) {
        app_error("--stats %s: cannot write it", path);
        return -1;
    }
    const rad_solution *sol = ses->sol;
    fprintf(f, "{\"mode\": \"%s\", \"width\": %d, \"height\": %d, \"spp\": %d, \"seed\": %llu, ", A->ig->name,
            sc->view.width, sc->view.height, sc->settings.spp, (unsigned long long)sc->settings.seed);
    fprintf(f, "\"rays_closest\": %llu, \"rays_any_hit\": %llu, \"seconds_render\": %.6g, \"seconds\": %.6g, ",
            (unsigned long long)rs->rays.closest, (unsigned long long)rs->rays.occluded, rs->seconds_render,
            rs->seconds);
    fprintf(f, "\"mrays_per_second\": %.6g, \"peak_bytes\": %.0f, ",
            rs->seconds_render > 0
                ? ((double)rs->rays.closest + (double)rs->rays.occluded) * 1e-6 / rs->seconds_render
                : 0.0,
            rs->peak_bytes);
    /* hierarchical (hierarchical_links > 0): "patches" are its leaves,
     * "form_factors" its links, "seconds_form_factors" the refinement's */
    if (sol)
        fprintf(f, "\"patches\": %zu, \"form_factors\": %zu, \"radiosity_cached\": %s, "
                   "\"seconds_radiosity\": %.6g, \"seconds_patches\": %.6g, \"seconds_form_factors\": %.6g, "
                   "\"seconds_solve\": %.6g, \"solver_iterations\": %d, \"form_factor_rays\": %llu, "
                   "\"hierarchical_links\": %zu, \"hierarchical_receiving_clusters\": %zu, \"hierarchical_bytes\": %.0f, "
                   "\"hierarchical_seconds\": {\"setup\": %.6g, \"link\": %.6g, \"settle\": %.6g, \"regeo\": %.6g, "
                   "\"estimate\": %.6g, \"solve\": %.6g, \"output\": %.6g}}\n",
                sol->P->n, sol->nnz, ses->sol_cached ? "true" : "false", ses->seconds_pass, sol->seconds_patches,
                sol->seconds_ff, sol->seconds_solve, sol->stats.iterations,
                (unsigned long long)(sol->ff_rays.closest + sol->ff_rays.occluded), sol->links, sol->receiving_clusters,
                sol->pass_bytes,
                sol->hier_seconds.setup, sol->hier_seconds.link, sol->hier_seconds.settle, sol->hier_seconds.regeo,
                sol->hier_seconds.estimate, sol->hier_seconds.solve, sol->hier_seconds.output);
    else
        fprintf(f, "\"patches\": 0}\n");
    int bad = ferror(f);
    if (fclose(f) != 0 || bad || rename(tmp, path) != 0) {
        remove(tmp);
        app_error("--stats %s: write failed", path);
        return -1;
    }
    return 0;
}

/* The radiosity pass (when the mode runs it), the render, the outputs; the exit code. */
/* --frames: one radiosity solution (or its cache) for all; the frames
 * handed out to the ranks (each renders whole frames with its threads and
 * writes them: OUT.0001.exr, OUT.0001.png, ...). */
static int render_frames(const render_args *A, scene *sc, ig_session *ses, rt_film *film)
{
    rr_error err;
    rr_status st = ig_uses_pass(A->ig, sc) ? app_session_field(ses, A->quiet, &err) : RR_OK;
    if (st != RR_OK) { /* before the frame list opens: the caller ends every rank (app_mpi_abort) */
        app_error("%s", err.msg);
        return st == RR_ERR_INTERRUPTED ? APP_EXIT_INTERRUPTED
                                        : st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
    }
    rr_dist *dist = ses->dist;
    ses->dist = NULL; /* a frame is this rank's alone */
    long n = A->frame_last - A->frame_first + 1, local = 0, done = 0;
    if (dist)
        st = dist->begin(dist, n, &err);
    render_args F = *A;
    char exr[4300], png[4300];
    int rc = APP_EXIT_OK;
    size_t base = strlen(A->out_exr) - 4;
    while (st == RR_OK && rc == APP_EXIT_OK) {
        long i = dist ? (long)dist->next(dist) : (local < n ? local++ : -1);
        if (i < 0)
            break;
        int frame = (int)(A->frame_first + i);
        rr_view v;
        if ((st = scene_path_view(sc, frame, &v, &err)) != RR_OK)
            break;
        sc->view = v;
        rt_film_free(film);
        if ((st = rt_film_init(film, v.width, v.height, &err)) != RR_OK)
            break;
        double t0 = rr_now_seconds(), secs = 0;
        if ((st = ig_render(ses, A->ig, NULL, film, &secs, &err)) != RR_OK)
            break;
        app_scrub_film(film);
        snprintf(exr, sizeof exr, "%.*s.%04d.exr", (int)base, A->out_exr, frame);
        snprintf(png, sizeof png, "%.*s.%04d.png", (int)base, A->out_exr, frame);
        F.out_exr = exr, F.out_png = A->no_png ? NULL : png;
        if ((rc = write_outputs(&F, sc, ses, film, rr_now_seconds() - t0)) == APP_EXIT_OK && !A->quiet)
            printf("frame %d: %s (%.2f s)\n", frame, exr, secs);
        done++;
    }
    if (dist) {
        rr_status e = dist->end(dist, &err);
        if (st == RR_OK)
            st = e;
    }
    ses->dist = dist;
    if (st == RR_ERR_INTERRUPTED) {
        app_error("interrupted: %ld frame(s) of %ld written on this rank", done, n);
        return APP_EXIT_INTERRUPTED;
    }
    if (st != RR_OK) {
        app_error("%s", err.msg);
        return st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
    }
    if (rc == APP_EXIT_OK && !A->quiet)
        printf("rendered %ld frame(s) of %s (%ld here), mode %s\n", n, A->scene_path, done, A->ig->name);
    return rc;
}

static int render_and_write(const render_args *A, scene *sc, ig_session *ses, rt_film *film)
{
    rr_error err;
    double t0 = rr_now_seconds();
    app_progress prog = {!A->quiet && isatty(STDERR_FILENO), -1, t0, "rendering"};
    rr_status st = ig_uses_pass(A->ig, sc) ? app_session_field(ses, A->quiet, &err) : RR_OK;
    render_stats rs;
    memset(&rs, 0, sizeof rs);
    if (st == RR_OK) {
        ig_render_opts ro = {(rt_filter)A->filter, draw_progress, &prog, &rs.rays};
        prog.t0 = rr_now_seconds();
        st = ig_render(ses, A->ig, &ro, film, &rs.seconds_render, &err);
    }
    int writer = app_mpi_rank() == 0; /* under mpirun, rank 0 writes every output */
    if (st == RR_ERR_INTERRUPTED) {
        if (prog.enabled)
            fputc('\n', stderr);
        return writer ? write_partial(A, sc, film, &err) : APP_EXIT_INTERRUPTED;
    }
    if (st != RR_OK) {
        app_error("%s", err.msg);
        /* A scene the radiosity pass cannot take (reflectance >= 1, no
         * emitter) is bad input; running out of memory is not. */
        return st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
    }
    if (!writer)
        return APP_EXIT_OK;
    if (A->plot && write_plot(A, ses->sol) != 0)
        return APP_EXIT_RUNTIME;
    app_scrub_film(film);
    double secs = rr_now_seconds() - t0;
    int rc = write_outputs(A, sc, ses, film, secs);
    if (rc != APP_EXIT_OK)
        return rc;
    rs.seconds = rr_now_seconds() - t0;
    rs.peak_bytes = peak_rss_bytes();
    if (A->stats && write_stats(A->stats, A, sc, ses, &rs) != 0)
        return APP_EXIT_RUNTIME;
    if (!A->quiet) {
        print_summary(A, sc, film, secs);
        print_stats(ses, &rs);
    }
    return APP_EXIT_OK;
}

int app_cmd_render(int argc, char **argv)
{
    render_args A;
    memset(&A, 0, sizeof A);
    scene *sc = NULL;
    rt_film film;
    rt_accel *accel = NULL;
    ig_session ses;
    memset(&ses, 0, sizeof ses);
    memset(&film, 0, sizeof film);
    app_signals sig = {0};
    int rc = APP_EXIT_RUNTIME;
    rr_error err;
    if (!(A.sets = calloc((size_t)argc + 1, sizeof *A.sets))) {
        app_error("out of memory");
        return APP_EXIT_RUNTIME;
    }
    if ((rc = parse_args(&A, argc, argv)) >= 0)
        goto agree;
    if (app_mpi_rank() != 0)
        A.quiet = 1;
    rc = APP_EXIT_USAGE;
    if (!(sc = load_scene(&A)) || settle_outputs(&A, sc) != 0)
        goto agree;
    double pass_bytes = 0.0;
    if (app_check_memory(sc, A.ig, A.cache_path, aov_count(A.aovs), A.max_memory, &pass_bytes, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto agree;
    }
    rc = APP_EXIT_RUNTIME;
    if (rt_film_init(&film, sc->view.width, sc->view.height, &err) != RR_OK ||
        rt_accel_build(sc, &accel, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto agree;
    }
    rc = -1;
agree:
    /* Under mpirun every rank has read the input by now: all go on, or all
     * stop (before any collective work), with the message printed once. */
    {
        int all = app_mpi_agree(rc < 0 ? APP_EXIT_OK : rc);
        if (rc >= 0 || all != APP_EXIT_OK) {
            rc = rc >= 0 && rc > all ? rc : all;
            goto done;
        }
    }
    app_diagnose_light(sc, accel);
    app_session_init(&ses, sc, accel, A.cache_path);
    ses.pass.hier.max_bytes = pass_bytes;
    ses.dist = app_mpi_dist();
    app_signals_catch(&sig); /* SIGINT and SIGTERM stop the same way (app_stop says which) */
    rc = A.frame_first ? render_frames(&A, sc, &ses, &film) : render_and_write(&A, sc, &ses, &film);
    app_mpi_abort(rc); /* a failure on one rank must not leave the others waiting */
done:
    app_signals_restore(&sig);
    rt_film_free(&film);
    ig_session_free(&ses);
    rt_accel_destroy(accel);
    scene_destroy(sc);
    for (size_t i = 0; i < A.nsets; i++)
        free(A.sets[i]);
    free(A.sets);
    return rc;
}
