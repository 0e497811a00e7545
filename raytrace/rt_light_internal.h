/* rt_light_internal.h - private to raytrace/: the light table's layout,
 * shared by rt_light.c (building, evaluation towards a point) and rt_emit.c
 * (emission of particles, the lights' powers). */
#ifndef RT_LIGHT_INTERNAL_H
#define RT_LIGHT_INTERNAL_H

#include "rt_internal.h"

#define RT_VIRTUAL_PER_LIGHT 64
#define RT_VIRTUAL_MAX 65536
#define RT_MIRROR_PLANES_MAX 256

typedef enum light_kind { LK_POINT, LK_DIRECTIONAL, LK_TRIANGLE, LK_SPHERE } light_kind;

typedef struct mplane {
    rr_vec3 n;          /* unit normal */
    double d;           /* n . x = d on the plane */
    uint32_t object;
    double reflectance; /* mean mirror reflectance of its (first) triangle's material */
    rr_vec3 *verts;     /* corners of its triangles (for the pruning side tests) */
    size_t nverts;
} mplane;

typedef struct light {
    light_kind kind;
    uint32_t index;     /* scene light (delta), triangle, or object (sphere: spheres and solids) */
    int nchain;
    uint32_t chain[RT_CHAIN_MAX]; /* mirror planes, c[0] first from the light */
    rr_vec3 p;          /* point: (virtual) position; directional: (virtual) unit direction to the light;
                           sphere, triangle: (virtual) centre of the bounding sphere */
    double r;           /* sphere, triangle: bounding radius */
    rr_vec3 tv[3], tn;  /* triangle: (virtual) corners and front normal */
    double area;        /* triangle: area */
    rr_rgb radiance;    /* triangle: Le; delta: intensity */
    double weight;      /* pick weight (area lights) */
    uint32_t vfirst, vcount; /* real area lights: their images are area[vfirst .. +vcount) */
} light;

struct rt_lights {
    const scene *s;
    const rt_accel *a;
    double scale;
    mplane *planes;
    size_t nplanes;
    int32_t *tri_plane;   /* scene triangle -> mirror plane, -1 */
    light *delta;
    size_t ndelta;
    light *area;          /* real ones first (nreal), then images */
    size_t narea, nreal;
    double *cdf;          /* over area */
    int32_t *tri_light;   /* scene triangle -> real area light, -1 */
    int32_t *obj_light;   /* scene object -> real area light (spheres, solids), -1 */
    int has_mirror;       /* any material with a mirror reflectance */
    /* Emission (rt_lights_emit): the real delta lights, then the real area lights. */
    uint32_t *emit_delta; /* index into delta of each real delta light */
    size_t nemit_delta;
    double *ecdf;         /* over the nemit_delta + nreal emitters, by power weight */
    rr_vec3 scene_c;      /* bounding sphere of the scene (directional lights' disk) */
    double scene_r;
};

/* The light tracer's emission from a sphere (uniform on the surface, cosine
 * about the normal) and from a solid (random lines through its light sphere
 * c, r): the emit functions of the primitive table (rt.h, rt_prims). */
int rt__emit_sphere(const rt_lights *L, uint32_t i, rr_vec3 c, double r, const double u[6], double pk,
                    rt_emission *out);
int rt__emit_solid(const rt_lights *L, uint32_t i, rr_vec3 c, double r, const double u[6], double pk,
                   rt_emission *out);

/* The emission table (L->emit_delta, L->ecdf, the scene's bounding sphere),
 * once the lights are built. */
rr_status rt__lights_build_emitters(rt_lights *L, rr_error *err);

/* The mirror planes of L->s into L->planes and L->tri_plane (L->s and
 * L->scale set; rt_light.c, "Mirror planes"). */
rr_status rt__lights_build_planes(rt_lights *L, rr_error *err);

#endif
