/* rad_pass.c - the radiosity pass end to end, and its display: radiosity at
 * vertices (area-weighted), Gouraud-interpolated across each patch. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "rad_hier_internal.h"
#include "rad_pass_internal.h"

#define FIRST_SHOT_CHUNK 256 /* patches per unit of the first shot's deterministic sums */

rad_patch_opts rad_pass_patch_limits(const scene *s, const rad_pass_opts *o)
{
    rad_patch_opts p;
    memset(&p, 0, sizeof p); /* the curved limits: those of every surface */
    p.max_area = o && o->patch.max_area > 0 ? o->patch.max_area : s->radiosity.patch_area;
    p.max_edge = o && o->patch.max_edge > 0 ? o->patch.max_edge : s->radiosity.patch_edge;
    p.accel = o ? o->patch.accel : NULL;
    if (!(p.max_area > 0)) {
        /* Automatic: about 2000 patches' worth of the scene's surface. */
        double total = 0;
        for (size_t t = 0; t < s->ntris; t++)
            total += scene_tri_area(s, t);
        for (size_t i = 0; i < s->nobjects; i++) {
            /* Spheres exactly, solids by their bounding box (rt_prims). */
            rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)i);
            if (k != RT_PRIM_TRIANGLE)
                total += rt_prims[k].area(s, (uint32_t)i);
        }
        p.max_area = total > 0 ? total / 2000.0 : 1.0;
    }
    if (!(p.max_edge > 0))
        p.max_edge = 2.0 * sqrt(p.max_area);
    return p;
}

/* The hierarchical method's roots and smallest elements, from the same
 * limits (rad_hier_internal.h). */
rad_patch_opts rad__hier_root_limits(const scene *s, const rad_pass_opts *o)
{
    rad_patch_opts p = rad_pass_patch_limits(s, o);
    /* Curved surfaces keep the patches' limits: an element is a flat piece
     * of its root, with the root's normal, so a sphere's roots 16 times the
     * patch area shaded it in facets of ~40 degrees, and the lit side of
     * sphere-to-board's sphere came out +7.0 % in the radiosity display
     * (the flat method, at the patch area, +2.5 %); the incident power was
     * right (-0.6 % against the light tracer). */
    p.curved_max_area = p.max_area;
    p.curved_max_edge = p.max_edge;
    p.max_area *= 16.0;
    p.max_edge *= 4.0;
    return p;
}

double rad__hier_min_area(const scene *s, const rad_pass_opts *o)
{
    if (o && o->hier.min_area > 0)
        return o->hier.min_area;
    if (s->radiosity.min_area > 0)
        return s->radiosity.min_area;
    return rad_pass_patch_limits(s, o).max_area / 16.0;
}

/* Rough per-item costs (per patch: RAD_PATCH_BYTES); a form factor is a
 * column (uint32) and a value (double). The form factors' peak is 2 + U raw
 * matrices, U the union's size over the raw one (1 to 2; measured 1.36 on scenes/room.json and 1.49
 * on the Cornell box at 108,854 patches): 3.5 is within 20 % for any U. */
#define RAD_FF_ENTRY_BYTES 12.0
#define RAD_FF_PEAK_RAWS 3.5

double rad_pass_memory_estimate(const scene *s, const rad_pass_opts *o, int cached, double *patches)
{
    rad_patch_opts lim = rad_pass_patch_limits(s, o);
    if (rad__pass_method(s, o, NULL) == RAD_METHOD_HIERARCHICAL) {
        /* The least it needs: the roots as elements, clusters and leaves
         * (the pass keeps its links under rad_hier_opts.max_bytes); a cache
         * is read as leaves, about the flat patch count. */
        rad_patch_opts rl = rad__hier_root_limits(s, o);
        double roots = rad_patches_estimate(s, &rl), leaves = fmax(rad_patches_estimate(s, &lim), roots);
        if (patches)
            *patches = cached ? leaves : roots;
        return cached ? leaves * RAD_PATCH_BYTES : rad__hier_bytes(0.0, roots, roots);
    }
    double n = rad_patches_estimate(s, &lim);
    int method = o->use_scene_choices ? (int)s->radiosity.form_factors : (int)o->ff.method;
    int samples = o->ff.samples > 0 ? o->ff.samples : s->radiosity.ff_samples;
    double per_row = method == RAD_FF_MONTE_CARLO ? fmin(n, (double)(samples > 0 ? samples : 1)) : n;
    if (patches)
        *patches = n;
    return n * (double)RAD_PATCH_BYTES + (cached ? 0.0 : RAD_FF_PEAK_RAWS * RAD_FF_ENTRY_BYTES * n * per_row);
}

