/* rad_hier_bury.c - what the hierarchical pass probes of each element: its
 * buried parts (rad_hier.c's header, "Buried parts"): which points of an
 * element lie under another surface, by the flat pass's rule
 * (rad__ff_buried, rad_ff.c), and the probes that give every element its
 * buried fixed points and open share; and a leaf's data, its first shot,
 * whether it sees a closed part of the scene ("Row sums") and how much of
 * it the backs of surfaces hide (the elements' exposures, read by the
 * refinement's unevenly_exposed). */
#include <math.h>
#include <omp.h>

#include "rad_hier_ctx.h"
#include "rad_ff_internal.h"
#include "rad_pass_internal.h"

/* The thin gaps' width for e's points (rad__ff_buried): hctx.gap, the flat
 * method's burial distance for its largest patches, the same at every level
 * (each element's own, as for backs, would bury a root's points a hand's
 * width over a lamp); or a tenth of e's root's size where that is less: no
 * element of a small root straddles a gap that wide (the 1M room's bunnies,
 * a centimetre tall, stand 0.25 mm over a floor whose gap is 7.7 cm: what
 * their probes cost is in notes/radiosity.md, "Thin gaps"). None on an
 * emitter, whose light starts in the gap (a window pane behind its frame). */
static double cover_gap(const hctx *c, const hel *e)
{
    return rr_min(c->gap, RAD_FF_BURY * sqrt(c->R->p[e->root].area));
}
static double gap_of(const hctx *c, const hel *e)
{
    return rr_rgb_max(c->R->p[e->root].emission) > 0 ? 0.0 : cover_gap(c, e);
}

int rad__hier_buried(const hctx *c, const hel *e, rr_vec3 xs, rr_vec3 ns)
{
    rr_ray r = {rt_offset_origin(c->ext, xs, ns, ns), ns};
    return rad__ff_point_buried(c->s, c->a, r, ns, RAD_FF_BURY * sqrt(e->area), gap_of(c, e), 1);
}

int rad__hier_in_slot(const hctx *c, const hel *e, rr_vec3 xs, rr_vec3 ns)
{
    double gap = gap_of(c, e);
    if (!(gap > 0))
        return 0;
    rr_ray r = {rt_offset_origin(c->ext, xs, ns, ns), ns};
    rt_hit h;
    return rt_accel_closest_two_sided(c->a, r, 0.0, gap, &h) && h.front &&
           !(rr_rgb_max(c->s->materials[h.material].emission) > 0);
}

int rad__hier_point_buried(const hctx *c, const hel *e, rr_vec3 x)
{
    rr_vec3 xs, ns;
    root_surface(c, e->root, x, &xs, &ns);
    return rad__hier_buried(c, e, xs, ns);
}

/* Element x's burial: which of its fixed points are buried (a probe along
 * the normal from each), and its open share, from PROBES cosine-distributed
 * rays from stratified points by the flat pass's rule for a ray's first leg
 * (rad_ff.c). Without it, the parts of a window pane under its glazing bars
 * (closed boxes against it) emitted (+6.9 % of its light against the light
 * tracer), and shelf boards gathered light under the books (+20..41 %). */
#define PROBES 16
static void el_probe(hctx *c, uint32_t x)
{
    hel *e = &c->el[x];
    e->kbur = 0;
    for (int k = 0; k < 4; k++)
        if (rad__hier_point_buried(c, e, tri_at(e->c, k_pts[k][0], k_pts[k][1], k_pts[k][2])))
            e->kbur |= 1u << k;
    rr_rng rng = rr_rng_make(0x5851f42d4c957f2dULL, x);
    double bury = RAD_FF_BURY * sqrt(e->area);
    int open = 0, covered = 0, cov = 0;
    double ob[PROBES][2], pb[PROBES][2];
    double gap = gap_of(c, e), cgap = gap > 0 ? 0.0 : cover_gap(c, e); /* cgap: an emitter's */
    for (uint32_t k = 0; k < PROBES; k++) {
        double u, v, u1, u2;
        rad_ff_tri_stratum(k, PROBES, &rng, &u, &v);
        rad_ff_square_stratum((k * 7) % PROBES, PROBES, &rng, &u1, &u2); /* strata paired across */
        pb[k][0] = u;
        pb[k][1] = v;
        rr_vec3 xs, ns;
        root_surface(c, e->root, tri_at(e->c, 1.0 - u - v, u, v), &xs, &ns);
        rr_vec3 d = rad_ff_cosine_dir(ns, u1, u2);
        rr_ray r = {rt_offset_origin(c->ext, xs, ns, ns), d};
        int b = rad__ff_point_buried(c->s, c->a, r, ns, bury, gap, 1);
        covered |= b && b != RAD_BURIED_SLOT;
        if (cgap > 0 && !b) {
            int bc = rad__ff_point_buried(c->s, c->a, r, ns, bury, cgap, 1);
            cov += bc != 0;
        }
        if (!b) {
            ob[open][0] = u;
            ob[open][1] = v;
            open++;
        }
    }
    e->open = (double)open / PROBES;
    /* Partly buried, and by slots alone (no probe under a cover): its fixed
     * points are 4 of the open probes' points (spread over the strata), all
     * open (el_kpt). An emitter partly under a thin gap's cover (a window
     * pane behind its glazing bars, 1 mm off) is not buried there, but its
     * part under the cover sees the cover alone: its fixed points are 4 of
     * all its probes' points, covered or not, as the fixed pattern, away
     * from the element's edges, seldom fell under bars that lie along the
     * pane's middle lines (the pane took in 3-4 % more than the light
     * tracer counts: notes/radiosity.md, "Slivers and sources seen close"). */
    int emit_own = cgap > 0 && cov > 0 && cov < (int)PROBES;
    e->own = (open > 0 && open < (int)PROBES && !covered) || emit_own;
    e->bur = e->own ? 0 : e->kbur;
    for (int q = 0; q < 4 && e->own; q++) {
        const double *b = emit_own ? pb[q * PROBES / 4] : ob[q * open / 4];
        e->kb[q][0] = (uint16_t)lrint(b[0] * 65535.0);
        e->kb[q][1] = (uint16_t)lrint(fmin(b[1], 1.0 - b[0]) * 65535.0);
    }
    e->nbur = e->open < 1.0 ? rad__hier_near_buried(c, e) : 0;
    e->probed = 1;
}

