/* rt_particle.c - light tracing: an energy ledger independent of the
 * radiosity pass (rt.h, "light tracing"; notes/energy.md).
 *
 * Work is split into batches of consecutive particles; a batch is summed by
 * one thread, in particle order, into its own tally, and the batches are
 * reduced in order: the ledger depends on the seed only, never on the thread
 * count. Each particle draws from its own stream (seed, particle index).
 */
#include <stdlib.h>
#include <string.h>

#include "rt_internal.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define DEFAULT_BATCHES 32

/* A tally: RT_LEDGER_COLUMNS rgb triples per row, then escaped, lost and unabsorbed. */
typedef struct tally {
    rr_rgb *v;
    uint64_t segments;
} tally;

static size_t tally_len(size_t rows) { return rows * RT_LEDGER_COLUMNS + 3; }

static void add(rr_rgb *v, size_t row, int col, rr_rgb p)
{
    rr_rgb *x = &v[row * RT_LEDGER_COLUMNS + (size_t)col];
    *x = rr_rgb_add(*x, p);
}

/* One particle from its emission to its end; returns rays traced. */
static uint64_t trace_one(const scene *s, const rt_accel *a, const rt_lights *L, double scale, size_t rows,
                          rr_rng *rng, rr_rgb *v)
{
    double u[6];
    for (int i = 0; i < 6; i++)
        u[i] = rr_rng_uniform(rng);
    rt_emission e;
    if (!rt_lights_emit(L, u, &e))
        return 0;
    size_t src = e.object != UINT32_MAX ? e.object : s->nobjects + e.light;
    rr_rgb P = e.power;
    rr_ray ray = e.ray;
    rr_rgb *escaped = &v[rows * RT_LEDGER_COLUMNS], *lost = escaped + 1, *unabsorbed = escaped + 2;
    for (uint64_t seg = 1;; seg++) {
        rt_hit h;
        /* The first leg of a surface's particle sees culled back faces: one
         * that meets a culling (closed) object's back face first left from
         * under that object (a window pane under its glazing bars), where
         * the radiosity pass buries the emitter (rad.h) and the ray tracer's
         * shadow rays meet the object's front: not emitted. */
        int hit = seg == 1 && e.object != UINT32_MAX ? rt_accel_closest_two_sided(a, ray, 0.0, INFINITY, &h)
                                                     : rt_accel_closest(a, ray, 0.0, INFINITY, &h);
        if (seg == 1) {
            if (hit && !h.front && e.object != UINT32_MAX && s->objects[h.object].cull_backfaces)
                return seg;
            add(v, src, RT_LEDGER_EMITTED, e.power);
        }
        if (!hit) {
            *escaped = rr_rgb_add(*escaped, P);
            *unabsorbed = rr_rgb_add(*unabsorbed, P);
            return seg;
        }
        const scene_material *m = &s->materials[h.material];
        rr_rgb rho = m->diffuse, mir = m->mirror;
        if (!h.front) {
            /* One-sided diffuse surfaces, two-sided mirrors (as in the
             * radiosity pass's extended form factors and the ray tracer):
             * the mirror part goes on, the rest ends here. */
            rr_rgb ends = rr_rgb_mul(rr_rgb_make(1.0 - mir.r, 1.0 - mir.g, 1.0 - mir.b), P);
            add(v, h.object, RT_LEDGER_BACK, ends);
            add(v, h.object, RT_LEDGER_MIRRORED, rr_rgb_mul(mir, P));
            *unabsorbed = rr_rgb_add(*unabsorbed, ends);
            rho = rr_rgb_make(0, 0, 0);
        } else {
            add(v, h.object, RT_LEDGER_INCIDENT, P);
            add(v, h.object, RT_LEDGER_REFLECTED, rr_rgb_mul(rho, P));
            add(v, h.object, RT_LEDGER_MIRRORED, rr_rgb_mul(mir, P));
            add(v, h.object, RT_LEDGER_ABSORBED,
                rr_rgb_mul(rr_rgb_make(1.0 - rho.r - mir.r, 1.0 - rho.g - mir.g, 1.0 - rho.b - mir.b), P));
        }
        if (seg >= RT_PARTICLE_BOUNCES) {
            *lost = rr_rgb_add(*lost, rr_rgb_mul(rr_rgb_add(rho, mir), P));
            *unabsorbed = rr_rgb_add(*unabsorbed, rr_rgb_mul(rr_rgb_add(rho, mir), P));
            return seg;
        }
        double pm = rr_rgb_mean(P);
        double qd = pm > 0.0 ? rr_rgb_mean(rr_rgb_mul(rho, P)) / pm : 0.0;
        double qm = pm > 0.0 ? rr_rgb_mean(rr_rgb_mul(mir, P)) / pm : 0.0;
        double x = rr_rng_uniform(rng);
        rr_vec3 N = h.normal, d;
        if (x < qd) {
            P = rr_rgb_scale(rr_rgb_mul(rho, P), 1.0 / qd);
            d = rt_cosine_dir(N, rr_rng_uniform(rng), rr_rng_uniform(rng));
        } else if (x < qd + qm) {
            P = rr_rgb_scale(rr_rgb_mul(mir, P), 1.0 / qm);
            rr_vec3 in = rr_v3_norm(ray.d);
            d = rr_v3_madd(in, N, -2.0 * rr_v3_dot(in, N)); /* R = d - 2(d.N)N */
        } else {
            return seg; /* absorbed (or ended on a back face): already tallied */
        }
        ray.o = rt_offset_origin(scale, h.point, N, d);
        ray.d = d;
    }
}

