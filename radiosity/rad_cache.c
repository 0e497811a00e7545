/* rad_cache.c - saving a radiosity solution and using it again.
 *
 * Rendering several views of one room should not redo the radiosity pass. The
 * cache holds what the display and the hybrid read (per patch B, emission,
 * first shot; per vertex B and indirect irradiance), not the form factors.
 * Patches are rebuilt on load (cheap and deterministic) and must match; a
 * hierarchical solution's tree is stored as its split bits and built again
 * over its roots (rad_hier_internal.h).
 *
 * The file starts with a key: 64-bit FNV-1a hashes, one per part of what the
 * solution depends on (geometry, back-face culling, materials with their
 * mirror reflectances, lights, the resolved patch limits, the form-factor
 * method, samples and seed, render.max_depth, the solver settings). A cache
 * whose key differs was made for another scene or other settings and is
 * refused, naming the parts that differ; a payload whose checksum does not
 * match is damaged and refused. Scene and cache files must be regular files
 * (a FIFO would block the read). */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "rad_hier_internal.h"
#include "rad_pass_internal.h"

#define CACHE_MAGIC "RADRAYRC"
#define CACHE_VERSION 17u /* 2: mirrors in the key; 3: the key in named parts, culling, a payload checksum;
                            4: the method in the key, hierarchical trees (split bits); 5: the
                            hierarchical pass's fixes of 2026-12-02 (version 4's hierarchical
                            solutions of room-like scenes were up to 36 % dark); 6: buried parts
                            of patches, patch vertices split at creases (other vertex counts); 7:
                            the indirect irradiance's vertex values back-projected; 8: the
                            hierarchical pass's buried parts (leaf areas are open areas); 9: the
                            hierarchical pass's cluster shadow rays end on surfaces that face the
                            receiver (sphere lamps' floors were up to 12 % dark); 10: its normal
                            buckets and sphere shadow-ray ends (a sphere lamp in a closed box was
                            10 % dark); 11: its roots on curved surfaces at the patch limits
                            (other trees); 12: the hierarchical display's vertex values
                            back-projected; 13: the oracle's black receivers, near links into
                            receiving clusters kept, and objects that take in little refined
                            (2026-12-06); 14: solids' patches scaled to the true area (their
                            solutions were 3-5 % dark); 15: solids' mesh leaves as their own
                            triangles, the area scaled per leaf (other patches); 16: the
                            hierarchical tree the same for every seed, the estimate's rays by
                            power, and the hierarchical changes since 15 (2026-12-07); 17: the
                            estimate's far element links between flat surfaces exact, its rays
                            over finer strata */

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
/* hash_bytes as the primitive table's digest callback. */
static void digest_add(void *user, const void *bytes, size_t n) { hash_bytes(user, bytes, n); }
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

/* What the solution depends on, resolved the way rad_pass_run resolves it,
 * in named parts, so that a refused cache can say what changed. Audit
 * (tests/test_radiosity.c flips each input): every input rad_pass_run reads
 * is in one part; the thread count is not (the pass is the same for any). */
enum {
    K_GEOMETRY,
    K_CULLING,
    K_MATERIALS,
    K_LIGHTS,
    K_PATCHES,
    K_FORM_FACTORS,
    K_MIRROR_DEPTH,
    K_SOLVER,
    K_METHOD,
    K_COUNT
};
static const char *const k_key_names[K_COUNT] = {"geometry", "back-face culling", "materials", "lights",
                                                 "patch limits", "form-factor settings", "render.max_depth",
                                                 "solver settings", "radiosity method and its settings"};

static void hash_solids(hasher *x, const scene *s)
{
    /* Field by field (the structs have padding). */
    for (size_t i = 0; i < s->ncsg; i++) {
        const scene_csg_node *n = &s->csg[i];
        uint32_t w[7] = {(uint32_t)n->op, n->left,   n->right, (uint32_t)n->solid, n->material, n->object,
                         (uint32_t)n->shape};
        hash_bytes(x, w, sizeof w);
        for (int r = 0; r < 3; r++)
            hash_vec(x, rr_v3(n->to_world.m[r][0], n->to_world.m[r][1], n->to_world.m[r][2]));
        hash_vec(x, n->to_world.t);
        hash_vec(x, n->center);
        hash_double(x, n->radius);
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++)
                hash_double(x, n->q[r][c]);
        hash_vec(x, n->clip_lo);
        hash_vec(x, n->clip_hi);
        uint64_t tr[2] = {n->tri_first, n->tri_count};
        hash_bytes(x, tr, sizeof tr);
    }
    for (size_t i = 0; i < s->ncsg_verts; i++)
        hash_vec(x, s->csg_verts[i]);
    if (s->ncsg_tris)
        hash_bytes(x, s->csg_tris, s->ncsg_tris * sizeof *s->csg_tris);
}

