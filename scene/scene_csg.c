/* scene_csg.c - solids: "quadric" objects (a tree of one leaf) and "csg"
 * trees over spheres, quadrics, boxes, closed meshes and nested csg nodes,
 * built into scene->csg (the contract is in scene.h, the format in
 * notes/scene-format.md, "Solids").
 *
 * A tree is built depth first: a node's children are appended before it, so
 * the root is the last node of its object. Transforms compose downwards (a
 * child's own transform acts first, then its parent's, up to the object's),
 * so every leaf holds its whole local-to-world map and inner nodes only
 * combine. n-ary unions and intersections fold into balanced binary trees
 * (depth ceil(log2 n)); differences fold left: difference [a, b, c] is
 * (a - b) - c, stored as two binary nodes.
 *
 * Bounds are conservative world boxes: the 8 corners of a leaf's local box
 * (sphere: centre +- radius; quadric and box: the clip box) through to_world,
 * a mesh's vertex bounds; inner nodes prune by their op (union: the union,
 * intersection: the overlap, difference: the left child's).
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "scene_internal.h"

#define SOLID_LIST "sphere, quadric, box, mesh, csg"
#define SHAPE_LIST "ellipsoid, cylinder, cone, paraboloid, hyperboloid, general"
#define OP_LIST "union, intersection, difference"

typedef enum solid_type { ST_SPHERE, ST_QUADRIC, ST_BOX, ST_MESH, ST_CSG } solid_type;

typedef struct solid_def {
    const char *name;
    solid_type type;
    const char *keys[3];
} solid_def;

static const solid_def k_solids[] = {
    {"sphere", ST_SPHERE, {"center", "radius", NULL}}, {"quadric", ST_QUADRIC, {"shape", NULL, NULL}},
    {"box", ST_BOX, {"min", "max", NULL}},             {"mesh", ST_MESH, {"file", "flip", NULL}},
    {"csg", ST_CSG, {"op", "children", NULL}},
};
#define N_SOLIDS (sizeof k_solids / sizeof k_solids[0])

typedef struct shape_def {
    const char *name;
    scene_quadric_shape shape;
    const char *keys[4];
} shape_def;

static const shape_def k_shapes[] = {
    {"ellipsoid", SCENE_QUADRIC_ELLIPSOID, {"radii", NULL, NULL, NULL}},
    {"cylinder", SCENE_QUADRIC_CYLINDER, {"radius", "height", NULL, NULL}},
    {"cone", SCENE_QUADRIC_CONE, {"radius", "height", NULL, NULL}},
    {"paraboloid", SCENE_QUADRIC_PARABOLOID, {"radius", "height", NULL, NULL}},
    {"hyperboloid", SCENE_QUADRIC_HYPERBOLOID, {"radius", "end_radius", "height", NULL}},
    {"general", SCENE_QUADRIC_GENERAL, {"q", "clip", NULL, NULL}},
};
#define N_SHAPES (sizeof k_shapes / sizeof k_shapes[0])

/* ---- small helpers ---- */

/* Inverse of an affine map; 0 when it is singular relative to its row
 * lengths (the same test as sp_parse_transform) or the inverse overflows. */
static int xform_inverse(const rr_xform *x, rr_xform *inv)
{
    const double(*a)[3] = x->m;
    double det = rr_xform_det(x), rows = 1;
    for (int r = 0; r < 3; r++)
        rows *= rr_v3_len(rr_v3(a[r][0], a[r][1], a[r][2]));
    if (!(fabs(det) > 1e-12 * rows) || !isfinite(det))
        return 0;
    /* inverse = adjugate / det; the adjugate is the transposed cofactor matrix. */
    double adj[3][3] = {{a[1][1] * a[2][2] - a[1][2] * a[2][1], a[0][2] * a[2][1] - a[0][1] * a[2][2],
                         a[0][1] * a[1][2] - a[0][2] * a[1][1]},
                        {a[1][2] * a[2][0] - a[1][0] * a[2][2], a[0][0] * a[2][2] - a[0][2] * a[2][0],
                         a[0][2] * a[1][0] - a[0][0] * a[1][2]},
                        {a[1][0] * a[2][1] - a[1][1] * a[2][0], a[0][1] * a[2][0] - a[0][0] * a[2][1],
                         a[0][0] * a[1][1] - a[0][1] * a[1][0]}};
    rr_xform r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = adj[i][j] / det;
    r.t = rr_v3_neg(rr_xform_vector(&r, x->t));
    int finite = rr_v3_isfinite(r.t);
    for (int i = 0; i < 3; i++)
        finite = finite && rr_v3_isfinite(rr_v3(r.m[i][0], r.m[i][1], r.m[i][2]));
    if (!finite)
        return 0;
    *inv = r;
    return 1;
}

static int box_empty(rr_vec3 lo, rr_vec3 hi) { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }

/* Grows an array to hold need elements; NULL on overflow or out of memory
 * (the old block is then still the caller's). */
