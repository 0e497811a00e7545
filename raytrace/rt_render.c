/* rt_render.c - the ray-tracing pass: the lecture's shading with shadows,
 * mirrors, area lights, and Monte Carlo secondary rays.
 *
 * Radiometry. Everything is linear RGB radiance. The lecture's
 *   I = a*A + d*(N.L) + s*(R.V)^k,  R = 2(N.L)N - L
 * is evaluated per light with the light's irradiance E at the hit (directional:
 * its intensity; point: intensity / r^2; area: Monte Carlo over the emitter):
 *   ambient   a * A * rho                 (only when the indirect term is "ambient")
 *   diffuse   (rho / pi) * E * (N.L)      only where Lit(H, L)
 *   specular  s * E * (R.V)^k             only where Lit(H, L)
 * The 1/pi makes a Lambertian surface of reflectance rho reflect exactly rho of
 * what it receives, which is what the radiosity pass (B = pi L) and the
 * secondary rays assume: without it the modes could not be compared.
 *
 * Who counts emission (so nothing is counted twice): every emitter, and its
 * images in planar mirrors, is sampled explicitly through the light interface
 * (rt_light.c) from every diffuse hit; BSDF rays (the secondary mode's bounce
 * rays, and in the other modes the direct term's own BSDF rays) that meet an
 * emitter, directly or through mirrors, keep the balance-heuristic share of
 * the BSDF strategy, so the two strategies together count each path once
 * (pb / (pb + nl pl), with pl the light table's pdf of the same path: 0 for a
 * path through a curved mirror, which only BSDF rays find). Camera rays and
 * the mirror rays they spawn add all the emission they see.
 */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "rt_internal.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define RT_TILE 16
#define RT_MAX_BOUNCES 256 /* safety cap; Russian roulette ends paths long before */

static const char *const k_layer_names[RT_LAYER_COUNT] = {"emission", "ambient",  "diffuse",  "specular",
                                                          "mirror",   "indirect", "radiosity"};

const char *rt_layer_name(int layer) { return layer >= 0 && layer < RT_LAYER_COUNT ? k_layer_names[layer] : "?"; }

rr_status rt_film_init(rt_film *f, int width, int height, rr_error *err)
{
    memset(f, 0, sizeof *f);
    rr_status st = rr_image_init(&f->beauty, width, height, err);
    for (int i = 0; st == RR_OK && i < RT_LAYER_COUNT; i++)
        st = rr_image_init(&f->layer[i], width, height, err);
    if (st != RR_OK)
        rt_film_free(f);
    return st;
}

void rt_film_free(rt_film *f)
{
    if (!f)
        return;
    rr_image_free(&f->beauty);
    for (int i = 0; i < RT_LAYER_COUNT; i++)
        rr_image_free(&f->layer[i]);
}

typedef struct render_ctx {
    const scene *s;
    const rt_accel *a;
    const rt_render_opts *o;
    rt_lights *lights;
    double eps_scale; /* length scale for ray offsets */
} render_ctx;

double rt_scene_scale(const scene *s)
{
    rr_vec3 ext = rr_v3_sub(s->bbox_max, s->bbox_min);
    double m = fmax(ext.x, fmax(ext.y, ext.z));
    return isfinite(m) && m > 0 ? m : 1.0;
}

rr_vec3 rt_offset_origin(double scale, rr_vec3 p, rr_vec3 n, rr_vec3 dir)
{
    double m = fmax(fabs(p.x), fmax(fabs(p.y), fabs(p.z)));
    double eps = 1e-9 * (m + scale);
    return rr_v3_madd(p, n, rr_v3_dot(n, dir) >= 0.0 ? eps : -eps);
}

typedef struct shade_out {
    rr_rgb c[RT_LAYER_COUNT];
} shade_out;

/* A BSDF ray's bookkeeping for multiple importance sampling (balance
 * heuristic): it left a diffuse point where nl light samples were taken,
 * with bsdf pdf pb (cos / pi), and has met the mirrors in path since. NULL
 * for rays that count all the emission they meet (camera and mirror rays
 * from them). */
typedef struct mis_state {
    double pb;
    int nl;
    rt_mirror_path path;
} mis_state;

static rr_rgb radiance(const render_ctx *c, rr_ray ray, int depth, int bounce, const mis_state *mis, rr_rng *rng,
                       shade_out *out);

/* The share of emission found by a BSDF ray at emitter hit h (ray direction
 * d) that the BSDF strategy keeps: pb / (pb + nl pl). */
