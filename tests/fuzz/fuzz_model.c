/* fuzz_model.c - libFuzzer harness for the model importer (imp_load) and the
 * scene's "model" objects (scene/scene_model.c).
 *
 * Input layout: the first byte chooses the format and a few scene options,
 * the rest is the file:
 *   byte 0 % 3 == 0   glTF JSON       -> model.gltf
 *              == 1   binary glTF     -> model.glb
 *              == 2   OBJ + MTL       -> model.obj and model.mtl: the rest is
 *                     split at the first "\n%%MTL\n" into the .obj text and
 *                     the .mtl text (no marker: an empty model.mtl)
 *   (byte 0 / 3) & 1  the model object gets "up": "z"
 *   (byte 0 / 3) & 2  ... and "transform": [{"scale": [-1, 1, 1]}] (a mirror:
 *                     the winding of every triangle is reversed)
 *   (byte 0 / 3) & 4  ... and "scale": 0.01, "cull": false
 * The seeds start with '0', '1' or '2' (48, 49, 50: no options).
 *
 * The files are written into a private temporary folder made once per
 * process (same names every run; the files of the other formats are removed
 * first, so that an input cannot see the previous one's). Then:
 *   1. imp_load(file) and, on success, checks on the model, imp_destroy;
 *   2. scene_load_string of a small scene whose only object is
 *      {"type": "model", "file": "model.<ext>"} (base folder: the temporary
 *      folder), so that the scene side runs too (materials and lights of the
 *      file, transforms, mesh welding, topology report, culling), with a
 *      64 MiB film limit; scene_destroy.
 * Any crash, sanitizer report, leak or abort is a finding, and so is a broken
 * contract: RR_OK without a result, a result written on failure, an empty
 * error message, a model that breaks the promises of imp.h (material
 * index in range, vertex indices in range, finite positions, at least one
 * triangle), or a scene that loads a file imp_load refused.
 * FUZZ_MODEL_VERBOSE=1 prints each input's outcome (for checking seeds).
 * See README.md.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "imp.h"
#include "scene.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* A broken loader contract is a finding: say which, then abort so that
 * libFuzzer saves the input. */
static void fuzz_check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz: contract broken: %s\n", what);
        abort();
    }
}

static char fuzz_dir[256];
static int fuzz_verbose; /* FUZZ_MODEL_VERBOSE=1: each input's outcome on stderr (checking seeds) */
static const char *const fuzz_files[] = {"model.gltf", "model.glb", "model.obj", "model.mtl"};
#define FUZZ_NFILES 4
#define FUZZ_MTL_MARKER "\n%%MTL\n"

static void fuzz_path(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", fuzz_dir, name);
}

static void fuzz_cleanup(void)
{
    char path[320];
    for (size_t i = 0; i < FUZZ_NFILES; i++) {
        fuzz_path(path, sizeof path, fuzz_files[i]);
        unlink(path);
    }
    rmdir(fuzz_dir);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    const char *tmp = getenv("TMPDIR");
    snprintf(fuzz_dir, sizeof fuzz_dir, "%s/radray-fuzz-model-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(fuzz_dir)) {
        perror("fuzz_model: mkdtemp");
        exit(1);
    }
    atexit(fuzz_cleanup);
    const char *v = getenv("FUZZ_MODEL_VERBOSE");
    fuzz_verbose = v && *v && strcmp(v, "0") != 0;
    return 0;
}

static void fuzz_write(const char *name, const uint8_t *data, size_t size)
{
    char path[320];
    fuzz_path(path, sizeof path, name);
    FILE *f = fopen(path, "wb");
    fuzz_check(f != NULL, "cannot create the input file");
    fuzz_check(!size || fwrite(data, 1, size, f) == size, "cannot write the input file");
    fuzz_check(fclose(f) == 0, "cannot close the input file");
}

/* First occurrence of the marker in data[0..size), or NULL. */
static const uint8_t *fuzz_find(const uint8_t *data, size_t size, const char *marker)
{
    size_t m = strlen(marker);
    for (size_t i = 0; i + m <= size; i++)
        if (memcmp(data + i, marker, m) == 0)
            return data + i;
    return NULL;
}

