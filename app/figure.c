/* figure.c - the comparison figure of `radray compare` (see figure.h), drawn
 * with cairo on an image surface (PNG) or a vector surface (PDF, SVG). The
 * layout is measured first (text widths decide the table's columns), then
 * drawn once onto the surface of the final size. */
#include <cairo-pdf.h>
#include <cairo-svg.h>
#include <cairo.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "figure.h"
#include "img.h"

/* Layout, in pixels (points on PDF). */
enum {
    MARGIN = 16,
    GAP = 12,         /* between panel columns */
    WRAP_W = 1240,    /* panel rows wrap beyond this width (eight layers made one 1,550-px row) */
    HEADER = 50,      /* title and subtitle */
    LABEL = 38,       /* panel name and caption above each image */
    ROW_GAP = 14,     /* between the panel row and the difference row */
    MIN_COLUMN = 180, /* panel columns are at least this wide, so that their labels fit */
    SMALL = 120,      /* renders narrower than this are enlarged (whole pixels) to MIN_COLUMN */
    TABLE_ROW = 18,
    SCALE_H = 68      /* the colour scale: bar, tick labels, two lines of note */
};

void fig_cell(const fig_table *t, int row, int col, char *buf, size_t n)
{
    double v = t->mean[(size_t)row * (size_t)t->ncols + (size_t)col];
    if (t->ref < 0) {
        snprintf(buf, n, "%.4g", v);
    } else if (col == t->ref) {
        snprintf(buf, n, "%.4g (ref)", v);
    } else {
        double r = t->mean[(size_t)row * (size_t)t->ncols + (size_t)t->ref];
        /* A black reference region has no meaningful relative difference. */
        double pct = fabs(r) < 1e-9 ? 0 : 100.0 * (v - r) / r;
        if (fabs(r) < 1e-9)
            snprintf(buf, n, "%.4g (n/a)", v);
        else if (fabs(pct) < 0.05) /* no "-0.0%" */
            snprintf(buf, n, "%.4g (0.0%%)", v);
        else
            snprintf(buf, n, "%.4g (%+.1f%%)", v, pct);
    }
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The colour scale's top is the 99th percentile of all differences, so that
 * a few Monte Carlo fireflies do not turn every other difference black. */
int fig_make_diffs(const rr_image *img, int n, int ref, float **diff, double *top, int *clipped)
{
    size_t npx = (size_t)img[0].width * (size_t)img[0].height, all_n = 0;
    float *all = malloc(sizeof *all * npx * (size_t)(n > 1 ? n - 1 : 1));
    if (!all)
        return -1;
    double mx = 0;
    for (int i = 0; i < n; i++) {
        if (i == ref)
            continue;
        if (!(diff[i] = malloc(sizeof *diff[i] * npx))) {
            free(all);
            return -1;
        }
        for (size_t p = 0; p < npx; p++) {
            const float *a = img[i].px + 3 * p, *b = img[ref].px + 3 * p;
            float d = (fabsf(a[0] - b[0]) + fabsf(a[1] - b[1]) + fabsf(a[2] - b[2])) / 3.0f;
            diff[i][p] = d;
            all[all_n++] = d;
            mx = fmax(mx, d);
        }
    }
    qsort(all, all_n, sizeof *all, cmp_float);
    *top = all_n ? all[(size_t)(0.99 * (double)(all_n - 1))] : 0;
    free(all);
    if (*top <= 0 || mx <= *top * 1.0001)
        *top = mx > 0 ? mx : 1;
    *clipped = mx > *top;
    return 0;
}

/* Plain-text twin of the figure's table, columns padded to line up. */
void fig_print_table(FILE *f, const fig_table *t)
{
    char buf[96];
    int wname = 6, wcol[FIG_MAX_PANELS], nc = t->ncols < FIG_MAX_PANELS ? t->ncols : FIG_MAX_PANELS;
    for (int r = 0; r < t->nrows; r++)
        wname = (int)fmax(wname, (double)strlen(t->rows[r]));
    for (int c = 0; c < nc; c++) {
        wcol[c] = (int)strlen(t->cols[c]);
        for (int r = 0; r < t->nrows; r++) {
            fig_cell(t, r, c, buf, sizeof buf);
            wcol[c] = (int)fmax(wcol[c], (double)strlen(buf));
        }
    }
    fprintf(f, "%s\n%-*s  %8s", t->title, wname, "region", "pixels");
    for (int c = 0; c < nc; c++)
        fprintf(f, "  %*s", wcol[c], t->cols[c]);
    fputc('\n', f);
    for (int r = 0; r < t->nrows; r++) {
        fprintf(f, "%-*s  %8ld", wname, t->rows[r], t->pixels[r]);
        for (int c = 0; c < nc; c++) {
            fig_cell(t, r, c, buf, sizeof buf);
            fprintf(f, "  %*s", wcol[c], buf);
        }
        fputc('\n', f);
    }
}

static void font(cairo_t *cr, double size, int bold)
{
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
                           bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, size);
}

