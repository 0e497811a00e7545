/* exr_digest.c - radray-exr-digest FILE.exr...: prints an FNV-1a digest of
 * each file's pixels (the main RGB and every layer, in name order), not of
 * its bytes: the header carries the render time, so two renders of the same
 * image differ as files but not here. For bench/image-checksums.sh. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "img.h"

static void add(uint64_t *h, const rr_image *im)
{
    const unsigned char *p = (const unsigned char *)im->px;
    size_t n = 3 * sizeof(float) * (size_t)im->width * (size_t)im->height;
    for (size_t i = 0; i < n; i++) {
        *h ^= p[i];
        *h *= 0x100000001b3ULL;
    }
}

int main(int argc, char **argv)
{
    int rc = 0;
    for (int a = 1; a < argc; a++) {
        char names[64][64];
        int n = 0;
        rr_error err;
        uint64_t h = 0xcbf29ce484222325ULL;
        rr_image im = {0};
        if (img_exr_layers(argv[a], names, 64, &n, &err) != RR_OK || img_read_exr(argv[a], NULL, &im, &err) != RR_OK) {
            fprintf(stderr, "radray-exr-digest: %s\n", err.msg);
            rc = 2;
            continue;
        }
        add(&h, &im);
        rr_image_free(&im);
        for (int l = 0; l < n; l++) {
            if (img_read_exr(argv[a], names[l], &im, &err) != RR_OK) {
                fprintf(stderr, "radray-exr-digest: %s\n", err.msg);
                rc = 2;
                break;
            }
            add(&h, &im);
            rr_image_free(&im);
        }
        printf("%016llx  %s\n", (unsigned long long)h, argv[a]);
    }
    return rc;
}
