/* test_radiosity.c - patches: limits, conformity (no T-vertices), lookup from
 * ray hits, units. (Form factors: test_formfactor.c; solvers and the energy
 * ledger: test_solver.c.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "ig.h"
#include "rad.h"
#include "rad_hier_internal.h"
#include "test_scenes.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static const char *k_scene =
    "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
    "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
    "\"materials\":{\"w\":{\"diffuse\":[0.5,0.6,0.7]},\"l\":{\"diffuse\":0.2,\"emission\":[1,2,3]}},"
    "\"objects\":["
    "{\"name\":\"box\",\"type\":\"box\",\"material\":\"w\",\"min\":[-1,-1,-1],\"max\":[1,1.5,1]},"
    "{\"name\":\"lamp\",\"type\":\"quad\",\"material\":\"l\",\"vertices\":[[-3,2,-3],[-3,2,3],[3,2,3],[3,2,-3]]},"
    "{\"name\":\"odd\",\"type\":\"triangles\",\"material\":\"w\",\"vertices\":[[5,0,0],[9,0,0],[5,0.5,0],[5,0,7]],"
    "\"indices\":[[0,1,2],[0,2,3],[0,3,1]]},"
    "{\"name\":\"ball\",\"type\":\"sphere\",\"material\":\"w\",\"center\":[0,4,0],\"radius\":0.7}]}";

static scene *load(void)
{
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(k_scene, "patches", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

static void limits_and_areas(void **state)
{
    (void)state;
    scene *s = load();
    rad_patch_opts o = {.max_area = 0.05, .max_edge = 0.4, .accel = NULL};
    rad_patches *P = NULL;
    rr_error err;
    assert_int_equal(rad_patches_build(s, &o, &P, &err), RR_OK);
    double tri_area = 0, patch_area = 0;
    for (size_t t = 0; t < s->ntris; t++)
        tri_area += scene_tri_area(s, t);
    for (size_t k = 0; k < P->n; k++) {
        const rad_patch *p = &P->p[k];
        assert_true(p->area <= o.max_area * (1 + 1e-12));
        for (int e = 0; e < 3; e++)
            assert_true(rr_v3_len(rr_v3_sub(P->verts[p->v[e]], P->verts[p->v[(e + 1) % 3]])) <= o.max_edge + 1e-12);
        assert_true(p->area > 0);
        if (p->tri >= 0) {
            patch_area += p->area;
            /* Same orientation as the source triangle. */
            assert_near(rr_v3_dot(p->normal, scene_tri_normal(s, (size_t)p->tri)), 1.0, 1e-9);
        }
    }
    assert_near(patch_area, tri_area, 1e-9 * tri_area);
    /* Units: E = pi * Le; rho from the material. */
    uint32_t lamp = P->tri_first[s->objects[1].tri_first];
    assert_near(P->p[lamp].emission.g, 2.0 * RR_PI, 1e-12);
    assert_near(P->p[lamp].rho.r, 0.2, 0);
    /* Sphere patches: flat triangles inscribed in the sphere, outward. */
    double sph = 0;
    for (size_t k = 0; k < P->n; k++)
        if (P->p[k].tri < 0) {
            sph += P->p[k].area;
            rr_vec3 out = rr_v3_norm(rr_v3_sub(P->p[k].centroid, s->objects[3].center));
            assert_true(rr_v3_dot(out, P->p[k].normal) > 0.9);
        }
    double full = 4 * RR_PI * 0.49;
    if (!(sph < full && sph > 0.95 * full)) /* inscribed: 1 - O(1/S^2) */
        fail_msg("sphere patch area %g of %g (S = %u)", sph, full, P->sphere_stacks);
    /* The estimate the memory check uses is the count, for triangles and spheres. */
    assert_true(rad_patches_estimate(s, &o) == (double)P->n);
    rad_patches_destroy(P);
    rad_patch_opts o2 = {.max_area = 0.5, .max_edge = 2.0, .accel = NULL};
    assert_int_equal(rad_patches_build(s, &o2, &P, &err), RR_OK);
    assert_true(rad_patches_estimate(s, &o2) == (double)P->n);
    rad_patches_destroy(P);
    rad_patches_destroy(NULL);
    scene_destroy(s);
}

/* One sliver across a fine grid sets the object's level: named by the
 * warning (with the patch counts), and a grid without it is not. */
static void warn_count(void *user, const char *msg)
{
    (void)msg;
    ++*(int *)user;
}

static void level_outlier_named(void **state)
{
    (void)state;
    static char json[65536];
    for (int sliver = 0; sliver < 2; sliver++) {
        size_t len = (size_t)snprintf(json, sizeof json,
                                      "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                                      "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},\"materials\":{\"w\":{}},"
                                      "\"objects\":[{\"type\":\"triangles\",\"name\":\"grid\",\"material\":\"w\","
                                      "\"vertices\":[");
        for (int j = 0; j <= 10; j++)
            for (int i = 0; i <= 10; i++)
                len += (size_t)snprintf(json + len, sizeof json - len, "%s[%g,%g,0]", i || j ? "," : "", 0.1 * i, 0.1 * j);
        len += (size_t)snprintf(json + len, sizeof json - len, ",[8,0,0]],\"indices\":[");
        for (int j = 0; j < 10; j++)
            for (int i = 0; i < 10; i++) {
                int a = j * 11 + i;
                len += (size_t)snprintf(json + len, sizeof json - len, "%s[%d,%d,%d],[%d,%d,%d]", i || j ? "," : "", a,
                                        a + 1, a + 12, a, a + 12, a + 11);
            }
        if (sliver)
            len += (size_t)snprintf(json + len, sizeof json - len, ",[0,121,120]");
        snprintf(json + len, sizeof json - len, "]}]}");
        scene *s = NULL;
        rr_error err;
        if (scene_load_string(json, "sliver", "", NULL, &s, &err) != RR_OK)
            fail_msg("%s", err.msg);
        int warned = 0;
        rr_warn_sink w = {warn_count, &warned};
        rad_patch_opts o = {.max_area = 0.01, .max_edge = 0.2, .accel = NULL};
        assert_int_equal(rad_patches_level_outliers(s, &o, &w), (size_t)sliver);
        assert_int_equal(warned, sliver);
        scene_destroy(s);
    }
}

