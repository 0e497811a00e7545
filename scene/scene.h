/* scene.h - radray scene files ("format": "radray-scene/1", JSON through cJSON)
 * and the in-memory scene every pass reads.
 *
 * The format is documented in notes/scene-format.md. Loading validates
 * everything: unknown keys, wrong types, missing values, non-finite numbers,
 * bad references and unreadable meshes are errors whose one-line message names
 * the file, the JSON path (e.g. "objects[3].material") and what was expected.
 * Zero-area triangles are dropped with a warning through opts->warn.
 *
 * After scene_load returns, the scene is immutable: every thread may read it.
 * Ownership: scene_load allocates *out; scene_destroy frees it (NULL is a no-op).
 * On failure *out is untouched.
 */
#ifndef SCENE_H
#define SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "imp.h"
#include "mesh.h"
#include "rr_core.h"

#define SCENE_FORMAT "radray-scene/1"
#define SCENE_NAME_MAX 64
#define SCENE_NONE UINT32_MAX /* "no model": scene_material.model, scene_object.model */

typedef struct scene_material {
    char name[SCENE_NAME_MAX];
    rr_rgb diffuse;   /* the lecture's d: Lambertian reflectance rho, each channel in [0, 1] */
    double ambient;   /* the lecture's a: weight of the ambient light A */
    rr_rgb specular;  /* the lecture's s: Phong weight, RGB */
    double k;         /* the lecture's k: Phong exponent, >= 0 */
    rr_rgb mirror;    /* mirror reflectance, each channel in [0, 1] */
    rr_rgb emission;  /* emitted radiance; non-zero makes every surface using it an area light */
    uint32_t model;   /* imported by scene->models[model], or SCENE_NONE (from "materials") */
    unsigned notes;   /* imported: what the mapping approximated or dropped (IMP_NOTE_* bits, imp.h) */
    int overridden;   /* imported, then replaced by the model object's "materials" entry */
} scene_material;

typedef enum scene_light_type { SCENE_LIGHT_DIRECTIONAL = 0, SCENE_LIGHT_POINT = 1 } scene_light_type;

typedef struct scene_light {
    char name[SCENE_NAME_MAX];
    scene_light_type type;
    rr_vec3 direction; /* directional: unit vector from the scene TOWARDS the light (the lecture's L) */
    rr_vec3 position;  /* point */
    rr_rgb intensity;  /* directional: irradiance on a surface facing the light; point: radiant intensity
                          (irradiance at distance 1, falls off with 1/r^2) */
} scene_light;

typedef enum scene_object_kind {
    SCENE_OBJ_MESH = 0,      /* triangles from a mesh file */
    SCENE_OBJ_TRIANGLES = 1, /* inline vertices + indices */
    SCENE_OBJ_QUAD = 2,      /* four vertices, split (v0,v1,v2), (v0,v2,v3) */
    SCENE_OBJ_BOX = 3,       /* axis-aligned box before its transform, 12 outward-facing triangles */
    SCENE_OBJ_SPHERE = 4,    /* analytic sphere (not tessellated) */
    SCENE_OBJ_CSG = 5        /* a solid: a CSG tree ("csg") or one quadric ("quadric"); see scene_csg_node */
} scene_object_kind;
/* A "model" object (a whole file imported, notes/import.md) is no kind of its
 * own: it becomes one SCENE_OBJ_MESH object per mesh of the file (its
 * materials and lights join the scene's), and a scene_model record. */

/* ---- solids: CSG trees over spheres, quadrics, boxes and closed meshes ----
 *
 * Every "csg" object and every standalone "quadric" object is a tree of
 * scene_csg_node in scene->csg (a quadric object is a tree of one leaf).
 * Transforms of inner nodes are already composed into their leaves, so a leaf
 * holds its whole local-to-world map; inner nodes only combine.
 *
 * A leaf is a closed solid, described in its local frame:
 *   SPHERE   |x - center|^2 <= radius^2 (center, radius: local)
 *   QUADRIC  x^T Q x <= 0 with x = (p, 1) and p inside the clip box
 *            [clip_lo, clip_hi] (named shapes are turned into Q + box by the
 *            loader; the box is always finite)
 *   BOX      p in [clip_lo, clip_hi]
 *   MESH     the inside of a watertight, consistently and outward oriented
 *            triangle mesh: triangles csg_tris[tri_first .. +tri_count),
 *            vertices in csg_verts, both already in WORLD space (to_world and
 *            to_local are then the identity)
 */
typedef enum scene_csg_op {
    SCENE_CSG_LEAF = 0,
    SCENE_CSG_UNION = 1,
    SCENE_CSG_INTERSECTION = 2,
    SCENE_CSG_DIFFERENCE = 3 /* left minus right */
} scene_csg_op;

typedef enum scene_solid_kind {
    SCENE_SOLID_SPHERE = 0,
    SCENE_SOLID_QUADRIC = 1,
    SCENE_SOLID_BOX = 2,
    SCENE_SOLID_MESH = 3
} scene_solid_kind;

