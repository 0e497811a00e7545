/* test_hier_cornell.c - the hierarchical radiosity method on the Cornell box
 * (scenes/cornell.json): under radiosity.max_links and --max-memory's share
 * against the flat method, and the light near the short block against a final
 * gather of the same solution (radiosity.relative_tolerance). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "rad.h"
#include "test_hier_util.h"
#include "test_scenes.h"

/* The Cornell box by method under radiosity.max_links (0: the default) and
 * rad_hier_opts.max_bytes (0: none), through the cache file cache (NULL:
 * none): every object's mean B, or -1 and the error in msg; bytes gets what
 * the pass says it held, bound whether max_bytes coarsened it. */
typedef struct cornell_run {
    int max_links;
    double max_bytes;
    const char *cache;
    double bytes;
    int bound, from_cache;
} cornell_run;

static int cornell_means_run(const char *method, cornell_run *cr, double mean[16], char *msg, size_t cap)
{
    int max_links = cr->max_links;
    char m[64], ml[64];
    snprintf(m, sizeof m, "radiosity.method=%s", method);
    snprintf(ml, sizeof ml, "radiosity.max_links=%d", max_links);
    const char *over[2] = {m, ml};
    scene *s = test_shipped_scene("cornell.json", over, max_links ? 2 : 1);
    rr_error err;
    assert_true(s->nobjects <= 16);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.use_scene_choices = 1;
    po.hier.max_bytes = cr->max_bytes;
    rad_solution *sol = NULL;
    int rc = 0;
    if (rad_pass_run_cached(s, a, &po, cr->cache, &cr->from_cache, &sol, &err) != RR_OK) {
        if (!msg)
            fail_msg("%s", err.msg);
        snprintf(msg, cap, "%.*s", (int)(cap - 1), err.msg);
        rc = -1;
    } else {
        cr->bytes = sol->pass_bytes;
        cr->bound = sol->memory_bound;
        double area[16] = {0};
        memset(mean, 0, 16 * sizeof *mean);
        for (size_t k = 0; k < sol->P->n; k++) {
            uint32_t o = sol->P->p[k].object;
            mean[o] += sol->B[k].g * sol->P->p[k].area;
            area[o] += sol->P->p[k].area;
        }
        for (size_t o = 0; o < s->nobjects; o++)
            mean[o] = area[o] > 0 ? mean[o] / area[o] : 0.0;
    }
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
    return rc;
}

static int cornell_means(const char *method, int max_links, double mean[16], char *msg, size_t cap)
{
    cornell_run cr = {max_links, 0.0, NULL, 0.0, 0, 0};
    return cornell_means_run(method, &cr, mean, msg, cap);
}

/* radiosity.max_links under what the tolerance asks (Cornell: 269 k links;
 * 40000 here): the first walk starts again with a coarser tolerance until
 * its refinement for accuracy fits (the cluster links that admissibility
 * needs, about 25 k here, are made whatever the cap), and links the cap
 * stops in later rounds stay as evaluated. Every object's mean B within 3 %
 * of the flat method's (Monte Carlo factors; under 0.5 % noise per object).
 * Before, the walk stopped where it reached the cap: the objects it had not
 * reached kept their coarsest links (ceiling -37 %, tall block -45 % in
 * incident power against the light tracer), a lamp cube's floor came out
 * black at 30000 links, and links re-added unevaluated at the cap held NaN. */
static void test_capped_links(void **state)
{
    (void)state;
    double h[16], f[16];
    cornell_means("hierarchical", 40000, h, NULL, 0);
    cornell_means("flat", 0, f, NULL, 0);
    for (int o = 0; o < 16 && f[o] > 0; o++) {
        print_message("cornell object %d at 40000 links: B %.5f, flat %.5f (%+.2f %%)\n", o, h[o], f[o],
                      100 * (h[o] / f[o] - 1));
        assert_true(fabs(h[o] / f[o] - 1) < 0.03);
    }
}

/* How far the hybrid's indirect light (rad_indirect_at: the leaves' gathered
 * Hind, interpolated) is from a final gather of the same solution (the mean
 * over cosine rays of (B - E) / pi where they land, rad_radiance_at), mean and
 * largest |ratio - 1| over floor points 5 .. 20 from the base of Cornell's
 * short block (three places along its front face), in its shadow. The gather
 * reads the solution's radiosity one bounce away, so it does not share the
 * links' visibility at the receiver: the error it measures is theirs. */
