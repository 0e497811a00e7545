/* img_png.c - 8-bit sRGB PNG previews through libpng 1.6.
 *
 * libpng reports errors by longjmp'ing to the setjmp point of png_jmpbuf.
 * To keep that safe, every resource lives in a state struct owned by the
 * public function, and the setjmp happens in a separate helper that only
 * touches the struct through a pointer: after a longjmp the caller sees the
 * struct's current contents (no "indeterminate non-volatile locals" issue)
 * and releases whatever was acquired, exactly once.
 */
#include "img.h"

#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <png.h>

double img_srgb_encode(double linear)
{
    /* Values outside [0, 1] (and NaN) are clamped so callers always get a
     * valid code value. */
    if (!(linear > 0.0))
        return 0.0;
    if (linear >= 1.0)
        return 1.0;
    /* IEC 61966-2-1: linear segment near black, 1/2.4 power elsewhere. */
    if (linear <= 0.0031308)
        return 12.92 * linear;
    return 1.055 * pow(linear, 1.0 / 2.4) - 0.055;
}

/* Linear value -> 8-bit sRGB code, with the exposure scale already known. */
static png_byte img_png_code(float v, double scale)
{
    double x = (double)v * scale;
    if (isnan(x))
        return 0;
    /* Clamping first keeps infinities and huge values well defined. */
    if (x < 0.0)
        x = 0.0;
    if (x > 1.0)
        x = 1.0;
    return (png_byte)floor(img_srgb_encode(x) * 255.0 + 0.5);
}

typedef struct img_png_msg {
    char text[256];
} img_png_msg;

/* libpng error callback: record the message, then unwind to png_jmpbuf
 * (libpng requires that this function not return). */
static void img_png_on_error(png_structp png, png_const_charp msg)
{
    img_png_msg *m = png_get_error_ptr(png);
    if (m)
        snprintf(m->text, sizeof m->text, "%s", msg ? msg : "libpng error");
    png_longjmp(png, 1);
}

/* Warnings (e.g. an unknown ancillary chunk) do not affect the result;
 * library code must not print, so they are dropped. */
static void img_png_on_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

/* ------------------------------------------------------------------ writing */

typedef struct img_png_writer {
    rr_atomic out;
    png_structp png;
    png_infop info;
    png_bytep row; /* 3 * width bytes, allocated before any libpng call */
    img_png_msg msg;
} img_png_writer;

/* Our own I/O callbacks instead of png_init_io: libpng's default writer
 * reports every failure as a bare "Write Error"; these name the cause
 * (e.g. "No space left on device"). */
static void img_png_write_data(png_structp png, png_bytep data, size_t len)
{
    img_png_writer *w = png_get_io_ptr(png);
    if (fwrite(data, 1, len, w->out.fp) != len)
        png_error(png, strerror(errno));
}

static void img_png_flush(png_structp png)
{
    img_png_writer *w = png_get_io_ptr(png);
    if (fflush(w->out.fp) != 0)
        png_error(png, strerror(errno));
}

