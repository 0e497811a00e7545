/* cmd_render.c - `radray render SCENE`: load, render, write EXR + PNG. */
#include <getopt.h>
#include <signal.h>
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
    "  -o, --output FILE.exr  EXR output (default out/<scene name>.exr)\n"
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
    "      --indirect KIND    what supplies diffuse interreflection, everything else equal:\n"
    "                         radiosity|secondary|ambient|none\n"
    "                         (overrides the mode's choice)\n"
    "      --filter F         pixel filter for supersampling: box (default) or tent\n"
    "radiosity options (override the scene's \"radiosity\" block):\n"
    "      --patch-area A     largest patch area (scene units squared)\n"
    "      --patch-edge L     longest patch edge\n"
    "      --solver S         auto, direct (CHOLMOD) or iterative (Gauss-Seidel)\n"
    "      --ff METHOD        form factors: montecarlo or quadrature\n"
    "      --ff-samples N     rays or sample points per patch\n"
    "      --plot FILE        write the solver's convergence (residual per iteration) as PNG or SVG\n"
    "      --radiosity-cache FILE  reuse the radiosity solution saved in FILE (made there when\n"
    "                         missing); one made for another scene or other settings is refused\n"
    "      --set KEY=VALUE    override any scene value by its JSON path, e.g.\n"
    "                         --set render.spp=16 --set materials.white.diffuse=[0.7,0.7,0.7]\n"
    "                         (repeatable; VALUE is JSON, or a string)\n"
    "      --max-memory SIZE  refuse, before any work, a render estimated to need more memory\n"
    "                         (film, BVH, radiosity patches and form factors) than SIZE,\n"
    "                         e.g. 512M, 4G (default: half the physical memory)\n"
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
    "--max-memory included), 130 interrupted, 143 terminated.\n";

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
    OPT_MAX_MEMORY
};

