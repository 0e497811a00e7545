/* scene_objects.c - "objects": shapes, transforms and their triangles.
 *
 * Every triangle-based shape goes through the same pipeline: build the
 * object's own vertex and index arrays, apply the transform (points by the
 * affine map, normals by the inverse transpose, winding reversed when the map
 * mirrors), analyse the topology, then append the non-degenerate triangles to
 * the scene. Spheres stay analytic. Transforms are parsed in scene_xform.c;
 * solids ("quadric", "csg") are built in scene_csg.c, whose mesh leaves load
 * through the same mesh path (sp_load_mesh); "model" objects in
 * scene_model.c, whose meshes join through sp_add_mesh_object.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "scene_internal.h"

#define K_COMMON "type", "name", "material", "transform", "cull"
static const char *const k_mesh[] = {K_COMMON, "file", "flip", NULL};
static const char *const k_triangles[] = {K_COMMON, "vertices", "indices", "flip", NULL};
static const char *const k_quad[] = {K_COMMON, "vertices", "flip", NULL};
static const char *const k_box[] = {K_COMMON, "min", "max", "flip", NULL};
static const char *const k_sphere[] = {K_COMMON, "center", "radius", NULL};

typedef struct obj_type {
    const char *name;
    scene_object_kind kind;
    const char *const *keys;
} obj_type;

/* Solids (keys NULL) check their keys in scene_csg.c: a quadric's keys
 * depend on its shape. */
static const obj_type k_types[] = {
    {"mesh", SCENE_OBJ_MESH, k_mesh},       {"triangles", SCENE_OBJ_TRIANGLES, k_triangles},
    {"quad", SCENE_OBJ_QUAD, k_quad},       {"box", SCENE_OBJ_BOX, k_box},
    {"sphere", SCENE_OBJ_SPHERE, k_sphere}, {"quadric", SCENE_OBJ_CSG, NULL},
    {"csg", SCENE_OBJ_CSG, NULL},           {"model", SCENE_OBJ_MESH, NULL},
};
#define N_TYPES (sizeof k_types / sizeof k_types[0])
#define TYPE_LIST "mesh, triangles, quad, box, sphere, quadric, csg, model"

/* A triangle is dropped as zero-area when twice its area is below 1e-12 of
 * its longest edge squared: repeated or collinear vertices, up to the
 * rounding a transform adds. Such a triangle has no usable normal. */
int sp_tri_degenerate(rr_vec3 a, rr_vec3 b, rr_vec3 c)
{
    rr_vec3 e0 = rr_v3_sub(b, a), e1 = rr_v3_sub(c, a), e2 = rr_v3_sub(c, b);
    double cr = rr_v3_len(rr_v3_cross(e0, e1));
    double l2 = fmax(rr_v3_len2(e0), fmax(rr_v3_len2(e1), rr_v3_len2(e2)));
    return !(cr > 1e-12 * l2);
}

/* ---- growing the scene's arrays ---- */

static rr_status reserve(const sp_ctx *c, scene *s, sp_build *b, size_t add_verts, size_t add_tris,
                         int need_normals, const char *opath)
{
    if (add_verts > UINT32_MAX - s->nverts || add_tris > UINT32_MAX - s->ntris)
        return sp_fail(c, RR_ERR_LIMIT, opath, "the scene would exceed %u vertices or triangles",
                       (unsigned)UINT32_MAX);
    size_t nv = s->nverts + add_verts, nt = s->ntris + add_tris;
    if (nv > b->cap_verts) {
        size_t cap = b->cap_verts ? b->cap_verts : 64;
        while (cap < nv)
            cap *= 2;
        if (cap > SIZE_MAX / sizeof(rr_vec3))
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu vertices", nv);
        rr_vec3 *v = realloc(s->verts, cap * sizeof *v);
        if (!v)
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu vertices", nv);
        s->verts = v;
        if (s->normals) {
            rr_vec3 *n = realloc(s->normals, cap * sizeof *n);
            if (!n)
                return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu normals", nv);
            s->normals = n;
        }
        b->cap_verts = cap;
    }
    /* Normals exist only once some object brings them; the vertices before
     * that get the zero vector ("no normal"). */
    if (need_normals && !s->normals) {
        s->normals = calloc(b->cap_verts, sizeof *s->normals);
        if (!s->normals)
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu normals", nv);
    }
    if (nt > b->cap_tris) {
        size_t cap = b->cap_tris ? b->cap_tris : 64;
        while (cap < nt)
            cap *= 2;
        if (cap > SIZE_MAX / sizeof(scene_tri))
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu triangles", nt);
        scene_tri *t = realloc(s->tris, cap * sizeof *t);
        if (!t)
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu triangles", nt);
        s->tris = t;
        b->cap_tris = cap;
    }
    return RR_OK;
}

