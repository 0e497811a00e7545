/* exr_error.c - radray-exr-error TEST.exr REF.exr [BLOCK] [--blocks CSV]: how far an image
 * is from a reference of the same size (main RGB layers), as the radiosity
 * acceptance numbers are stated (notes/radiosity.md):
 *   block     per BLOCK x BLOCK block (default 4) of the mean over its pixels
 *             and channels: |t - r| / r; median and 90th percentile over the
 *             blocks whose reference is above 1 % of the image mean (black
 *             background and the shadowed gaps say nothing about relative error)
 *   rel_rms   the root mean square of those block errors (blocks, not pixels:
 *             the noise of a Monte Carlo reference or render averages out)
 * Prints one line: rel_rms=... block_median=... block_p90=... blocks=N.
 * --blocks CSV also writes every block (bx,by,ref,err: its column and row,
 * the reference's mean, the signed (t - r) / r, empty where not compared),
 * for errors over a region (bench/cornell-ring.py: the ceiling beside the
 * lamp). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "img.h"

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : (x > y);
}

int main(int argc, char **argv)
{
    const char *csv = NULL;
    if (argc >= 5 && strcmp(argv[argc - 2], "--blocks") == 0) {
        csv = argv[argc - 1];
        argc -= 2;
    }
    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: radray-exr-error TEST.exr REF.exr [BLOCK] [--blocks CSV]\n");
        return 2;
    }
    int bs = argc == 4 ? atoi(argv[3]) : 4;
    FILE *bf = NULL;
    if (csv && !(bf = fopen(csv, "w"))) {
        fprintf(stderr, "radray-exr-error: %s: cannot write\n", csv);
        return 2;
    }
    rr_image t = {0}, r = {0};
    rr_error err;
    if (img_read_exr(argv[1], NULL, &t, &err) != RR_OK || img_read_exr(argv[2], NULL, &r, &err) != RR_OK) {
        fprintf(stderr, "radray-exr-error: %s\n", err.msg);
        return 2;
    }
    if (t.width != r.width || t.height != r.height || bs < 1) {
        fprintf(stderr, "radray-exr-error: %s is %dx%d, %s %dx%d (or a bad block size)\n", argv[1], t.width,
                t.height, argv[2], r.width, r.height);
        return 2;
    }
    size_t n = 3 * (size_t)t.width * (size_t)t.height;
    double se = 0, sr = 0;
    for (size_t i = 0; i < n; i++)
        sr += r.px[i];
    double mean = sr / (double)n;
    int bw = t.width / bs, bh = t.height / bs;
    double *e = malloc(((size_t)bw * bh + 1) * sizeof *e);
    size_t ne = 0;
    for (int by = 0; by < bh && e; by++)
        for (int bx = 0; bx < bw; bx++) {
            double st = 0, sref = 0;
            for (int y = by * bs; y < (by + 1) * bs; y++)
                for (int x = bx * bs; x < (bx + 1) * bs; x++)
                    for (int c = 0; c < 3; c++) {
                        size_t k = 3 * ((size_t)y * t.width + x) + c;
                        st += t.px[k];
                        sref += r.px[k];
                    }
            double m = sref / (3.0 * bs * bs);
            if (m > 0.01 * mean) {
                e[ne] = fabs(st - sref) / sref;
                se += e[ne] * e[ne];
                ne++;
                if (bf)
                    fprintf(bf, "%d,%d,%.9g,%.9g\n", bx, by, m, (st - sref) / sref);
            } else if (bf) {
                fprintf(bf, "%d,%d,%.9g,\n", bx, by, m);
            }
        }
    if (bf && fclose(bf) != 0) {
        fprintf(stderr, "radray-exr-error: %s: cannot write\n", csv);
        return 2;
    }
    if (!e || ne == 0) {
        fprintf(stderr, "radray-exr-error: no block to compare\n");
        return 2;
    }
    qsort(e, ne, sizeof *e, cmp_double);
    printf("rel_rms=%.5f block_median=%.5f block_p90=%.5f blocks=%zu\n", sqrt(se / (double)ne), e[ne / 2],
           e[(size_t)(0.9 * (double)(ne - 1))], ne);
    free(e);
    rr_image_free(&t);
    rr_image_free(&r);
    return 0;
}