static void *grow(void *arr, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap && arr)
        return arr;
    size_t nc = *cap ? *cap : 16;
    while (nc < need) {
        if (nc > SIZE_MAX / 2)
            return NULL;
        nc *= 2;
    }
    if (nc > SIZE_MAX / elem)
        return NULL;
    void *p = realloc(arr, nc * elem);
    if (p)
        *cap = nc;
    return p;
}

/* A node's name is its JSON path, cut to SCENE_NAME_MAX - 1 bytes (the
 * message paths are not cut; only the stored name is). */
static void set_name(scene_csg_node *n, const char *path)
{
    size_t len = strlen(path);
    if (len < sizeof n->name) {
        memcpy(n->name, path, len + 1);
        return;
    }
    len = sizeof n->name - 1;
    memcpy(n->name, path, len);
    memcpy(n->name + len - 3, "...", 4);
}

/* ---- the build ---- */

typedef struct solid_ctx {
    const sp_ctx *c;
    scene *s;
    sp_build *b;
    uint32_t object;
} solid_ctx;

/* Appends a zeroed node (identity transforms) and returns its index in *idx. */
static rr_status new_node(solid_ctx *sc, const char *path, scene_csg_op op, uint32_t material, uint32_t *idx)
{
    scene *s = sc->s;
    if (s->ncsg >= UINT32_MAX)
        return sp_fail(sc->c, RR_ERR_LIMIT, path, "the scene would exceed %u CSG nodes", (unsigned)UINT32_MAX);
    scene_csg_node *p = grow(s->csg, &sc->b->cap_csg, s->ncsg + 1, sizeof *s->csg);
    if (!p)
        return sp_fail(sc->c, RR_ERR_NOMEM, path, "out of memory for %zu CSG nodes", s->ncsg + 1);
    s->csg = p;
    scene_csg_node *n = &s->csg[s->ncsg];
    memset(n, 0, sizeof *n);
    n->op = op;
    n->object = sc->object;
    n->material = material;
    n->to_world = n->to_local = rr_xform_identity();
    set_name(n, path);
    *idx = (uint32_t)s->ncsg++;
    return RR_OK;
}

/* A length: a finite number > 0. */
static rr_status positive(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, double *out)
{
    if (!sp_get(obj, key))
        return sp_missing(c, path, key, "a number > 0");
    double v = 0;
    rr_status st = sp_number(c, obj, path, key, SP_REQUIRED, &v);
    if (st != RR_OK)
        return st;
    if (!(v > 0)) {
        char p[SP_PATH_MAX];
        sp_key(p, path, key);
        return sp_fail(c, RR_ERR_INVALID, p, "expected a number > 0 (got %g)", v);
    }
    *out = v;
    return RR_OK;
}

/* "max" must exceed "min" on every axis; reads both from obj. */
static rr_status read_box(const sp_ctx *c, const cJSON *obj, const char *path, rr_vec3 *lo, rr_vec3 *hi)
{
    rr_status st;
    if ((st = sp_vec3(c, obj, path, "min", SP_REQUIRED, lo)) != RR_OK ||
        (st = sp_vec3(c, obj, path, "max", SP_REQUIRED, hi)) != RR_OK)
        return st;
    if (!(hi->x > lo->x && hi->y > lo->y && hi->z > lo->z)) {
        char p[SP_PATH_MAX];
        sp_key(p, path, "max");
        return sp_fail(c, RR_ERR_INVALID, p,
                       "must be greater than min on every axis (min [%g, %g, %g], max [%g, %g, %g])", lo->x, lo->y,
                       lo->z, hi->x, hi->y, hi->z);
    }
    return RR_OK;
}

static const shape_def *find_shape(const sp_ctx *c, const cJSON *obj, const char *path, rr_status *st)
{
    const cJSON *v = sp_get(obj, "shape");
    char p[SP_PATH_MAX], got[96];
    sp_key(p, path, "shape");
    if (!v) {
        *st = sp_missing(c, path, "shape", "one of " SHAPE_LIST);
        return NULL;
    }
    if (!cJSON_IsString(v)) {
        *st = sp_fail(c, RR_ERR_INVALID, p, "expected one of " SHAPE_LIST " (got %s)", sp_describe(v, got, sizeof got));
        return NULL;
    }
    for (size_t i = 0; i < N_SHAPES; i++)
        if (strcmp(v->valuestring, k_shapes[i].name) == 0)
            return &k_shapes[i];
    *st = sp_fail(c, RR_ERR_INVALID, p, "unknown shape '%.64s' (known: " SHAPE_LIST ")", v->valuestring);
    return NULL;
}

