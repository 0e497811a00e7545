/* test_hier_rlc.c - receiving leaf clusters (radiosity.receiving_clusters;
 * rad_hier.c, "Receiving leaf clusters"): a closed room lit by a ceiling
 * lamp, with two scanned bunnies of many small triangles on its floor. With
 * the clusters on, the pass takes far fewer links, the light on each
 * bunny and on the room agrees with the light tracer (an independent
 * method), the ledger balances, the bits do not depend on the thread count,
 * and the automatic setting turns them on where the roots too small to
 * split would need more links than the cap allows. */
#include <math.h>
#include <omp.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "rad.h"
#include "test_hier_util.h"

/* The room (object 0), the lamp (1), the bunnies (2, 3); extra: more
 * radiosity settings (a leading comma). */
static scene *bunny_room(const char *extra)
{
    char json[4096];
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lookat\",\"eye\":[2,1,3.8],"
             "\"target\":[2,0.3,2],\"up\":[0,1,0],\"fov\":50,\"width\":16,\"height\":16},"
             "\"radiosity\":{\"method\":\"hierarchical\",\"min_area\":0.02,\"refine_tolerance\":1e-4%s},"
             "\"materials\":{\"wall\":{\"diffuse\":0.6},\"clay\":{\"diffuse\":[0.75,0.5,0.35]},"
             "\"lamp\":{\"diffuse\":0,\"emission\":4}},\"objects\":["
             "{\"name\":\"room\",\"type\":\"box\",\"material\":\"wall\",\"flip\":true,\"min\":[0,0,0],\"max\":[4,2,4]},"
             "{\"name\":\"lamp\",\"type\":\"quad\",\"material\":\"lamp\",\"vertices\":[[1.5,1.998,1.5],[2.5,1.998,1.5],"
             "[2.5,1.998,2.5],[1.5,1.998,2.5]]},"
             "{\"name\":\"bunny1\",\"type\":\"mesh\",\"material\":\"clay\",\"file\":\"%s/scenes/meshes/bunny.ply\","
             "\"transform\":[{\"scale\":0.08},{\"translate\":[1.3,0.00025,2.2]}]},"
             "{\"name\":\"bunny2\",\"type\":\"mesh\",\"material\":\"clay\",\"file\":\"%s/scenes/meshes/bunny.ply\","
             "\"transform\":[{\"scale\":0.08},{\"rotate\":{\"axis\":[0,1,0],\"degrees\":120}},"
             "{\"translate\":[2.8,0.00025,1.6]}]}]}",
             extra, RR_SOURCE_DIR, RR_SOURCE_DIR);
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "rlc", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

/* Per object, the incident power of the radiosity ledger (rows by object). */
static void ledger_incident(const rad_solution *sol, double inc[4], double *balance)
{
    rad_energy_row *rows = NULL;
    size_t n = 0;
    rr_error err;
    assert_int_equal(rad_energy_solution(sol, &rows, &n, &err), RR_OK);
    for (int o = 0; o < 4; o++)
        inc[o] = 0.0;
    for (size_t i = 0; i + 1 < n; i++)
        if (rows[i].object >= 0 && rows[i].object < 4)
            inc[rows[i].object] = rr_rgb_mean(rows[i].incident);
    const rad_energy_row *t = &rows[n - 1];
    double em = rr_rgb_mean(t->emitted);
    *balance = fabs(em - rr_rgb_mean(t->absorbed) - rr_rgb_mean(t->escaped)) / em;
    free(rows);
}

/* The light on the bunnies and the room against the light tracer, and the
 * links against element receivers. Tolerances: the light tracer's 4 SE plus
 * 3 % on a bunny, 1.5 % on the room. The pass's own error is that size: on
 * the 8- and 27-bunny rooms (bench/bunny-room.sh) element receivers put the
 * bunnies' incident power within 4.8 % and 8.0 % of the light tracer,
 * receiving leaf clusters within 2.2 % and 3.8 % (notes/radiosity.md). */