void rad_solution_destroy(rad_solution *sol)
{
    if (!sol)
        return;
    rad_patches_destroy(sol->P);
    rad_ff_destroy(sol->F);
    free(sol->B);
    free(sol->vertex_B);
    free(sol->emitted);
    free(sol->first_shot);
    free(sol->light_landed);
    free(sol->vertex_Hind);
    free(sol->hier_H);
    free(sol->hier_fsum);
    free(sol->stats.history);
    free(sol);
}

/* H0: irradiance on the triangle corner[0..2] of patch k of P (the patch
 * itself, or a part of it) from every point and directional light and their
 * images in planar mirrors (the light interface, rt_light.c), averaged over 4
 * points (centroid and the three points halfway to the corners), each with its
 * shadow rays. When landed is set, landed[l] += weight times what scene light
 * l contributes (weight (1 - m) A: the power of light l that ends on the
 * patch's front, for the energy ledger). When spread is set, it gets the
 * largest difference between two of the 4 points (max over channels). */
rr_rgb rad__first_shot(const scene *s, const rt_accel *a, const rt_lights *L, const rad_patches *P, uint32_t k,
                       const rr_vec3 corner[3], rr_rgb *landed, double weight, double *spread)
{
    static const double w[4][3] = {{1. / 3, 1. / 3, 1. / 3}, {2. / 3, 1. / 6, 1. / 6}, {1. / 6, 2. / 3, 1. / 6},
                                   {1. / 6, 1. / 6, 2. / 3}};
    rr_rgb H = rr_rgb_make(0, 0, 0), lo = rr_rgb_make(INFINITY, INFINITY, INFINITY), hi = rr_rgb_make(0, 0, 0);
    size_t nd = rt_lights_delta_count(L);
    for (int q = 0; q < 4; q++) {
        rr_vec3 xf = rr_v3_add(rr_v3_add(rr_v3_scale(corner[0], w[q][0]), rr_v3_scale(corner[1], w[q][1])),
                               rr_v3_scale(corner[2], w[q][2]));
        rr_vec3 x, N;
        rad_patch_surface(P, s, a, k, xf, &x, &N);
        rr_rgb Hq = rr_rgb_make(0, 0, 0);
        for (size_t i = 0; i < nd; i++) {
            rt_light_sample ls;
            if (!rt_lights_delta(L, i, x, N, &ls))
                continue;
            rr_rgb e = rr_rgb_scale(ls.E, 0.25 * rr_v3_dot(N, ls.L));
            H = rr_rgb_add(H, e); /* summed as before the spread was added: the same bits */
            Hq = rr_rgb_add(Hq, e);
            if (landed) {
                rr_rgb *d = &landed[rt_lights_delta_source(L, i)];
                *d = rr_rgb_add(*d, rr_rgb_scale(e, weight));
            }
        }
        lo = rr_rgb_make(fmin(lo.r, Hq.r), fmin(lo.g, Hq.g), fmin(lo.b, Hq.b));
        hi = rr_rgb_make(fmax(hi.r, Hq.r), fmax(hi.g, Hq.g), fmax(hi.b, Hq.b));
    }
    if (spread)
        *spread = 4.0 * fmax(hi.r - lo.r, fmax(hi.g - lo.g, hi.b - lo.b)); /* Hq holds a quarter of each point's */
    return H;
}

static rr_rgb first_shot(const scene *s, const rt_accel *a, const rt_lights *L, const rad_patches *P, size_t k,
                         rr_rgb *landed)
{
    const rad_patch *p = &P->p[k];
    rr_vec3 c[3] = {P->verts[p->v[0]], P->verts[p->v[1]], P->verts[p->v[2]]};
    return rad__first_shot(s, a, L, P, (uint32_t)k, c, landed, (1.0 - p->mirror) * p->area, NULL);
}

