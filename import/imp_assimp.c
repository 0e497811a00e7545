/* imp_assimp.c - files through Assimp (its C API): the node tree flattened
 * into one imp_mesh per (node, mesh), its lights, and the generic material
 * mapping (or, for .obj, the materials radray read from the .mtl files).
 *
 * Post-processing: triangulate, split by primitive type (points and lines
 * are dropped and counted). Assimp's OBJ reader makes every corner a vertex
 * of its own; mesh_weld joins them again where the surface is smooth (faces
 * within IMP_CREASE_DEG), not across creases, which is how a modeller's
 * export shares them and what the radiosity display averages over.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "imp_internal.h"

/* Faces meeting at more than this are a crease: their corners stay apart. */
#define IMP_CREASE_DEG 45.0

typedef struct as_ctx {
    const char *path;
    char dir[4096];
    const struct aiScene *sc;
    imp_model *m;
    rr_error *err;
} as_ctx;

/* key, type, index: what an AI_MATKEY_* macro expands to. */
static rr_rgb get_rgb(const struct aiMaterial *mat, const char *key, unsigned type, unsigned idx, rr_rgb def,
                      int *found)
{
    struct aiColor4D c;
    if (aiGetMaterialColor(mat, key, type, idx, &c) != aiReturn_SUCCESS) {
        if (found)
            *found = 0;
        return def;
    }
    if (found)
        *found = 1;
    return rr_rgb_make(c.r, c.g, c.b);
}

static double get_float(const struct aiMaterial *mat, const char *key, unsigned type, unsigned idx, double def)
{
    ai_real v;
    unsigned n = 1;
    return aiGetMaterialFloatArray(mat, key, type, idx, &v, &n) == aiReturn_SUCCESS && n == 1 ? (double)v : def;
}

static rr_status check_rgb(const as_ctx *c, const char *mat, const char *what, rr_rgb v, double hi)
{
    double x[3] = {v.r, v.g, v.b};
    for (int k = 0; k < 3; k++)
        if (!isfinite(x[k]) || x[k] < 0 || x[k] > hi)
            return rr_error_set(c->err, RR_ERR_INVALID, "%s: material '%s': %s[%d] is %g: must be %s", c->path, mat,
                                what, k, x[k], hi > 1e300 ? "a finite number >= 0" : "in [0, 1]");
    return RR_OK;
}

/* The generic mapping (formats without radray's own material reader):
 * diffuse, specular x strength and shininess, emissive x intensity,
 * reflective x reflectivity as a mirror. */
static rr_status generic_material(const as_ctx *c, const struct aiMaterial *mat, imp_material *x)
{
    x->diffuse = get_rgb(mat, AI_MATKEY_COLOR_DIFFUSE, rr_rgb_make(0.5, 0.5, 0.5), NULL);
    x->specular = rr_rgb_scale(get_rgb(mat, AI_MATKEY_COLOR_SPECULAR, rr_rgb_make(0, 0, 0), NULL),
                               get_float(mat, AI_MATKEY_SHININESS_STRENGTH, 1));
    x->k = get_float(mat, AI_MATKEY_SHININESS, 1);
    x->emission = rr_rgb_scale(get_rgb(mat, AI_MATKEY_COLOR_EMISSIVE, rr_rgb_make(0, 0, 0), NULL),
                               get_float(mat, AI_MATKEY_EMISSIVE_INTENSITY, 1));
    double refl = get_float(mat, AI_MATKEY_REFLECTIVITY, 0);
    rr_rgb mirror = rr_rgb_scale(get_rgb(mat, AI_MATKEY_COLOR_REFLECTIVE, rr_rgb_make(1, 1, 1), NULL), refl);
    rr_status st;
    if ((st = check_rgb(c, x->name, "diffuse colour", x->diffuse, 1)) != RR_OK ||
        (st = check_rgb(c, x->name, "specular colour", x->specular, INFINITY)) != RR_OK ||
        (st = check_rgb(c, x->name, "emissive colour", x->emission, INFINITY)) != RR_OK ||
        (st = check_rgb(c, x->name, "reflective colour x reflectivity", mirror, 1)) != RR_OK)
        return st;
    if (!(x->k >= 0 && isfinite(x->k)))
        return rr_error_set(c->err, RR_ERR_INVALID, "%s: material '%s': shininess %g must be >= 0", c->path,
                            x->name, x->k);
    if (rr_rgb_max(mirror) > 0) {
        x->mirror = mirror;
        double *d[3] = {&x->diffuse.r, &x->diffuse.g, &x->diffuse.b}, mm[3] = {mirror.r, mirror.g, mirror.b};
        for (int k = 0; k < 3; k++)
            if (*d[k] + mm[k] > 1)
                *d[k] = 1 - mm[k], x->notes |= IMP_NOTE_CLAMPED;
    }
    if (get_float(mat, AI_MATKEY_OPACITY, 1) < 1)
        x->notes |= IMP_NOTE_TRANSPARENT;
    struct aiString tex;
    if (aiGetMaterialTextureCount(mat, aiTextureType_DIFFUSE) > 0 &&
        aiGetMaterialTexture(mat, aiTextureType_DIFFUSE, 0, &tex, NULL, NULL, NULL, NULL, NULL, NULL) ==
            aiReturn_SUCCESS) {
        char file[4096];
        rr_error jerr;
        if (tex.data[0] != '*' && rr_path_join(c->dir, tex.data, file, sizeof file, &jerr) == RR_OK)
            imp__texture_mean(file, x);
        else
            x->notes |= IMP_NOTE_TEXTURE_DROP; /* embedded textures of FBX and the like: not decoded */
    }
    static const enum aiTextureType other[] = {aiTextureType_SPECULAR, aiTextureType_EMISSIVE, aiTextureType_NORMALS,
                                               aiTextureType_HEIGHT, aiTextureType_SHININESS, aiTextureType_OPACITY};
    for (size_t i = 0; i < sizeof other / sizeof other[0]; i++)
        if (aiGetMaterialTextureCount(mat, other[i]) > 0)
            x->notes |= IMP_NOTE_TEXTURE_DROP;
    return RR_OK;
}

