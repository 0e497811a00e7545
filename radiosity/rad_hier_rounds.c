/* rad_hier_rounds.c - the hierarchical pass's links evaluated and tested
 * again (rad_hier.c runs the rounds): every new link evaluated in parallel
 * and the split tests that read what the evaluation found (settle), the
 * visibility of the links whose rays a decision read drawn afresh once the
 * refinement has settled (estimate), and every kept link re-tested with the
 * solved radiosity
 * (relink). rad_hier.c's header has the tests and why ("Links and the
 * oracle", "Decide, then estimate"). */
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"

#define VIS_SHARE 0.125 /* partly visible links are split down to eps times this */

/* ---- link evaluation ---- */

/* The links' shadow rays come from rr_rng_make(key ^ way, (r << 32) | s):
 * key 0 while refining, whatever the seed, so that the tree is the scene's
 * own; the seed ^ ESTIMATE_DRAW for the transport's estimate, where a far
 * element link between flat surfaces has its visibility exact instead
 * (rad_hier_link.c exact_occluders) and each point of any other element
 * link casts up to ESTIMATE_PER rays (rad_hier.c, "Decide, then
 * estimate"). */
#define ESTIMATE_DRAW 0xa0761d6478bd642fULL
#define ESTIMATE_PER 8

/* How many shadow rays each point of element link l casts in the
 * estimate: ESTIMATE_PER where it carries over half its receiver's eps,
 * halved for each halving of its power, down to 1 under an eighth. A
 * leaf's noise is its links' visibility noise weighed by their power, so
 * the rays go where the power is (an allocation in proportion to each
 * stratum's weight). Cornell's back wall, seeds 1 and 2 (before the
 * contact share of 3 rays in 16): 97.5 % of the leaves within 0.5 %; with
 * one ray a point 90.6 %, with 4 a point on every link read 96.0 % (the
 * estimate 0.68 s against these rays' 0.79 s). */
static int estimate_per(const hctx *c, const hlink *l)
{
    double p = rad__hier_link_power(c, l->r, l->s, link_way(l)), e = receiver_eps(c, l->r);
    int per = ESTIMATE_PER;
    while (per > 1 && !(p > e * per / (2.0 * ESTIMATE_PER)))
        per /= 2;
    return per;
}

/* Link l evaluated whole, or (revis) its visibility drawn again, the
 * geometry kept where it is held without visibility. */
static void eval_link(const hctx *c, hlink *l, int revis)
{
    unsigned w = link_way(l);
    rr_rng rng = rr_rng_make((c->draw ? c->seed ^ c->draw : 0) ^ (w ? 0x9e3779b97f4a7c15ULL * w : 0), ((uint64_t)l->r << 32) | l->s);
    if (l->r & CLB)
        rad__hier_eval_rlc(c, l, &rng, revis);
    else if (l->s & CLB)
        (revis ? rad__hier_revis_cluster : rad__hier_eval_cluster)(c, l, &rng);
    else
        (revis ? rad__hier_revis_ee : rad__hier_eval_ee)(c, l, &rng, revis ? estimate_per(c, l) : 1);
}

/* The partial-visibility split reads link l's rays: it carries VIS_SHARE
 * eps without visibility (whatever its rays said: all passing or all
 * blocked keeps it, some of each splits it). */
static int reads_rays(const hctx *c, const hlink *l)
{
    return rad__hier_link_power(c, l->r, l->s, link_way(l)) > VIS_SHARE * receiver_eps(c, l->r);
}

#define EVAL_BLOCK 256

/* Links lo .. hi - 1 evaluated in parallel (revis: their visibility drawn
 * again, where a decision read it), with progress (links evaluated of those
 * made so far, from one thread); stops early when interrupted. */