static void cache_key(const scene *s, const rad_pass_opts *o, uint64_t key[K_COUNT])
{
    hasher x[K_COUNT];
    for (int k = 0; k < K_COUNT; k++) {
        x[k].h = 0xcbf29ce484222325ULL;
        hash_bytes(&x[k], k_key_names[k], strlen(k_key_names[k]));
    }
    hasher *g = &x[K_GEOMETRY];
    for (size_t i = 0; i < s->nverts; i++)
        hash_vec(g, s->verts[i]);
    for (size_t i = 0; i < s->ntris; i++)
        hash_bytes(g, &s->tris[i], sizeof s->tris[i]);
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_object *ob = &s->objects[i];
        hash_bytes(g, &ob->kind, sizeof ob->kind);
        hash_bytes(g, &ob->material, sizeof ob->material);
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)i);
        if (k != RT_PRIM_TRIANGLE)
            rt_prims[k].digest(s, (uint32_t)i, digest_add, g); /* a sphere's centre and radius */
        hash_bytes(g, &ob->csg_root, sizeof ob->csg_root);
        hash_bytes(&x[K_CULLING], &ob->cull_backfaces, sizeof ob->cull_backfaces);
    }
    hash_solids(g, s);
    for (size_t i = 0; i < s->nmaterials; i++) {
        hash_rgb(&x[K_MATERIALS], s->materials[i].diffuse);
        hash_rgb(&x[K_MATERIALS], s->materials[i].emission);
        hash_rgb(&x[K_MATERIALS], s->materials[i].mirror);
    }
    for (size_t i = 0; i < s->nlights; i++) {
        hash_bytes(&x[K_LIGHTS], &s->lights[i].type, sizeof s->lights[i].type);
        hash_vec(&x[K_LIGHTS], s->lights[i].direction);
        hash_vec(&x[K_LIGHTS], s->lights[i].position);
        hash_rgb(&x[K_LIGHTS], s->lights[i].intensity);
    }
    rad_patch_opts po = rad_pass_patch_limits(s, o);
    hash_double(&x[K_PATCHES], po.max_area);
    hash_double(&x[K_PATCHES], po.max_edge);
    int method = o->use_scene_choices ? (int)s->radiosity.form_factors : (int)o->ff.method;
    int samples = o->ff.samples > 0 ? o->ff.samples : s->radiosity.ff_samples;
    int solver = o->use_scene_choices ? (int)s->radiosity.solver : (int)o->solve.solver;
    double tol = o->solve.tolerance > 0 ? o->solve.tolerance : s->radiosity.tolerance;
    hash_bytes(&x[K_FORM_FACTORS], &method, sizeof method);
    hash_bytes(&x[K_FORM_FACTORS], &samples, sizeof samples);
    hash_bytes(&x[K_FORM_FACTORS], &o->ff.seed, sizeof o->ff.seed);
    hash_bytes(&x[K_FORM_FACTORS], &o->ff.raw, sizeof o->ff.raw);
    hash_bytes(&x[K_SOLVER], &solver, sizeof solver);
    hash_double(&x[K_SOLVER], tol);
    int depth = o->ff.mirror_depth > 0 ? o->ff.mirror_depth : s->settings.max_depth;
    hash_bytes(&x[K_MIRROR_DEPTH], &depth, sizeof depth);
    int hier = rad__pass_method(s, o, NULL) == RAD_METHOD_HIERARCHICAL;
    hash_bytes(&x[K_METHOD], &hier, sizeof hier);
    if (hier) {
        double rtol = o->hier.tolerance > 0 ? o->hier.tolerance : s->radiosity.refine_tolerance;
        double links = o->hier.max_links > 0 ? (double)o->hier.max_links : s->radiosity.max_links;
        hash_double(&x[K_METHOD], rtol);
        hash_double(&x[K_METHOD], rad__hier_min_area(s, o));
        hash_double(&x[K_METHOD], links);
        double rel = o->hier.relative > 0 ? o->hier.relative : s->radiosity.relative_tolerance;
        if (rel > 0) /* (off keeps the keys of the caches made before it existed) */
            hash_double(&x[K_METHOD], rel);
        if (s->radiosity.receiving_clusters != 0.0) /* (automatic, the default, keeps them too) */
            hash_double(&x[K_METHOD], 1e6 + s->radiosity.receiving_clusters);
    }
    for (int k = 0; k < K_COUNT; k++)
        key[k] = x[k].h;
}

