/* scene_parse.c - the scene's non-geometric parts: camera, render settings,
 * materials, lights. Each parser checks its keys against a fixed list first,
 * so that a misspelt key is reported as such instead of being ignored and
 * silently replaced by a default. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#include <unistd.h>

#include "scene_internal.h"

/* ---- camera ---- */

static const char *const k_cam_lecture[] = {"type", "E", "O", "U", "s", "w", "h", NULL};
static const char *const k_cam_lookat[] = {"type", "eye", "target", "up", "fov", "width", "height", NULL};

/* The film budget when the caller sets none: half the physical memory, since
 * the renderer needs the other half for the scene, its acceleration structure
 * and the rest of the system. */
static size_t default_film_limit(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || psize <= 0)
        return SIZE_MAX; /* unknown: let the allocation itself decide */
    double half = (double)pages * (double)psize / 2.0;
    return half >= (double)SIZE_MAX ? SIZE_MAX : (size_t)half;
}

/* A render holds the beauty image and up to 7 same-sized layers (AOVs), so
 * the film needs 8 images' worth of memory. Refusing here, at load, beats
 * failing (or swapping) after the scene and its acceleration structure are
 * built. */
static rr_status check_film(const sp_ctx *c, long width, long height)
{
    size_t one = rr_image_bytes(width, height);
    size_t need = (one == 0 || one > SIZE_MAX / 8) ? 0 : one * 8;
    size_t limit = c->opts && c->opts->max_image_bytes ? c->opts->max_image_bytes : default_film_limit();
    if (need != 0 && need <= limit)
        return RR_OK;
    char a[32], b[32];
    return sp_fail(c, RR_ERR_LIMIT, "camera", "a %ld x %ld image needs %s of film, over the limit of %s", width, height,
                   rr_size_text(8.0 * 3.0 * sizeof(float) * (double)width * (double)height, a, sizeof a),
                   rr_size_text((double)limit, b, sizeof b));
}

/* rr_view's messages start with "view: "; in a scene the place is "camera". */
static rr_status view_fail(const sp_ctx *c, rr_status st)
{
    char msg[RR_ERROR_MSG_MAX];
    const char *m = c->err ? c->err->msg : "";
    if (strncmp(m, "view: ", 6) == 0)
        m += 6;
    snprintf(msg, sizeof msg, "%s", m);
    return sp_fail(c, st, "camera", "%s", msg);
}

static rr_status parse_lecture(const sp_ctx *c, const cJSON *cam, scene *s)
{
    rr_vec3 E, O, U;
    double pix = 0, w = 0, h = 0;
    rr_status st;
    if ((st = sp_vec3(c, cam, "camera", "E", SP_REQUIRED, &E)) != RR_OK ||
        (st = sp_vec3(c, cam, "camera", "O", SP_REQUIRED, &O)) != RR_OK ||
        (st = sp_vec3(c, cam, "camera", "U", SP_REQUIRED, &U)) != RR_OK ||
        (st = sp_number(c, cam, "camera", "s", SP_REQUIRED, &pix)) != RR_OK ||
        (st = sp_int(c, cam, "camera", "w", SP_REQUIRED, 0, (INT_MAX - 1) / 2, &w)) != RR_OK ||
        (st = sp_int(c, cam, "camera", "h", SP_REQUIRED, 0, (INT_MAX - 1) / 2, &h)) != RR_OK)
        return st;
    if (!(pix > 0))
        return sp_fail(c, RR_ERR_INVALID, "camera.s", "the pixel scale must be > 0 (got %g)", pix);
    if ((st = check_film(c, 2 * (long)w + 1, 2 * (long)h + 1)) != RR_OK)
        return st;
    st = rr_view_lecture(E, O, U, pix, (int)w, (int)h, &s->view, c->err);
    return st == RR_OK ? RR_OK : view_fail(c, st);
}