static void test_rlc_light_tracer(void **state)
{
    (void)state;
    scene *s = bunny_room(",\"receiving_clusters\":1");
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    assert_true(sol->receiving_clusters > 0);
    double inc[4], bal;
    ledger_incident(sol, inc, &bal);
    print_message("receiving leaf clusters: %zu, links %zu, ledger balance %.2g\n", sol->receiving_clusters,
                  sol->links, bal);
    assert_true(bal < 1e-4); /* a closed room */

    scene *se = bunny_room(",\"receiving_clusters\":0");
    rt_accel *ae = NULL;
    rad_solution *el = run(se, &ae);
    assert_int_equal(el->receiving_clusters, 0);
    double inc_el[4], bal_el;
    ledger_incident(el, inc_el, &bal_el);
    print_message("element receivers: links %zu\n", el->links);
    assert_true((double)sol->links < 0.6 * (double)el->links);

    rt_lights *L = NULL;
    assert_int_equal(rt_lights_build(s, a, 0, &L, NULL), RR_OK);
    rt_particle_opts po = {0};
    po.particles = 1000000;
    po.seed = 11;
    rt_particle_ledger g;
    rr_error err;
    if (rt_particles_trace(s, a, L, &po, &g, &err) != RR_OK)
        fail_msg("%s", err.msg);
    const char *name[4] = {"room", "lamp", "bunny1", "bunny2"};
    const double tol[4] = {0.015, 1.0, 0.03, 0.03};
    for (int o = 0; o < 4; o++) {
        double lt = rr_rgb_mean(g.row[o].c[RT_LEDGER_INCIDENT]), se_ = rr_rgb_mean(g.se[o].c[RT_LEDGER_INCIDENT]);
        print_message("%s: incident %.5g (clusters, %+.2f %%), %.5g (element receivers, %+.2f %%), light tracer %.5g "
                      "+- %.2g\n",
                      name[o], inc[o], 100.0 * (inc[o] / lt - 1.0), inc_el[o], 100.0 * (inc_el[o] / lt - 1.0), lt, se_);
        if (o == 1)
            continue; /* the lamp takes little, its underside only */
        if (!(fabs(inc[o] - lt) <= 4.0 * se_ + tol[o] * lt))
            fail_msg("%s: incident %.6g, light tracer %.6g +- %.3g", name[o], inc[o], lt, se_);
    }
    rt_particle_ledger_free(&g);
    rt_lights_destroy(L);
    rad_solution_destroy(el);
    rt_accel_destroy(ae);
    scene_destroy(se);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* The same bits at 1 and 2 threads, and the automatic setting, with a cap
 * that the bunnies' 7348 small roots would pass as element receivers (200
 * links a root, half the cap), makes the same clusters as asking for them. */
static void test_rlc_threads_and_auto(void **state)
{
    (void)state;
    rad_solution *sol[2];
    rt_accel *a[2];
    scene *s[2];
    const char *extra[2] = {",\"receiving_clusters\":1", ",\"max_links\":2000000"};
    for (int k = 0; k < 2; k++) {
        s[k] = bunny_room(extra[k]);
        omp_set_num_threads(k + 1);
        a[k] = NULL;
        sol[k] = run(s[k], &a[k]);
    }
    assert_true(sol[0]->receiving_clusters > 0);
    assert_int_equal(sol[1]->P->n, sol[0]->P->n);
    assert_int_equal(sol[1]->links, sol[0]->links);
    assert_int_equal(sol[1]->receiving_clusters, sol[0]->receiving_clusters);
    assert_memory_equal(sol[1]->B, sol[0]->B, sol[0]->P->n * sizeof *sol[0]->B);
    for (int k = 0; k < 2; k++) {
        rad_solution_destroy(sol[k]);
        rt_accel_destroy(a[k]);
        scene_destroy(s[k]);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rlc_light_tracer),
        cmocka_unit_test(test_rlc_threads_and_auto),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
