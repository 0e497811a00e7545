/* test_regress.c - regression tests from fuzzing (tests/fuzz, notes/robustness.md).
 *
 * fuzz_corpus_seeds: every seed of the fuzz corpus goes through exactly what
 * the fuzz harnesses do with an input (scene_load_string with a 64 MiB image
 * budget and tests/data/scenes as base folder; mesh_load + mesh_analyze) and
 * must load: a seed that stops loading would leave the fuzzers starting from
 * error paths only. Inputs that once crashed or hung a loader are added here,
 * each with its own test, once the loader is fixed (open findings are listed
 * in notes/robustness.md).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "mesh.h"
#include "scene.h"

#define CORPUS RR_SOURCE_DIR "/tests/fuzz/corpus"

/* Calls fn on every regular entry of dir (sorted order does not matter);
 * returns how many there were. */
static size_t for_each_file(const char *dir, void (*fn)(const char *path))
{
    DIR *d = opendir(dir);
    if (!d)
        fail_msg("cannot open %s", dir);
    size_t n = 0;
    struct dirent *e;
    char path[4096];
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        fn(path);
        n++;
    }
    closedir(d);
    return n;
}

static void load_scene_seed(const char *path)
{
    char *text = NULL;
    size_t n = 0;
    rr_error err = {0};
    if (rr_file_read_all(path, &text, &n, &err) != RR_OK)
        fail_msg("%s", err.msg);
    char *z = text; /* NUL-terminated by rr_file_read_all, as the harness does */
    scene_load_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.max_image_bytes = (size_t)64 << 20;
    scene *s = NULL;
    if (scene_load_string(z, "fuzz.json", RR_TEST_DATA "/scenes", &opts, &s, &err) != RR_OK)
        fail_msg("seed %s no longer loads: %s", path, err.msg);
    assert_non_null(s);
    scene_destroy(s);
    free(z);
}

static void load_mesh_seed(const char *path)
{
    mesh_tri *m = NULL;
    rr_error err = {0};
    if (mesh_load(path, &m, &err) != RR_OK)
        fail_msg("seed %s no longer loads: %s", path, err.msg);
    mesh_report rep;
    assert_int_equal(mesh_analyze(m, &rep, &err), RR_OK);
    assert_true(m->ntris > 0);
    mesh_destroy(m);
}

/* An input of fuzz_model (tests/fuzz/fuzz_model.c: byte 0 % 3 picks glTF,
 * binary glTF or OBJ + MTL, the rest is the file, an OBJ's .mtl after
 * "\n%%MTL\n") through imp_load; the status (or NULL on a crash-free
 * refusal's message). */
static rr_status load_model_input(const char *path, rr_error *err)
{
    char *data = NULL;
    size_t n = 0;
    if (rr_file_read_all(path, &data, &n, err) != RR_OK || n == 0)
        fail_msg("cannot read %s", path);
    static const char *const ext[] = {"gltf", "glb", "obj"};
    char dir[] = "/tmp/rr_model_XXXXXX", file[64], mtl[64];
    assert_non_null(mkdtemp(dir));
    int fmt = (unsigned char)data[0] % 3;
    snprintf(file, sizeof file, "%s/model.%s", dir, ext[fmt]);
    snprintf(mtl, sizeof mtl, "%s/model.mtl", dir);
    const char *body = data + 1, *split = NULL;
    size_t len = n - 1, blen = len;
    if (fmt == 2)
        for (size_t i = 0; i + 7 <= len && !split; i++)
            if (memcmp(body + i, "\n%%MTL\n", 7) == 0)
                split = body + i, blen = i;
    FILE *f = fopen(file, "wb");
    assert_non_null(f);
    fwrite(body, 1, blen, f);
    fclose(f);
    if (fmt == 2) {
        f = fopen(mtl, "wb");
        assert_non_null(f);
        if (split)
            fwrite(split + 7, 1, len - blen - 7, f);
        fclose(f);
    }
    imp_model *m = NULL;
    rr_status st = imp_load(file, &m, err);
    imp_destroy(m);
    remove(file);
    remove(mtl);
    rmdir(dir);
    free(data);
    return st;
}

static void load_model_seed(const char *path)
{
    rr_error err = {0};
    if (load_model_input(path, &err) != RR_OK)
        fail_msg("seed %s no longer loads: %s", path, err.msg);
}

static void fuzz_corpus_seeds(void **state)
{
    (void)state;
    assert_true(for_each_file(CORPUS "/scene", load_scene_seed) >= 5);
    assert_true(for_each_file(CORPUS "/mesh", load_mesh_seed) >= 5);
    assert_true(for_each_file(CORPUS "/model", load_model_seed) >= 5);
}

/* Fuzzing findings of the importer (notes/robustness.md): a statement
 * after a lone CR or a NUL that radray's .mtl reader did not see made
 * Assimp's crash (it reads the .mtl no more), an OBJ whose hidden usemtl
 * got the default grey. Each is refused now, with the line. */
static void model_findings_refused(void **state)
{
    (void)state;
    static const struct {
        const char *file, *want;
    } cases[] = {
        {"model-mtl-cr-hides-statement-assimp-segv", "before any newmtl"},
        {"model-mtl-nul-hides-statement-assimp-segv", "NUL byte"},
        {"model-obj-cr-hides-mtllib-assimp-segv", ""},
        {"model-obj-cr-hides-usemtl-default-material", "usemtl"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[512];
        snprintf(path, sizeof path, "%s/tests/fuzz/findings/%s", RR_SOURCE_DIR, cases[i].file);
        rr_error err = {0};
        rr_status st = load_model_input(path, &err);
        printf("%s: %s\n", cases[i].file, st == RR_OK ? "loads" : err.msg);
        if (cases[i].want[0] && (st == RR_OK || !strstr(err.msg, cases[i].want)))
            fail_msg("%s: expected a refusal mentioning \"%s\", got %s", cases[i].file, cases[i].want,
                     st == RR_OK ? "RR_OK" : err.msg);
    }
}

/* Fuzzing finding: a PLY "format ascii <v>" line whose version is nan, inf or
 * beyond float range made OpenMesh 9 loop forever. It must be refused. The
 * test gives the loader 20 s (alarm) so a regression fails instead of hanging. */
static void ply_version_not_a_number(void **state)
{
    (void)state;
    static const char *versions[] = {"inf", "nan", "-inf", "1e999", "infinity"};
    char dir[] = "/tmp/rr_regress_XXXXXX";
    assert_non_null(mkdtemp(dir));
    alarm(20);
    mesh_tri *m = NULL;
    rr_error err = {0};
    assert_int_equal(mesh_load(RR_SOURCE_DIR "/tests/fuzz/findings/ply-format-version-inf-hang.ply", &m, &err),
                     RR_ERR_PARSE);
    assert_null(m);
    for (size_t i = 0; i < sizeof versions / sizeof versions[0]; i++) {
        char path[128];
        snprintf(path, sizeof path, "%s/v%zu.ply", dir, i);
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fprintf(f, "ply\nformat ascii %s\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                versions[i]);
        fclose(f);
        assert_int_equal(mesh_load(path, &m, &err), RR_ERR_PARSE);
        assert_null(m);
        assert_non_null(strstr(err.msg, "format version"));
        remove(path);
    }
    alarm(0);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(fuzz_corpus_seeds),
        cmocka_unit_test(model_findings_refused),
        cmocka_unit_test(ply_version_not_a_number),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