static double bsdf_weight(const render_ctx *c, const mis_state *mis, const rt_hit *h, rr_vec3 d)
{
    if (!mis)
        return 1.0;
    mis_state m = *mis;
    m.path.dist += h->t;
    double pl = mis->nl * rt_lights_pdf(c->lights, &m.path, h, d);
    return mis->pb / (mis->pb + pl);
}

/* The mirror path of a BSDF ray one more reflection on (at hit h). */
static void mis_reflect(const render_ctx *c, mis_state *m, const rt_hit *h)
{
    m->path.dist += h->t;
    int q = rt_lights_mirror_plane(c->lights, h);
    if (q < 0 || m->path.n >= RT_CHAIN_MAX)
        m->path.curved = 1;
    else
        m->path.plane[m->path.n++] = (uint32_t)q;
}

/* Cosine-weighted direction about N (Malley's method). */
static rr_vec3 cosine_dir(rr_vec3 N, rr_rng *rng);

/* Emission that a BSDF ray from H along unit dir meets directly or through
 * mirrors (up to the mirror depth left), weighted against light sampling. */
static rr_rgb bsdf_emission(const render_ctx *c, rr_vec3 H, rr_vec3 N, rr_vec3 dir, int depth, mis_state *mis)
{
    rr_rgb thru = rr_rgb_make(1, 1, 1);
    rr_ray r = {rt_offset_origin(c->eps_scale, H, N, dir), dir};
    rt_hit eh;
    int found = rt_lights_find_emitter(c->lights, r, &eh);
    if (found == 0)
        return rr_rgb_make(0, 0, 0);
    if (found == 1)
        return rr_rgb_scale(c->s->materials[eh.material].emission, bsdf_weight(c, mis, &eh, r.d));
    for (;;) {
        rt_hit h;
        if (!rt_accel_closest(c->a, r, 0.0, INFINITY, &h))
            return rr_rgb_make(0, 0, 0);
        const scene_material *m = &c->s->materials[h.material];
        if (h.front && rr_rgb_max(m->emission) > 0.0)
            return rr_rgb_scale(rr_rgb_mul(thru, m->emission), bsdf_weight(c, mis, &h, r.d));
        if (!(rr_rgb_max(m->mirror) > 0.0) || depth >= c->o->max_depth)
            return rr_rgb_make(0, 0, 0);
        mis_reflect(c, mis, &h);
        thru = rr_rgb_mul(thru, m->mirror);
        rr_vec3 R = rr_v3_madd(r.d, h.normal, -2.0 * rr_v3_dot(r.d, h.normal));
        r.o = rt_offset_origin(c->eps_scale, h.point, h.normal, R);
        r.d = R;
        depth++;
    }
}

/* The lecture's Phong terms for one light (rt.h): the shading every light
 * sample of the renderer goes through, and rt_reflected_intensity too. */
void rt_phong(rr_vec3 N, rr_vec3 L, rr_vec3 V, const scene_material *m, rr_rgb E, rr_rgb *diffuse, rr_rgb *specular)
{
    double ndotl = rr_v3_dot(N, L);
    if (ndotl <= 0.0)
        return; /* the light is behind the surface: negative dot products clamp to zero */
    *diffuse = rr_rgb_add(*diffuse, rr_rgb_scale(rr_rgb_mul(m->diffuse, E), ndotl / RR_PI));
    if (rr_rgb_max(m->specular) <= 0.0)
        return;
    rr_vec3 R = rr_v3_sub(rr_v3_scale(N, 2.0 * ndotl), L); /* R = 2(N.L)N - L */
    double rv = rr_v3_dot(R, V);
    if (rv > 0.0)
        *specular = rr_rgb_add(*specular, rr_rgb_scale(rr_rgb_mul(m->specular, E), pow(rv, m->k)));
}

/* Direct light at H: every delta light (and its mirror images) with its
 * shadow rays, nl samples of the area lights (and their images), and nb BSDF
 * rays for the diffuse part, combined with the light samples by the balance
 * heuristic against nbw BSDF rays in all (nbw = nb, or 1 when the caller
 * takes a bounce ray; nbw = 0: pure light sampling). */
