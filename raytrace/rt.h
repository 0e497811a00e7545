/* rt.h - the ray-tracing pass.
 *
 * Offers:
 *  - The lecture's reference geometry, kept deliberately literal so that it can
 *    be read next to the lecture notes and so that every fast path has
 *    something to be tested against:
 *      rt_orient          s(A,B,C,D) = (AB x AC) . AD > 0
 *      rt_front_facing    s(A,B,C,E)
 *      rt_ray_hits_tri    s(P,B,C,E) && s(A,P,C,E) && s(A,B,P,E)
 *      rt_dist_along_ray  t = (AB x AC).EA / (AB x AC).EP
 *  - rt_ref_closest: front-most hit over the whole scene by brute force
 *    (every triangle with the lecture's tests, every sphere in closed form).
 *  - rt_accel_*: the fast path, a BVH with a watertight triangle test, tested
 *    against rt_ref_closest.
 *  - rt_render: the ray-tracing pass (shading, shadows, mirrors, area lights,
 *    secondary rays) into a film with per-component layers.
 *
 * The scene is read-only here; rendering is multithreaded with OpenMP over
 * rows, every pixel draws from its own RNG stream (rr_rng_make(seed, pixel)),
 * so the image is bit-identical whatever the thread count.
 */
#ifndef RT_H
#define RT_H

#include <signal.h>

#include "rr_core.h"
#include "scene.h"

/* s(A,B,C,D): 1 when D lies on the side of plane ABC that AB x AC points to. */
int rt_orient(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 D);
/* Triangle ABC is seen from its front from E (counter-clockwise from E). */
int rt_front_facing(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 E);
/* The ray from E through P meets front-facing triangle ABC (the lecture's test;
 * for a back-facing triangle call it with B and C swapped). */
int rt_ray_hits_tri(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C);
/* Parameter t of the hit H = E + t EP with the plane of ABC (t = 1 at P). The
 * plane must not contain the ray direction (the caller checks facing first). */
double rt_dist_along_ray(rr_vec3 E, rr_vec3 P, rr_vec3 A, rr_vec3 B, rr_vec3 C);

/* The lecture's shading terms for one light of irradiance E arriving along the
 * unit direction L at a surface with unit normal N seen along unit V:
 *   diffuse  += (rho/pi) E (N.L)
 *   specular += s E (R.V)^k,  R = 2(N.L)N - L
 * Negative dot products clamp to zero. (The 1/pi: see rt_render.c.) Used by the
 * renderer for every light sample. */
void rt_phong(rr_vec3 N, rr_vec3 L, rr_vec3 V, const scene_material *m, rr_rgb E, rr_rgb *diffuse, rr_rgb *specular);

/* ReflectedIntensity(E, H, N, L) = a*A*rho + diffuse + specular for one lit
 * light of irradiance `light` (V = HE/|HE|). Shadowing is the caller's Lit(H,L). */
rr_rgb rt_reflected_intensity(rr_vec3 E, rr_vec3 H, rr_vec3 N, rr_vec3 L, const scene_material *m, rr_rgb A,
                              rr_rgb light);

/* The one rule for starting a new ray on a surface (shadow, mirror, bounce,
 * form-factor rays alike): p pushed along the unit normal n, towards the side
 * that dir leaves to, by 1e-9 * (max |coordinate of p| + scale). scale is the
 * scene's extent (rt_scene_scale), so the offset scales with the scene and with
 * the rounding of p; see notes/raytracer.md. */
double rt_scene_scale(const scene *s);
rr_vec3 rt_offset_origin(double scale, rr_vec3 p, rr_vec3 n, rr_vec3 dir);

/* A ray's front-most hit. */
typedef struct rt_hit {
    double t;          /* along the ray's (unnormalised) direction */
    rr_vec3 point;
    rr_vec3 normal;    /* unit geometric normal, facing the ray's origin */
    uint32_t object;   /* index into scene->objects */
    uint32_t material;
    int64_t tri;       /* triangle index, or -1 for a sphere or a solid */
    int64_t part;      /* solids: the CSG leaf (index into scene->csg) whose surface was hit; else -1 */
    int front;         /* the ray met the surface's front side */
} rt_hit;

/* Front-most hit with t in (tmin, tmax) among all triangles and spheres, by
 * brute force with the lecture's tests (back faces culled per object). Returns
 * 1 and fills *hit, or 0 when nothing is hit. */
int rt_ref_closest(const scene *s, rr_ray ray, double tmin, double tmax, rt_hit *hit);

/* Point p lies inside closed object obj (scene_object_closed; 0 for an open one): for
 * diagnostics (a light inside a closed object that faces outwards). */
