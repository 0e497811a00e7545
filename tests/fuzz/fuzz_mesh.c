/* fuzz_mesh.c - libFuzzer harness for the mesh loaders (mesh_load + mesh_analyze).
 *
 * Each input is written to a file in a private temporary folder and loaded
 * through mesh_load. The format is chosen by the file's extension, so the
 * input is tried as each of .obj .ply .off .stl in turn, or only as the one
 * named by the environment variable FUZZ_MESH_EXT (e.g. FUZZ_MESH_EXT=ply) to
 * focus a run on one reader. A loaded mesh is analysed (mesh_analyze) and
 * destroyed. Any crash, sanitizer report, leak or abort is a finding. See
 * README.md.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "mesh.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
/* A broken loader contract is a finding: say which, then abort so that
 * libFuzzer saves the input. */
static void fuzz_check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz: contract broken: %s\n", what);
        abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char fuzz_dir[256];
static const char *fuzz_exts[] = {"obj", "ply", "off", "stl"};
static size_t fuzz_first = 0, fuzz_count = 4;

static void fuzz_cleanup(void)
{
    char path[320];
    for (size_t i = 0; i < 4; i++) {
        snprintf(path, sizeof path, "%s/in.%s", fuzz_dir, fuzz_exts[i]);
        unlink(path);
    }
    rmdir(fuzz_dir);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    const char *tmp = getenv("TMPDIR");
    snprintf(fuzz_dir, sizeof fuzz_dir, "%s/radray-fuzz-mesh-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(fuzz_dir)) {
        perror("fuzz_mesh: mkdtemp");
        exit(1);
    }
    atexit(fuzz_cleanup);
    const char *only = getenv("FUZZ_MESH_EXT");
    if (only && *only) {
        for (size_t i = 0; i < 4; i++)
            if (strcmp(only, fuzz_exts[i]) == 0) {
                fuzz_first = i;
                fuzz_count = 1;
            }
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[320];
    for (size_t i = fuzz_first; i < fuzz_first + fuzz_count; i++) {
        snprintf(path, sizeof path, "%s/in.%s", fuzz_dir, fuzz_exts[i]);
        FILE *f = fopen(path, "wb");
        fuzz_check(f != NULL, "cannot create the input file");
        fuzz_check(!size || fwrite(data, 1, size, f) == size, "cannot write the input file");
        fuzz_check(fclose(f) == 0, "cannot close the input file");

        mesh_tri *m = NULL;
        rr_error err;
        rr_error_clear(&err);
        rr_status st = mesh_load(path, &m, &err);
        if (st == RR_OK) {
            fuzz_check(m != NULL, "RR_OK must come with a mesh");
            mesh_report rep;
            fuzz_check(mesh_analyze(m, &rep, &err) == RR_OK || err.msg[0] != '\0', "analysis failures carry a message");
            mesh_destroy(m);
        } else {
            fuzz_check(m == NULL, "on failure *out is untouched");
            fuzz_check(err.msg[0] != '\0', "every failure carries a message");
        }
    }
    return 0;
}
