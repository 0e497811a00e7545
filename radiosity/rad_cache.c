/* rad_cache.c - saving a radiosity solution and using it again.
 *
 * Rendering several views of one room should not redo the radiosity pass. The
 * cache holds what the display and the hybrid read (per patch B, emission,
 * first shot; per vertex B and indirect irradiance), not the form factors.
 * Patches are rebuilt on load (cheap and deterministic) and must match.
 *
 * The file starts with a key: a 64-bit FNV-1a hash of everything the solution
 * depends on: geometry, materials, lights, the resolved patch limits, the
 * form-factor method, samples and seed, the solver settings, and the mirrors
 * (reflectances, render.max_depth: extended form factors and light images). A cache whose
 * key differs was made for another scene or other settings and is refused. */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "rad.h"

#define CACHE_MAGIC "RADRAYRC"
#define CACHE_VERSION 2u /* 2: mirrors in the key (extended form factors, images of lights) */

typedef struct hasher {
    uint64_t h;
} hasher;

static void hash_bytes(hasher *x, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        x->h ^= p[i];
        x->h *= 0x100000001b3ULL;
    }
}
static void hash_double(hasher *x, double v) { hash_bytes(x, &v, sizeof v); }
static void hash_vec(hasher *x, rr_vec3 v)
{
    hash_double(x, v.x);
    hash_double(x, v.y);
    hash_double(x, v.z);
}
static void hash_rgb(hasher *x, rr_rgb c)
{
    hash_double(x, c.r);
    hash_double(x, c.g);
    hash_double(x, c.b);
}

/* What the solution depends on, resolved the way rad_pass_run resolves it. */
static uint64_t cache_key(const scene *s, const rad_pass_opts *o)
{
    hasher x = {0xcbf29ce484222325ULL};
    hash_bytes(&x, CACHE_MAGIC, 8);
    for (size_t i = 0; i < s->nverts; i++)
        hash_vec(&x, s->verts[i]);
    for (size_t i = 0; i < s->ntris; i++)
        hash_bytes(&x, &s->tris[i], sizeof s->tris[i]);
    for (size_t i = 0; i < s->nmaterials; i++) {
        hash_rgb(&x, s->materials[i].diffuse);
        hash_rgb(&x, s->materials[i].emission);
        hash_rgb(&x, s->materials[i].mirror);
    }
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_object *ob = &s->objects[i];
        hash_bytes(&x, &ob->kind, sizeof ob->kind);
        hash_bytes(&x, &ob->material, sizeof ob->material);
        if (ob->kind == SCENE_OBJ_SPHERE) {
            hash_vec(&x, ob->center);
            hash_double(&x, ob->radius);
        }
        hash_bytes(&x, &ob->csg_root, sizeof ob->csg_root);
    }
    /* Solids: field by field (the structs have padding). */
    for (size_t i = 0; i < s->ncsg; i++) {
        const scene_csg_node *n = &s->csg[i];
        uint32_t w[6] = {(uint32_t)n->op, n->left, n->right, (uint32_t)n->solid, n->material, n->object};
        hash_bytes(&x, w, sizeof w);
        for (int r = 0; r < 3; r++)
            hash_vec(&x, rr_v3(n->to_world.m[r][0], n->to_world.m[r][1], n->to_world.m[r][2]));
        hash_vec(&x, n->to_world.t);
        hash_vec(&x, n->center);
        hash_double(&x, n->radius);
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++)
                hash_double(&x, n->q[r][c]);
        hash_vec(&x, n->clip_lo);
        hash_vec(&x, n->clip_hi);
        uint64_t tr[2] = {n->tri_first, n->tri_count};
        hash_bytes(&x, tr, sizeof tr);
    }
    for (size_t i = 0; i < s->ncsg_verts; i++)
        hash_vec(&x, s->csg_verts[i]);
    if (s->ncsg_tris)
        hash_bytes(&x, s->csg_tris, s->ncsg_tris * sizeof *s->csg_tris);
    for (size_t i = 0; i < s->nlights; i++) {
        hash_bytes(&x, &s->lights[i].type, sizeof s->lights[i].type);
        hash_vec(&x, s->lights[i].direction);
        hash_vec(&x, s->lights[i].position);
        hash_rgb(&x, s->lights[i].intensity);
    }
    rad_patch_opts po = rad_pass_patch_limits(s, o);
    hash_double(&x, po.max_area);
    hash_double(&x, po.max_edge);
    int method = o->use_scene_choices ? (int)s->radiosity.form_factors : (int)o->ff.method;
    int samples = o->ff.samples > 0 ? o->ff.samples : s->radiosity.ff_samples;
    int solver = o->use_scene_choices ? (int)s->radiosity.solver : (int)o->solve.solver;
    double tol = o->solve.tolerance > 0 ? o->solve.tolerance : s->radiosity.tolerance;
    hash_bytes(&x, &method, sizeof method);
    hash_bytes(&x, &samples, sizeof samples);
    hash_bytes(&x, &o->ff.seed, sizeof o->ff.seed);
    hash_bytes(&x, &o->ff.raw, sizeof o->ff.raw);
    hash_bytes(&x, &solver, sizeof solver);
    hash_double(&x, tol);
    int depth = o->ff.mirror_depth > 0 ? o->ff.mirror_depth : s->settings.max_depth;
    hash_bytes(&x, &depth, sizeof depth);
    return x.h;
}