int rt_object_encloses(const scene *s, uint32_t obj, rr_vec3 p);

/* Ray-sphere hits in closed form, numerically stable (no cancellation for far
 * or grazing rays): the smallest t in (tmin, tmax), or 0 when none. */
int rt_sphere_hit(rr_vec3 center, double radius, rr_ray ray, double tmin, double tmax, double *t);

/* The BVH over a scene (below). */
typedef struct rt_accel rt_accel;

/* ---- solids (CSG trees and quadrics, rt_solid.c) ----
 *
 * A ray meets a solid in a sorted list of disjoint spans [t_in, t_out] where
 * it is inside; CSG combines the lists of the children (Roth 1982). Each end
 * records the leaf whose surface it lies on and which of that leaf's surfaces
 * (quadric body, a clip-box face, a mesh triangle), so the normal and material
 * of the final hit are those of the surface actually hit (normals flipped on
 * surfaces taken from a subtracted solid). */
#define RT_SPAN_MAX 64 /* spans per list; more crossings than this along one ray are cut (the farthest) */

typedef struct rt_span_end {
    double t;
    uint32_t leaf;     /* index into scene->csg */
    int32_t surface;   /* leaf-specific: -1 quadric/sphere body, 0..5 box/clip face, >= 0 mesh triangle (csg_tris) */
    int flip;          /* 1 when the leaf's outward normal must be negated (surface of a subtracted solid) */
} rt_span_end;

typedef struct rt_span {
    rt_span_end in, out;
} rt_span;

typedef struct rt_spans {
    int n;
    rt_span s[RT_SPAN_MAX];
} rt_spans;

/* In all of these, a is the accel built over s (its per-mesh BVHs make mesh
 * leaves fast) or NULL, which tests every mesh triangle (the reference). */

/* All spans of object obj's solid along the ray, clipped to (tmin, tmax), sorted. */
void rt_solid_spans(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax,
                    rt_spans *out);
/* The same for one node (subtree) of scene->csg. */
void rt_csg_spans(const scene *s, const rt_accel *a, uint32_t node, rr_ray ray, double tmin, double tmax,
                  rt_spans *out);
/* Front-most surface hit of a solid with t in (tmin, tmax): hit->tri = -1,
 * hit->part = the leaf, material of that leaf, unit normal facing the ray;
 * back faces culled when the object culls. hit->point is filled. */
int rt_solid_closest(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax,
                     rt_hit *hit);
/* 1 when world point p lies inside the solid of CSG node `node` (its closure,
 * up to rounding; for tessellation and tests). */
int rt_csg_contains(const scene *s, const rt_accel *a, uint32_t node, rr_vec3 p);
/* Outward unit normal of a leaf's surface at world point p (surface as in rt_span_end). */
rr_vec3 rt_csg_leaf_normal(const scene *s, uint32_t leaf, int32_t surface, rr_vec3 p);

/* ---- the primitive table (rt_prim.c) ----
 *
 * Every kind of primitive the BVH holds, and what each pass needs of it, in
 * one row per kind: the BVH (bounds, hit), the light table and the light
 * tracer (emission, light sphere, emit), the diagnostics (encloses), the
 * radiosity pass (area; its own table, rad_patch.c, adds tessellation and
 * patch lookup per kind) and the solution cache (digest). A kind is either
 * per triangle (the scene's triangle array, whatever object made it) or per
 * object (one primitive per scene object of kind object_kind, index = the
 * object's). Adding a kind: its row here, its syntax in scene/, its patches
 * in radiosity/rad_patch.c. */
