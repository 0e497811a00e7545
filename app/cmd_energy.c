/* cmd_energy.c - `radray energy SCENE`: where the emitted power went, by two
 * independent estimators (the radiosity pass's ledger and a light tracer's),
 * compared per object; `--check` turns the comparison into an exit code.
 * Definitions of every column: notes/energy.md. */
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "app.h"
#include "rad.h"

static const char energy_usage[] =
    "usage: radray energy SCENE [options]\n"
    "\n"
    "Where the emitted power goes, by two independent estimators:\n"
    "  the radiosity ledger     from the radiosity pass's solution (B = E + rho F B);\n"
    "  the light-tracing ledger particles emitted by every emitter in proportion to its power\n"
    "                           and scattered by each material (diffuse, mirror; Russian roulette),\n"
    "                           with standard errors from independent batches.\n"
    "Per object: emitted, incident (arriving at front faces), reflected (diffusely), mirrored,\n"
    "absorbed; light tracing also: back (arriving at back faces, where it ends: surfaces are\n"
    "one-sided in the radiosity pass). In total: escaped (radiosity: landed on no patch's front;\n"
    "light tracing: left the scene + back faces + lost). Power = radiosity x area, in scene units;\n"
    "point lights emit 4 pi I, directional lights E pi R^2 (R: the scene's bounding radius).\n"
    "Tables show the mean of R, G, B; --json has the triples. Definitions: notes/energy.md.\n"
    "\n"
    "options:\n"
    "      --check            exit 1 unless the ledgers agree: every object (and light) above 0.1 %\n"
    "                         of the emitted power within 4 standard errors + the allowance in\n"
    "                         emitted, incident and absorbed power, the total escaped likewise,\n"
    "                         and no power created (escaped below 0)\n"
    "      --allowance PCT    discretisation allowance of the radiosity pass, percent (default 1)\n"
    "      --particles N      light-tracing particles (default 1000000; 0: radiosity ledger only)\n"
    "      --batches N        batches for the standard errors (default 32)\n"
    "      --seed N           seed of the light tracer (default: the scene's)\n"
    "      --threads N        threads (default: the scene's, else all)\n"
    "      --json             machine-readable output\n"
    "      --patch-area A     largest patch area\n"
    "      --patch-edge L     longest patch edge\n"
    "      --solver S         auto, direct or iterative\n"
    "      --ff METHOD        montecarlo or quadrature\n"
    "      --ff-samples N     rays or points per patch\n"
    "      --set KEY=VALUE    override a scene value by its JSON path (repeatable)\n"
    "      --max-memory SIZE  refuse, before any work, a pass estimated to need more memory than\n"
    "                         SIZE, e.g. 512M, 4G (default: half the physical memory);\n"
    "                         the hierarchical pass stays under it while it refines\n"
    "  -q, --quiet            no progress bar\n"
    "  -h, --help             show this help\n"
    "\n"
    "Warnings name causes of lost light: an emitter inside a closed object facing outwards, light\n"
    "ending on back faces, power created by the form factors.\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error, balance broken or (with --check) the ledgers disagree,\n"
    "2 usage error or bad input, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).\n";

typedef struct energy_args {
    const char *path;
    char **sets;
    size_t nsets;
    int json, check, quiet;
    long particles, batches, threads;
    long long seed; /* < 0: the scene's */
    double allowance;
    size_t max_memory;
} energy_args;

static void json_rgb(const char *key, rr_rgb c, int last)
{
    printf("\"%s\": [%.10g, %.10g, %.10g]%s", key, c.r, c.g, c.b, last ? "" : ", ");
}

