/* bench_direct.c - radray-bench-direct: the noise of the direct term near an
 * area light's edge (multiple importance sampling), and the error of two EXR
 * renders against a reference.
 *
 *   radray-bench-direct spread [--threads N]
 *       A closed box lit by a ceiling quad lamp that touches the back wall,
 *       the camera on the top of that wall (where 1/d^2 of light sampling
 *       makes the tail): the direct diffuse layer (whitted / hybrid direct
 *       term) at 16, 64 and 256 spp over 4 seeds, against a 4096-spp
 *       reference: per-pixel relative spread (standard deviation over the
 *       seeds / reference, median over the pixels) and the worst pixel of
 *       all the 64-spp renders relative to the reference.
 *   radray-bench-direct error [--layer NAME] REF.exr A.exr [B.exr ...]
 *       relative RMS error of each image (or of one layer, e.g. diffuse:
 *       emitters seen directly dominate the main image's error) against REF
 *       (sqrt(sum (a-r)^2 / sum r^2) over every channel).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "img.h"
#include "rt.h"

#define BOX                                                                                                       \
    "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lookat\",\"eye\":[1,1.5,1.2],\"target\":[1,1.85,0],"   \
    "\"up\":[0,1,0],\"fov\":40,\"width\":48,\"height\":36},"                                                       \
    "\"materials\":{\"white\":{\"diffuse\":[0.6,0.6,0.6]},\"lamp\":{\"diffuse\":0,\"emission\":[6,6,6]}},"        \
    "\"objects\":["                                                                                                \
    "{\"name\":\"floor\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[0,0,2],[2,0,2],[2,0,0]]}," \
    "{\"name\":\"ceiling\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,2,0],[2,2,0],[2,2,2],[0,2,2]]}," \
    "{\"name\":\"back\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[2,0,0],[2,2,0],[0,2,0]]},"  \
    "{\"name\":\"front\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,2],[0,2,2],[2,2,2],[2,0,2]]}," \
    "{\"name\":\"left\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[0,0,0],[0,2,0],[0,2,2],[0,0,2]]},"  \
    "{\"name\":\"right\",\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[2,0,0],[2,0,2],[2,2,2],[2,2,0]]}," \
    "{\"name\":\"lamp\",\"type\":\"quad\",\"material\":\"lamp\","                                                  \
    "\"vertices\":[[0.8,1.999,0.001],[1.2,1.999,0.001],[1.2,1.999,0.4],[0.8,1.999,0.4]]}]}"

static int render(const scene *s, const rt_accel *a, int spp, uint64_t seed, int threads, rt_film *f)
{
    rt_render_opts o;
    memset(&o, 0, sizeof o);
    o.spp = spp;
    o.seed = seed;
    o.threads = threads;
    o.max_depth = s->settings.max_depth;
    o.light_samples = s->settings.light_samples;
    o.indirect = RT_INDIRECT_NONE;
    rr_error err;
    if (rt_film_init(f, s->view.width, s->view.height, &err) != RR_OK || rt_render(s, a, &o, f, &err) != RR_OK) {
        fprintf(stderr, "radray-bench-direct: %s\n", err.msg);
        return -1;
    }
    return 0;
}

static double pxv(const rr_image *im, size_t k) { return (im->px[3 * k] + im->px[3 * k + 1] + im->px[3 * k + 2]) / 3.0; }

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int spread(int threads)
{
    scene *s;
    rt_accel *a;
    rr_error err;
    if (scene_load_string(BOX, "box", "", NULL, &s, &err) != RR_OK || rt_accel_build(s, &a, &err) != RR_OK) {
        fprintf(stderr, "radray-bench-direct: %s\n", err.msg);
        return 1;
    }
    rt_film ref;
    if (render(s, a, 4096, 99, threads, &ref))
        return 1;
    size_t n = (size_t)s->view.width * (size_t)s->view.height;
    const rr_image *R = &ref.layer[RT_LAYER_DIFFUSE];
    enum { SEEDS = 4 };
    static const int spps[] = {16, 64, 256};
    printf("direct diffuse layer, %d x %d px beside a quad lamp, light_samples %d; reference 4096 spp\n",
           s->view.width, s->view.height, s->settings.light_samples);
    printf("%6s %22s %22s %20s\n", "spp", "median rel. spread", "x sqrt(spp/16)", "worst pixel vs ref");
    double *rel = malloc(n * sizeof *rel);
    for (size_t q = 0; q < sizeof spps / sizeof spps[0]; q++) {
        rt_film f[SEEDS];
        for (int k = 0; k < SEEDS; k++)
            if (render(s, a, spps[q], (uint64_t)k + 1, threads, &f[k]))
                return 1;
        size_t m = 0;
        double worst = 0;
        for (size_t i = 0; i < n; i++) {
            double r = pxv(R, i);
            if (!(r > 1e-3))
                continue;
            double mean = 0, var = 0;
            for (int k = 0; k < SEEDS; k++)
                mean += pxv(&f[k].layer[RT_LAYER_DIFFUSE], i) / SEEDS;
            for (int k = 0; k < SEEDS; k++) {
                double d = pxv(&f[k].layer[RT_LAYER_DIFFUSE], i) - mean;
                var += d * d / (SEEDS - 1);
                worst = fmax(worst, pxv(&f[k].layer[RT_LAYER_DIFFUSE], i) / r - 1.0);
            }
            rel[m++] = sqrt(var) / r;
        }
        qsort(rel, m, sizeof *rel, cmp_double);
        double med = m ? rel[m / 2] : 0;
        printf("%6d %21.4f%% %21.4f%% %+19.1f%%   (%zu pixels)\n", spps[q], 100 * med, 100 * med * sqrt(spps[q] / 16.0),
               100 * worst, m);
        for (int k = 0; k < SEEDS; k++)
            rt_film_free(&f[k]);
    }
    free(rel);
    rt_film_free(&ref);
    rt_accel_destroy(a);
    scene_destroy(s);
    return 0;
}

static int error(const char *layer, int argc, char **argv)
{
    rr_image ref;
    rr_error err;
    if (img_read_exr(argv[0], layer, &ref, &err) != RR_OK) {
        fprintf(stderr, "radray-bench-direct: %s\n", err.msg);
        return 2;
    }
    size_t n = 3 * (size_t)ref.width * (size_t)ref.height;
    for (int i = 1; i < argc; i++) {
        rr_image im;
        if (img_read_exr(argv[i], layer, &im, &err) != RR_OK) {
            fprintf(stderr, "radray-bench-direct: %s\n", err.msg);
            return 2;
        }
        if (im.width != ref.width || im.height != ref.height) {
            fprintf(stderr, "radray-bench-direct: %s is %d x %d, the reference %d x %d\n", argv[i], im.width,
                    im.height, ref.width, ref.height);
            return 2;
        }
        double num = 0, den = 0;
        for (size_t k = 0; k < n; k++) {
            double d = (double)im.px[k] - (double)ref.px[k];
            num += d * d;
            den += (double)ref.px[k] * (double)ref.px[k];
        }
        printf("%s: relative RMS error %.4f\n", argv[i], sqrt(num / den));
        rr_image_free(&im);
    }
    rr_image_free(&ref);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "spread"))
        return spread(argc >= 4 && !strcmp(argv[2], "--threads") ? atoi(argv[3]) : 0);
    if (argc >= 6 && !strcmp(argv[1], "error") && !strcmp(argv[2], "--layer"))
        return error(argv[3], argc - 4, argv + 4);
    if (argc >= 4 && !strcmp(argv[1], "error"))
        return error(NULL, argc - 2, argv + 2);
    fprintf(stderr, "usage: radray-bench-direct spread [--threads N]\n"
                    "       radray-bench-direct error [--layer NAME] REF.exr A.exr [B.exr ...]\n");
    return 2;
}