/* ---- the shapes' own arrays ---- */

/* An object's triangles before they join the scene: either views into a
 * loaded mesh (loaded != NULL, freed with mesh_destroy) or malloc'd arrays. */
typedef struct obj_geom {
    mesh_tri m;
    mesh_tri *loaded;
} obj_geom;

static void geom_free(obj_geom *g)
{
    if (g->loaded) {
        mesh_destroy(g->loaded);
    } else {
        free(g->m.pos);
        free(g->m.normals);
        free(g->m.tris);
    }
    memset(g, 0, sizeof *g);
}

static rr_status geom_alloc(const sp_ctx *c, obj_geom *g, size_t nverts, size_t ntris, const char *opath)
{
    g->m.nverts = nverts;
    g->m.ntris = ntris;
    g->m.pos = malloc(3 * nverts * sizeof *g->m.pos);
    g->m.tris = malloc(3 * ntris * sizeof *g->m.tris);
    if (!g->m.pos || !g->m.tris)
        return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory");
    return RR_OK;
}

static void geom_set(obj_geom *g, size_t i, rr_vec3 p)
{
    g->m.pos[3 * i] = p.x, g->m.pos[3 * i + 1] = p.y, g->m.pos[3 * i + 2] = p.z;
}
static rr_vec3 geom_get(const double *a, size_t i) { return rr_v3(a[3 * i], a[3 * i + 1], a[3 * i + 2]); }

/* Reads an array of points [[x, y, z], ...] into g's positions. n = 0: any
 * number >= 1; otherwise exactly n. */
static rr_status read_points(const sp_ctx *c, const cJSON *obj, const char *opath, int n, obj_geom *g,
                             size_t ntris)
{
    const cJSON *v = sp_get(obj, "vertices");
    const char *expected = n == 4 ? "an array of 4 points [x, y, z]" : "an array of points [x, y, z]";
    if (!v)
        return sp_missing(c, opath, "vertices", expected);
    char p[SP_PATH_MAX];
    sp_key(p, opath, "vertices");
    rr_status st = sp_array(c, v, p, n, expected);
    if (st != RR_OK)
        return st;
    if ((st = geom_alloc(c, g, (size_t)cJSON_GetArraySize(v), ntris, opath)) != RR_OK)
        return st;
    size_t i = 0;
    for (const cJSON *it = v->child; it; it = it->next, i++) {
        char pi[SP_PATH_MAX];
        sp_idx(pi, p, i);
        rr_vec3 q;
        if ((st = sp_vec3_item(c, it, pi, &q)) != RR_OK)
            return st;
        geom_set(g, i, q);
    }
    return RR_OK;
}

static rr_status build_triangles(const sp_ctx *c, const cJSON *obj, const char *opath, obj_geom *g)
{
    const cJSON *idx = sp_get(obj, "indices");
    const char *expected = "an array of triangles [i, j, k] (0-based vertex indices)";
    if (!idx)
        return sp_missing(c, opath, "indices", expected);
    char p[SP_PATH_MAX];
    sp_key(p, opath, "indices");
    rr_status st = sp_array(c, idx, p, 0, expected);
    if (st != RR_OK)
        return st;
    if ((st = read_points(c, obj, opath, 0, g, (size_t)cJSON_GetArraySize(idx))) != RR_OK)
        return st;
    size_t t = 0;
    for (const cJSON *tri = idx->child; tri; tri = tri->next, t++) {
        char pt[SP_PATH_MAX];
        sp_idx(pt, p, t);
        if ((st = sp_array(c, tri, pt, 3, "a triangle [i, j, k] of 3 vertex indices")) != RR_OK)
            return st;
        for (int k = 0; k < 3; k++) {
            char pk[SP_PATH_MAX];
            sp_idx(pk, pt, (size_t)k);
            const cJSON *e = cJSON_GetArrayItem(tri, k);
            double d;
            if ((st = sp_int_item(c, e, pk, -9007199254740992.0, 9007199254740992.0, &d)) != RR_OK)
                return st;
            if (d < 0 || d >= (double)g->m.nverts)
                return sp_fail(c, RR_ERR_INVALID, pk,
                               "vertex index %.0f is out of range (the object has %zu vertices, 0..%zu)", d,
                               g->m.nverts, g->m.nverts - 1);
            g->m.tris[3 * t + (size_t)k] = (uint32_t)d;
        }
    }
    return RR_OK;
}