typedef enum rt_prim_kind { RT_PRIM_TRIANGLE = 0, RT_PRIM_SPHERE = 1, RT_PRIM_SOLID = 2, RT_PRIM_KINDS = 3 } rt_prim_kind;
struct rt_ray_pre;       /* the per-ray set-up of the fast path (rt_internal.h) */
typedef struct rt_lights rt_lights;
typedef struct rt_emission rt_emission;
typedef struct rt_prim_class {
    const char *name;
    int per_object;  /* 0: per scene triangle; 1: per object of kind object_kind */
    int object_kind; /* scene_object_kind (per-object kinds) */
    /* World-space box containing primitive i exactly. */
    void (*bounds)(const scene *s, uint32_t i, rr_vec3 *lo, rr_vec3 *hi);
    /* Nearest hit with tmin < t < *tmax: fills hit (when not NULL; hit->point
     * is left to the caller), lowers *tmax, returns 1. */
    int (*hit)(const rt_accel *a, uint32_t i, const struct rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit);
    /* Surface area; for a solid an upper estimate (its bounding box's). */
    double (*area)(const scene *s, uint32_t i);
    /* Mean over RGB of the radiance of its brightest emitting surface; 0: it does not emit. */
    double (*emission)(const scene *s, uint32_t i);
    /* Per-object kinds: the sphere the light table samples it through (scale:
     * the scene's length scale); 0 when it has none (an empty solid). */
    int (*light_sphere)(const scene *s, uint32_t i, double scale, rr_vec3 *c, double *r);
    /* Per-object kinds: one particle of the light tracer from it (light
     * sphere c, r; u uniform in [0,1)^6; the emitter was picked with
     * probability pk, which out->power includes); 0: this sample emits nothing. */
    int (*emit)(const rt_lights *L, uint32_t i, rr_vec3 c, double r, const double u[6], double pk, rt_emission *out);
    /* Per-object kinds: point p is inside (a closed primitive). */
    int (*encloses)(const scene *s, uint32_t i, rr_vec3 p);
    /* Per-object kinds: feeds what of it (beyond the object's kind, material,
     * csg_root and culling) the radiosity solution depends on to add. */
    void (*digest)(const scene *s, uint32_t i, void (*add)(void *user, const void *bytes, size_t n), void *user);
} rt_prim_class;
extern const rt_prim_class rt_prims[RT_PRIM_KINDS];
/* The kind of object o's primitives: a per-object kind, or RT_PRIM_TRIANGLE
 * (meshes, inline triangles, quads, boxes). */
rt_prim_kind rt_prim_kind_of(const scene *s, uint32_t o);
/* How many primitives the BVH holds for s (triangles + per-object ones). */
size_t rt_prim_total(const scene *s);

/* The fast path: a BVH over every triangle, sphere and solid of a scene
 * (binned SAH, collapsed into 4- or 8-wide nodes with SIMD box tests,
 * watertight triangle test; notes/performance.md). The accel keeps a pointer
 * to the scene, which must outlive it. Queries are thread-safe (read-only).
 * Built by s->settings.threads threads (0: OpenMP's default, all cores) for
 * scenes of 65536 primitives or more; the same BVH, bytes included, for any
 * thread count. */

rr_status rt_accel_build(const scene *s, rt_accel **out, rr_error *err);
/* An accel for the solids' own queries alone (rt_solid_spans,
 * rt_solid_closest, rt_csg_contains: the solids' mesh-leaf BVHs), without
 * the BVH over the primitives, which no other query may then be asked of:
 * for work before the full build (the radiosity pass's patch estimate). */
rr_status rt_accel_build_solids(const scene *s, rt_accel **out, rr_error *err);
void rt_accel_destroy(rt_accel *a); /* NULL is a no-op */
/* What an accel holds, for benchmarks and tools. */
typedef struct rt_accel_stats {
    int width;            /* children per node: 4, 8 or 16 */
    size_t nodes;         /* wide nodes of the scene BVH */
    size_t node_bytes;    /* bytes per wide node (128, 256 or 448) */
    size_t records;       /* leaf packets (up to 4 primitives each) */
    size_t record_bytes;  /* bytes per packet (160: the triangles' float copies of their vertices included) */
    size_t bytes;         /* nodes + packets + double copies (72 per packet lane when a triangle is not
                             float) + solids' BVHs */
} rt_accel_stats;
rt_accel_stats rt_accel_stats_of(const rt_accel *a);
size_t rt_accel_node_count(const rt_accel *a); /* rt_accel_stats_of(a).nodes */
/* Same contract as rt_ref_closest (and tested against it). */
int rt_accel_closest(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit);
/* The same with no back faces culled, of any object: a ray that starts
 * inside a closed box meets the box's back face first. For the form-factor
 * rays' burial test (radiosity/rad_ff.c) and the light tracer's particles,
 * which start on surfaces that may lie under a closed object. A back face
 * of a culling object within 1e-9 (relative) beyond the front face found
 * first is returned instead: where a box's face lies flush with another
 * surface, a ray leaving the box meets the box. */
int rt_accel_closest_two_sided(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit);
/* rt_accel_closest for n rays at once (any n >= 0), walked together in
 * packets of up to RT_PACKET_MAX: found[i] says whether rays[i] hit, and
 * hits[i] is then what rt_accel_closest gives for it, bit for bit. Faster
 * for coherent rays (the camera rays of a small tile, in tile order); no
 * faster for incoherent ones. Returns the number of hits. */
