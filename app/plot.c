/* plot.c - line plots drawn with cairo, PNG or SVG: the radiosity solver's
 * convergence (--plot: residual per iteration) and compare's error against
 * time (--convergence). The y axis is logarithmic, the x axis linear or
 * logarithmic. */
#include <cairo.h>
#include <cairo-svg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "app.h"

/* The decades [lo, hi] (log10) that hold every positive value of v. */
static void decades(const double *v, int n, double *lo, double *hi)
{
    *lo = INFINITY;
    *hi = -INFINITY;
    for (int i = 0; i < n; i++)
        if (v[i] > 0 && isfinite(v[i])) {
            *lo = fmin(*lo, log10(v[i]));
            *hi = fmax(*hi, log10(v[i]));
        }
    if (!(*lo <= *hi)) {
        *lo = -1;
        *hi = 0;
    }
    *lo = floor(*lo);
    *hi = ceil(*hi);
    if (*hi <= *lo)
        *hi = *lo + 1;
}

typedef struct axes {
    double L, T, pw, ph;     /* plot area */
    double xlo, xhi, ylo, yhi; /* x in its own units (log10 when logx), y in decades */
    int logx;
} axes;

static double px(const axes *a, double x)
{
    double u = a->logx ? (x > 0 ? log10(x) : a->xlo) : x;
    return a->L + a->pw * (u - a->xlo) / (a->xhi - a->xlo);
}

static double py(const axes *a, double y)
{
    double v = y > 0 && isfinite(y) ? log10(y) : a->ylo;
    return a->T + a->ph * (a->yhi - v) / (a->yhi - a->ylo);
}

static void draw_axes(cairo_t *cr, const axes *a, const char *title, const char *xlabel, const char *ylabel,
                      double H)
{
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, 12);
    cairo_set_line_width(cr, 1);
    char lab[32];
    for (int e = (int)a->ylo; e <= (int)a->yhi; e++) { /* one grid line per decade */
        double y = a->T + a->ph * (a->yhi - e) / (a->yhi - a->ylo);
        cairo_set_source_rgb(cr, 0.85, 0.85, 0.85);
        cairo_move_to(cr, a->L, y);
        cairo_line_to(cr, a->L + a->pw, y);
        cairo_stroke(cr);
        snprintf(lab, sizeof lab, "1e%d", e);
        cairo_set_source_rgb(cr, 0, 0, 0);
        cairo_move_to(cr, 10, y + 4);
        cairo_show_text(cr, lab);
    }
    if (a->logx) {
        for (int e = (int)floor(a->xlo); e <= (int)ceil(a->xhi); e++) {
            if (e < a->xlo || e > a->xhi)
                continue;
            double x = a->L + a->pw * (e - a->xlo) / (a->xhi - a->xlo);
            cairo_set_source_rgb(cr, 0.85, 0.85, 0.85);
            cairo_move_to(cr, x, a->T);
            cairo_line_to(cr, x, a->T + a->ph);
            cairo_stroke(cr);
            snprintf(lab, sizeof lab, "1e%d", e);
            cairo_set_source_rgb(cr, 0, 0, 0);
            cairo_move_to(cr, x - 10, a->T + a->ph + 18);
            cairo_show_text(cr, lab);
        }
    } else {
        snprintf(lab, sizeof lab, "%g", a->xlo);
        cairo_move_to(cr, a->L - 3, a->T + a->ph + 18);
        cairo_show_text(cr, lab);
        snprintf(lab, sizeof lab, "%g", a->xhi);
        cairo_move_to(cr, a->L + a->pw - 10, a->T + a->ph + 18);
        cairo_show_text(cr, lab);
    }
    cairo_move_to(cr, a->L + a->pw / 2 - 30, H - 12);
    cairo_show_text(cr, xlabel);
    cairo_move_to(cr, 10, a->T - 16);
    cairo_show_text(cr, ylabel);
    cairo_set_font_size(cr, 14);
    cairo_move_to(cr, a->L, 20);
    cairo_show_text(cr, title);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_rectangle(cr, a->L, a->T, a->pw, a->ph);
    cairo_stroke(cr);
}

