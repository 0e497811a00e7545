/* rr_image.c - float RGB film. */
#include "rr_image.h"

#include <stdint.h>
#include <stdlib.h>

size_t rr_image_bytes(long width, long height)
{
    if (width <= 0 || height <= 0)
        return 0;
    size_t w = (size_t)width, h = (size_t)height;
    if (w > SIZE_MAX / h)
        return 0;
    size_t n = w * h;
    if (n > SIZE_MAX / (3 * sizeof(float)))
        return 0;
    return n * 3 * sizeof(float);
}

rr_status rr_image_init(rr_image *img, int width, int height, rr_error *err)
{
    size_t bytes = rr_image_bytes(width, height);
    if (bytes == 0)
        return rr_error_set(err, RR_ERR_INVALID, "image size %d x %d is not valid", width, height);
    float *px = calloc(1, bytes);
    if (!px)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for a %d x %d image (%zu bytes)", width, height, bytes);
    img->width = width;
    img->height = height;
    img->px = px;
    return RR_OK;
}

void rr_image_free(rr_image *img)
{
    if (!img)
        return;
    free(img->px);
    img->px = NULL;
    img->width = img->height = 0;
}