rr_status rad__first_shots(const scene *s, const rt_accel *a, rad_solution *sol, rr_error *err)
{
    size_t n = sol->P->n;
    rr_status st;
    rt_lights *L = NULL;
    if ((st = rt_lights_build(s, a, s->settings.max_depth, &L, err)) != RR_OK)
        return st;
    /* Chunks of patches, each summing its lights' landed power in patch
     * order, reduced in chunk order: the same sums for any thread count. */
    size_t nl = s->nlights, nchunks = (n + FIRST_SHOT_CHUNK - 1) / FIRST_SHOT_CHUNK;
    rr_rgb *part = nl ? calloc(nchunks * nl, sizeof *part) : NULL;
    free(sol->light_landed);
    sol->light_landed = calloc(nl ? nl : 1, sizeof *sol->light_landed);
    if ((nl && !part) || !sol->light_landed) {
        free(part);
        rt_lights_destroy(L);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for %zu patches", s->path, n);
    }
#pragma omp parallel for schedule(dynamic, 1) if (nl > 0)
    for (long c = 0; c < (long)nchunks; c++) {
        size_t hi = ((size_t)c + 1) * FIRST_SHOT_CHUNK < n ? ((size_t)c + 1) * FIRST_SHOT_CHUNK : n;
        for (size_t k = (size_t)c * FIRST_SHOT_CHUNK; k < hi; k++) {
            rad_patch *p = &sol->P->p[k];
            sol->emitted[k] = p->emission;
            sol->first_shot[k] = nl ? first_shot(s, a, L, sol->P, k, part + (size_t)c * nl) : rr_rgb_make(0, 0, 0);
            p->emission = rr_rgb_add(p->emission, rr_rgb_mul(p->rho, sol->first_shot[k]));
        }
    }
    for (size_t c = 0; c < nchunks && nl; c++)
        for (size_t l = 0; l < nl; l++)
            sol->light_landed[l] = rr_rgb_add(sol->light_landed[l], part[c * nl + l]);
    free(part);
    rt_lights_destroy(L);
    return RR_OK;
}

/* Whether a surface of the scene (a triangle, a sphere, a solid's leaf)
 * has material m: a mirror material that nothing uses is no mirror. */
static int material_used(const scene *s, uint32_t m)
{
    for (size_t i = 0; i < s->ntris; i++)
        if (s->tris[i].material == m)
            return 1;
    for (size_t i = 0; i < s->nobjects; i++)
        if (s->objects[i].kind == SCENE_OBJ_SPHERE && s->objects[i].material == m)
            return 1;
    for (size_t i = 0; i < s->ncsg; i++)
        if (s->csg[i].op == SCENE_CSG_LEAF && s->csg[i].material == m)
            return 1;
    return 0;
}

static int mirror_material(const scene *s, size_t i)
{
    return rr_rgb_max(s->materials[i].mirror) > 0 && material_used(s, (uint32_t)i);
}

/* Says what the pass does not carry of this scene's mirrors. */
static void mirror_warnings(const scene *s, const rad_ff_opts *fo, const rr_warn_sink *warn)
{
    int any = 0, coloured = 0;
    for (size_t i = 0; i < s->nmaterials; i++) {
        rr_rgb m = s->materials[i].mirror;
        if (mirror_material(s, i)) {
            any = 1;
            coloured |= m.r != m.g || m.g != m.b;
        }
    }
    if (any && fo->method == RAD_FF_QUADRATURE)
        rr_warn(warn, "%s: radiosity: quadrature form factors do not reflect off mirrors: light by way of mirrors "
                      "is missing from the radiosity pass (use \"form_factors\": \"montecarlo\")",
                s->path);
    else if (coloured)
        rr_warn(warn, "%s: radiosity: a coloured mirror reflects the mean of its three channels in the radiosity "
                      "pass (the ray tracer uses all three)",
                s->path);
}

static int scene_has_mirrors(const scene *s)
{
    for (size_t i = 0; i < s->nmaterials; i++)
        if (mirror_material(s, i))
            return 1;
    return 0;
}