static rr_status read_materials(const as_ctx *c, const struct imp__mtl *mtl)
{
    for (unsigned i = 0; i < c->sc->mNumMaterials; i++) {
        const struct aiMaterial *mat = c->sc->mMaterials[i];
        struct aiString name;
        name.length = 0, name.data[0] = '\0';
        aiGetMaterialString(mat, AI_MATKEY_NAME, &name);
        imp_material *x = imp__add_material(c->m);
        if (!x)
            return rr_error_set(c->err, RR_ERR_NOMEM, "%s: out of memory", c->path);
        imp__name(x->name, name.data, "material", i);
        if (mtl) {
            /* Faces without usemtl get Assimp's "DefaultMaterial". */
            if (!imp__mtl_material(mtl, name.data, x)) {
                x->diffuse = rr_rgb_make(0.5, 0.5, 0.5), x->k = 1, x->notes = IMP_NOTE_DEFAULT;
                imp__name(x->name, "default", "", 0);
            }
            continue;
        }
        /* A material without a name (what Assimp makes up for a PLY or STL:
         * white, diffuse 1 and specular 1) or Assimp's default one is no
         * material of the file: radray's default grey. */
        if (name.length == 0 || strcmp(name.data, AI_DEFAULT_MATERIAL_NAME) == 0) {
            x->diffuse = rr_rgb_make(0.5, 0.5, 0.5), x->k = 1, x->notes = IMP_NOTE_DEFAULT;
            imp__name(x->name, "default", "", 0);
            continue;
        }
        rr_status st = generic_material(c, mat, x);
        if (st != RR_OK)
            return st;
    }
    return RR_OK;
}

/* ---- geometry ---- */

static rr_vec3 xf_point(const struct aiMatrix4x4 *t, struct aiVector3D p)
{
    return rr_v3(t->a1 * (double)p.x + t->a2 * (double)p.y + t->a3 * (double)p.z + t->a4,
                 t->b1 * (double)p.x + t->b2 * (double)p.y + t->b3 * (double)p.z + t->b4,
                 t->c1 * (double)p.x + t->c2 * (double)p.y + t->c3 * (double)p.z + t->c4);
}

static double det3(const struct aiMatrix4x4 *t)
{
    return t->a1 * (t->b2 * t->c3 - t->b3 * t->c2) - t->a2 * (t->b1 * t->c3 - t->b3 * t->c1) +
           t->a3 * (t->b1 * t->c2 - t->b2 * t->c1);
}

/* Normals by the cofactor matrix (inverse transpose up to a positive scale
 * when det > 0; sign corrected otherwise). */
