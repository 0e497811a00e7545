/* imp.c - imp_load: the reader for a file's extension, the lock, the checks
 * every reader's result passes, and the model's growing arrays. */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <stb/stb_image.h>

#include "imp_internal.h"

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;

static const char *const k_notes[IMP_NOTE_BITS] = {
    "no material in the file: radray's default grey",
    "base-colour texture averaged to one colour (radray has no textures)",
    "textures other than the base colour dropped (normal, roughness, emissive, ...)",
    "transparency dropped: rendered opaque",
    "glossy or metallic reflection approximated (diffuse or Phong)",
    "diffuse lowered so that diffuse + mirror <= 1",
    "unlit material rendered as a diffuse surface",
};

const char *imp_note_text(unsigned bit)
{
    for (unsigned i = 0; i < IMP_NOTE_BITS; i++)
        if (bit == 1u << i)
            return k_notes[i];
    return NULL;
}

/* ---- growing arrays ---- */

static void *grow(void *arr, size_t n, size_t *cap, size_t size)
{
    if (n < *cap)
        return arr;
    size_t c = *cap ? 2 * *cap : 8;
    if (c > SIZE_MAX / size)
        return NULL;
    void *p = realloc(arr, c * size);
    if (p)
        *cap = c;
    return p;
}

/* Capacities live beside the model (not in the public struct). */
typedef struct imp_caps {
    size_t materials, meshes, lights;
} imp_caps;

typedef struct imp_model_full {
    imp_model m; /* first: imp_model * and imp_model_full * are the same address */
    imp_caps cap;
    size_t triangles; /* over every mesh so far */
} imp_model_full;

imp_material *imp__add_material(imp_model *m)
{
    imp_model_full *f = (imp_model_full *)m;
    imp_material *a = grow(m->materials, m->nmaterials, &f->cap.materials, sizeof *a);
    if (!a)
        return NULL;
    m->materials = a;
    imp_material *x = &a[m->nmaterials++];
    memset(x, 0, sizeof *x);
    return x;
}

imp_light *imp__add_light(imp_model *m)
{
    imp_model_full *f = (imp_model_full *)m;
    imp_light *a = grow(m->lights, m->nlights, &f->cap.lights, sizeof *a);
    if (!a)
        return NULL;
    m->lights = a;
    imp_light *x = &a[m->nlights++];
    memset(x, 0, sizeof *x);
    return x;
}

rr_status imp__add_mesh(imp_model *m, const char *name, uint32_t material, mesh_tri *tri, rr_error *err)
{
    imp_model_full *f = (imp_model_full *)m;
    /* A small file can instance one big mesh from many nodes: the total is
     * bounded before it becomes memory. */
    if (tri->ntris > IMP_MAX_TRIANGLES - f->triangles) {
        mesh_destroy(tri);
        return rr_error_set(err, RR_ERR_LIMIT, "the file has more than %u triangles (nodes instancing meshes count "
                            "each time)", (unsigned)IMP_MAX_TRIANGLES);
    }
    f->triangles += tri->ntris;
    imp_mesh *a = grow(m->meshes, m->nmeshes, &f->cap.meshes, sizeof *a);
    if (!a) {
        mesh_destroy(tri);
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for %zu meshes", m->nmeshes + 1);
    }
    m->meshes = a;
    imp_mesh *x = &a[m->nmeshes++];
    memset(x, 0, sizeof *x);
    imp__name(x->name, name, "mesh", m->nmeshes - 1);
    x->material = material;
    x->tri = tri;
    return RR_OK;
}

void imp__name(char *dst, const char *src, const char *fallback, size_t i)
{
    if (!src || !*src) {
        snprintf(dst, IMP_NAME_MAX, "%s%zu", fallback, i);
        return;
    }
    size_t n = strlen(src);
    if (n >= IMP_NAME_MAX) {
        n = IMP_NAME_MAX - 1;
        while (n > 0 && ((unsigned char)src[n] & 0xC0) == 0x80) /* do not cut a UTF-8 sequence */
            n--;
    }
    memcpy(dst, src, n);
    dst[n] = '\0';
}