static rr_status parse_lookat(const sp_ctx *c, const cJSON *cam, scene *s)
{
    rr_vec3 eye, target, up;
    double fov = 0, width = 0, height = 0;
    rr_status st;
    if ((st = sp_vec3(c, cam, "camera", "eye", SP_REQUIRED, &eye)) != RR_OK ||
        (st = sp_vec3(c, cam, "camera", "target", SP_REQUIRED, &target)) != RR_OK ||
        (st = sp_vec3(c, cam, "camera", "up", SP_REQUIRED, &up)) != RR_OK ||
        (st = sp_number(c, cam, "camera", "fov", SP_REQUIRED, &fov)) != RR_OK ||
        (st = sp_int(c, cam, "camera", "width", SP_REQUIRED, 1, INT_MAX, &width)) != RR_OK ||
        (st = sp_int(c, cam, "camera", "height", SP_REQUIRED, 1, INT_MAX, &height)) != RR_OK)
        return st;
    if (!(fov > 0 && fov < 180))
        return sp_fail(c, RR_ERR_INVALID, "camera.fov", "must be in (0, 180) degrees (got %g)", fov);
    if ((st = check_film(c, (long)width, (long)height)) != RR_OK)
        return st;
    st = rr_view_lookat(eye, target, up, fov, (int)width, (int)height, &s->view, c->err);
    if (st != RR_OK)
        return view_fail(c, st);
    s->camera.lookat = 1;
    s->camera.eye = eye;
    s->camera.target = target;
    s->camera.up = up;
    s->camera.fov = fov;
    return RR_OK;
}

rr_status sp_parse_camera(const sp_ctx *c, const cJSON *root, scene *s)
{
    const cJSON *cam = sp_get(root, "camera");
    char got[96];
    if (!cam)
        return sp_missing(c, "", "camera", "an object with \"type\": \"lecture\" or \"lookat\"");
    if (!cJSON_IsObject(cam))
        return sp_fail(c, RR_ERR_INVALID, "camera", "expected an object (got %s)", sp_describe(cam, got, sizeof got));
    const cJSON *type = sp_get(cam, "type");
    if (!type)
        return sp_missing(c, "camera", "type", "\"lecture\" or \"lookat\"");
    if (cJSON_IsString(type) && strcmp(type->valuestring, "lecture") == 0) {
        rr_status st = sp_check_object(c, cam, "camera", k_cam_lecture);
        return st != RR_OK ? st : parse_lecture(c, cam, s);
    }
    if (cJSON_IsString(type) && strcmp(type->valuestring, "lookat") == 0) {
        rr_status st = sp_check_object(c, cam, "camera", k_cam_lookat);
        return st != RR_OK ? st : parse_lookat(c, cam, s);
    }
    return sp_fail(c, RR_ERR_INVALID, "camera.type", "expected \"lecture\" or \"lookat\" (got %s)",
                   sp_describe(type, got, sizeof got));
}

/* ---- render settings ---- */

/* Integer settings, table-driven: one row states key, range and default. The
 * limits keep values sane for the renderer: max_depth bounds a recursion,
 * threads and light_samples multiply work per pixel. */
typedef enum { RI_INT, RI_U64 } ri_kind;
typedef struct render_int {
    const char *key;
    double lo, hi, def;
    ri_kind kind;
    size_t offset;
} render_int;

static const render_int k_render_ints[] = {
    {"spp", 1, 1 << 24, 1, RI_INT, offsetof(scene_settings, spp)},
    {"seed", 0, 9007199254740992.0, 0, RI_U64, offsetof(scene_settings, seed)},
    {"max_depth", 0, 1000, 5, RI_INT, offsetof(scene_settings, max_depth)},
    {"threads", 0, 4096, 0, RI_INT, offsetof(scene_settings, threads)},
    {"light_samples", 1, 1 << 16, 16, RI_INT, offsetof(scene_settings, light_samples)},
};

static const char *const k_render[] = {"spp",        "seed",       "max_depth", "threads", "exposure",
                                       "background", "ambient",    "light_samples", "half_float", NULL};

