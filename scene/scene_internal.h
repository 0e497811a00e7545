/* scene_internal.h - shared by the scene loader's translation units; not a
 * public header (nothing outside scene/ includes it).
 *
 * The loader runs in three stages, one file each:
 *   scene_json.c     text -> cJSON tree (line:column syntax errors), "--set"
 *                    overrides, and the typed getters every stage uses
 *   scene_syntax.c   why and where a text is not JSON (for the message)
 *   scene_parse.c    camera, render settings, materials, lights
 *   scene_xform.c    an object's transform steps
 *   scene_objects.c  objects: shapes, transforms, triangles into the scene
 *   scene_csg.c      solids: "quadric" and "csg" objects into scene->csg
 *   scene_model.c    "model" objects: a whole file through import/ (imp.h)
 *   scene.c          the public API, the top level, and the finishing passes
 *                    (bounding box, emissive triangle list)
 *
 * Every message is "<file>: <json path>: <what is wrong>". The getters take
 * the JSON path of the enclosing value and the key, so that each caller states
 * its path once and every message comes out the same way.
 */
#ifndef SCENE_INTERNAL_H
#define SCENE_INTERNAL_H

#include <cjson/cJSON.h>

#include "scene.h"

/* JSON paths are at most a few keys deep; material names are limited to
 * SCENE_NAME_MAX, so this is room enough (longer paths are cut, never overrun). */
#define SP_PATH_MAX 384

typedef struct sp_ctx {
    const char *file;     /* the scene's name in messages */
    const char *base_dir; /* relative mesh paths resolve against it */
    const scene_load_opts *opts;
    rr_error *err;
} sp_ctx;

typedef enum sp_need { SP_OPTIONAL = 0, SP_REQUIRED = 1 } sp_need;

/* ---- scene_json.c ---- */

/* Parses text into *root (a JSON object or anything else; the caller checks).
 * Syntax errors read "<file>:<line>:<col>: invalid JSON near '...'". */
rr_status sp_parse_text(const sp_ctx *c, const char *text, cJSON **root);

/* scene_syntax.c: NULL when text is valid JSON (RFC 8259), otherwise the
 * culprit character, with the reason in *why. */
const char *sp_json_locate(const char *text, const char **why);

/* Applies opts->overrides to root, in order. */
rr_status sp_apply_overrides(const sp_ctx *c, cJSON *root);

/* Records "<file>: <path>: <message>" (path may be "" for the whole file) in
 * c->err and returns code. */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
rr_status sp_fail(const sp_ctx *c, rr_status code, const char *path, const char *fmt, ...);

/* out = parent.key / parent[i] (out has SP_PATH_MAX bytes; parent may be ""). */
void sp_key(char *out, const char *parent, const char *key);
void sp_idx(char *out, const char *parent, size_t i);

/* "a string", "an array of 2 items", ... for "got ..." in messages. */
const char *sp_describe(const cJSON *v, char *buf, size_t n);

/* Checks that v is a JSON object, that every key is one of allowed
 * (NULL-terminated) and that no key appears twice (cJSON keeps duplicates and
 * would silently use the first). The message for an unknown key lists the
 * allowed ones. */
rr_status sp_check_object(const sp_ctx *c, const cJSON *v, const char *path, const char *const *allowed);

/* Typed getters. With SP_OPTIONAL a missing key leaves *out unchanged (the
 * caller stores the default first); with SP_REQUIRED it is an error that says
 * what was expected. The _item forms validate a value already in hand. */
const cJSON *sp_get(const cJSON *obj, const char *key);
rr_status sp_missing(const sp_ctx *c, const char *path, const char *key, const char *expected);

rr_status sp_number_item(const sp_ctx *c, const cJSON *v, const char *path, double *out);
rr_status sp_number(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                    double *out);
/* A finite number in [lo, hi]. */
rr_status sp_number_range(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                          double lo, double hi, double *out);
/* An integer (no fractional part) in [lo, hi]; lo and hi within +-2^53. */
rr_status sp_int_item(const sp_ctx *c, const cJSON *v, const char *path, double lo, double hi, double *out);
rr_status sp_int(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, double lo,
                 double hi, double *out);
rr_status sp_bool(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, int *out);
/* A string of at most out_size - 1 bytes; empty strings are refused when
 * nonempty is set. */
rr_status sp_string(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                    int nonempty, char *out, size_t out_size);
rr_status sp_vec3_item(const sp_ctx *c, const cJSON *v, const char *path, rr_vec3 *out);
rr_status sp_vec3(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need,
                  rr_vec3 *out);
/* A colour: a number (grey) or [r, g, b], each channel in [lo, hi]. */
rr_status sp_color(const sp_ctx *c, const cJSON *obj, const char *path, const char *key, sp_need need, double lo,
                   double hi, rr_rgb *out);
/* An array of exactly n items (n = 0: any length >= 1). */
rr_status sp_array(const sp_ctx *c, const cJSON *v, const char *path, int n, const char *expected);

/* ---- scene_parse.c ---- */