#define RT_PACKET_MAX 64
int rt_accel_closest_n(const rt_accel *a, const rr_ray *rays, int n, double tmin, double tmax, rt_hit *hits,
                       unsigned char *found);
/* Any hit with t in (tmin, tmax): for shadow rays; stops at the first occluder. */
int rt_accel_occluded(const rt_accel *a, rr_ray ray, double tmin, double tmax);
/* rt_accel_occluded for n rays at once (any n >= 0), in packets of up to
 * RT_PACKET_MAX: occ[i] = rt_accel_occluded(a, rays[i], tmin, tmax), bit for
 * bit. Faster for coherent rays on large meshes: rays from one point, or
 * rays that end at one point (o + d the same, tmax <= 1: the shadow rays of
 * a tile towards one point light), 1.7-2x one at a time on the bench's
 * 100k-1M triangle scenes; rays to different points of an area light gain
 * 1.1-1.3x there, and nothing on small scenes (notes/performance.md).
 * Returns the number occluded. */
int rt_accel_occluded_n(const rt_accel *a, const rr_ray *rays, int n, double tmin, double tmax, unsigned char *occ);
/* The scene triangles whose box meets the box [lo, hi] (the BVH's walk, no
 * ray): their indices into scene->tris, in the BVH's leaf order (the same
 * for any thread count), into tri[]. Returns how many there are, or cap + 1
 * where there are more than cap (the walk stops there, tri[] holding cap of
 * them); *other (when not NULL) is set to 1 where a sphere's or a solid's
 * leaf box met the query's before that, else 0. For the radiosity pass's
 * exact visibility (radiosity/rad_hier_link.c exact_occluders, rad_vis.c),
 * which reads the triangles between two surfaces. */
size_t rt_accel_tris_in_box(const rt_accel *a, rr_vec3 lo, rr_vec3 hi, uint32_t *tri, size_t cap, int *other);
/* Rays traced through rt_accel_closest (camera, mirror, bounce and BSDF
 * rays, area-light shadow rays, which must meet the emitter, form-factor
 * rays) and rt_accel_occluded (any-hit: visibility towards point and
 * directional lights and patch points), counted per thread since the thread
 * started: take the difference of two readings. */
typedef struct rt_ray_counts {
    uint64_t closest, occluded;
} rt_ray_counts;
rt_ray_counts rt_ray_counts_of_thread(void);
/* Adds to *total (atomically: threads of one parallel region share it) what
 * this thread has traced since the reading `before`. */
void rt_ray_counts_add_since(rt_ray_counts *total, rt_ray_counts before);

/* ---- the shadow-ray rule (rt_light.c) ----
 *
 * The one rule for every visibility query between a surface point x (unit
 * normal n, on the side the query leaves to) and a target: the origin is
 * offset by rt_offset_origin, and a segment to a point target y ends at
 * RT_SHADOW_END of the way there, so that the surface y lies on (an emitter,
 * a patch, a mirror) never occludes itself. */
#define RT_SHADOW_END (1.0 - 1e-7)
int rt_visible(const rt_accel *a, double scale, rr_vec3 x, rr_vec3 n, rr_vec3 y);
/* The same towards direction dir, to infinity (directional lights). */
int rt_visible_dir(const rt_accel *a, double scale, rr_vec3 x, rr_vec3 n, rr_vec3 dir);

/* ---- lights (rt_light.c): the one light interface ----
 *
 * Every emitter of a scene, for every pass that needs direct light (the ray
 * tracer's shading, the radiosity pass's first shot):
 *  - delta lights: point and directional lights, evaluated one by one;
 *  - area lights: emissive triangles, emissive spheres and solids (a CSG tree
 *    or quadric any of whose leaves emits), sampled with probability
 *    proportional to power and with a solid-angle pdf (for multiple
 *    importance sampling against BSDF sampling);
 *  - virtual images of both kinds in planar mirrors: chains of up to
 *    max_mirror_depth mirror planes (coplanar mirror triangles of one object),
 *    clipped to the finite mirrors and shadowed on every leg, each leg times
 *    the mirror's reflectance. Curved mirrors (spheres, solids) have no
 *    images: light through them is found by BSDF rays only.
 * Read-only once built: thread-safe. a must be built over s; both must
 * outlive the table. */
#define RT_CHAIN_MAX 8 /* mirrors in one image's chain */

