/* rr_image.h - the float RGB image that every render writes into (part of core).
 *
 * Pixels are linear RGB floats, row-major, row 0 at the top of the picture,
 * 3 floats per pixel. An rr_image owns its pixels: rr_image_init allocates,
 * rr_image_free releases (and is a no-op on a zeroed or already freed image). */
#ifndef RR_IMAGE_H
#define RR_IMAGE_H

#include <stddef.h>

#include "rr_error.h"
#include "rr_math.h"

typedef struct rr_image {
    int width, height;
    float *px; /* 3 * width * height floats */
} rr_image;

/* Bytes needed for a width x height RGB float image, or 0 when the size
 * overflows size_t or a dimension is not positive. */
size_t rr_image_bytes(long width, long height);

/* Allocates a zero-filled image. Fails with RR_ERR_INVALID for non-positive
 * sizes and RR_ERR_NOMEM when the allocation fails; *img is untouched then. */
rr_status rr_image_init(rr_image *img, int width, int height, rr_error *err);
void rr_image_free(rr_image *img);

static inline float *rr_image_at(const rr_image *img, int x, int y)
{
    return img->px + 3 * ((size_t)y * (size_t)img->width + (size_t)x);
}
static inline void rr_image_set(rr_image *img, int x, int y, rr_rgb c)
{
    float *p = rr_image_at(img, x, y);
    p[0] = (float)c.r;
    p[1] = (float)c.g;
    p[2] = (float)c.b;
}
static inline rr_rgb rr_image_get(const rr_image *img, int x, int y)
{
    const float *p = rr_image_at(img, x, y);
    return rr_rgb_make(p[0], p[1], p[2]);
}

#endif