static double text_width(cairo_t *cr, const char *s)
{
    cairo_text_extents_t e;
    cairo_text_extents(cr, s, &e);
    return e.x_advance;
}

/* align: 0 left of x, 1 right-aligned to x, 2 centred on x. */
static void text(cairo_t *cr, double x, double y, int align, const char *s)
{
    double w = align ? text_width(cr, s) : 0;
    cairo_move_to(cr, align == 1 ? x - w : align == 2 ? x - w / 2 : x, y);
    cairo_show_text(cr, s);
}

/* Inferno, sampled at 9 even steps: perceptually ordered and readable in grey,
 * so a larger difference always looks brighter. */
static void inferno(double t, unsigned char rgb[3])
{
    static const unsigned char k[9][3] = {{0, 0, 4},      {31, 12, 72},   {85, 15, 109},
                                          {136, 34, 106}, {186, 54, 85},  {227, 89, 51},
                                          {249, 140, 10}, {249, 201, 50}, {252, 255, 164}};
    t = t < 0 || t != t ? 0 : t > 1 ? 1 : t;
    double f = t * 8;
    int i = (int)f;
    if (i >= 8)
        i = 7;
    f -= i;
    for (int c = 0; c < 3; c++)
        rgb[c] = (unsigned char)lround(k[i][c] + f * (k[i + 1][c] - k[i][c]));
}

/* An RGB24 surface of w x h pixels, each enlarged to k x k, filled by
 * fill(x, y, rgb). The enlargement is done here, pixel by pixel, rather than
 * by scaling when drawing: PDF and SVG viewers smooth scaled images whatever
 * filter the file asks for, and a smoothed 21-pixel render is unreadable. */
typedef void (*pixel_fn)(const void *user, int x, int y, unsigned char rgb[3]);

static cairo_surface_t *make_surface(int w, int h, int k, pixel_fn fill, const void *user)
{
    cairo_surface_t *s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w * k, h * k);
    if (cairo_surface_status(s) != CAIRO_STATUS_SUCCESS)
        return s;
    cairo_surface_flush(s);
    unsigned char *data = cairo_image_surface_get_data(s);
    int stride = cairo_image_surface_get_stride(s);
    for (int y = 0; y < h; y++) {
        uint32_t *row = (uint32_t *)(data + (size_t)y * (size_t)k * (size_t)stride);
        for (int x = 0; x < w; x++) {
            unsigned char c[3];
            fill(user, x, y, c);
            for (int i = 0; i < k; i++)
                row[x * k + i] = 0xff000000u | (uint32_t)c[0] << 16 | (uint32_t)c[1] << 8 | c[2];
        }
        for (int j = 1; j < k; j++)
            memcpy(data + ((size_t)y * (size_t)k + (size_t)j) * (size_t)stride, row, sizeof(uint32_t) * (size_t)(w * k));
    }
    cairo_surface_mark_dirty(s);
    return s;
}

typedef struct tone_src {
    const rr_image *img;
    double scale;
} tone_src;

/* The PNG preview's tone map (img_write_png): value * 2^exposure, clamped, sRGB. */
static void tone_px(const void *user, int x, int y, unsigned char rgb[3])
{
    const tone_src *t = user;
    const float *p = rr_image_at(t->img, x, y);
    for (int c = 0; c < 3; c++) {
        double v = p[c] * t->scale;
        v = v > 0 ? (v < 1 ? v : 1) : 0;
        rgb[c] = (unsigned char)lround(255.0 * img_srgb_encode(v));
    }
}

typedef struct diff_src {
    const float *v;
    int width;
    double top;
} diff_src;

static void diff_px(const void *user, int x, int y, unsigned char rgb[3])
{
    const diff_src *d = user;
    double t = d->v[(size_t)y * (size_t)d->width + (size_t)x] / d->top;
    /* Square-root scale: a mode that is off by a tenth of the worst one still
     * shows, instead of vanishing next to it (e.g. next to the radiosity
     * display, which has no highlights or mirrors at all). */
    inferno(t > 0 ? sqrt(t) : 0, rgb);
}