static void draw(cairo_t *cr, double W, double H, const app_series *s, int ns, const char *title,
                 const char *xlabel, const char *ylabel, int logx)
{
    static const double colour[][3] = {{0.10, 0.30, 0.80}, {0.85, 0.35, 0.10}, {0.10, 0.60, 0.25},
                                       {0.60, 0.20, 0.65}, {0.40, 0.40, 0.40}, {0.75, 0.60, 0.05}};
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    axes a = {80, 62, W - 80 - 150, H - 62 - 50, INFINITY, -INFINITY, INFINITY, -INFINITY, logx};
    for (int k = 0; k < ns; k++) {
        double lo, hi;
        decades(s[k].y, s[k].n, &lo, &hi);
        a.ylo = fmin(a.ylo, lo);
        a.yhi = fmax(a.yhi, hi);
        for (int i = 0; i < s[k].n; i++) {
            double u = logx ? (s[k].x[i] > 0 ? log10(s[k].x[i]) : NAN) : s[k].x[i];
            if (isfinite(u)) {
                a.xlo = fmin(a.xlo, u);
                a.xhi = fmax(a.xhi, u);
            }
        }
    }
    if (!(a.xlo <= a.xhi))
        a.xlo = 0, a.xhi = 1;
    if (logx) {
        a.xlo = floor(a.xlo * 4) / 4; /* a little room, in quarter decades */
        a.xhi = ceil(a.xhi * 4) / 4;
    }
    if (a.xhi <= a.xlo)
        a.xhi = a.xlo + 1;
    if (!(a.ylo <= a.yhi))
        a.ylo = -1, a.yhi = 0;
    draw_axes(cr, &a, title, xlabel, ylabel, H);
    cairo_set_line_width(cr, 2);
    for (int k = 0; k < ns; k++) {
        const double *c = colour[k % 6];
        cairo_set_source_rgb(cr, c[0], c[1], c[2]);
        for (int i = 0; i < s[k].n; i++) {
            double x = px(&a, s[k].x[i]), y = py(&a, s[k].y[i]);
            if (i == 0)
                cairo_move_to(cr, x, y);
            else
                cairo_line_to(cr, x, y);
        }
        cairo_stroke(cr);
        for (int i = 0; s[k].n > 1 && i < s[k].n; i++) { /* the measured points */
            cairo_arc(cr, px(&a, s[k].x[i]), py(&a, s[k].y[i]), 3, 0, 2 * RR_PI);
            cairo_fill(cr);
        }
        if (s[k].name) {
            double ly = a.T + 16 + 18 * k;
            cairo_move_to(cr, a.L + a.pw + 12, ly - 4);
            cairo_line_to(cr, a.L + a.pw + 32, ly - 4);
            cairo_stroke(cr);
            cairo_set_source_rgb(cr, 0, 0, 0);
            cairo_set_font_size(cr, 12);
            cairo_move_to(cr, a.L + a.pw + 38, ly);
            cairo_show_text(cr, s[k].name);
        }
    }
}

int app_plot_lines(const char *path, const app_series *s, int ns, const char *title, const char *xlabel,
                   const char *ylabel, int logx, rr_error *err)
{
    char tmp[4200];
    if (rr_file_tmpname(path, tmp, sizeof tmp, err) != RR_OK)
        return -1;
    size_t len = strlen(path);
    int svg = len > 4 && strcasecmp(path + len - 4, ".svg") == 0;
    const double W = 760, H = 420;
    cairo_surface_t *sf = svg ? cairo_svg_surface_create(tmp, W, H)
                              : cairo_image_surface_create(CAIRO_FORMAT_RGB24, (int)W, (int)H);
    cairo_t *cr = cairo_create(sf);
    draw(cr, W, H, s, ns, title, xlabel, ylabel, logx);
    cairo_destroy(cr);
    cairo_status_t cs;
    if (svg) {
        cairo_surface_finish(sf);
        cs = cairo_surface_status(sf);
    } else {
        cs = cairo_surface_write_to_png(sf, tmp);
    }
    cairo_surface_destroy(sf);
    if (cs != CAIRO_STATUS_SUCCESS) {
        remove(tmp);
        rr_error_set(err, RR_ERR_IO, "%s: cannot write the plot: %s", path, cairo_status_to_string(cs));
        return -1;
    }
    return rr_file_replace(tmp, path, err) == RR_OK ? 0 : -1;
}

int app_plot_residuals(const char *path, const double *res, int n, const char *title, rr_error *err)
{
    double *x = malloc((size_t)(n > 0 ? n : 1) * sizeof *x);
    if (!x) {
        rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory for the plot", path);
        return -1;
    }
    for (int i = 0; i < n; i++)
        x[i] = i + 1;
    app_series s = {NULL, x, res, n};
    int rc = app_plot_lines(path, &s, 1, title, "iteration", "residual", 0, err);
    free(x);
    return rc;
}