static const solid_def *find_solid(const sp_ctx *c, const cJSON *obj, const char *path, rr_status *st)
{
    const cJSON *v = sp_get(obj, "type");
    char p[SP_PATH_MAX], got[96];
    sp_key(p, path, "type");
    if (!v) {
        *st = sp_missing(c, path, "type", "one of " SOLID_LIST);
        return NULL;
    }
    if (!cJSON_IsString(v)) {
        *st = sp_fail(c, RR_ERR_INVALID, p, "expected one of " SOLID_LIST " (got %s)", sp_describe(v, got, sizeof got));
        return NULL;
    }
    for (size_t i = 0; i < N_SOLIDS; i++)
        if (strcmp(v->valuestring, k_solids[i].name) == 0)
            return &k_solids[i];
    if (strcmp(v->valuestring, "quad") == 0 || strcmp(v->valuestring, "triangles") == 0)
        *st = sp_fail(c, RR_ERR_INVALID, p,
                      "a '%s' cannot be part of a csg: it does not enclose a volume (solids: " SOLID_LIST ")",
                      v->valuestring);
    else
        *st = sp_fail(c, RR_ERR_INVALID, p, "unknown type '%.64s' (solids: " SOLID_LIST ")", v->valuestring);
    return NULL;
}

rr_status sp_solid_check_keys(const sp_ctx *c, const cJSON *obj, const char *path, int top)
{
    char got[96];
    if (!cJSON_IsObject(obj))
        return sp_fail(c, RR_ERR_INVALID, path, "expected a solid object (got %s)", sp_describe(obj, got, sizeof got));
    rr_status st = RR_OK;
    const solid_def *sd = find_solid(c, obj, path, &st);
    if (!sd)
        return st;
    const char *allowed[16];
    size_t n = 0;
    allowed[n++] = "type";
    if (top)
        allowed[n++] = "name";
    allowed[n++] = "material";
    allowed[n++] = "transform";
    if (top)
        allowed[n++] = "cull";
    for (size_t i = 0; i < 3 && sd->keys[i]; i++)
        allowed[n++] = sd->keys[i];
    if (sd->type == ST_QUADRIC) {
        const shape_def *sh = find_shape(c, obj, path, &st);
        if (!sh)
            return st;
        for (size_t i = 0; i < 4 && sh->keys[i]; i++)
            allowed[n++] = sh->keys[i];
    }
    allowed[n] = NULL;
    if (!top)
        for (size_t i = 0; i < 2; i++) {
            const char *k = i == 0 ? "name" : "cull";
            if (sp_get(obj, k))
                return sp_fail(c, RR_ERR_INVALID, path,
                               "'%s' is allowed only on the object itself, not on a csg child (allowed here: "
                               "type, material, transform and the keys of a %s)",
                               k, sd->name);
        }
    return sp_check_object(c, obj, path, allowed);
}

/* Fills a leaf's transforms from world, and its bounds from the local box
 * [lo, hi] (all 8 corners through to_world). */
static rr_status leaf_frame(solid_ctx *sc, const char *path, const rr_xform *world, rr_vec3 lo, rr_vec3 hi,
                            scene_csg_node *n)
{
    rr_xform inv;
    if (!xform_inverse(world, &inv))
        return sp_fail(sc->c, RR_ERR_INVALID, path,
                       "the transform, composed with those of the enclosing csg nodes, is singular (determinant %g)",
                       rr_xform_det(world));
    n->to_world = *world;
    n->to_local = inv;
    rr_vec3 blo = rr_v3(INFINITY, INFINITY, INFINITY), bhi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (int i = 0; i < 8; i++) {
        rr_vec3 p = rr_xform_point(world, rr_v3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z));
        blo = rr_v3_min(blo, p);
        bhi = rr_v3_max(bhi, p);
    }
    if (!rr_v3_isfinite(blo) || !rr_v3_isfinite(bhi))
        return sp_fail(sc->c, RR_ERR_INVALID, path, "the transformed solid is not finite");
    n->bbox_lo = blo;
    n->bbox_hi = bhi;
    return RR_OK;
}

/* Q and the clip box of a named shape (canonical frame: the y axis is the
 * axis), or of "general". */
