/* scene.c - the public scene API: loading (top level of the format), the
 * finishing passes (bounding box, emissive triangles), destruction, and the
 * per-triangle helpers. The format is documented in notes/scene-format.md. */
#include <string.h>

#include "scene_internal.h"

static const char *const k_top[] = {"format",  "name",    "description", "camera",    "materials",
                                    "lights",  "objects", "render",      "radiosity", "camera_path", NULL};

/* The first check: a file that is not a radray scene at all (another JSON
 * file, a future version) should say so, not complain about its keys. */
static rr_status check_format(const sp_ctx *c, const cJSON *root)
{
    char got[96];
    if (!cJSON_IsObject(root))
        return sp_fail(c, RR_ERR_INVALID, "", "expected a JSON object with \"format\": \"%s\" (got %s)", SCENE_FORMAT,
                       sp_describe(root, got, sizeof got));
    const cJSON *f = sp_get(root, "format");
    if (!f)
        return sp_fail(c, RR_ERR_INVALID, "format", "missing (expected \"%s\"; is this a radray scene file?)",
                       SCENE_FORMAT);
    if (!cJSON_IsString(f) || strcmp(f->valuestring, SCENE_FORMAT) != 0)
        return sp_fail(c, RR_ERR_INVALID, "format", "expected \"%s\" (got %s)", SCENE_FORMAT,
                       sp_describe(f, got, sizeof got));
    return RR_OK;
}

/* "scenes/cornell.json" -> "cornell". */
static void default_name(const char *path, char *out, size_t n)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t len = strlen(base);
    if (len > 5 && strcmp(base + len - 5, ".json") == 0)
        len -= 5;
    if (len >= n)
        len = n - 1;
    memcpy(out, base, len);
    out[len] = '\0';
}

static rr_status collect_emissive(const sp_ctx *c, scene *s)
{
    size_t n = 0;
    for (size_t i = 0; i < s->ntris; i++)
        if (rr_rgb_max(s->materials[s->tris[i].material].emission) > 0)
            n++;
    if (n == 0)
        return RR_OK;
    s->emissive_tris = malloc(n * sizeof *s->emissive_tris);
    if (!s->emissive_tris)
        return sp_fail(c, RR_ERR_NOMEM, "", "out of memory for the emissive triangle list");
    for (size_t i = 0; i < s->ntris; i++)
        if (rr_rgb_max(s->materials[s->tris[i].material].emission) > 0)
            s->emissive_tris[s->nemissive++] = (uint32_t)i;
    return RR_OK;
}

static void compute_bbox(scene *s)
{
    rr_vec3 lo = rr_v3(INFINITY, INFINITY, INFINITY), hi = rr_v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t i = 0; i < s->nverts; i++) {
        lo = rr_v3_min(lo, s->verts[i]);
        hi = rr_v3_max(hi, s->verts[i]);
    }
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_object *o = &s->objects[i];
        if (o->kind == SCENE_OBJ_SPHERE) {
            rr_vec3 r = rr_v3(o->radius, o->radius, o->radius);
            lo = rr_v3_min(lo, rr_v3_sub(o->center, r));
            hi = rr_v3_max(hi, rr_v3_add(o->center, r));
        } else if (o->kind == SCENE_OBJ_CSG) {
            /* The root's bounds, already pruned by the ops; an empty solid
             * (lo > hi, warned about at load) adds nothing. */
            const scene_csg_node *r = &s->csg[o->csg_root];
            if (r->bbox_lo.x <= r->bbox_hi.x && r->bbox_lo.y <= r->bbox_hi.y && r->bbox_lo.z <= r->bbox_hi.z) {
                lo = rr_v3_min(lo, r->bbox_lo);
                hi = rr_v3_max(hi, r->bbox_hi);
            }
        }
    }
    if (!(lo.x <= hi.x)) /* nothing at all (cannot happen: objects are required) */
        lo = hi = rr_v3(0, 0, 0);
    s->bbox_min = lo;
    s->bbox_max = hi;
}