typedef struct cache_header {
    char magic[8];
    uint32_t version, pad;
    uint64_t key, n, nverts;
} cache_header;

static int write_all(FILE *f, const void *p, size_t n) { return fwrite(p, 1, n, f) == n; }

static rr_status cache_save(const char *path, uint64_t key, const rad_solution *sol, rr_error *err)
{
    rr_atomic a;
    rr_status st = rr_atomic_begin(&a, path, err);
    if (st != RR_OK)
        return st;
    cache_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, CACHE_MAGIC, 8);
    h.version = CACHE_VERSION;
    h.key = key;
    h.n = sol->P->n;
    h.nverts = sol->P->nverts;
    size_t n = sol->P->n, nv = sol->P->nverts;
    int ok = write_all(a.fp, &h, sizeof h) && write_all(a.fp, sol->B, n * sizeof *sol->B) &&
             write_all(a.fp, sol->emitted, n * sizeof *sol->emitted) &&
             write_all(a.fp, sol->first_shot, n * sizeof *sol->first_shot) &&
             write_all(a.fp, sol->vertex_B, nv * sizeof *sol->vertex_B) &&
             write_all(a.fp, sol->vertex_Hind, nv * sizeof *sol->vertex_Hind);
    if (!ok) {
        rr_atomic_abort(&a);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write the radiosity cache", path);
    }
    return rr_atomic_commit(&a, err);
}

static int read_all(FILE *f, void *p, size_t n) { return fread(p, 1, n, f) == n; }

/* Loads into a solution whose patches are already built. */
static rr_status cache_load(const char *path, uint64_t key, rad_solution *sol, rr_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return rr_error_set(err, RR_ERR_IO, "%s: cannot open the radiosity cache", path);
    cache_header h;
    rr_status st = RR_OK;
    if (!read_all(f, &h, sizeof h) || memcmp(h.magic, CACHE_MAGIC, 8) != 0 || h.version != CACHE_VERSION) {
        st = rr_error_set(err, RR_ERR_INVALID, "%s: not a radray radiosity cache (version %u)", path, CACHE_VERSION);
    } else if (h.key != key || h.n != sol->P->n || h.nverts != sol->P->nverts) {
        st = rr_error_set(err, RR_ERR_INVALID,
                          "%s: this radiosity cache was made for a different scene or different radiosity settings; "
                          "refusing it (delete it, or give another --radiosity-cache file)",
                          path);
    } else {
        size_t n = sol->P->n, nv = sol->P->nverts ? sol->P->nverts : 1;
        sol->B = malloc(n * sizeof *sol->B);
        sol->emitted = malloc(n * sizeof *sol->emitted);
        sol->first_shot = malloc(n * sizeof *sol->first_shot);
        sol->vertex_B = malloc(nv * sizeof *sol->vertex_B);
        sol->vertex_Hind = malloc(nv * sizeof *sol->vertex_Hind);
        if (!sol->B || !sol->emitted || !sol->first_shot || !sol->vertex_B || !sol->vertex_Hind)
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading the radiosity cache", path);
        else if (!read_all(f, sol->B, n * sizeof *sol->B) || !read_all(f, sol->emitted, n * sizeof *sol->emitted) ||
                 !read_all(f, sol->first_shot, n * sizeof *sol->first_shot) ||
                 !read_all(f, sol->vertex_B, sol->P->nverts * sizeof *sol->vertex_B) ||
                 !read_all(f, sol->vertex_Hind, sol->P->nverts * sizeof *sol->vertex_Hind) || fgetc(f) != EOF)
            st = rr_error_set(err, RR_ERR_PARSE, "%s: the radiosity cache is truncated or damaged", path);
    }
    fclose(f);
    return st;
}

rr_status rad_pass_run_cached(const scene *s, const rt_accel *a, const rad_pass_opts *o, const char *cache_path,
                              int *from_cache, rad_solution **out, rr_error *err)
{
    rad_pass_opts def;
    memset(&def, 0, sizeof def);
    def.use_scene_choices = 1;
    if (!o)
        o = &def;
    *from_cache = 0;
    if (!cache_path)
        return rad_pass_run(s, a, o, out, err);
    uint64_t key = cache_key(s, o);
    struct stat stt;
    if (stat(cache_path, &stt) != 0) {
        rr_status st = rad_pass_run(s, a, o, out, err);
        if (st != RR_OK)
            return st;
        st = cache_save(cache_path, key, *out, err);
        if (st != RR_OK) {
            rad_solution_destroy(*out);
            *out = NULL;
        }
        return st;
    }
    rad_solution *sol = calloc(1, sizeof *sol);
    if (sol)
        sol->scene = s;
    if (!sol)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory");
    rad_patch_opts po = rad_pass_patch_limits(s, o);
    po.accel = a;
    rr_status st = rad_patches_build(s, &po, &sol->P, err);
    if (st == RR_OK)
        st = cache_load(cache_path, key, sol, err);
    if (st != RR_OK) {
        rad_solution_destroy(sol);
        return st;
    }
    *from_cache = 1;
    *out = sol;
    return RR_OK;
}