rr_status sp_parse_render(const sp_ctx *c, const cJSON *root, scene *s)
{
    scene_settings *set = &s->settings;
    memset(set, 0, sizeof *set);
    for (size_t i = 0; i < sizeof k_render_ints / sizeof k_render_ints[0]; i++) {
        const render_int *ri = &k_render_ints[i];
        char *field = (char *)set + ri->offset;
        if (ri->kind == RI_INT)
            *(int *)field = (int)ri->def;
        else
            *(uint64_t *)field = (uint64_t)ri->def;
    }
    const cJSON *r = sp_get(root, "render");
    if (!r)
        return RR_OK;
    rr_status st = sp_check_object(c, r, "render", k_render);
    if (st != RR_OK)
        return st;
    for (size_t i = 0; i < sizeof k_render_ints / sizeof k_render_ints[0]; i++) {
        const render_int *ri = &k_render_ints[i];
        double v = ri->def;
        if ((st = sp_int(c, r, "render", ri->key, SP_OPTIONAL, ri->lo, ri->hi, &v)) != RR_OK)
            return st;
        char *field = (char *)set + ri->offset;
        if (ri->kind == RI_INT)
            *(int *)field = (int)v;
        else
            *(uint64_t *)field = (uint64_t)v;
    }
    if ((st = sp_number(c, r, "render", "exposure", SP_OPTIONAL, &set->exposure)) != RR_OK ||
        (st = sp_color(c, r, "render", "background", SP_OPTIONAL, 0, INFINITY, &set->background)) != RR_OK ||
        (st = sp_color(c, r, "render", "ambient", SP_OPTIONAL, 0, INFINITY, &set->ambient)) != RR_OK ||
        (st = sp_bool(c, r, "render", "half_float", SP_OPTIONAL, &set->half_float)) != RR_OK)
        return st;
    return RR_OK;
}

/* ---- radiosity settings ---- */

static const char *const k_radiosity[] = {"patch_area", "patch_edge", "solver", "form_factors",
                                          "ff_samples", "tolerance",  "method",
                                          "refine_tolerance", "min_area", "max_links", "relative_tolerance",
                                          "receiving_clusters", NULL};

/* Looks a string value up in names (NULL-terminated); missing keeps *out. */
static rr_status parse_choice(const sp_ctx *c, const cJSON *obj, const char *path, const char *key,
                              const char *const *names, int *out)
{
    char val[32], where[SP_PATH_MAX];
    if (!sp_get(obj, key))
        return RR_OK;
    rr_status st = sp_string(c, obj, path, key, SP_REQUIRED, 1, val, sizeof val);
    if (st != RR_OK)
        return st;
    for (int i = 0; names[i]; i++)
        if (!strcmp(val, names[i])) {
            *out = i;
            return RR_OK;
        }
    sp_key(where, path, key);
    char list[128] = "";
    for (int i = 0; names[i]; i++) {
        strncat(list, i ? ", " : "", sizeof list - strlen(list) - 1);
        strncat(list, names[i], sizeof list - strlen(list) - 1);
    }
    return sp_fail(c, RR_ERR_INVALID, where, "expected one of %s (got \"%s\")", list, val);
}

rr_status sp_parse_radiosity(const sp_ctx *c, const cJSON *root, scene *s)
{
    scene_radiosity *r = &s->radiosity;
    memset(r, 0, sizeof *r);
    r->ff_samples = 512;
    r->tolerance = 0.0; /* the method's default (rad.h) */
    r->method = SCENE_RAD_DEFAULT_METHOD;
    r->refine_tolerance = 1.5e-5;
    r->max_links = 100e6;
    const cJSON *v = sp_get(root, "radiosity");
    if (!v)
        return RR_OK;
    static const char *const solvers[] = {"auto", "direct", "iterative", NULL};
    static const char *const ffs[] = {"montecarlo", "quadrature", NULL};
    static const char *const methods[] = {"hierarchical", "flat", NULL};
    int solver = 0, ff = 0, method = (int)r->method;
    double samples = r->ff_samples;
    rr_status st;
    if ((st = sp_check_object(c, v, "radiosity", k_radiosity)) != RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "patch_area", SP_OPTIONAL, 1e-300, INFINITY, &r->patch_area)) !=
            RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "patch_edge", SP_OPTIONAL, 1e-300, INFINITY, &r->patch_edge)) !=
            RR_OK ||
        (st = parse_choice(c, v, "radiosity", "solver", solvers, &solver)) != RR_OK ||
        (st = parse_choice(c, v, "radiosity", "form_factors", ffs, &ff)) != RR_OK ||
        (st = sp_int(c, v, "radiosity", "ff_samples", SP_OPTIONAL, 1, 1 << 20, &samples)) != RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "tolerance", SP_OPTIONAL, 1e-15, 0.1, &r->tolerance)) != RR_OK ||
        (st = parse_choice(c, v, "radiosity", "method", methods, &method)) != RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "refine_tolerance", SP_OPTIONAL, 1e-12, 1.0, &r->refine_tolerance)) !=
            RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "min_area", SP_OPTIONAL, 1e-300, INFINITY, &r->min_area)) != RR_OK ||
        (st = sp_int(c, v, "radiosity", "max_links", SP_OPTIONAL, 1000, 4e9, &r->max_links)) != RR_OK ||
        (st = sp_number_range(c, v, "radiosity", "relative_tolerance", SP_OPTIONAL, 0.0, 1.0,
                              &r->relative_tolerance)) != RR_OK)
        return st;
    double rc = -1.0; /* absent: automatic (0 in the settings) */
    if ((st = sp_number_range(c, v, "radiosity", "receiving_clusters", SP_OPTIONAL, 0.0, 1e3, &rc)) != RR_OK)
        return st;
    r->receiving_clusters = rc < 0 ? 0.0 : rc > 0 ? rc : -1.0;
    r->method = (scene_rad_method)method;
    r->solver = (scene_rad_solver)solver;
    r->form_factors = (scene_rad_ff)ff;
    r->ff_samples = (int)samples;
    return RR_OK;
}