static void bar_px(const void *user, int x, int y, unsigned char rgb[3])
{
    (void)y;
    inferno((x + 0.5) / *(const int *)user, rgb);
}

/* Draws surface s at (x, y), one surface pixel per unit, framed. */
static void draw_image(cairo_t *cr, cairo_surface_t *s, double x, double y)
{
    int w = cairo_image_surface_get_width(s), h = cairo_image_surface_get_height(s);
    cairo_set_source_surface(cr, s, x, y);
    cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_NEAREST);
    cairo_rectangle(cr, x, y, w, h);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, x - 0.5, y - 0.5, w + 1, h + 1);
    cairo_stroke(cr);
}

static void label(cairo_t *cr, double x, double y, const char *title, const char *caption)
{
    cairo_set_source_rgb(cr, 0, 0, 0);
    font(cr, 13, 1);
    text(cr, x, y + 15, 0, title);
    cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
    font(cr, 11, 0);
    text(cr, x, y + 31, 0, caption);
}

typedef struct layout {
    int k, dw, dh;          /* enlargement and displayed panel size */
    int col_w;              /* panel column width */
    double W, H;
    double y_panels, y_diff, y_table; /* y_panels, y_diff: of the first band */
    int per_row;            /* panels per band (a row of panels, and their differences under them) */
    double band_h;          /* height of one band */
    double col_x[FIG_MAX_PANELS + 2]; /* table columns: left edge of names, then right edges */
    double table_w;
} layout;

/* Width of table column c (-2 names, -1 pixels, >= 0 values) at the current font. */
static double table_col_width(cairo_t *cr, const fig_table *t, int c)
{
    char buf[96];
    font(cr, 12, 1);
    double w = text_width(cr, c == -2 ? "region" : c == -1 ? "pixels" : t->cols[c]);
    font(cr, 12, 0);
    for (int r = 0; r < t->nrows; r++) {
        if (c == -2)
            snprintf(buf, sizeof buf, "%s", t->rows[r]);
        else if (c == -1)
            snprintf(buf, sizeof buf, "%ld", t->pixels[r]);
        else
            fig_cell(t, r, c, buf, sizeof buf);
        w = fmax(w, text_width(cr, buf));
    }
    return w;
}

static void measure(const fig_desc *d, layout *L)
{
    cairo_surface_t *s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, 1, 1);
    cairo_t *cr = cairo_create(s);
    L->k = d->width < SMALL ? (MIN_COLUMN + d->width - 1) / d->width : 1;
    L->dw = d->width * L->k;
    L->col_w = L->dw > MIN_COLUMN ? L->dw : MIN_COLUMN;
    L->dh = d->height * L->k;
    L->y_panels = MARGIN + HEADER;
    double bottom = L->y_panels + LABEL + L->dh;
    L->y_diff = bottom + ROW_GAP;
    if (d->diff)
        bottom = L->y_diff + LABEL + (L->dh > SCALE_H ? L->dh : SCALE_H);
    /* Bands of at most WRAP_W, the panels shared out evenly between them. */
    int n = d->npanels > 0 ? d->npanels : 1, per = n;
    while (per > 1 && per * L->col_w + (per - 1) * GAP > WRAP_W)
        per--;
    int bands = (n + per - 1) / per;
    L->per_row = (n + bands - 1) / bands;
    L->band_h = bottom - L->y_panels + ROW_GAP + 10;
    L->y_table = bottom + (bands - 1) * L->band_h + 24;
    const fig_table *t = &d->table;
    double x = MARGIN;
    L->col_x[0] = x;
    x += table_col_width(cr, t, -2) + 24;
    x += table_col_width(cr, t, -1);
    L->col_x[1] = x;
    for (int c = 0; c < t->ncols; c++) {
        x += 28 + table_col_width(cr, t, c);
        L->col_x[c + 2] = x;
    }
    L->table_w = x - MARGIN;
    font(cr, 13, 1);
    double tw = text_width(cr, t->title);
    font(cr, 17, 1);
    tw = fmax(tw, text_width(cr, d->title));
    font(cr, 12, 0);
    tw = fmax(tw, text_width(cr, d->subtitle));
    double panels_w = L->per_row * L->col_w + (L->per_row - 1) * GAP;
    L->W = ceil(2 * MARGIN + fmax(panels_w, fmax(L->table_w, tw)));
    L->H = ceil(L->y_table + 30 + TABLE_ROW * (t->nrows + 1) + MARGIN);
    cairo_destroy(cr);
    cairo_surface_destroy(s);
}