typedef struct cache_header {
    char magic[8];
    uint32_t version, nkeys;
    uint64_t key[K_COUNT];
    uint64_t n, nverts;
    uint64_t nbits;    /* hierarchical: the tree's split bits (rad_hier_internal.h); 0 for flat patches */
    uint64_t checksum; /* FNV-1a of the payload, in order */
} cache_header;

/* The payload: the split bits (hierarchical), then per patch B, emission,
 * first shot; per vertex B and indirect irradiance. */
#define PAYLOAD_PARTS 6
typedef struct payload {
    void *p[PAYLOAD_PARTS];
    size_t n[PAYLOAD_PARTS];
} payload;

static payload payload_of(const rad_solution *sol, const rad_split_bits *bits)
{
    size_t n = sol->P->n, nv = sol->P->nverts;
    payload d = {{bits->bit, sol->B, sol->emitted, sol->first_shot, sol->vertex_B, sol->vertex_Hind},
                 {bits->n, n * sizeof(rr_rgb), n * sizeof(rr_rgb), n * sizeof(rr_rgb), nv * sizeof(rr_rgb),
                  nv * sizeof(rr_rgb)}};
    return d;
}

static uint64_t payload_checksum(const payload *d)
{
    hasher x = {0xcbf29ce484222325ULL};
    for (int i = 0; i < PAYLOAD_PARTS; i++)
        hash_bytes(&x, d->p[i], d->n[i]);
    return x.h;
}

static int write_all(FILE *f, const void *p, size_t n) { return n == 0 || fwrite(p, 1, n, f) == n; }

static rr_status cache_save(const char *path, const uint64_t *key, const rad_solution *sol, rr_error *err)
{
    rr_atomic a;
    rr_status st = rr_atomic_begin(&a, path, err);
    if (st != RR_OK)
        return st;
    cache_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, CACHE_MAGIC, 8);
    h.version = CACHE_VERSION;
    h.nkeys = K_COUNT;
    memcpy(h.key, key, sizeof h.key);
    h.n = sol->P->n;
    h.nverts = sol->P->nverts;
    rad_split_bits bits = {NULL, 0};
    if (sol->P->roots && rad__hier_bits(sol->P, &bits) != 0) {
        rr_atomic_abort(&a);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory writing the radiosity cache", path);
    }
    h.nbits = bits.n;
    payload d = payload_of(sol, &bits);
    h.checksum = payload_checksum(&d);
    int ok = write_all(a.fp, &h, sizeof h);
    for (int i = 0; i < PAYLOAD_PARTS && ok; i++)
        ok = write_all(a.fp, d.p[i], d.n[i]);
    free(bits.bit);
    if (!ok) {
        rr_atomic_abort(&a);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write the radiosity cache", path);
    }
    return rr_atomic_commit(&a, err);
}

static int read_all(FILE *f, void *p, size_t n) { return n == 0 || fread(p, 1, n, f) == n; }

/* "geometry, lights" for the parts of the key that differ. */
static void changed_parts(const uint64_t *a, const uint64_t *b, char *out, size_t n)
{
    size_t len = 0;
    out[0] = '\0';
    for (int k = 0; k < K_COUNT && len < n; k++)
        if (a[k] != b[k])
            len += (size_t)snprintf(out + len, n - len, "%s%s", len ? ", " : "", k_key_names[k]);
}

/* Loads into sol: the patches are built here (for a hierarchical solution,
 * its roots, then the tree from the file's split bits), and must match. */