static rr_status quadric_shape(const sp_ctx *c, const cJSON *v, const char *path, const shape_def *sh,
                               double q[4][4], rr_vec3 *lo, rr_vec3 *hi)
{
    rr_status st;
    double r = 0, h = 0;
    memset(q, 0, 16 * sizeof q[0][0]);
    switch (sh->shape) {
    case SCENE_QUADRIC_ELLIPSOID: {
        rr_vec3 a;
        char p[SP_PATH_MAX];
        sp_key(p, path, "radii");
        if ((st = sp_vec3(c, v, path, "radii", SP_REQUIRED, &a)) != RR_OK)
            return st;
        for (int i = 0; i < 3; i++) {
            double ai = rr_v3_get(a, i);
            if (!(ai > 0)) {
                char pi[SP_PATH_MAX];
                sp_idx(pi, p, (size_t)i);
                return sp_fail(c, RR_ERR_INVALID, pi, "expected a number > 0 (got %g)", ai);
            }
            q[i][i] = 1.0 / (ai * ai);
            if (!isfinite(q[i][i]) || q[i][i] == 0) {
                char pi[SP_PATH_MAX];
                sp_idx(pi, p, (size_t)i);
                return sp_fail(c, RR_ERR_INVALID, pi, "the radius %g is out of range (1/radius^2 over- or underflows)",
                               ai);
            }
        }
        q[3][3] = -1;
        *lo = rr_v3_neg(a);
        *hi = a;
        return RR_OK;
    }
    case SCENE_QUADRIC_CYLINDER:
    case SCENE_QUADRIC_CONE:
    case SCENE_QUADRIC_PARABOLOID:
        if ((st = positive(c, v, path, "radius", &r)) != RR_OK || (st = positive(c, v, path, "height", &h)) != RR_OK)
            return st;
        q[0][0] = q[2][2] = 1;
        if (sh->shape == SCENE_QUADRIC_CYLINDER) {
            q[3][3] = -r * r;
            *lo = rr_v3(-r, -h / 2, -r);
            *hi = rr_v3(r, h / 2, r);
        } else if (sh->shape == SCENE_QUADRIC_CONE) {
            q[1][1] = -(r / h) * (r / h);
            *lo = rr_v3(-r, 0, -r);
            *hi = rr_v3(r, h, r);
        } else {
            q[1][3] = q[3][1] = -0.5 * (r * r / h);
            *lo = rr_v3(-r, 0, -r);
            *hi = rr_v3(r, h, r);
        }
        break;
    case SCENE_QUADRIC_HYPERBOLOID: {
        double R = 0;
        if ((st = positive(c, v, path, "radius", &r)) != RR_OK ||
            (st = positive(c, v, path, "end_radius", &R)) != RR_OK ||
            (st = positive(c, v, path, "height", &h)) != RR_OK)
            return st;
        if (!(R > r)) {
            char p[SP_PATH_MAX];
            sp_key(p, path, "end_radius");
            return sp_fail(c, RR_ERR_INVALID, p,
                           "must be greater than radius (the waist; got end_radius %g, radius %g)", R, r);
        }
        double k = (R * R - r * r) / ((h / 2) * (h / 2));
        q[0][0] = q[2][2] = 1;
        q[1][1] = -k;
        q[3][3] = -r * r;
        *lo = rr_v3(-R, -h / 2, -R);
        *hi = rr_v3(R, h / 2, R);
        break;
    }
    case SCENE_QUADRIC_GENERAL: {
        const cJSON *qv = sp_get(v, "q");
        char p[SP_PATH_MAX];
        const char *expected = "a symmetric 4x4 matrix [[q00, q01, q02, q03], ..., [q30, q31, q32, q33]]";
        if (!qv)
            return sp_missing(c, path, "q", expected);
        sp_key(p, path, "q");
        if ((st = sp_array(c, qv, p, 4, expected)) != RR_OK)
            return st;
        double big = 0;
        for (int i = 0; i < 4; i++) {
            char pr[SP_PATH_MAX];
            sp_idx(pr, p, (size_t)i);
            const cJSON *row = cJSON_GetArrayItem(qv, i);
            if ((st = sp_array(c, row, pr, 4, "a row of 4 numbers")) != RR_OK)
                return st;
            for (int j = 0; j < 4; j++) {
                char pk[SP_PATH_MAX];
                sp_idx(pk, pr, (size_t)j);
                if ((st = sp_number_item(c, cJSON_GetArrayItem(row, j), pk, &q[i][j])) != RR_OK)
                    return st;
                big = fmax(big, fabs(q[i][j]));
            }
        }
        for (int i = 0; i < 4; i++)
            for (int j = i + 1; j < 4; j++)
                if (fabs(q[i][j] - q[j][i]) > 1e-12 * big)
                    return sp_fail(c, RR_ERR_INVALID, p, "must be symmetric: q[%d][%d] = %g but q[%d][%d] = %g", i, j,
                                   q[i][j], j, i, q[j][i]);
        int surface = 0;
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++)
                if (i < 3 || j < 3)
                    surface = surface || q[i][j] != 0;
        if (!surface)
            return sp_fail(c, RR_ERR_INVALID, p,
                           "has no x, y or z terms: it describes no surface (everything or nothing is inside)");
        /* Exactly symmetric from here on, so that x^T Q x and its gradient
         * 2 Q x agree whichever half a consumer reads. */
        for (int i = 0; i < 4; i++)
            for (int j = i + 1; j < 4; j++)
                q[i][j] = q[j][i] = 0.5 * q[i][j] + 0.5 * q[j][i]; /* no overflow near DBL_MAX */
        const cJSON *cv = sp_get(v, "clip");
        static const char *const k_clip[] = {"min", "max", NULL};
        if (!cv)
            return sp_missing(c, path, "clip",
                              "a finite box {\"min\": [x, y, z], \"max\": [x, y, z]} (a general quadric needs one)");
        sp_key(p, path, "clip");
        if ((st = sp_check_object(c, cv, p, k_clip)) != RR_OK || (st = read_box(c, cv, p, lo, hi)) != RR_OK)
            return st;
        break;
    }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (!isfinite(q[i][j]))
                return sp_fail(c, RR_ERR_INVALID, path, "the %s's coefficients overflow (lengths out of range)",
                               sh->name);
    if (!rr_v3_isfinite(*lo) || !rr_v3_isfinite(*hi))
        return sp_fail(c, RR_ERR_INVALID, path, "the %s's clip box overflows (lengths out of range)", sh->name);
    return RR_OK;
}