rad_method rad__pass_method(const scene *s, const rad_pass_opts *o, const rr_warn_sink *warn)
{
    rad_method m = o->use_scene_choices ? (s->radiosity.method == SCENE_RAD_FLAT ? RAD_METHOD_FLAT
                                                                                 : RAD_METHOD_HIERARCHICAL)
                                        : o->method;
    if (m == RAD_METHOD_HIERARCHICAL && scene_has_mirrors(s) && rt_scene_mirror_kind(s) == RT_MIRRORS_CURVED) {
        /* The hierarchical pass links by way of chains of planar mirrors
         * (rad_hier.c, "Mirrors"); the flat Monte Carlo form factors follow
         * rays off mirrors of any shape (extended form factors). */
        if (warn)
            rr_warn(warn, "%s: radiosity: the scene has a curved mirror: the flat method (Monte Carlo form factors "
                          "through mirrors) is used instead of the hierarchical one, which links by way of planar "
                          "mirrors only",
                    s->path);
        m = RAD_METHOD_FLAT;
    }
    return m;
}

rr_status rad_pass_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, rad_solution **out, rr_error *err)
{
    rad_pass_opts def;
    memset(&def, 0, sizeof def);
    def.use_scene_choices = 1;
    if (!o)
        o = &def;
    rad_solution *sol = rad__solution_new(s);
    if (!sol)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", s->path);
    rr_status st;
    if (rad__pass_method(s, o, &o->warn) == RAD_METHOD_HIERARCHICAL) {
        if ((st = rad__hier_run(s, a, o, sol, err)) != RR_OK)
            goto fail;
        *out = sol;
        return RR_OK;
    }
    double t0 = rr_now_seconds();
    rad_patch_opts po = rad_pass_patch_limits(s, o);
    po.accel = a;
    rad_patches_level_outliers(s, &po, &o->warn);
    if ((st = rad_patches_build(s, &po, &sol->P, err)) != RR_OK)
        goto fail;
    double t1 = rr_now_seconds();
    rad_ff_opts fo = o->ff;
    if (o->use_scene_choices)
        fo.method = s->radiosity.form_factors == SCENE_FF_QUADRATURE ? RAD_FF_QUADRATURE : RAD_FF_MONTE_CARLO;
    if (fo.samples <= 0)
        fo.samples = s->radiosity.ff_samples;
    if (fo.mirror_depth <= 0)
        fo.mirror_depth = s->settings.max_depth;
    mirror_warnings(s, &fo, &o->warn);
    fo.rays = &sol->ff_rays;
    if ((st = rad_ff_compute(s, a, sol->P, &fo, &sol->F, err)) != RR_OK)
        goto fail;
    sol->nnz = sol->F->rowptr[sol->F->n];
    /* From here on a patch's area is its open part's (rad.h: buried parts):
     * the solve, the first shots, the ledger and the vertex means all weigh
     * a patch by the area that can be lit and seen. */
    for (size_t i = 0; i < sol->P->n; i++)
        sol->P->p[i].area *= sol->F->open[i];
    double t2 = rr_now_seconds();
    rad_solve_opts so = o->solve;
    if (o->use_scene_choices)
        so.solver = (rad_solver)s->radiosity.solver;
    if (!(so.tolerance > 0))
        so.tolerance = s->radiosity.tolerance;
    if (!so.interrupt)
        so.interrupt = o->ff.interrupt; /* one interrupt for the whole pass */
    size_t n = sol->P->n;
    rr_rgb *Hind = malloc(n * sizeof *Hind);
    if (rad__solution_arrays(sol) != 0 || !Hind) {
        free(Hind);
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for %zu patches", s->path, n);
        goto fail;
    }
    if ((st = rad__first_shots(s, a, sol, err)) != RR_OK) {
        free(Hind);
        goto fail;
    }
    if ((st = rad_solve(sol->P, sol->F, &so, sol->B, &sol->stats, err)) != RR_OK) {
        free(Hind);
        rr_error_prefix(err, "%s: radiosity", s->path);
        goto fail;
    }
    double t3 = rr_now_seconds();
    /* Indirect irradiance: what arrives from other patches, less what they
     * emit themselves (that is direct light, which the ray tracer computes). */
    const rad_ff *F = sol->F;
    for (size_t i = 0; i < n; i++) {
        rr_rgb h = rr_rgb_make(0, 0, 0);
        for (size_t e = F->rowptr[i]; e < F->rowptr[i + 1]; e++) {
            uint32_t j = F->col[e];
            rr_rgb bounced = rr_rgb_add(sol->B[j], rr_rgb_scale(sol->emitted[j], -1.0));
            h = rr_rgb_add(h, rr_rgb_scale(bounced, F->val[e]));
        }
        Hind[i] = h;
    }
    /* Vertex values: mean of the patches around a vertex, weighted by area
     * (the classic display of Cohen & Greenberg; patches of one object share
     * vertices, so the interpolated image is continuous across the object);
     * the hybrid's indirect irradiance then back-projected (RAD_HIND_SWEEPS). */
    if (rad__to_vertices(sol->P, sol->B, 0, sol->vertex_B) != RR_OK || rad__to_vertices(sol->P, Hind, RAD_HIND_SWEEPS, sol->vertex_Hind) != RR_OK) {
        free(Hind);
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", s->path);
        goto fail;
    }
    free(Hind);
    sol->seconds_patches = t1 - t0;
    sol->seconds_ff = t2 - t1;
    sol->seconds_solve = t3 - t2;
    *out = sol;
    return RR_OK;
fail:
    rad_solution_destroy(sol);
    return st;
}