static rr_status cache_load(const char *path, const uint64_t *key, const scene *s, const rt_accel *a,
                            const rad_pass_opts *o, int hier, rad_solution *sol, rr_error *err)
{
    rr_status st = RR_OK;
    rr_error why;
    if (rr_file_check_regular(path, &why) != RR_OK) /* bad input, as a wrong cache is */
        return rr_error_set(err, RR_ERR_INVALID, "%s (--radiosity-cache)", why.msg);
    FILE *f = fopen(path, "rb");
    if (!f)
        return rr_error_set(err, RR_ERR_IO, "%s: cannot open the radiosity cache", path);
    cache_header h;
    char what[256];
    rad_split_bits bits = {NULL, 0};
    if (!read_all(f, &h, sizeof h) || memcmp(h.magic, CACHE_MAGIC, 8) != 0 || h.version != CACHE_VERSION ||
        h.nkeys != K_COUNT) {
        st = rr_error_set(err, RR_ERR_INVALID, "%s: not a radray radiosity cache (version %u)", path, CACHE_VERSION);
    } else if (memcmp(h.key, key, sizeof h.key) != 0) {
        changed_parts(h.key, key, what, sizeof what);
        st = rr_error_set(err, RR_ERR_INVALID,
                          "%s: this radiosity cache was made with different %s; refusing it (delete it, or give "
                          "another --radiosity-cache file)",
                          path, what);
    } else if (hier != (h.nbits > 0) || h.nbits > (uint64_t)1 << 40) {
        st = rr_error_set(err, RR_ERR_INVALID, "%s: the radiosity cache is damaged (its element tree); delete it", path);
    } else if (hier && !(bits.bit = malloc((size_t)h.nbits))) {
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading the radiosity cache", path);
    } else {
        bits.n = (size_t)h.nbits;
        if (hier && !read_all(f, bits.bit, bits.n))
            st = rr_error_set(err, RR_ERR_INVALID, "%s: the radiosity cache is truncated or damaged", path);
        rad_patch_opts po = hier ? rad__hier_root_limits(s, o) : rad_pass_patch_limits(s, o);
        po.accel = a;
        rad_patches *roots = NULL;
        if (st == RR_OK)
            st = rad_patches_build(s, &po, hier ? &roots : &sol->P, err);
        if (st == RR_OK && hier && (st = rad__hier_leaves(roots, &bits, &sol->P, err)) != RR_OK)
            rr_error_prefix(err, "%s: the radiosity cache does not fit the scene", path);
    }
    if (st == RR_OK && (h.n != sol->P->n || h.nverts != sol->P->nverts))
        st = rr_error_set(err, RR_ERR_INVALID,
                          "%s: this radiosity cache was made with different patches; refusing it (delete it, or give "
                          "another --radiosity-cache file)",
                          path);
    if (st == RR_OK) {
        int ok = rad__solution_arrays(sol) == 0;
        payload d = payload_of(sol, &bits);
        if (!ok)
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading the radiosity cache", path);
        for (int i = 1; i < PAYLOAD_PARTS && ok; i++)
            ok = read_all(f, d.p[i], d.n[i]);
        if (st == RR_OK && (!ok || fgetc(f) != EOF))
            st = rr_error_set(err, RR_ERR_INVALID, "%s: the radiosity cache is truncated or damaged", path);
        else if (st == RR_OK && payload_checksum(&d) != h.checksum)
            st = rr_error_set(err, RR_ERR_INVALID,
                              "%s: the radiosity cache is damaged (its checksum does not match its data); delete it",
                              path);
    }
    free(bits.bit);
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
    uint64_t key[K_COUNT];
    cache_key(s, o, key);
    struct stat stt;
    if (stat(cache_path, &stt) != 0) {
        rr_status st = rad_pass_run(s, a, o, out, err);
        if (st != RR_OK)
            return st;
        /* Several ranks hold the same solution: rank 0 writes it. */
        if (o->ff.dist && o->ff.dist->rank != 0)
            return RR_OK;
        if ((*out)->memory_bound) {
            rr_warn(&o->warn, "%s: radiosity: not cached in %s, as --max-memory made it coarser than its settings ask",
                    s->path, cache_path);
            return RR_OK;
        }
        st = cache_save(cache_path, key, *out, err);
        if (st != RR_OK) {
            rad_solution_destroy(*out);
            *out = NULL;
        }
        return st;
    }
    rad_solution *sol = rad__solution_new(s);
    if (!sol)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory");
    int hier = rad__pass_method(s, o, NULL) == RAD_METHOD_HIERARCHICAL;
    rr_status st = cache_load(cache_path, key, s, a, o, hier, sol, err);
    if (st != RR_OK) {
        rad_solution_destroy(sol);
        return st;
    }
    *from_cache = 1;
    *out = sol;
    return RR_OK;
}