static const char *plural(size_t n, const char *one, const char *many) { return n == 1 ? one : many; }

/* A mesh leaf: loaded through the object pipeline's mesh path, in WORLD
 * space, refused unless it bounds a volume (watertight, manifold,
 * consistently and outward oriented). */
static rr_status mesh_leaf(solid_ctx *sc, const cJSON *v, const char *path, const rr_xform *world, uint32_t material,
                           uint32_t *idx)
{
    const sp_ctx *c = sc->c;
    scene *s = sc->s;
    int flip = 0;
    rr_status st = sp_bool(c, v, path, "flip", SP_OPTIONAL, &flip);
    if (st != RR_OK)
        return st;
    char source[4096];
    mesh_tri *m = NULL;
    if ((st = sp_load_mesh(c, v, path, world, 1, flip, source, &m)) != RR_OK)
        return st;
    const char *file = sp_get(v, "file")->valuestring; /* sp_load_mesh checked it is a string */
    mesh_report rep;
    if ((st = mesh_analyze(m, &rep, c->err)) != RR_OK) {
        rr_error_prefix(c->err, "%s: %s", c->file, path);
        goto done;
    }
    if (rep.boundary_edges) {
        st = sp_fail(c, RR_ERR_INVALID, path, "mesh '%s' is not watertight: %zu boundary %s; a mesh inside CSG must be closed",
                     file, rep.boundary_edges, plural(rep.boundary_edges, "edge", "edges"));
        goto done;
    }
    if (rep.nonmanifold_edges) {
        st = sp_fail(c, RR_ERR_INVALID, path,
                     "mesh '%s' is not manifold: %zu %s shared by three or more triangles; a mesh inside CSG must "
                     "bound a volume",
                     file, rep.nonmanifold_edges, plural(rep.nonmanifold_edges, "edge", "edges"));
        goto done;
    }
    if (rep.misoriented_edges) {
        st = sp_fail(c, RR_ERR_INVALID, path,
                     "mesh '%s' is not consistently oriented: %zu %s with inconsistent orientation (neighbouring "
                     "triangles wind the same way along them); a mesh inside CSG needs one outward orientation",
                     file, rep.misoriented_edges, plural(rep.misoriented_edges, "edge", "edges"));
        goto done;
    }
    /* Signed volume (divergence theorem); world space, the winding already
     * corrected for a mirroring transform, so outward means positive. */
    double vol = 0;
    rr_vec3 lo = rr_v3(INFINITY, INFINITY, INFINITY), hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    size_t keep = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *ti = m->tris + 3 * t;
        rr_vec3 p[3];
        for (int k = 0; k < 3; k++) {
            p[k] = rr_v3(m->pos[3 * ti[k]], m->pos[3 * ti[k] + 1], m->pos[3 * ti[k] + 2]);
            lo = rr_v3_min(lo, p[k]);
            hi = rr_v3_max(hi, p[k]);
        }
        vol += rr_v3_dot(p[0], rr_v3_cross(p[1], p[2])) / 6.0;
        keep += !sp_tri_degenerate(p[0], p[1], p[2]);
    }
    rr_vec3 ext = rr_v3_sub(hi, lo);
    double scale = fmax(ext.x, fmax(ext.y, ext.z));
    if (!(fabs(vol) > 1e-12 * scale * scale * scale)) {
        st = sp_fail(c, RR_ERR_INVALID, path, "mesh '%s' encloses no volume (signed volume %g)", file, vol);
        goto done;
    }
    if (vol < 0) {
        st = sp_fail(c, RR_ERR_INVALID, path,
                     "mesh '%s' is oriented inwards (signed volume %g < 0); a mesh inside CSG must face outwards: %s",
                     file, vol, flip ? "remove \"flip\": true" : "set \"flip\": true");
        goto done;
    }
    if (keep < m->ntris)
        rr_warn(c->opts ? &c->opts->warn : NULL, "%s: %s: dropped %zu zero-area triangle%s of mesh '%s'", c->file,
                path, m->ntris - keep, m->ntris - keep == 1 ? "" : "s", file);

    if (m->nverts > UINT32_MAX - s->ncsg_verts || keep > UINT32_MAX - s->ncsg_tris) {
        st = sp_fail(c, RR_ERR_LIMIT, path, "the scene would exceed %u CSG mesh vertices or triangles",
                     (unsigned)UINT32_MAX);
        goto done;
    }
    rr_vec3 *pv = grow(s->csg_verts, &sc->b->cap_csg_verts, s->ncsg_verts + m->nverts, sizeof *s->csg_verts);
    if (!pv) {
        st = sp_fail(c, RR_ERR_NOMEM, path, "out of memory for mesh '%s'", file);
        goto done;
    }
    s->csg_verts = pv;
    uint32_t(*pt)[3] = grow(s->csg_tris, &sc->b->cap_csg_tris, s->ncsg_tris + keep, sizeof *s->csg_tris);
    if (!pt) {
        st = sp_fail(c, RR_ERR_NOMEM, path, "out of memory for mesh '%s'", file);
        goto done;
    }
    s->csg_tris = pt;
    if ((st = new_node(sc, path, SCENE_CSG_LEAF, material, idx)) != RR_OK)
        goto done;
    scene_csg_node *n = &s->csg[*idx];
    n->solid = SCENE_SOLID_MESH;
    n->bbox_lo = lo;
    n->bbox_hi = hi;
    n->tri_first = s->ncsg_tris;
    n->tri_count = keep;
    size_t base = s->ncsg_verts;
    for (size_t i = 0; i < m->nverts; i++)
        s->csg_verts[base + i] = rr_v3(m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]);
    s->ncsg_verts += m->nverts;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *ti = m->tris + 3 * t;
        if (sp_tri_degenerate(s->csg_verts[base + ti[0]], s->csg_verts[base + ti[1]], s->csg_verts[base + ti[2]]))
            continue;
        uint32_t *d = s->csg_tris[s->ncsg_tris++];
        d[0] = (uint32_t)(base + ti[0]);
        d[1] = (uint32_t)(base + ti[1]);
        d[2] = (uint32_t)(base + ti[2]);
    }
