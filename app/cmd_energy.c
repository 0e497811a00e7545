/* cmd_energy.c - `radray energy SCENE`: the energy ledger of the radiosity
 * solution: where the emitted power went, per surface and in total. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"
#include "rad.h"

static const char energy_usage[] =
    "usage: radray energy SCENE [options]\n"
    "\n"
    "Runs the radiosity pass on SCENE and prints, per object and in total, the\n"
    "power emitted, incident, reflected (diffusely), mirrored (reflected on by mirrors),\n"
    "absorbed and escaped (through openings),\n"
    "and checks the balance: emitted = absorbed + escaped.\n"
    "Power is radiosity x area: scene emission Le (radiance) emits pi Le per unit area.\n"
    "\n"
    "options:\n"
    "      --json             machine-readable output (RGB triples)\n"
    "      --patch-area A     largest patch area\n"
    "      --patch-edge L     longest patch edge\n"
    "      --solver S         auto, direct or iterative\n"
    "      --ff METHOD        montecarlo or quadrature\n"
    "      --ff-samples N     rays or points per patch\n"
    "      --set KEY=VALUE    override a scene value by its JSON path (repeatable)\n"
    "      --max-memory SIZE  refuse, before any work, a pass estimated to need more memory than\n"
    "                         SIZE, e.g. 512M, 4G (default: half the physical memory)\n"
    "  -h, --help             show this help\n"
    "\n"
    "Exit codes: 0 ok (balance holds), 1 runtime error or balance broken, 2 usage error or bad input.\n";

static void json_rgb(const char *key, rr_rgb c, int last)
{
    printf("\"%s\": [%.10g, %.10g, %.10g]%s", key, c.r, c.g, c.b, last ? "" : ", ");
}

static void json_string(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        if (*s == '"' || *s == '\\')
            printf("\\%c", *s);
        else if ((unsigned char)*s < 0x20)
            printf("\\u%04x", *s);
        else
            putchar(*s);
    }
    putchar('"');
}

int app_cmd_energy(int argc, char **argv)
{
    enum { O_JSON = 256, O_AREA, O_EDGE, O_SOLVER, O_FF, O_SAMPLES, O_SET, O_MAXMEM };
    static const struct option longopts[] = {
        {"json", no_argument, NULL, O_JSON},         {"patch-area", required_argument, NULL, O_AREA},
        {"patch-edge", required_argument, NULL, O_EDGE}, {"solver", required_argument, NULL, O_SOLVER},
        {"ff", required_argument, NULL, O_FF},       {"ff-samples", required_argument, NULL, O_SAMPLES},
        {"set", required_argument, NULL, O_SET},     {"help", no_argument, NULL, 'h'},
        {"max-memory", required_argument, NULL, O_MAXMEM},
        {NULL, 0, NULL, 0}};
    static const char *const keys[] = {"radiosity.patch_area", "radiosity.patch_edge", "radiosity.solver",
                                       "radiosity.form_factors", "radiosity.ff_samples"};
    char **sets = calloc((size_t)argc + 1, sizeof *sets);
    size_t nsets = 0;
    int json = 0, rc = APP_EXIT_USAGE;
    scene *s = NULL;
    rt_accel *a = NULL;
    rad_solution *sol = NULL;
    rad_energy_row *rows = NULL;
    size_t nrows = 0;
    size_t max_memory = app_default_max_memory();
    if (!sets) {
        app_error("out of memory");
        return APP_EXIT_RUNTIME;
    }
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":h", longopts, NULL)) != -1) {
        if (c == 'h') {
            fputs(energy_usage, stdout);
            rc = APP_EXIT_OK;
            goto done;
        } else if (c == O_JSON) {
            json = 1;
        } else if (c >= O_AREA && c <= O_SAMPLES) {
            size_t n = strlen(keys[c - O_AREA]) + strlen(optarg) + 2;
            if ((sets[nsets] = malloc(n)) != NULL)
                snprintf(sets[nsets], n, "%s=%s", keys[c - O_AREA], optarg);
            nsets++;
        } else if (c == O_MAXMEM) {
            if (app_parse_size(optarg, &max_memory)) {
                app_error("--max-memory: expected a size such as 512M or 4G, got '%s'", optarg);
                goto done;
            }
        } else if (c == O_SET) {
            sets[nsets++] = strdup(optarg);
        } else if (c == ':') {
            app_error("option '%s' needs a value (try 'radray energy --help')", argv[optind - 1]);
            goto done;
        } else {
            app_error("unknown option '%s' (try 'radray energy --help')", argv[optind - 1]);
            goto done;
        }
    }
    for (size_t i = 0; i < nsets; i++)
        if (!sets[i]) {
            app_error("out of memory");
            rc = APP_EXIT_RUNTIME;
            goto done;
        }
    if (optind != argc - 1) {
        app_error("energy: expected one SCENE (try 'radray energy --help')");
        goto done;
    }
    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = (const char *const *)sets;
    lo.noverrides = nsets;
    lo.warn = app_warn_sink();
    lo.max_image_bytes = max_memory;
    if (scene_load(argv[optind], &lo, &s, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    app_pipeline mem;
    memset(&mem, 0, sizeof mem);
    mem.sc = s;
    if (app_check_memory(&mem, APP_MODE_RADIOSITY, -1, max_memory, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    rc = APP_EXIT_RUNTIME;
    if (rt_accel_build(s, &a, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    po.warn = app_warn_sink();
    po.ff.seed = s->settings.seed;
    po.ff.threads = s->settings.threads;
    rr_status st = rad_pass_run(s, a, &po, &sol, &err);
    if (st == RR_OK)
        st = rad_energy(s, sol->P, sol->F, sol->B, &rows, &nrows, &err);
    if (st != RR_OK) {
        app_error("%s", err.msg);
        rc = st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
        goto done;
    }
    const rad_energy_row *t = &rows[nrows - 1];
    double worst = 0;
    for (int ch = 0; ch < 3; ch++) {
        double e = ch == 0 ? t->emitted.r : (ch == 1 ? t->emitted.g : t->emitted.b);
        double ab = ch == 0 ? t->absorbed.r + t->escaped.r
                            : (ch == 1 ? t->absorbed.g + t->escaped.g : t->absorbed.b + t->escaped.b);
        double rel = e > 0 ? fabs(e - ab) / e : fabs(ab);
        worst = rel > worst ? rel : worst;
    }
    /* The balance holds to the solver's residual; allow a generous multiple. */
    double tol = fmax(1e-6, 100.0 * sol->stats.residual);
    if (json) {
        printf("{\"scene\": ");
        json_string(s->path);
        printf(", \"patches\": %zu, \"form_factors\": %zu, \"solver\": \"%s\", \"iterations\": %d, "
               "\"residual\": %.3g, \"balance_relative_error\": %.3g, \"balanced\": %s, \"rows\": [",
               sol->P->n, sol->nnz, sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative",
               sol->stats.iterations, sol->stats.residual, worst, worst <= tol ? "true" : "false");
        for (size_t i = 0; i < nrows; i++) {
            printf("%s{\"name\": ", i ? ", " : "");
            json_string(rows[i].name);
            printf(", \"area\": %.10g, ", rows[i].area);
            json_rgb("emitted", rows[i].emitted, 0);
            json_rgb("incident", rows[i].incident, 0);
            json_rgb("reflected", rows[i].reflected, 0);
            json_rgb("mirrored", rows[i].mirrored, 0);
            json_rgb("absorbed", rows[i].absorbed, 0);
            json_rgb("escaped", rows[i].escaped, 1);
            printf("}");
        }
        printf("]}\n");
    } else {
        printf("energy ledger of %s: %zu patches, %zu form factors, %s solver, residual %.2g\n", s->path, sol->P->n,
               sol->nnz, sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative", sol->stats.residual);
        printf("power = radiosity x area (scene units), mean of R, G, B\n\n");
        printf("%-18s %12s %12s %12s %12s %12s %12s %12s\n", "surface", "area", "emitted", "incident", "reflected",
               "mirrored", "absorbed", "escaped");
        for (size_t i = 0; i < nrows; i++) {
            const rad_energy_row *r = &rows[i];
            if (i == nrows - 1)
                printf("%s\n", "------------------------------------------------------------------------------------"
                               "--------------------------------------------");
            printf("%-18s %12.5g %12.5g %12.5g %12.5g %12.5g %12.5g %12.5g\n", r->name, r->area,
                   rr_rgb_mean(r->emitted), rr_rgb_mean(r->incident), rr_rgb_mean(r->reflected),
                   rr_rgb_mean(r->mirrored), rr_rgb_mean(r->absorbed), rr_rgb_mean(r->escaped));
        }
        printf("\nbalance: emitted = absorbed + escaped to %.2g (relative, worst channel): %s\n", worst,
               worst <= tol ? "holds" : "BROKEN");
    }
    rc = worst <= tol ? APP_EXIT_OK : APP_EXIT_RUNTIME;
done:
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
    for (size_t i = 0; i < nsets; i++)
        free(sets[i]);
    free(sets);
    return rc;
}
