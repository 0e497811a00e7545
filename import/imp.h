/* imp.h - whole model files in: their meshes, materials and lights, mapped to
 * radray's material model (the "model" scene object, notes/import.md).
 *
 * Readers (notes/import.md says why):
 *   .gltf .glb                  tinygltf (imp_gltf.cpp)
 *   .obj (+ .mtl)               Assimp for the geometry; the .mtl is read and
 *                               checked by radray (imp_obj.c), line by line
 *   .fbx .dae .3ds .ply ...     Assimp (imp_assimp.c), the generic mapping
 * No C++ exception crosses into C; every failure comes back as an rr_status
 * with a one-line message that starts with the file name and names the
 * material, mesh, node or line at fault.
 *
 * What comes back is in the file's own frame and units (node transforms
 * applied; the scene applies "scale", "up" and "transform"). Materials are
 * already radray's (diffuse, Phong specular and k, mirror, emission), with
 * a note bit for everything the mapping approximated or dropped; the mapping
 * table is in notes/import.md.
 *
 * Ownership: imp_load allocates *out, imp_destroy frees it (NULL is a no-op).
 * On failure *out is left untouched. Calls are serialised by a lock (Assimp's
 * logger is global).
 */
#ifndef IMP_H
#define IMP_H

#include <stddef.h>
#include <stdint.h>

#include "mesh.h"
#include "rr_core.h"

#define IMP_NAME_MAX 64
/* The most triangles a file may bring (over every node's instance of every
 * mesh): 2^27, about 10 GiB once in a scene. More is RR_ERR_LIMIT. */
#define IMP_MAX_TRIANGLES (1u << 27)

/* What the mapping approximated or dropped, one bit each (imp_note_text). */
enum {
    IMP_NOTE_DEFAULT = 1u << 0,      /* the file gives no material: radray's default grey */
    IMP_NOTE_TEXTURE_AVG = 1u << 1,  /* base-colour / Kd texture replaced by its mean colour */
    IMP_NOTE_TEXTURE_DROP = 1u << 2, /* other textures (normal, roughness, emissive...) or an unreadable one */
    IMP_NOTE_TRANSPARENT = 1u << 3,  /* transparency / transmission / refraction dropped: opaque */
    IMP_NOTE_ROUGH = 1u << 4,        /* metallic or glossy reflection approximated (diffuse or Phong) */
    IMP_NOTE_CLAMPED = 1u << 5,      /* diffuse lowered so that diffuse + mirror <= 1 */
    IMP_NOTE_UNLIT = 1u << 6         /* KHR_materials_unlit / illum 0: mapped as a diffuse surface */
};
#define IMP_NOTE_BITS 7

/* One line of text per note bit ("base-colour texture averaged"...); NULL
 * for a bit that is not a note. */
const char *imp_note_text(unsigned bit);

typedef struct imp_material {
    char name[IMP_NAME_MAX];  /* as the file names it; "material<i>" when it has none */
    rr_rgb diffuse;           /* Lambertian reflectance, each in [0, 1] */
    rr_rgb specular;          /* Phong weight, >= 0 */
    double k;                 /* Phong exponent, >= 0 */
    rr_rgb mirror;            /* mirror reflectance; diffuse + mirror <= 1 per channel */
    rr_rgb emission;          /* emitted radiance, >= 0 */
    unsigned notes;           /* IMP_NOTE_* */
} imp_material;

typedef struct imp_mesh {
    char name[IMP_NAME_MAX];  /* node name (mesh name, primitive) as the file gives them */
    uint32_t material;        /* index into imp_model.materials */
    mesh_tri *tri;            /* node transforms applied, counter-clockwise = front */
} imp_mesh;

typedef enum imp_light_type { IMP_LIGHT_POINT = 0, IMP_LIGHT_DIRECTIONAL = 1 } imp_light_type;

typedef struct imp_light {
    char name[IMP_NAME_MAX];
    imp_light_type type;
    rr_vec3 position;         /* point */
    rr_vec3 direction;        /* directional: unit, from the scene TOWARDS the light */
    rr_rgb intensity;         /* colour x intensity, as radray's point / directional lights */
} imp_light;

typedef struct imp_model {
    char format[16];          /* "gltf", "glb", "obj", or Assimp's extension ("fbx"...) */
    imp_material *materials;
    size_t nmaterials;
    imp_mesh *meshes;
    size_t nmeshes;
    imp_light *lights;
    size_t nlights;
    size_t dropped_prims;     /* point and line primitives (radray renders surfaces) */
    size_t dropped_lights;    /* spot lights and other kinds radray does not have */
    size_t dropped_cameras;   /* cameras in the file (the scene's camera is used) */
} imp_model;

/* Loads the model at path; the reader is chosen by extension
 * (case-insensitive). */
rr_status imp_load(const char *path, imp_model **out, rr_error *err);

void imp_destroy(imp_model *m);

/* Number of triangles over every mesh. */
size_t imp_triangles(const imp_model *m);

#endif