done:
    mesh_destroy(m);
    return st;
}

/* Bounds of op(a, b). An empty box (lo > hi on some axis) stays finite, so
 * that a consumer taking its centre gets no NaN. */
static void combine_bounds(scene_csg_op op, const scene_csg_node *a, const scene_csg_node *b, scene_csg_node *n)
{
    int ea = box_empty(a->bbox_lo, a->bbox_hi), eb = box_empty(b->bbox_lo, b->bbox_hi);
    if (op == SCENE_CSG_DIFFERENCE || (op == SCENE_CSG_UNION && eb)) {
        n->bbox_lo = a->bbox_lo, n->bbox_hi = a->bbox_hi;
    } else if (op == SCENE_CSG_UNION && ea) {
        n->bbox_lo = b->bbox_lo, n->bbox_hi = b->bbox_hi;
    } else if (op == SCENE_CSG_UNION) {
        n->bbox_lo = rr_v3_min(a->bbox_lo, b->bbox_lo);
        n->bbox_hi = rr_v3_max(a->bbox_hi, b->bbox_hi);
    } else { /* intersection: the overlap, empty when either is */
        n->bbox_lo = rr_v3_max(a->bbox_lo, b->bbox_lo);
        n->bbox_hi = rr_v3_min(a->bbox_hi, b->bbox_hi);
    }
}

static rr_status build_node(solid_ctx *sc, const cJSON *v, const char *path, int level, const rr_xform *world,
                            uint32_t material, uint32_t *idx, int *depth);

/* One binary node over children a and b (depths da, db) named np; refuses
 * when level - 1 + its depth is over the limit (every enclosing csg adds at
 * least one level, so that is a lower bound of the final depth, exact at the
 * object, level 1). */
static rr_status combine(solid_ctx *sc, const char *path, const char *np, scene_csg_op op, uint32_t material,
                         int level, uint32_t a, int da, uint32_t b, int db, uint32_t *idx, int *depth)
{
    int d = 1 + (da > db ? da : db);
    if (level - 1 + d > SP_CSG_DEPTH_MAX)
        return sp_fail(sc->c, RR_ERR_LIMIT, path,
                       "the CSG tree is at least %d levels deep, over the limit of %d (group the children into "
                       "nested csg objects)",
                       level - 1 + d, SP_CSG_DEPTH_MAX);
    uint32_t ni;
    rr_status st = new_node(sc, np, op, material, &ni);
    if (st != RR_OK)
        return st;
    scene_csg_node *n = &sc->s->csg[ni];
    n->left = a;
    n->right = b;
    combine_bounds(n->op, &sc->s->csg[a], &sc->s->csg[b], n);
    *idx = ni;
    *depth = d;
    return RR_OK;
}

/* Children [lo, hi) of a union or intersection as a balanced tree (the first
 * half on the left: three children are (a op b) op c, as a left fold). The
 * node the file wrote is the root; the others are named after the children
 * they combine. */
static rr_status fold_balanced(solid_ctx *sc, const char *path, scene_csg_op op, uint32_t material, int level,
                               const uint32_t *ci, const int *cd, size_t lo, size_t hi, int root, uint32_t *idx,
                               int *depth)
{
    if (hi - lo == 1) {
        *idx = ci[lo];
        *depth = cd[lo];
        return RR_OK;
    }
    size_t mid = lo + (hi - lo + 1) / 2;
    uint32_t a, b;
    int da, db;
    rr_status st = fold_balanced(sc, path, op, material, level, ci, cd, lo, mid, 0, &a, &da);
    if (st == RR_OK)
        st = fold_balanced(sc, path, op, material, level, ci, cd, mid, hi, 0, &b, &db);
    if (st != RR_OK)
        return st;
    char np[SP_PATH_MAX + 48]; /* path (< SP_PATH_MAX) + ".children[lo..hi]" */
    if (root)
        snprintf(np, sizeof np, "%s", path);
    else
        snprintf(np, sizeof np, "%s.children[%zu..%zu]", path, lo, hi - 1);
    return combine(sc, path, np, op, material, level, a, da, b, db, idx, depth);
}

