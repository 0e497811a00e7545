/* figure.h - the labelled comparison figure of `radray compare`, composed with
 * cairo (private to app/).
 *
 * One figure: a title, a row of panels (tone-mapped renders, each with a name
 * and a caption), optionally a row of difference images under them (a colour
 * map of |panel - reference|, with the colour scale drawn in the reference's
 * own slot), and a table of per-region mean radiance. PNG, PDF or SVG by the
 * extension of the path, written atomically. Text goes through cairo's toy
 * text API, so the figure needs no font files of its own.
 */
#ifndef FIGURE_H
#define FIGURE_H

#include <stdio.h>

#include "rr_core.h"

/* Panels per figure, and columns per table. */
#define FIG_MAX_PANELS 16

typedef struct fig_panel {
    char title[64];      /* bold line above the image: a mode or a layer name */
    char caption[96];    /* smaller line: samples, render time */
    const rr_image *img; /* linear RGB, shown as value * 2^exposure, clamped, sRGB-encoded */
} fig_panel;

/* The per-region table: rows are scene objects, columns are the panels. */
typedef struct fig_table {
    int nrows, ncols;
    const char *const *rows;  /* row names */
    const long *pixels;       /* pixels per row */
    const double *mean;       /* nrows x ncols, row-major: mean radiance (mean of RGB) */
    const char *const *cols;  /* column names */
    int ref;                  /* column that the others are compared to, -1: none */
    char title[160];
} fig_table;

typedef struct fig_desc {
    char title[128];
    char subtitle[256];
    int width, height;        /* of every panel image, in pixels */
    double exposure;          /* stops */
    int npanels;
    const fig_panel *panels;
    /* Difference row: diff[i] holds width*height per-pixel |panel i - reference|
     * (mean over RGB), NULL for the reference itself. diff NULL: no row. */
    const float *const *diff;
    int ref;                  /* panel index of the reference (diff row only) */
    double diff_top;          /* radiance difference at the top of the colour map (square-root scale) */
    int diff_clipped;         /* some differences exceed diff_top (the scale label says so) */
    fig_table table;
} fig_desc;

/* One table cell as text: "0.1234 (+3.2%)" relative to the reference
 * column, "0.1234 (ref)" in it, "0.1234" when there is no reference. Shared by
 * the figure and the plain-text table so that both read the same. */
void fig_cell(const fig_table *t, int row, int col, char *buf, size_t n);

/* Difference images: diff[i] = per-pixel |img[i] - img[ref]| (mean over RGB),
 * malloc'd, for every i but ref (left NULL); all images the same size. *top is
 * the radiance difference for the top of the shared colour map, *clipped
 * whether some differences exceed it. Returns -1 when out of memory (the
 * arrays made so far stay in diff[] for the caller to free). */
int fig_make_diffs(const rr_image *img, int n, int ref, float **diff, double *top, int *clipped);

/* The table as plain text on f: a title line, a header, one line per row. */
void fig_print_table(FILE *f, const fig_table *t);

/* Writes the figure to path (.png, .pdf or .svg, case-insensitive; anything
 * else is PNG) through a temporary file renamed into place. */
rr_status fig_write(const char *path, const fig_desc *d, rr_error *err);

#endif
