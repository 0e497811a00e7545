/* bench_scenes.h - the procedural benchmark scenes and ray sets shared by
 * radray-bench (bench_rays.c) and radray-bench-embree (bench_embree.c).
 *
 * Three scenes (room-100k, mesh-1m: procedural; bunny-1m: the scanned
 * Stanford bunny, Loop-subdivided; recipes in bench/README.md) are built
 * from a fixed recipe and seed, written as binary PLY into a temporary folder
 * and loaded through the real scene path (scene_load_string). The three ray
 * workloads (primary, diffuse, shadow) are generated once from the primary
 * hits of a radray BVH, so every consumer traces exactly the same rays.
 */
#ifndef BENCH_SCENES_H
#define BENCH_SCENES_H

#include <stddef.h>
#include <stdint.h>

#include "rr_core.h"
#include "rt.h"
#include "scene.h"

/* Program name used in error messages ("radray-bench" unless changed). */
extern const char *bench_prog;

double now_s(void);                 /* CLOCK_MONOTONIC seconds */
double median(double *v, int n);    /* sorts v in place */
void *xmalloc(size_t n);            /* exits on failure */
void cpu_model(char *out, size_t size); /* "model name" from /proc/cpuinfo */

/* A growing triangle soup: float positions (what the PLY stores), int indices. */
typedef struct soup {
    float *pos;
    size_t nverts, vcap;
    int32_t *idx;
    size_t ntris, tcap;
} soup;

void soup_free(soup *m);

typedef struct bench_scene {
    const char *name;
    const char *recipe; /* one line, printed with the results */
    soup mesh;
    /* Camera (a lookat camera in the scene JSON), point light. */
    rr_vec3 eye, target;
    double fov;
    rr_vec3 light;
    double light_size; /* 0: the point light; else shadow rays go to points of a horizontal square
                          of that side (a fraction of the scene's extent) centred on it */
} bench_scene;

void make_room(bench_scene *b, uint64_t seed);
void make_mesh1m(bench_scene *b, uint64_t seed);
/* bunny-1m from the PLY at ply (scenes/meshes/bunny.ply). */
void make_bunny1m(bench_scene *b, const char *ply);
int write_ply(const char *path, const soup *m);

/* Writes b's mesh as PLY into tmpdir, loads it as a scene with a res x res
 * camera, removes the PLY and frees b->mesh. Times in seconds. Exits on error. */
scene *bench_load_scene(bench_scene *b, int res, const char *tmpdir, double *t_write, double *t_load);

typedef struct ray_set {
    rr_ray *rays;
    size_t n;
    double tmax;   /* the same for every ray of a set */
    int width;     /* the image's width and height in pixels */
    int height;
    uint32_t *pix; /* the pixel (y * width + x) ray i belongs to, in increasing order;
                      NULL for the primary set, whose ray i is pixel i */
} ray_set;

/* The rays of a set grouped by tile x tile pixel tiles (rows of tiles,
 * scanline order within a tile; partial tiles at the right and bottom
 * edges): idx[j] is the j-th ray's index in the set (n entries), and the
 * rays of tile t are idx[start[t] .. start[t + 1]) (ntiles + 1 entries; a
 * tile may hold none). The tiles are the packets of radray's packet walks
 * (rt_accel_closest_n, rt_accel_occluded_n). */
typedef struct tile_order {
    uint32_t *idx;
    size_t *start;
    size_t ntiles;
} tile_order;
tile_order bench_tile_order(const ray_set *rs, int tile);
void bench_tile_order_free(tile_order *t);
void ray_set_free(ray_set *rs);

rr_vec3 cosine_dir(rr_vec3 n, double u1, double u2);
rr_vec3 offset_origin(rr_vec3 p, rr_vec3 n, rr_vec3 dir, double extent);

/* The three workloads: primary (one per pixel), diffuse (one cosine-weighted
 * ray from every primary hit, from PCG stream (seed, pixel)) and shadow (from
 * every primary hit facing b->light, t < 1 - 1e-7; to a point of the square
 * light when b->light_size > 0). Primary hits come from a. */
void bench_make_rays(const scene *s, const rt_accel *a, const bench_scene *b, uint64_t seed, ray_set *prim,
                     ray_set *diff, ray_set *shad);

#endif
