/* rad_ff_internal.h - the sampling patterns of the form-factor estimators
 * (rad_ff.c), here so that the tests can check them directly; the matrix's
 * storage and reciprocity (rad_ff_matrix.c); the clipping and polygon points
 * the hierarchical links share (rad_hier.c). Not part of the public API (rad.h). */
#ifndef RAD_FF_INTERNAL_H
#define RAD_FF_INTERNAL_H

#include <math.h>
#include <stdint.h>

#include "rr_core.h"
#include "rt.h"

/* Largest m with m * m <= n. */
static inline uint32_t rad_ff_isqrt(uint32_t n)
{
    uint32_t m = (uint32_t)sqrt((double)n);
    while ((uint64_t)(m + 1) * (m + 1) <= n)
        m++;
    while ((uint64_t)m * m > n)
        m--;
    return m;
}

/* Jittered stratum k of n on the unit square (for directions): an nx x ny
 * grid (nx = floor(sqrt n)), the n - nx*ny left over samples uniform. */
static inline void rad_ff_square_stratum(uint32_t k, uint32_t n, rr_rng *rng, double *u1, double *u2)
{
    uint32_t nx = rad_ff_isqrt(n), ny = n / nx;
    if (nx > 0 && k < nx * ny) {
        *u1 = ((double)(k % nx) + rr_rng_uniform(rng)) / nx;
        *u2 = ((double)(k / nx) + rr_rng_uniform(rng)) / ny;
    } else {
        *u1 = rr_rng_uniform(rng);
        *u2 = rr_rng_uniform(rng);
    }
}

static inline void rad_ff_shuffle(uint32_t *perm, uint32_t n, rr_rng *rng)
{
    for (uint32_t k = 0; k < n; k++)
        perm[k] = k;
    for (uint32_t k = n; k > 1; k--) {
        uint32_t r = rr_rng_below(rng, k);
        uint32_t t = perm[k - 1];
        perm[k - 1] = perm[r];
        perm[r] = t;
    }
}

/* Stratum k of n on a triangle: the triangle is cut into m^2 similar
 * sub-triangles (m = floor(sqrt n), the grid rad_patch uses), and the sample
 * is uniform in sub-triangle k; the n - m^2 left over samples are uniform on
 * the whole triangle. Similar sub-triangles keep every stratum compact, unlike
 * a jittered square pushed through the square-root warp, whose strata turn
 * into slivers at one corner. Returns (u, v): P = A + u (B - A) + v (C - A). */
static inline void rad_ff_tri_stratum(uint32_t k, uint32_t n, rr_rng *rng, double *u, double *v)
{
    uint32_t m = rad_ff_isqrt(n);
    double a = rr_rng_uniform(rng), b = rr_rng_uniform(rng);
    if (a + b > 1.0) { /* fold the square onto the unit right triangle */
        a = 1.0 - a;
        b = 1.0 - b;
    }
    if (k >= m * m) {
        *u = a;
        *v = b;
        return;
    }
    /* Row j holds 2 (m - j) - 1 sub-triangles, j (2m - j) before it: the row
     * of k is the largest j with j (2m - j) <= k, j = m - sqrt(m^2 - k) up to
     * rounding (fixed by the loops). */
    double jr = floor((double)m - sqrt((double)m * m - (double)k));
    uint32_t j = jr < 0 ? 0u : (jr > m - 1 ? m - 1 : (uint32_t)jr);
    while (j > 0 && (uint64_t)j * (2 * m - j) > k)
        j--;
    while (j + 1 < m && (uint64_t)(j + 1) * (2 * m - j - 1) <= k)
        j++;
    uint32_t t = k - j * (2 * m - j), i = t / 2;
    if (t % 2 == 0) { /* upright: (i, j), (i+1, j), (i, j+1) */
        *u = (i + a) / m;
        *v = (j + b) / m;
    } else { /* inverted: (i+1, j+1), (i, j+1), (i+1, j) */
        *u = (i + 1 - a) / m;
        *v = (j + 1 - b) / m;
    }
}

/* Cosine-weighted direction about unit N from (u1, u2): the light
 * interface's (rt_cosine_dir, the same sampling the light tracer uses). */
static inline rr_vec3 rad_ff_cosine_dir(rr_vec3 N, double u1, double u2) { return rt_cosine_dir(N, u1, u2); }

/* ---- the matrix (rad_ff_matrix.c) ---- */