/* Children of a difference, folded left: ((a - b) - c) - ... */
static rr_status fold_left(solid_ctx *sc, const char *path, uint32_t material, int level, const uint32_t *ci,
                           const int *cd, size_t n, uint32_t *idx, int *depth)
{
    uint32_t acc = ci[0];
    int accd = cd[0];
    for (size_t i = 1; i < n; i++) {
        char np[SP_PATH_MAX + 48];
        if (i + 1 < n)
            snprintf(np, sizeof np, "%s.children[0..%zu]", path, i);
        else
            snprintf(np, sizeof np, "%s", path);
        rr_status st = combine(sc, path, np, SCENE_CSG_DIFFERENCE, material, level, acc, accd, ci[i], cd[i], &acc, &accd);
        if (st != RR_OK)
            return st;
    }
    *idx = acc;
    *depth = accd;
    return RR_OK;
}

/* A "csg" node: its children, folded into binary nodes. */
static rr_status csg_node(solid_ctx *sc, const cJSON *v, const char *path, int level, const rr_xform *world,
                          uint32_t material, uint32_t *idx, int *depth)
{
    const sp_ctx *c = sc->c;
    static const struct {
        const char *name;
        scene_csg_op op;
    } ops[] = {{"union", SCENE_CSG_UNION}, {"intersection", SCENE_CSG_INTERSECTION}, {"difference", SCENE_CSG_DIFFERENCE}};
    char p[SP_PATH_MAX], got[96];
    const cJSON *ov = sp_get(v, "op");
    sp_key(p, path, "op");
    if (!ov)
        return sp_missing(c, path, "op", "one of " OP_LIST);
    if (!cJSON_IsString(ov))
        return sp_fail(c, RR_ERR_INVALID, p, "expected one of " OP_LIST " (got %s)", sp_describe(ov, got, sizeof got));
    int op = -1;
    for (size_t i = 0; i < 3; i++)
        if (strcmp(ov->valuestring, ops[i].name) == 0)
            op = (int)ops[i].op;
    if (op < 0)
        return sp_fail(c, RR_ERR_INVALID, p, "unknown op '%.64s' (known: " OP_LIST ")", ov->valuestring);

    const cJSON *ch = sp_get(v, "children");
    sp_key(p, path, "children");
    if (!ch)
        return sp_missing(c, path, "children", "an array of at least 2 solids");
    if (!cJSON_IsArray(ch))
        return sp_fail(c, RR_ERR_INVALID, p, "expected an array of at least 2 solids (got %s)",
                       sp_describe(ch, got, sizeof got));
    int nch = cJSON_GetArraySize(ch);
    if (nch < 2)
        return sp_fail(c, RR_ERR_INVALID, p, "expected at least 2 children (got %d): a csg combines two or more solids",
                       nch);
    /* Its children are one level further down (a leaf counts as a level). */
    if (level + 1 > SP_CSG_DEPTH_MAX)
        return sp_fail(c, RR_ERR_LIMIT, path, "the CSG tree is nested deeper than the limit of %d levels",
                       SP_CSG_DEPTH_MAX);
    /* Unions and intersections (associative and commutative) fold into a
     * balanced tree, ceil(log2 n) binary nodes above the deepest child;
     * differences fold left, a chain n - 1 long ((a - b) - c). Refuse
     * before building anything when that alone is too deep. */
    int balanced = op != SCENE_CSG_DIFFERENCE, fold = 0;
    while (balanced && (1 << fold) < nch)
        fold++;
    if (!balanced)
        fold = nch - 1;
    if (level + fold > SP_CSG_DEPTH_MAX)
        return sp_fail(c, RR_ERR_LIMIT, p,
                       "%d children fold into %d levels of binary nodes (%s), deeper than the limit of %d levels for "
                       "the whole tree; group them into nested csg objects",
                       nch, fold, balanced ? "a balanced tree" : "a chain: difference folds left",
                       SP_CSG_DEPTH_MAX);
    uint32_t *ci = malloc((size_t)nch * sizeof *ci);
    int *cd = malloc((size_t)nch * sizeof *cd);
    if (!ci || !cd) {
        free(ci);
        free(cd);
        return sp_fail(c, RR_ERR_NOMEM, p, "out of memory for %d children", nch);
    }
    rr_status st = RR_OK;
    size_t i = 0;
    for (const cJSON *it = ch->child; it && st == RR_OK; it = it->next, i++) {
        char cp[SP_PATH_MAX];
        sp_idx(cp, p, i);
        if ((st = sp_solid_check_keys(c, it, cp, 0)) != RR_OK)
            break;
        uint32_t cmat = material;
        if (sp_get(it, "material") && (st = sp_find_material(c, it, cp, sc->s, &cmat)) != RR_OK)
            break;
        rr_xform own, cw;
        int has;
        if ((st = sp_parse_transform(c, it, cp, &own, &has)) != RR_OK)
            break;
        cw = rr_xform_compose(world, &own); /* the child's own transform first, then its parents' */
        st = build_node(sc, it, cp, level + 1, &cw, cmat, &ci[i], &cd[i]);
    }
    if (st == RR_OK)
        st = balanced ? fold_balanced(sc, path, (scene_csg_op)op, material, level, ci, cd, 0, (size_t)nch, 1, idx, depth)
                      : fold_left(sc, path, material, level, ci, cd, (size_t)nch, idx, depth);
    free(ci);
    free(cd);
    return st;
}

