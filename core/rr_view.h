/* rr_view.h - the lecture's view: viewpoint E, screen centre O, pixel scale s,
 * resolution (2w+1) x (2h+1), up vector U (part of core).
 *
 *   VO = O - E              (view direction, not normalised)
 *   I  = VO x U / |VO x U|  (screen "right")
 *   J  = I x VO / |I x VO|  (screen "up")
 *   P(x, y) = O + s*x*I + s*y*J,   x in [-w, w], y in [-h, h]
 *   primary ray: E + t*EP, so t = 1 on the screen.
 *
 * Pixel (col, row) of the image, row 0 at the top, sits at
 *   x = col - (width-1)/2,  y = (height-1)/2 - row,
 * which is exactly x = col - w, y = h - row for the lecture's odd resolutions,
 * and extends to even widths (half-integer x) for the conventional camera.
 */
#ifndef RR_VIEW_H
#define RR_VIEW_H

#include "rr_error.h"
#include "rr_math.h"

typedef struct rr_view {
    rr_vec3 E, O, U;   /* as given */
    double s;          /* pixel scale: world size of one pixel on the screen */
    int width, height; /* pixels; 2w+1 and 2h+1 for the lecture's form */
    rr_vec3 I, J;      /* derived unit screen axes */
} rr_view;

/* The lecture's form. Fails (RR_ERR_INVALID, message says which) when E == O,
 * U is zero or parallel to VO, s <= 0, w or h negative, or a value is not finite. */
rr_status rr_view_lecture(rr_vec3 E, rr_vec3 O, rr_vec3 U, double s, int w, int h, rr_view *out, rr_error *err);

/* The conventional form: eye, look-at target, up, full vertical field of view
 * in degrees (0 < fov < 180), image size in pixels. Builds the equivalent
 * lecture view with O one unit in front of the eye. Same failures, plus a bad
 * fov or a non-positive size. */
rr_status rr_view_lookat(rr_vec3 eye, rr_vec3 target, rr_vec3 up, double fov_deg, int width, int height,
                         rr_view *out, rr_error *err);

/* The same view at another width: the screen keeps its extent (s scales by
 * old/new width) and the height follows the aspect ratio (at least 1 pixel).
 * Used by --width. Fails for width < 1. */
rr_status rr_view_resize(const rr_view *v, int width, rr_view *out, rr_error *err);

/* Screen point P for pixel (col, row) shifted by (dx, dy) pixels, where
 * (0, 0) is the pixel centre and +dx is right, +dy is up. */
rr_vec3 rr_view_screen_point(const rr_view *v, int col, int row, double dx, double dy);

/* Primary ray E + t*EP through rr_view_screen_point. */
rr_ray rr_view_ray(const rr_view *v, int col, int row, double dx, double dy);

#endif