static rr_status build_quad(const sp_ctx *c, const cJSON *obj, const char *opath, obj_geom *g)
{
    rr_status st = read_points(c, obj, opath, 4, g, 2);
    if (st != RR_OK)
        return st;
    static const uint32_t q[6] = {0, 1, 2, 0, 2, 3};
    memcpy(g->m.tris, q, sizeof q);
    return RR_OK;
}

static rr_status build_box(const sp_ctx *c, const cJSON *obj, const char *opath, obj_geom *g)
{
    rr_vec3 lo, hi;
    rr_status st;
    if ((st = sp_vec3(c, obj, opath, "min", SP_REQUIRED, &lo)) != RR_OK ||
        (st = sp_vec3(c, obj, opath, "max", SP_REQUIRED, &hi)) != RR_OK)
        return st;
    if (!(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z)) {
        char p[SP_PATH_MAX];
        sp_key(p, opath, "max");
        return sp_fail(c, RR_ERR_INVALID, p,
                       "must be greater than min on every axis (min [%g, %g, %g], max [%g, %g, %g])",
                       lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
    }
    if ((st = geom_alloc(c, g, 8, 12, opath)) != RR_OK)
        return st;
    /* Corner i has x from bit 0, y from bit 1, z from bit 2 (0 = min, 1 = max).
     * Each face is two counter-clockwise triangles seen from outside. */
    for (size_t i = 0; i < 8; i++)
        geom_set(g, i, rr_v3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z));
    static const uint32_t faces[6][4] = {
        {0, 4, 6, 2}, /* -x */
        {1, 3, 7, 5}, /* +x */
        {0, 1, 5, 4}, /* -y */
        {2, 6, 7, 3}, /* +y */
        {0, 2, 3, 1}, /* -z */
        {4, 5, 7, 6}, /* +z */
    };
    for (size_t f = 0; f < 6; f++) {
        const uint32_t *q = faces[f];
        uint32_t *t = g->m.tris + 6 * f;
        t[0] = q[0], t[1] = q[1], t[2] = q[2];
        t[3] = q[0], t[4] = q[2], t[5] = q[3];
    }
    return RR_OK;
}

/* source (4096 bytes) receives the resolved path. */
static rr_status build_mesh(const sp_ctx *c, const cJSON *obj, const char *opath, char *source, obj_geom *g)
{
    char file[4096] = "", p[SP_PATH_MAX];
    rr_status st = sp_string(c, obj, opath, "file", SP_REQUIRED, 1, file, sizeof file);
    if (st != RR_OK)
        return st;
    sp_key(p, opath, "file");
    if ((st = rr_path_join(c->base_dir, file, source, 4096, c->err)) != RR_OK)
        return rr_error_prefix(c->err, "%s: %s", c->file, p);
    mesh_tri *m = NULL;
    if ((st = mesh_load(source, &m, c->err)) != RR_OK)
        return rr_error_prefix(c->err, "%s: %s", c->file, p);
    g->loaded = m;
    g->m = *m;
    if (m->ntris == 0)
        return sp_fail(c, RR_ERR_INVALID, p, "%s has no triangles", source);
    /* mesh_load promises valid indices; a broken promise must not become an
     * out-of-bounds read in the renderer. */
    for (size_t i = 0; i < 3 * m->ntris; i++)
        if (m->tris[i] >= m->nverts)
            return sp_fail(c, RR_ERR_INTERNAL, p, "%s: triangle %zu refers to vertex %u of %zu", source, i / 3,
                           (unsigned)m->tris[i], m->nverts);
    return RR_OK;
}

/* ---- one object ---- */

