/* test_hier.c - the hierarchical radiosity method (rad_hier.c) against closed
 * forms: a closed furnace, the cube lit by its ceiling; and the patch set of
 * its leaves (lookup, no cracks), determinism across thread counts, and the
 * cache. The Cornell box's tests (the link cap, the memory bound, light near
 * occluders) are in test_hier_cornell.c. */
#include <omp.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "rad.h"
#include "rad_ff_internal.h"
#include "rad_hier_ctx.h"
#include "test_hier_util.h"
#include "test_scenes.h"

static scene *load(const char *json)
{
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "hier", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

/* The [-1,1]^3 cube, inward faces; material f for all but face apart (of
 * test_inward_cube's order -x, +x, -y, +y, -z, +z; -1: none), which gets c. */
static scene *cube(const char *mats, int apart)
{
    char json[8192];
    size_t len = (size_t)snprintf(json, sizeof json,
                                  "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,0],"
                                  "\"O\":[0,0,-1],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                                  "\"radiosity\":{\"method\":\"hierarchical\"},\"materials\":{%s},\"objects\":[",
                                  mats);
    len = test_inward_cube(json, sizeof json, len, "f");
    snprintf(json + len, sizeof json - len, "]}");
    if (apart >= 0) {
        char *p = json;
        for (int k = 0; k <= apart; k++)
            p = strstr(p + 1, "\"material\":\"f\"");
        p[12] = 'c';
    }
    return load(json);
}

/* The cube lit by its ceiling: E = pi Le = 1 there, rho = 0.5 everywhere. */
static scene *lit_cube(void)
{
    char mats[256];
    snprintf(mats, sizeof mats, "\"f\":{\"diffuse\":0.5},\"c\":{\"diffuse\":0.5,\"emission\":%.17g}", 1.0 / RR_PI);
    return cube(mats, 3); /* the ceiling */
}

/* Closed furnace, rho = 0.9, every face emitting E: B = E / (1 - rho) at
 * every leaf. The leaves see a closed scene (k = 1 / sigma, rad_hier.c). */
static void test_furnace(void **state)
{
    (void)state;
    const double rho = 0.9, Le = 0.5;
    char mats[256];
    snprintf(mats, sizeof mats, "\"f\":{\"diffuse\":%g,\"emission\":%g}", rho, Le);
    scene *s = cube(mats, -1);
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    double want = RR_PI * Le / (1 - rho), worst = 0;
    for (size_t k = 0; k < sol->P->n; k++)
        worst = fmax(worst, fabs(sol->B[k].g - want) / want);
    assert_true(sol->P->n > 6 * 16);
    assert_true(worst < 1e-3);
    rad_energy_row *rows = NULL;
    size_t nrows = 0;
    rr_error err;
    assert_int_equal(rad_energy_solution(sol, &rows, &nrows, &err), RR_OK);
    const rad_energy_row *t = &rows[nrows - 1];
    assert_true(fabs(t->emitted.g - (t->absorbed.g + t->escaped.g)) < 1e-4 * t->emitted.g);
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The closed furnace with one face a perfect mirror (diffuse 0, mirror 1):
 * a uniform field reflected is the same field, so B = E / (1 - rho) holds
 * at every diffuse leaf, and the ledger balances. What it checks is that
 * the links by way of the mirror (rad_hier.c, "Mirrors") and the row sums
 * agree: each leaf's scale k = 1 / sigma reads the mirror's share through
 * them, and a way's shadow ray that grazed the mirror's edge (an end on a
 * face coplanar with the receiver's image) marked links partly visible,
 * which loses k: worst leaf 5.1e-3 then, 9e-9 now. It cannot see the ways
 * missing (k would scale the missing share away, as it would in any
 * uniform field): test_transport's room with a mirror does (its floor -21
 * % in the radiosity display without them). The mirror covers its whole
 * face, so no shadow ray by way of it can miss it. */
static void test_furnace_mirror(void **state)
{
    (void)state;
    const double rho = 0.9, Le = 0.5;
    char mats[256];
    snprintf(mats, sizeof mats, "\"f\":{\"diffuse\":%g,\"emission\":%g},\"c\":{\"diffuse\":0,\"mirror\":1}", rho,
             Le);
    scene *s = cube(mats, 0); /* the -x face: "c", the mirror */
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    double want = RR_PI * Le / (1 - rho), worst = 0, sum = 0, area = 0;
    for (size_t k = 0; k < sol->P->n; k++) {
        if (sol->P->p[k].object == 0)
            continue; /* the mirror: B = 0 */
        double e = (sol->B[k].g - want) / want;
        worst = fmax(worst, fabs(e));
        sum += e * sol->P->p[k].area;
        area += sol->P->p[k].area;
    }
    print_message("furnace with a mirror face: mean %+.2e, worst leaf %.2e\n", sum / area, worst);
    assert_true(fabs(sum / area) < 1e-3);
    assert_true(worst < 5e-3);
    rad_energy_row *rows = NULL;
    size_t nrows = 0;
    rr_error err;
    assert_int_equal(rad_energy_solution(sol, &rows, &nrows, &err), RR_OK);
    const rad_energy_row *t = &rows[nrows - 1];
    print_message("furnace with a mirror face: emitted %.6g, absorbed %.6g, escaped %.3g\n", t->emitted.g,
                  t->absorbed.g, t->escaped.g);
    assert_true(fabs(t->emitted.g - (t->absorbed.g + t->escaped.g)) < 1e-3 * t->emitted.g);
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Which mirrors the hierarchical method carries (rad_pass.c, rad__pass_method):
 * planar ones, by its ways (two that face each other by chains of them); a
 * curved one sends the scene to the flat method, with a warning that says
 * why. */
static void warn_keep(void *user, const char *msg) { snprintf(user, 512, "%s", msg); }

static void mirror_method(const char *label, const char *mirrors, int want_hier, const char *want_warning)
{
    char json[4096];
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lookat\",\"eye\":[1,1,3],\"target\":[1,0.5,0],"
             "\"up\":[0,1,0],\"fov\":50,\"width\":8,\"height\":8},\"radiosity\":{\"method\":\"hierarchical\"},"
             "\"materials\":{\"white\":{\"diffuse\":0.6},\"mirror\":{\"diffuse\":0,\"mirror\":0.9},"
             "\"lamp\":{\"diffuse\":0,\"emission\":5}},\"objects\":["
             "{\"name\":\"floor\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[0,0,2],[2,0,2],"
             "[2,0,0]]},{\"name\":\"lamp\",\"type\":\"quad\",\"material\":\"lamp\",\"vertices\":[[0.8,1.4,0.8],"
             "[1.2,1.4,0.8],[1.2,1.4,1.2],[0.8,1.4,1.2]]}%s]}",
             mirrors);
    scene *s = load(json);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    char warning[512] = "";
    po.warn.fn = warn_keep;
    po.warn.user = warning;
    rad_solution *sol = NULL;
    rr_error err;
    if (rad_pass_run(s, a, &po, &sol, &err) != RR_OK)
        fail_msg("%s", err.msg);
    print_message("%s: %s %s\n", label, sol->P->roots ? "hierarchical" : "flat;", warning);
    assert_int_equal(sol->P->roots != NULL, want_hier);
    if (want_warning)
        assert_non_null(strstr(warning, want_warning));
    else
        assert_string_equal(warning, "");
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

static void test_mirror_method(void **state)
{
    (void)state;
    const char *m0 = ",{\"name\":\"m0\",\"type\":\"quad\",\"material\":\"mirror\","
                     "\"vertices\":[[0,0,0],[0,1.5,0],[0,1.5,2],[0,0,2]]}";
    const char *m1 = ",{\"name\":\"m1\",\"type\":\"quad\",\"material\":\"mirror\","
                     "\"vertices\":[[2,0,0],[2,0,2],[2,1.5,2],[2,1.5,0]]}";
    const char *m_coplanar = ",{\"name\":\"m2\",\"type\":\"quad\",\"material\":\"mirror\","
                             "\"vertices\":[[0,0,2.5],[0,1.5,2.5],[0,1.5,3],[0,0,3]]}";
    const char *ball = ",{\"name\":\"ball\",\"type\":\"sphere\",\"material\":\"mirror\","
                       "\"center\":[1,0.3,1],\"radius\":0.2}";
    char two[1024];
    mirror_method("one mirror", m0, 1, NULL);
    snprintf(two, sizeof two, "%s%s", m0, m_coplanar); /* two mirrors in one plane: neither sees the other */
    mirror_method("two mirrors in one plane", two, 1, NULL);
    snprintf(two, sizeof two, "%s%s", m0, m1);
    mirror_method("two facing mirrors", two, 1, NULL);
    mirror_method("a mirror ball", ball, 0, "a curved mirror");
    /* A closed mirror box: light meets its faces from outside only, so no
     * chain passes from one face to another (its inside is sealed). Taken
     * as two-sided, its 6 planes made chains of up to render.max_depth (5)
     * faces by way of the inside, 514 of them past WAYS_MAX (127): a
     * warning that light was left out (scenes/interior.json's mirror). */
    const char *mbox = ",{\"name\":\"mbox\",\"type\":\"box\",\"material\":\"mirror\","
                       "\"min\":[0.3,0.2,0.3],\"max\":[0.6,0.5,0.6]}";
    mirror_method("a closed mirror box", mbox, 1, NULL);
}

/* The energy ledger of a solution: its rows (free()), *nrows of them. */
static rad_energy_row *ledger(const rad_solution *sol, size_t *nrows)
{
    rr_error err;
    rad_energy_row *rows = NULL;
    if (rad_energy_solution(sol, &rows, nrows, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return rows;
}

/* The ledger's balance, emitted = absorbed + escaped, for hierarchical
 * solutions: escaped counts what leaves each leaf through the links it
 * sends by (rad_hier_solve.c, column_sums), so the balance is the solve's
 * and the bookkeeping's, not the links' reciprocity (which they lack):
 * read from each leaf's own row sum it was 7.8e-4 off on Cornell and 2.6 %
 * on the mirror room (a closed room with a mirror and a lamp of
 * reflectance 0, whose receiving links the oracle never refines); then
 * 5.7e-6 and 4e-8; now 1.4e-8 and 4e-8, since leaves buried whole send
 * nothing (rad_hier_solve.c, set_leaf_src: 15 such nodes of Cornell sent
 * 2e-6 of the power by links that no open area accounted for).
 * Whether the power went where it should is the light tracer's check
 * (radray energy --check; test_energy). */
static void ledger_balance(const char *name, double tol, double escaped_tol, const char *solve_tol)
{
    char tset[64] = "";
    if (solve_tol)
        snprintf(tset, sizeof tset, "radiosity.tolerance=%s", solve_tol);
    const char *over[2] = {"radiosity.method=hierarchical", tset};
    scene *s = test_shipped_scene(name, over, solve_tol ? 2 : 1);
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    size_t nrows = 0;
    rad_energy_row *rows = ledger(sol, &nrows);
    const rad_energy_row *t = &rows[nrows - 1];
    double worst = 0.0;
    const double e[3] = {t->emitted.r, t->emitted.g, t->emitted.b}, ab[3] = {t->absorbed.r, t->absorbed.g, t->absorbed.b},
                 es[3] = {t->escaped.r, t->escaped.g, t->escaped.b};
    for (int k = 0; k < 3; k++)
        worst = fmax(worst, fabs(e[k] - ab[k] - es[k]) / e[k]);
    print_message("%s, hierarchical: emitted = absorbed + escaped to %.2g (worst channel); escaped %.2g of the "
                  "emitted power\n",
                  name, worst, t->escaped.g / t->emitted.g);
    assert_true(worst < tol);
    if (escaped_tol > 0)
        assert_true(fabs(t->escaped.g) < escaped_tol * t->emitted.g);
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

static void test_ledger_balance(void **state)
{
    (void)state;
    /* The bookkeeping, read at a solve to 1e-9; at the default solve
     * (RAD_HIER_TOLERANCE 1e-6), the 1e-4 for closed scenes. */
    ledger_balance("cornell.json", 1e-6, 0.0, "1e-9");
    ledger_balance("cornell.json", 1e-4, 0.0, NULL);
    /* A closed room: escaped, what the links do not deliver, is the
     * solution's loss (the light tracer: 8e-5 of the emitted power, through
     * the back faces of the mirror's frame), held to the 1e-4 for
     * closed scenes. 6.5e-3 while interior elements sent the mean over
     * their whole area, buried leaves included (rad_hier_solve.c, pull_el);
     * 2.7e-4 then; 7e-6 with the column scale (rad_hier_solve.c,
     * column_scale). */
    ledger_balance("mirror-room.json", 1e-6, 1e-4, "1e-9");
    /* The cube lit by a lamp 0.01 under its ceiling: the light tracer loses
     * 2.9e-4 of the power on the lamp's back; the hierarchical solution 5.3e-3
     * before the column scale, 9.5e-4 with it (the leaves in the lamp's gap
     * take in too much: notes/radiosity.md). */
    ledger_balance("../tests/data/scenes/energy/cube-ceiling-lit.json", 1e-6, 1.5e-3, "1e-9");
}

/* scenes/room.json made a closed furnace: every material rho = 0.5 and
 * emitting Le = 0.5 (the mirror a plain diffuser), so B = pi Le / (1 - rho)
 * = pi at every leaf, whatever the furniture hides, and the leaves' errors
 * are the pass's own: the visibility of partly hidden links, the clusters'
 * geometry and what an interior receiver pushes down to its leaves. Leaves
 * that take part are those more than half of whose outgoing power the links
 * deliver (sol->hier_fsum); the faces lying against the one-sided walls
 * (the shelf's back panel on the back wall) see nothing and keep B = E (a
 * known gap, rad_hier.c). Over those, weighted by area: the mean within 1 %
 * and the 5th percentile within 6 %. Measured: mean -0.56 %, 5th percentile
 * -3.83 % (-0.60 %, -4.0 % before the column scale, rad_hier_solve.c;
 * -0.74 %, -4.2 % while interior elements sent the mean of their
 * leaves over their whole area, buried ones included; -0.41 %, -3.9 % while
 * hier_fsum was each leaf's own row sum: the same solution, other leaves
 * taken; -0.7, -4.6 % before cluster shadow
 * rays stopped ending on surfaces turned away, rad_hier_cluster.c); before the links' transport
 * was estimated from rays of its own (rad_hier.c, "Decide, then estimate"),
 * the clusters' geometry read deeper and the factors shared by shape among
 * the receivers' children ("Shape"), -2.5 % and -7.1 %. */
static int cmp_pair(const void *x, const void *y)
{
    const double *a = x, *b = y;
    return a[0] < b[0] ? -1 : a[0] > b[0];
}

static void test_furnace_room(void **state)
{
    (void)state;
    static const char *const mats[] = {"floor", "ceiling", "wall", "blue_wall", "white_paint", "dark_wood", "wood",
                                       "chair", "rug", "lacquer", "glossy_red", "glossy_green", "glossy_blue",
                                       "mirror", "book_red", "book_yellow", "book_teal", "book_orange", "book_blue",
                                       "book_green", "lamp", "sky"};
    enum { NM = sizeof mats / sizeof *mats };
    char set[NM + 1][96];
    const char *over[NM + 1];
    for (int i = 0; i < NM; i++) {
        snprintf(set[i], sizeof set[i], "materials.%s={\"diffuse\":0.5,\"emission\":0.5}", mats[i]);
        over[i] = set[i];
    }
    snprintf(set[NM], sizeof set[NM], "radiosity.method=hierarchical");
    over[NM] = set[NM];
    scene *s = test_shipped_scene("room.json", over, NM + 1);
    for (size_t m = 0; m < s->nmaterials; m++) /* room.json has no material the list above misses */
        if (s->materials[m].diffuse.g != 0.5 || s->materials[m].emission.g != 0.5 || s->materials[m].mirror.g != 0)
            fail_msg("room.json: material '%s' is not in this test's list", s->materials[m].name);
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    const rad_patches *P = sol->P;
    double (*v)[2] = malloc(P->n * sizeof *v), atot = 0.0, mean = 0.0;
    assert_non_null(v);
    size_t n = 0;
    for (size_t k = 0; k < P->n; k++)
        if (sol->hier_fsum[k].g > 0.5 && P->p[k].area > 0) {
            v[n][0] = sol->B[k].g / RR_PI;
            v[n][1] = P->p[k].area;
            atot += v[n][1];
            mean += v[n][0] * v[n][1];
            n++;
        }
    assert_true(n > P->n / 2);
    mean /= atot;
    qsort(v, n, sizeof *v, cmp_pair);
    double acc = 0.0, p5 = 0.0;
    for (size_t k = 0; k < n && acc < 0.05 * atot; k++) {
        acc += v[k][1];
        p5 = v[k][0];
    }
    print_message("furnace room: %zu leaves, area-weighted mean %.4f, 5th percentile %.4f\n", n, mean, p5);
    assert_true(fabs(mean - 1.0) < 0.01);
    assert_true(p5 > 0.94);
    free(v);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The cube lit by its ceiling (E = 1, rho = 0.5 everywhere): face means of B
 * against the converged values 1.104364 (ceiling), 0.171216 (floor),
 * 0.181105 (sides) (issue 13), within the 0.5 % the issue asks. Measured
 * now: ceiling -0.05 %, floor +0.39 %, sides -0.07 % to -0.03 %
 * (notes/radiosity.md, "Hierarchical"). */
static void test_cube_ceiling(void **state)
{
    (void)state;
    scene *s = lit_cube();
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    double sum[6] = {0}, area[6] = {0};
    for (size_t k = 0; k < sol->P->n; k++) {
        uint32_t o = sol->P->p[k].object;
        sum[o] += sol->B[k].g * sol->P->p[k].area;
        area[o] += sol->P->p[k].area;
    }
    for (int o = 0; o < 6; o++) {
        double b = sum[o] / area[o], ref = o == 3 ? 1.104364 : o == 2 ? 0.171216 : 0.181105;
        print_message("cube face %d: B %.6f (%+.2f %%)\n", o, b, 100 * (b / ref - 1));
        if (o == 3)
            assert_true(fabs(b / 1.104364 - 1) < 0.005);
        else if (o == 2)
            assert_true(fabs(b / 0.171216 - 1) < 0.005);
        else
            assert_true(fabs(b / 0.181105 - 1) < 0.005);
    }
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The floor's mean B of the cube with a lamp 2 mm under its ceiling (as
 * scenes/room.json has its lamp and window): the surface above the lamp is
 * hidden by it and shares its clusters. Cluster shadow rays drawn by area
 * lost a third of the lamp's light there (-31 % on room.json's floor, -20.6 %
 * here); drawn by power, the row sums counted the hidden ceiling and scaled
 * the floor down 10 %. Now -0.5 % (3 % allowed: the flat method's noise
 * over the floor is under 0.5 %, the cluster links' own error a few per
 * cent in the rooms measured, notes/radiosity.md, "Hierarchical"). */
static double lamp_cube_floor(const char *method)
{
    char json[8192];
    size_t len = (size_t)snprintf(json, sizeof json,
                                  "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,0],"
                                  "\"O\":[0,0,-1],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                                  "\"radiosity\":{\"method\":\"%s\",\"patch_area\":0.001},\"materials\":{"
                                  "\"f\":{\"diffuse\":0.5},\"l\":{\"diffuse\":0,\"emission\":1}},\"objects\":[",
                                  method);
    len = test_inward_cube(json, sizeof json, len, "f");
    snprintf(json + len, sizeof json - len,
             ",{\"type\":\"quad\",\"material\":\"l\",\"vertices\":[[-0.3,0.998,-0.3],[0.3,0.998,-0.3],"
             "[0.3,0.998,0.3],[-0.3,0.998,0.3]]}]}");
    scene *s = load(json);
    rt_accel *a = NULL;
    rad_solution *sol = pass(s, &a);
    double sum = 0.0, area = 0.0;
    for (size_t k = 0; k < sol->P->n; k++)
        if (sol->P->p[k].object == 2) {
            sum += rr_rgb_mean(sol->B[k]) * sol->P->p[k].area;
            area += sol->P->p[k].area;
        }
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
    return sum / area;
}

/* The hierarchical floor against the flat method's (Monte Carlo factors,
 * 512 rays per patch: under 0.5 % noise over a whole face), within 3 %. */
static void test_lamp_under_ceiling(void **state)
{
    (void)state;
    double h = lamp_cube_floor("hierarchical"), f = lamp_cube_floor("flat");
    print_message("lamp under the ceiling: floor B hierarchical %.5f, flat %.5f (%+.2f %%)\n", h, f, 100 * (h / f - 1));
    assert_true(fabs(h / f - 1) < 0.03);
}

/* Form factor from a point to the rectangle [0, a] x [0, b] of a parallel
 * plane at distance h, the point facing it over the rectangle's corner (the
 * closed form for a corner-aligned rectangle). */
static double corner_ff(double a, double b, double h)
{
    double A = sqrt(a * a + h * h), B = sqrt(b * b + h * h);
    return (a / A * atan(b / A) + b / B * atan(a / B)) / (2.0 * RR_PI);
}

/* A 2 x 2 board (reflectance 0.5, so its links refine) facing down, 0.5
 * over a 6 x 6 lamp (Le = 1, reflectance 0) centred under it: what the
 * board takes in is pi times the integral of the point form factor over it,
 * a closed form per point (four corner rectangles) integrated by the
 * midpoint rule (300 x 300: converged to 1e-5). The board's leaves see the
 * lamp over all but 3.6 % of their hemisphere, so 16 closedness rays often
 * all land: with k = 1 / sigma read from a leaf's own 16 the board took in
 * +1.6 %; now that a root's leaves decide together, -0.3 % (1 % allowed:
 * the links' quadrature at the receivers' points, refined to eps). */
static void test_board_over_lamp(void **state)
{
    (void)state;
    scene *s = load("{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,4],\"O\":[0,0,3],"
                    "\"U\":[0,1,0],\"s\":1,\"w\":4,\"h\":4},\"radiosity\":{\"method\":\"hierarchical\"},"
                    "\"materials\":{\"l\":{\"diffuse\":0,\"emission\":1},\"b\":{\"diffuse\":0.5}},\"objects\":["
                    "{\"type\":\"quad\",\"material\":\"l\",\"vertices\":[[-3,-3,-1],[3,-3,-1],[3,3,-1],[-3,3,-1]]},"
                    "{\"type\":\"quad\",\"material\":\"b\",\"vertices\":[[-1,-1,-0.5],[-1,1,-0.5],[1,1,-0.5],"
                    "[1,-1,-0.5]]}]}");
    const int n = 300;
    double sum = 0.0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double x = (i + 0.5) / n * 2 - 1, y = (j + 0.5) / n * 2 - 1;
            sum += corner_ff(3 - x, 3 - y, 0.5) + corner_ff(3 + x, 3 - y, 0.5) + corner_ff(3 - x, 3 + y, 0.5) +
                   corner_ff(3 + x, 3 + y, 0.5);
        }
    double want = RR_PI * 4.0 * sum / ((double)n * n);
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    size_t nrows = 0;
    rad_energy_row *rows = ledger(sol, &nrows);
    double got = -1.0;
    for (size_t k = 0; k < nrows; k++)
        if (rows[k].object == 1)
            got = rows[k].incident.g;
    print_message("board over a lamp: takes in %.5f, closed form %.5f (%+.2f %%)\n", got, want, 100 * (got / want - 1));
    assert_true(fabs(got / want - 1) < 0.01);
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The leaves: each centroid is found again through the tree; every T-vertex
 * (the middle of an edge that is a whole edge of some leaf) carries the mean
 * of that edge's ends, so Gouraud shading is continuous across the edge; the
 * same B for 1 and 2 threads, bit for bit. */
static void test_leaves(void **state)
{
    (void)state;
    scene *s = lit_cube();
    rt_accel *a = NULL;
    omp_set_num_threads(1);
    rad_solution *one = run(s, &a);
    rt_accel_destroy(a);
    omp_set_num_threads(2);
    rad_solution *sol = run(s, &a);
    const rad_patches *P = sol->P;
    assert_int_equal(one->P->n, P->n);
    assert_memory_equal(one->B, sol->B, P->n * sizeof *sol->B);
    assert_true(P->nqt > 0);
    for (size_t k = 0; k < P->n; k++)
        assert_int_equal(rad_patch_locate(P, s, P->p[k].tri, P->p[k].object, P->p[k].centroid), (uint32_t)k);
    size_t tverts = 0;
    for (size_t k = 0; k < P->n; k++)
        for (int e = 0; e < 3; e++) {
            uint32_t va = P->p[k].v[e], vb = P->p[k].v[(e + 1) % 3];
            for (size_t v = P->roots->nverts; v < P->nverts; v++) {
                const uint32_t *m = &P->mid[2 * (v - P->roots->nverts)];
                if ((m[0] == va && m[1] == vb) || (m[0] == vb && m[1] == va)) {
                    tverts++;
                    double want = 0.5 * (sol->vertex_B[va].g + sol->vertex_B[vb].g);
                    assert_true(fabs(sol->vertex_B[v].g - want) <= 1e-12 * fmax(1.0, want));
                }
            }
        }
    assert_true(tverts > 0);
    rad_solution_destroy(one);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The mean of the point-to-polygon factor over a triangle r (normal nr)
 * towards triangle s by M^2 similar sub-triangles' centroids: the reference
 * for the near-pair rules (its error falls as 1 / M). */
static double tri_at3(const rr_vec3 t[3], const double b[3], int k)
{
    const double *q[3] = {&t[0].x, &t[1].x, &t[2].x};
    return b[0] * q[0][k] + b[1] * q[1][k] + b[2] * q[2][k];
}
static rr_vec3 bary_point(const rr_vec3 t[3], const double b[3])
{
    return rr_v3(tri_at3(t, b, 0), tri_at3(t, b, 1), tri_at3(t, b, 2));
}
static double uniform_mean(const rr_vec3 r[3], rr_vec3 nr, const rr_vec3 s[3], int M)
{
    double sum = 0.0;
    int n = 0;
    for (int j = 0; j < M; j++)
        for (int i = 0; i + j < M; i++)
            for (int h = 0; h < 2 && (h == 0 || i + j + 1 < M); h++) {
                double u = (i + (h ? 2.0 : 1.0) / 3.0) / M, v = (j + (h ? 2.0 : 1.0) / 3.0) / M;
                const double b[3] = {1.0 - u - v, u, v};
                sum += rad_ff_point_polygon(bary_point(r, b), nr, s, 3);
                n++;
            }
    return sum / n;
}

static double tri_radius(const rr_vec3 t[3])
{
    rr_vec3 c = rr_v3_scale(rr_v3_add(rr_v3_add(t[0], t[1]), t[2]), 1.0 / 3.0);
    double m = 0.0;
    for (int k = 0; k < 3; k++)
        m = fmax(m, rr_v3_len(rr_v3_sub(t[k], c)));
    return m;
}

/* The hierarchical near pairs' quadrature rules (rad_hier_link.c):
 * - both integrate every polynomial of degree <= 5 in the barycentrics
 *   exactly (the mean of b1^i b2^j over a triangle is 2 i! j! / (i + j +
 *   2)!), with weights summing to 1;
 * - on random facing pairs of triangles (sizes 1:4 to 4:1) whose centres
 *   are closer than twice their radii, against 8100 points: the 7-point
 *   rule within 1 % where the centres are further apart than the radii's
 *   sum (measured 0.65 %), the 28-point rule within 0.2 % there (0.07 %)
 *   and within 5 % closer (4.2 %; the 36 points it replaced: 4.8 %).
 * A point or weight off in its 6th digit fails the first part. */
/* ---- the links' sort (rad__hier_sort_links) ---- */

static int cmp_link_order(const void *a, const void *b)
{
    const hlink *x = a, *y = b; /* receivers as numbers: receiving clusters (CLB) after the elements */
    if (x->r != y->r)
        return x->r < y->r ? -1 : 1;
    if (x->s != y->s)
        return x->s < y->s ? -1 : 1;
    return (link_way(x) > link_way(y)) - (link_way(x) < link_way(y));
}

static uint64_t sort_rand(uint64_t *z)
{
    *z ^= *z << 13;
    *z ^= *z >> 7;
    *z ^= *z << 17;
    return *z;
}

/* Sorts the n links of want's order, given as ln (owned by c from here),
 * and checks every byte of every link against want. */
static void check_sorted(hctx *c, hlink *ln, size_t n, const hlink *want)
{
    c->ln = ln;
    c->nln = c->capln = n;
    assert_int_equal(rad__hier_sort_links(c), 0);
    for (size_t i = 0; i < n; i++)
        if (memcmp(&c->ln[i], &want[i], sizeof *want) != 0)
            fail_msg("link %zu of %zu: receiver %u source %u, expected %u %u", i, n, c->ln[i].r, c->ln[i].s, want[i].r,
                     want[i].s);
    free(c->ln);
    c->ln = NULL;
}

/* The solve's order against qsort's: random links to elements and to
 * receiving clusters (receiver keys over three bytes, so the radix sort
 * takes three passes), shuffled whole (too many for the tail's copy: the
 * sort in place), and as a sorted prefix with a shuffled tail of 10000
 * (the tail sorted into a copy and merged), each link's other fields moving
 * with it; a handful (an insertion sort). */
static void test_link_sort(void **state)
{
    (void)state;
    hctx c;
    memset(&c, 0, sizeof c);
    unsigned char rlc = 2;
    c.nel = 70000;
    c.ncl = 30000;
    c.rlc = &rlc; /* only whether there are receiving clusters is read */
    size_t n = 1000000, m = 0; /* more than the tail's copy may hold: shuffled whole, they are sorted in place */
    hlink *all = calloc(n, sizeof *all);
    assert_non_null(all);
    uint64_t z = 88172645463325252ULL;
    for (size_t i = 0; i < n; i++) {
        hlink *l = &all[i];
        uint64_t v = sort_rand(&z);
        l->r = v % 5 == 0 ? CLB | (uint32_t)(v >> 8) % 30000u : (uint32_t)(v >> 8) % 70000u;
        l->s = (uint32_t)(sort_rand(&z) % 256u); /* few sources: a receiver holds many links, some more than 64 */
        l->flags = (unsigned char)((sort_rand(&z) % 3u) << 1);
    }
    qsort(all, n, sizeof *all, cmp_link_order);
    for (size_t i = 0; i < n; i++) /* distinct links only: the order is total */
        if (m == 0 || cmp_link_order(&all[m - 1], &all[i]) != 0)
            all[m++] = all[i];
    for (size_t i = 0; i < m; i++) { /* payload: where each link came from */
        all[i].f = (float)i;
        all[i].v = (unsigned char)i;
    }
    assert_true(m > 900000);

    hlink *ln = malloc(m * sizeof *ln);
    assert_non_null(ln);
    memcpy(ln, all, m * sizeof *ln);
    for (size_t i = m - 1; i > 0; i--) {
        size_t j = (size_t)(sort_rand(&z) % (i + 1));
        hlink t = ln[i];
        ln[i] = ln[j];
        ln[j] = t;
    }
    check_sorted(&c, ln, m, all);

    /* kept links in order, then 10000 new ones (the copy fits: 0.75 of a
     * patch-set entry per element) */
    ln = malloc(m * sizeof *ln);
    assert_non_null(ln);
    unsigned char *tail = calloc(m, 1);
    assert_non_null(tail);
    for (size_t k = 0; k < 10000; k++)
        tail[sort_rand(&z) % m] = 1;
    size_t kept = 0, nt = 0;
    for (size_t i = 0; i < m; i++)
        if (!tail[i])
            ln[kept++] = all[i];
    for (size_t i = 0; i < m; i++)
        if (tail[i])
            ln[kept + nt++] = all[i];
    for (size_t i = nt - 1; i > 0; i--) {
        size_t j = (size_t)(sort_rand(&z) % (i + 1));
        hlink t = ln[kept + i];
        ln[kept + i] = ln[kept + j];
        ln[kept + j] = t;
    }
    check_sorted(&c, ln, m, all);
    free(tail);

    /* a handful, in reverse */
    ln = malloc(12 * sizeof *ln);
    assert_non_null(ln);
    for (size_t i = 0; i < 12; i++)
        ln[i] = all[m - 1 - 2 * i];
    hlink few[12];
    for (size_t i = 0; i < 12; i++)
        few[i] = all[m - 1 - 2 * (11 - i)];
    check_sorted(&c, ln, 12, few);
    free(all);
}

static void test_near_pair_rules(void **state)
{
    (void)state;
    double b[64][3], w[64];
    for (int smooth = 0; smooth < 2; smooth++) {
        int n = rad__hier_near_rule(smooth, b, w);
        assert_int_equal(n, smooth ? 7 : 28);
        for (int i = 0; i <= 5; i++)
            for (int j = 0; i + j <= 5; j++) {
                double q = 0.0, fi = 1.0, fj = 1.0, fij = 1.0;
                for (int k = 0; k < n; k++)
                    q += w[k] * pow(b[k][1], i) * pow(b[k][2], j);
                for (int k = 2; k <= i; k++)
                    fi *= k;
                for (int k = 2; k <= j; k++)
                    fj *= k;
                for (int k = 2; k <= i + j + 2; k++)
                    fij *= k;
                double want = 2.0 * fi * fj / fij;
                if (!(fabs(q - want) <= 1e-12))
                    fail_msg("rule %d: mean of b1^%d b2^%d %.17g, exact %.17g", smooth, i, j, q, want);
            }
    }
    rr_rng rng = rr_rng_make(5, 9);
    double worst[2][2] = {{0, 0}, {0, 0}}; /* [smooth][centres further apart than the radii] */
    int kept = 0;
    for (int it = 0; it < 100000 && kept < 400; it++) {
        rr_vec3 r[3] = {rr_v3(0, 0, 0), rr_v3(2 * rr_rng_uniform(&rng) - 1, 2 * rr_rng_uniform(&rng) - 1, 0),
                        rr_v3(2 * rr_rng_uniform(&rng) - 1, 2 * rr_rng_uniform(&rng) - 1, 0)}, nr = rr_v3(0, 0, 1);
        if (fabs(r[1].x * r[2].y - r[1].y * r[2].x) < 0.2)
            continue;
        double sc = pow(4.0, 2 * rr_rng_uniform(&rng) - 1);
        rr_vec3 c = rr_v3(2 * rr_rng_uniform(&rng) - 1, 2 * rr_rng_uniform(&rng) - 1, 2.5 * rr_rng_uniform(&rng)), s[3];
        for (int k = 0; k < 3; k++)
            s[k] = rr_v3_add(c, rr_v3_scale(rr_v3(2 * rr_rng_uniform(&rng) - 1, 2 * rr_rng_uniform(&rng) - 1,
                                                  2 * rr_rng_uniform(&rng) - 1), sc));
        if (s[0].z <= 1e-3 || s[1].z <= 1e-3 || s[2].z <= 1e-3)
            continue; /* s wholly in front of r */
        rr_vec3 ns = rr_v3_cross(rr_v3_sub(s[1], s[0]), rr_v3_sub(s[2], s[0]));
        double L = rr_v3_len(ns);
        if (L < 0.05 * sc * sc)
            continue;
        ns = rr_v3_scale(ns, 1.0 / L);
        double d0 = rr_v3_dot(ns, rr_v3_sub(r[0], s[0]));
        int facing = 1;
        for (int k = 0; k < 3; k++)
            facing &= d0 * rr_v3_dot(ns, rr_v3_sub(r[k], s[0])) > 0 && fabs(rr_v3_dot(ns, rr_v3_sub(r[k], s[0]))) > 1e-3;
        double rr_ = tri_radius(r), rs = tri_radius(s);
        rr_vec3 cr = rr_v3_scale(rr_v3_add(rr_v3_add(r[0], r[1]), r[2]), 1.0 / 3.0);
        rr_vec3 cs = rr_v3_scale(rr_v3_add(rr_v3_add(s[0], s[1]), s[2]), 1.0 / 3.0);
        double q = rr_v3_len(rr_v3_sub(cr, cs)) / (rr_ + rs);
        if (!facing || q >= 2.0)
            continue;
        double ref = uniform_mean(r, nr, s, 90);
        if (!(ref > 1e-4))
            continue;
        kept++;
        for (int smooth = 0; smooth < 2; smooth++) {
            int n = rad__hier_near_rule(smooth, b, w);
            double m = 0.0;
            for (int k = 0; k < n; k++)
                m += w[k] * rad_ff_point_polygon(bary_point(r, b[k]), nr, s, 3);
            double e = fabs(m / ref - 1.0);
            worst[smooth][q >= 1.0] = fmax(worst[smooth][q >= 1.0], e);
        }
    }
    print_message("near-pair rules over %d pairs: 28 points %.3f / %.3f %%, 7 points (apart) %.3f %%\n", kept,
                  100 * worst[0][0], 100 * worst[0][1], 100 * worst[1][1]);
    assert_int_equal(kept, 400);
    assert_true(worst[1][1] < 0.01);
    assert_true(worst[0][1] < 0.002);
    assert_true(worst[0][0] < 0.05);
}

/* The cache keeps a hierarchical solution: the tree comes back from its split
 * bits (same leaves, same values, bytes compared); another refinement
 * tolerance, or a relative one, refuses the file, naming the method's settings. */
static void test_cache(void **state)
{
    (void)state;
    scene *s = lit_cube();
    rt_accel *a = NULL;
    rr_error err;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    char path[] = "/tmp/radray-test-hier-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    unlink(path);
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    rad_solution *made = NULL, *read = NULL;
    int from = -1;
    assert_int_equal(rad_pass_run_cached(s, a, &po, path, &from, &made, &err), RR_OK);
    assert_int_equal(from, 0);
    if (rad_pass_run_cached(s, a, &po, path, &from, &read, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(from, 1);
    assert_non_null(read->P->roots);
    assert_int_equal(read->P->n, made->P->n);
    assert_int_equal(read->P->nverts, made->P->nverts);
    assert_memory_equal(read->P->p, made->P->p, made->P->n * sizeof *made->P->p);
    assert_memory_equal(read->B, made->B, made->P->n * sizeof *made->B);
    assert_memory_equal(read->vertex_Hind, made->vertex_Hind, made->P->nverts * sizeof *made->vertex_Hind);
    for (size_t k = 0; k < made->P->n; k += 97)
        assert_int_equal(rad_patch_locate(read->P, s, made->P->p[k].tri, made->P->p[k].object,
                                          made->P->p[k].centroid),
                         (uint32_t)k);
    rad_solution_destroy(read);
    read = NULL;
    po.hier.tolerance = 1e-5;
    assert_int_equal(rad_pass_run_cached(s, a, &po, path, &from, &read, &err), RR_ERR_INVALID);
    assert_non_null(strstr(err.msg, "radiosity method and its settings"));
    po.hier.tolerance = 0.0; /* the scene's, as made; radiosity.relative_tolerance is in the key too */
    po.hier.relative = 0.05;
    assert_int_equal(rad_pass_run_cached(s, a, &po, path, &from, &read, &err), RR_ERR_INVALID);
    assert_non_null(strstr(err.msg, "radiosity method and its settings"));
    unlink(path);
    rad_solution_destroy(made);
    rt_accel_destroy(a);
    scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_furnace),
        cmocka_unit_test(test_furnace_mirror),
        cmocka_unit_test(test_mirror_method),
        cmocka_unit_test(test_ledger_balance),
        cmocka_unit_test(test_furnace_room),
        cmocka_unit_test(test_lamp_under_ceiling),
        cmocka_unit_test(test_cube_ceiling),
        cmocka_unit_test(test_board_over_lamp),
        cmocka_unit_test(test_leaves),
        cmocka_unit_test(test_cache),
        cmocka_unit_test(test_near_pair_rules),
        cmocka_unit_test(test_link_sort),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