static void direct_light(const render_ctx *c, rr_vec3 H, rr_vec3 N, rr_vec3 V, const scene_material *m, int nl, int nb,
                         int nbw, int depth, rr_rng *rng, rr_rgb *diffuse, rr_rgb *specular)
{
    const rt_lights *L = c->lights;
    size_t nd = rt_lights_delta_count(L);
    for (size_t k = 0; k < nd; k++) {
        rt_light_sample ls;
        if (rt_lights_delta(L, k, H, N, &ls))
            rt_phong(N, ls.L, V, m, ls.E, diffuse, specular);
    }
    if (rt_lights_area_count(L) == 0)
        return;
    int n = nl > 0 ? nl : 1;
    for (int k = 0; k < n; k++) {
        double u0 = ((double)k + rr_rng_uniform(rng)) / n;
        double u1 = rr_rng_uniform(rng), u2 = rr_rng_uniform(rng);
        rt_light_sample ls;
        if (!rt_lights_sample(L, H, N, u0, u1, u2, &ls))
            continue;
        rr_rgb dd = rr_rgb_make(0, 0, 0);
        rt_phong(N, ls.L, V, m, rr_rgb_scale(ls.E, 1.0 / n), &dd, specular);
        /* Near an emitter the BSDF strategy wins, which is what keeps the
         * 1/d^2 of light sampling from making fireflies. */
        if (nbw > 0) {
            double pl = n * ls.pdf, pb = nbw * rr_v3_dot(N, ls.L) / RR_PI;
            dd = rr_rgb_scale(dd, pl / (pl + pb));
        }
        *diffuse = rr_rgb_add(*diffuse, dd);
    }
    if (nb <= 0 || !(rr_rgb_max(m->diffuse) > 0.0))
        return;
    for (int k = 0; k < nb; k++) {
        rr_vec3 dir = cosine_dir(N, rng);
        mis_state ms;
        memset(&ms, 0, sizeof ms);
        ms.pb = nb * rr_v3_dot(N, dir) / RR_PI;
        ms.nl = n;
        ms.path.origin = H;
        rr_rgb Le = bsdf_emission(c, H, N, dir, depth, &ms);
        /* rho/pi Le cos / (cos/pi) / nb = rho Le / nb */
        *diffuse = rr_rgb_add(*diffuse, rr_rgb_scale(rr_rgb_mul(m->diffuse, Le), 1.0 / nb));
    }
}

static rr_vec3 cosine_dir(rr_vec3 N, rr_rng *rng)
{
    double r = sqrt(rr_rng_uniform(rng)), phi = 2.0 * RR_PI * rr_rng_uniform(rng);
    double x = r * cos(phi), y = r * sin(phi), z = sqrt(fmax(0.0, 1.0 - x * x - y * y));
    /* Orthonormal basis (Duff et al. 2017, branchless). */
    double sign = copysign(1.0, N.z);
    double a = -1.0 / (sign + N.z), b = N.x * N.y * a;
    rr_vec3 T = rr_v3(1.0 + sign * N.x * N.x * a, sign * b, -sign * N.x);
    rr_vec3 B = rr_v3(b, sign + N.y * N.y * a, -N.y);
    return rr_v3_add(rr_v3_add(rr_v3_scale(T, x), rr_v3_scale(B, y)), rr_v3_scale(N, z));
}

/* The mirror layer at hit h seen along -V: the mirror reflectance times
 * what the reflected ray R = 2(N.V)N - V sees, while mirror depth is left. */
static rr_rgb mirror_term(const render_ctx *c, const rt_hit *h, rr_vec3 V, const scene_material *m, int depth,
                          int bounce, const mis_state *mis, rr_rng *rng)
{
    if (!(rr_rgb_max(m->mirror) > 0.0) || depth >= c->o->max_depth)
        return rr_rgb_make(0, 0, 0);
    rr_vec3 N = h->normal;
    rr_vec3 R = rr_v3_sub(rr_v3_scale(N, 2.0 * rr_v3_dot(N, V)), V);
    rr_ray mr = {rt_offset_origin(c->eps_scale, h->point, N, R), R};
    mis_state mm;
    if (mis) {
        mm = *mis;
        mis_reflect(c, &mm, h);
    }
    return rr_rgb_mul(m->mirror, radiance(c, mr, depth + 1, bounce, mis ? &mm : NULL, rng, NULL));
}

/* The radiosity display at hit h: the view-independent solution, emitters
 * included, and what mirrors show of it. */