static void near_block_gather(const char *rel, double *mean_dev, double *max_dev)
{
    const char *over[1] = {rel ? rel : "radiosity.relative_tolerance=0"};
    scene *s = test_shipped_scene("cornell.json", over, 1);
    rt_accel *a = NULL;
    rad_solution *sol = run(s, &a);
    /* the front face's base, (130, 0, 65) to (290, 0, 114); n: away from the block */
    double L = hypot(160.0, 49.0), tx = 160.0 / L, tz = 49.0 / L;
    const double us[3] = {30, 55, 80}, ds[3] = {5, 10, 20};
    *mean_dev = *max_dev = 0.0;
    for (int i = 0; i < 9; i++) {
        double u = us[i / 3], d = ds[i % 3];
        rt_hit h;
        rr_ray down = {rr_v3(130 + u * tx + d * tz, 1.0, 65 + u * tz - d * tx), rr_v3(0, -1, 0)};
        assert_true(rt_accel_closest(a, down, 0, 10, &h));
        rr_rgb rho = s->materials[h.material].diffuse;
        double look = rad_indirect_at(sol, s, &h, rho).g, sum = 0.0;
        rr_rng rng = rr_rng_make(11, (uint64_t)i);
        enum { N = 40000 }; /* the gather's own noise: ~0.3 % */
        for (int k = 0; k < N; k++) {
            double r2 = rr_rng_uniform(&rng), ph = 2 * RR_PI * rr_rng_uniform(&rng), r = sqrt(r2);
            rr_ray ray = {rr_v3(h.point.x, 1e-6, h.point.z), rr_v3(r * cos(ph), sqrt(1 - r2), r * sin(ph))};
            rt_hit g;
            if (rt_accel_closest(a, ray, 0, INFINITY, &g))
                sum += rad_radiance_at(sol, s, &g).g - (g.front ? s->materials[g.material].emission.g : 0.0);
        }
        double fg = rho.g * sum / N, dev = fabs(look / fg - 1);
        print_message("%s: floor %g from the short block (at %g along it): indirect %.5f, final gather %.5f (%+.1f %%)\n",
                      over[0], d, u, look, fg, 100 * (look / fg - 1));
        *mean_dev += dev / 9;
        *max_dev = fmax(*max_dev, dev);
    }
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Light near occluders (rad_hier.c): a link held at a floor element that
 * reaches up to the short block gives all of it the visibility its 4 shadow
 * rays found from its fixed points, which lie away from the block. Without
 * the relative tests (radiosity.relative_tolerance 0, the default of scenes
 * that do not set it; cornell.json sets 0.05) the floor in the block's
 * shadow comes out 26 % (up to 46 %) brighter than the gather says; with radiosity.relative_tolerance 0.02,
 * which passes such links to the children where some of the element's
 * leaves have surfaces close by and others not, 5.8 % on average (4.7 %
 * when 4 of a leaf's 16 closedness rays had to meet a surface close by for
 * it to split at the contact; 3 now: rad_hier_ctx.h CONTACT_SHARE).
 * Asserted: a mean under 8 % and under half the default's, and every point
 * under 20 %: the point 5 from the block nearest its corner is +14 %, the
 * others within 8 %. */
static void test_near_occluders(void **state)
{
    (void)state;
    double dm, dx, rm, rx;
    near_block_gather(NULL, &dm, &dx);
    near_block_gather("radiosity.relative_tolerance=0.02", &rm, &rx);
    print_message("mean |indirect / gather - 1|: relative_tolerance 0 %.3f (most %.3f), 0.02 %.3f (most %.3f)\n",
                  dm, dx, rm, rx);
    assert_true(rm < 0.08 && rx < 0.2);
    assert_true(rm < 0.5 * dm);
}

/* A cap under what admissibility alone needs is an error that says so,
 * not a pass that runs over it (or, before, one whose links past the cap
 * held form factors up to 3300 and diverged: the 1M-triangle room). */
static void test_cap_too_small(void **state)
{
    (void)state;
    double h[16];
    char msg[512];
    assert_int_equal(cornell_means("hierarchical", 5000, h, msg, sizeof msg), -1);
    print_message("%s\n", msg);
    assert_non_null(strstr(msg, "radiosity.max_links"));
}

/* --max-memory's share for the pass (rad_hier_opts.max_bytes), 6 MiB where
 * Cornell's pass holds 40.9 MiB unbounded (23.0 MiB with relative_tolerance
 * 0, the relative tests off): the refinement stops under it
 * (what the pass holds is what the process's peak adds, within 8 % on seven
 * scenes: notes/radiosity.md), every object's mean B stays within 3 % of the
 * flat method's, as for max_links, and the coarsened solution is not cached
 * (the cache key does not hold the limit). 1 MiB, under what admissibility
 * alone needs, is an error naming --max-memory. */
static void test_memory_bound(void **state)
{
    (void)state;
    char path[] = "/tmp/radray-test-hier-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    unlink(path);
    double h[16], f[16], limit = 6.0 * 1048576.0;
    cornell_run cr = {0, limit, path, 0.0, 0, -1};
    cornell_means_run("hierarchical", &cr, h, NULL, 0);
    print_message("cornell at max_bytes %.0f: the pass held %.0f bytes\n", limit, cr.bytes);
    assert_true(cr.bound);
    assert_true(cr.bytes <= limit);
    assert_int_equal(cr.from_cache, 0);
    assert_int_equal(access(path, F_OK), -1); /* not cached */
    cornell_means("flat", 0, f, NULL, 0);
    for (int o = 0; o < 16 && f[o] > 0; o++) {
        print_message("cornell object %d at 6 MiB: B %.5f, flat %.5f (%+.2f %%)\n", o, h[o], f[o],
                      100 * (h[o] / f[o] - 1));
        assert_true(fabs(h[o] / f[o] - 1) < 0.03);
    }
    cornell_run small = {0, 1048576.0, NULL, 0.0, 0, 0};
    char msg[512];
    assert_int_equal(cornell_means_run("hierarchical", &small, h, msg, sizeof msg), -1);
    print_message("%s\n", msg);
    assert_non_null(strstr(msg, "--max-memory"));
}

/* Cornell's back wall by seed: the hierarchical pass as the scene asks for
 * it, with render.seed 1 and 2 (the acceptance: "two seeds give
 * radiosity values within 0.5 % per leaf"). The refinement draws its rays
 * whatever the seed, so both have the same leaves; the estimate's are the
 * seed's: far element links between flat surfaces exact (rad_vis.c, no
 * rays), the rest 1 to 8 rays from each of a link's points by its power
 * (rad_hier.c, "Decide, then estimate"). Measured (radray-seeds, seeds 1-10
 * in pairs): every leaf of the wall within 0.5 %, at most 0.15-0.39 %
 * apart (with rays on every link 96.8-98.3 % within, at most 0.9-1.5 %;
 * with the refinement's rays drawn by the seed 82.3 %, and a quarter of
 * the leaves not the same). Held here at the figure, every leaf
 * within 0.5 %: the largest difference of seeds 1 and 2 is 0.21 %. */
static rad_solution *cornell_seed(unsigned seed, scene **out_s, rt_accel **out_a)
{
    char sd[64];
    snprintf(sd, sizeof sd, "render.seed=%u", seed);
    const char *over[1] = {sd};
    scene *s = test_shipped_scene("cornell.json", over, 1);
    rt_accel *a = NULL;
    rad_solution *sol = pass_seed(s, &a, s->settings.seed);
    *out_s = s;
    *out_a = a;
    return sol;
}

static void test_two_seeds(void **state)
{
    (void)state;
    scene *s1, *s2;
    rt_accel *a1, *a2;
    rad_solution *x = cornell_seed(1, &s1, &a1), *y = cornell_seed(2, &s2, &a2);
    assert_int_equal(x->P->n, y->P->n); /* the same leaves */
    int wall = -1;
    for (size_t o = 0; o < s1->nobjects; o++)
        if (!strcmp(s1->objects[o].name, "back_wall"))
            wall = (int)o;
    assert_true(wall >= 0);
    size_t n = 0, within = 0;
    double worst = 0.0;
    for (size_t k = 0; k < x->P->n; k++) {
        for (int j = 0; j < 3; j++)
            assert_true(rr_v3_len(rr_v3_sub(x->P->verts[x->P->p[k].v[j]], y->P->verts[y->P->p[k].v[j]])) < 1e-9);
        if (x->P->p[k].object != (uint32_t)wall)
            continue;
        double bx = x->B[k].r + x->B[k].g + x->B[k].b, by = y->B[k].r + y->B[k].g + y->B[k].b;
        assert_true(by > 0);
        double d = fabs(bx / by - 1);
        n++;
        within += d <= 0.005;
        worst = fmax(worst, d);
    }
    print_message("cornell back wall, seeds 1 and 2: %zu leaves, %.1f %% within 0.5 %%, largest %.2f %%\n", n,
                  100.0 * (double)within / (double)n, 100 * worst);
    assert_true(n > 1000);
    assert_true(within == n);
    assert_true(worst <= 0.005);
    rad_solution_destroy(x);
    rad_solution_destroy(y);
    rt_accel_destroy(a1);
    rt_accel_destroy(a2);
    scene_destroy(s1);
    scene_destroy(s2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_capped_links),
        cmocka_unit_test(test_cap_too_small),
        cmocka_unit_test(test_memory_bound),
        cmocka_unit_test(test_near_occluders),
        cmocka_unit_test(test_two_seeds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