/* No T-vertices: in the closed box every patch edge is shared by exactly two
 * patches (a T-vertex would leave an edge used once on each side), counted
 * by position; by vertex index, the two share the edge's vertices when they
 * lie in one face and not across the box's edges (creases), so that the
 * Gouraud means of one face do not take in its neighbour's. */
typedef struct edge_use {
    uint64_t key; /* by canonical (position) vertex ids */
    uint64_t ikey; /* by vertex index */
    uint32_t patch;
} edge_use;

static int cmp_use(const void *a, const void *b)
{
    const edge_use *x = a, *y = b;
    return x->key < y->key ? -1 : x->key > y->key ? 1 : (x->ikey < y->ikey ? -1 : x->ikey > y->ikey);
}

static uint64_t edge_key(uint64_t a, uint64_t b) { return a < b ? (a << 32 | b) : (b << 32 | a); }

static void conforming_box(void **state)
{
    (void)state;
    scene *s = load();
    rad_patch_opts o = {.max_area = 0.03, .max_edge = 0.3, .accel = NULL};
    rad_patches *P = NULL;
    assert_int_equal(rad_patches_build(s, &o, &P, NULL), RR_OK);
    uint32_t *canon = malloc(P->nverts * sizeof *canon);
    for (size_t v = 0; v < P->nverts; v++) {
        canon[v] = (uint32_t)v;
        for (size_t u = 0; u < v; u++)
            if (rr_v3_len(rr_v3_sub(P->verts[u], P->verts[v])) < 1e-9) {
                canon[v] = (uint32_t)u;
                break;
            }
    }
    size_t n = 0, cap = 3 * P->n, creases = 0, shared = 0;
    edge_use *edges = malloc(cap * sizeof *edges);
    for (size_t k = 0; k < P->n; k++)
        if (P->p[k].object == 0)
            for (int e = 0; e < 3; e++) {
                uint32_t a = P->p[k].v[e], b = P->p[k].v[(e + 1) % 3];
                edges[n++] = (edge_use){edge_key(canon[a], canon[b]), edge_key(a, b), (uint32_t)k};
            }
    qsort(edges, n, sizeof *edges, cmp_use);
    assert_true(n > 300);
    for (size_t i = 0; i < n;) {
        size_t j = i;
        while (j < n && edges[j].key == edges[i].key)
            j++;
        if (j - i != 2)
            fail_msg("edge %zu used %zu times", i, j - i);
        double c = rr_v3_dot(P->p[edges[i].patch].normal, P->p[edges[i + 1].patch].normal);
        int same = edges[i].ikey == edges[i + 1].ikey;
        if (same != (c > 0.99))
            fail_msg("edge %zu: normals' cosine %.3f, vertices %s", i, c, same ? "shared" : "apart");
        creases += !same;
        shared += same;
        i = j;
    }
    /* 12 box edges, each split into as many patch edges as its face's level. */
    assert_true(creases >= 12 && shared > creases);
    free(canon);
    free(edges);
    rad_patches_destroy(P);
    scene_destroy(s);
}

/* A hit anywhere on a triangle or sphere finds the patch that contains it. */
static void locate_hits(void **state)
{
    (void)state;
    scene *s = load();
    rad_patch_opts o = {.max_area = 0.02, .max_edge = 0.25, .accel = NULL};
    rad_patches *P = NULL;
    assert_int_equal(rad_patches_build(s, &o, &P, NULL), RR_OK);
    rr_rng rng = rr_rng_make(3, 3);
    for (size_t t = 0; t < s->ntris; t++)
        for (int k = 0; k < 200; k++) {
            double u = rr_rng_uniform(&rng), v = rr_rng_uniform(&rng);
            if (u + v > 1) {
                u = 1 - u;
                v = 1 - v;
            }
            const scene_tri *tr = &s->tris[t];
            rr_vec3 A = s->verts[tr->v[0]], B = s->verts[tr->v[1]], C = s->verts[tr->v[2]];
            rr_vec3 p = rr_v3_add(A, rr_v3_add(rr_v3_scale(rr_v3_sub(B, A), u), rr_v3_scale(rr_v3_sub(C, A), v)));
            uint32_t q = rad_patch_locate(P, s, (int64_t)t, tr->object, p);
            assert_true(q < P->n);
            assert_int_equal(P->p[q].tri, (int64_t)t);
            double b[3];
            rad_patch_barycentric(P, q, p, b);
            for (int e = 0; e < 3; e++)
                assert_true(b[e] > -1e-9);
        }
    const scene_object *ball = &s->objects[3];
    for (int k = 0; k < 2000; k++) {
        double z = 2 * rr_rng_uniform(&rng) - 1, ph = 2 * RR_PI * rr_rng_uniform(&rng), r = sqrt(1 - z * z);
        rr_vec3 p = rr_v3_add(ball->center, rr_v3_scale(rr_v3(r * cos(ph), r * sin(ph), z), ball->radius));
        uint32_t q = rad_patch_locate(P, s, -1, 3, p);
        assert_true(q < P->n);
        assert_int_equal(P->p[q].object, 3);
        /* The point projects into its (flat) patch along the radius, up to the
         * difference between the patch's straight edges and the (theta, phi)
         * rings of the lookup (chords bulge from the latitude lines): a few percent of a patch at S = 8. */
        rr_vec3 dir = rr_v3_sub(p, ball->center);
        double t = rr_v3_dot(P->p[q].normal, rr_v3_sub(P->p[q].centroid, ball->center)) / rr_v3_dot(P->p[q].normal, dir);
        double b[3];
        rad_patch_barycentric(P, q, rr_v3_add(ball->center, rr_v3_scale(dir, t)), b);
        for (int e = 0; e < 3; e++)
            if (!(b[e] > -0.05))
                fail_msg("sphere point %d: patch %u, b = %g %g %g", k, q, b[0], b[1], b[2]);
    }
    rad_patches_destroy(P);
    scene_destroy(s);
}