rr_status sp_find_material(const sp_ctx *c, const cJSON *obj, const char *opath, const scene *s, uint32_t *out)
{
    char name[SCENE_NAME_MAX + 1] = "", p[SP_PATH_MAX];
    const cJSON *v = sp_get(obj, "material");
    if (!v)
        return sp_missing(c, opath, "material", "the name of a material");
    sp_key(p, opath, "material");
    if (cJSON_IsString(v)) {
        for (size_t i = 0; i < s->nmaterials; i++)
            if (strcmp(s->materials[i].name, v->valuestring) == 0) {
                *out = (uint32_t)i;
                return RR_OK;
            }
        char known[512] = "";
        size_t len = 0;
        for (size_t i = 0; i < s->nmaterials && len < sizeof known; i++)
            len += (size_t)snprintf(known + len, sizeof known - len, "%s%s", i ? ", " : "", s->materials[i].name);
        snprintf(name, sizeof name, "%s", v->valuestring);
        if (s->nmaterials == 0)
            return sp_fail(c, RR_ERR_INVALID, p, "unknown material '%s' (the scene has no \"materials\")", name);
        return sp_fail(c, RR_ERR_INVALID, p, "unknown material '%s' (known: %s)", name, known);
    }
    char got[96];
    return sp_fail(c, RR_ERR_INVALID, p, "expected the name of a material (got %s)", sp_describe(v, got, sizeof got));
}

/* -1 auto, 0 off, 1 on. */
rr_status sp_parse_cull(const sp_ctx *c, const cJSON *obj, const char *opath, int *cull)
{
    const cJSON *v = sp_get(obj, "cull");
    *cull = -1;
    if (!v || (cJSON_IsString(v) && strcmp(v->valuestring, "auto") == 0))
        return RR_OK;
    if (cJSON_IsBool(v)) {
        *cull = cJSON_IsTrue(v) ? 1 : 0;
        return RR_OK;
    }
    char p[SP_PATH_MAX], got[96];
    sp_key(p, opath, "cull");
    return sp_fail(c, RR_ERR_INVALID, p, "expected true, false or \"auto\" (got %s)", sp_describe(v, got, sizeof got));
}

static rr_status build_sphere(const sp_ctx *c, const cJSON *obj, const char *opath, const rr_xform *x, int has_x,
                              scene_object *o)
{
    rr_status st;
    double r = 0;
    if ((st = sp_vec3(c, obj, opath, "center", SP_REQUIRED, &o->center)) != RR_OK ||
        (st = sp_number(c, obj, opath, "radius", SP_REQUIRED, &r)) != RR_OK)
        return st;
    if (!(r > 0)) {
        char p[SP_PATH_MAX];
        sp_key(p, opath, "radius");
        return sp_fail(c, RR_ERR_INVALID, p, "must be > 0 (got %g)", r);
    }
    if (has_x) {
        /* A sphere stays a sphere only under a similarity: M^T M = s^2 I. */
        rr_vec3 col[3];
        for (int j = 0; j < 3; j++)
            col[j] = rr_v3(x->m[0][j], x->m[1][j], x->m[2][j]);
        double s2 = (rr_v3_len2(col[0]) + rr_v3_len2(col[1]) + rr_v3_len2(col[2])) / 3.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                if (fabs(rr_v3_dot(col[i], col[j]) - (i == j ? s2 : 0.0)) > 1e-9 * s2) {
                    char p[SP_PATH_MAX];
                    sp_key(p, opath, "transform");
                    return sp_fail(c, RR_ERR_INVALID, p,
                                   "a sphere takes only rotations, translations and uniform scales; non-uniform "
                                   "scale (or shear) of a sphere needs the quadric type (\"type\": \"quadric\", "
                                   "\"shape\": \"ellipsoid\") or a sphere inside a csg");
                }
        o->center = rr_xform_point(x, o->center);
        r *= sqrt(s2);
        if (!rr_v3_isfinite(o->center) || !isfinite(r))
            return sp_fail(c, RR_ERR_INVALID, opath, "the transformed sphere is not finite");
    }
    o->radius = r;
    o->tri_first = o->tri_count = 0;
    return RR_OK;
}

/* Transforms g in place: points by x, normals by its inverse transpose,
 * winding reversed when the map mirrors (negative determinant) XOR flip, and
 * the file's normals negated when flip is set. */
