/* rr_view.c - the lecture's view set-up and primary rays. */
#include "rr_view.h"

static int finite3(rr_vec3 v) { return rr_v3_isfinite(v); }

/* Derived quantities, not only the inputs: every corner of the screen, and
 * the ray to it, must be finite (s * w overflowing makes NaN rays). */
static rr_status rr_view_check(const rr_view *v, rr_error *err)
{
    for (int k = 0; k < 4; k++) {
        int col = k & 1 ? v->width - 1 : 0, row = k & 2 ? v->height - 1 : 0;
        rr_ray r = rr_view_ray(v, col, row, k & 1 ? 1.0 : -1.0, k & 2 ? -1.0 : 1.0); /* the tent filter's reach */
        if (!finite3(r.d) || !(rr_v3_len2(r.d) > 0.0) || !isfinite(rr_v3_len2(r.d)))
            return rr_error_set(err, RR_ERR_INVALID,
                                "view: the screen (O, s and the size: corner %d, %d) is too large: its rays are not "
                                "finite (s = %g, %d x %d pixels)",
                                col, row, v->s, v->width, v->height);
    }
    return RR_OK;
}

rr_status rr_view_lecture(rr_vec3 E, rr_vec3 O, rr_vec3 U, double s, int w, int h, rr_view *out, rr_error *err)
{
    if (!finite3(E) || !finite3(O) || !finite3(U) || !isfinite(s))
        return rr_error_set(err, RR_ERR_INVALID, "view: E, O, U and s must be finite numbers");
    if (!(s > 0.0))
        return rr_error_set(err, RR_ERR_INVALID, "view: pixel scale s must be > 0 (got %g)", s);
    if (w < 0 || h < 0)
        return rr_error_set(err, RR_ERR_INVALID, "view: w and h must be >= 0 (got w=%d, h=%d)", w, h);
    if (w > (1 << 20) || h > (1 << 20))
        return rr_error_set(err, RR_ERR_INVALID, "view: w and h must be at most %d (got w=%d, h=%d)", 1 << 20, w, h);
    rr_vec3 VO = rr_v3_sub(O, E);
    if (!finite3(VO))
        return rr_error_set(err, RR_ERR_INVALID, "view: O - E overflows (E and O are too far apart)");
    /* Unit vectors first (scaled, so that large or tiny components are fine). */
    rr_vec3 vo = rr_v3_unit(VO), u = rr_v3_unit(U);
    if (!(rr_v3_len(vo) > 0.0))
        return rr_error_set(err, RR_ERR_INVALID, "view: the screen centre O equals the viewpoint E");
    if (!(rr_v3_len(u) > 0.0))
        return rr_error_set(err, RR_ERR_INVALID, "view: the up vector U is zero");
    rr_vec3 I = rr_v3_cross(vo, u);
    /* |vo x u| = sin(angle): compare it with a small threshold so that
     * "almost parallel" (numerically meaningless axes) is refused too. */
    double li = rr_v3_len(I);
    if (!(li > 1e-9))
        return rr_error_set(err, RR_ERR_INVALID,
                            "view: the up vector U is parallel to the view direction VO = O - E; "
                            "choose an up vector that is not along the line of sight");
    I = rr_v3_scale(I, 1.0 / li);
    rr_vec3 J = rr_v3_norm(rr_v3_cross(I, vo));
    rr_view v;
    v.E = E;
    v.O = O;
    v.U = U;
    v.s = s;
    v.width = 2 * w + 1;
    v.height = 2 * h + 1;
    v.I = I;
    v.J = J;
    rr_status st = rr_view_check(&v, err);
    if (st != RR_OK)
        return st;
    *out = v;
    return RR_OK;
}

rr_status rr_view_lookat(rr_vec3 eye, rr_vec3 target, rr_vec3 up, double fov_deg, int width, int height,
                         rr_view *out, rr_error *err)
{
    if (!isfinite(fov_deg) || !(fov_deg > 0.0 && fov_deg < 180.0))
        return rr_error_set(err, RR_ERR_INVALID, "view: fov must be in (0, 180) degrees (got %g)", fov_deg);
    if (width <= 0 || height <= 0 || width > (1 << 21) || height > (1 << 21))
        return rr_error_set(err, RR_ERR_INVALID, "view: width and height must be in [1, %d] (got %d x %d)", 1 << 21,
                            width, height);
    if (!finite3(eye) || !finite3(target))
        return rr_error_set(err, RR_ERR_INVALID, "view: eye and target must be finite numbers");
    rr_vec3 dir = rr_v3_sub(target, eye);
    if (!(rr_v3_len(dir) > 0.0))
        return rr_error_set(err, RR_ERR_INVALID, "view: the target equals the eye");
    /* O one unit in front of E; the screen's height 2*tan(fov/2) spans `height` pixels. */
    rr_vec3 O = rr_v3_add(eye, rr_v3_norm(dir));
    double s = 2.0 * tan(0.5 * fov_deg * RR_PI / 180.0) / (double)height;
    rr_status st = rr_view_lecture(eye, O, up, s, 0, 0, out, err);
    if (st != RR_OK)
        return st;
    out->width = width;
    out->height = height;
    return rr_view_check(out, err);
}

rr_vec3 rr_view_screen_point(const rr_view *v, int col, int row, double dx, double dy)
{
    double x = (double)col - 0.5 * (double)(v->width - 1) + dx;
    double y = 0.5 * (double)(v->height - 1) - (double)row + dy;
    return rr_v3_add(v->O, rr_v3_add(rr_v3_scale(v->I, v->s * x), rr_v3_scale(v->J, v->s * y)));
}

rr_ray rr_view_ray(const rr_view *v, int col, int row, double dx, double dy)
{
    rr_ray r;
    r.o = v->E;
    r.d = rr_v3_sub(rr_view_screen_point(v, col, row, dx, dy), v->E);
    return r;
}

rr_status rr_view_resize(const rr_view *v, int width, rr_view *out, rr_error *err)
{
    if (width < 1 || width > (1 << 21))
        return rr_error_set(err, RR_ERR_INVALID, "view: width must be in [1, %d] (got %d)", 1 << 21, width);
    rr_view r = *v;
    double scale = (double)v->width / (double)width;
    long h = lround((double)v->height / scale);
    r.width = width;
    r.height = h < 1 ? 1 : (int)h;
    r.s = v->s * scale;
    rr_status st = rr_view_check(&r, err);
    if (st != RR_OK)
        return st;
    *out = r;
    return RR_OK;
}