/* What a quadric leaf was written as (for messages, tessellation and tests). */
typedef enum scene_quadric_shape {
    SCENE_QUADRIC_GENERAL = 0,
    SCENE_QUADRIC_ELLIPSOID = 1,
    SCENE_QUADRIC_CYLINDER = 2,
    SCENE_QUADRIC_CONE = 3,
    SCENE_QUADRIC_PARABOLOID = 4,
    SCENE_QUADRIC_HYPERBOLOID = 5
} scene_quadric_shape;

typedef struct scene_csg_node {
    scene_csg_op op;
    uint32_t object;           /* the scene object whose tree this node belongs to */
    uint32_t left, right;      /* inner nodes: children, indices into scene->csg */
    rr_vec3 bbox_lo, bbox_hi;  /* world bounds, pruned by the op (intersection: the overlap;
                                  difference: the left child's); may be empty (lo > hi) */
    /* leaves only: */
    scene_solid_kind solid;
    scene_quadric_shape shape; /* quadric leaves */
    uint32_t material;         /* the material of this leaf's surface */
    rr_xform to_world, to_local; /* local <-> world (affine, inverse of each other) */
    rr_vec3 center;            /* sphere, local */
    double radius;
    double q[4][4];            /* quadric, local, symmetric */
    rr_vec3 clip_lo, clip_hi;  /* quadric clip box / box, local */
    size_t tri_first, tri_count; /* mesh: range in scene->csg_tris */
    char name[SCENE_NAME_MAX]; /* JSON path of the node, e.g. "objects[2].children[1]" */
} scene_csg_node;

typedef struct scene_object {
    char name[SCENE_NAME_MAX]; /* from the file, or "objects[i]" */
    scene_object_kind kind;
    uint32_t material;         /* index into scene->materials */
    int cull_backfaces;        /* resolved from "cull": see notes/scene-format.md */
    size_t tri_first, tri_count; /* range in scene->tris (0, 0 for spheres) */
    rr_vec3 center;            /* spheres: world-space centre and radius */
    double radius;
    uint32_t csg_root;         /* solids (SCENE_OBJ_CSG): root node in scene->csg */
    char source[4096];         /* meshes and imported meshes: the resolved file path; "" otherwise */
    uint32_t model;            /* imported by scene->models[model], or SCENE_NONE */
    mesh_report report;        /* topology of this object's triangles (meshes, boxes, quads, triangles) */
    size_t dropped_degenerate; /* zero-area triangles dropped at load */
} scene_object;

typedef struct scene_tri {
    uint32_t v[3];    /* indices into scene->verts; counter-clockwise seen from the front */
    uint32_t object;  /* index into scene->objects */
    uint32_t material;
} scene_tri;

/* One "model" object: the file and what came from it. */
typedef struct scene_model {
    char name[SCENE_NAME_MAX];  /* the object's "name" (default: the file name without extension) */
    char source[4096];          /* resolved path */
    char format[16];            /* "gltf", "glb", "obj", "fbx", ... */
    size_t object_first, object_count;     /* its objects in scene->objects */
    size_t material_first, material_count; /* its materials in scene->materials (0 with "material") */
    size_t light_first, light_count;       /* its lights in scene->lights */
    size_t triangles;           /* as imported (zero-area ones included) */
    size_t dropped_prims, dropped_lights, dropped_cameras; /* what radray does not render (points, lines,
                                   spot lights, the file's cameras) */
} scene_model;

typedef struct scene_settings {
    int spp;                /* samples per pixel, >= 1 (default 1) */
    uint64_t seed;          /* default 0 */
    int max_depth;          /* the most mirror reflections on any path, in every mode and pass (camera,
                               mirror, BSDF, secondary and form-factor rays, the lights' mirror images),
                               >= 0 (default 5); diffuse bounces are not bounded by it */
    int threads;            /* 0 = all cores (default) */
    double exposure;        /* PNG preview exposure in stops (default 0) */
    rr_rgb background;      /* radiance of rays that hit nothing (default black) */
    rr_rgb ambient;         /* the lecture's ambient light A (default 0) */
    int light_samples;      /* shadow rays per area light per hit (default 16) */
    int half_float;         /* EXR pixel type: 0 float (default), 1 half */
} scene_settings;

/* The radiosity pass ("radiosity" block; notes/scene-format.md). */
typedef enum scene_rad_solver { SCENE_RAD_AUTO = 0, SCENE_RAD_DIRECT = 1, SCENE_RAD_ITERATIVE = 2 } scene_rad_solver;
typedef enum scene_rad_ff { SCENE_FF_MONTE_CARLO = 0, SCENE_FF_QUADRATURE = 1 } scene_rad_ff;
typedef enum scene_rad_method { SCENE_RAD_HIERARCHICAL = 0, SCENE_RAD_FLAT = 1 } scene_rad_method;
#define SCENE_RAD_DEFAULT_METHOD SCENE_RAD_HIERARCHICAL