static void shade_field(const render_ctx *c, const rt_hit *h, rr_vec3 V, int depth, int bounce, rr_rng *rng,
                        shade_out *local)
{
    const scene_material *m = &c->s->materials[h->material];
    local->c[RT_LAYER_RADIOSITY] = c->o->field->radiance(c->o->field, h);
    local->c[RT_LAYER_MIRROR] = mirror_term(c, h, V, m, depth, bounce, NULL, rng);
}

/* The diffuse bounce of the secondary mode: rho/pi * L * cos / (cos/pi) =
 * rho * L, Russian roulette past 3 bounces. */
static rr_rgb bounce_term(const render_ctx *c, const rt_hit *h, const scene_material *m, int depth, int bounce,
                          int nlight, rr_rng *rng)
{
    rr_rgb weight = m->diffuse;
    if (bounce >= 3) {
        double q = fmin(0.95, rr_rgb_max(m->diffuse));
        if (rr_rng_uniform(rng) >= q)
            return rr_rgb_make(0, 0, 0);
        weight = rr_rgb_scale(weight, 1.0 / q);
    }
    rr_vec3 dir = cosine_dir(h->normal, rng);
    rr_ray br = {rt_offset_origin(c->eps_scale, h->point, h->normal, dir), dir};
    mis_state bm;
    memset(&bm, 0, sizeof bm);
    bm.pb = rr_v3_dot(h->normal, dir) / RR_PI;
    bm.nl = nlight;
    bm.path.origin = h->point;
    return rr_rgb_mul(weight, radiance(c, br, depth, bounce + 1, &bm, rng, NULL));
}

/* The lecture's shading at hit h seen along -V: emission, direct light with
 * shadow rays, Phong, mirrors, and the indirect term the options name. */
static void shade_surface(const render_ctx *c, const rt_hit *h, rr_vec3 dir, rr_vec3 V, int depth, int bounce,
                          const mis_state *mis, rr_rng *rng, shade_out *local)
{
    const scene *s = c->s;
    const scene_material *m = &s->materials[h->material];
    rr_vec3 N = h->normal; /* faces the incoming ray */
    if (h->front && rr_rgb_max(m->emission) > 0.0)
        local->c[RT_LAYER_EMISSION] = rr_rgb_scale(m->emission, bsdf_weight(c, mis, h, dir));
    int diffuse = rr_rgb_max(m->diffuse) > 0.0;
    rt_indirect indirect = diffuse ? c->o->indirect : RT_INDIRECT_NONE;
    int bounces = indirect == RT_INDIRECT_SECONDARY && bounce < RT_MAX_BOUNCES;
    /* Soft shadows get light_samples at the points the eye sees (and mirrors
     * show); deeper diffuse bounces take one sample each, as their noise
     * averages out over the many paths through a pixel. */
    int nlight = bounce == 0 ? c->o->light_samples : 1;
    if (nlight < 1)
        nlight = 1;
    /* BSDF rays for the direct term where no bounce ray is taken (multiple
     * importance sampling in every mode, not only with secondary rays). */
    int nbsdf = bounces || !rt_lights_near(c->lights, h->point) ? 0 : (nlight + 3) / 4;
    if (diffuse || rr_rgb_max(m->specular) > 0.0)
        direct_light(c, h->point, N, V, m, nlight, nbsdf, bounces ? 1 : nbsdf, depth, rng,
                     &local->c[RT_LAYER_DIFFUSE], &local->c[RT_LAYER_SPECULAR]);
    if (indirect == RT_INDIRECT_AMBIENT)
        local->c[RT_LAYER_AMBIENT] = rr_rgb_scale(rr_rgb_mul(m->diffuse, s->settings.ambient), m->ambient);
    local->c[RT_LAYER_MIRROR] = mirror_term(c, h, V, m, depth, bounce, mis, rng);
    if (indirect == RT_INDIRECT_RADIOSITY)
        local->c[RT_LAYER_INDIRECT] = c->o->field->indirect(c->o->field, h, m->diffuse);
    if (bounces)
        local->c[RT_LAYER_INDIRECT] = bounce_term(c, h, m, depth, bounce, nlight, rng);
}