rr_status rt_lights_build(const scene *s, const rt_accel *a, int max_mirror_depth, rt_lights **out, rr_error *err);
void rt_lights_destroy(rt_lights *L); /* NULL is a no-op */
size_t rt_lights_delta_count(const rt_lights *L);   /* point and directional lights and their images */
size_t rt_lights_area_count(const rt_lights *L);    /* area lights and their images */
size_t rt_lights_image_count(const rt_lights *L);   /* of all of them, the images */
size_t rt_lights_mirror_planes(const rt_lights *L);
/* The scene light (index into scene->lights) of delta light k or of its image. */
uint32_t rt_lights_delta_source(const rt_lights *L, size_t k);
/* The defined power of scene light l: point 4 pi I, directional E pi R^2 (R:
 * the radius of the scene's bounding sphere; rt_lights_emit's disk). */
rr_rgb rt_light_power(const scene *s, size_t l);
/* 1 when the scene has any emitter (a light, an emissive triangle, sphere or
 * solid leaf): the one rule for "is there light to interreflect". */
int rt_scene_emits(const scene *s);

/* What one light (sample) sends to a surface point. */
typedef struct rt_light_sample {
    rr_vec3 L;   /* unit direction from the point towards the light, or its image */
    rr_rgb E;    /* irradiance on a surface facing L (mirror reflectances and, for a
                    sampled area light, 1/pdf included); the shading multiplies by N.L */
    double pdf;  /* area lights: solid-angle pdf of the sample (light choice included); delta: 0 */
    double dist; /* distance to the (image of the) light point; NAN for curved lights */
    int image;   /* 1 when it arrived by way of mirrors */
} rt_light_sample;

/* Delta light k (0 <= k < rt_lights_delta_count) at point x with unit normal
 * n: 1 and *out when its light (or its image's, through its mirrors)
 * reaches x from the side n points to, unshadowed; else 0. */
int rt_lights_delta(const rt_lights *L, size_t k, rr_vec3 x, rr_vec3 n, rt_light_sample *out);
/* One area-light sample at x from uniforms u0 (light choice), u1, u2 (point):
 * 1 and *out when it is unshadowed and arrives on n's side; else 0 (a sample
 * that counts 0: the estimator stays unbiased). */
int rt_lights_sample(const rt_lights *L, rr_vec3 x, rr_vec3 n, double u0, double u1, double u2, rt_light_sample *out);

/* A BSDF ray's way from a surface point to an emitter, for the pdf that
 * rt_lights_sample would have given the same path. */
typedef struct rt_mirror_path {
    rr_vec3 origin;                  /* the surface point the ray left */
    int n;                           /* planar mirrors met, in order from the origin */
    uint32_t plane[RT_CHAIN_MAX];
    int curved;                      /* met a mirror that has no images (or more than RT_CHAIN_MAX) */
    double dist;                     /* length of the whole way, origin to the emitter's hit */
} rt_mirror_path;

/* For BSDF rays that only look for emitters (the direct term's own BSDF
 * rays): in a scene without mirrors and with at most RT_FIND_EMITTER_MAX area
 * lights, tests the ray against the emissive triangles alone and then one
 * shadow ray to the nearest: 1 and *h (t, point, tri, object, material,
 * front) when it reaches an emitter's front unoccluded, 0 when it reaches
 * none; -1 when the table cannot tell (mirrors, many or curved emitters
 * near the ray): trace the ray instead. Same answers as a closest-hit walk
 * up to rounding at emitter edges. */
#define RT_FIND_EMITTER_MAX 64
int rt_lights_find_emitter(const rt_lights *L, rr_ray r, rt_hit *h);

/* 1 when point x lies within RT_NEAR_RADII bounding radii of an area light
 * or one of its images (always 1 beyond RT_NEAR_MAX of them): where light
 * sampling alone has a heavy tail (1/d^2 of points close to the emitter) and
 * BSDF rays are worth their cost. A function of x alone, so choosing the
 * number of BSDF rays by it keeps multiple importance sampling unbiased. */
#define RT_NEAR_RADII 2.0
#define RT_NEAR_MAX 64
int rt_lights_near(const rt_lights *L, rr_vec3 x);

/* ---- emission (rt_light.c): lights as sources of particles ----
 *
 * The same emitters seen the other way round, for light tracing: a particle
 * leaves a real emitter (images play no part: particles reflect off mirrors
 * themselves), the emitter picked with probability proportional to its power
 * weight: point light 4 pi I, directional light E pi R^2 (R: the radius of
 * the scene's bounding sphere; the light crosses the disk of that radius
 * facing it, from outside the scene), emissive triangle pi Le A, emissive
 * sphere pi Le 4 pi r^2, solid pi Le_max 4 pi R_b^2 (its bounding sphere).
 * Surfaces emit Lambertian from their front. A solid's emissive surface is
 * found without knowing its area: a random line through its bounding sphere
 * (uniform in the measure of lines, which is cos * area * solid angle) meets
 * it where it meets it, and each crossing out of the solid on an emissive
 * leaf is an emission point and direction (one chosen of them, weighted by
 * their count). So every power below is an unbiased estimate. */