/* ---- materials ---- */

static const char *const k_material[] = {"diffuse", "ambient", "specular", "k", "mirror", "emission", NULL};

rr_status sp_parse_material(const sp_ctx *c, const cJSON *v, const char *path, scene_material *m)
{
    rr_status st = sp_check_object(c, v, path, k_material);
    if (st != RR_OK)
        return st;
    /* Defaults: a mid-grey Lambertian surface and nothing else, so that a
     * material written as {} is visible under any light and neither shines
     * nor reflects. */
    m->diffuse = rr_rgb_make(0.5, 0.5, 0.5);
    m->ambient = 0.0;
    m->specular = rr_rgb_make(0, 0, 0);
    m->k = 1.0;
    m->mirror = rr_rgb_make(0, 0, 0);
    m->emission = rr_rgb_make(0, 0, 0);
    m->model = SCENE_NONE;
    m->notes = 0;
    if ((st = sp_color(c, v, path, "diffuse", SP_OPTIONAL, 0, 1, &m->diffuse)) != RR_OK ||
        (st = sp_number_range(c, v, path, "ambient", SP_OPTIONAL, 0, INFINITY, &m->ambient)) != RR_OK ||
        (st = sp_color(c, v, path, "specular", SP_OPTIONAL, 0, INFINITY, &m->specular)) != RR_OK ||
        (st = sp_number_range(c, v, path, "k", SP_OPTIONAL, 0, INFINITY, &m->k)) != RR_OK ||
        (st = sp_color(c, v, path, "mirror", SP_OPTIONAL, 0, 1, &m->mirror)) != RR_OK ||
        (st = sp_color(c, v, path, "emission", SP_OPTIONAL, 0, INFINITY, &m->emission)) != RR_OK)
        return st;
    /* A mirror written without a diffuse part is a pure mirror (the grey
     * default would make it reflect more than it receives). */
    if (!sp_get(v, "diffuse") && rr_rgb_max(m->mirror) > 0.0)
        m->diffuse = rr_rgb_make(0, 0, 0);
    /* What a surface reflects, diffusely and as a mirror, cannot be more than
     * it receives (the passes would create light). */
    static const char ch[3] = {'R', 'G', 'B'};
    double d[3] = {m->diffuse.r, m->diffuse.g, m->diffuse.b}, r[3] = {m->mirror.r, m->mirror.g, m->mirror.b};
    for (int k = 0; k < 3; k++)
        if (d[k] + r[k] > 1.0 + 1e-12)
            return sp_fail(c, RR_ERR_INVALID, path,
                           "diffuse + mirror reflectance is %g in channel %c: a surface cannot reflect more than it "
                           "receives (at most 1)",
                           d[k] + r[k], ch[k]);
    return RR_OK;
}