typedef struct rad_ff rad_ff;
struct rad_patches;
/* An n-row matrix with room for nnz entries (rowptr zeroed); NULL when out of memory. */
rad_ff *rad__ff_alloc(size_t n, size_t nnz);
void rad__ff_free(rad_ff *F);
/* The matrix rad_ff_compute returns, from the raw estimates F (consumed):
 * F itself when o->raw, else made reciprocal and (Monte Carlo) balanced.
 * NULL when out of memory. */
struct rad_ff_opts;
rad_ff *rad__ff_finish(const struct rad_patches *P, rad_ff *F, const struct rad_ff_opts *o);

/* atan2(y, x) for y >= 0, within a few ulps (rad_ff.c): the contour
 * integral's angles. */
double rad__ff_angle(double y, double x);

/* The hierarchical links' quadrature rules for near pairs (rad_hier_link.c):
 * smooth, 7 points of degree 5; else that rule on each of the 4 children
 * (28). Barycentrics into b, weights (summing to 1) into w; returns the
 * count. */
int rad__hier_near_rule(int smooth, double (*b)[3], double *w);

/* Sutherland-Hodgman: the part of triangle tri on the front of the plane
 * (n, p0), vertices within tol of it kept; at most 4 vertices (rad_ff.c). */
int rad__clip_front(const rr_vec3 tri[3], rr_vec3 n, rr_vec3 p0, double tol, rr_vec3 out[4]);
/* The factor from x (unit normal nx) to the part of convex polygon poly
 * (nv <= 4 vertices, in front of x's tangent plane) that x sees past the
 * triangles occ[0 .. nocc) (cull[t] != 0: occ[t] is of an object that culls
 * back faces, and does not occlude where x sees its back; cull may be
 * NULL), surfaces within tol of x's tangent plane or of poly's plane not
 * occluding (rad_vis.c). *hidden: some part of poly is hidden. Where
 * nothing is, rad_ff_point_polygon(x, nx, poly, nv) exactly; -1 when the
 * visible part has more pieces than it holds (the caller casts rays). */
double rad__ff_visible(rr_vec3 x, rr_vec3 nx, const rr_vec3 *poly, int nv, const rr_vec3 (*occ)[3],
                       const unsigned char *cull, int nocc, double tol, int *hidden);
/* Point (u, v) of a clipped polygon of 3 or 4 vertices, the quad's triangle
 * picked by area with the golden-ratio sequence in k (rad_ff.c). */
rr_vec3 rad__poly_point(const rr_vec3 *poly, int nv, double u, double v, uint32_t k);

/* A sphere's or a solid's facet stands for more area than its triangle has
 * (rad_patch.c scales its patch area to the true surface's): a factor to it,
 * read on its triangle, is scaled by q->area / (the triangle's area), by the
 * quadrature (rad_ff.c) and the hierarchical links (rad_hier_link.c). 1 for
 * triangles' patches. */
struct rad_patches;
struct rad_patch;
double rad__facet_scale(const struct rad_patches *P, const struct rad_patch *q);

/* ---- buried parts (rad.h; rad_ff.c, rad_hier.c) ---- */

/* Whether the first leg r of a ray from a surface point of normal n, whose
 * two-sided closest hit is h, started under a surface: h is a back face of an
 * object that culls back faces (the origin is inside a closed box) at any
 * distance, or of any surface closer than bury, or of one that encloses the
 * origin (probes near the tangent plane meet back faces too). Or it started
 * in a thin gap: h is the front of a surface that does not emit at a height
 * w under gap above the tangent plane (t times the cosine), and four probes
 * close to the plane meet surfaces under 2 w above it too, a slot about w
 * wide around the point (a panel 3 mm under a ceiling, a rug 1 mm over the floor:
 * the pass's elements cannot resolve the light in such a slot, which comes
 * in only a few gap widths from its rim, and spread the light of their open
 * part over it; notes/radiosity.md, "Thin gaps"). gap 0: no such test. */
int rad__ff_buried(const scene *s, const rt_accel *a, rr_ray r, rr_vec3 n, const rt_hit *h, double bury, double gap,
                   int sides);
/* rad__ff_buried's answer for a point buried in a thin gap (else 1 for one
 * under a cover, 0 for an open one). sides (the hierarchical pass): the
 * point's own side of the slot must go on round it too (rad_ff.c
 * own_side_goes_on). */
#define RAD_BURIED_SLOT 2
/* The same for a ray not yet traced (a probe): its two-sided closest hit,
 * then the rule; a ray that meets nothing is open. */
int rad__ff_point_buried(const scene *s, const rt_accel *a, rr_ray r, rr_vec3 n, double bury, double gap, int sides);

#endif