static rr_vec3 xf_normal(const struct aiMatrix4x4 *t, double sg, struct aiVector3D n)
{
    double c[3][3] = {{t->b2 * t->c3 - t->b3 * t->c2, t->b3 * t->c1 - t->b1 * t->c3, t->b1 * t->c2 - t->b2 * t->c1},
                      {t->a3 * t->c2 - t->a2 * t->c3, t->a1 * t->c3 - t->a3 * t->c1, t->a2 * t->c1 - t->a1 * t->c2},
                      {t->a2 * t->b3 - t->a3 * t->b2, t->a3 * t->b1 - t->a1 * t->b3, t->a1 * t->b2 - t->a2 * t->b1}};
    rr_vec3 r = rr_v3(c[0][0] * n.x + c[0][1] * n.y + c[0][2] * n.z, c[1][0] * n.x + c[1][1] * n.y + c[1][2] * n.z,
                      c[2][0] * n.x + c[2][1] * n.y + c[2][2] * n.z);
    return rr_v3_norm(rr_v3_scale(r, sg));
}

static rr_status add_mesh(const as_ctx *c, const struct aiMesh *am, const struct aiMatrix4x4 *t, const char *name)
{
    size_t nv = am->mNumVertices, nt = 0;
    for (unsigned f = 0; f < am->mNumFaces; f++)
        nt += am->mFaces[f].mNumIndices == 3;
    c->m->dropped_prims += am->mNumFaces - nt;
    if (nt == 0)
        return RR_OK;
    double *pos = malloc(3 * nv * sizeof *pos), *nrm = am->mNormals ? malloc(3 * nv * sizeof *nrm) : NULL;
    uint32_t *tris = malloc(3 * nt * sizeof *tris);
    rr_status st = RR_OK;
    if (!pos || !tris || (am->mNormals && !nrm)) {
        st = rr_error_set(c->err, RR_ERR_NOMEM, "%s: mesh '%s': out of memory", c->path, name);
        goto done;
    }
    double det = det3(t), sg = det < 0 ? -1 : 1;
    for (size_t v = 0; v < nv; v++) {
        rr_vec3 p = xf_point(t, am->mVertices[v]);
        if (!rr_v3_isfinite(p)) {
            st = rr_error_set(c->err, RR_ERR_INVALID, "%s: mesh '%s': vertex %zu is not finite", c->path, name, v);
            goto done;
        }
        pos[3 * v] = p.x, pos[3 * v + 1] = p.y, pos[3 * v + 2] = p.z;
        if (nrm) {
            rr_vec3 n = xf_normal(t, sg, am->mNormals[v]);
            nrm[3 * v] = n.x, nrm[3 * v + 1] = n.y, nrm[3 * v + 2] = n.z;
        }
    }
    size_t k = 0;
    for (unsigned f = 0; f < am->mNumFaces; f++) {
        const struct aiFace *fc = &am->mFaces[f];
        if (fc->mNumIndices != 3)
            continue;
        /* A mirroring node transform turns counter-clockwise into clockwise. */
        tris[k++] = fc->mIndices[0];
        tris[k++] = fc->mIndices[det < 0 ? 2 : 1];
        tris[k++] = fc->mIndices[det < 0 ? 1 : 2];
    }
    mesh_tri *mt = NULL;
    if ((st = mesh_from_arrays(pos, nv, tris, nt, nrm, &mt, c->err)) == RR_OK &&
        (st = mesh_weld(mt, IMP_CREASE_DEG, c->err)) != RR_OK)
        mesh_destroy(mt);
    if (st == RR_OK)
        st = imp__add_mesh(c->m, name, am->mMaterialIndex, mt, c->err);
    if (st != RR_OK)
        rr_error_prefix(c->err, "%s: mesh '%s'", c->path, name);
done:
    free(pos);
    free(nrm);
    free(tris);
    return st;
}

static rr_status walk(const as_ctx *c, const struct aiNode *node, struct aiMatrix4x4 parent, int depth)
{
    if (depth > 64)
        return rr_error_set(c->err, RR_ERR_INVALID, "%s: node '%s': the node tree is more than 64 deep", c->path,
                            node->mName.data);
    struct aiMatrix4x4 t = parent;
    aiMultiplyMatrix4(&t, &node->mTransformation);
    for (unsigned i = 0; i < node->mNumMeshes; i++) {
        unsigned mi = node->mMeshes[i];
        if (mi >= c->sc->mNumMeshes)
            return rr_error_set(c->err, RR_ERR_INTERNAL, "%s: node '%s' refers to mesh %u of %u", c->path,
                                node->mName.data, mi, c->sc->mNumMeshes);
        const struct aiMesh *am = c->sc->mMeshes[mi];
        char name[IMP_NAME_MAX * 2];
        const char *base = node->mName.length ? node->mName.data : am->mName.data;
        /* names are cut to IMP_NAME_MAX later; keep the index visible */
        if (node->mNumMeshes > 1)
            snprintf(name, sizeof name, "%.*s.%u", IMP_NAME_MAX - 8, base, i);
        else
            snprintf(name, sizeof name, "%.*s", IMP_NAME_MAX, base);
        rr_status st = add_mesh(c, am, &t, name);
        if (st != RR_OK)
            return st;
    }
    for (unsigned i = 0; i < node->mNumChildren; i++) {
        rr_status st = walk(c, node->mChildren[i], t, depth + 1);
        if (st != RR_OK)
            return st;
    }
    return RR_OK;
}

