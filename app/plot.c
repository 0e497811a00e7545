/* plot.c - the radiosity convergence plot (--plot FILE.png|FILE.svg), drawn
 * with cairo: residual per iteration on a log scale. */
#include <cairo.h>
#include <cairo-svg.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "app.h"

static void draw(cairo_t *cr, double W, double H, const double *res, int n, const char *title)
{
    const double L = 80, R = 20, T = 40, B = 50;
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; i++)
        if (res[i] > 0) {
            lo = fmin(lo, log10(res[i]));
            hi = fmax(hi, log10(res[i]));
        }
    if (!(lo <= hi)) {
        lo = -1;
        hi = 0;
    }
    lo = floor(lo);
    hi = ceil(hi);
    if (hi <= lo)
        hi = lo + 1;
    double pw = W - L - R, ph = H - T - B;
    int nx = n > 1 ? n - 1 : 1;
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, 12);
    cairo_set_line_width(cr, 1);
    /* Grid and labels: one line per decade. */
    for (int e = (int)lo; e <= (int)hi; e++) {
        double y = T + ph * (hi - e) / (hi - lo);
        cairo_set_source_rgb(cr, 0.85, 0.85, 0.85);
        cairo_move_to(cr, L, y);
        cairo_line_to(cr, L + pw, y);
        cairo_stroke(cr);
        char lab[16];
        snprintf(lab, sizeof lab, "1e%d", e);
        cairo_set_source_rgb(cr, 0, 0, 0);
        cairo_move_to(cr, 10, y + 4);
        cairo_show_text(cr, lab);
    }
    char lab[32];
    snprintf(lab, sizeof lab, "%d", n);
    cairo_move_to(cr, L + pw - 10, T + ph + 18);
    cairo_show_text(cr, lab);
    cairo_move_to(cr, L - 3, T + ph + 18);
    cairo_show_text(cr, "1");
    cairo_move_to(cr, L + pw / 2 - 30, H - 12);
    cairo_show_text(cr, "iteration");
    cairo_set_font_size(cr, 14);
    cairo_move_to(cr, L, 24);
    cairo_show_text(cr, title);
    /* Axes. */
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_rectangle(cr, L, T, pw, ph);
    cairo_stroke(cr);
    /* The curve. */
    cairo_set_source_rgb(cr, 0.1, 0.3, 0.8);
    cairo_set_line_width(cr, 2);
    for (int i = 0; i < n; i++) {
        double v = res[i] > 0 ? log10(res[i]) : lo;
        double x = L + pw * (n > 1 ? (double)i / nx : 0.5), y = T + ph * (hi - v) / (hi - lo);
        if (i == 0)
            cairo_move_to(cr, x, y);
        else
            cairo_line_to(cr, x, y);
    }
    cairo_stroke(cr);
}

int app_plot_residuals(const char *path, const double *res, int n, const char *title, rr_error *err)
{
    char tmp[4200];
    if (rr_file_tmpname(path, tmp, sizeof tmp, err) != RR_OK)
        return -1;
    size_t len = strlen(path);
    int svg = len > 4 && strcasecmp(path + len - 4, ".svg") == 0;
    const double W = 640, H = 400;
    cairo_surface_t *sf = svg ? cairo_svg_surface_create(tmp, W, H)
                              : cairo_image_surface_create(CAIRO_FORMAT_RGB24, (int)W, (int)H);
    cairo_t *cr = cairo_create(sf);
    draw(cr, W, H, res, n, title);
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