/* Node v at path (keys checked), level 1 for the object itself; world is its
 * whole local-to-world map (own transform included), material its own or
 * inherited. *idx: its index in s->csg; *depth: its subtree's depth. */
static rr_status build_node(solid_ctx *sc, const cJSON *v, const char *path, int level, const rr_xform *world,
                            uint32_t material, uint32_t *idx, int *depth)
{
    const sp_ctx *c = sc->c;
    if (level > SP_CSG_DEPTH_MAX)
        return sp_fail(c, RR_ERR_LIMIT, path, "the CSG tree is nested deeper than the limit of %d levels",
                       SP_CSG_DEPTH_MAX);
    rr_status st = RR_OK;
    const solid_def *sd = find_solid(c, v, path, &st);
    if (!sd)
        return st;
    if (sd->type == ST_CSG)
        return csg_node(sc, v, path, level, world, material, idx, depth);
    *depth = 1;
    if (sd->type == ST_MESH)
        return mesh_leaf(sc, v, path, world, material, idx);

    scene_csg_node leaf;
    memset(&leaf, 0, sizeof leaf);
    rr_vec3 lo, hi;
    if (sd->type == ST_SPHERE) {
        leaf.solid = SCENE_SOLID_SPHERE;
        if ((st = sp_vec3(c, v, path, "center", SP_REQUIRED, &leaf.center)) != RR_OK ||
            (st = positive(c, v, path, "radius", &leaf.radius)) != RR_OK)
            return st;
        rr_vec3 r = rr_v3(leaf.radius, leaf.radius, leaf.radius);
        lo = rr_v3_sub(leaf.center, r);
        hi = rr_v3_add(leaf.center, r);
        if (!rr_v3_isfinite(lo) || !rr_v3_isfinite(hi))
            return sp_fail(c, RR_ERR_INVALID, path, "the sphere is not finite");
    } else if (sd->type == ST_BOX) {
        leaf.solid = SCENE_SOLID_BOX;
        if ((st = read_box(c, v, path, &lo, &hi)) != RR_OK)
            return st;
        leaf.clip_lo = lo;
        leaf.clip_hi = hi;
    } else {
        const shape_def *sh = find_shape(c, v, path, &st);
        if (!sh)
            return st;
        leaf.solid = SCENE_SOLID_QUADRIC;
        leaf.shape = sh->shape;
        if ((st = quadric_shape(c, v, path, sh, leaf.q, &lo, &hi)) != RR_OK)
            return st;
        leaf.clip_lo = lo;
        leaf.clip_hi = hi;
    }
    if ((st = leaf_frame(sc, path, world, lo, hi, &leaf)) != RR_OK ||
        (st = new_node(sc, path, SCENE_CSG_LEAF, material, idx)) != RR_OK)
        return st;
    scene_csg_node *n = &sc->s->csg[*idx];
    leaf.op = n->op;
    leaf.object = n->object;
    leaf.material = n->material;
    memcpy(leaf.name, n->name, sizeof leaf.name);
    *n = leaf;
    return RR_OK;
}

rr_status sp_parse_solid(const sp_ctx *c, const cJSON *obj, const char *opath, size_t oi, const rr_xform *x,
                         scene *s, sp_build *b)
{
    solid_ctx sc = {c, s, b, (uint32_t)oi};
    scene_object *o = &s->objects[oi];
    uint32_t root;
    int depth;
    rr_status st = build_node(&sc, obj, opath, 1, x, o->material, &root, &depth);
    if (st != RR_OK)
        return st;
    o = &s->objects[oi];
    o->csg_root = root;
    o->tri_first = o->tri_count = 0;
    memset(&o->report, 0, sizeof o->report);
    o->report.watertight = o->report.consistently_oriented = 1; /* closed by construction */
    const scene_csg_node *r = &s->csg[root];
    if (box_empty(r->bbox_lo, r->bbox_hi))
        rr_warn(c->opts ? &c->opts->warn : NULL,
                "%s: %s: the solid is empty (its intersection's parts do not overlap); nothing of it will be seen",
                c->file, opath);
    return RR_OK;
}