void rt_particle_ledger_free(rt_particle_ledger *g)
{
    if (!g)
        return;
    free(g->row);
    free(g->se);
    g->row = g->se = NULL;
}

/* Mean and standard error of the mean over the batch tallies t[0..nb). */
static void reduce(const tally *t, int nb, size_t rows, rt_particle_ledger *g)
{
    size_t n = tally_len(rows);
    for (size_t k = 0; k < n; k++) {
        rr_rgb sum = {0, 0, 0}, sq = {0, 0, 0};
        for (int b = 0; b < nb; b++) {
            sum = rr_rgb_add(sum, t[b].v[k]);
            sq = rr_rgb_add(sq, rr_rgb_mul(t[b].v[k], t[b].v[k]));
        }
        /* Batch b estimates the ledger as nb * its tally (it holds 1/nb of the particles). */
        rr_rgb mean = sum;
        double c[3] = {sum.r, sum.g, sum.b}, q[3] = {sq.r, sq.g, sq.b}, se[3];
        for (int ch = 0; ch < 3; ch++) {
            double mb = c[ch] / nb; /* mean batch tally */
            double var = (q[ch] / nb - mb * mb) * nb / (nb - 1.0);
            se[ch] = sqrt(fmax(0.0, var) / nb) * nb;
        }
        rr_rgb e = rr_rgb_make(se[0], se[1], se[2]);
        if (k < rows * RT_LEDGER_COLUMNS) {
            g->row[k / RT_LEDGER_COLUMNS].c[k % RT_LEDGER_COLUMNS] = mean;
            g->se[k / RT_LEDGER_COLUMNS].c[k % RT_LEDGER_COLUMNS] = e;
        } else if (k == rows * RT_LEDGER_COLUMNS) {
            g->escaped = mean;
            g->escaped_se = e;
        } else if (k == rows * RT_LEDGER_COLUMNS + 1) {
            g->lost = mean;
            g->lost_se = e;
        } else {
            g->unabsorbed = mean;
            g->unabsorbed_se = e;
        }
    }
}

