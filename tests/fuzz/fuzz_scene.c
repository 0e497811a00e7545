/* fuzz_scene.c - libFuzzer harness for the scene loader (scene_load_string).
 *
 * Each input is taken as scene JSON text (NUL-terminated copy), loaded with a
 * small image budget so that a fuzzed resolution cannot allocate a huge film,
 * and destroyed. Relative mesh paths resolve against FUZZ_BASE_DIR
 * (tests/data/scenes by default, where meshes/tetra.obj lives). Any crash,
 * sanitizer report, leak or abort (RR_CHECK) is a finding: the loader must
 * turn every bad input into an rr_status. See README.md.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene.h"

#ifndef FUZZ_BASE_DIR
#define FUZZ_BASE_DIR ""
#endif

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

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = '\0';

    const char *base = getenv("FUZZ_BASE_DIR");
    scene_load_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.max_image_bytes = (size_t)64 << 20; /* 64 MiB of film at most */

    scene *s = NULL;
    rr_error err;
    rr_error_clear(&err);
    rr_status st = scene_load_string(text, "fuzz.json", base ? base : FUZZ_BASE_DIR, &opts, &s, &err);
    if (st == RR_OK) {
        fuzz_check(s != NULL, "RR_OK must come with a scene");
        scene_destroy(s);
    } else {
        fuzz_check(s == NULL, "on failure *out is untouched");
        fuzz_check(err.msg[0] != '\0', "every failure carries a message");
    }
    free(text);
    return 0;
}
