/* scene_model.c - "model" objects: a whole file (glTF, OBJ+MTL, FBX, ...)
 * imported through import/ (imp.h) into the scene's objects, materials and
 * lights (notes/import.md).
 *
 * The file's frame is taken in three steps, each acting after the one
 * before: "scale" (file units to scene units), "up" (a Z-up file turned to
 * radray's Y-up), then the object's "transform". Every mesh of the file
 * becomes one object named "<model>/<mesh>", through the same path as a
 * "mesh" object (welding, topology report, zero-area triangles, culling).
 */
#include <math.h>
#include <string.h>

#include "scene_internal.h"

static const char *const k_model[] = {"type",  "name", "file", "material", "materials",
                                      "scale", "up",   "transform", "cull", NULL};

/* "<model>/<name>", cut to SCENE_NAME_MAX - 1 bytes at a UTF-8 boundary. */
static void join_name(char *out, const char *model, const char *name)
{
    char buf[2 * SCENE_NAME_MAX + 2];
    snprintf(buf, sizeof buf, "%s/%s", model, name);
    size_t n = strlen(buf);
    if (n >= SCENE_NAME_MAX) {
        n = SCENE_NAME_MAX - 1;
        while (n > 0 && ((unsigned char)buf[n] & 0xC0) == 0x80)
            n--;
    }
    memcpy(out, buf, n);
    out[n] = '\0';
}

/* The file name without folder and extension. */
static void stem(const char *path, char *out, size_t n)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    snprintf(out, n, "%s", base);
    char *dot = strrchr(out, '.');
    if (dot && dot != out)
        *dot = '\0';
}