static rr_status transform_geom(const sp_ctx *c, const char *opath, const rr_xform *x, int has_x, int flip,
                                obj_geom *g)
{
    mesh_tri *m = &g->m;
    int mirrored = flip;
    if (has_x) {
        double det = rr_xform_det(x);
        const double(*a)[3] = x->m;
        /* Normals go by the inverse transpose, cof(M) / det(M): the sign of
         * det keeps them pointing the way the (possibly re-wound) faces do. */
        double cof[3][3] = {{a[1][1] * a[2][2] - a[1][2] * a[2][1], a[1][2] * a[2][0] - a[1][0] * a[2][2],
                             a[1][0] * a[2][1] - a[1][1] * a[2][0]},
                            {a[0][2] * a[2][1] - a[0][1] * a[2][2], a[0][0] * a[2][2] - a[0][2] * a[2][0],
                             a[0][1] * a[2][0] - a[0][0] * a[2][1]},
                            {a[0][1] * a[1][2] - a[0][2] * a[1][1], a[0][2] * a[1][0] - a[0][0] * a[1][2],
                             a[0][0] * a[1][1] - a[0][1] * a[1][0]}};
        double sg = det < 0 ? -1.0 : 1.0;
        for (size_t i = 0; i < m->nverts; i++) {
            geom_set(g, i, rr_xform_point(x, geom_get(m->pos, i)));
            if (m->normals) {
                rr_vec3 n = geom_get(m->normals, i);
                rr_vec3 t = rr_v3(cof[0][0] * n.x + cof[0][1] * n.y + cof[0][2] * n.z,
                                  cof[1][0] * n.x + cof[1][1] * n.y + cof[1][2] * n.z,
                                  cof[2][0] * n.x + cof[2][1] * n.y + cof[2][2] * n.z);
                t = rr_v3_norm(rr_v3_scale(t, sg));
                m->normals[3 * i] = t.x, m->normals[3 * i + 1] = t.y, m->normals[3 * i + 2] = t.z;
            }
        }
        /* A mirroring map turns counter-clockwise into clockwise; swapping two
         * indices restores "counter-clockwise = front". */
        if (det < 0)
            mirrored = !mirrored;
    }
    for (size_t i = 0; i < m->nverts; i++)
        if (!rr_v3_isfinite(geom_get(m->pos, i)))
            return sp_fail(c, RR_ERR_INVALID, opath, "vertex %zu is not finite%s", i,
                           has_x ? " after the transform" : "");
    if (flip && m->normals)
        for (size_t i = 0; i < 3 * m->nverts; i++)
            m->normals[i] = -m->normals[i];
    if (mirrored)
        for (size_t t = 0; t < m->ntris; t++) {
            uint32_t tmp = m->tris[3 * t + 1];
            m->tris[3 * t + 1] = m->tris[3 * t + 2];
            m->tris[3 * t + 2] = tmp;
        }
    return RR_OK;
}

rr_status sp_load_mesh(const sp_ctx *c, const cJSON *obj, const char *opath, const rr_xform *x, int has_x, int flip,
                       char *source, mesh_tri **out)
{
    obj_geom g;
    memset(&g, 0, sizeof g);
    rr_status st = build_mesh(c, obj, opath, source, &g);
    if (st == RR_OK)
        st = transform_geom(c, opath, x, has_x, flip, &g);
    if (st != RR_OK) {
        geom_free(&g);
        return st;
    }
    *out = g.loaded;
    return RR_OK;
}

/* Transforms g in place, analyses it and appends its non-degenerate triangles
 * to the scene. */