/* ---- lights ---- */

static int find_node(const struct aiNode *node, const char *name, struct aiMatrix4x4 parent, struct aiMatrix4x4 *out,
                     int depth)
{
    struct aiMatrix4x4 t = parent;
    aiMultiplyMatrix4(&t, &node->mTransformation);
    if (strcmp(node->mName.data, name) == 0) {
        *out = t;
        return 1;
    }
    for (unsigned i = 0; depth < 64 && i < node->mNumChildren; i++)
        if (find_node(node->mChildren[i], name, t, out, depth + 1))
            return 1;
    return 0;
}

static rr_status read_lights(const as_ctx *c)
{
    struct aiMatrix4x4 id;
    aiIdentityMatrix4(&id);
    for (unsigned i = 0; i < c->sc->mNumLights; i++) {
        const struct aiLight *l = c->sc->mLights[i];
        if (l->mType != aiLightSource_POINT && l->mType != aiLightSource_DIRECTIONAL) {
            c->m->dropped_lights++;
            continue;
        }
        struct aiMatrix4x4 t = id;
        find_node(c->sc->mRootNode, l->mName.data, id, &t, 0);
        imp_light *x = imp__add_light(c->m);
        if (!x)
            return rr_error_set(c->err, RR_ERR_NOMEM, "%s: out of memory", c->path);
        imp__name(x->name, l->mName.data, "light", i);
        x->intensity = rr_rgb_make(l->mColorDiffuse.r, l->mColorDiffuse.g, l->mColorDiffuse.b);
        if (!(x->intensity.r >= 0 && x->intensity.g >= 0 && x->intensity.b >= 0) || !isfinite(rr_rgb_max(x->intensity)))
            return rr_error_set(c->err, RR_ERR_INVALID, "%s: light '%s': the colour must be finite and >= 0",
                                c->path, x->name);
        if (l->mType == aiLightSource_POINT) {
            x->type = IMP_LIGHT_POINT;
            x->position = xf_point(&t, l->mPosition);
        } else {
            struct aiMatrix4x4 r = t;
            r.a4 = r.b4 = r.c4 = 0;
            x->type = IMP_LIGHT_DIRECTIONAL;
            x->direction = rr_v3_norm(rr_v3_scale(xf_point(&r, l->mDirection), -1));
        }
        if (!rr_v3_isfinite(x->position) || !rr_v3_isfinite(x->direction))
            return rr_error_set(c->err, RR_ERR_INVALID, "%s: light '%s' is not finite", c->path, x->name);
    }
    return RR_OK;
}

rr_status imp__load_assimp(const char *path, const char *text, size_t text_size, const struct imp__mtl *mtl,
                           imp_model *m, rr_error *err)
{
    as_ctx c = {path, "", NULL, m, err};
    rr_path_dirname(path, c.dir, sizeof c.dir);
    unsigned flags = aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_ValidateDataStructure;
    if (text && text_size > UINT32_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: the file is larger than 4 GiB", path);
    c.sc = text ? aiImportFileFromMemory(text, (unsigned)text_size, flags, "obj") : aiImportFile(path, flags);
    if (!c.sc)
        return rr_error_set(err, RR_ERR_PARSE, "%s: %s", path, aiGetErrorString());
    rr_status st = RR_OK;
    if (c.sc->mFlags & AI_SCENE_FLAGS_INCOMPLETE || !c.sc->mRootNode)
        st = rr_error_set(err, RR_ERR_PARSE, "%s: the file is incomplete (Assimp could not read a whole scene)", path);
    if (st == RR_OK)
        st = read_materials(&c, mtl);
    if (st == RR_OK) {
        struct aiMatrix4x4 id;
        aiIdentityMatrix4(&id);
        st = walk(&c, c.sc->mRootNode, id, 0);
    }
    if (st == RR_OK)
        st = read_lights(&c);
    m->dropped_cameras = c.sc->mNumCameras;
    aiReleaseImport(c.sc);
    return st;
}