static rr_status build_scene(const sp_ctx *c, cJSON *root, scene *s)
{
    rr_status st;
    if ((st = check_format(c, root)) != RR_OK || (st = sp_apply_overrides(c, root)) != RR_OK ||
        (st = check_format(c, root)) != RR_OK || (st = sp_check_object(c, root, "", k_top)) != RR_OK)
        return st;
    default_name(s->path, s->name, sizeof s->name);
    /* "description" is for people reading the file; it is checked, not kept. */
    const cJSON *d = sp_get(root, "description");
    if (d && !cJSON_IsString(d)) {
        char got[96];
        return sp_fail(c, RR_ERR_INVALID, "description", "expected a string (got %s)", sp_describe(d, got, sizeof got));
    }
    if ((st = sp_string(c, root, "", "name", SP_OPTIONAL, 1, s->name, sizeof s->name)) != RR_OK ||
        (st = sp_parse_materials(c, root, s)) != RR_OK || (st = sp_parse_camera(c, root, s)) != RR_OK ||
        (st = sp_parse_camera_path(c, root, s)) != RR_OK ||
        (st = sp_parse_render(c, root, s)) != RR_OK ||
        (st = sp_parse_radiosity(c, root, s)) != RR_OK || (st = sp_parse_lights(c, root, s)) != RR_OK ||
        (st = sp_parse_objects(c, root, s)) != RR_OK || (st = collect_emissive(c, s)) != RR_OK)
        return st;
    compute_bbox(s);
    return RR_OK;
}

rr_status scene_load_string(const char *json, const char *name, const char *base_dir, const scene_load_opts *opts,
                            scene **out, rr_error *err)
{
    static const scene_load_opts no_opts;
    if (!name)
        name = "<string>";
    sp_ctx c = {name, base_dir ? base_dir : "", opts ? opts : &no_opts, err};
    if (!json || !out)
        return rr_error_set(err, RR_ERR_INTERNAL, "%s: scene_load_string needs a text and an output", name);
    cJSON *root = NULL;
    rr_status st = sp_parse_text(&c, json, &root);
    if (st != RR_OK)
        return st;
    scene *s = calloc(1, sizeof *s);
    if (!s) {
        cJSON_Delete(root);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory", name);
    }
    snprintf(s->path, sizeof s->path, "%s", name);
    st = build_scene(&c, root, s);
    cJSON_Delete(root);
    if (st != RR_OK) {
        scene_destroy(s);
        return st;
    }
    *out = s;
    return RR_OK;
}

rr_status scene_load(const char *path, const scene_load_opts *opts, scene **out, rr_error *err)
{
    char *text = NULL;
    size_t size = 0;
    rr_status st = rr_file_read_all(path, &text, &size, err);
    if (st != RR_OK)
        return st;
    /* cJSON stops at a NUL; a NUL inside the file would hide the rest of it. */
    size_t len = strlen(text);
    if (len != size) {
        free(text);
        return rr_error_set(err, RR_ERR_PARSE, "%s: the file contains a NUL byte at offset %zu (not a text file?)",
                            path, len);
    }
    char dir[4096];
    rr_path_dirname(path, dir, sizeof dir);
    st = scene_load_string(text, path, dir, opts, out, err);
    free(text);
    return st;
}

void scene_destroy(scene *s)
{
    if (!s)
        return;
    free(s->materials);
    free(s->lights);
    free(s->models);
    free(s->path_keys);
    free(s->objects);
    free(s->verts);
    free(s->normals);
    free(s->tris);
    free(s->csg);
    free(s->csg_verts);
    free(s->csg_tris);
    free(s->emissive_tris);
    free(s);
}

rr_vec3 scene_tri_normal(const scene *s, size_t i)
{
    const scene_tri *t = &s->tris[i];
    rr_vec3 a = s->verts[t->v[0]];
    return rr_v3_norm(rr_v3_cross(rr_v3_sub(s->verts[t->v[1]], a), rr_v3_sub(s->verts[t->v[2]], a)));
}

double scene_tri_area(const scene *s, size_t i)
{
    const scene_tri *t = &s->tris[i];
    rr_vec3 a = s->verts[t->v[0]];
    return 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(s->verts[t->v[1]], a), rr_v3_sub(s->verts[t->v[2]], a)));
}