/* The promises of imp.h that the scene relies on. */
static void fuzz_check_model(const imp_model *m)
{
    fuzz_check(m->nmeshes > 0 && m->meshes != NULL, "RR_OK with no meshes");
    fuzz_check(imp_triangles(m) > 0, "RR_OK with no triangles");
    fuzz_check(memchr(m->format, '\0', sizeof m->format) != NULL, "format is NUL-terminated");
    for (size_t i = 0; i < m->nmaterials; i++) {
        const imp_material *x = &m->materials[i];
        fuzz_check(memchr(x->name, '\0', sizeof x->name) != NULL, "material name is NUL-terminated");
        fuzz_check(isfinite(x->k) && x->k >= 0, "material k is finite and >= 0");
    }
    for (size_t i = 0; i < m->nmeshes; i++) {
        const imp_mesh *me = &m->meshes[i];
        fuzz_check(memchr(me->name, '\0', sizeof me->name) != NULL, "mesh name is NUL-terminated");
        fuzz_check(me->material < m->nmaterials, "mesh material index in range");
        fuzz_check(me->tri != NULL, "mesh has triangles");
        const mesh_tri *t = me->tri;
        for (size_t v = 0; v < 3 * t->nverts; v++)
            fuzz_check(isfinite(t->pos[v]), "vertex positions are finite");
        for (size_t k = 0; k < 3 * t->ntris; k++)
            fuzz_check(t->tris[k] < t->nverts, "vertex index in range");
    }
    for (size_t i = 0; i < m->nlights; i++) {
        const imp_light *l = &m->lights[i];
        fuzz_check(memchr(l->name, '\0', sizeof l->name) != NULL, "light name is NUL-terminated");
        fuzz_check(l->type == IMP_LIGHT_POINT || l->type == IMP_LIGHT_DIRECTIONAL, "light type is known");
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    unsigned format = data[0] % 3, opt = (unsigned)(data[0] / 3);
    data++, size--;

    char path[320];
    for (size_t i = 0; i < FUZZ_NFILES; i++) {
        fuzz_path(path, sizeof path, fuzz_files[i]);
        unlink(path);
    }
    const char *name = fuzz_files[format];
    if (format == 2) {
        const uint8_t *mark = fuzz_find(data, size, FUZZ_MTL_MARKER);
        size_t nobj = mark ? (size_t)(mark - data) : size;
        fuzz_write("model.obj", data, nobj);
        if (mark) {
            size_t skip = nobj + strlen(FUZZ_MTL_MARKER);
            fuzz_write("model.mtl", data + skip, size - skip);
        } else {
            fuzz_write("model.mtl", data, 0);
        }
    } else {
        fuzz_write(name, data, size);
    }

    /* 1. The importer alone. */
    fuzz_path(path, sizeof path, name);
    imp_model *m = NULL;
    rr_error err;
    rr_error_clear(&err);
    rr_status st = imp_load(path, &m, &err);
    int imported = st == RR_OK;
    if (fuzz_verbose)
        fprintf(stderr, "fuzz_model: imp_load %s: %s\n", name, st == RR_OK ? "ok" : err.msg);
    if (st == RR_OK) {
        fuzz_check(m != NULL, "RR_OK must come with a model");
        fuzz_check_model(m);
        if (fuzz_verbose)
            fprintf(stderr, "fuzz_model:   %zu meshes, %zu triangles, %zu materials, %zu lights, dropped %zu prims "
                    "%zu lights %zu cameras\n", m->nmeshes, imp_triangles(m), m->nmaterials, m->nlights,
                    m->dropped_prims, m->dropped_lights, m->dropped_cameras);
        imp_destroy(m);
    } else {
        fuzz_check(m == NULL, "on failure *out is untouched");
        fuzz_check(err.msg[0] != '\0', "every failure carries a message");
    }

    /* 2. The same file as a scene's "model" object. */
    char json[1024];
    snprintf(json, sizeof json,
             "{\"format\": \"radray-scene/1\", \"name\": \"fuzz-model\","
             " \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 5], \"target\": [0, 0, 0], \"up\": [0, 1, 0],"
             " \"fov\": 40, \"width\": 16, \"height\": 16},"
             " \"objects\": [{\"type\": \"model\", \"file\": \"%s\"%s%s%s}]}",
             name, opt & 1 ? ", \"up\": \"z\"" : "", opt & 2 ? ", \"transform\": [{\"scale\": [-1, 1, 1]}]" : "",
             opt & 4 ? ", \"scale\": 0.01, \"cull\": false" : "");
    scene_load_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.max_image_bytes = (size_t)64 << 20; /* 64 MiB of film at most */
    scene *s = NULL;
    rr_error_clear(&err);
    st = scene_load_string(json, "fuzz-model.json", fuzz_dir, &opts, &s, &err);
    if (fuzz_verbose)
        fprintf(stderr, "fuzz_model: scene %s: %s\n", json, st == RR_OK ? "ok" : err.msg);
    if (st == RR_OK) {
        fuzz_check(s != NULL, "RR_OK must come with a scene");
        fuzz_check(imported, "the scene loaded a model that imp_load refused");
        fuzz_check(s->nmodels == 1, "a loaded scene has its one model");
        scene_destroy(s);
    } else {
        fuzz_check(s == NULL, "on failure *out is untouched");
        fuzz_check(err.msg[0] != '\0', "every failure carries a message");
    }
    return 0;
}
