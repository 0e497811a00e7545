/* imp_internal.h - shared by the importer's readers; not a public header.
 *
 *   imp.c         imp_load (dispatch by extension, the lock, final checks),
 *                 the model's growing arrays, the notes' texts, texture means
 *   imp_obj.c     .obj: the .mtl files read and checked line by line, the
 *                 MTL mapping; the geometry through imp_assimp.c
 *   imp_assimp.c  Assimp: node tree flattened into meshes, generic materials
 *   imp_gltf.cpp  tinygltf: nodes, primitives, materials, punctual lights
 */
#ifndef IMP_INTERNAL_H
#define IMP_INTERNAL_H

#include "imp.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Appends to m's arrays (grown by doubling); the new element is zeroed.
 * NULL when out of memory. */
imp_material *imp__add_material(imp_model *m);
imp_light *imp__add_light(imp_model *m);
/* Takes ownership of tri (freed with the model, or here on failure). */
rr_status imp__add_mesh(imp_model *m, const char *name, uint32_t material, mesh_tri *tri, rr_error *err);

/* Mean linear colour of an 8-bit image whose channels are sRGB-encoded
 * (the colour textures of glTF and MTL are): each channel through the sRGB
 * transfer function, then averaged. channels 1..4 (grey, grey+alpha, RGB,
 * RGBA; alpha ignored). */
rr_rgb imp__srgb_mean(const unsigned char *px, size_t npixels, int channels);

/* Images larger than this (pixels) are not decoded: the texture is
 * dropped (noted), instead of gigabytes for one mean colour. */
#define IMP_TEXTURE_MAX_PIXELS (1u << 26)

/* x->diffuse times the mean colour of the image file (any format stb_image
 * reads: PNG, JPEG, TGA, BMP, ...), and IMP_NOTE_TEXTURE_AVG; when the file
 * cannot be read, IMP_NOTE_TEXTURE_DROP and x->diffuse unchanged. */
void imp__texture_mean(const char *file, imp_material *x);

/* Copies src into a name buffer of IMP_NAME_MAX bytes (cut at a UTF-8
 * boundary), or fallback with index i when src is empty. */
void imp__name(char *dst, const char *src, const char *fallback, size_t i);

/* Readers: fill m (already zeroed, format set). Messages start with path. */
rr_status imp__load_gltf(const char *path, int binary, imp_model *m, rr_error *err);
rr_status imp__load_obj(const char *path, imp_model *m, rr_error *err);
/* Assimp. mtl != NULL (OBJ): materials come from it by name, Assimp's own
 * material table is ignored; the file is then read from text (text_size
 * bytes: the .obj with its mtllib lines made comments), not from path. */
struct imp__mtl;
/* The MTL mapping of material name (imp_obj.c) into *out: 0 if mtl has no
 * such material. */
int imp__mtl_material(const struct imp__mtl *mtl, const char *name, imp_material *out);
rr_status imp__load_assimp(const char *path, const char *text, size_t text_size, const struct imp__mtl *mtl,
                           imp_model *m, rr_error *err);

#ifdef __cplusplus
}
#endif

#endif