rr_status rt_particles_trace(const scene *s, const rt_accel *a, const rt_lights *L, const rt_particle_opts *o,
                             rt_particle_ledger *out, rr_error *err)
{
    int nb = o->batches > 0 ? o->batches : DEFAULT_BATCHES;
    if (nb < 2 || o->particles < (uint64_t)nb)
        return rr_error_set(err, RR_ERR_INVALID, "light tracing: need at least 2 batches and a particle per batch");
    if (rt_lights_emitter_count(L) == 0)
        return rr_error_set(err, RR_ERR_INVALID, "light tracing: the scene has no emitter");
    size_t rows = s->nobjects + s->nlights, n = tally_len(rows);
    tally *t = calloc((size_t)nb, sizeof *t);
    rr_rgb *store = calloc((size_t)nb * n, sizeof *store);
    rt_particle_ledger g;
    memset(&g, 0, sizeof g);
    g.row = calloc(rows ? rows : 1, sizeof *g.row);
    g.se = calloc(rows ? rows : 1, sizeof *g.se);
    if (!t || !store || !g.row || !g.se) {
        free(t);
        free(store);
        rt_particle_ledger_free(&g);
        return rr_error_set(err, RR_ERR_NOMEM, "light tracing: out of memory for %d tallies of %zu rows", nb, rows);
    }
    for (int b = 0; b < nb; b++)
        t[b].v = store + (size_t)b * n;
    double scale = rt_scene_scale(s), t0 = rr_now_seconds();
    uint64_t done = 0, total = o->particles;
    int stopped = 0;
#ifdef _OPENMP
    int threads = o->threads > 0 ? o->threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
#endif
    for (int b = 0; b < nb; b++) {
        uint64_t lo = total * (uint64_t)b / (uint64_t)nb, hi = total * (uint64_t)(b + 1) / (uint64_t)nb;
        for (uint64_t p = lo; p < hi; p++) {
            if (o->interrupt && *o->interrupt) {
#ifdef _OPENMP
#pragma omp atomic write
#endif
                stopped = 1;
                break;
            }
            rr_rng rng = rr_rng_make(o->seed ^ 0x6c69676874ULL, p);
            t[b].segments += trace_one(s, a, L, scale, rows, &rng, t[b].v);
            if (((p - lo) & 1023u) == 1023u || p + 1 == hi) {
                uint64_t k = ((p - lo) & 1023u) + 1;
                uint64_t now;
#ifdef _OPENMP
#pragma omp atomic capture
#endif
                now = done += k;
                if (o->progress) {
#ifdef _OPENMP
#pragma omp critical(rt_particle_progress)
#endif
                    o->progress(o->progress_user, now, total);
                }
            }
        }
    }
    if (stopped) {
        free(t);
        free(store);
        rt_particle_ledger_free(&g);
        return rr_error_set(err, RR_ERR_INTERRUPTED, "light tracing interrupted");
    }
    reduce(t, nb, rows, &g);
    for (int b = 0; b < nb; b++)
        g.segments += t[b].segments;
    /* Every batch traced total / nb particles: the sums above estimate the
     * ledger of `total` particles, each of weight 1 / total. */
    double w = 1.0 / (double)total;
    for (size_t r = 0; r < rows; r++)
        for (int c = 0; c < RT_LEDGER_COLUMNS; c++) {
            g.row[r].c[c] = rr_rgb_scale(g.row[r].c[c], w);
            g.se[r].c[c] = rr_rgb_scale(g.se[r].c[c], w);
        }
    g.escaped = rr_rgb_scale(g.escaped, w);
    g.escaped_se = rr_rgb_scale(g.escaped_se, w);
    g.lost = rr_rgb_scale(g.lost, w);
    g.lost_se = rr_rgb_scale(g.lost_se, w);
    g.unabsorbed = rr_rgb_scale(g.unabsorbed, w);
    g.unabsorbed_se = rr_rgb_scale(g.unabsorbed_se, w);
    g.nobjects = s->nobjects;
    g.nlights = s->nlights;
    g.particles = total;
    g.batches = nb;
    g.seconds = rr_now_seconds() - t0;
    free(t);
    free(store);
    *out = g;
    return RR_OK;
}