static double srgb_to_linear(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

rr_rgb imp__srgb_mean(const unsigned char *px, size_t npixels, int channels)
{
    double lut[256], sum[3] = {0, 0, 0};
    for (int i = 0; i < 256; i++)
        lut[i] = srgb_to_linear(i / 255.0);
    int colour = channels >= 3;
    for (size_t p = 0; p < npixels; p++) {
        const unsigned char *q = px + p * (size_t)channels;
        for (int k = 0; k < 3; k++)
            sum[k] += lut[q[colour ? k : 0]];
    }
    double n = npixels ? (double)npixels : 1.0;
    return rr_rgb_make(sum[0] / n, sum[1] / n, sum[2] / n);
}

void imp__texture_mean(const char *file, imp_material *x)
{
    int w = 0, h = 0, ch = 0;
    rr_error ignored;
    /* a FIFO would block the read; a huge image would take gigabytes */
    if (rr_file_check_regular(file, &ignored) != RR_OK || !stbi_info(file, &w, &h, &ch) || w <= 0 || h <= 0 ||
        (size_t)w * (size_t)h > IMP_TEXTURE_MAX_PIXELS) {
        x->notes |= IMP_NOTE_TEXTURE_DROP;
        return;
    }
    unsigned char *px = stbi_load(file, &w, &h, &ch, 0);
    if (!px || w <= 0 || h <= 0 || ch < 1 || ch > 4) {
        x->notes |= IMP_NOTE_TEXTURE_DROP;
        stbi_image_free(px);
        return;
    }
    x->diffuse = rr_rgb_mul(x->diffuse, imp__srgb_mean(px, (size_t)w * (size_t)h, ch));
    x->notes |= IMP_NOTE_TEXTURE_AVG;
    stbi_image_free(px);
}

/* ---- imp_load ---- */

void imp_destroy(imp_model *m)
{
    if (!m)
        return;
    for (size_t i = 0; i < m->nmeshes; i++)
        mesh_destroy(m->meshes[i].tri);
    free(m->meshes);
    free(m->materials);
    free(m->lights);
    free(m);
}

size_t imp_triangles(const imp_model *m)
{
    size_t n = 0;
    for (size_t i = 0; i < m->nmeshes; i++)
        n += m->meshes[i].tri->ntris;
    return n;
}

static int rgb_ok(rr_rgb c, double hi)
{
    return isfinite(c.r) && isfinite(c.g) && isfinite(c.b) && c.r >= 0 && c.g >= 0 && c.b >= 0 && c.r <= hi &&
           c.g <= hi && c.b <= hi;
}

/* Every reader promises these; a broken promise is an internal error, not a
 * crash in the scene loader. */
static rr_status check_model(const char *path, const imp_model *m, rr_error *err)
{
    for (size_t i = 0; i < m->nmaterials; i++) {
        const imp_material *x = &m->materials[i];
        if (!rgb_ok(x->diffuse, 1) || !rgb_ok(x->mirror, 1) || !rgb_ok(x->specular, INFINITY) ||
            !rgb_ok(x->emission, INFINITY) || !(x->k >= 0 && isfinite(x->k)) || x->diffuse.r + x->mirror.r > 1 + 1e-9 ||
            x->diffuse.g + x->mirror.g > 1 + 1e-9 || x->diffuse.b + x->mirror.b > 1 + 1e-9)
            return rr_error_set(err, RR_ERR_INTERNAL, "%s: material '%s' was mapped out of range", path, x->name);
    }
    for (size_t i = 0; i < m->nmeshes; i++)
        if (m->meshes[i].material >= m->nmaterials || !m->meshes[i].tri)
            return rr_error_set(err, RR_ERR_INTERNAL, "%s: mesh '%s' has no valid material", path,
                                m->meshes[i].name);
    if (imp_triangles(m) == 0)
        return rr_error_set(err, RR_ERR_INVALID, "%s: the file has no triangles%s", path,
                            m->dropped_prims ? " (only points or lines, which radray does not render)" : "");
    return RR_OK;
}

/* A default material no mesh uses (Assimp's OBJ reader always makes one)
 * would only clutter the scene's list: removed, indices shifted. */
static void drop_unused_defaults(imp_model *m)
{
    for (size_t i = m->nmaterials; i-- > 0;) {
        if (!(m->materials[i].notes & IMP_NOTE_DEFAULT))
            continue;
        int used = 0;
        for (size_t j = 0; j < m->nmeshes && !used; j++)
            used = m->meshes[j].material == i;
        if (used)
            continue;
        memmove(&m->materials[i], &m->materials[i + 1], (m->nmaterials - i - 1) * sizeof *m->materials);
        m->nmaterials--;
        for (size_t j = 0; j < m->nmeshes; j++)
            if (m->meshes[j].material > i)
                m->meshes[j].material--;
    }
}

static const char *extension(const char *path)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    return dot && (!slash || dot > slash) ? dot + 1 : "";
}

rr_status imp_load(const char *path, imp_model **out, rr_error *err)
{
    rr_status st = rr_file_check_regular(path, err);
    if (st != RR_OK)
        return st;
    imp_model_full *f = calloc(1, sizeof *f);
    if (!f)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory", path);
    imp_model *m = &f->m;
    const char *ext = extension(path);
    size_t i = 0;
    for (; ext[i] && i + 1 < sizeof m->format; i++)
        m->format[i] = (char)(ext[i] >= 'A' && ext[i] <= 'Z' ? ext[i] - 'A' + 'a' : ext[i]);
    m->format[i] = '\0';
    pthread_mutex_lock(&g_lock);
    if (strcmp(m->format, "gltf") == 0 || strcmp(m->format, "glb") == 0)
        st = imp__load_gltf(path, strcmp(m->format, "glb") == 0, m, err);
    else if (strcmp(m->format, "obj") == 0)
        st = imp__load_obj(path, m, err);
    else
        st = imp__load_assimp(path, NULL, 0, NULL, m, err);
    pthread_mutex_unlock(&g_lock);
    if (st == RR_OK) {
        drop_unused_defaults(m);
        st = check_model(path, m, err);
    }
    if (st != RR_OK) {
        imp_destroy(m);
        return st;
    }
    *out = m;
    return RR_OK;
}
