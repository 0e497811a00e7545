/* rt_preview.c - flat-shaded preview of the front-most hits (brute force).
 *
 * This is what `radray render` draws until the full ray tracer lands: it
 * exercises the whole pipeline (scene -> view -> rays -> film -> EXR/PNG) with
 * the lecture's reference hit test, and nothing more. */
#include <math.h>

#include "rt.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static rr_rgb shade_preview(const scene *s, rr_ray ray)
{
    rt_hit h;
    if (!rt_ref_closest(s, ray, 0.0, INFINITY, &h))
        return s->settings.background;
    const scene_material *m = &s->materials[h.material];
    double ndotv = fabs(rr_v3_dot(h.normal, rr_v3_norm(ray.d)));
    return rr_rgb_add(m->emission, rr_rgb_scale(m->diffuse, 0.15 + 0.85 * ndotv));
}

/* Sub-pixel offset of sample k of n in [-0.5, 0.5)^2: stratified on a grid of
 * ceil(sqrt(n)) columns, jittered inside each stratum. */
static void sample_offset(int k, int n, rr_rng *rng, double *dx, double *dy)
{
    if (n == 1) {
        *dx = *dy = 0.0;
        return;
    }
    int cols = (int)ceil(sqrt((double)n));
    int rows = (n + cols - 1) / cols;
    int cx = k % cols, cy = k / cols;
    *dx = ((double)cx + rr_rng_uniform(rng)) / cols - 0.5;
    *dy = ((double)cy + rr_rng_uniform(rng)) / rows - 0.5;
}

rr_status rt_render_preview(const scene *s, const rt_render_opts *opts, rr_image *img, rr_error *err)
{
    const rr_view *v = &s->view;
    if (img->width != v->width || img->height != v->height || !img->px)
        return rr_error_set(err, RR_ERR_INTERNAL, "film is %d x %d but the view is %d x %d", img->width,
                            img->height, v->width, v->height);
    int spp = opts->spp > 0 ? opts->spp : 1;
    int done = 0;
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = opts->threads > 0 ? opts->threads : omp_get_max_threads();
#endif
    (void)nthreads;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads)
    for (int row = 0; row < v->height; row++) {
        for (int col = 0; col < v->width; col++) {
            rr_rng rng = rr_rng_make(opts->seed, (uint64_t)row * (uint64_t)v->width + (uint64_t)col);
            rr_rgb sum = rr_rgb_make(0, 0, 0);
            for (int k = 0; k < spp; k++) {
                double dx, dy;
                sample_offset(k, spp, &rng, &dx, &dy);
                sum = rr_rgb_add(sum, shade_preview(s, rr_view_ray(v, col, row, dx, dy)));
            }
            rr_image_set(img, col, row, rr_rgb_scale(sum, 1.0 / spp));
        }
        int now;
#pragma omp atomic capture
        now = ++done;
        if (opts->progress) {
#pragma omp critical(rt_progress)
            opts->progress(opts->progress_user, now, v->height);
        }
    }
    return RR_OK;
}