/* The radiance along ray, whose closest hit (found, h) is known. */
static rr_rgb radiance_at(const render_ctx *c, rr_ray ray, int found, const rt_hit *h, int depth, int bounce,
                          const mis_state *mis, rr_rng *rng, shade_out *out)
{
    const scene *s = c->s;
    if (!found) {
        if (out) {
            memset(out, 0, sizeof *out);
            out->c[RT_LAYER_EMISSION] = s->settings.background;
        }
        return s->settings.background;
    }
    rr_vec3 V = rr_v3_norm(rr_v3_neg(ray.d));
    shade_out local;
    memset(&local, 0, sizeof local);
    if (c->o->show_field)
        shade_field(c, h, V, depth, bounce, rng, &local);
    else
        shade_surface(c, h, ray.d, V, depth, bounce, mis, rng, &local);
    rr_rgb sum = rr_rgb_make(0, 0, 0);
    for (int i = 0; i < RT_LAYER_COUNT; i++)
        sum = rr_rgb_add(sum, local.c[i]);
    if (out)
        *out = local;
    return sum;
}

static rr_rgb radiance(const render_ctx *c, rr_ray ray, int depth, int bounce, const mis_state *mis, rr_rng *rng,
                       shade_out *out)
{
    rt_hit h;
    int found = rt_accel_closest(c->a, ray, 0.0, INFINITY, &h);
    return radiance_at(c, ray, found, &h, depth, bounce, mis, rng, out);
}

/* Stratified sub-pixel offset for sample k of n, warped by the pixel filter:
 * box over [-0.5, 0.5]^2, or tent over [-1, 1]^2 (filter importance sampling,
 * so every sample has weight 1 and pixels stay independent). The first m^2
 * samples (m = floor(sqrt(n))) are multi-jittered (Chiu, Shirley and Wang
 * 1994, with the per-pattern shuffles of Kensler's correlated multi-jittered
 * sampling, 2013): one per cell of an m x m grid, and one per column of an
 * m^2 x m^2 grid and per row of it, the sub-column (sub-row) of the samples
 * of one grid row (column) shuffled by a permutation drawn for the pixel
 * (key). An edge along x or y is then sampled in m^2 strata instead of m
 * (Cornell at 128 px, 4 spp, against a 4096-spp reference: radiosity
 * display block rel_rms 0.0642 -> 0.0454, hybrid 0.0692 -> 0.0419). The
 * rest are uniform over the pixel: each sample is uniform over the pixel,
 * so the estimate is unbiased for any n. (A grid of ceil(sqrt(n)) columns
 * filled row by row left its last row short of samples when n is not a
 * square: at 32 spp the bottom sixth of every pixel had 2 samples instead
 * of 5 or 6, and the edges of Cornell's lamp came out up to 29 % off per
 * 4 x 4 block against a 4096-spp reference.) */
static double tent_warp(double u)
{
    return u < 0.5 ? sqrt(2.0 * u) - 1.0 : 1.0 - sqrt(2.0 - 2.0 * u);
}

static uint32_t gcd_u32(uint32_t a, uint32_t b)
{
    while (b) {
        uint32_t t = a % b;
        a = b;
        b = t;
    }
    return a;
}

/* Element i of a permutation of 0 .. m - 1 drawn from seed: i -> (a i + b)
 * mod m, a coprime with m. A bijection, so the strata stay one sample each;
 * b uniform, so each element is uniform over 0 .. m - 1 (what keeps the
 * samples unbiased); no table (m is up to 4096 at 2^24 spp). */
static int shuffled(int i, int m, uint64_t seed)
{
    rr_rng r = rr_rng_make(seed, 0x6d6a6974ULL);
    uint32_t a;
    do
        a = 1u + rr_rng_below(&r, (uint32_t)m);
    while (gcd_u32(a, (uint32_t)m) != 1u);
    uint32_t b = rr_rng_below(&r, (uint32_t)m);
    return (int)(((uint64_t)a * (uint64_t)i + b) % (uint64_t)m);
}

static void pixel_offset(int k, int n, rt_filter filter, uint64_t key, rr_rng *rng, double *dx, double *dy)
{
    int m = (int)sqrt((double)n);
    while ((m + 1) * (m + 1) <= n)
        m++;
    while (m * m > n)
        m--;
    double u, v;
    if (k < m * m) {
        int i = k % m, j = k / m; /* its cell: column i, row j */
        int sx = m > 1 ? shuffled(j, m, key) : 0, sy = m > 1 ? shuffled(i, m, ~key) : 0;
        u = ((double)i + ((double)sx + rr_rng_uniform(rng)) / m) / m;
        v = ((double)j + ((double)sy + rr_rng_uniform(rng)) / m) / m;
    } else {
        u = rr_rng_uniform(rng);
        v = rr_rng_uniform(rng);
    }
    if (n == 1 && filter == RT_FILTER_BOX) {
        *dx = *dy = 0.0; /* one sample: the lecture's ray through the pixel centre */
        return;
    }
    if (filter == RT_FILTER_TENT) {
        *dx = tent_warp(u);
        *dy = tent_warp(v);
    } else {
        *dx = u - 0.5;
        *dy = v - 0.5;
    }
}