struct rt_emission {
    rr_ray ray;        /* origin (offset off the surface) and unit direction */
    rr_rgb power;      /* power the particle carries (pick and sampling pdfs divided out) */
    uint32_t object;   /* scene object that emitted it, or UINT32_MAX for a scene light */
    uint32_t light;    /* scene light (point, directional), or UINT32_MAX */
};

/* Real emitters (scene lights, emissive triangles, spheres, solids). */
size_t rt_lights_emitter_count(const rt_lights *L);
/* One particle from uniforms u[0] (emitter choice) .. u[5]: 1 and *out, or 0
 * when the sample emits nothing (a line that missed the solid's emissive
 * surface: it counts 0, the estimate stays unbiased). */
int rt_lights_emit(const rt_lights *L, const double u[6], rt_emission *out);
/* Cosine-weighted unit direction about unit N from (u1, u2) (Malley's method
 * on Duff et al.'s branchless basis). */
rr_vec3 rt_cosine_dir(rr_vec3 N, double u1, double u2);

/* ---- light tracing (rt_particle.c): an independent energy ledger ----
 *
 * Particles from rt_lights_emit, traced with closest hits through the BVH
 * and scattered by the radiosity pass's model of each material: Lambertian
 * diffuse (rho), one-sided (light arriving at a back face ends there, but
 * for its mirror part), plus perfect mirror (m), two-sided; Phong specular ignored (the lecture's display term, in
 * neither ledger). Tallies use expected values at each hit (incident P,
 * reflected rho P, mirrored m P, absorbed (1 - rho - m) P), and the particle
 * goes on by Russian roulette (diffuse with probability mean(rho P)/mean(P),
 * mirror with mean(m P)/mean(P), power rescaled so its mean stays P's).
 * A particle's power ends in back (back faces), escaped (hit nothing) or
 * lost (past RT_PARTICLE_BOUNCES), or is absorbed at front faces; absorbed
 * is tallied by its expected value at every hit, so the ledger balances in
 * expectation (to its standard errors), not per particle. Standard errors from independent
 * batches. Deterministic for a seed whatever the thread count (one RNG stream
 * per particle, one tally per batch, batches summed in order). */
#define RT_PARTICLE_BOUNCES 100000

/* Columns of a ledger row (power, linear RGB, scene units). */
enum {
    RT_LEDGER_EMITTED = 0, /* leaving the object's emissive surfaces (or the light) */
    RT_LEDGER_INCIDENT,    /* arriving at its front faces */
    RT_LEDGER_REFLECTED,   /* of that, reflected diffusely */
    RT_LEDGER_MIRRORED,    /* reflected by its mirror reflectance (either side) */
    RT_LEDGER_ABSORBED,    /* absorbed at its front faces */
    RT_LEDGER_BACK,        /* arriving at its back faces and ending there (all but the mirror part) */
    RT_LEDGER_COLUMNS
};
typedef struct rt_ledger_row {
    rr_rgb c[RT_LEDGER_COLUMNS];
} rt_ledger_row;

typedef struct rt_particle_opts {
    uint64_t particles; /* in total (>= batches) */
    int batches;        /* >= 2; standard errors from the spread between batches (0: 32) */
    uint64_t seed;
    int threads;        /* 0 = OpenMP default */
    void (*progress)(void *user, uint64_t done, uint64_t total); /* one thread at a time */
    void *progress_user;
    const volatile sig_atomic_t *interrupt; /* non-zero: stop within a particle, RR_ERR_INTERRUPTED */
} rt_particle_opts;

typedef struct rt_particle_ledger {
    size_t nobjects, nlights;          /* rows: scene objects, then scene lights */
    rt_ledger_row *row, *se;           /* [nobjects + nlights]: mean and standard error of the mean */
    rr_rgb escaped, escaped_se;        /* left the scene (hit nothing) */
    rr_rgb lost, lost_se;              /* cut by RT_PARTICLE_BOUNCES */
    rr_rgb unabsorbed, unabsorbed_se;  /* escaped + back faces + lost: what the radiosity ledger calls escaped */
    uint64_t particles, segments;      /* particles emitted, rays traced */
    int batches;
    double seconds;     /* wall time of the tracing */
} rt_particle_ledger;

rr_status rt_particles_trace(const scene *s, const rt_accel *a, const rt_lights *L, const rt_particle_opts *o,
                             rt_particle_ledger *out, rr_error *err);
