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
 * Who counts emission (so nothing is counted twice): a triangle emitter is
 * sampled explicitly (next-event estimation) from every diffuse hit, so a
 * diffuse bounce ray that happens to hit it adds nothing; camera rays and mirror
 * rays do add what they see. Emissive spheres are not sampled explicitly; any
 * ray that meets one adds its emission.
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

/* Area-light table: emissive triangles chosen with probability proportional to
 * area times mean emitted radiance (their power up to pi). */
typedef struct light_table {
    const uint32_t *tris;
    double *cdf; /* cdf[i] = sum of weights of tris[0..i] / total */
    double *area;
    int64_t *index_of; /* scene triangle -> entry, or -1 (for MIS weights of bounce hits) */
    size_t n;
} light_table;

typedef struct render_ctx {
    const scene *s;
    const rt_accel *a;
    const rt_render_opts *o;
    light_table lights;
    double eps_scale; /* length scale for ray offsets */
} render_ctx;

static rr_status light_table_build(const scene *s, light_table *lt, rr_error *err)
{
    memset(lt, 0, sizeof *lt);
    if (s->nemissive == 0)
        return RR_OK;
    lt->cdf = malloc(s->nemissive * sizeof *lt->cdf);
    lt->area = malloc(s->nemissive * sizeof *lt->area);
    lt->index_of = malloc(s->ntris * sizeof *lt->index_of);
    if (!lt->cdf || !lt->area || !lt->index_of) {
        free(lt->cdf);
        free(lt->area);
        free(lt->index_of);
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for the area-light table");
    }
    for (size_t t = 0; t < s->ntris; t++)
        lt->index_of[t] = -1;
    for (size_t i = 0; i < s->nemissive; i++)
        lt->index_of[s->emissive_tris[i]] = (int64_t)i;
    double total = 0;
    for (size_t i = 0; i < s->nemissive; i++) {
        uint32_t t = s->emissive_tris[i];
        lt->area[i] = scene_tri_area(s, t);
        total += lt->area[i] * rr_rgb_mean(s->materials[s->tris[t].material].emission);
        lt->cdf[i] = total;
    }
    for (size_t i = 0; i < s->nemissive; i++)
        lt->cdf[i] = total > 0 ? lt->cdf[i] / total : (double)(i + 1) / (double)s->nemissive;
    lt->tris = s->emissive_tris;
    lt->n = s->nemissive;
    return RR_OK;
}

static void light_table_free(light_table *lt)
{
    free(lt->cdf);
    free(lt->area);
    free(lt->index_of);
}

/* Probability (per unit solid angle, seen from the shading point) that one
 * light sample picks the point at distance d on entry li whose cosine towards
 * the shading point is cos_y. */
static double light_pdf_solid_angle(const light_table *lt, size_t li, double d2, double cos_y)
{
    double pick = lt->cdf[li] - (li ? lt->cdf[li - 1] : 0.0);
    return pick / lt->area[li] * d2 / cos_y;
}

/* Index of the first cdf entry > u; *u_out re-used as a fresh uniform inside
 * the chosen interval (keeps the stratification of u for the point sample). */
