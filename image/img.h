/* img.h - image files: OpenEXR (through the OpenEXR 3 C core API, openexr.h)
 * and PNG previews (libpng).
 *
 * EXR: linear float (or half) RGB in channels R, G, B, plus any number of named
 * extra layers, each stored as channels "<layer>.R", "<layer>.G", "<layer>.B"
 * (the OpenEXR layer naming convention, which viewers such as Blender or
 * tev show as layers). Uncompressed scanlines or ZIP compression.
 *
 * PNG: 8-bit sRGB preview: each linear value is multiplied by 2^exposure,
 * clamped to [0, 1], encoded with the sRGB transfer curve.
 *
 * Every writer writes to a temporary file in the destination folder and renames
 * it into place only when complete (rr_file.h), so a failure never leaves a
 * truncated file where a good one was.
 *
 * Errors: all functions return an rr_status and fill err with a message that
 * starts with the file name.
 */
#ifndef IMG_H
#define IMG_H

#include "rr_core.h"

typedef struct img_layer {
    const char *name;     /* e.g. "diffuse": letters, digits, '_' and '-' */
    const rr_image *image; /* same size as the main image */
} img_layer;

typedef enum img_pixel_type { IMG_FLOAT = 0, IMG_HALF = 1 } img_pixel_type;

/* Writes rgb (and layers, may be NULL when nlayers is 0) to path. */
rr_status img_write_exr(const char *path, const rr_image *rgb, const img_layer *layers, int nlayers,
                        img_pixel_type type, rr_error *err);

/* A string attribute of the EXR header, e.g. {"radray:mode", "hybrid"}. */
typedef struct img_attr {
    const char *name;  /* 1..255 bytes */
    const char *value; /* at most 65535 bytes */
} img_attr;

/* img_write_exr with string attributes in the header (what made the image:
 * viewers such as exrheader and tev show them). */
rr_status img_write_exr_attrs(const char *path, const rr_image *rgb, const img_layer *layers, int nlayers,
                              img_pixel_type type, const img_attr *attrs, int nattrs, rr_error *err);

/* The string attribute `name` of an EXR file into buf (truncated to n - 1
 * bytes); RR_ERR_INVALID when the file has none of that name. */
rr_status img_read_exr_attr(const char *path, const char *name, char *buf, size_t n, rr_error *err);

/* Reads one layer of an EXR file into *out (allocated; free with
 * rr_image_free). layer NULL or "" reads the main R, G, B channels. Half and
 * float files are both accepted. Fails with a message that lists the layers the
 * file has when the layer is missing. *out untouched on failure. */
rr_status img_read_exr(const char *path, const char *layer, rr_image *out, rr_error *err);

/* Names of the extra layers in an EXR file: fills names[0..*count) with up
 * to max entries (each at most 63 characters + NUL). */
rr_status img_exr_layers(const char *path, char names[][64], int max, int *count, rr_error *err);

/* sRGB transfer (IEC 61966-2-1) of a linear value in [0, 1]. */
double img_srgb_encode(double linear);

/* Writes an 8-bit sRGB PNG preview of rgb scaled by 2^exposure. */
rr_status img_write_png(const char *path, const rr_image *rgb, double exposure, rr_error *err);

/* Reads an 8-bit RGB(A) PNG into a malloc'd buffer of 3*w*h bytes (alpha dropped). */
rr_status img_read_png(const char *path, unsigned char **rgb8, int *width, int *height, rr_error *err);

#endif