void rt_particle_ledger_free(rt_particle_ledger *g); /* NULL and double free are harmless */

/* The mirror plane of a hit, or -1 (not a planar mirror). */
int rt_lights_mirror_plane(const rt_lights *L, const rt_hit *h);

/* ---- mirror planes for the radiosity pass (rt_mirror.c; rt_lights_via_mirrors in rt_light.c) ---- */

/* What a scene's mirrors are, by the table's rule for planes: none;
 * planar (every mirror surface in one of the table's planes); curved (a
 * mirror sphere or solid leaf, or more planes than RT_MIRROR_PLANES_MAX).
 * Needs no accelerator. */
typedef enum rt_mirror_kind { RT_MIRRORS_NONE, RT_MIRRORS_PLANAR, RT_MIRRORS_CURVED } rt_mirror_kind;
rt_mirror_kind rt_scene_mirror_kind(const scene *s);
/* Mirror plane k (0 <= k < rt_lights_mirror_planes): n . x = d, its mean
 * reflectance, the corners of its triangles (3 each; owned by L). */
typedef struct rt_mirror_plane {
    rr_vec3 n;
    double d;
    double reflectance;
    const rr_vec3 *verts;
    size_t nverts;
    uint32_t object;   /* the scene object its triangles belong to */
} rt_mirror_plane;
rt_mirror_plane rt_lights_plane(const rt_lights *L, size_t k);
/* The shadow-ray rule (rt_visible) folded at the mirror planes chain[0 ..
 * n-1] (1 <= n <= RT_CHAIN_MAX), chain[0] met first from x: 1 when the
 * straight segment from x (normal nx, on whose side it must leave) towards
 * y's image in the chain, folded leg by leg as a light image's legs are,
 * has each leg meet its plane's own triangles first, and the last leg
 * reaches y (normal ny) unoccluded. */
int rt_lights_via_mirrors(const rt_lights *L, const uint32_t *chain, int n, rr_vec3 x, rr_vec3 nx, rr_vec3 y,
                          rr_vec3 ny);
/* Solid-angle pdf with which rt_lights_sample picks the emitter point hit by
 * path's ray (h: the hit on the emitter, last_dir: the last leg's unit
 * direction); 0 when no light (image) of the table covers that path. */
double rt_lights_pdf(const rt_lights *L, const rt_mirror_path *path, const rt_hit *h, rr_vec3 last_dir);

/* The radiosity pass's solution as the ray tracer reads it: the one typed
 * interface through which it reaches rt_render (radiosity/ implements it,
 * rad_solution_field; raytrace cannot include radiosity). An implementation
 * embeds this struct and finds itself from the pointer. Both functions are
 * called from many threads at once. */
typedef struct rt_field rt_field;
struct rt_field {
    /* Radiance B/pi leaving the hit, emitters included (the display). */
    rr_rgb (*radiance)(const rt_field *f, const rt_hit *hit);
    /* Indirect diffuse radiance leaving a hit on a surface of reflectance
     * rho: light after at least one diffuse reflection, so that the ray
     * tracer's direct light is not counted twice (the hybrid). */
    rr_rgb (*indirect)(const rt_field *f, const rt_hit *hit, rr_rgb rho);
};

/* What supplies the diffuse interreflection. */
typedef enum rt_indirect {
    RT_INDIRECT_NONE = 0,      /* direct light only */
    RT_INDIRECT_AMBIENT = 1,   /* the lecture's a * A * rho (Whitted) */
    RT_INDIRECT_SECONDARY = 2, /* Monte Carlo secondary rays (unbiased reference) */
    RT_INDIRECT_RADIOSITY = 3  /* the radiosity pass, through field->indirect (the hybrid) */
} rt_indirect;

typedef enum rt_filter { RT_FILTER_BOX = 0, RT_FILTER_TENT = 1 } rt_filter;

/* Follows a ray through perfect mirror reflections (surfaces whose material has
 * any mirror reflectance), R = d - 2(d.N)N, up to max_bounces. Returns the
 * number of reflections and stores the last ray (the one that left the last
 * mirror); *escaped is 1 when that ray hits nothing. For tests and tools. */
int rt_follow_mirrors(const rt_accel *a, rr_ray ray, int max_bounces, rr_ray *last, int *escaped);