static void bad_limits(void **state)
{
    (void)state;
    scene *s = load();
    rad_patches *P = NULL;
    rr_error err;
    rad_patch_opts o = {.max_area = 0, .max_edge = 1, .accel = NULL};
    assert_int_equal(rad_patches_build(s, &o, &P, &err), RR_ERR_INVALID);
    assert_null(P);
    rad_patch_opts tiny = {.max_area = 1e-12, .max_edge = 1e-6, .accel = NULL};
    assert_int_equal(rad_patches_build(s, &tiny, &P, &err), RR_ERR_LIMIT);
    assert_non_null(strstr(err.msg, "patches"));
    assert_null(P);
    scene_destroy(s);
}

/* The radiosity pass against an independent method: the Cornell box rendered
 * from the radiosity solution, by the hybrid (ray-traced direct light plus the
 * radiosity pass's indirect light), and with Monte Carlo secondary rays must
 * agree, object by object, on the mean radiance over the pixels that see the
 * object. A hybrid that counted direct light twice would be ~2x too bright.
 * At full size (255 px, 256 spp, ~2200 patches) the measured differences are
 * 0.4-4.6 % (notes/radiosity.md); here, small and quick, the tolerance is 6 %
 * (discretisation) plus 4 standard errors of the Monte Carlo mean. */