int app_cmd_render(int argc, char **argv)
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
        {"max-memory", required_argument, NULL, OPT_MAX_MEMORY},
        {NULL, 0, NULL, 0}};
    const char *out_exr = NULL, *out_png = NULL, *plot = NULL;
    int no_png = 0, quiet = 0;
    long width = 0;
    static const char *const filters[] = {"box", "tent", NULL};
    int mode = APP_MODE_HYBRID, indirect = -1, filter = RT_FILTER_BOX;
    /* Overrides: one per --set, plus those the shorthand options expand to. */
    char **sets = calloc((size_t)argc + 1, sizeof *sets);
    size_t nsets = 0;
    int rc = APP_EXIT_USAGE;
    scene *sc = NULL;
    rt_film film;
    rt_accel *accel = NULL;
    app_pipeline pl;
    memset(&pl, 0, sizeof pl);
    memset(&film, 0, sizeof film);
    char exr_default[4200], png_default[4200], partial[4200];
    size_t max_memory = app_default_max_memory();
    app_signals sig = {0};
    if (!sets) {
        app_error("out of memory");
        return APP_EXIT_RUNTIME;
    }

    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":o:qh", longopts, NULL)) != -1) {
        const char *key = NULL;
        switch (c) {
        case 'o': out_exr = optarg; break;
        case OPT_PNG: out_png = optarg; break;
        case OPT_NO_PNG: no_png = 1; break;
        case OPT_PLOT: plot = optarg; break;
        case OPT_CACHE: pl.cache_path = optarg; break;
        case 'q': quiet = 1; break;
        case 'h':
            fputs(render_usage, stdout);
            rc = APP_EXIT_OK;
            goto done;
        case OPT_WIDTH:
            if (app_parse_int(optarg, 1, 1 << 21, &width)) {
                app_error("--width: expected an integer in [1, %d], got '%s'", 1 << 21, optarg);
                goto done;
            }
            break;
        case OPT_MAX_MEMORY:
            if (app_parse_size(optarg, &max_memory)) {
                app_error("--max-memory: expected a size such as 512M or 4G, got '%s'", optarg);
                goto done;
            }
            break;
        case OPT_MODE:
            if ((mode = app_pick(optarg, app_mode_names)) < 0) {
                app_error("--mode: expected hybrid, whitted, secondary or radiosity, got '%s'", optarg);
                goto done;
            }
            break;
        case OPT_INDIRECT:
            if ((indirect = app_pick(optarg, app_indirect_names)) < 0) {
                app_error("--indirect: expected radiosity, secondary, ambient or none, got '%s'", optarg);
                goto done;
            }
            break;
        case OPT_FILTER:
            if ((filter = app_pick(optarg, filters)) < 0) {
                app_error("--filter: expected box or tent, got '%s'", optarg);
                goto done;
            }
            break;
        case OPT_PATCH_AREA: key = "radiosity.patch_area"; break;
        case OPT_PATCH_EDGE: key = "radiosity.patch_edge"; break;
        case OPT_SOLVER: key = "radiosity.solver"; break;
        case OPT_FF: key = "radiosity.form_factors"; break;
        case OPT_FF_SAMPLES: key = "radiosity.ff_samples"; break;
        case OPT_SPP: key = "render.spp"; break;
        case OPT_SEED: key = "render.seed"; break;
        case OPT_THREADS: key = "render.threads"; break;
        case OPT_EXPOSURE: key = "render.exposure"; break;
        case OPT_HALF: key = "render.half_float"; break;
        case OPT_SET:
            sets[nsets++] = strdup(optarg);
            break;
        case ':':
            app_error("option '%s' needs a value (try 'radray render --help')", argv[optind - 1]);
            goto done;
        default:
            app_error("unknown option '%s' (try 'radray render --help')", argv[optind - 1]);
            goto done;
        }
        if (key) {
            const char *val = c == OPT_HALF ? "true" : optarg;
            size_t n = strlen(key) + strlen(val) + 2;
            sets[nsets] = malloc(n);
            if (sets[nsets])
                snprintf(sets[nsets], n, "%s=%s", key, val);
            nsets++;
        }
    }
    for (size_t i = 0; i < nsets; i++)
        if (!sets[i]) {
            app_error("out of memory");
            rc = APP_EXIT_RUNTIME;
            goto done;
        }
    if (optind != argc - 1) {
        app_error(optind >= argc ? "render: missing SCENE (try 'radray render --help')"
                                 : "render: expected one SCENE, got extra arguments (try 'radray render --help')");
        goto done;
    }
    const char *scene_path = argv[optind];

    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = (const char *const *)sets;
    lo.noverrides = nsets;
    lo.warn = app_warn_sink();
    lo.max_image_bytes = max_memory;
    if (scene_load(scene_path, &lo, &sc, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    app_diagnose_scene(sc);
    if (width > 0) {
        rr_view v;
        if (rr_view_resize(&sc->view, (int)width, &v, &err) != RR_OK) {
            app_error("--width: %s", err.msg);
            goto done;
        }
        sc->view = v;
    }

    /* Output names: out/<scene name>.exr by default, PNG beside the EXR. */
    if (!out_exr) {
        const char *base = strrchr(scene_path, '/');
        base = base ? base + 1 : scene_path;
        size_t n = strcspn(base, ".");
        snprintf(exr_default, sizeof exr_default, "out/%.*s.exr", (int)n, base);
        out_exr = exr_default;
    }
    if (!app_ends_with(out_exr, ".exr")) {
        app_error("-o %s: the output must end in .exr (the PNG preview is written beside it)", out_exr);
        goto done;
    }
    if (!out_png && !no_png) {
        snprintf(png_default, sizeof png_default, "%.*s.png", (int)(strlen(out_exr) - 4), out_exr);
        out_png = png_default;
    }
    snprintf(partial, sizeof partial, "%.*s.partial.exr", (int)(strlen(out_exr) - 4), out_exr);
    {
        const char *ins[64];
        size_t nin = app_scene_inputs(sc, ins, 63);
        ins[nin++] = pl.cache_path;
        const char *outs[4] = {out_exr, no_png ? NULL : out_png, plot, partial};
        const char *what[4] = {"-o", "--png", "--plot", "the partial image"};
        if (app_check_outputs(outs, what, 4, ins, nin))
            goto done;
    }
    if (plot && mode != APP_MODE_RADIOSITY && app_mode_indirect(mode, indirect) != RT_INDIRECT_RADIOSITY) {
        app_error("--plot: the convergence plot belongs to the radiosity pass: use it with --mode radiosity");
        goto done;
    }
    pl.sc = sc;
    pl.quiet = quiet;
    pl.interrupt = &app_stop;
    if (app_check_memory(&pl, mode, indirect, max_memory, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    if (rt_film_init(&film, sc->view.width, sc->view.height, &err) != RR_OK ||
        rt_accel_build(sc, &accel, &err) != RR_OK) {
        app_error("%s", err.msg);
        rc = APP_EXIT_RUNTIME;
        goto done;
    }
    app_diagnose_light(sc, accel);

    app_progress prog = {!quiet && isatty(STDERR_FILENO), -1, rr_now_seconds(), "rendering"};
    rc = APP_EXIT_RUNTIME;
    pl.accel = accel;
    app_signals_catch(&sig); /* SIGINT and SIGTERM stop the same way (app_stop says which) */
    rr_status rst = app_render_mode(&pl, mode, indirect, filter, &film, NULL, draw_progress, &prog, &err);
    if (rst == RR_ERR_INTERRUPTED) {
        if (prog.enabled)
            fputc('\n', stderr);
        app_scrub_film(&film);
        img_layer pl_layers[RT_LAYER_COUNT];
        for (int i = 0; i < RT_LAYER_COUNT; i++) {
            pl_layers[i].name = rt_layer_name(i);
            pl_layers[i].image = &film.layer[i];
        }
        rr_error werr;
        if (img_write_exr(partial, &film.beauty, pl_layers, RT_LAYER_COUNT,
                          sc->settings.half_float ? IMG_HALF : IMG_FLOAT, &werr) != RR_OK) {
            app_error("%s; the partial image could not be written either: %s", err.msg, werr.msg);
            rc = APP_EXIT_RUNTIME;
        } else {
            app_error("%s; wrote the partial image (unfinished tiles black) to %s", err.msg, partial);
            rc = app_stop == SIGTERM ? APP_EXIT_TERMINATED : APP_EXIT_INTERRUPTED;
        }
        goto done;
    }
    if (rst != RR_OK) {
        app_error("%s", err.msg);
        /* A scene the radiosity pass cannot take (reflectance >= 1, no
         * emitter) is bad input; running out of memory is not. */
        rc = rst == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
        goto done;
    }
    if (plot && pl.sol && pl.sol->stats.nhistory > 0) {
        char title[128];
        snprintf(title, sizeof title, "Gauss-Seidel residual, %zu patches", pl.sol->P->n);
        if (app_plot_residuals(plot, pl.sol->stats.history, pl.sol->stats.nhistory, title, &err) != 0) {
            app_error("%s", err.msg);
            goto done;
        }
        if (!quiet)
            printf("wrote %s (convergence plot)\n", plot);
    } else if (plot) {
        fprintf(stderr, "radray: warning: --plot: the direct solver has no iterations to plot "
                        "(use --solver iterative)\n");
    }
    app_scrub_film(&film);
    double secs = rr_now_seconds() - prog.t0;
    if (app_write_film(out_exr, no_png ? NULL : out_png, &film, sc->settings.half_float, sc->settings.exposure,
                       &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    if (!quiet) {
        printf("rendered %s: %d x %d, %d spp, indirect %s, %.2f s\n", scene_path, film.beauty.width,
               film.beauty.height, sc->settings.spp, mode == APP_MODE_RADIOSITY ? "radiosity display" : app_indirect_names[app_mode_indirect(mode, indirect)], secs);
        printf("wrote %s (linear %s RGB; layers", out_exr, sc->settings.half_float ? "half" : "float");
        for (int i = 0; i < RT_LAYER_COUNT; i++)
            printf(" %s", rt_layer_name(i));
        printf(")\n");
        if (!no_png)
            printf("wrote %s (sRGB preview, exposure %+g)\n", out_png, sc->settings.exposure);
    }
    rc = APP_EXIT_OK;
done:
    app_signals_restore(&sig);
    rt_film_free(&film);
    rad_solution_destroy(pl.sol);
    rt_accel_destroy(accel);
    scene_destroy(sc);
    for (size_t i = 0; i < nsets; i++)
        free(sets[i]);
    free(sets);
    return rc;
}