static rr_status finish_triangles(const sp_ctx *c, scene *s, sp_build *b, size_t oi, const char *opath,
                                  const rr_xform *x, int has_x, int flip, obj_geom *g)
{
    scene_object *o = &s->objects[oi];
    mesh_tri *m = &g->m;
    rr_status st = transform_geom(c, opath, x, has_x, flip, g);
    if (st != RR_OK)
        return st;

    /* The report describes the object as written (degenerate triangles
     * included): a zero-area sliver that closes a seam still closes it. */
    st = mesh_analyze(m, &o->report, c->err);
    if (st != RR_OK)
        return rr_error_prefix(c->err, "%s: %s", c->file, opath);

    size_t keep = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *v = m->tris + 3 * t;
        if (!sp_tri_degenerate(geom_get(m->pos, v[0]), geom_get(m->pos, v[1]), geom_get(m->pos, v[2])))
            keep++;
    }
    o->dropped_degenerate = m->ntris - keep;
    if (keep == 0)
        return sp_fail(c, RR_ERR_INVALID, opath, "every triangle has zero area (%zu dropped); the object is empty",
                       m->ntris);
    if (o->dropped_degenerate)
        rr_warn(c->opts ? &c->opts->warn : NULL, "%s: %s: dropped %zu zero-area triangle%s", c->file, opath,
                o->dropped_degenerate, o->dropped_degenerate == 1 ? "" : "s");

    if ((st = reserve(c, s, b, m->nverts, keep, m->normals != NULL, opath)) != RR_OK)
        return st;
    size_t base = s->nverts;
    for (size_t i = 0; i < m->nverts; i++) {
        s->verts[base + i] = geom_get(m->pos, i);
        if (s->normals) {
            /* A normal that is not finite is no normal: the zero vector. */
            rr_vec3 n = m->normals ? geom_get(m->normals, i) : rr_v3(0, 0, 0);
            s->normals[base + i] = rr_v3_isfinite(n) ? n : rr_v3(0, 0, 0);
        }
    }
    s->nverts += m->nverts;
    o->tri_first = s->ntris;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *v = m->tris + 3 * t;
        if (sp_tri_degenerate(geom_get(m->pos, v[0]), geom_get(m->pos, v[1]), geom_get(m->pos, v[2])))
            continue;
        scene_tri *st_ = &s->tris[s->ntris++];
        st_->v[0] = (uint32_t)(base + v[0]);
        st_->v[1] = (uint32_t)(base + v[1]);
        st_->v[2] = (uint32_t)(base + v[2]);
        st_->object = (uint32_t)oi;
        st_->material = o->material;
    }
    o->tri_count = keep;
    return RR_OK;
}

rr_status sp_add_mesh_object(const sp_ctx *c, scene *s, sp_build *b, size_t oi, const char *opath,
                             const rr_xform *x, int has_x, mesh_tri *m)
{
    obj_geom g;
    memset(&g, 0, sizeof g);
    g.m = *m; /* a view: transformed in place */
    return finish_triangles(c, s, b, oi, opath, x, has_x, 0, &g);
}

int sp_cull_auto(const scene *s, size_t oi, size_t first_node)
{
    const scene_object *o = &s->objects[oi];
    int closed = scene_object_closed(s, (uint32_t)oi);
    int mirror = rr_rgb_max(s->materials[o->material].mirror) > 0.0;
    /* A solid is closed by construction; its leaves may bring their own
     * materials, and a mirror on any of them is a mirror path. */
    if (o->kind == SCENE_OBJ_CSG) {
        for (size_t i = first_node; i < s->ncsg; i++)
            if (s->csg[i].op == SCENE_CSG_LEAF && rr_rgb_max(s->materials[s->csg[i].material].mirror) > 0.0)
                mirror = 1;
    }
    return closed && !mirror;
}

rr_status sp_new_object(const sp_ctx *c, scene *s, sp_build *b, const char *opath, size_t *oi)
{
    if (s->nobjects == b->cap_objects) {
        size_t cap = b->cap_objects ? 2 * b->cap_objects : 16;
        if (cap > UINT32_MAX)
            return sp_fail(c, RR_ERR_LIMIT, opath, "the scene would exceed %u objects", (unsigned)UINT32_MAX);
        scene_object *o = realloc(s->objects, cap * sizeof *o);
        if (!o)
            return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu objects", cap);
        s->objects = o;
        b->cap_objects = cap;
    }
    *oi = s->nobjects++;
    memset(&s->objects[*oi], 0, sizeof s->objects[*oi]);
    s->objects[*oi].model = SCENE_NONE;
    return RR_OK;
}