static void cornell_radiosity_vs_secondary(void **state)
{
    (void)state;
    char path[512];
    snprintf(path, sizeof path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    scene *s = NULL;
    rr_error err;
    assert_int_equal(scene_load(path, NULL, &s, &err), RR_OK);
    rr_view v;
    assert_int_equal(rr_view_resize(&s->view, 41, &v, NULL), RR_OK);
    s->view = v;
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    ig_session ses;
    ig_session_init(&ses, s, a);
    rt_film fr, fs, fh;
    assert_int_equal(rt_film_init(&fr, v.width, v.height, NULL), RR_OK);
    assert_int_equal(rt_film_init(&fh, v.width, v.height, NULL), RR_OK);
    assert_int_equal(rt_film_init(&fs, v.width, v.height, NULL), RR_OK);
    s->settings.seed = 4;
    s->settings.max_depth = 5;
    s->settings.light_samples = 4;
    s->settings.threads = 2;
    s->settings.spp = 1;
    if (ig_render(&ses, ig_find("radiosity"), NULL, &fr, NULL, &err) != RR_OK)
        fail_msg("%s", err.msg);
    s->settings.spp = 16;
    assert_int_equal(ig_render(&ses, ig_find("hybrid"), NULL, &fh, NULL, NULL), RR_OK);
    s->settings.spp = 256;
    assert_int_equal(ig_render(&ses, ig_find("secondary"), NULL, &fs, NULL, NULL), RR_OK);
    enum { MAXO = 16 };
    double sr[MAXO] = {0}, sh[MAXO] = {0}, ss[MAXO] = {0}, ss2[MAXO] = {0};
    int n[MAXO] = {0};
    for (int y = 0; y < v.height; y++)
        for (int x = 0; x < v.width; x++) {
            rt_hit h;
            if (!rt_accel_closest(a, rr_view_ray(&v, x, y, 0, 0), 0, INFINITY, &h) || h.object >= MAXO)
                continue;
            /* Only pixels well inside one object (the radiosity render uses the
             * pixel centre, the secondary render spreads samples over the pixel). */
            int inside = 1;
            for (int d = 0; d < 4 && inside; d++) {
                rt_hit h2;
                double dx = d < 2 ? (d ? -0.5 : 0.5) : 0, dy = d >= 2 ? (d == 3 ? -0.5 : 0.5) : 0;
                inside = rt_accel_closest(a, rr_view_ray(&v, x, y, dx, dy), 0, INFINITY, &h2) &&
                         h2.object == h.object;
            }
            if (!inside)
                continue;
            double r = rr_rgb_mean(rr_image_get(&fr.beauty, x, y)), q = rr_rgb_mean(rr_image_get(&fs.beauty, x, y));
            sr[h.object] += r;
            sh[h.object] += rr_rgb_mean(rr_image_get(&fh.beauty, x, y));
            ss[h.object] += q;
            ss2[h.object] += q * q;
            n[h.object]++;
        }
    int checked = 0;
    for (size_t i = 0; i < s->nobjects && i < MAXO; i++) {
        if (n[i] < 20)
            continue;
        double mr = sr[i] / n[i], ms = ss[i] / n[i];
        double se = sqrt(fmax(0.0, ss2[i] / n[i] - ms * ms) / n[i]);
        double mh = sh[i] / n[i];
        if (fabs(mr - ms) > 0.06 * ms + 4 * se)
            fail_msg("%s: radiosity %.4f vs secondary %.4f (se %.4f)", s->objects[i].name, mr, ms, se);
        if (fabs(mh - ms) > 0.06 * ms + 4 * se)
            fail_msg("%s: hybrid %.4f vs secondary %.4f (se %.4f)", s->objects[i].name, mh, ms, se);
        checked++;
    }
    assert_true(checked >= 6);
    rt_film_free(&fr);
    rt_film_free(&fh);
    rt_film_free(&fs);
    ig_session_free(&ses);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* White furnace through the whole pipeline: a closed box whose inner faces all
 * have reflectance rho and emit E. Every Monte Carlo form-factor ray from an
 * inner face lands on an inner face, so each raw row sums to exactly 1, and
 * then B = E / (1 - rho) exactly: the solve must give it to 1e-6. (The
 * reciprocity step averages A_i F_ij with A_j F_ji and moves row sums by the
 * sampling noise, so this test takes the raw estimates; solver-level furnaces
 * with exact F, both solvers, are in test_solver.c.) */
static void furnace_pipeline(void **state)
{
    (void)state;
    const double rho = 0.7, Le = 0.5;
    char json[4096];
    size_t len = (size_t)snprintf(json, sizeof json,
                                  "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,0],"
                                  "\"O\":[0,0,-1],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                                  "\"materials\":{\"f\":{\"diffuse\":%g,\"emission\":%g}},\"objects\":[",
                                  rho, Le);
    len = test_inward_cube(json, sizeof json, len, "f");
    snprintf(json + len, sizeof json - len, "]}");
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "furnace", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rad_pass_opts po;
    memset(&po, 0, sizeof po);
    po.patch.max_area = 0.05;
    po.patch.max_edge = 0.5;
    po.ff.method = RAD_FF_MONTE_CARLO;
    po.ff.samples = 64;
    po.ff.raw = 1;
    po.solve.solver = RAD_SOLVER_ITERATIVE;
    po.solve.tolerance = 1e-12;
    rad_solution *sol = NULL;
    if (rad_pass_run(s, a, &po, &sol, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_true(sol->P->n >= 6 * 64);
    double want = RR_PI * Le / (1 - rho);
    for (size_t k = 0; k < sol->P->n; k++)
        assert_near(sol->B[k].g, want, 1e-6 * want);
    rad_energy_row *rows = NULL;
    size_t nrows = 0;
    assert_int_equal(rad_energy(s, sol->P, sol->F, sol->B, &rows, &nrows, &err), RR_OK);
    const rad_energy_row *t = &rows[nrows - 1];
    assert_near(t->emitted.r, t->absorbed.r + t->escaped.r, 1e-6 * t->emitted.r);
    assert_near(t->escaped.r, 0.0, 1e-9 * t->emitted.r);
    free(rows);
    rad_solution_destroy(sol);
    rt_accel_destroy(a);
    scene_destroy(s);
}


/* ---- solids ---- */

/* A unit sphere with a bite taken by a sphere of radius 0.6 at (0.9, 0, 0). */
static const char *k_bite =
    "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
    "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
    "\"materials\":{\"w\":{\"diffuse\":0.5},\"r\":{\"diffuse\":[0.9,0.1,0.1]}},"
    "\"objects\":[{\"name\":\"bite\",\"type\":\"csg\",\"op\":\"difference\",\"material\":\"w\",\"children\":["
    "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
    "{\"type\":\"sphere\",\"center\":[0.9,0,0],\"radius\":0.6,\"material\":\"r\"}]}]}";

/* Patches of a solid cover exactly the surface of the final solid: every
 * vertex lies on a leaf surface AND on the solid (none on the part of the big
 * sphere that was bitten off, none on the part of the small sphere outside
 * the big one), the patches face outwards, carry the material of the leaf
 * surface under them, and their total area is the analytic area
 *   4 pi R^2 - 2 pi R (R - x) + 2 pi r (r - (d - x)),  x = (d^2 + R^2 - r^2) / 2d
 * (sphere, less the cap bitten off, plus the cap of the small sphere inside).
 * The triangles themselves fall short of it: they are chords of each
 * sphere's own grid (rad_solid.c; area short by about (h kappa)^2 / 12, 0.1 %
 * for pieces of 0.08, 1 % at the coarse limits), and the rim's pieces are
 * kept or dropped whole, down to an eighth of a cell (under marching
 * tetrahedra, before, the rim was cut by a chamfer a cell wide: 1.1 % and
 * 5.9 % short). The patches' areas are scaled to each leaf's true area
 * measured by Crofton's formula (within 0.1 % on scenes/csg.json's solids
 * against their converged values), so they sum to the analytic area within
 * 0.3 %, at fine cells and at coarse ones. */
static void solid_patches_at(double max_area, double max_edge, int sides, double *facets, double *area,
                             double *amax, double *want);

static void solid_patches_cover_the_final_surface(void **state)
{
    (void)state;
    double facets, area, amax, want;
    solid_patches_at(0.003, 0.08, 1, &facets, &area, &amax, &want);
    print_message("solid: cells of 0.08: triangles %.5f (%+.3f %%), patches %.5f (%+.3f %%) vs analytic %.5f\n",
                  facets, 100 * (facets / want - 1), area, 100 * (area / want - 1), want);
    if (fabs(area - want) > 0.003 * want)
        fail_msg("solid area %.5f, analytic %.5f", area, want);
    solid_patches_at(0.0225, 0.45, 0, &facets, &area, &amax, &want);
    print_message("solid: cells of 0.45: triangles %.5f (%+.3f %%), patches %.5f (%+.3f %%) vs analytic %.5f\n",
                  facets, 100 * (facets / want - 1), area, 100 * (area / want - 1), want);
    assert_true(facets < 0.995 * want); /* the case the scaling is for: chords */
    if (fabs(area - want) > 0.003 * want)
        fail_msg("coarse solid area %.5f, analytic %.5f", area, want);
}

/* Builds k_bite's patches at these limits and checks them (with sides, also
 * that they face out and carry the leaf's material: at fine cells, where
 * the rim's band is thin); returns the triangles' and the patches' areas. */
static void solid_patches_at(double max_area, double max_edge, int sides, double *facets, double *area_out,
                             double *amax_out, double *want_out)
{
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(k_bite, "bite", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    rad_patch_opts o = {.max_area = max_area, .max_edge = max_edge, .accel = a};
    rad_patches *P = NULL;
    assert_int_equal(rad_patches_build(s, &o, &P, &err), RR_OK);
    const double R = 1, r = 0.6, d = 0.9, x = (d * d + R * R - r * r) / (2 * d);
    const double want = 4 * RR_PI * R * R - 2 * RR_PI * R * (R - x) + 2 * RR_PI * r * (r - (d - x));
    rr_vec3 c = rr_v3(d, 0, 0);
    /* The rim's pieces are split down to an eighth of a cell (rad_solid.c)
     * and kept when most of their sample points are on the surface. */
    double rim = rr_v3_len(P->solid[0].cell) / 4.0;
    for (size_t v = 0; v < P->nverts; v++) {
        double db = rr_v3_len(P->verts[v]) - R, ds = rr_v3_len(rr_v3_sub(P->verts[v], c)) - r;
        /* On one of the two spheres (each its own grid)... */
        if (!(fabs(db) < 1e-9 || fabs(ds) < 1e-9))
            fail_msg("vertex %zu off both surfaces: %g, %g", v, db, ds);
        /* ...and on the final solid: in the big sphere, out of the small one (a rim piece's corner may
         * stick out by a piece). */
        if (!(db < rim && ds > -rim))
            fail_msg("vertex %zu off the solid: %g, %g (rim pieces %g)", v, db, ds, rim);
    }
    double area = 0, amax = 0;
    double outward = 0, red_ok = 0; /* area */
    *facets = 0;
    for (size_t k = 0; k < P->n; k++) {
        const rad_patch *p = &P->p[k];
        assert_int_equal(p->object, 0);
        assert_true(p->area > 0);
        rr_vec3 A = P->verts[p->v[0]], B = P->verts[p->v[1]], C = P->verts[p->v[2]];
        double tri = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
        amax = fmax(amax, tri);
        *facets += tri;
        area += p->area;
        rr_vec3 out = rr_v3_madd(p->centroid, p->normal, 0.02), in = rr_v3_madd(p->centroid, p->normal, -0.02);
        outward += tri * (!rt_csg_contains(s, a, s->objects[0].csg_root, out) &&
                          rt_csg_contains(s, a, s->objects[0].csg_root, in));
        /* The bite's surface is the red leaf's. */
        int on_bite = rr_v3_len(rr_v3_sub(p->centroid, c)) < r + 1e-3 && rr_v3_len(p->centroid) < R - 1e-3;
        red_ok += tri * (on_bite == (p->rho.g < 0.3));
    }
    /* Near the rim the 0.02 probes and the leaf under a centre may be the
     * other side's: a band of patches a cell or two wide (or many small rim
     * pieces, rad_solid.c): by area. */
    print_message("solid: %zu patches (%.0f asked for), largest %.2f x the limit, outward %.2f %%, "
                  "material %.2f %%\n",
                  P->n, want / o.max_area, amax / o.max_area, 100.0 * outward / *facets, 100.0 * red_ok / *facets);
    assert_true(!sides || outward > 0.97 * *facets);
    assert_true(!sides || red_ok > 0.97 * *facets);
    /* The limits are targets for solids (rad_solid.c), and the estimate used
     * for memory checks bounds the count. */
    assert_true(amax < 3 * o.max_area);
    assert_true((double)P->n <= rad_solid_patch_estimate(s, 0, &o));
    *area_out = area;
    *amax_out = amax;
    *want_out = want;
    /* Hits on the surface find a patch within a cell of them. */
    rr_rng rng = rr_rng_make(7, 0);
    for (int i = 0; i < 2000; i++) {
        rr_ray ray = {rr_v3(4 * rr_rng_uniform(&rng) - 2, 4 * rr_rng_uniform(&rng) - 2, 5),
                      rr_v3(0.2 * rr_rng_uniform(&rng) - 0.1, 0.2 * rr_rng_uniform(&rng) - 0.1, -1)};
        rt_hit h;
        if (!rt_accel_closest(a, ray, 0, INFINITY, &h))
            continue;
        uint32_t k = rad_patch_locate(P, s, h.tri, h.object, h.point);
        assert_true(k < P->n);
        assert_true(rr_v3_len(rr_v3_sub(P->p[k].centroid, h.point)) < 1.25 * max_edge);
    }
    rad_patches_destroy(P);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* A mesh leaf's part of a solid is made of its own triangles (rad_solid.c):
 * the tetrahedron x, y, z >= 0, x + y + z <= 2 (tetra.obj scaled by 2) less
 * the ball of radius 0.5 at the origin. Analytic area: three right faces (2
 * each) and the slanted one (2 sqrt 3), less three quarter discs (pi 0.25 /
 * 4 each), plus the ball's octant (4 pi 0.25 / 8). The patches on the mesh
 * (flat) lie in its faces and, but for the pieces cut at the rim (down to an
 * eighth of a cell: a band 0.04 wide on a rim 2.4 long, at most 0.1 either
 * way, and kept or dropped by their sample points, so it mostly cancels),
 * sum to the faces' area less the discs: within 0.5 %; the other patches
 * (the ball's, by marching tetrahedra, scaled to their leaf's true area)
 * lie within a cell of the sphere; all of it within 0.5 %. Before, the mesh's
 * part was marching triangles too, which miss a scanned mesh's detail
 * (scenes/bunny-csg.json's bunny: 28 % of its area). */
static void mesh_leaf_patches_are_its_triangles(void **state)
{
    (void)state;
    static const char *json =
        "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[1,1,6],\"O\":[1,1,5],"
        "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},\"materials\":{\"a\":{\"diffuse\":0.5},\"b\":{\"diffuse\":0.2}},"
        "\"objects\":[{\"type\":\"csg\",\"op\":\"difference\",\"material\":\"a\",\"children\":["
        "{\"type\":\"mesh\",\"file\":\"meshes/tetra.obj\",\"transform\":[{\"scale\":2}]},"
        "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.5,\"material\":\"b\"}]}]}";
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(json, "tetra", RR_TEST_DATA "/scenes", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
    const double faces = 6.0 + 2.0 * sqrt(3.0) - 3.0 * RR_PI * 0.25 / 4.0, ball = 4.0 * RR_PI * 0.25 / 8.0;
    for (int fine = 0; fine < 2; fine++) {
        rad_patch_opts o = {.max_area = fine ? 0.002 : 0.02, .max_edge = fine ? 0.06 : 0.2, .accel = a};
        rad_patches *P = NULL;
        assert_int_equal(rad_patches_build(s, &o, &P, &err), RR_OK);
        double on_mesh = 0, rest = 0, cell = rr_v3_len(P->solid[0].cell);
        size_t nflat = 0, outward = 0;
        for (size_t k = 0; k < P->n; k++) {
            const rad_patch *p = &P->p[k];
            rr_vec3 x = p->centroid;
            if (p->flat) {
                nflat++;
                on_mesh += p->area;
                /* In one of the faces: x = 0, y = 0, z = 0 or x + y + z = 2. */
                double d = fmin(fmin(fabs(x.x), fabs(x.y)), fmin(fabs(x.z), fabs(x.x + x.y + x.z - 2) / sqrt(3.0)));
                if (!(d < 1e-12))
                    fail_msg("flat patch %zu off the mesh's faces by %g", k, d);
                assert_true(rr_v3_len(x) > 0.5 - cell / 8.0);
            } else {
                rest += p->area;
                assert_true(fabs(rr_v3_len(x) - 0.5) < cell);
            }
            /* Facing out of the solid (the ball's chords lie a sagitta inside
             * the ball: probed a cell far). */
            double r = p->flat ? 1e-4 : cell;
            rr_vec3 out = rr_v3_madd(x, p->normal, r), in = rr_v3_madd(x, p->normal, -r);
            outward += !rt_csg_contains(s, a, s->objects[0].csg_root, out) && rt_csg_contains(s, a, s->objects[0].csg_root, in);
        }
        print_message("mesh leaf (cells %.3f): %zu of %zu patches its own, area %.4f (%+.3f %%) of %.4f; "
                      "the ball's %.4f (%+.3f %%); outward %.2f %%\n",
                      cell, nflat, P->n, on_mesh, 100 * (on_mesh / faces - 1), faces, rest, 100 * (rest / ball - 1),
                      100.0 * outward / P->n);
        assert_true(nflat > 0 && nflat < P->n);
        assert_true(fabs(on_mesh - faces) < 0.005 * faces);
        assert_true(fabs(on_mesh + rest - faces - ball) < 0.005 * (faces + ball));
        assert_true(outward > 0.97 * P->n);
        /* the count --max-memory reads (rad_solid_own.c's estimate) */
        double est = rad_solid_patch_estimate(s, 0, &o);
        print_message("estimated %.0f patches\n", est);
        assert_true(fabs(est / (double)P->n - 1.0) <= 0.25);
        rad_patches_destroy(P);
    }
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* Random solids of every leaf kind (random ops, transforms, non-uniform
 * scales; a fixed seed) tessellate without failing, and every patch is a
 * proper piece of the final surface: positive finite area, unit normal, its
 * centre within a cell of the surface (a boundary along its normal; flat
 * patches, mesh triangles and faces, exactly on one), and none turned into
 * the solid (over 1 % of the area). Found the mesh leaves' shared edge
 * points keyed by step alone, across triangles split to different levels.
 * And the patch count that --max-memory reads (rad_patches_estimate, without
 * a BVH) is within 25 % of the count made, for solids of 100 patches or
 * more (it was 2 - 2.5 times the count while it was the marching
 * tetrahedra's rule). */
static void random_solids_tessellate(void **state)
{
    (void)state;
    static const char *leaves[] = {
        "{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.5",
        "{\"type\":\"box\",\"min\":[-0.4,-0.3,-0.5],\"max\":[0.4,0.3,0.5]",
        "{\"type\":\"quadric\",\"shape\":\"cylinder\",\"radius\":0.35,\"height\":1",
        "{\"type\":\"quadric\",\"shape\":\"cone\",\"radius\":0.5,\"height\":0.9",
        "{\"type\":\"quadric\",\"shape\":\"paraboloid\",\"radius\":0.45,\"height\":0.8",
        "{\"type\":\"quadric\",\"shape\":\"hyperboloid\",\"radius\":0.2,\"end_radius\":0.45,\"height\":0.9",
        "{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[0.6,0.35,0.45]",
        "{\"type\":\"mesh\",\"file\":\"meshes/tetra.obj\"",
    };
    static const char *ops[] = {"union", "intersection", "difference"};
    rr_rng rng = rr_rng_make(2026, 12);
    int built = 0;
    double worst = 0.0; /* the estimate's largest relative error */
    enum { TRIALS = 24 };
    for (int trial = 0; trial < TRIALS; trial++) {
        char kids[2][512];
        for (int k = 0; k < 2; k++) {
            int l = (int)(rr_rng_uniform(&rng) * 8) % 8;
            double t[3], ax[3], ang = 360 * rr_rng_uniform(&rng), sc[3];
            for (int i = 0; i < 3; i++) {
                t[i] = 0.5 * rr_rng_uniform(&rng) - 0.25;
                ax[i] = rr_rng_uniform(&rng) - 0.5;
                sc[i] = 0.7 + 0.6 * rr_rng_uniform(&rng);
            }
            snprintf(kids[k], sizeof kids[k],
                     "%s,\"material\":\"%s\",\"transform\":[{\"scale\":[%.3f,%.3f,%.3f]},{\"rotate\":{\"axis\":[%.3f,%.3f,%.3f],"
                     "\"degrees\":%.1f}},{\"translate\":[%.3f,%.3f,%.3f]}]}",
                     leaves[l], k ? "b" : "a", sc[0], sc[1], sc[2], ax[0], ax[1], ax[2] + 0.01, ang, t[0], t[1], t[2]);
        }
        const char *op = ops[(int)(rr_rng_uniform(&rng) * 3) % 3];
        char json[2048];
        snprintf(json, sizeof json,
                 "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
                 "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},\"materials\":{\"a\":{\"diffuse\":0.5},\"b\":{\"diffuse\":0.2}},"
                 "\"objects\":[{\"type\":\"csg\",\"op\":\"%s\",\"material\":\"a\",\"children\":[%s,%s]}]}",
                 op, kids[0], kids[1]);
        scene *s = NULL;
        rr_error err;
        if (scene_load_string(json, "random", RR_TEST_DATA "/scenes", NULL, &s, &err) != RR_OK)
            fail_msg("%s\n%s", err.msg, json);
        rt_accel *a = NULL;
        assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
        rad_patch_opts o = {.max_area = 0.004, .max_edge = 0.12, .accel = a};
        rad_patches *P = NULL;
        if (rad_patches_build(s, &o, &P, &err) != RR_OK)
            fail_msg("%s\n%s", err.msg, json);
        double cell = rr_v3_len(P->solid[0].cell), area = 0, inward = 0;
        for (size_t k = 0; k < P->n; k++) {
            const rad_patch *p = &P->p[k];
            if (!(p->area > 0 && isfinite(p->area)) || !(fabs(rr_v3_len(p->normal) - 1) < 1e-9))
                fail_msg("patch %zu: area %g, |normal| %g\n%s", k, p->area, rr_v3_len(p->normal), json);
            rt_spans sp;
            rr_ray ray = {p->centroid, p->normal};
            /* Flat pieces lie in their leaf's surface (to rounding), curved
             * ones are chords (within a cell); a rim piece (split, at most a
             * quarter of the area limit) may have its centre just off the
             * final surface. */
            double r = p->flat ? 1e-9 * (1 + rr_v3_len(p->centroid)) : cell;
            rt_solid_spans(s, a, 0, ray, -cell, cell, &sp);
            int near = 0;
            for (int q = 0; q < sp.n; q++)
                near |= fabs(sp.s[q].in.t) < r || fabs(sp.s[q].out.t) < r;
            if (!near && !(p->area < 0.25 * o.max_area))
                fail_msg("patch %zu (flat %u, area %g) off the surface\n%s", k, p->flat, p->area, json);
            rr_vec3 A = P->verts[p->v[0]], B = P->verts[p->v[1]], C = P->verts[p->v[2]];
            double tri = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
            /* probes a quarter of the piece's edge out and in: beyond a chord's
             * sagitta where the curvature radius exceeds half the edge */
            double h = fmax(1e-4, 0.25 * sqrt(2.0 * tri));
            rr_vec3 out = rr_v3_madd(p->centroid, p->normal, h), in = rr_v3_madd(p->centroid, p->normal, -h);
            /* turned inwards: the solid ahead, not behind (where both probes
             * are out, the solid is thinner than the probes there) */
            inward += tri * (rt_csg_contains(s, a, s->objects[0].csg_root, out) &&
                             !rt_csg_contains(s, a, s->objects[0].csg_root, in));
            area += tri;
        }
        /* The estimate that --max-memory reads (without the BVH, as the
         * app asks it before building one) against the count. */
        rad_patch_opts on = o;
        on.accel = NULL;
        double est = rad_patches_estimate(s, &on), ratio = P->n ? est / (double)P->n : 1.0;
        if (P->n >= 100) {
            worst = fmax(worst, fabs(ratio - 1.0));
            if (!(fabs(ratio - 1.0) <= 0.25))
                fail_msg("%zu patches, estimated %.0f\n%s", P->n, est, json);
        }
        if (P->n) {
            built++;
            if (!(inward < 0.01 * area))
                fail_msg("inward over %.1f %% of the area\n%s", 100 * inward / area, json);
        }
        rad_patches_destroy(P);
        rt_accel_destroy(a);
        scene_destroy(s);
    }
    print_message("random solids: %d of %d with a surface; patch estimates within %.1f %%\n", built, TRIALS,
                  100 * worst);
    assert_true(built >= TRIALS / 2);
}

/* The radiosity of the board under a red sphere (colour bleeding) is the same
 * whether the sphere is the analytic sphere (UV tessellation) or the same
 * sphere as a solid, a quadric ellipsoid with equal radii (marching
 * tetrahedra): two independent tessellations. Compared: the red and the green
 * power the board receives within 0.6 of the point under the sphere,
 * quadrature form factors (no Monte Carlo noise; visibility rays only where
 * the sphere partly hides the lamp). Tolerance 3 %: the two tessellations
 * differ in area by under 1 % and the sphere's patches see the board through
 * facets that differ at the patch scale. */
static void solid_bleeds_like_the_sphere(void **state)
{
    (void)state;
    const char *fmt =
        "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,1,5],\"O\":[0,1,4],"
        "\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
        "\"materials\":{\"board\":{\"diffuse\":0.8},\"red\":{\"diffuse\":[0.8,0.05,0.05]},"
        "\"lamp\":{\"diffuse\":0,\"emission\":[9,9,9]}},\"objects\":["
        "{\"type\":\"quad\",\"material\":\"board\",\"vertices\":[[-1.5,0,-1.5],[-1.5,0,1.5],[1.5,0,1.5],[1.5,0,-1.5]]},"
        "{\"type\":\"quad\",\"material\":\"lamp\",\"vertices\":[[-2.3,2.6,-0.75],[-0.8,2.6,-0.75],[-0.8,2.6,0.75],"
        "[-2.3,2.6,0.75]]},%s]}";
    const char *ball[2] = {
        "{\"type\":\"sphere\",\"material\":\"red\",\"center\":[0,0.75,0],\"radius\":0.5}",
        "{\"type\":\"quadric\",\"shape\":\"ellipsoid\",\"radii\":[0.5,0.5,0.5],\"material\":\"red\","
        "\"transform\":[{\"translate\":[0,0.75,0]}]}"};
    double red[2] = {0, 0}, green[2] = {0, 0};
    for (int v = 0; v < 2; v++) {
        char json[2048];
        snprintf(json, sizeof json, fmt, ball[v]);
        scene *s = NULL;
        rr_error err;
        if (scene_load_string(json, v ? "solid" : "sphere", "", NULL, &s, &err) != RR_OK)
            fail_msg("%s", err.msg);
        rt_accel *a = NULL;
        assert_int_equal(rt_accel_build(s, &a, NULL), RR_OK);
        rad_pass_opts po;
        memset(&po, 0, sizeof po);
        po.patch.max_area = 0.01;
        po.patch.max_edge = 0.15;
        po.ff.method = RAD_FF_QUADRATURE;
        po.ff.samples = 16;
        po.solve.solver = RAD_SOLVER_DIRECT;
        rad_solution *sol = NULL;
        if (rad_pass_run(s, a, &po, &sol, &err) != RR_OK)
            fail_msg("%s", err.msg);
        /* Indirect irradiance on the board: light after a bounce, most of
         * it off the sphere in the red channel. */
        for (size_t k = 0; k < sol->P->n; k++) {
            const rad_patch *p = &sol->P->p[k];
            if (p->object != 0 || rr_v3_len(p->centroid) > 0.6)
                continue;
            double H[3] = {0, 0, 0};
            for (int e = 0; e < 3; e++) {
                rr_rgb h = sol->vertex_Hind[p->v[e]];
                H[0] += h.r / 3, H[1] += h.g / 3;
            }
            red[v] += H[0] * p->area;
            green[v] += H[1] * p->area;
        }
        rad_solution_destroy(sol);
        rt_accel_destroy(a);
        scene_destroy(s);
    }
    print_message("board under the ball: red %.5f (sphere) %.5f (solid), green %.5f %.5f\n", red[0], red[1], green[0],
                  green[1]);
    /* Bleeding at all: the board under the sphere gets several times more red. */
    assert_true(red[0] > 3 * green[0]);
    if (fabs(red[1] - red[0]) > 0.03 * red[0] || fabs(green[1] - green[0]) > 0.05 * green[0])
        fail_msg("board under the sphere: red %.5f (sphere) vs %.5f (solid), green %.5f vs %.5f", red[0], red[1],
                 green[0], green[1]);
}

/* Vertex values from patch values (rad__to_vertices). On a unit floor, patch
 * values the exact means of f = 1 + 2x over each patch (f at the centroid,
 * f being linear): plain area-weighted means are exact at interior vertices
 * of the symmetric grid but flatten f at the floor's edges x = 0 and x = 1
 * (a one-sided mean lies a third of a patch inwards); back-projection
 * (RAD_HIND_SWEEPS sweeps) brings the edges' values towards f and each
 * patch's interpolated mean towards its value. A constant field stays exact. */
static double linear_f(rr_vec3 p) { return 1.0 + 2.0 * p.x; }

static void edge_errors(const rad_patches *P, const rr_rgb *vv, double *vertex_err, double *mean_err)
{
    *vertex_err = *mean_err = 0;
    for (size_t v = 0; v < P->nverts; v++)
        *vertex_err = fmax(*vertex_err, fabs(vv[v].g - linear_f(P->verts[v])));
    for (size_t k = 0; k < P->n; k++) {
        const uint32_t *pv = P->p[k].v;
        double m = (vv[pv[0]].g + vv[pv[1]].g + vv[pv[2]].g) / 3.0;
        *mean_err = fmax(*mean_err, fabs(m - linear_f(P->p[k].centroid)));
    }
}

static void vertex_values_keep_patch_means(void **state)
{
    (void)state;
    static const char *const floor_json =
        "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0.5,1,0.5],\"O\":[0.5,0,0.5],"
        "\"U\":[0,0,-1],\"s\":0.1,\"w\":2,\"h\":2},\"materials\":{\"w\":{\"diffuse\":0.5}},\"objects\":["
        "{\"name\":\"floor\",\"type\":\"quad\",\"material\":\"w\",\"vertices\":[[0,0,0],[0,0,1],[1,0,1],[1,0,0]]}]}";
    scene *s = NULL;
    rr_error err;
    if (scene_load_string(floor_json, "floor", "", NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    rad_patch_opts o = {.max_area = 0.01, .max_edge = 0.2, .accel = NULL};
    rad_patches *P = NULL;
    assert_int_equal(rad_patches_build(s, &o, &P, NULL), RR_OK);
    assert_true(P->n >= 100);
    rr_rgb *H = malloc(P->n * sizeof *H), *plain = malloc(P->nverts * sizeof *plain);
    rr_rgb *swept = malloc(P->nverts * sizeof *swept);
    for (size_t k = 0; k < P->n; k++)
        H[k] = rr_rgb_make(1, linear_f(P->p[k].centroid), 1);
    assert_int_equal(rad__to_vertices(P, H, 0, plain), RR_OK);
    assert_int_equal(rad__to_vertices(P, H, RAD_HIND_SWEEPS, swept), RR_OK);
    double plain_v, plain_m, swept_v, swept_m;
    edge_errors(P, plain, &plain_v, &plain_m);
    edge_errors(P, swept, &swept_v, &swept_m);
    print_message("f = 1 + 2x on %zu patches: worst vertex error %.4f -> %.4f, worst patch-mean error %.4f -> %.4f\n",
                  P->n, plain_v, swept_v, plain_m, swept_m);
    /* Cells of 1/8 here (f changes by 0.25 across one): the one-sided means at
     * the edges are off by a good part of that (0.125 measured). */
    assert_true(plain_v > 0.05);
    assert_true(swept_v < 0.5 * plain_v && swept_m < 0.5 * plain_m);
    for (size_t v = 0; v < P->nverts; v++) /* the constant channels */
        assert_true(fabs(swept[v].r - 1.0) < 1e-12 && fabs(swept[v].b - 1.0) < 1e-12);
    free(H);
    free(plain);
    free(swept);
    rad_patches_destroy(P);
    scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(limits_and_areas),
        cmocka_unit_test(solid_patches_cover_the_final_surface),
        cmocka_unit_test(mesh_leaf_patches_are_its_triangles),
        cmocka_unit_test(random_solids_tessellate),
        cmocka_unit_test(solid_bleeds_like_the_sphere),
        cmocka_unit_test(conforming_box),
        cmocka_unit_test(vertex_values_keep_patch_means),
        cmocka_unit_test(level_outlier_named),
        cmocka_unit_test(locate_hits),
        cmocka_unit_test(bad_limits),
        cmocka_unit_test(furnace_pipeline),
        cmocka_unit_test(cornell_radiosity_vs_secondary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