static void eval_links(hctx *c, size_t lo, size_t hi, int revis, void (*progress)(void *, size_t, size_t),
                       void *user)
{
    size_t done = 0;
    long nb = (long)((hi - lo + EVAL_BLOCK - 1) / EVAL_BLOCK);
#pragma omp parallel
    {
        rt_ray_counts before = rt_ray_counts_of_thread();
        /* blocks of EVAL_BLOCK links handed out in turn, the count of those
         * done added once a block (an atomic per link is a cache line that
         * the threads pass back and forth) */
#pragma omp for schedule(dynamic, 1)
        for (long b = 0; b < nb; b++) {
            size_t b0 = lo + (size_t)b * EVAL_BLOCK, b1 = b0 + EVAL_BLOCK < hi ? b0 + EVAL_BLOCK : hi;
            for (size_t i = b0; i < b1 && !interrupted(c); i++)
                /* the estimate leaves a link with the refinement's draw
                 * where no decision read its rays: the partial-visibility
                 * split (the only test that reads them) never found it
                 * carrying VIS_SHARE eps when it kept it (link_mark_read;
                 * rad_hier.c, "Decide, then estimate") */
                if (!revis || link_rays_read(&c->ln[i]))
                    eval_link(c, &c->ln[i], revis);
            size_t d;
#pragma omp atomic capture
            d = done += b1 - b0;
            if (progress && omp_get_thread_num() == 0 && d / 4096 != (d - (b1 - b0)) / 4096)
                progress(user, c->evaluated + d, c->evaluated + (hi - lo));
        }
        rt_ray_counts_add_since(&c->rays, before);
    }
    c->evaluated += hi - lo;
}

/* ---- the rounds ---- */

/* The receiver's irradiance from s varies across it by more than eps of
 * power: rho A_r (F_max - F_min) B_s over its quadrature points. */
static int uneven(const hctx *c, const hlink *l)
{
    if (l->r & CLB)
        return 0; /* a receiving leaf cluster's: dF holds its direction, and it is not split */
    return node_rho(c, l->r) * node_area(c, l->r) * l->dF * node_B(c, l->s) > receiver_eps(c, l->r);
}

/* Receiver r's leaves are exposed unevenly: some see the backs of
 * surfaces close by (the ceiling in the gap over a lamp, whose back faces
 * it), others do not. No light comes from a surface's back, so those
 * leaves take in less from every source than the link's shadow rays, from
 * r's fixed points, say; the link goes to r's children while the
 * difference can carry VIS_SHARE of eps, as a partly visible link does. */
static int unevenly_exposed(const hctx *c, const hlink *l)
{
    if (l->r & CLB)
        return 0;
    const hel *e = &c->el[l->r];
    if (e->child == NONE)
        return 0;
    double eps = VIS_SHARE * receiver_eps(c, l->r), spread = e->xhi - e->xlo;
    /* Unevenly occluded (radiosity.relative_tolerance only): some of r's
     * leaves have surfaces close by, others not, so what r's fixed points
     * see of s is not what all of it sees ("Light near occluders"). */
    if (c->rel > 0 && e->ohi - e->olo > spread)
        spread = e->ohi - e->olo;
    return spread > 0 && spread * rad__hier_link_power(c, l->r, l->s, link_way(l)) > eps;
}

/* What source s sends varies over its open leaves (shi - slo, from
 * rad__hier_exposures), and the link's error bound for that, its power
 * times (shi - slo) / B_s, is over SOURCE_SHARE of the receiver's eps: the
 * link carries s's mean, while r may see mostly one part of s (the floor
 * close under an object, in the object's shadow, seen by its underside).
 * Or, for a near pair (centres closer than twice the sum of their radii, as
 * rad_hier_link.c reads near pairs) whose source
 * varies by more than SOURCE_VARY of its mean, the bound is over
 * SOURCE_REL of r's own power (A_r B_r): each such link carries little
 * (under a sofa raised 8 cm on its legs, a tenth of eps), but every link
 * into the underside reads the bright floor beside the sofa, one way: the
 * underside took in 3.1 times the light tracer's count. Such a link goes
 * to s's children (rad__hier_split_link's source-first mode).
 * notes/radiosity.md, "Sources that vary" and "Slivers and sources seen
 * close". */
#define SOURCE_SHARE 0.25
#define SOURCE_REL 0.25
#define SOURCE_VARY 0.5
static int source_uneven(const hctx *c, const hlink *l)
{
    if ((l->s & CLB) || c->el[l->s].child == NONE)
        return 0;
    const hel *e = &c->el[l->s];
    double B = node_B(c, l->s);
    if (!(B > 0) || !(e->shi > e->slo))
        return 0;
    double err = rad__hier_link_power(c, l->r, l->s, link_way(l)) * (e->shi - e->slo) / B;
    if (err > SOURCE_SHARE * receiver_eps(c, l->r))
        return 1;
    double d = rr_v3_len(rr_v3_sub(node_ctr(c, l->s), way_point(c, link_way(l), node_ctr(c, l->r))));
    return d < 2.0 * (node_radius(c, l->r) + e->radius) && e->shi - e->slo > SOURCE_VARY * B &&
           err > SOURCE_REL * node_area(c, l->r) * node_B(c, l->r);
}

