/* metrics.c - image error metrics of `radray compare` against a reference
 * (app.h, "metrics.c"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"
#include "img.h"

/* Adds per-pixel value v (the mean over R, G, B of a per-channel term) to a
 * running mean and its standard error. */
typedef struct acc {
    double sum, sum2;
    long n;
} acc;

static void acc_add(acc *a, double v)
{
    a->sum += v;
    a->sum2 += v * v;
    a->n++;
}

static app_metric acc_value(const acc *a)
{
    app_metric m = {0.0, 0.0};
    if (a->n == 0)
        return m;
    double mean = a->sum / (double)a->n;
    double var = a->n > 1 ? fmax(0.0, (a->sum2 - (double)a->n * mean * mean) / (double)(a->n - 1)) : 0.0;
    m.value = mean;
    m.se = sqrt(var / (double)a->n);
    return m;
}

void app_metrics_region(const rr_image *x, const rr_image *r, const int *region, int which, app_metrics *out)
{
    acc rel = {0}, mare = {0}, bias = {0};
    size_t npx = (size_t)x->width * (size_t)x->height;
    for (size_t p = 0; p < npx; p++) {
        if (region && region[p] != which)
            continue;
        double vr = 0, vm = 0, vb = 0;
        for (int c = 0; c < 3; c++) {
            double a = x->px[3 * p + c], b = r->px[3 * p + c], d = a - b;
            vr += d * d / (b * b + APP_METRIC_EPS);
            vm += fabs(d) / (fabs(b) + APP_METRIC_EPS);
            vb += d / (fabs(b) + APP_METRIC_EPS);
        }
        acc_add(&rel, vr / 3.0);
        acc_add(&mare, vm / 3.0);
        acc_add(&bias, vb / 3.0);
    }
    out->relmse = acc_value(&rel);
    out->mare = acc_value(&mare);
    out->bias = acc_value(&bias);
    out->pixels = rel.n;
    out->ssim = NAN;
}

/* Display luminance of pixel p: each channel times 2^exposure, clamped to
 * [0, 1], sRGB-encoded (what the figure shows), then Rec. 709 weights. */
static double display_luma(const rr_image *im, size_t p, double scale)
{
    static const double w[3] = {0.2126, 0.7152, 0.0722};
    double y = 0;
    for (int c = 0; c < 3; c++)
        y += w[c] * img_srgb_encode(fmin(1.0, fmax(0.0, im->px[3 * p + c] * scale)));
    return y;
}

double app_metric_ssim(const rr_image *x, const rr_image *r, double exposure)
{
    enum { HALF = 5 }; /* 11 x 11 Gaussian window, sigma 1.5 (Wang et al. 2004) */
    int w = x->width, h = x->height;
    size_t npx = (size_t)w * (size_t)h;
    double *a = malloc(npx * sizeof *a), *b = malloc(npx * sizeof *b);
    if (!a || !b) {
        free(a);
        free(b);
        return NAN;
    }
    double scale = pow(2.0, exposure);
    for (size_t p = 0; p < npx; p++) {
        a[p] = display_luma(x, p, scale);
        b[p] = display_luma(r, p, scale);
    }
    double g[2 * HALF + 1];
    for (int k = -HALF; k <= HALF; k++)
        g[k + HALF] = exp(-(double)(k * k) / (2.0 * 1.5 * 1.5));
    const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03; /* (K L)^2 with L = 1 */
    double total = 0;
    for (int y = 0; y < h; y++)
        for (int xx = 0; xx < w; xx++) {
            /* The window clipped to the image, renormalised. */
            double sw = 0, ma = 0, mb = 0, saa = 0, sbb = 0, sab = 0;
            for (int dy = -HALF; dy <= HALF; dy++)
                for (int dx = -HALF; dx <= HALF; dx++) {
                    int u = xx + dx, v = y + dy;
                    if (u < 0 || v < 0 || u >= w || v >= h)
                        continue;
                    double gw = g[dx + HALF] * g[dy + HALF];
                    size_t q = (size_t)v * (size_t)w + (size_t)u;
                    sw += gw;
                    ma += gw * a[q];
                    mb += gw * b[q];
                    saa += gw * a[q] * a[q];
                    sbb += gw * b[q] * b[q];
                    sab += gw * a[q] * b[q];
                }
            ma /= sw;
            mb /= sw;
            double va = fmax(0.0, saa / sw - ma * ma), vb = fmax(0.0, sbb / sw - mb * mb), cov = sab / sw - ma * mb;
            total += (2 * ma * mb + c1) * (2 * cov + c2) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
        }
    free(a);
    free(b);
    return total / (double)npx;
}