static rr_status parse_object(const sp_ctx *c, const cJSON *obj, size_t ji, scene *s, sp_build *b)
{
    char opath[SP_PATH_MAX], got[96];
    sp_idx(opath, "objects", ji);
    if (!cJSON_IsObject(obj))
        return sp_fail(c, RR_ERR_INVALID, opath, "expected an object (got %s)", sp_describe(obj, got, sizeof got));
    const cJSON *type = sp_get(obj, "type");
    char tpath[SP_PATH_MAX];
    sp_key(tpath, opath, "type");
    if (!type)
        return sp_missing(c, opath, "type", "one of " TYPE_LIST);
    if (!cJSON_IsString(type))
        return sp_fail(c, RR_ERR_INVALID, tpath, "expected one of " TYPE_LIST " (got %s)",
                       sp_describe(type, got, sizeof got));
    const obj_type *ty = NULL;
    for (size_t i = 0; i < N_TYPES; i++)
        if (strcmp(type->valuestring, k_types[i].name) == 0)
            ty = &k_types[i];
    if (!ty)
        return sp_fail(c, RR_ERR_INVALID, tpath, "unknown type '%.64s' (known: " TYPE_LIST ")", type->valuestring);
    if (strcmp(ty->name, "model") == 0)
        return sp_parse_model(c, obj, opath, ji, s, b);
    rr_status st = ty->keys ? sp_check_object(c, obj, opath, ty->keys) : sp_solid_check_keys(c, obj, opath, 1);
    size_t oi;
    if (st != RR_OK || (st = sp_new_object(c, s, b, opath, &oi)) != RR_OK)
        return st;

    scene_object *o = &s->objects[oi];
    o->kind = ty->kind;
    snprintf(o->name, sizeof o->name, "objects[%zu]", ji);
    int cull, has_x, flip = 0;
    rr_xform x;
    if ((st = sp_string(c, obj, opath, "name", SP_OPTIONAL, 1, o->name, sizeof o->name)) != RR_OK ||
        (st = sp_find_material(c, obj, opath, s, &o->material)) != RR_OK ||
        (st = sp_parse_cull(c, obj, opath, &cull)) != RR_OK ||
        (st = sp_parse_transform(c, obj, opath, &x, &has_x)) != RR_OK)
        return st;

    size_t first_node = s->ncsg;
    if (ty->kind == SCENE_OBJ_SPHERE) {
        st = build_sphere(c, obj, opath, &x, has_x, o);
    } else if (ty->kind == SCENE_OBJ_CSG) {
        st = sp_parse_solid(c, obj, opath, oi, &x, s, b);
    } else {
        obj_geom g;
        memset(&g, 0, sizeof g);
        /* "flip": true turns any triangle object inside out (a room built from a box, seen from inside). */
        st = sp_bool(c, obj, opath, "flip", SP_OPTIONAL, &flip);
        if (st == RR_OK) {
            switch (ty->kind) {
            case SCENE_OBJ_MESH: st = build_mesh(c, obj, opath, o->source, &g); break;
            case SCENE_OBJ_TRIANGLES: st = build_triangles(c, obj, opath, &g); break;
            case SCENE_OBJ_QUAD: st = build_quad(c, obj, opath, &g); break;
            default: st = build_box(c, obj, opath, &g); break;
            }
        }
        if (st == RR_OK)
            st = finish_triangles(c, s, b, oi, opath, &x, has_x, flip, &g);
        geom_free(&g);
    }
    if (st != RR_OK)
        return st;

    o->cull_backfaces = cull < 0 ? sp_cull_auto(s, oi, first_node) : cull;
    return RR_OK;
}

int scene_object_closed(const scene *s, uint32_t obj)
{
    const scene_object *o = &s->objects[obj];
    if (o->kind == SCENE_OBJ_BOX || o->kind == SCENE_OBJ_SPHERE || o->kind == SCENE_OBJ_CSG)
        return 1;
    return (o->kind == SCENE_OBJ_MESH || o->kind == SCENE_OBJ_TRIANGLES) && o->report.watertight &&
           o->report.consistently_oriented;
}

rr_status sp_parse_objects(const sp_ctx *c, const cJSON *root, scene *s)
{
    const cJSON *objs = sp_get(root, "objects");
    char got[96];
    if (!objs)
        return sp_missing(c, "", "objects", "an array of objects");
    if (!cJSON_IsArray(objs))
        return sp_fail(c, RR_ERR_INVALID, "objects", "expected an array of objects (got %s)",
                       sp_describe(objs, got, sizeof got));
    size_t n = (size_t)cJSON_GetArraySize(objs);
    if (n == 0)
        return sp_fail(c, RR_ERR_INVALID, "objects", "expected at least one object");
    sp_build b;
    memset(&b, 0, sizeof b);
    size_t i = 0;
    for (const cJSON *it = objs->child; it; it = it->next, i++) {
        rr_status st = parse_object(c, it, i, s, &b);
        if (st != RR_OK)
            return st;
    }
    return RR_OK;
}