/* The camera rays of a tile in packets of RT_PACKET_TILE x RT_PACKET_TILE
 * pixels (rt_accel_closest_n: neighbouring pixels' rays walk the BVH
 * together, the same hits as one at a time). */
#define RT_PACKET_TILE 8

/* Per pixel of a tile: its RNG stream and its sums over the samples. */
typedef struct tile_px {
    rr_rng rng;
    uint64_t key; /* the pixel's sub-pixel shuffles (pixel_offset) */
    shade_out acc;
} tile_px;

/* Renders the tile at (x0, y0) into film; 0 when an interrupt stopped it
 * (the tile is then black, like the tiles never begun). Sample by sample
 * over the tile: the camera rays of sample k of every pixel are traced
 * together, then each pixel shades its own. Every pixel draws from its own
 * stream in the order it did one pixel at a time (offset, then shading, for
 * k = 0, 1, ...), so the image is the same bits. */
static int render_tile(const render_ctx *c, int spp, int x0, int y0, rt_film *film)
{
    const rr_view *v = &c->s->view;
    const rt_render_opts *o = c->o;
    const int w = x0 + RT_TILE < v->width ? RT_TILE : v->width - x0;
    const int h = y0 + RT_TILE < v->height ? RT_TILE : v->height - y0;
    tile_px px[RT_TILE * RT_TILE];
    rr_ray rays[RT_TILE * RT_TILE];
    rt_hit hits[RT_TILE * RT_TILE];
    unsigned char found[RT_TILE * RT_TILE];
    int order[RT_TILE * RT_TILE], n = 0; /* pixel (y * RT_TILE + x) of each ray, packet by packet */
    for (int py = 0; py < h; py += RT_PACKET_TILE)
        for (int pxl = 0; pxl < w; pxl += RT_PACKET_TILE)
            for (int y = py; y < py + RT_PACKET_TILE && y < h; y++)
                for (int x = pxl; x < pxl + RT_PACKET_TILE && x < w; x++)
                    order[n++] = y * RT_TILE + x;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            tile_px *q = &px[y * RT_TILE + x];
            q->rng = rr_rng_make(o->seed, (uint64_t)(y0 + y) * (uint64_t)v->width + (uint64_t)(x0 + x));
            q->key = rr_hash64(rr_hash64(o->seed) ^ ((uint64_t)(y0 + y) * (uint64_t)v->width + (uint64_t)(x0 + x)));
            memset(&q->acc, 0, sizeof q->acc);
        }
    int stopped = 0;
    for (int k = 0; k < spp && !stopped; k++) {
        for (int j = 0; j < n; j++) {
            int p = order[j];
            double dx, dy;
            pixel_offset(k, spp, o->filter, px[p].key, &px[p].rng, &dx, &dy);
            rays[j] = rr_view_ray(v, x0 + p % RT_TILE, y0 + p / RT_TILE, dx, dy);
        }
        for (int j = 0; j < n; j += RT_PACKET_TILE * RT_PACKET_TILE) {
            int m = n - j < RT_PACKET_TILE * RT_PACKET_TILE ? n - j : RT_PACKET_TILE * RT_PACKET_TILE;
            rt_accel_closest_n(c->a, rays + j, m, 0.0, INFINITY, hits + j, found + j);
        }
        for (int j = 0; j < n; j++) {
            if (o->interrupt && *o->interrupt) {
                stopped = 1;
                break;
            }
            tile_px *q = &px[order[j]];
            shade_out so;
            radiance_at(c, rays[j], found[j], &hits[j], 0, 0, NULL, &q->rng, &so);
            for (int i = 0; i < RT_LAYER_COUNT; i++)
                q->acc.c[i] = rr_rgb_add(q->acc.c[i], so.c[i]);
        }
    }
    if (!stopped) {
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const tile_px *q = &px[y * RT_TILE + x];
                rr_rgb sum = rr_rgb_make(0, 0, 0);
                for (int i = 0; i < RT_LAYER_COUNT; i++) {
                    rr_rgb mean = rr_rgb_scale(q->acc.c[i], 1.0 / spp);
                    rr_image_set(&film->layer[i], x0 + x, y0 + y, mean);
                    sum = rr_rgb_add(sum, mean);
                }
                rr_image_set(&film->beauty, x0 + x, y0 + y, sum);
            }
        return 1;
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            rr_image_set(&film->beauty, x0 + x, y0 + y, rr_rgb_make(0, 0, 0));
            for (int i = 0; i < RT_LAYER_COUNT; i++)
                rr_image_set(&film->layer[i], x0 + x, y0 + y, rr_rgb_make(0, 0, 0));
        }
    return 0;
}