/* scale, then up, then the object's transform. */
static rr_status frame(const sp_ctx *c, const cJSON *obj, const char *opath, rr_xform *x)
{
    double scale = 1;
    char up[8] = "y", p[SP_PATH_MAX];
    rr_status st;
    if ((st = sp_number(c, obj, opath, "scale", SP_OPTIONAL, &scale)) != RR_OK ||
        (st = sp_string(c, obj, opath, "up", SP_OPTIONAL, 1, up, sizeof up)) != RR_OK)
        return st;
    if (!(scale > 0)) {
        sp_key(p, opath, "scale");
        return sp_fail(c, RR_ERR_INVALID, p, "must be > 0 (got %g)", scale);
    }
    rr_xform f = rr_xform_identity();
    if (strcmp(up, "z") == 0) { /* (x, y, z) -> (x, z, -y): the file's +Z becomes +Y */
        f.m[1][1] = 0, f.m[1][2] = 1;
        f.m[2][1] = -1, f.m[2][2] = 0;
    } else if (strcmp(up, "y") != 0) {
        sp_key(p, opath, "up");
        return sp_fail(c, RR_ERR_INVALID, p, "expected \"y\" or \"z\" (got \"%s\")", up);
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            f.m[i][j] *= scale;
    rr_xform t;
    int has;
    if ((st = sp_parse_transform(c, obj, opath, &t, &has)) != RR_OK)
        return st;
    *x = rr_xform_compose(&t, &f);
    return RR_OK;
}

static rr_status grow_materials(const sp_ctx *c, scene *s, size_t add, const char *opath)
{
    scene_material *m = realloc(s->materials, (s->nmaterials + add) * sizeof *m);
    if (!m)
        return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu materials", s->nmaterials + add);
    s->materials = m;
    return RR_OK;
}

/* The file's materials into the scene, "<model>/<name>"; the object's
 * "materials" entries replace the ones they name. */
static rr_status add_materials(const sp_ctx *c, const cJSON *obj, const char *opath, const imp_model *im,
                               scene_model *sm, scene *s)
{
    rr_status st = grow_materials(c, s, im->nmaterials, opath);
    if (st != RR_OK)
        return st;
    sm->material_first = s->nmaterials;
    for (size_t i = 0; i < im->nmaterials; i++) {
        const imp_material *x = &im->materials[i];
        scene_material *m = &s->materials[s->nmaterials++];
        memset(m, 0, sizeof *m);
        join_name(m->name, sm->name, x->name);
        m->diffuse = x->diffuse, m->specular = x->specular, m->k = x->k;
        m->mirror = x->mirror, m->emission = x->emission;
        m->model = (uint32_t)(s->nmodels), m->notes = x->notes;
    }
    sm->material_count = im->nmaterials;
    const cJSON *ov = sp_get(obj, "materials");
    char p[SP_PATH_MAX], got[96];
    sp_key(p, opath, "materials");
    if (!ov)
        return RR_OK;
    if (!cJSON_IsObject(ov))
        return sp_fail(c, RR_ERR_INVALID, p, "expected an object mapping the file's material names to materials (got %s)",
                       sp_describe(ov, got, sizeof got));
    for (const cJSON *it = ov->child; it; it = it->next) {
        size_t i = 0;
        while (i < im->nmaterials && strcmp(im->materials[i].name, it->string) != 0)
            i++;
        char q[SP_PATH_MAX];
        sp_key(q, p, it->string);
        if (i == im->nmaterials) {
            char known[512] = "";
            size_t len = 0;
            for (size_t j = 0; j < im->nmaterials && len < sizeof known; j++)
                len += (size_t)snprintf(known + len, sizeof known - len, "%s%s", j ? ", " : "", im->materials[j].name);
            return sp_fail(c, RR_ERR_INVALID, q, "the file has no material '%.64s' (it has: %s)", it->string, known);
        }
        scene_material *m = &s->materials[sm->material_first + i];
        if ((st = sp_parse_material(c, it, q, m)) != RR_OK)
            return st;
        m->model = (uint32_t)s->nmodels, m->overridden = 1;
    }
    return RR_OK;
}

static rr_status add_lights(const sp_ctx *c, const char *opath, const imp_model *im, const rr_xform *x,
                            scene_model *sm, scene *s)
{
    sm->light_first = s->nlights;
    if (im->nlights == 0)
        return RR_OK;
    scene_light *l = realloc(s->lights, (s->nlights + im->nlights) * sizeof *l);
    if (!l)
        return sp_fail(c, RR_ERR_NOMEM, opath, "out of memory for %zu lights", s->nlights + im->nlights);
    s->lights = l;
    for (size_t i = 0; i < im->nlights; i++) {
        const imp_light *il = &im->lights[i];
        scene_light *d = &s->lights[s->nlights++];
        memset(d, 0, sizeof *d);
        join_name(d->name, sm->name, il->name);
        d->intensity = il->intensity;
        if (il->type == IMP_LIGHT_POINT) {
            d->type = SCENE_LIGHT_POINT;
            d->position = rr_xform_point(x, il->position);
        } else {
            d->type = SCENE_LIGHT_DIRECTIONAL;
            /* a direction is a normal's dual: the inverse transpose would keep
             * angles under shear, but a light's direction is a direction of
             * travel, mapped as a vector */
            d->direction = rr_v3_unit(rr_xform_vector(x, il->direction));
        }
        if (!rr_v3_isfinite(d->position) || !rr_v3_isfinite(d->direction) ||
            (d->type == SCENE_LIGHT_DIRECTIONAL && !(rr_v3_len(d->direction) > 0)))
            return sp_fail(c, RR_ERR_INVALID, opath, "light '%s' is not finite after the transform", il->name);
    }
    sm->light_count = im->nlights;
    return RR_OK;
}

/* One object per mesh. material: the object's "material" for all, or
 * SCENE_NONE for the file's own. */
static rr_status add_objects(const sp_ctx *c, const char *opath, imp_model *im, const rr_xform *x, int cull,
                             uint32_t material, scene_model *sm, scene *s, sp_build *b)
{
    sm->object_first = s->nobjects;
    for (size_t i = 0; i < im->nmeshes; i++) {
        imp_mesh *me = &im->meshes[i];
        size_t oi;
        rr_status st = sp_new_object(c, s, b, opath, &oi);
        if (st != RR_OK)
            return st;
        scene_object *o = &s->objects[oi];
        o->kind = SCENE_OBJ_MESH;
        join_name(o->name, sm->name, me->name);
        o->material = material != SCENE_NONE ? material : (uint32_t)(sm->material_first + me->material);
        o->model = (uint32_t)s->nmodels;
        snprintf(o->source, sizeof o->source, "%s", sm->source);
        char mpath[SP_PATH_MAX];
        snprintf(mpath, sizeof mpath, "%s (mesh '%s')", opath, me->name);
        if ((st = sp_add_mesh_object(c, s, b, oi, mpath, x, 1, me->tri)) != RR_OK)
            return st;
        s->objects[oi].cull_backfaces = cull < 0 ? sp_cull_auto(s, oi, s->ncsg) : cull;
    }
    sm->object_count = im->nmeshes;
    return RR_OK;
}

static rr_status import_file(const sp_ctx *c, const cJSON *obj, const char *opath, scene_model *sm, imp_model **im)
{
    char file[4096] = "", p[SP_PATH_MAX];
    rr_status st = sp_string(c, obj, opath, "file", SP_REQUIRED, 1, file, sizeof file);
    if (st != RR_OK)
        return st;
    sp_key(p, opath, "file");
    if ((st = rr_path_join(c->base_dir, file, sm->source, sizeof sm->source, c->err)) != RR_OK ||
        (st = imp_load(sm->source, im, c->err)) != RR_OK)
        return rr_error_prefix(c->err, "%s: %s", c->file, p);
    snprintf(sm->format, sizeof sm->format, "%s", (*im)->format);
    stem(file, sm->name, sizeof sm->name);
    return sp_string(c, obj, opath, "name", SP_OPTIONAL, 1, sm->name, sizeof sm->name);
}

rr_status sp_parse_model(const sp_ctx *c, const cJSON *obj, const char *opath, size_t ji, scene *s, sp_build *b)
{
    (void)ji;
    rr_status st = sp_check_object(c, obj, opath, k_model);
    if (st != RR_OK)
        return st;
    scene_model sm;
    memset(&sm, 0, sizeof sm);
    imp_model *im = NULL;
    rr_xform x;
    int cull;
    uint32_t material = SCENE_NONE;
    if ((st = import_file(c, obj, opath, &sm, &im)) != RR_OK || (st = frame(c, obj, opath, &x)) != RR_OK ||
        (st = sp_parse_cull(c, obj, opath, &cull)) != RR_OK)
        goto done;
    if (sp_get(obj, "material")) { /* everything in one material: the file's are not added */
        if (sp_get(obj, "materials")) {
            char p[SP_PATH_MAX];
            sp_key(p, opath, "materials");
            st = sp_fail(c, RR_ERR_INVALID, p, "give either \"material\" (one for everything) or \"materials\" "
                                               "(replacing some of the file's), not both");
            goto done;
        }
        st = sp_find_material(c, obj, opath, s, &material);
    } else {
        st = add_materials(c, obj, opath, im, &sm, s);
    }
    if (st == RR_OK)
        st = add_lights(c, opath, im, &x, &sm, s);
    if (st == RR_OK)
        st = add_objects(c, opath, im, &x, cull, material, &sm, s, b);
    if (st != RR_OK)
        goto done;
    sm.triangles = imp_triangles(im);
    sm.dropped_prims = im->dropped_prims, sm.dropped_lights = im->dropped_lights;
    sm.dropped_cameras = im->dropped_cameras;
    scene_model *mods = realloc(s->models, (s->nmodels + 1) * sizeof *mods);
    if (!mods) {
        st = sp_fail(c, RR_ERR_NOMEM, opath, "out of memory");
        goto done;
    }
    s->models = mods;
    s->models[s->nmodels++] = sm;
    if (sm.dropped_prims || sm.dropped_lights)
        rr_warn(c->opts ? &c->opts->warn : NULL, "%s: %s: %s: dropped %zu point/line primitive%s and %zu spot light%s "
                "(radray renders surfaces, and has point and directional lights only)", c->file, opath, sm.source,
                sm.dropped_prims, sm.dropped_prims == 1 ? "" : "s", sm.dropped_lights,
                sm.dropped_lights == 1 ? "" : "s");
done:
    imp_destroy(im);
    return st;
}