static size_t light_pick(const light_table *lt, double u, double *pdf)
{
    size_t lo = 0, hi = lt->n - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (lt->cdf[mid] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    *pdf = lt->cdf[lo] - (lo ? lt->cdf[lo - 1] : 0.0);
    return lo;
}

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

static rr_vec3 offset_origin(const render_ctx *c, rr_vec3 p, rr_vec3 n, rr_vec3 dir)
{
    return rt_offset_origin(c->eps_scale, p, n, dir);
}

/* Lit(H, L): nothing between the offset origin and the light. */
static int lit(const render_ctx *c, rr_vec3 from, rr_vec3 to_dir, double tmax)
{
    rr_ray r = {from, to_dir};
    return !rt_accel_occluded(c->a, r, 0.0, tmax);
}

typedef struct shade_out {
    rr_rgb c[RT_LAYER_COUNT];
} shade_out;

/* mis_pdf < 0: the ray counts all the triangle emission it meets (camera and
 * mirror rays); >= 0: a diffuse bounce ray, whose triangle emission is weighted
 * against the mis_n light samples taken at its origin (see radiance). */
static rr_rgb radiance(const render_ctx *c, rr_ray ray, int depth, int bounce, double mis_pdf, int mis_n, rr_rng *rng,
                       shade_out *out);

/* Uniform point on triangle t: (u1, u2) -> barycentrics (square-root warp). */
static rr_vec3 tri_point(const scene *s, uint32_t t, double u1, double u2)
{
    const scene_tri *tr = &s->tris[t];
    double su = sqrt(u1);
    double b0 = 1.0 - su, b1 = u2 * su;
    rr_vec3 A = s->verts[tr->v[0]], B = s->verts[tr->v[1]], C = s->verts[tr->v[2]];
    return rr_v3_add(rr_v3_add(rr_v3_scale(A, b0), rr_v3_scale(B, b1)), rr_v3_scale(C, 1.0 - b0 - b1));
}

/* Direct light at H: diffuse and specular, every light, shadow rays. */
static void direct_light(const render_ctx *c, rr_vec3 H, rr_vec3 N, rr_vec3 V, const scene_material *m, int nsamples,
                         int mis, rr_rng *rng, rr_rgb *diffuse, rr_rgb *specular)
{
    const scene *s = c->s;
    for (size_t i = 0; i < s->nlights; i++) {
        const scene_light *l = &s->lights[i];
        rr_vec3 L;
        double tmax, falloff = 1.0;
        if (l->type == SCENE_LIGHT_DIRECTIONAL) {
            L = l->direction;
            tmax = INFINITY;
        } else {
            rr_vec3 d = rr_v3_sub(l->position, H);
            double r2 = rr_v3_len2(d);
            if (!(r2 > 0.0))
                continue;
            L = rr_v3_scale(d, 1.0 / sqrt(r2));
            falloff = 1.0 / r2;
            tmax = sqrt(r2);
        }
        double ndotl = rr_v3_dot(N, L);
        if (ndotl <= 0.0)
            continue;
        rr_vec3 o = offset_origin(c, H, N, L);
        if (!lit(c, o, L, tmax == INFINITY ? INFINITY : tmax * (1.0 - 1e-9)))
            continue;
        rt_phong(N, L, V, m, rr_rgb_scale(l->intensity, falloff), diffuse, specular);
    }
    /* Area lights: n stratified samples over (emitter choice, point on it). */
    if (c->lights.n == 0)
        return;
    int n = nsamples > 0 ? nsamples : 1;
    for (int k = 0; k < n; k++) {
        double pick_pdf;
        double u0 = ((double)k + rr_rng_uniform(rng)) / n;
        size_t li = light_pick(&c->lights, u0, &pick_pdf);
        if (!(pick_pdf > 0.0))
            continue;
        uint32_t t = c->lights.tris[li];
        rr_vec3 y = tri_point(s, t, rr_rng_uniform(rng), rr_rng_uniform(rng));
        rr_vec3 ny = scene_tri_normal(s, t);
        rr_vec3 w = rr_v3_sub(y, H);
        double d2 = rr_v3_len2(w);
        if (!(d2 > 0.0))
            continue;
        double d = sqrt(d2);
        rr_vec3 L = rr_v3_scale(w, 1.0 / d);
        double cos_x = rr_v3_dot(N, L), cos_y = -rr_v3_dot(ny, L); /* emitters radiate from their front */
        if (cos_x <= 0.0 || cos_y <= 0.0)
            continue;
        rr_vec3 o = offset_origin(c, H, N, L);
        rr_vec3 to = rr_v3_sub(y, o);
        if (!lit(c, o, to, 1.0 - 1e-7))
            continue;
        double pdf_area = pick_pdf / c->lights.area[li];
        rr_rgb Le = s->materials[s->tris[t].material].emission;
        /* Irradiance estimate of this sample: Le cos_y / d^2 / pdf, then N.L = cos_x in rt_phong. */
        rr_rgb dd = rr_rgb_make(0, 0, 0);
        rt_phong(N, L, V, m, rr_rgb_scale(Le, cos_y / (d2 * pdf_area * n)), &dd, specular);
        if (mis) {
            /* Balance heuristic against the cosine-weighted bounce ray that
             * could have found the same point (it estimates the diffuse part
             * only): near an emitter the bounce ray wins, which is what keeps
             * the 1/d^2 of light sampling from making fireflies. */
            double pl = n * light_pdf_solid_angle(&c->lights, li, d2, cos_y), pb = cos_x / RR_PI;
            dd = rr_rgb_scale(dd, pl / (pl + pb));
        }
        *diffuse = rr_rgb_add(*diffuse, dd);
    }
}

/* Cosine-weighted direction about N (Malley's method). */
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

static rr_rgb radiance(const render_ctx *c, rr_ray ray, int depth, int bounce, double mis_pdf, int mis_n, rr_rng *rng,
                       shade_out *out)
{
    const scene *s = c->s;
    rt_hit h;
    if (!rt_accel_closest(c->a, ray, 0.0, INFINITY, &h)) {
        if (out) {
            memset(out, 0, sizeof *out);
            out->c[RT_LAYER_EMISSION] = s->settings.background;
        }
        return s->settings.background;
    }
    const scene_material *m = &s->materials[h.material];
    rr_vec3 N = h.normal; /* faces the incoming ray */
    rr_vec3 V = rr_v3_norm(rr_v3_neg(ray.d));
    shade_out local;
    memset(&local, 0, sizeof local);
    if (c->o->radiosity) {
        /* Radiosity display: the view-independent solution, emitters included. */
        local.c[RT_LAYER_RADIOSITY] = c->o->radiosity(c->o->radiosity_user, &h);
        if (out)
            *out = local;
        return local.c[RT_LAYER_RADIOSITY];
    }
    if (h.front && rr_rgb_max(m->emission) > 0.0) {
        double w = 1.0;
        if (mis_pdf >= 0.0 && h.tri >= 0 && c->lights.n > 0 && c->lights.index_of[h.tri] >= 0) {
            /* A bounce ray met a sampled emitter: the balance-heuristic share
             * of the bounce strategy (ray.d is unit, so h.t is the distance). */
            double cos_y = -rr_v3_dot(scene_tri_normal(s, (size_t)h.tri), ray.d);
            double pl = mis_n * light_pdf_solid_angle(&c->lights, (size_t)c->lights.index_of[h.tri], h.t * h.t, cos_y);
            w = mis_pdf / (mis_pdf + pl);
        }
        local.c[RT_LAYER_EMISSION] = rr_rgb_scale(m->emission, w);
    }
    int diffuse = rr_rgb_max(m->diffuse) > 0.0;
    int bounces = diffuse && c->o->indirect == RT_INDIRECT_SECONDARY && bounce < RT_MAX_BOUNCES;
    /* Soft shadows get light_samples at the points the eye sees (and mirrors
     * show); deeper diffuse bounces take one sample each, as their noise
     * averages out over the many paths through a pixel. */
    int nlight = bounce == 0 ? c->o->light_samples : 1;
    if (nlight < 1)
        nlight = 1;
    if (diffuse || rr_rgb_max(m->specular) > 0.0)
        direct_light(c, h.point, N, V, m, nlight, bounces, rng, &local.c[RT_LAYER_DIFFUSE],
                     &local.c[RT_LAYER_SPECULAR]);
    if (diffuse && c->o->indirect == RT_INDIRECT_AMBIENT)
        local.c[RT_LAYER_AMBIENT] = rr_rgb_scale(rr_rgb_mul(m->diffuse, s->settings.ambient), m->ambient);
    if (rr_rgb_max(m->mirror) > 0.0 && depth < c->o->max_depth) {
        /* R = 2(N.V)N - V */
        rr_vec3 R = rr_v3_sub(rr_v3_scale(N, 2.0 * rr_v3_dot(N, V)), V);
        rr_ray mr = {offset_origin(c, h.point, N, R), R};
        rr_rgb Lm = radiance(c, mr, depth + 1, bounce, -1.0, 0, rng, NULL);
        local.c[RT_LAYER_MIRROR] = rr_rgb_mul(m->mirror, Lm);
    }
    if (diffuse && c->o->indirect == RT_INDIRECT_RADIOSITY && c->o->radiosity_indirect)
        local.c[RT_LAYER_INDIRECT] = c->o->radiosity_indirect(c->o->radiosity_user, &h, m->diffuse);
    if (bounces) {
        /* rho/pi * L * cos / (cos/pi) = rho * L; Russian roulette past 3 bounces. */
        rr_rgb weight = m->diffuse;
        int go = 1;
        if (bounce >= 3) {
            double q = fmin(0.95, rr_rgb_max(m->diffuse));
            if (rr_rng_uniform(rng) >= q)
                go = 0;
            else
                weight = rr_rgb_scale(weight, 1.0 / q);
        }
        if (go) {
            rr_vec3 dir = cosine_dir(N, rng);
            rr_ray br = {offset_origin(c, h.point, N, dir), dir};
            rr_rgb Li = radiance(c, br, depth, bounce + 1, rr_v3_dot(N, dir) / RR_PI, nlight, rng, NULL);
            local.c[RT_LAYER_INDIRECT] = rr_rgb_mul(weight, Li);
        }
    }
    rr_rgb sum = rr_rgb_make(0, 0, 0);
    for (int i = 0; i < RT_LAYER_COUNT; i++)
        sum = rr_rgb_add(sum, local.c[i]);
    if (out)
        *out = local;
    return sum;
}

/* Stratified sub-pixel offset for sample k of n, warped by the pixel filter:
 * box over [-0.5, 0.5]^2, or tent over [-1, 1]^2 (filter importance sampling,
 * so every sample has weight 1 and pixels stay independent). */
static double tent_warp(double u)
{
    return u < 0.5 ? sqrt(2.0 * u) - 1.0 : 1.0 - sqrt(2.0 - 2.0 * u);
}

static void pixel_offset(int k, int n, rt_filter filter, rr_rng *rng, double *dx, double *dy)
{
    int cols = (int)ceil(sqrt((double)n));
    int rows = (n + cols - 1) / cols;
    double u = ((double)(k % cols) + rr_rng_uniform(rng)) / cols;
    double v = ((double)(k / cols) + rr_rng_uniform(rng)) / rows;
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

rr_status rt_render(const scene *s, const rt_accel *a, const rt_render_opts *o, rt_film *film, rr_error *err)
{
    const rr_view *v = &s->view;
    if (film->beauty.width != v->width || film->beauty.height != v->height)
        return rr_error_set(err, RR_ERR_INTERNAL, "film is %d x %d but the view is %d x %d", film->beauty.width,
                            film->beauty.height, v->width, v->height);
    render_ctx c;
    c.s = s;
    c.a = a;
    c.o = o;
    c.eps_scale = rt_scene_scale(s);
    rr_status st = light_table_build(s, &c.lights, err);
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
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (int tile = 0; tile < ntiles; tile++) {
        int x0 = (tile % tiles_x) * RT_TILE, y0 = (tile / tiles_x) * RT_TILE;
        int stopped = 0;
        for (int row = y0; row < y0 + RT_TILE && row < v->height && !stopped; row++)
            for (int col = x0; col < x0 + RT_TILE && col < v->width; col++) {
                if (o->interrupt && *o->interrupt) {
                    stopped = 1;
                    break;
                }
                rr_rng rng = rr_rng_make(o->seed, (uint64_t)row * (uint64_t)v->width + (uint64_t)col);
                shade_out acc;
                memset(&acc, 0, sizeof acc);
                for (int k = 0; k < spp; k++) {
                    double dx, dy;
                    pixel_offset(k, spp, o->filter, &rng, &dx, &dy);
                    shade_out so;
                    radiance(&c, rr_view_ray(v, col, row, dx, dy), 0, 0, -1.0, 0, &rng, &so);
                    for (int i = 0; i < RT_LAYER_COUNT; i++)
                        acc.c[i] = rr_rgb_add(acc.c[i], so.c[i]);
                }
                rr_rgb sum = rr_rgb_make(0, 0, 0);
                for (int i = 0; i < RT_LAYER_COUNT; i++) {
                    rr_rgb mean = rr_rgb_scale(acc.c[i], 1.0 / spp);
                    rr_image_set(&film->layer[i], col, row, mean);
                    sum = rr_rgb_add(sum, mean);
                }
                rr_image_set(&film->beauty, col, row, sum);
            }
        if (stopped) {
            /* A tile begun but not finished: black, like the tiles never begun. */
            for (int row = y0; row < y0 + RT_TILE && row < v->height; row++)
                for (int col = x0; col < x0 + RT_TILE && col < v->width; col++) {
                    rr_image_set(&film->beauty, col, row, rr_rgb_make(0, 0, 0));
                    for (int i = 0; i < RT_LAYER_COUNT; i++)
                        rr_image_set(&film->layer[i], col, row, rr_rgb_make(0, 0, 0));
                }
            continue;
        }
        int now;
#pragma omp atomic capture
        now = ++done;
        if (o->progress) {
#pragma omp critical(rt_progress)
            o->progress(o->progress_user, now, ntiles);
        }
    }
    light_table_free(&c.lights);
    if (o->interrupt && *o->interrupt)
        return rr_error_set(err, RR_ERR_INTERRUPTED, "interrupted: %d of %d tiles finished", done, ntiles);
    return RR_OK;
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
        ray.o = offset_origin(&c, h.point, h.normal, R);
        ray.d = R;
        n++;
    }
    *last = ray;
    return n;
}