/* Returns 0 on success, -1 after a libpng error (message in w->msg). */
static int img_png_write_body(img_png_writer *w, const rr_image *rgb, double scale)
{
    if (setjmp(png_jmpbuf(w->png)))
        return -1;
    png_set_write_fn(w->png, w, img_png_write_data, img_png_flush);
    png_set_IHDR(w->png, w->info, (png_uint_32)rgb->width, (png_uint_32)rgb->height, 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    /* sRGB chunk, plus the matching gAMA and cHRM that the PNG spec
     * recommends for decoders that do not know sRGB. */
    png_set_sRGB_gAMA_and_cHRM(w->png, w->info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(w->png, w->info);
    for (int y = 0; y < rgb->height; y++) {
        const float *src = rr_image_at(rgb, 0, y);
        for (size_t i = 0; i < 3 * (size_t)rgb->width; i++)
            w->row[i] = img_png_code(src[i], scale);
        png_write_row(w->png, w->row);
    }
    png_write_end(w->png, w->info);
    return 0;
}

rr_status img_write_png(const char *path, const rr_image *rgb, double exposure, rr_error *err)
{
    if (!rgb || !rgb->px || rgb->width <= 0 || rgb->height <= 0)
        return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write PNG: the image is empty", path);
    if (!isfinite(exposure))
        return rr_error_set(err, RR_ERR_INVALID, "%s: cannot write PNG: exposure %g is not finite", path, exposure);
    double scale = exp2(exposure);

    img_png_writer w;
    memset(&w, 0, sizeof w);
    w.row = malloc(3 * (size_t)rgb->width);
    if (!w.row)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory writing PNG", path);
    rr_status st = rr_atomic_begin(&w.out, path, err);
    if (st != RR_OK) {
        free(w.row);
        return st;
    }
    w.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &w.msg, img_png_on_error, img_png_on_warning);
    if (w.png)
        w.info = png_create_info_struct(w.png);
    if (!w.png || !w.info) {
        png_destroy_write_struct(&w.png, &w.info);
        rr_atomic_abort(&w.out);
        free(w.row);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory writing PNG", path);
    }
    int bad = img_png_write_body(&w, rgb, scale);
    png_destroy_write_struct(&w.png, &w.info);
    free(w.row);
    if (bad) {
        rr_atomic_abort(&w.out);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write PNG: %s", path, w.msg.text);
    }
    /* Buffered write errors (disk full...) surface here, in the flush. */
    return rr_atomic_commit(&w.out, err);
}

/* ------------------------------------------------------------------ reading */

typedef struct img_png_reader {
    FILE *fp;
    png_structp png;
    png_infop info;
    unsigned char *pixels; /* 3 * width * height bytes, the result */
    png_bytepp rows;       /* row pointers into pixels */
    png_uint_32 width, height;
    img_png_msg msg;
} img_png_reader;

/* Returns 0 on success, -1 after a libpng error (message in r->msg), -2
 * when out of memory, -3 when the image is too large to address. */
static int img_png_read_body(img_png_reader *r)
{
    if (setjmp(png_jmpbuf(r->png)))
        return -1;
    png_init_io(r->png, r->fp);
    png_set_sig_bytes(r->png, 8);
    png_read_info(r->png, r->info);

    int depth = 0, color = 0, interlace = 0;
    png_get_IHDR(r->png, r->info, &r->width, &r->height, &depth, &color, &interlace, NULL, NULL);
    /* Normalise every colour type to 8-bit RGB without alpha. */
    if (color == PNG_COLOR_TYPE_PALETTE)
        png_set_palette_to_rgb(r->png);
    if (color == PNG_COLOR_TYPE_GRAY && depth < 8)
        png_set_expand_gray_1_2_4_to_8(r->png);
    if (color == PNG_COLOR_TYPE_GRAY || color == PNG_COLOR_TYPE_GRAY_ALPHA)
        png_set_gray_to_rgb(r->png);
    if (depth == 16)
        png_set_scale_16(r->png);
    /* Alpha is dropped; a tRNS chunk is simply not expanded to alpha. */
    png_set_strip_alpha(r->png);
    if (interlace != PNG_INTERLACE_NONE)
        png_set_interlace_handling(r->png);
    png_read_update_info(r->png, r->info);

    if (png_get_rowbytes(r->png, r->info) != 3 * (size_t)r->width) {
        snprintf(r->msg.text, sizeof r->msg.text, "unexpected row layout after conversion to 8-bit RGB");
        return -1;
    }
    if (r->width > INT32_MAX || r->height > INT32_MAX || (size_t)r->width * 3 > SIZE_MAX / r->height)
        return -3;
    r->pixels = malloc(3 * (size_t)r->width * r->height);
    r->rows = calloc(r->height, sizeof(png_bytep)); /* calloc checks the product */
    if (!r->pixels || !r->rows)
        return -2;
    for (png_uint_32 y = 0; y < r->height; y++)
        r->rows[y] = r->pixels + 3 * (size_t)r->width * y;
    png_read_image(r->png, r->rows);
    png_read_end(r->png, NULL);
    return 0;
}

rr_status img_read_png(const char *path, unsigned char **rgb8, int *width, int *height, rr_error *err)
{
    img_png_reader r;
    memset(&r, 0, sizeof r);
    r.fp = fopen(path, "rb");
    if (!r.fp)
        return rr_error_set(err, RR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    png_byte sig[8];
    if (fread(sig, 1, sizeof sig, r.fp) != sizeof sig || png_sig_cmp(sig, 0, sizeof sig) != 0) {
        fclose(r.fp);
        return rr_error_set(err, RR_ERR_PARSE, "%s: not a PNG file", path);
    }
    r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r.msg, img_png_on_error, img_png_on_warning);
    if (r.png)
        r.info = png_create_info_struct(r.png);
    rr_status st = RR_OK;
    if (!r.png || !r.info) {
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading PNG", path);
    } else {
        int rc = img_png_read_body(&r);
        if (rc == -1)
            st = rr_error_set(err, RR_ERR_PARSE, "%s: cannot read PNG: %s", path, r.msg.text);
        else if (rc == -2)
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading a %u x %u PNG", path,
                              (unsigned)r.width, (unsigned)r.height);
        else if (rc == -3)
            st = rr_error_set(err, RR_ERR_LIMIT, "%s: PNG of %u x %u pixels is too large", path,
                              (unsigned)r.width, (unsigned)r.height);
    }
    png_destroy_read_struct(&r.png, &r.info, NULL);
    fclose(r.fp);
    free(r.rows);
    if (st != RR_OK) {
        free(r.pixels);
        return st;
    }
    *rgb8 = r.pixels;
    *width = (int)r.width;
    *height = (int)r.height;
    return RR_OK;
}