rr_status sp_parse_materials(const sp_ctx *c, const cJSON *root, scene *s)
{
    const cJSON *mats = sp_get(root, "materials");
    char got[96];
    if (!mats) /* a scene of imported models brings its own */
        return RR_OK;
    if (!cJSON_IsObject(mats))
        return sp_fail(c, RR_ERR_INVALID, "materials", "expected an object mapping names to materials (got %s)",
                       sp_describe(mats, got, sizeof got));
    size_t n = (size_t)cJSON_GetArraySize(mats);
    if (n == 0)
        return RR_OK;
    s->materials = calloc(n, sizeof *s->materials);
    if (!s->materials)
        return sp_fail(c, RR_ERR_NOMEM, "materials", "out of memory");
    for (const cJSON *it = mats->child; it; it = it->next) {
        size_t i = s->nmaterials;
        char path[SP_PATH_MAX];
        sp_key(path, "materials", it->string);
        size_t len = strlen(it->string);
        if (len == 0)
            return sp_fail(c, RR_ERR_INVALID, "materials", "a material name is empty");
        if (len >= SCENE_NAME_MAX)
            return sp_fail(c, RR_ERR_INVALID, path, "the material name is too long (%zu bytes, at most %d)", len,
                           SCENE_NAME_MAX - 1);
        for (size_t j = 0; j < i; j++)
            if (strcmp(s->materials[j].name, it->string) == 0)
                return sp_fail(c, RR_ERR_INVALID, path, "material '%s' is defined twice", it->string);
        memcpy(s->materials[i].name, it->string, len + 1);
        rr_status st = sp_parse_material(c, it, path, &s->materials[i]);
        if (st != RR_OK)
            return st;
        s->nmaterials++;
    }
    return RR_OK;
}

/* ---- lights ---- */

static const char *const k_light_dir[] = {"type", "name", "direction", "intensity", NULL};
static const char *const k_light_point[] = {"type", "name", "position", "intensity", NULL};

static rr_status parse_light(const sp_ctx *c, const cJSON *v, const char *path, size_t index, scene_light *l)
{
    char got[96];
    if (!cJSON_IsObject(v))
        return sp_fail(c, RR_ERR_INVALID, path, "expected an object (got %s)", sp_describe(v, got, sizeof got));
    const cJSON *type = sp_get(v, "type");
    if (!type)
        return sp_missing(c, path, "type", "\"directional\" or \"point\"");
    rr_status st;
    if (cJSON_IsString(type) && strcmp(type->valuestring, "directional") == 0) {
        l->type = SCENE_LIGHT_DIRECTIONAL;
        if ((st = sp_check_object(c, v, path, k_light_dir)) != RR_OK ||
            (st = sp_vec3(c, v, path, "direction", SP_REQUIRED, &l->direction)) != RR_OK)
            return st;
        l->direction = rr_v3_unit(l->direction); /* scaled first: no overflow to a dead (0, 0, 0) light */
        if (!(rr_v3_len(l->direction) > 0)) {
            char p[SP_PATH_MAX];
            sp_key(p, path, "direction");
            return sp_fail(c, RR_ERR_INVALID, p, "the direction is the zero vector");
        }
    } else if (cJSON_IsString(type) && strcmp(type->valuestring, "point") == 0) {
        l->type = SCENE_LIGHT_POINT;
        if ((st = sp_check_object(c, v, path, k_light_point)) != RR_OK ||
            (st = sp_vec3(c, v, path, "position", SP_REQUIRED, &l->position)) != RR_OK)
            return st;
    } else {
        char p[SP_PATH_MAX];
        sp_key(p, path, "type");
        return sp_fail(c, RR_ERR_INVALID, p, "expected \"directional\" or \"point\" (got %s); area lights are "
                       "objects with an emitting material", sp_describe(type, got, sizeof got));
    }
    snprintf(l->name, sizeof l->name, "lights[%zu]", index);
    if ((st = sp_string(c, v, path, "name", SP_OPTIONAL, 1, l->name, sizeof l->name)) != RR_OK ||
        (st = sp_color(c, v, path, "intensity", SP_REQUIRED, 0, INFINITY, &l->intensity)) != RR_OK)
        return st;
    return RR_OK;
}

rr_status sp_parse_lights(const sp_ctx *c, const cJSON *root, scene *s)
{
    const cJSON *lights = sp_get(root, "lights");
    char got[96];
    if (!lights)
        return RR_OK;
    if (!cJSON_IsArray(lights))
        return sp_fail(c, RR_ERR_INVALID, "lights", "expected an array of lights (got %s)",
                       sp_describe(lights, got, sizeof got));
    size_t n = (size_t)cJSON_GetArraySize(lights);
    if (n == 0)
        return RR_OK;
    s->lights = calloc(n, sizeof *s->lights);
    if (!s->lights)
        return sp_fail(c, RR_ERR_NOMEM, "lights", "out of memory");
    size_t i = 0;
    for (const cJSON *it = lights->child; it; it = it->next, i++) {
        char path[SP_PATH_MAX];
        sp_idx(path, "lights", i);
        rr_status st = parse_light(c, it, path, i, &s->lights[i]);
        if (st != RR_OK)
            return st;
        s->nlights++;
    }
    return RR_OK;
}