/* Gouraud: the vertex values of the patch under the hit, by barycentrics. */
static rr_rgb interpolate(const rad_solution *sol, const scene *s, const rt_hit *h, const rr_rgb *vertex_values)
{
    uint32_t k = rad_patch_locate(sol->P, s, h->tri, h->object, h->point);
    if (k >= sol->P->n)
        return rr_rgb_make(0, 0, 0); /* a solid too thin to have patches */
    const rad_patch *p = &sol->P->p[k];
    double b[3];
    rad_patch_barycentric(sol->P, k, h->point, b);
    double sum = 0;
    for (int e = 0; e < 3; e++) {
        b[e] = b[e] < 0 ? 0 : b[e];
        sum += b[e];
    }
    rr_rgb B = rr_rgb_make(0, 0, 0);
    for (int e = 0; e < 3; e++)
        B = rr_rgb_add(B, rr_rgb_scale(vertex_values[p->v[e]], sum > 0 ? b[e] / sum : 1.0 / 3.0));
    return B;
}

rr_rgb rad_radiance_at(const rad_solution *sol, const scene *s, const rt_hit *h)
{
    /* Patches radiate from their front only; the back of an open surface
     * shows nothing. */
    if (!h->front)
        return rr_rgb_make(0, 0, 0);
    return rr_rgb_scale(interpolate(sol, s, h, sol->vertex_B), 1.0 / RR_PI);
}

rr_rgb rad_indirect_at(const rad_solution *sol, const scene *s, const rt_hit *h, rr_rgb rho)
{
    if (!h->front)
        return rr_rgb_make(0, 0, 0);
    return rr_rgb_scale(rr_rgb_mul(rho, interpolate(sol, s, h, sol->vertex_Hind)), 1.0 / RR_PI);
}

/* The solution that embeds field f. */
static const rad_solution *field_owner(const rt_field *f)
{
    return (const rad_solution *)(const void *)((const char *)f - offsetof(rad_solution, field));
}

static rr_rgb field_radiance(const rt_field *f, const rt_hit *hit)
{
    const rad_solution *sol = field_owner(f);
    return rad_radiance_at(sol, sol->scene, hit);
}

static rr_rgb field_indirect(const rt_field *f, const rt_hit *hit, rr_rgb rho)
{
    const rad_solution *sol = field_owner(f);
    return rad_indirect_at(sol, sol->scene, hit, rho);
}

const rt_field *rad_solution_field(const rad_solution *sol) { return &sol->field; }

int rad__solution_arrays(rad_solution *sol)
{
    size_t n = sol->P->n, nv = sol->P->nverts ? sol->P->nverts : 1;
    sol->B = malloc(n * sizeof *sol->B);
    sol->emitted = malloc(n * sizeof *sol->emitted);
    sol->first_shot = malloc(n * sizeof *sol->first_shot);
    sol->vertex_B = malloc(nv * sizeof *sol->vertex_B);
    sol->vertex_Hind = malloc(nv * sizeof *sol->vertex_Hind);
    return sol->B && sol->emitted && sol->first_shot && sol->vertex_B && sol->vertex_Hind ? 0 : -1;
}

rad_solution *rad__solution_new(const scene *s)
{
    rad_solution *sol = calloc(1, sizeof *sol);
    if (!sol)
        return NULL;
    sol->field.radiance = field_radiance;
    sol->field.indirect = field_indirect;
    sol->scene = s;
    return sol;
}