void rad__hier_probe_new(hctx *c)
{
#pragma omp parallel
    {
        rt_ray_counts before = rt_ray_counts_of_thread();
#pragma omp for schedule(dynamic, 64)
        for (long i = 0; i < (long)c->nel; i++)
            if (!c->el[i].probed && !interrupted(c))
                el_probe(c, (uint32_t)i);
        rt_ray_counts_add_since(&c->rays, before);
    }
}

/* ---- leaf data: first shot and closedness ---- */

#define CLOSED_RAYS 16 /* rays from a leaf that decide whether it sees a closed part of the scene */
#define OCCL_NEAR 2.0  /* a closedness ray that meets a surface within this many root radii counts in occl */

static void leaf_data(const hctx *c, uint32_t x)
{
    hel *e = &c->el[x];
    const rad_patch *rp = &c->R->p[e->root];
    e->H0 = c->L ? rad__first_shot(c->s, c->a, c->L, c->R, e->root, e->c, NULL, 0.0, &e->spread)
                 : rr_rgb_make(0, 0, 0);
    e->E = rr_rgb_add(rp->emission, rr_rgb_mul(rp->rho, e->H0));
    rr_rng rng = rr_rng_make(0x9e3779b97f4a7c15ULL, x);
    int any = open_pt(e, 0) >= 0, landed = 0, back = 0, near = 0, touch = 0; /* from its open points */
    double touch_d = e->radius;
    double near_d = OCCL_NEAR * c->el[e->root].radius;
    for (int k = 0; k < CLOSED_RAYS && any; k++) {
        rr_vec3 xs, ns;
        double b[3];
        el_kpt(e, open_pt(e, k), b);
        root_surface(c, e->root, tri_at(e->c, b[0], b[1], b[2]), &xs, &ns);
        double u1, u2;
        rad_ff_square_stratum((uint32_t)k, CLOSED_RAYS, &rng, &u1, &u2);
        rr_vec3 dir = rad_ff_cosine_dir(ns, u1, u2);
        rr_ray ray = {rt_offset_origin(c->ext, xs, ns, dir), dir};
        rt_hit h;
        if (rt_accel_closest(c->a, ray, 0.0, INFINITY, &h)) {
            landed += h.front;
            back += !h.front;
            near += h.t < near_d; /* dir is a unit vector */
            touch += h.t < touch_d;
        }
    }
    e->closed = any && landed == CLOSED_RAYS;
    e->land = any ? (float)landed / CLOSED_RAYS : -1.0f;
    e->back = any ? (float)back / CLOSED_RAYS : -1.0f;
    e->occl = any ? (float)near / CLOSED_RAYS : -1.0f;
    e->touch = any ? (float)touch / CLOSED_RAYS : 0.0f;
    e->fresh = 0;
}

void rad__hier_leaves_data(hctx *c, size_t ne)
{
#pragma omp parallel
    {
        rt_ray_counts before = rt_ray_counts_of_thread();
#pragma omp for schedule(dynamic, 64)
        for (long i = 0; i < (long)ne; i++)
            if (c->el[i].fresh && c->el[i].child == NONE && !interrupted(c))
                leaf_data(c, (uint32_t)i);
        rt_ray_counts_add_since(&c->rays, before);
    }
}

/* Each element's least and most exposure over its leaves (xlo, xhi), an
 * exposure being 1 - back, the share of a leaf's closedness rays that did
 * not meet a surface's back, and the same of occl (olo, ohi); leaves with no
 * data yet, or no open point, are left out (xlo > xhi when none is left). */
static void exposure(hctx *c, uint32_t x)
{
    hel *e = &c->el[x];
    if (e->child == NONE) {
        int known = !e->fresh && e->back >= 0.0f;
        e->xlo = known ? 1.0f - e->back : 1.0f;
        e->xhi = known ? 1.0f - e->back : 0.0f;
        e->olo = known ? e->occl : 1.0f;
        e->ohi = known ? e->occl : 0.0f;
        float sv = (float)rr_rgb_max(e->src);
        e->slo = e->open > 0 ? sv : INFINITY;
        e->shi = e->open > 0 ? sv : 0.0f;
        return;
    }
    e->xlo = e->olo = 1.0f;
    e->xhi = e->ohi = 0.0f;
    e->slo = INFINITY;
    e->shi = 0.0f;
    for (uint32_t k = 0; k < 4; k++) {
        const hel *ch = &c->el[e->child + k];
        exposure(c, e->child + k);
        e->xlo = fminf(e->xlo, ch->xlo);
        e->xhi = fmaxf(e->xhi, ch->xhi);
        e->olo = fminf(e->olo, ch->olo);
        e->ohi = fmaxf(e->ohi, ch->ohi);
        e->slo = fminf(e->slo, ch->slo);
        e->shi = fmaxf(e->shi, ch->shi);
    }
}

void rad__hier_exposures(hctx *c)
{
#pragma omp parallel for schedule(dynamic, 64)
    for (long r = 0; r < (long)c->R->n; r++)
        exposure(c, (uint32_t)r);
}