static void draw_table(cairo_t *cr, const fig_desc *d, const layout *L)
{
    const fig_table *t = &d->table;
    char buf[96];
    double y = L->y_table;
    cairo_set_source_rgb(cr, 0, 0, 0);
    font(cr, 13, 1);
    text(cr, MARGIN, y + 14, 0, t->title);
    y += 36;
    font(cr, 12, 1);
    text(cr, L->col_x[0], y, 0, "region");
    text(cr, L->col_x[1], y, 1, "pixels");
    for (int c = 0; c < t->ncols; c++)
        text(cr, L->col_x[c + 2], y, 1, t->cols[c]);
    cairo_set_line_width(cr, 1);
    cairo_move_to(cr, MARGIN, y + 5.5);
    cairo_line_to(cr, MARGIN + L->table_w, y + 5.5);
    cairo_stroke(cr);
    font(cr, 12, 0);
    for (int r = 0; r < t->nrows; r++) {
        y += TABLE_ROW;
        if (r % 2 == 0) {
            /* Banded rows guide the eye along a long row of numbers. */
            cairo_set_source_rgb(cr, 0.94, 0.94, 0.94);
            cairo_rectangle(cr, MARGIN, y - 13, L->table_w, TABLE_ROW);
            cairo_fill(cr);
        }
        cairo_set_source_rgb(cr, 0, 0, 0);
        text(cr, L->col_x[0], y, 0, t->rows[r]);
        snprintf(buf, sizeof buf, "%ld", t->pixels[r]);
        text(cr, L->col_x[1], y, 1, buf);
        for (int c = 0; c < t->ncols; c++) {
            fig_cell(t, r, c, buf, sizeof buf);
            text(cr, L->col_x[c + 2], y, 1, buf);
        }
    }
}

/* The colour scale, in the reference's slot of the difference row. */
static void draw_scale(cairo_t *cr, const fig_desc *d, const layout *L, double x, double y)
{
    char buf[96];
    snprintf(buf, sizeof buf, "reference: %s", d->panels[d->ref].title);
    label(cr, x, y, buf, "|difference|, mean of RGB");
    int bw = L->col_w - 20;
    double bx = x + (L->col_w - bw) / 2.0, by = y + LABEL + fmax(0, (L->dh - SCALE_H) / 2.0);
    /* The bar is an image filled through the same map as the panels. */
    cairo_surface_t *bar = make_surface(bw, 16, 1, bar_px, &bw);
    draw_image(cr, bar, bx, by);
    cairo_surface_destroy(bar);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_line_width(cr, 1);
    font(cr, 11, 0);
    for (int i = 0; i <= 2; i++) {
        double tx = bx + bw * i / 2.0;
        cairo_move_to(cr, tx, by + 16);
        cairo_line_to(cr, tx, by + 21);
        cairo_stroke(cr);
        if (i == 2 && d->diff_clipped)
            snprintf(buf, sizeof buf, "\xe2\x89\xa5%.3g", d->diff_top); /* >= */
        else
            snprintf(buf, sizeof buf, "%.3g", d->diff_top * (i / 2.0) * (i / 2.0));
        text(cr, tx, by + 33, i == 0 ? 0 : i == 1 ? 2 : 1, buf);
    }
    cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
    text(cr, bx, by + 50, 0, "square-root scale");
    if (d->diff_clipped)
        text(cr, bx, by + 64, 0, "top = 99th percentile");
}