/* Receiver r has an open part but all four points of k_pts are buried: its
 * open part is a sliver along its edges, which its children resolve (it
 * may read it at points of its own, el_kpt), so its links go to them. */
static int unrepresented(const hctx *c, uint32_t r)
{
    return !(r & CLB) && c->el[r].open > 0 && (c->el[r].kbur & 15u) == 15u && splittable(c, r);
}

/* Evaluates the links from c->first_new on, and computes the data of fresh
 * leaves; then splits what the visibility and first-shot tests ask for, and
 * again, until nothing changes. */
rr_status rad__hier_settle(hctx *c, void (*progress)(void *, size_t, size_t), void *user, rr_error *err)
{
    size_t tested = 0; /* the elements below it were tested by an earlier pass (below) */
    for (int pass = 0; pass < 32; pass++) {
        size_t lo = c->first_new;
        rad__hier_probe_new(c); /* the links read their ends' burial */
        eval_links(c, lo, c->nln, 0, progress, user);
        size_t ne = c->nel;
        rad__hier_leaves_data(c, ne);
        if (interrupted(c))
            return rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (links)", c->s->path);
        if (progress)
            progress(user, c->evaluated, c->evaluated);
        /* Leaves whose first shot varies by more than eps of power split,
         * and partly buried ones whose buried share carries that much: the
         * burial's edge lies within them, and their points stand for both
         * sides of it. What these tests read of an element (its first
         * shot's spread, its open share, its B, eps) holds through the
         * passes of one settle, so a pass tests only the elements made
         * since the last one: every pass over all of them was 1.7 s of the
         * 1M room's pass, on one thread. */
        int changed = 0;
        for (size_t i = tested; i < ne && !c->nomem; i++) {
            hel *e = &c->el[i];
            if (e->child != NONE || e->fresh || !splittable(c, (uint32_t)i))
                continue;
            int shot = e->spread > 0 && rr_rgb_max(el_rho(c, (uint32_t)i)) * e->area * e->spread > c->eps;
            int part = e->open > 0 && e->open < 1 &&
                       rr_rgb_max(e->B) * e->area * fmin(e->open, 1.0 - e->open) > c->eps;
            if ((shot || part) && !rad__hier_past_cap(c))
                changed |= rad__hier_el_split(c, (uint32_t)i) == 0;
        }
        tested = ne;
        /* Partly visible links that carry enough split once more (which,
         * decided in parallel: splitting changes no node a test reads). */
        rad__hier_exposures(c);
        size_t keep = lo;
        c->first_new = c->nln;
        size_t old_end = c->nln;
        unsigned char *want = malloc(old_end - lo + 1);
        if (!want)
            return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
#pragma omp parallel for schedule(static)
        for (long i = (long)lo; i < (long)old_end; i++) {
            const hlink *l = &c->ln[i];
            int unev = uneven(c, l);
            int other = unev || unrepresented(c, l->r) || unevenly_exposed(c, l);
            int read = !other && reads_rays(c, l);
            /* bit 0: split it; bit 1: kept, its rays read; bit 2: uneven (a leaf
             * at a contact may then split below min_area: contact_splittable) */
            want[i - (long)lo] = (unsigned char)((other || (read && l->vis > 0 && l->vis < VIS_ONE) ? 1 : read ? 2 : 0) | (unev ? 4 : 0));
        }
        for (size_t i = lo; i < old_end && !c->nomem; i++) {
            hlink l = c->ln[i];
            int split = (want[i - lo] & 1) && !rad__hier_past_cap(c) &&
                        rad__hier_split_link(c, l.r, l.s, want[i - lo] & 4 ? 2 : 1, link_way(&l));
            if (want[i - lo] & 2)
                link_mark_read(&l);
            if (!split)
                c->ln[keep++] = l;
            changed |= split;
        }
        free(want);
        /* Compact: kept links of this batch, then the new ones. */
        size_t nnew = c->nln - old_end;
        memmove(c->ln + keep, c->ln + old_end, nnew * sizeof *c->ln);
        c->nln = keep + nnew;
        c->first_new = keep;
        if (c->nomem)
            return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for %zu links", c->s->path, c->nln);
        if (!changed)
            return RR_OK;
    }
    return RR_OK;
}

/* Decide, then estimate: the visibility of every link whose rays a
 * decision read drawn afresh (ESTIMATE_DRAW) once the refinement has
 * settled (rad_hier.c's header); the geometry is kept where it is held
 * without visibility (cluster links, near pairs: a far pair is evaluated
 * whole). */