typedef struct scene_radiosity {
    double patch_area;      /* largest patch area; 0 = automatic (surface area / 2000) */
    double patch_edge;      /* longest patch edge; 0 = automatic (2 sqrt(patch_area)) */
    scene_rad_solver solver; /* default auto */
    scene_rad_ff form_factors; /* default Monte Carlo */
    int ff_samples;         /* rays (Monte Carlo) or points (quadrature) per patch, default 512 */
    double tolerance;       /* the solver's stop: 0 unless set, then the method's default (rad.h:
                             * RAD_FLAT_TOLERANCE, RAD_HIER_TOLERANCE) */
    scene_rad_method method; /* hierarchical or flat (SCENE_RAD_DEFAULT_METHOD) */
    double refine_tolerance; /* hierarchical: link error over emitted power, default 1.5e-5 */
    double min_area;        /* hierarchical: smallest element; 0 = automatic */
    double relative_tolerance; /* hierarchical: receiver splits also at this share of the receiver's own power; 0 = off */
    double max_links;       /* hierarchical: links at most, default 1e8 */
    double receiving_clusters; /* hierarchical: clusters of roots too small to split, of radius up to this
                                * times sqrt(min_area), receive as one; 0 = automatic (on, at 1, where the
                                * links would not fit otherwise), < 0 = never (the file's 0) */
} scene_radiosity;

/* The camera as the file gave it (view is always the lecture's form). */
typedef struct scene_camera {
    int lookat;             /* 1: "type": "lookat" (eye, target, up, fov below); 0: "lecture" */
    rr_vec3 eye, target, up;
    double fov;             /* degrees, vertical */
} scene_camera;

/* A key frame of "camera_path" (a walkthrough). */
typedef struct scene_key {
    double frame;           /* 1..path_frames, increasing over the keys */
    rr_vec3 eye, target;
    double fov;             /* degrees, vertical */
} scene_key;

typedef struct scene {
    char path[4096];        /* the file it was loaded from ("<string>" names for in-memory) */
    char name[SCENE_NAME_MAX];
    rr_view view;
    scene_camera camera;
    scene_key *path_keys;   /* "camera_path" keys (NULL, 0: none), and its frame count and up vector */
    size_t npath;
    int path_frames;
    rr_vec3 path_up;
    scene_settings settings;
    scene_radiosity radiosity;
    scene_material *materials;
    size_t nmaterials;
    scene_light *lights;
    size_t nlights;
    scene_model *models;
    size_t nmodels;
    scene_object *objects;
    size_t nobjects;
    rr_vec3 *verts;         /* world space */
    rr_vec3 *normals;       /* per vertex as the mesh file gave them, unit, or zero vector where it had none;
                               NULL if none at all. No pass reads them yet: every pass shades with the
                               face normal (scene_tri_normal), so that the ray tracer and the radiosity
                               patches agree on which side a surface faces */
    size_t nverts;
    scene_tri *tris;
    size_t ntris;
    scene_csg_node *csg;    /* nodes of every solid's tree (see scene_csg_node) */
    size_t ncsg;
    rr_vec3 *csg_verts;     /* mesh leaves' vertices, world space */
    size_t ncsg_verts;
    uint32_t (*csg_tris)[3]; /* mesh leaves' triangles, outward counter-clockwise */
    size_t ncsg_tris;
    uint32_t *emissive_tris; /* indices of triangles whose material emits */
    size_t nemissive;
    rr_vec3 bbox_min, bbox_max; /* of all triangles, spheres and solids */
} scene;

typedef struct scene_load_opts {
    /* "--set" overrides, each "json.path=value" (e.g. "render.spp=64",
     * "camera.w=100", "objects[2].material=red"): value is parsed as JSON, and
     * taken as a string when it is not valid JSON. Applied before validation,
     * so an override is checked like the file itself. */
    const char *const *overrides;
    size_t noverrides;
    /* Memory allowed for the image buffers (bytes); 0 = half the physical
     * memory. A resolution whose film would exceed it is refused. */
    size_t max_image_bytes;
    rr_warn_sink warn;
} scene_load_opts;

/* Loads and validates a scene file. opts may be NULL (defaults). */
rr_status scene_load(const char *path, const scene_load_opts *opts, scene **out, rr_error *err);

/* Same from a string. name is used in messages; relative mesh paths resolve
 * against base_dir ("" = current folder). */
rr_status scene_load_string(const char *json, const char *name, const char *base_dir, const scene_load_opts *opts,
                            scene **out, rr_error *err);

void scene_destroy(scene *s);

/* The view of frame 1..path_frames of the camera path, at the size of
 * s->view (so that --width applies to every frame). */
rr_status scene_path_view(const scene *s, int frame, rr_view *out, rr_error *err);

/* Geometric (face) normal of triangle i, unit length, from the winding. */
rr_vec3 scene_tri_normal(const scene *s, size_t i);
double scene_tri_area(const scene *s, size_t i);
/* Object obj is a closed solid: a box, sphere or solid, or a mesh or
 * triangle list that is watertight and consistently oriented (the rule by
 * which "cull": "auto" culls). */
int scene_object_closed(const scene *s, uint32_t obj);

#endif