typedef struct rt_render_opts {
    int spp;          /* samples per pixel over the pixel filter: a jittered m x m grid (m = floor(sqrt(spp))), the rest uniform */
    uint64_t seed;
    int threads;      /* 0 = OpenMP default */
    int max_depth;    /* the most mirror reflections on any path (scene render.max_depth) */
    int light_samples; /* shadow rays per hit for the area lights */
    rt_indirect indirect;
    rt_filter filter;
    /* The radiosity solution (NULL: none), needed by RT_INDIRECT_RADIOSITY
     * and by show_field (rt_render refuses either without it). */
    const rt_field *field;
    /* Radiosity display: every camera-ray hit shows the field's radiance
     * (emitters included) and what mirrors show of it; nothing else is
     * shaded and indirect is not used. */
    int show_field;
    /* Progress, called from one thread at a time with the work units (tiles)
     * finished so far. */
    void (*progress)(void *user, int done, int total);
    void *progress_user;
    /* Interrupt (e.g. set by a SIGINT handler): when it points to a non-zero
     * value, checked before every pixel and every 256 samples of one,
     * rt_render stops starting work,
     * clears the tiles it had begun (finished tiles stay, the rest is black)
     * and returns RR_ERR_INTERRUPTED. NULL: never interrupted. */
    const volatile sig_atomic_t *interrupt;
    /* When set, receives the rays this render traced (all threads). */
    rt_ray_counts *rays;
    /* Several processes (NULL: this one alone): the tiles come from dist's
     * work list, and at the end every rank's film holds the whole image
     * (each tile rendered by exactly one rank, merged with the others'
     * zeros: the same bytes as one process). The film must start zeroed
     * (rt_film_init). Progress counts this rank's tiles. */
    rr_dist *dist;
} rt_render_opts;

/* Per-component layers of a render; the beauty image is their sum. */
enum {
    RT_LAYER_EMISSION = 0, /* emitters seen directly (and through mirrors) */
    RT_LAYER_AMBIENT,      /* a * A * rho */
    RT_LAYER_DIFFUSE,      /* direct diffuse: (rho/pi) E (N.L), shadowed */
    RT_LAYER_SPECULAR,     /* Phong: s E (R.V)^k, shadowed */
    RT_LAYER_MIRROR,       /* mirror reflectance times what the mirror ray sees */
    RT_LAYER_INDIRECT,     /* diffuse interreflection (secondary rays or the radiosity pass) */
    RT_LAYER_RADIOSITY,    /* radiosity display: B/pi interpolated across patches */
    RT_LAYER_COUNT
};
const char *rt_layer_name(int layer);

typedef struct rt_film {
    rr_image beauty;
    rr_image layer[RT_LAYER_COUNT];
} rt_film;

rr_status rt_film_init(rt_film *f, int width, int height, rr_error *err);
void rt_film_free(rt_film *f); /* NULL and double free are harmless */

/* The ray-tracing pass: for every pixel, spp rays from E through the pixel
 * (stratified, filtered), front-most hit through the BVH, direct light with
 * shadow rays, Phong specular, recursive mirrors, and the chosen indirect
 * term. Deterministic for a seed whatever the thread count (tiles over OpenMP,
 * one RNG stream per pixel). */
rr_status rt_render(const scene *s, const rt_accel *a, const rt_render_opts *opts, rt_film *film, rr_error *err);

/* Arbitrary output variables (for figures and denoisers) of the first hit
 * of each pixel's centre ray, one image per AOV (view-sized, initialised):
 *   albedo     the diffuse reflectance of the material hit (0 on a miss)
 *   normal     the unit surface normal there, facing the ray (0 on a miss)
 *   depth      the distance from the eye E to the hit, in every channel (0 on a miss)
 *   object_id  the index of the object hit in the scene's objects, in every
 *              channel (-1 on a miss)
 * Only the AOVs whose bit (1u << RT_AOV_*) is in mask are written.
 * Deterministic, threads as rt_render_opts.threads; the rays go in 8 x 8
 * pixel packets (rt_accel_closest_n). */
enum { RT_AOV_ALBEDO = 0, RT_AOV_NORMAL, RT_AOV_DEPTH, RT_AOV_OBJECT_ID, RT_AOV_COUNT };
const char *rt_aov_name(int aov);
void rt_render_aovs(const scene *s, const rt_accel *a, unsigned mask, rr_image *aov, int threads);

/* NaN/Inf guard for the output: every pixel of the beauty image or of a layer
 * with a non-finite channel is set to 0 (all three channels, in that image).
 * Returns the number of pixels so cleared (counted once however many images
 * had one there) and stores the coordinates of the first max_report of them,
 * in row-major order, in xs/ys (either may be NULL when max_report is 0). */
size_t rt_film_scrub_nonfinite(rt_film *film, size_t max_report, int *xs, int *ys);

#endif