rr_status sp_parse_camera(const sp_ctx *c, const cJSON *root, scene *s);
/* scene_path.c: "camera_path" (after the camera). */
rr_status sp_parse_camera_path(const sp_ctx *c, const cJSON *root, scene *s);
rr_status sp_parse_render(const sp_ctx *c, const cJSON *root, scene *s);
rr_status sp_parse_radiosity(const sp_ctx *c, const cJSON *root, scene *s);
rr_status sp_parse_materials(const sp_ctx *c, const cJSON *root, scene *s);
/* One material object at path into *m (its name is the caller's). */
rr_status sp_parse_material(const sp_ctx *c, const cJSON *v, const char *path, scene_material *m);
rr_status sp_parse_lights(const sp_ctx *c, const cJSON *root, scene *s);

/* ---- scene_xform.c ---- */

/* Composes obj's "transform" (steps applied in order: the first step acts on
 * the object first) into *out, checked finite and non-singular. *has is 0
 * (and *out the identity) when the object has none. */
rr_status sp_parse_transform(const sp_ctx *c, const cJSON *obj, const char *opath, rr_xform *out, int *has);

/* ---- scene_objects.c ---- */

/* Capacities of the scene arrays that grow while objects are parsed. */
typedef struct sp_build {
    size_t cap_objects;                 /* s->objects */
    size_t cap_verts, cap_tris;         /* s->verts (and s->normals), s->tris */
    size_t cap_csg;                     /* s->csg */
    size_t cap_csg_verts, cap_csg_tris; /* s->csg_verts, s->csg_tris */
} sp_build;

/* Fills s->objects, s->verts, s->normals and s->tris (and, through
 * sp_parse_solid, s->csg, s->csg_verts, s->csg_tris). Needs s->materials. */
rr_status sp_parse_objects(const sp_ctx *c, const cJSON *root, scene *s);

/* Appends a zeroed object (model SCENE_NONE) to s->objects; *oi its index.
 * Pointers into s->objects are invalid afterwards. */
rr_status sp_new_object(const sp_ctx *c, scene *s, sp_build *b, const char *opath, size_t *oi);

/* obj's "cull": -1 auto (also when absent), 0 off, 1 on. */
rr_status sp_parse_cull(const sp_ctx *c, const cJSON *obj, const char *opath, int *cull);

/* The "auto" culling rule (notes/scene-format.md, "Back-face culling"):
 * closed and not a mirror. first_node: the object's first CSG node. */
int sp_cull_auto(const scene *s, size_t oi, size_t first_node);

/* Object oi (material and name set) gets m's triangles, through the same
 * path as a "mesh" object: transformed by x (in place: m's arrays change),
 * analysed, zero-area triangles dropped with a warning. */
rr_status sp_add_mesh_object(const sp_ctx *c, scene *s, sp_build *b, size_t oi, const char *opath,
                             const rr_xform *x, int has_x, mesh_tri *m);

/* obj's required "material" (a name from s->materials) into *out. */
rr_status sp_find_material(const sp_ctx *c, const cJSON *obj, const char *opath, const scene *s, uint32_t *out);

/* Twice the area below 1e-12 of the longest edge squared: no usable normal. */
int sp_tri_degenerate(rr_vec3 a, rr_vec3 b, rr_vec3 c);

/* The "mesh" object's path for obj's "file" (relative to c->base_dir):
 * loads it, applies x (when has_x) with the winding reversed when x mirrors
 * XOR flip, and hands back the mesh (the caller frees it with mesh_destroy).
 * source (4096 bytes) receives the resolved path. Degenerate triangles are
 * kept; nothing is analysed. */
rr_status sp_load_mesh(const sp_ctx *c, const cJSON *obj, const char *opath, const rr_xform *x, int has_x, int flip,
                       char *source, mesh_tri **out);

/* ---- scene_model.c ---- */

/* A "model" object at objects[ji] (opath): imports its file and appends its
 * objects, materials and lights, and a scene_model. */
rr_status sp_parse_model(const sp_ctx *c, const cJSON *obj, const char *opath, size_t ji, scene *s, sp_build *b);

/* ---- scene_csg.c ---- */

/* Deepest root-to-leaf path of a stored CSG tree, in nodes (a lone leaf is 1
 * deep). n-ary children fold left into a chain, so a node with n children
 * adds n - 1 levels. Bounds the ray tracer's recursion and span stacks. */
#define SP_CSG_DEPTH_MAX 32

/* Checks the keys of a solid (a "quadric" or "csg" object, or any CSG child
 * when top is 0: then "name" and "cull" are refused, "material" optional). */
rr_status sp_solid_check_keys(const sp_ctx *c, const cJSON *obj, const char *path, int top);

/* Builds object oi (a "quadric" or "csg"; keys checked, its material, name,
 * cull and transform x already parsed into s->objects[oi]) into s->csg and
 * sets its csg_root, and its report to closed (a solid is closed by
 * construction). */
rr_status sp_parse_solid(const sp_ctx *c, const cJSON *obj, const char *opath, size_t oi, const rr_xform *x,
                         scene *s, sp_build *b);

#endif