static void draw(cairo_t *cr, const fig_desc *d, const layout *L, cairo_surface_t **panel, cairo_surface_t **diff)
{
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    font(cr, 17, 1);
    text(cr, MARGIN, MARGIN + 17, 0, d->title);
    cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
    font(cr, 12, 0);
    text(cr, MARGIN, MARGIN + 37, 0, d->subtitle);
    for (int i = 0; i < d->npanels; i++) {
        double x = MARGIN + (i % L->per_row) * (L->col_w + GAP), dy = (i / L->per_row) * L->band_h;
        double y_panel = L->y_panels + dy, y_diff = L->y_diff + dy;
        /* Each column's text stays in its column, however long a name is. */
        cairo_save(cr);
        cairo_rectangle(cr, x - 1, 0, L->col_w + GAP - 2, L->y_table);
        cairo_clip(cr);
        label(cr, x, y_panel, d->panels[i].title, d->panels[i].caption);
        draw_image(cr, panel[i], x, y_panel + LABEL);
        if (d->diff && i == d->ref)
            draw_scale(cr, d, L, x, y_diff);
        cairo_restore(cr);
        if (!d->diff || i == d->ref)
            continue;
        char t[160], c[96];
        snprintf(t, sizeof t, "|%s \xe2\x88\x92 %s|", d->panels[i].title, d->panels[d->ref].title);
        double sum = 0, mx = 0;
        size_t n = (size_t)d->width * (size_t)d->height;
        for (size_t p = 0; p < n; p++) {
            sum += d->diff[i][p];
            mx = fmax(mx, d->diff[i][p]);
        }
        snprintf(c, sizeof c, "mean %.3g, max %.3g", sum / (double)n, mx);
        cairo_save(cr);
        cairo_rectangle(cr, x - 1, 0, L->col_w + GAP - 2, L->y_table);
        cairo_clip(cr);
        label(cr, x, y_diff, t, c);
        draw_image(cr, diff[i], x, y_diff + LABEL);
        cairo_restore(cr);
    }
    draw_table(cr, d, L);
}

static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), m = strlen(ext);
    return n >= m && strcasecmp(path + n - m, ext) == 0;
}

rr_status fig_write(const char *path, const fig_desc *d, rr_error *err)
{
    layout L;
    memset(&L, 0, sizeof L);
    measure(d, &L);
    /* The image surfaces of the panels and differences, made once and shared
     * by whichever target surface the figure is drawn on. */
    cairo_surface_t *panel[FIG_MAX_PANELS] = {0}, *diff[FIG_MAX_PANELS] = {0};
    int np = d->npanels;
    rr_status st = RR_OK;
    if (np < 1 || np > FIG_MAX_PANELS || d->table.ncols > FIG_MAX_PANELS)
        return rr_error_set(err, RR_ERR_INVALID, "%s: a figure holds 1 to %d panels", path, FIG_MAX_PANELS);
    for (int i = 0; i < np && st == RR_OK; i++) {
        tone_src ts = {d->panels[i].img, pow(2.0, d->exposure)};
        panel[i] = make_surface(d->width, d->height, L.k, tone_px, &ts);
        if (d->diff && d->diff[i]) {
            diff_src ds = {d->diff[i], d->width, d->diff_top > 0 ? d->diff_top : 1};
            diff[i] = make_surface(d->width, d->height, L.k, diff_px, &ds);
        }
        if (cairo_surface_status(panel[i]) != CAIRO_STATUS_SUCCESS ||
            (diff[i] && cairo_surface_status(diff[i]) != CAIRO_STATUS_SUCCESS))
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: cannot make the figure's images", path);
    }
    char tmp[4200];
    if (st == RR_OK)
        st = rr_file_tmpname(path, tmp, sizeof tmp, err);
    if (st == RR_OK) {
        int pdf = has_ext(path, ".pdf"), svg = has_ext(path, ".svg");
        cairo_surface_t *sf = pdf   ? cairo_pdf_surface_create(tmp, L.W, L.H)
                              : svg ? cairo_svg_surface_create(tmp, L.W, L.H)
                                    : cairo_image_surface_create(CAIRO_FORMAT_RGB24, (int)L.W, (int)L.H);
        cairo_t *cr = cairo_create(sf);
        draw(cr, d, &L, panel, diff);
        cairo_status_t cs = cairo_status(cr);
        cairo_destroy(cr);
        if (cs == CAIRO_STATUS_SUCCESS) {
            if (pdf || svg) {
                cairo_surface_finish(sf);
                cs = cairo_surface_status(sf);
            } else {
                cs = cairo_surface_write_to_png(sf, tmp);
            }
        }
        cairo_surface_destroy(sf);
        if (cs != CAIRO_STATUS_SUCCESS) {
            remove(tmp);
            st = rr_error_set(err, RR_ERR_IO, "%s: cannot write the figure: %s", path, cairo_status_to_string(cs));
        } else {
            st = rr_file_replace(tmp, path, err);
        }
    }
    for (int i = 0; i < np; i++) {
        cairo_surface_destroy(panel[i]);
        cairo_surface_destroy(diff[i]);
    }
    return st;
}
