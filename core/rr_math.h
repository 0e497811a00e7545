/* rr_math.h - small value types: vectors, colours, rays (part of core, see rr_core.h).
 *
 * Everything here is a transparent struct passed by value with static inline
 * operations. Geometry is double precision throughout: the lecture's orientation
 * tests and the watertight hit test both want the extra mantissa bits, and the
 * cost is small next to memory traffic. */
#ifndef RR_MATH_H
#define RR_MATH_H

#include <math.h>

typedef struct rr_vec3 {
    double x, y, z;
} rr_vec3;

/* Linear RGB radiometric quantity (radiance, reflectance, power...). */
typedef struct rr_rgb {
    double r, g, b;
} rr_rgb;

/* A ray H = o + t*d. d is not necessarily unit length: the lecture's primary
 * ray has d = EP, so that t = 1 lies on the screen. */
typedef struct rr_ray {
    rr_vec3 o, d;
} rr_ray;

static inline rr_vec3 rr_v3(double x, double y, double z) { rr_vec3 v = {x, y, z}; return v; }
static inline rr_vec3 rr_v3_add(rr_vec3 a, rr_vec3 b) { return rr_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline rr_vec3 rr_v3_sub(rr_vec3 a, rr_vec3 b) { return rr_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline rr_vec3 rr_v3_scale(rr_vec3 a, double s) { return rr_v3(a.x * s, a.y * s, a.z * s); }
static inline rr_vec3 rr_v3_mul(rr_vec3 a, rr_vec3 b) { return rr_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline rr_vec3 rr_v3_neg(rr_vec3 a) { return rr_v3(-a.x, -a.y, -a.z); }
/* a + s*b, the workhorse of ray evaluation. */
static inline rr_vec3 rr_v3_madd(rr_vec3 a, rr_vec3 b, double s) { return rr_v3(a.x + s * b.x, a.y + s * b.y, a.z + s * b.z); }
static inline double rr_v3_dot(rr_vec3 a, rr_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline rr_vec3 rr_v3_cross(rr_vec3 a, rr_vec3 b)
{
    return rr_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double rr_v3_len2(rr_vec3 a) { return rr_v3_dot(a, a); }
static inline double rr_v3_len(rr_vec3 a) { return sqrt(rr_v3_dot(a, a)); }
/* Unit vector along a; the zero vector stays zero (callers that cannot accept
 * that check the length first). */
static inline rr_vec3 rr_v3_norm(rr_vec3 a)
{
    double l = rr_v3_len(a);
    return l > 0.0 ? rr_v3_scale(a, 1.0 / l) : a;
}
/* fmax and fmin with their rule for NaN (the other operand) inlined: in
 * this build (no -ffinite-math-only) fmax is a call into libm, on every
 * material test of the shading (rr_rgb_max) and every bound of the BVH
 * build. Of two equal operands (+0 and -0 too) the first. */
static inline double rr_max(double a, double b) { return a >= b || b != b ? a : b; }
static inline double rr_min(double a, double b) { return a <= b || b != b ? a : b; }
/* The same for any finite a, however large or small its components (scaled by
 * the largest first, so the squared length cannot overflow or underflow); the
 * zero vector (and a non-finite one) gives zero. For input, not hot paths. */
static inline rr_vec3 rr_v3_unit(rr_vec3 a)
{
    double m = rr_max(fabs(a.x), rr_max(fabs(a.y), fabs(a.z)));
    if (!(m > 0.0) || !isfinite(m))
        return rr_v3(0.0, 0.0, 0.0);
    return rr_v3_norm(rr_v3_scale(a, 1.0 / m));
}
static inline rr_vec3 rr_v3_min(rr_vec3 a, rr_vec3 b) { return rr_v3(rr_min(a.x, b.x), rr_min(a.y, b.y), rr_min(a.z, b.z)); }
static inline rr_vec3 rr_v3_max(rr_vec3 a, rr_vec3 b) { return rr_v3(rr_max(a.x, b.x), rr_max(a.y, b.y), rr_max(a.z, b.z)); }
static inline double rr_v3_get(rr_vec3 a, int axis) { return axis == 0 ? a.x : (axis == 1 ? a.y : a.z); }
static inline int rr_v3_isfinite(rr_vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
static inline rr_vec3 rr_ray_at(rr_ray r, double t) { return rr_v3_madd(r.o, r.d, t); }

static inline rr_rgb rr_rgb_make(double r, double g, double b) { rr_rgb c = {r, g, b}; return c; }
static inline rr_rgb rr_rgb_add(rr_rgb a, rr_rgb b) { return rr_rgb_make(a.r + b.r, a.g + b.g, a.b + b.b); }
static inline rr_rgb rr_rgb_mul(rr_rgb a, rr_rgb b) { return rr_rgb_make(a.r * b.r, a.g * b.g, a.b * b.b); }
static inline rr_rgb rr_rgb_scale(rr_rgb a, double s) { return rr_rgb_make(a.r * s, a.g * s, a.b * s); }
static inline double rr_rgb_max(rr_rgb a) { return rr_max(a.r, rr_max(a.g, a.b)); }
static inline double rr_rgb_mean(rr_rgb a) { return (a.r + a.g + a.b) / 3.0; }
static inline int rr_rgb_isfinite(rr_rgb a) { return isfinite(a.r) && isfinite(a.g) && isfinite(a.b); }

/* Affine transform: p' = M p + t (row-major 3x3 M). */
typedef struct rr_xform {
    double m[3][3];
    rr_vec3 t;
} rr_xform;

static inline rr_xform rr_xform_identity(void)
{
    rr_xform x = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {0, 0, 0}};
    return x;
}
static inline rr_vec3 rr_xform_vector(const rr_xform *x, rr_vec3 v)
{
    return rr_v3(x->m[0][0] * v.x + x->m[0][1] * v.y + x->m[0][2] * v.z,
                 x->m[1][0] * v.x + x->m[1][1] * v.y + x->m[1][2] * v.z,
                 x->m[2][0] * v.x + x->m[2][1] * v.y + x->m[2][2] * v.z);
}
static inline rr_vec3 rr_xform_point(const rr_xform *x, rr_vec3 p) { return rr_v3_add(rr_xform_vector(x, p), x->t); }
/* a after b: (a*b)(p) = a(b(p)). */
static inline rr_xform rr_xform_compose(const rr_xform *a, const rr_xform *b)
{
    rr_xform r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.m[i][j] = a->m[i][0] * b->m[0][j] + a->m[i][1] * b->m[1][j] + a->m[i][2] * b->m[2][j];
    r.t = rr_xform_point(a, b->t);
    return r;
}
static inline double rr_xform_det(const rr_xform *x)
{
    const double(*m)[3] = x->m;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

#define RR_PI 3.14159265358979323846

#endif
