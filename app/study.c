/* study.c - what `radray compare` measures against a reference (app.h,
 * "study.c"): the pixels each object fills whole, the statistics file
 * (--stats) and the convergence plot (--convergence). The metrics themselves
 * are metrics.c's. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"

static int object_hit(const scene *sc, const rt_accel *a, int col, int row, double dx, double dy)
{
    rt_hit hit;
    return rt_accel_closest(a, rr_view_ray(&sc->view, col, row, dx, dy), 0.0, INFINITY, &hit) ? (int)hit.object : -1;
}

int *app_pixel_regions(const scene *sc, const rt_accel *a)
{
    int w = sc->view.width, h = sc->view.height;
    int *region = malloc(sizeof *region * (size_t)w * (size_t)h);
    int *corner = malloc(sizeof *corner * (size_t)(w + 1) * (size_t)(h + 1));
    if (!region || !corner) {
        free(region);
        free(corner);
        return NULL;
    }
    /* Corner (i, j) is the top-left corner of pixel (i, j); the last row and
     * column are the far corners of the last pixels. */
    for (int j = 0; j <= h; j++)
        for (int i = 0; i <= w; i++)
            corner[(size_t)j * (size_t)(w + 1) + (size_t)i] =
                object_hit(sc, a, i < w ? i : w - 1, j < h ? j : h - 1, i < w ? -0.5 : 0.5, j < h ? 0.5 : -0.5);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int o = object_hit(sc, a, x, y, 0, 0);
            const int *c0 = corner + (size_t)y * (size_t)(w + 1) + (size_t)x, *c1 = c0 + w + 1;
            region[(size_t)y * (size_t)w + (size_t)x] = c0[0] == o && c0[1] == o && c1[0] == o && c1[1] == o ? o : -1;
        }
    free(corner);
    return region;
}

void app_json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

static void json_metric(FILE *f, const char *name, app_metric m)
{
    fprintf(f, "\"%s\": %.9g, \"%s_se\": %.9g", name, m.value, name, m.se);
}

/* One row: the metrics mt of panel `panel` over `area`, as JSON or CSV
 * (ssim NaN: not given). */
static void stats_row(FILE *f, int json, const char *panel, const char *area, const app_metrics *mt, double ssim,
                      int first)
{
    if (!json) {
        fprintf(f, "%s,%s,%ld,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", panel, area, mt->pixels, mt->relmse.value,
                mt->relmse.se, mt->mare.value, mt->mare.se, mt->bias.value, mt->bias.se, ssim);
        return;
    }
    fprintf(f, "%s\n    {\"panel\": ", first ? "" : ",");
    app_json_string(f, panel);
    fputs(", \"region\": ", f);
    app_json_string(f, area);
    fprintf(f, ", \"pixels\": %ld, ", mt->pixels);
    json_metric(f, "relmse", mt->relmse);
    fputs(", ", f);
    json_metric(f, "mare", mt->mare);
    fputs(", ", f);
    json_metric(f, "bias", mt->bias);
    if (isfinite(ssim))
        fprintf(f, ", \"ssim\": %.9g", ssim);
    fputs("}", f);
}

int app_write_stats(const char *path, const app_study *st, int quiet)
{
    const scene *sc = st->sc;
    int *region = app_pixel_regions(sc, st->accel);
    long *count = calloc(sc->nobjects + 1, sizeof *count);
    rr_error err;
    FILE *f = NULL;
    char tmp[4096];
    int json = app_ends_with(path, ".json"), rc = -1;
    if (!region || !count) {
        app_error("out of memory");
        goto done;
    }
    size_t npx = (size_t)sc->view.width * (size_t)sc->view.height;
    for (size_t p = 0; p < npx; p++)
        if (region[p] >= 0)
            count[region[p]]++;
    if (rr_file_make_parent_dirs(path, &err) != RR_OK || rr_file_tmpname(path, tmp, sizeof tmp, &err) != RR_OK ||
        !(f = fopen(tmp, "w"))) {
        app_error("--stats %s: cannot write it", path);
        goto done;
    }
    if (json) {
        fputs("{\"reference\": ", f);
        app_json_string(f, st->titles[st->ref]);
        fprintf(f, ", \"eps\": %g, \"rows\": [", APP_METRIC_EPS);
    } else {
        fputs("panel,region,pixels,relmse,relmse_se,mare,mare_se,bias,bias_se,ssim\n", f);
    }
    long threshold = (long)fmax(4.0, 0.001 * (double)npx); /* the figure's table rows */
    int first = 1;
    for (int i = 0; i < st->n; i++) {
        if (i == st->ref)
            continue;
        stats_row(f, json, st->titles[i], "(all pixels)", &st->whole[i], st->ssim[i], first);
        first = 0;
        for (size_t o = 0; o < sc->nobjects; o++) {
            if (count[o] < threshold)
                continue;
            app_metrics mt;
            app_metrics_region(&st->img[i], &st->img[st->ref], region, (int)o, &mt);
            stats_row(f, json, st->titles[i], sc->objects[o].name, &mt, NAN, 0);
        }
    }
    if (json)
        fputs("\n]}\n", f);
    int bad = ferror(f);
    if (fclose(f) != 0 || bad || rename(tmp, path) != 0) {
        remove(tmp);
        app_error("--stats %s: write failed", path);
        goto done;
    }
    if (!quiet)
        printf("wrote %s (statistics against %s)\n", path, st->titles[st->ref]);
    rc = 0;
done:
    free(region);
    free(count);
    return rc;
}

enum { CONV_MAX = 16, CONV_MODES = 16 };

rr_status app_convergence(const char *path, ig_session *ses, scene *sc, const app_conv_mode *modes, int n,
                          const rr_image *ref, const char *ref_title, rt_film *film, int quiet, rr_error *err)
{
    int base_spp = sc->settings.spp, ns = 0;
    static double xs[CONV_MODES][CONV_MAX], ys[CONV_MODES][CONV_MAX];
    app_series series[CONV_MODES];
    if (!quiet)
        printf("convergence against %s: mode, spp, seconds, relMSE\n", ref_title);
    for (int i = 0; i < n && ns < CONV_MODES; i++, ns++) {
        int k = 0;
        for (long spp = 1; spp <= modes[i].spp && k < CONV_MAX; spp *= 2, k++) {
            sc->settings.spp = (int)spp;
            double secs = 0;
            rr_status st = ig_render(ses, modes[i].ig, NULL, film, &secs, err);
            sc->settings.spp = base_spp;
            if (st != RR_OK)
                return st;
            app_metrics mt;
            app_metrics_region(&film->beauty, ref, NULL, 0, &mt);
            xs[ns][k] = secs + modes[i].extra_seconds;
            ys[ns][k] = mt.relmse.value;
            if (!quiet)
                printf("  %-10s %8ld %10.3f %12.4g\n", modes[i].ig->name, spp, xs[ns][k], ys[ns][k]);
        }
        series[ns] = (app_series){modes[i].ig->name, xs[ns], ys[ns], k};
    }
    char title[160];
    snprintf(title, sizeof title, "relMSE against %s by render time (spp 1, 2, 4, ...)", ref_title);
    if (rr_file_make_parent_dirs(path, err) != RR_OK ||
        app_plot_lines(path, series, ns, title, "seconds (radiosity pass included)", "relMSE", 1, err))
        return err && err->code != RR_OK ? err->code : RR_ERR_IO;
    if (!quiet)
        printf("wrote %s (convergence plot)\n", path);
    return RR_OK;
}