/* Ends the ranks' tile list and merges their films: every pixel was
 * rendered by one rank and is zero bits in the others (a fresh film). */
static rr_status gather_film(rr_dist *dist, rt_film *film, rr_error *err)
{
    rr_status st = dist->end(dist, err);
    size_t n = 3 * (size_t)film->beauty.width * (size_t)film->beauty.height;
    if (st == RR_OK)
        st = dist->merge(dist, film->beauty.px, n, err);
    for (int i = 0; i < RT_LAYER_COUNT && st == RR_OK; i++)
        st = dist->merge(dist, film->layer[i].px, n, err);
    return st;
}

rr_status rt_render(const scene *s, const rt_accel *a, const rt_render_opts *o, rt_film *film, rr_error *err)
{
    const rr_view *v = &s->view;
    if (film->beauty.width != v->width || film->beauty.height != v->height)
        return rr_error_set(err, RR_ERR_INTERNAL, "film is %d x %d but the view is %d x %d", film->beauty.width,
                            film->beauty.height, v->width, v->height);
    if ((o->show_field || o->indirect == RT_INDIRECT_RADIOSITY) && !(o->field && o->field->radiance && o->field->indirect))
        return rr_error_set(err, RR_ERR_INTERNAL, "%s needs the radiosity solution (rt_render_opts.field)",
                            o->show_field ? "the radiosity display" : "the radiosity indirect term");
    render_ctx c;
    c.s = s;
    c.a = a;
    c.o = o;
    c.eps_scale = rt_scene_scale(s);
    rr_status st = rt_lights_build(s, a, o->max_depth, &c.lights, err);
    if (st != RR_OK)
        return st;
    int spp = o->spp > 0 ? o->spp : 1;
    int tiles_x = (v->width + RT_TILE - 1) / RT_TILE, tiles_y = (v->height + RT_TILE - 1) / RT_TILE;
    int ntiles = tiles_x * tiles_y, done = 0;
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    (void)nthreads;
    rt_ray_counts total = {0, 0};
    rr_dist *dist = o->dist;
    if (dist && (st = dist->begin(dist, ntiles, err)) != RR_OK) {
        rt_lights_destroy(c.lights);
        return st;
    }
    long long next_tile = 0;
#pragma omp parallel num_threads(nthreads)
    {
    rt_ray_counts before = rt_ray_counts_of_thread();
    long long t;
    /* The next tile: from the ranks' shared list, or this process's. */
    while ((t = rr_dist_take(dist, &next_tile, ntiles)) >= 0) {
        int tile = (int)t;
        if (!render_tile(&c, spp, (tile % tiles_x) * RT_TILE, (tile / tiles_x) * RT_TILE, film))
            continue;
        int now;
#pragma omp atomic capture
        now = ++done;
        if (o->progress) {
#pragma omp critical(rt_progress)
            o->progress(o->progress_user, now, ntiles);
        }
    }
    rt_ray_counts_add_since(&total, before);
    }
    if (o->rays)
        *o->rays = total;
    rt_lights_destroy(c.lights);
    if (dist && (st = gather_film(dist, film, err)) != RR_OK)
        return st;
    if (o->interrupt && *o->interrupt)
        return rr_error_set(err, RR_ERR_INTERRUPTED, "interrupted: %d of %d tiles finished", done, ntiles);
    return RR_OK;
}

static const char *const k_aov_names[RT_AOV_COUNT] = {"albedo", "normal", "depth", "object_id"};

const char *rt_aov_name(int aov) { return aov >= 0 && aov < RT_AOV_COUNT ? k_aov_names[aov] : "?"; }

