/* scene_xform.c - an object's "transform": an array of steps (translate,
 * scale, rotate, matrix) composed into one affine map, applied in order. */
#include <math.h>
#include <string.h>

#include "scene_internal.h"

static const char *const k_step[] = {"translate", "scale", "rotate", "matrix", NULL};
static const char *const k_rotate[] = {"axis", "degrees", NULL};

/* Rotation by deg degrees about axis (right-handed: counter-clockwise when
 * the axis points at the viewer). Multiples of 90 degrees get exact sines, so
 * that a rotated axis-aligned quad stays exactly axis-aligned. */
static rr_xform rotation(rr_vec3 axis, double deg)
{
    rr_vec3 k = rr_v3_norm(axis);
    double d = fmod(deg, 360.0);
    if (d < 0)
        d += 360.0;
    double cs, sn;
    if (d == 0) {
        cs = 1, sn = 0;
    } else if (d == 90) {
        cs = 0, sn = 1;
    } else if (d == 180) {
        cs = -1, sn = 0;
    } else if (d == 270) {
        cs = 0, sn = -1;
    } else {
        cs = cos(d * RR_PI / 180.0);
        sn = sin(d * RR_PI / 180.0);
    }
    double t = 1 - cs, x = k.x, y = k.y, z = k.z;
    rr_xform r = {{{cs + t * x * x, t * x * y - sn * z, t * x * z + sn * y},
                   {t * x * y + sn * z, cs + t * y * y, t * y * z - sn * x},
                   {t * x * z - sn * y, t * y * z + sn * x, cs + t * z * z}},
                  {0, 0, 0}};
    return r;
}

static rr_status parse_step(const sp_ctx *c, const cJSON *step, const char *path, rr_xform *x)
{
    rr_status st = sp_check_object(c, step, path, k_step);
    if (st != RR_OK)
        return st;
    if (cJSON_GetArraySize(step) != 1)
        return sp_fail(c, RR_ERR_INVALID, path,
                       "expected exactly one of translate, scale, rotate, matrix (got %d keys)",
                       cJSON_GetArraySize(step));
    const cJSON *v = step->child;
    char p[SP_PATH_MAX];
    sp_key(p, path, v->string);
    *x = rr_xform_identity();
    if (strcmp(v->string, "translate") == 0)
        return sp_vec3_item(c, v, p, &x->t);
    if (strcmp(v->string, "scale") == 0) {
        rr_vec3 s;
        if (cJSON_IsNumber(v)) {
            double u;
            if ((st = sp_number_item(c, v, p, &u)) != RR_OK)
                return st;
            s = rr_v3(u, u, u);
        } else if (cJSON_IsArray(v)) {
            if ((st = sp_vec3_item(c, v, p, &s)) != RR_OK)
                return st;
        } else {
            char got[96];
            return sp_fail(c, RR_ERR_INVALID, p, "expected a number or an array of 3 numbers (got %s)",
                           sp_describe(v, got, sizeof got));
        }
        if (s.x == 0 || s.y == 0 || s.z == 0)
            return sp_fail(c, RR_ERR_INVALID, p, "a zero scale flattens the object");
        x->m[0][0] = s.x, x->m[1][1] = s.y, x->m[2][2] = s.z;
        return RR_OK;
    }
    if (strcmp(v->string, "rotate") == 0) {
        rr_vec3 axis;
        double deg = 0;
        if ((st = sp_check_object(c, v, p, k_rotate)) != RR_OK ||
            (st = sp_vec3(c, v, p, "axis", SP_REQUIRED, &axis)) != RR_OK ||
            (st = sp_number(c, v, p, "degrees", SP_REQUIRED, &deg)) != RR_OK)
            return st;
        if (!(rr_v3_len(axis) > 0)) {
            char pa[SP_PATH_MAX];
            sp_key(pa, p, "axis");
            return sp_fail(c, RR_ERR_INVALID, pa, "the rotation axis is the zero vector");
        }
        *x = rotation(axis, deg);
        return RR_OK;
    }
    /* matrix: three rows [a, b, c, t] of the affine map p' = M p + t. */
    if ((st = sp_array(c, v, p, 3, "3 rows of 4 numbers [[m00, m01, m02, tx], [..., ty], [..., tz]]")) != RR_OK)
        return st;
    for (int r = 0; r < 3; r++) {
        char pr[SP_PATH_MAX];
        sp_idx(pr, p, (size_t)r);
        const cJSON *row = cJSON_GetArrayItem(v, r);
        if ((st = sp_array(c, row, pr, 4, "a row of 4 numbers")) != RR_OK)
            return st;
        double e[4];
        for (int k = 0; k < 4; k++) {
            char pk[SP_PATH_MAX];
            sp_idx(pk, pr, (size_t)k);
            if ((st = sp_number_item(c, cJSON_GetArrayItem(row, k), pk, &e[k])) != RR_OK)
                return st;
        }
        x->m[r][0] = e[0], x->m[r][1] = e[1], x->m[r][2] = e[2];
        *(r == 0 ? &x->t.x : r == 1 ? &x->t.y : &x->t.z) = e[3];
    }
    return RR_OK;
}

rr_status sp_parse_transform(const sp_ctx *c, const cJSON *obj, const char *opath, rr_xform *out, int *has)
{
    *out = rr_xform_identity();
    *has = 0;
    const cJSON *tr = sp_get(obj, "transform");
    if (!tr)
        return RR_OK;
    char p[SP_PATH_MAX], got[96];
    sp_key(p, opath, "transform");
    if (!cJSON_IsArray(tr))
        return sp_fail(c, RR_ERR_INVALID, p,
                       "expected an array of steps like {\"translate\": [x, y, z]} (got %s)",
                       sp_describe(tr, got, sizeof got));
    size_t i = 0;
    for (const cJSON *step = tr->child; step; step = step->next, i++) {
        char ps[SP_PATH_MAX];
        sp_idx(ps, p, i);
        rr_xform x;
        rr_status st = parse_step(c, step, ps, &x);
        if (st != RR_OK)
            return st;
        *out = rr_xform_compose(&x, out);
    }
    *has = 1;
    int finite = rr_v3_isfinite(out->t);
    double rows = 1;
    for (int r = 0; r < 3; r++) {
        rr_vec3 row = rr_v3(out->m[r][0], out->m[r][1], out->m[r][2]);
        finite = finite && rr_v3_isfinite(row);
        rows *= rr_v3_len(row);
    }
    if (!finite)
        return sp_fail(c, RR_ERR_INVALID, p, "the combined transform overflows (it is not finite)");
    /* Relative to the row lengths, so a tiny but proper uniform scale passes. */
    double det = rr_xform_det(out);
    if (!(fabs(det) > 1e-12 * rows))
        return sp_fail(c, RR_ERR_INVALID, p, "the transform is singular (determinant %g): it flattens the object",
                       det);
    return RR_OK;
}