/* 0: go on; else the exit code. */
static int parse_args(int argc, char **argv, energy_args *A)
{
    enum { O_JSON = 256, O_AREA, O_EDGE, O_SOLVER, O_FF, O_SAMPLES, O_SET, O_MAXMEM, O_CHECK, O_ALLOW, O_PARTICLES,
           O_BATCHES, O_SEED, O_THREADS };
    static const struct option longopts[] = {
        {"json", no_argument, NULL, O_JSON},         {"patch-area", required_argument, NULL, O_AREA},
        {"patch-edge", required_argument, NULL, O_EDGE}, {"solver", required_argument, NULL, O_SOLVER},
        {"ff", required_argument, NULL, O_FF},       {"ff-samples", required_argument, NULL, O_SAMPLES},
        {"set", required_argument, NULL, O_SET},     {"help", no_argument, NULL, 'h'},
        {"max-memory", required_argument, NULL, O_MAXMEM}, {"check", no_argument, NULL, O_CHECK},
        {"allowance", required_argument, NULL, O_ALLOW}, {"particles", required_argument, NULL, O_PARTICLES},
        {"batches", required_argument, NULL, O_BATCHES}, {"seed", required_argument, NULL, O_SEED},
        {"threads", required_argument, NULL, O_THREADS}, {"quiet", no_argument, NULL, 'q'},
        {NULL, 0, NULL, 0}};
    static const char *const keys[] = {"radiosity.patch_area", "radiosity.patch_edge", "radiosity.solver",
                                       "radiosity.form_factors", "radiosity.ff_samples"};
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":hq", longopts, NULL)) != -1) {
        long v;
        char *end;
        if (c == 'h') {
            fputs(energy_usage, stdout);
            return APP_EXIT_OK + 1000;
        } else if (c == 'q') {
            A->quiet = 1;
        } else if (c == O_JSON) {
            A->json = 1;
        } else if (c == O_CHECK) {
            A->check = 1;
        } else if (c >= O_AREA && c <= O_SAMPLES) {
            size_t n = strlen(keys[c - O_AREA]) + strlen(optarg) + 2;
            if ((A->sets[A->nsets] = malloc(n)) != NULL)
                snprintf(A->sets[A->nsets], n, "%s=%s", keys[c - O_AREA], optarg);
            A->nsets++;
        } else if (c == O_SET) {
            A->sets[A->nsets++] = strdup(optarg);
        } else if (c == O_MAXMEM) {
            if (app_parse_size(optarg, &A->max_memory)) {
                app_error("--max-memory: expected a size such as 512M or 4G, got '%s'", optarg);
                return APP_EXIT_USAGE;
            }
        } else if (c == O_ALLOW) {
            A->allowance = strtod(optarg, &end);
            if (end == optarg || *end || !(A->allowance >= 0.0 && A->allowance <= 100.0)) {
                app_error("--allowance: expected a percentage in [0, 100], got '%s'", optarg);
                return APP_EXIT_USAGE;
            }
        } else if (c == O_PARTICLES || c == O_BATCHES || c == O_THREADS) {
            long lo = c == O_BATCHES ? 2 : c == O_THREADS ? 1 : 0;
            long hi = c == O_PARTICLES ? 1L << 40 : c == O_BATCHES ? 1024 : 4096;
            if (app_parse_int(optarg, lo, hi, &v)) {
                const char *name = c == O_PARTICLES ? "--particles" : c == O_BATCHES ? "--batches" : "--threads";
                app_error("%s: expected a whole number in [%ld, %ld], got '%s'", name, lo, hi, optarg);
                return APP_EXIT_USAGE;
            }
            *(c == O_PARTICLES ? &A->particles : c == O_BATCHES ? &A->batches : &A->threads) = v;
        } else if (c == O_SEED) {
            if (app_parse_int(optarg, 0, 2147483647L, &v)) {
                app_error("--seed: expected a whole number in [0, 2147483647], got '%s'", optarg);
                return APP_EXIT_USAGE;
            }
            A->seed = v;
        } else if (c == ':') {
            app_error("option '%s' needs a value (try 'radray energy --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        } else {
            app_error("unknown option '%s' (try 'radray energy --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        }
    }
    for (size_t i = 0; i < A->nsets; i++)
        if (!A->sets[i]) {
            app_error("out of memory");
            return APP_EXIT_RUNTIME;
        }
    if (optind != argc - 1) {
        app_error("energy: expected one SCENE (try 'radray energy --help')");
        return APP_EXIT_USAGE;
    }
    if (A->particles > 0 && A->particles < A->batches) {
        app_error("--particles: need at least one particle per batch (%ld)", A->batches);
        return APP_EXIT_USAGE;
    }
    A->path = argv[optind];
    return 0;
}

static void particle_progress(void *user, uint64_t done, uint64_t total)
{
    app_pass_progress(user, (size_t)done, (size_t)total);
}

/* The radiosity balance: emitted = absorbed + escaped up to the solver. */
static double balance_error(const rad_energy_row *t)
{
    rr_rgb e = t->emitted, s = rr_rgb_add(t->absorbed, t->escaped);
    double worst = 0;
    double ev[3] = {e.r, e.g, e.b}, sv[3] = {s.r, s.g, s.b};
    for (int ch = 0; ch < 3; ch++) {
        double rel = ev[ch] > 0 ? fabs(ev[ch] - sv[ch]) / ev[ch] : fabs(sv[ch]);
        worst = rel > worst ? rel : worst;
    }
    return worst;
}

typedef struct energy_result {
    const scene *s;
    ig_session ses;          /* the radiosity pass, as render runs it */
    const rad_solution *sol; /* ses.sol */
    rad_energy_row *rows;
    size_t nrows;
    rt_particle_ledger g; /* g.row NULL: no light tracing */
    rad_energy_cmp *cmp;
    size_t ncmp, failures;
    double balance, balance_tol;
    int created;          /* escaped below 0 beyond the solver's tolerance */
    double allowance;
    double pass_bytes;    /* what --max-memory leaves the pass (rad_hier_opts.max_bytes) */
} energy_result;

static const char *column_name(int c)
{
    return c == RT_LEDGER_EMITTED    ? "emitted"
           : c == RT_LEDGER_INCIDENT ? "incident"
           : c == RT_LEDGER_ABSORBED ? "absorbed"
                                     : "escaped";
}

static void print_text(const energy_result *R)
{
    const rad_solution *sol = R->sol;
    printf("energy ledger of %s: %zu patches, %zu form factors, %s solver, residual %.2g\n", R->s->path, sol->P->n,
           sol->nnz, sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative", sol->stats.residual);
    printf("power = radiosity x area (scene units), mean of R, G, B\n\nradiosity ledger\n");
    printf("%-18s %12s %12s %12s %12s %12s %12s %12s\n", "surface", "area", "emitted", "incident", "reflected",
           "mirrored", "absorbed", "escaped");
    for (size_t i = 0; i < R->nrows; i++) {
        const rad_energy_row *r = &R->rows[i];
        if (i == R->nrows - 1)
            printf("%.*s\n", 18 + 7 * 13, "-------------------------------------------------------------------"
                                         "------------------------------------------------------------");
        printf("%-18s %12.5g %12.5g %12.5g %12.5g %12.5g %12.5g %12.5g\n", r->name, r->area, rr_rgb_mean(r->emitted),
               rr_rgb_mean(r->incident), rr_rgb_mean(r->reflected), rr_rgb_mean(r->mirrored),
               rr_rgb_mean(r->absorbed), rr_rgb_mean(r->escaped));
    }
    printf("\nbalance: emitted = absorbed + escaped to %.2g (relative, worst channel): %s\n", R->balance,
           R->balance <= R->balance_tol ? "holds" : "BROKEN");
    const rt_particle_ledger *g = &R->g;
    if (!g->row)
        return;
    printf("\nlight-tracing ledger: %llu particles in %d batches, %.3g rays, %.2f s (%.3g particles/s)\n",
           (unsigned long long)g->particles, g->batches, (double)g->segments, g->seconds,
           (double)g->particles / fmax(g->seconds, 1e-9));
    printf("%-18s %12s %12s %12s %12s %12s %12s %10s\n", "surface", "emitted", "incident", "reflected", "mirrored",
           "absorbed", "back", "SE(abs.)");
    for (size_t r = 0; r < g->nobjects + g->nlights; r++) {
        const rt_ledger_row *x = &g->row[r];
        int any = 0;
        for (int c = 0; c < RT_LEDGER_COLUMNS; c++)
            any |= rr_rgb_max(x->c[c]) > 0.0;
        if (!any)
            continue;
        const char *name = r < g->nobjects ? R->s->objects[r].name : R->s->lights[r - g->nobjects].name;
        printf("%-18s %12.5g %12.5g %12.5g %12.5g %12.5g %12.5g %10.2g\n", name,
               rr_rgb_mean(x->c[RT_LEDGER_EMITTED]), rr_rgb_mean(x->c[RT_LEDGER_INCIDENT]),
               rr_rgb_mean(x->c[RT_LEDGER_REFLECTED]), rr_rgb_mean(x->c[RT_LEDGER_MIRRORED]),
               rr_rgb_mean(x->c[RT_LEDGER_ABSORBED]), rr_rgb_mean(x->c[RT_LEDGER_BACK]),
               rr_rgb_mean(g->se[r].c[RT_LEDGER_ABSORBED]));
    }
    printf("escaped: %.5g left the scene, %.5g lost (bounce cap); radiosity's escaped compares with %.5g +- %.2g "
           "(left + back faces + lost)\n",
           rr_rgb_mean(g->escaped), rr_rgb_mean(g->lost), rr_rgb_mean(g->unabsorbed), rr_rgb_mean(g->unabsorbed_se));
    size_t checked = 0;
    double worst_z = 0.0;
    for (size_t i = 0; i < R->ncmp; i++)
        if (R->cmp[i].checked) {
            checked++;
            worst_z = fmax(worst_z, R->cmp[i].z);
        }
    printf("\ncheck: %zu comparisons above 0.1 %% of the emitted power, within 4 SE + %.3g %%: ", checked,
           100.0 * R->allowance);
    if (R->failures)
        printf("%zu DISAGREE\n", R->failures);
    else
        printf("all agree (largest |difference| %.2g SE)\n", worst_z);
    for (size_t i = 0; i < R->ncmp; i++) {
        const rad_energy_cmp *c = &R->cmp[i];
        if (c->checked && !c->pass && c->part != 0.0)
            printf("  %-18s %-8s radiosity %.5g, light tracing %.5g +- %.2g: %+.2f %%, %.1f SE\n", c->name,
                   column_name(c->column), c->rad, c->part, c->se, 100.0 * (c->rad - c->part) / fabs(c->part), c->z);
        else if (c->checked && !c->pass) /* nothing to be relative to: say it against the emitted power */
            printf("  %-18s %-8s radiosity %.5g, light tracing 0 +- %.2g: %+.3g %% of the emitted power\n", c->name,
                   column_name(c->column), c->rad, c->se,
                   100.0 * c->rad / fmax(rr_rgb_mean(R->rows[R->nrows - 1].emitted), 1e-300));
    }
    if (R->created)
        printf("  power created: the radiosity ledger's escaped power is below 0\n");
}

/* The mirrors' share and power created, on stderr (both outputs). */
static void report_shares(const energy_result *R)
{
    const rad_energy_row *t = &R->rows[R->nrows - 1];
    double e = rr_rgb_mean(t->emitted);
    rr_warn_sink w = app_warn_sink();
    if (R->created)
        rr_warn(&w,
                "%s: the radiosity ledger creates power: escaped %.4g of %.4g emitted is below 0 (form-factor rows "
                "summing above 1: quadrature form factors, or too few Monte Carlo rays)",
                R->s->path, rr_rgb_mean(t->escaped), e);
    double mr = rr_rgb_mean(t->mirrored), mp = 0.0;
    for (size_t r = 0; R->g.row && r < R->g.nobjects + R->g.nlights; r++)
        mp += rr_rgb_mean(R->g.row[r].c[RT_LEDGER_MIRRORED]);
    if (e > 0.0 && (mr > 0.0 || mp > 0.0))
        fprintf(stderr, "radray: mirrors reflect %.1f %% of the emitted power on (radiosity ledger)%s", 100.0 * mr / e,
                R->g.row ? "" : "\n");
    if (e > 0.0 && (mr > 0.0 || mp > 0.0) && R->g.row)
        fprintf(stderr, ", %.1f %% (light tracing)\n", 100.0 * mp / e);
}

static void json_ledger_rows(const energy_result *R)
{
    printf("\"rows\": [");
    for (size_t i = 0; i < R->nrows; i++) {
        const rad_energy_row *r = &R->rows[i];
        printf("%s{\"name\": ", i ? ", " : "");
        app_json_string(stdout, r->name);
        printf(", \"object\": %lld, \"light\": %lld, \"area\": %.10g, ", (long long)r->object, (long long)r->light,
               r->area);
        json_rgb("emitted", r->emitted, 0);
        json_rgb("incident", r->incident, 0);
        json_rgb("reflected", r->reflected, 0);
        json_rgb("mirrored", r->mirrored, 0);
        json_rgb("absorbed", r->absorbed, 0);
        json_rgb("escaped", r->escaped, 1);
        printf("}");
    }
    printf("]");
}

static void json_particles(const energy_result *R)
{
    static const char *const cols[RT_LEDGER_COLUMNS] = {"emitted", "incident", "reflected",
                                                        "mirrored", "absorbed", "back"};
    const rt_particle_ledger *g = &R->g;
    printf(", \"light_tracing\": {\"particles\": %llu, \"batches\": %d, \"rays\": %llu, \"seconds\": %.4g, ",
           (unsigned long long)g->particles, g->batches, (unsigned long long)g->segments, g->seconds);
    json_rgb("escaped", g->escaped, 0);
    json_rgb("escaped_se", g->escaped_se, 0);
    json_rgb("lost", g->lost, 0);
    json_rgb("lost_se", g->lost_se, 0);
    printf("\"rows\": [");
    for (size_t r = 0; r < g->nobjects + g->nlights; r++) {
        printf("%s{\"name\": ", r ? ", " : "");
        app_json_string(stdout, r < g->nobjects ? R->s->objects[r].name : R->s->lights[r - g->nobjects].name);
        printf(", \"object\": %lld, \"light\": %lld, ", r < g->nobjects ? (long long)r : -1LL,
               r < g->nobjects ? -1LL : (long long)(r - g->nobjects));
        for (int c = 0; c < RT_LEDGER_COLUMNS; c++) {
            char key[32];
            json_rgb(cols[c], g->row[r].c[c], 0);
            snprintf(key, sizeof key, "%s_se", cols[c]);
            json_rgb(key, g->se[r].c[c], c == RT_LEDGER_COLUMNS - 1);
        }
        printf("}");
    }
    printf("]}, \"check\": {\"allowance\": %.6g, \"sigmas\": 4, \"failures\": %zu, \"comparisons\": [", R->allowance,
           R->failures);
    for (size_t i = 0; i < R->ncmp; i++) {
        const rad_energy_cmp *c = &R->cmp[i];
        printf("%s{\"name\": ", i ? ", " : "");
        app_json_string(stdout, c->name);
        printf(", \"object\": %lld, \"light\": %lld, \"column\": \"%s\", \"radiosity\": %.10g, \"particles\": %.10g, "
               "\"se\": %.6g, \"z\": %.6g, \"checked\": %s, \"pass\": %s}",
               (long long)c->object, (long long)c->light, column_name(c->column), c->rad, c->part, c->se,
               isfinite(c->z) ? c->z : 1e308, c->checked ? "true" : "false", c->pass ? "true" : "false");
    }
    printf("]}");
}

static void print_json(const energy_result *R, int agree)
{
    const rad_solution *sol = R->sol;
    printf("{\"scene\": ");
    app_json_string(stdout, R->s->path);
    printf(", \"patches\": %zu, \"form_factors\": %zu, \"solver\": \"%s\", \"iterations\": %d, "
           "\"residual\": %.3g, \"balance_relative_error\": %.3g, \"balanced\": %s, \"power_created\": %s, ",
           sol->P->n, sol->nnz, sol->stats.used == RAD_SOLVER_DIRECT ? "direct" : "iterative", sol->stats.iterations,
           sol->stats.residual, R->balance, R->balance <= R->balance_tol ? "true" : "false",
           R->created ? "true" : "false");
    json_ledger_rows(R);
    if (R->g.row)
        json_particles(R);
    printf(", \"agree\": %s}\n", agree ? "true" : "false");
}

/* Runs both estimators and the comparison into R; 0 or the exit code. */
static int run(const energy_args *A, scene *s, rt_accel *a, energy_result *R)
{
    rr_error err;
    app_session_init(&R->ses, s, a, NULL);
    R->ses.pass.hier.max_bytes = R->pass_bytes;
    rr_status st = app_session_field(&R->ses, A->quiet, &err);
    const rad_solution *sol = R->sol = R->ses.sol;
    if (st == RR_ERR_INTERRUPTED) {
        app_error("%s", err.msg);
        return app_stop == SIGTERM ? APP_EXIT_TERMINATED : APP_EXIT_INTERRUPTED;
    }
    if (st == RR_OK)
        st = rad_energy_solution(sol, &R->rows, &R->nrows, &err);
    if (st != RR_OK) {
        app_error("%s", err.msg);
        return st == RR_ERR_INVALID ? APP_EXIT_USAGE : APP_EXIT_RUNTIME;
    }
    const rad_energy_row *t = &R->rows[R->nrows - 1];
    R->balance = balance_error(t);
    /* 100 x what the solve was asked (the residual where it stopped above
     * that): the hierarchical solve stops at its tolerance of the largest B
     * and 10 x it of the emitted power (rad.h RAD_HIER_TOLERANCE), whose
     * imbalance does not follow the residual it reached */
    double solved = fmax(sol->stats.residual, sol->stats.tolerance);
    R->balance_tol = fmax(1e-6, 100.0 * solved);
    R->created = rr_rgb_mean(t->escaped) < -R->balance_tol * rr_rgb_mean(t->emitted);
    if (A->particles == 0)
        return 0;
    rt_lights *L = NULL;
    if ((st = rt_lights_build(s, a, 0, &L, &err)) != RR_OK) {
        app_error("%s", err.msg);
        return APP_EXIT_RUNTIME;
    }
    rt_particle_opts o = {0};
    o.particles = (uint64_t)A->particles;
    o.batches = (int)A->batches;
    o.seed = A->seed >= 0 ? (uint64_t)A->seed : s->settings.seed;
    o.threads = A->threads > 0 ? (int)A->threads : s->settings.threads;
    app_progress bar = {!A->quiet && isatty(STDERR_FILENO), -1, rr_now_seconds(), "light tracing"};
    if (!A->quiet)
        fprintf(stderr, "light tracing %ld particles in %ld batches\n", A->particles, A->batches);
    o.progress = particle_progress;
    o.progress_user = &bar;
    o.interrupt = &app_stop;
    st = rt_particles_trace(s, a, L, &o, &R->g, &err);
    rt_lights_destroy(L);
    if (st == RR_ERR_INTERRUPTED) {
        if (bar.enabled)
            fputc('\n', stderr);
        app_error("interrupted");
        return app_stop == SIGTERM ? APP_EXIT_TERMINATED : APP_EXIT_INTERRUPTED;
    }
    rad_energy_check_opts co = {4.0, R->allowance, 0.001};
    if (st == RR_OK)
        st = rad_energy_compare(R->rows, R->nrows, &R->g, &co, &R->cmp, &R->ncmp, &R->failures, &err);
    if (st != RR_OK) {
        app_error("%s", err.msg);
        return APP_EXIT_RUNTIME;
    }
    app_diagnose_ledger(s, &R->g, 0.01);
    return 0;
}

int app_cmd_energy(int argc, char **argv)
{
    energy_args A = {0};
    A.particles = 1000000;
    A.batches = 32;
    A.seed = -1;
    A.allowance = 1.0;
    A.max_memory = app_default_max_memory();
    A.sets = calloc((size_t)argc + 1, sizeof *A.sets);
    scene *s = NULL;
    rt_accel *a = NULL;
    energy_result R;
    memset(&R, 0, sizeof R);
    app_signals sig = {0};
    if (!A.sets) {
        app_error("out of memory");
        return APP_EXIT_RUNTIME;
    }
    int rc = parse_args(argc, argv, &A);
    if (rc != 0) {
        rc = rc == 1000 ? APP_EXIT_OK : rc;
        goto done;
    }
    rc = APP_EXIT_USAGE;
    R.allowance = A.allowance / 100.0;
    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = (const char *const *)A.sets;
    lo.noverrides = A.nsets;
    lo.warn = app_warn_sink();
    lo.max_image_bytes = A.max_memory;
    if (app_scene_load(A.path, &lo, &s, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    R.s = s;
    if (app_check_memory(s, ig_find("radiosity"), NULL, 0, A.max_memory, &R.pass_bytes, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    app_diagnose_scene(s);
    rc = APP_EXIT_RUNTIME;
    if (rt_accel_build(s, &a, &err) != RR_OK) {
        app_error("%s", err.msg);
        goto done;
    }
    app_signals_catch(&sig);
    if ((rc = run(&A, s, a, &R)) != 0)
        goto done;
    report_shares(&R);
    int agree = R.balance <= R.balance_tol && !R.created && R.failures == 0;
    if (A.json)
        print_json(&R, agree);
    else
        print_text(&R);
    rc = R.balance > R.balance_tol || (A.check && !agree) ? APP_EXIT_RUNTIME : APP_EXIT_OK;
done:
    app_signals_restore(&sig);
    free(R.cmp);
    rt_particle_ledger_free(&R.g);
    free(R.rows);
    ig_session_free(&R.ses);
    rt_accel_destroy(a);
    scene_destroy(s);
    for (size_t i = 0; i < A.nsets; i++)
        free(A.sets[i]);
    free(A.sets);
    return rc;
}