void rt_render_aovs(const scene *s, const rt_accel *a, unsigned mask, rr_image *aov, int threads)
{
    const rr_view *v = &s->view;
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = threads > 0 ? threads : omp_get_max_threads();
#endif
    (void)nthreads;
    (void)threads;
    /* 8 x 8 pixel packets (rt_accel_closest_n), rows of packets to threads. */
    const int P = RT_PACKET_TILE, prow = (v->height + P - 1) / P;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (int pr = 0; pr < prow; pr++)
        for (int x0 = 0; x0 < v->width; x0 += P) {
            rr_ray r[RT_PACKET_TILE * RT_PACKET_TILE];
            rt_hit hs[RT_PACKET_TILE * RT_PACKET_TILE];
            unsigned char f[RT_PACKET_TILE * RT_PACKET_TILE];
            int cols[RT_PACKET_TILE * RT_PACKET_TILE], rows[RT_PACKET_TILE * RT_PACKET_TILE], n = 0;
            for (int row = pr * P; row < pr * P + P && row < v->height; row++)
                for (int col = x0; col < x0 + P && col < v->width; col++) {
                    cols[n] = col;
                    rows[n] = row;
                    r[n++] = rr_view_ray(v, col, row, 0.0, 0.0);
                }
            rt_accel_closest_n(a, r, n, 0.0, INFINITY, hs, f);
            for (int j = 0; j < n; j++) {
                const rt_hit *hp = &hs[j];
                rr_rgb val[RT_AOV_COUNT];
                if (f[j]) {
                    double depth = hp->t * rr_v3_len(r[j].d), id = (double)hp->object;
                    val[RT_AOV_ALBEDO] = s->materials[hp->material].diffuse;
                    val[RT_AOV_NORMAL] = rr_rgb_make(hp->normal.x, hp->normal.y, hp->normal.z);
                    val[RT_AOV_DEPTH] = rr_rgb_make(depth, depth, depth);
                    val[RT_AOV_OBJECT_ID] = rr_rgb_make(id, id, id);
                } else {
                    val[RT_AOV_ALBEDO] = val[RT_AOV_NORMAL] = val[RT_AOV_DEPTH] = rr_rgb_make(0, 0, 0);
                    val[RT_AOV_OBJECT_ID] = rr_rgb_make(-1, -1, -1);
                }
                for (int k = 0; k < RT_AOV_COUNT; k++)
                    if (mask & (1u << k))
                        rr_image_set(&aov[k], cols[j], rows[j], val[k]);
            }
        }
}

static int pixel_finite(const rr_image *im, size_t k)
{
    const float *p = im->px + 3 * k;
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

size_t rt_film_scrub_nonfinite(rt_film *film, size_t max_report, int *xs, int *ys)
{
    rr_image *img[RT_LAYER_COUNT + 1];
    img[0] = &film->beauty;
    for (int i = 0; i < RT_LAYER_COUNT; i++)
        img[i + 1] = &film->layer[i];
    int w = film->beauty.width, h = film->beauty.height;
    if (!film->beauty.px || w <= 0 || h <= 0)
        return 0;
    size_t bad = 0, npx = (size_t)w * (size_t)h;
    for (size_t k = 0; k < npx; k++) {
        int hit = 0;
        for (int i = 0; i < RT_LAYER_COUNT + 1; i++) {
            const rr_image *im = img[i];
            if (!im->px || im->width != w || im->height != h || pixel_finite(im, k))
                continue;
            float *p = im->px + 3 * k;
            p[0] = p[1] = p[2] = 0.0f;
            hit = 1;
        }
        if (!hit)
            continue;
        if (bad < max_report) {
            if (xs)
                xs[bad] = (int)(k % (size_t)w);
            if (ys)
                ys[bad] = (int)(k / (size_t)w);
        }
        bad++;
    }
    return bad;
}

int rt_follow_mirrors(const rt_accel *a, rr_ray ray, int max_bounces, rr_ray *last, int *escaped)
{
    const scene *s = a->scene;
    render_ctx c;
    memset(&c, 0, sizeof c);
    c.s = s;
    c.a = a;
    c.eps_scale = rt_scene_scale(s);
    int n = 0;
    *escaped = 0;
    for (;;) {
        rt_hit h;
        if (!rt_accel_closest(a, ray, 0.0, INFINITY, &h)) {
            *escaped = 1;
            break;
        }
        if (n >= max_bounces || rr_rgb_max(s->materials[h.material].mirror) <= 0.0)
            break;
        rr_vec3 R = rr_v3_madd(ray.d, h.normal, -2.0 * rr_v3_dot(ray.d, h.normal));
        ray.o = rt_offset_origin(c.eps_scale, h.point, h.normal, R);
        ray.d = R;
        n++;
    }
    *last = ray;
    return n;
}