rr_status rad__hier_estimate(hctx *c, void (*progress)(void *, size_t, size_t), void *user, rr_error *err)
{
    c->draw = ESTIMATE_DRAW;
    eval_links(c, 0, c->nln, 1, progress, user);
    if (interrupted(c))
        return rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (links)", c->s->path);
    if (progress)
        progress(user, c->evaluated, c->evaluated);
    return RR_OK;
}

/* What each object's leaves take in by the last solve, rho A H summed
 * (link_eps, which relink reads): 0, or -1 out of memory. */
int rad__hier_object_powers(hctx *c)
{
    size_t no = c->s->nobjects ? c->s->nobjects : 1;
    if (!c->objpow && !(c->objpow = calloc(no, sizeof *c->objpow)))
        return -1;
    memset(c->objpow, 0, no * sizeof *c->objpow);
    for (size_t i = 0; i < c->nel; i++)
        if (c->el[i].child == NONE)
            c->objpow[c->R->p[c->el[i].root].object] +=
                node_rho(c, (uint32_t)i) * c->el[i].area * rr_rgb_max(c->el[i].H);
    return 0;
}

/* Re-tests every link with the solved radiosity; those that now carry too
 * much are replaced by refined ones. Returns whether anything changed. The
 * links kept move to the front in place and only the ends of those to split
 * are set aside (a copy of every link held them twice, as the sort did). */
typedef struct split_end {
    uint32_t r, s;
    unsigned char how, way;
} split_end;

int rad__hier_relink(hctx *c)
{
    size_t n = c->nln, keep = 0, nsplit = 0;
    int changed = 0;
    unsigned char *split = calloc(n ? n : 1, 1);
    if (!split) {
        c->nomem = 1;
        return 0;
    }
    /* 1: too much power (split the larger end); 2: partly hidden (split the
     * receiver first); 3: uneven (the receiver first, a leaf at a contact
     * below min_area too), as settle tests new links; 5: the source varies
     * (split the source first: source_uneven). */
    rad__hier_exposures(c);
#pragma omp parallel for schedule(static)
    for (long i = 0; i < (long)n; i++) {
        const hlink *l = &c->ln[i];
        double p = 0.0;
        if (!(splittable(c, l->r) | splittable(c, l->s)))
            split[i] = contact_splittable(c, l->r) && uneven(c, l) ? 3 : 0;
        else if ((p = rad__hier_link_power(c, l->r, l->s, link_way(l))) > link_eps(c, l->r))
            split[i] = 1;
        else if (uneven(c, l))
            split[i] = 3;
        else if (source_uneven(c, l))
            split[i] = 5;
        else if (unrepresented(c, l->r) || unevenly_exposed(c, l))
            split[i] = 2;
        else if (p > VIS_SHARE * receiver_eps(c, l->r)) /* as reads_rays, the power computed once */
            split[i] = l->vis > 0 && l->vis < VIS_ONE ? 2 : 4; /* 4: kept, its rays read */
    }
    for (size_t i = 0; i < n; i++)
        nsplit += split[i] != 0 && split[i] != 4;
    split_end *se = malloc((nsplit ? nsplit : 1) * sizeof *se);
    if (!se) {
        free(split);
        c->nomem = 1;
        return 0;
    }
    for (size_t i = 0, k = 0; i < n; i++)
        if (split[i] != 0 && split[i] != 4) {
            se[k++] = (split_end){c->ln[i].r, c->ln[i].s, split[i], (unsigned char)link_way(&c->ln[i])};
        } else {
            c->ln[keep] = c->ln[i]; /* keep <= i: in place */
            if (split[i] == 4)
                link_mark_read(&c->ln[keep]);
            keep++;
        }
    free(split);
    c->nln = keep;
    c->first_new = keep;
    for (size_t k = 0; k < nsplit && !c->nomem; k++)
        if (!rad__hier_past_cap(c)) {
            /* how 1, 2, 3: the larger end, the receiver first, and at
             * contacts; 5: the source first */
            rad__hier_split_link(c, se[k].r, se[k].s, se[k].how == 5 ? 3 : se[k].how - 1, se[k].way);
            changed = 1;
        } else {
            /* kept whole past the cap, and evaluated again (changed: the
             * round's settle evaluates the links from first_new; without it
             * the rounds ended and these held f = NaN) */
            c->capped = 1;
            rad__hier_link_add(c, se[k].r, se[k].s, se[k].way);
            changed = 1;
        }
    free(se);
    return changed;
}
