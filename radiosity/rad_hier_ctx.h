/* rad_hier_ctx.h - private to the hierarchical pass (rad_hier.c builds and
 * refines the hierarchy, rad_hier_rounds.c evaluates and re-tests its links,
 * rad_hier_solve.c solves on it): its elements,
 * clusters and links, and the solving steps the builder calls. */
#ifndef RAD_HIER_CTX_H
#define RAD_HIER_CTX_H

#include <string.h>

#include "rad.h"

#define NONE UINT32_MAX
#define CLB 0x80000000u /* node reference: cluster bit (else an element index) */
#define CL(x) ((x) & ~CLB)

typedef struct hel {
    rr_vec3 c[3], ctr;
    double area, radius;
    uint32_t root, child, depth;
    int closed;     /* leaf: its closedness rays all landed on fronts */
    int shut;       /* root: every closedness ray of its leaves landed on a front: k applies (roots_shut) */
    int probed;     /* its burial probes are done (open, bur) */
    double open;    /* the open share of its area: not buried under another surface (rad.h: buried parts) */
    unsigned bur;   /* bit k: its fixed point k (el_kpt) is buried */
    unsigned kbur;  /* bit k: k_pts[k] is buried (bur, unless it has points of its own) */
    int own;        /* its fixed points are open points of its own (kb), not k_pts: part of it lies in a slot */
    uint16_t kb[4][2]; /* own: barycentrics b1, b2 of its fixed points, in 1 / 65535 */
    uint64_t nbur;  /* bit k: near-pair quadrature point k is buried (rad__hier_near_buried) */
    int fresh;      /* leaf data (first shot, closedness) still to compute */
    double spread;  /* leaf: the first shot's largest difference between its points */
    rr_rgb B, src, H, E, H0;
    rr_rgb Hc[3];   /* what its links send its corners beyond their mean (hlink.sh): a linear field, gathered with H */
    double k;       /* leaf: row-sum scale */
    float land;     /* leaf: the share of its closedness rays that landed on fronts; -1: it has no open point */
    float back;     /* leaf: the share that met a surface's back (no light comes from there); -1 as land */
    float xlo, xhi; /* the least and most of 1 - back over its leaves (rad__hier_exposure) */
    float occl;     /* leaf: the share of its closedness rays that met a surface within OCCL_NEAR root radii; -1 as land */
    float olo, ohi; /* the least and most occl over its leaves (rad__hier_exposure) */
    float slo, shi; /* the least and most of what its open leaves send (src, largest channel; rad__hier_exposure) */
    float touch;    /* leaf: the share of its closedness rays that met a surface within its own radius (a contact) */
    int partial;    /* it has a partly visible link (rad__hier_gather of B = 1) */
} hel;

/* Normal buckets: what a node shows and sends towards a direction. A
 * normal's bucket is the face of the cube it points to (+x, -x, +y, -y, +z,
 * -z; ties to the first axis); a node keeps per bucket its surfaces' weight
 * times normal summed (v, the weight area or power) and their weight (s).
 * Towards u it sends, per bucket, max(0, v . u): exact for one flat surface,
 * for coplanar ones and for surfaces facing along the axes (a room's
 * clusters), but below the truth where the bucket holds normals on both
 * sides of u's horizon, and by s - |v| in total over the sphere of
 * directions (a curved node's). That shortfall is put back as (s - |v|) / 2
 * (1 - |cos|), cos between u and v: it integrates to what is missing and
 * sits away from the bucket's mean normal, where the normals on the far
 * side of the horizon send it. On a model of a 96-facet sphere (a throwaway
 * numpy script, the nodes as the cluster tree splits them), against the
 * exact sum of A max(0, n . u) over 1500 directions: one node -16.8 % on
 * average (rms 18.8 %) without it, 0.0 % (rms 6.8 %) with it; 8 nodes -4.0
 * % (4.4 %) and 0.0 % (1.6 %); 32 nodes -2.2 % (2.5 %) and 0.0 % (1.1 %).
 * Spreading it evenly over the sphere, or over v's hemisphere, was as
 * unbiased with a larger rms. The six-direction split these replace (power
 * over the axes in the proportions n_a / |n|_1) was 33 % low along the
 * axes for a sphere at any depth and 29 % off for a facet at 45 degrees. */
typedef struct nbuckets {
    rr_vec3 v[6];
    double s[6];
} nbuckets;

static inline int normal_bucket(rr_vec3 n)
{
    double ax = fabs(n.x), ay = fabs(n.y), az = fabs(n.z);
    if (ax >= ay && ax >= az)
        return n.x < 0;
    if (ay >= az)
        return 2 + (n.y < 0);
    return 4 + (n.z < 0);
}

static inline void nb_add_surface(nbuckets *nb, rr_vec3 n, double w)
{
    int b = normal_bucket(n);
    nb->v[b] = rr_v3_add(nb->v[b], rr_v3_scale(n, w));
    nb->s[b] += w;
}

static inline void nb_add(nbuckets *nb, const nbuckets *o)
{
    for (int b = 0; b < 6; b++) {
        nb->v[b] = rr_v3_add(nb->v[b], o->v[b]);
        nb->s[b] += o->s[b];
    }
}

typedef struct hcl {
    rr_vec3 lo, hi, ctr;
    double radius, area, rho_max;
    double uarea;      /* its surfaces' area times (1 - their mirror reflectance): what sends for B = 1 (node_uarea) */
    uint32_t child[2]; /* node references */
    nbuckets An;       /* its surfaces' area by normal bucket (nbuckets), as uarea weighs it */
    double flat;       /* sum over the buckets of |An.v| over its area: 1 where no bucket is curved */
    rr_rgb P;          /* power of the current source values */
    rr_vec3 ac, pc;    /* centroids of its area (uarea's) and of that power (ac where it has none) */
    nbuckets Dn;       /* its surfaces' power (all channels) by normal bucket */
} hcl;

/* What a link's geometry (rad_hier_cluster.c cluster_geo) and its shadow
 * rays' draws (node_sample) read of a cluster, packed in float into four
 * cache lines (rad__hier_cl_pack; an hcl spans nine or ten): those reads
 * wait on memory, a frontier of 8 to 32 clusters per link. mask: bit 0
 * cl_flat; bit 1 + b, Dn's bucket b holds power (its s > 0); bit 7 + b,
 * An's bucket b holds area. */
typedef struct hcf {
    float ctr[3], radius;
    uint32_t child[2];
    float pc[3], ac[3];
    uint32_t mask;
    float pad[3];
    float Dv[6][3], Ds[6];
    float Av[6][3], As[6];
} hcf;

/* What a cluster's buckets (a packed record's v and s; bits: the buckets
 * that hold something, its mask shifted) send towards unit direction u:
 * sum_b max(0, v_b . u), and where a bucket is curved (flat 0) half its
 * shortfall s_b - |v_b| spread by |v_b . u|. flat: every bucket's normals
 * are parallel (cl_flat), so nothing is missing. In float a bucket's |v|
 * and its s differ by rounding where its normals agree: a shortfall under
 * 1e-6 of s is that, not a curve. */
static inline double nbf_proj(const float v[6][3], const float s[6], unsigned bits, rr_vec3 u, int flat)
{
    double p = 0.0;
    for (int b = 0; b < 6; b++) {
        if (!((bits >> b) & 1u))
            continue;
        double vx = v[b][0], vy = v[b][1], vz = v[b][2];
        double d = vx * u.x + vy * u.y + vz * u.z;
        p += d > 0 ? d : 0.0;
        if (flat)
            continue;
        double L = sqrt(vx * vx + vy * vy + vz * vz), sb = s[b], miss = sb - L;
        if (miss > 1e-6 * sb)
            p += L > 1e-9 * sb ? 0.5 * miss * (1.0 - fabs(d) / L) : 0.25 * miss;
    }
    return p;
}
static inline rr_vec3 cf_v3(const float v[3]) { return rr_v3(v[0], v[1], v[2]); }

/* A cluster with no curved bucket (hcl.flat within rounding of 1): its
 * buckets send exactly what its surfaces do, and nbf_proj skips the
 * shortfall's square roots. */
static inline int cl_flat(const hcl *k) { return k->flat >= 1.0 - 1e-12; }

/* A root element as the clusters' walks read it (the leaves of the cluster
 * tree are the roots, element r is root r): packed, where the element's and
 * its patch's records were two cache misses a child (the draws' descents
 * waited on them: node_proj_area and node_proj_power were 17 % of the 1M
 * room's samples). ssum is src.r + src.g + src.b, set by rad__hier_sources;
 * om is 1 - its mirror reflectance (node_uarea is area om). The same values,
 * so the same bits. */
typedef struct hroot {
    rr_vec3 n, ctr;
    double area, om, ssum;
    int flat; /* rad_patch.flat: its surface points are its own (rad_patch_surface) */
} hroot;

/* Visibilities are held in 96ths: every share of 1 to 4 shadow rays, and
 * of 1, 2, 4 or 8 rays from each of up to 4 points (the estimate's element
 * links, rad_hier_rounds.c estimate_per), is a whole number of them. */
#define VIS_ONE 96

typedef struct hlink {
    uint32_t r, s;  /* receiver (an element), source (element or cluster) */
    float f;        /* the transport's geometry: g = f v / VIS_ONE (rad_hier.c, "Transport") */
    float fa;       /* the same for B = 1 with the visibility va (cluster sources: of the source's area) */
    float dF;       /* how much the factor varies over r, without visibility */
    unsigned char v, va; /* the visibilities of g and of the B = 1 gather, in VIS_ONE-ths */
    unsigned char vis;   /* share of the shadow rays to open parts that passed (the partial test), in VIS_ONE-ths */
    unsigned char flags; /* bit 0: some of its shadow rays passed, some not; above: its way (link_way) */
    unsigned char sh[4];   /* how the factor is spread over r, a linear field (set_shape); all 0: evenly */
} hlink;

/* The shape of a factor over its receiver: a linear field in barycentrics,
 * mean 1, from the factor fk[k] in each of the receiver's children (el_split's
 * order: the corners A, B, C, then the middle; the corner children's means
 * are met exactly, the middle one reads the mean). Stored as each corner's
 * departure from the mean, d in [-1, 2], in 85ths from -1 (sh[0..2]; they
 * add up to 0 once read back), sh[3] bit 0 set; all 0 (even) where no
 * corner is 1 % off, which the gather skips. sh[3] bit 1 is not the
 * shape's: LINK_READ (link_mark_read), which the shape leaves as it is. */
#define LINK_READ 2u
static inline void link_clear_shape(hlink *l)
{
    l->sh[0] = l->sh[1] = l->sh[2] = 0;
    l->sh[3] &= LINK_READ;
}
static inline void set_shape(hlink *l, const double fk[4])
{
    double m = (fk[0] + fk[1] + fk[2]) / 3.0, dev = 0.0, d[3];
    for (int k = 0; k < 3; k++) {
        d[k] = m > 0 ? rr_min(2.0, rr_max(-1.0, 2.0 * (fk[k] - m) / m)) : 0.0;
        dev = rr_max(dev, fabs(d[k]));
    }
    link_clear_shape(l);
    if (!(dev > 0.01))
        return;
    for (int k = 0; k < 3; k++)
        l->sh[k] = (unsigned char)lround((d[k] + 1.0) * 85.0);
    l->sh[3] |= 1u;
}
/* A split test read link l's shadow rays: it was kept where its rays
 * decided (the partial-visibility split, rad_hier_rounds.c), so the
 * estimate draws them again (rad_hier.c, "Decide, then estimate"). */
static inline void link_mark_read(hlink *l) { l->sh[3] |= LINK_READ; }
static inline int link_rays_read(const hlink *l) { return (l->sh[3] & LINK_READ) != 0; }
/* The corners' departures back (adding up to 0); 0 when the link is even. */
static inline int link_shape(const hlink *l, float d[3])
{
    if (!(l->sh[3] & 1u))
        return 0;
    /* written out (no loops), so that d stays in registers in the gather */
    float d0 = (float)l->sh[0] * (1.0f / 85.0f) - 1.0f, d1 = (float)l->sh[1] * (1.0f / 85.0f) - 1.0f,
          d2 = (float)l->sh[2] * (1.0f / 85.0f) - 1.0f;
    float mean = (d0 + d1 + d2) * (1.0f / 3.0f);
    d[0] = d0 - mean;
    d[1] = d1 - mean;
    d[2] = d2 - mean;
    return 1;
}

/* Whether some of a link's shadow rays passed and some not. */
static inline int link_partial(const hlink *l) { return l->flags & 1; }
static inline void link_set_partial(hlink *l, int partial)
{
    l->flags = (unsigned char)((l->flags & ~1u) | (partial != 0));
}
/* A link's way: 0 straight, w by way of the mirrors of hctx.img[w - 1] (the
 * receiver read as its image in them: rview). */
#define WAYS_MAX 127
static inline unsigned link_way(const hlink *l) { return l->flags >> 1; }

/* The transport coefficient of a link, and the same for B = 1. */
static inline float link_g(const hlink *l) { return l->f * (float)l->v * (1.0f / VIS_ONE); }
static inline float link_ga(const hlink *l) { return l->fa * (float)l->va * (1.0f / VIS_ONE); }
/* A share k / n of n rays in VIS_ONE-ths: exact where n divides VIS_ONE
 * (1 to 4 rays, or 1 to 8 from each of up to 4 points: the transport's
 * visibilities), rounded otherwise (the rays to open parts of s, which the
 * partial test reads as all, none or some). */
static inline unsigned char vis_share(int k, int n)
{
    return (unsigned char)(n > 0 ? (k * VIS_ONE + n / 2) / n : 0);
}

/* A mirror of a way: the light table's plane n . x = d, and a rectangle in
 * the plane (origin o, unit axes u, v) around its triangles. */
typedef struct hwin {
    rr_vec3 n;
    double d;
    rr_vec3 o, u, v;
    double u0, u1, v0, v1;
} hwin;

/* A way (rad_hier_mirror.c): light from a source that meets the planar
 * mirrors plane[n - 1], ..., plane[0] in turn before the receiver (plane[0]
 * met first leaving the receiver). T maps the receiver to its image in them
 * all (reflected in plane[0] first); Tk[k] to its image in plane[0 .. k-1],
 * Yk[k] a source to its image in plane[k .. n-1] (for the culling). */
typedef struct himg {
    int n;
    uint32_t plane[RT_CHAIN_MAX];
    double rho; /* the product of their mean reflectances */
    rr_xform T, Ti, Tk[RT_CHAIN_MAX], Yk[RT_CHAIN_MAX]; /* Ti: T's inverse */
    hwin win[RT_CHAIN_MAX];
} himg;

typedef struct hctx {
    const scene *s;
    const rt_accel *a;
    const rad_patches *R;
    const rt_lights *L;
    const rt_lights *M; /* the mirror planes' table (ways), when img */
    himg *img;          /* the ways by mirrors links pass: way w is img[w - 1] */
    unsigned nimg;
    hel *el;
    size_t nel, capel;
    hcl *cl;
    hcf *cf; /* the clusters packed (hcf), as of the last rad__hier_cl_pack */
    hroot *rt; /* per root (hroot) */
    size_t ncl;
    uint32_t top;
    hlink *ln;
    size_t nln, capln, first_new;
    rr_rgb *sv;       /* the gather's source values, elements then clusters (rad__hier_gather) */
    size_t capsv;
    size_t evaluated; /* links evaluated so far (progress) */
    rt_ray_counts rays; /* rays traced while linking (sol->ff_rays): every parallel region that traces adds its own */
    double eps, min_area;
    double gap; /* thin gaps narrower than this are buried (rad__ff_buried): RAD_FF_BURY of the flat patch size (gap_of: or of the root's) */
    double *objpow;   /* per scene object: what its leaves take in, rho A H (link_eps); NULL: not yet */
    double power;     /* the emitted power (rad_hier.c emitted_power): the last solve's power test */
    int last_solve;   /* the solve the ledger reads (after the rounds): it also passes the power test */
    double eps_asked; /* eps as radiosity.refine_tolerance asks it (eps grows under --max-memory) */
    double rel;       /* radiosity.relative_tolerance, once the receivers' B is known (receiver_eps); 0: off */
    size_t max_links;
    double max_bytes; /* the pass's own arrays at most this (rad_hier_opts.max_bytes); 0: no limit */
    int capped, nomem;
    int by_memory;    /* the cap reached was max_bytes (the messages name --max-memory) */
    int first, over; /* the first walk (rad_hier.c, first_refine) stops when it reaches the cap (over) */
    int unit;       /* the sources are B = 1 (rad__hier_sources): gathers read hlink.ga */
    rr_rgb cs;      /* what the leaves send is their B times cs: the column scale (rad__hier_solve) */
    double ext, plane_tol;
    uint64_t seed;  /* the estimate's draws only (rad_hier.c, "Decide, then estimate") */
    uint64_t draw;  /* which shadow rays the links draw: 0 while refining, ESTIMATE_DRAW for the estimate */
    const volatile sig_atomic_t *interrupt;
    /* Receiving leaf clusters (radiosity.receiving_clusters; rad_hier.c,
     * "Receiving leaf clusters"): rlc[k] is 1 for the clusters that may
     * receive as one, 2 for the highest of them (where the gather's walks
     * start), NULL when there are none; nrlc counts the highest. */
    unsigned char *rlc;
    size_t nrlc;
    double rlc_bytes; /* what their tables may hold (rad__hier_rlc_bytes), for the pass's count */
    double rlc_radius; /* their largest radius */
    struct rlc_geo *rg; /* per receiving leaf cluster's group of links, from rg0 on (rad__hier_groups) */
    uint32_t *rgi;      /* per cluster: its group's index in rg, NONE where it has no links */
    size_t rg0;
    /* The roots in the cluster tree's depth-first order, for rlc_push
     * (rad_hier_rlc.c): rdfs[p] the root at position p, rn[p] its normal and openness,
     * rpos[k] the position of cluster k's first root; rH[p] what rlc_push
     * gathered for it, rf[p] 1 where it read some links. */
    uint32_t *rdfs, *rpos;
    struct rlc_root *rn;
    rr_rgb *rH;
    unsigned char *rf;
    int rlc_auto;      /* made only where the first walk does not fit without them (first_refine) */
} hctx;

/* A unit direction packed into a float's 32 bits (octahedral, 16 bits a
 * coordinate: within 1e-4 rad), and back: a receiving leaf cluster's link
 * keeps the direction its light comes from in hlink.dF (rad__hier_eval_rlc). */
static inline float dir_pack(rr_vec3 u)
{
    double l1 = fabs(u.x) + fabs(u.y) + fabs(u.z);
    double x = l1 > 0 ? u.x / l1 : 0.0, y = l1 > 0 ? u.y / l1 : 0.0;
    if (u.z < 0) {
        double ox = (1.0 - fabs(y)) * (x < 0 ? -1.0 : 1.0), oy = (1.0 - fabs(x)) * (y < 0 ? -1.0 : 1.0);
        x = ox;
        y = oy;
    }
    uint32_t qx = (uint32_t)lround((x * 0.5 + 0.5) * 65535.0), qy = (uint32_t)lround((y * 0.5 + 0.5) * 65535.0);
    uint32_t b = qx | qy << 16;
    float f;
    memcpy(&f, &b, sizeof f);
    return f;
}
static inline rr_vec3 dir_unpack(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    double x = (double)(b & 0xffffu) / 65535.0 * 2.0 - 1.0, y = (double)(b >> 16) / 65535.0 * 2.0 - 1.0;
    double z = 1.0 - fabs(x) - fabs(y);
    if (z < 0) {
        double ox = (1.0 - fabs(y)) * (x < 0 ? -1.0 : 1.0), oy = (1.0 - fabs(x)) * (y < 0 ? -1.0 : 1.0);
        x = ox;
        y = oy;
    }
    return rr_v3_norm(rr_v3(x, y, z));
}

/* A receiving leaf cluster's links' direction buckets: the cube face a
 * direction points to (normal_bucket), each cut in four by the signs of
 * its other two components. With the six faces alone a face's light mixed
 * directions on both sides of a flat surface's horizon (the floor seen
 * beside a chair, below its seat, and the walls above it, in one bucket
 * whose mean direction is level), and its spread term gave the seat's
 * underside 17 % less than the light tracer counts (notes/radiosity.md,
 * "Receiving clusters: finer direction buckets"). */
#define RLC_BUCKETS 24
static inline int rlc_dir_bucket(rr_vec3 u)
{
    int b = normal_bucket(u), a = b / 2;
    double p[3] = {u.x, u.y, u.z};
    return 4 * b + 2 * (p[(a + 1) % 3] < 0) + (p[(a + 2) % 3] < 0);
}
/* A receiving leaf cluster's link's direction u, kept in hlink.dF, and its
 * bucket (rlc_dir_bucket(u)) in sh[0], which such a link's shape leaves
 * free (it has none): the gather reads the bucket every sweep. */
static inline void rlc_set_dir(hlink *l, rr_vec3 u)
{
    l->dF = dir_pack(u);
    l->sh[0] = (unsigned char)rlc_dir_bucket(u);
}
static inline int rlc_bucket(const hlink *l) { return l->sh[0]; }

/* Node x is a receiving leaf cluster: a receiver as a cluster end is (its
 * links split into its children while closer than admissible or carrying
 * more than eps), each root under it reading their light with its own
 * normal (rad__hier_gather). */
static inline int is_rlc(const hctx *c, uint32_t x) { return (x & CLB) && c->rlc && c->rlc[CL(x)]; }

static inline int interrupted(const hctx *c) { return c->interrupt && *c->interrupt; }

/* What link l brings its receiver in the gather: its source's value as
 * rad__hier_gather copied it (c->sv: elements, then clusters) times its
 * transport (for B = 1 where c->unit). */
static inline rr_rgb link_light(const hctx *c, const hlink *l)
{
    rr_rgb v = l->s & CLB ? c->sv[c->nel + CL(l->s)] : c->sv[l->s];
    return rr_rgb_scale(v, c->unit ? link_ga(l) : link_g(l));
}

static inline rr_vec3 el_normal(const hctx *c, uint32_t e) { return c->rt[c->el[e].root].n; }

/* rad_patch_surface for a point p of an element of root `root`: a scene
 * triangle's point is its own, its normal the root's (hroot), read without
 * the patch's record (a cache miss a shadow ray's end). */
static inline void root_surface(const hctx *c, uint32_t root, rr_vec3 p, rr_vec3 *xs, rr_vec3 *ns)
{
    if (c->rt[root].flat) {
        *xs = p;
        *ns = c->rt[root].n;
        return;
    }
    rad_patch_surface(c->R, c->s, c->a, root, p, xs, ns);
}

/* Point x and direction v as seen by way w: their image in its mirrors (an
 * isometry: a receiver read there exchanges light with the real sources as
 * the real one does by way of the mirrors); themselves on way 0. */
static inline rr_vec3 way_point(const hctx *c, unsigned w, rr_vec3 x)
{
    return w ? rr_xform_point(&c->img[w - 1].T, x) : x;
}
static inline rr_vec3 way_dir(const hctx *c, unsigned w, rr_vec3 v) { return w ? rr_xform_vector(&c->img[w - 1].T, v) : v; }
/* The real point whose image by way w is x. */
static inline rr_vec3 way_back(const hctx *c, unsigned w, rr_vec3 x)
{
    return w ? rr_xform_point(&c->img[w - 1].Ti, x) : x;
}
/* The shadow-ray rule by way w's mirrors, from x (normal nx) on the real
 * receiver to y (normal ny) on the source. */
static inline int way_visible(const hctx *c, unsigned w, rr_vec3 x, rr_vec3 nx, rr_vec3 y, rr_vec3 ny)
{
    const himg *g = &c->img[w - 1];
    return rt_lights_via_mirrors(c->M, g->plane, g->n, x, nx, y, ny);
}
/* What way w passes on: its mirrors' reflectances (1 straight). */
static inline double way_rho(const hctx *c, unsigned w) { return w ? c->img[w - 1].rho : 1.0; }

/* A receiver element as a link of way w reads it: its corners, centre and
 * normal reflected in the way's mirrors (e itself for burial and its root). */
typedef struct rview {
    const hel *e;
    rr_vec3 c[3], ctr, n;
    unsigned way;
} rview;
static inline rview rview_of(const hctx *c, uint32_t r, unsigned w)
{
    rview v;
    v.e = &c->el[r];
    v.way = w;
    for (int k = 0; k < 3; k++)
        v.c[k] = way_point(c, w, v.e->c[k]);
    v.ctr = way_point(c, w, v.e->ctr);
    v.n = way_dir(c, w, el_normal(c, r));
    return v;
}
static inline rr_rgb el_rho(const hctx *c, uint32_t e) { return c->R->p[c->el[e].root].rho; }

/* ---- shared by the builder (rad_hier.c) and the clusters (rad_hier_cluster.c) ---- */

#define VIS_RAYS 4 /* shadow rays per link */

/* The largest channel of the mean radiosity node x shoots. */
static inline double node_B(const hctx *c, uint32_t x)
{
    if (x & CLB) {
        const hcl *k = &c->cl[CL(x)];
        return k->area > 0 ? rr_rgb_max(k->P) / k->area : 0.0;
    }
    return rr_rgb_max(c->el[x].src); /* the area mean of its leaves' B (rad__hier_sources) */
}
static inline double node_area(const hctx *c, uint32_t x);
/* The receiver-first tests' threshold for receiver r (an element): eps, or
 * less where the share rel of r's own power is less (rad_hier.c, "Light near
 * occluders"). */
static inline double receiver_eps(const hctx *c, uint32_t r)
{
    if (!(c->rel > 0) || (r & CLB))
        return c->eps;
    double e = c->rel * node_area(c, r) * node_B(c, r);
    return e < c->eps ? e : c->eps;
}
/* The power a link into element r may carry (rad_hier.c's header;
 * notes/radiosity.md, "Objects that take in little"): eps, or, from the
 * second round on (objpow known), OBJ_SHARE of what r's object takes in
 * where that is less, but not below eps / OBJ_FLOOR. */
#define OBJ_SHARE 0.05
#define OBJ_FLOOR 4.0
static inline double link_eps(const hctx *c, uint32_t r)
{
    if (!c->objpow || (r & CLB))
        return c->eps;
    double e = OBJ_SHARE * c->objpow[c->R->p[c->el[r].root].object], lo = c->eps / OBJ_FLOOR;
    return e < lo ? lo : e < c->eps ? e : c->eps;
}
/* Node x can be split: a cluster, or an element whose children keep
 * min_area, or are still long for it: a sliver (a long thin triangle of a
 * mesh, which el_split cuts into slivers again) splits while its children's
 * radius is over sqrt(SLIVER_R2 min_area), so that its fixed points are not
 * a hand's width apart along it. interior.json's glazing bars (long faces
 * of triangles 3 cm x 30-70 cm, the horizontal bars 0.5 mm short of the
 * vertical one's sides) had leaves at min_area reaching across those
 * slots, with a fixed point in a slot for every link: the faces along the
 * slots took in 9-10 % less than the light tracer counts (notes/radiosity.md,
 * "Slivers and sources seen close"). A child under min_area reaches this
 * radius only at about 5:1 and longer (radius^2 over 4 times its area; a
 * well-shaped one has 0.8-1.9); at 8 the bars stayed as they were. */
#define SLIVER_R2 4.0
static inline int splittable(const hctx *c, uint32_t x)
{
    if (x & CLB)
        return 1;
    const hel *e = &c->el[x];
    return e->area * 0.25 >= c->min_area || e->radius * e->radius * 0.25 >= SLIVER_R2 * c->min_area;
}
/* A leaf at a contact: more of its closedness rays than this (3 of the 16)
 * meet a surface within its radius. A leaf along a right-angle crease sends
 * about a fifth of them there (its fixed points lie 1/6 to 1/2 of its size
 * from the edge), so 0.2 (4 of 16) left about half such leaves whole:
 * Cornell's short block kept 21-unit leaves along the floor where the lit
 * and the shadowed floor meet, and its front face came out 1.3-2.7 times
 * the final gather's light there, 65 % too bright in the hybrid's 4x4
 * blocks (notes/radiosity.md, "Creases"). */
#define CONTACT_SHARE 0.15
#define CONTACT_AREA 16.0 /* such a leaf may split down to min_area / CONTACT_AREA (radiosity.relative_tolerance) */
/* Under radiosity.relative_tolerance, a leaf at a contact may be split
 * below min_area for the uneven test (rad_hier.c, "Light near occluders"):
 * the light falls within a few units of the edge where two surfaces meet.
 * An element split so already passes its links on to its children. */
static inline int contact_splittable(const hctx *c, uint32_t x)
{
    if (!(c->rel > 0) || (x & CLB))
        return 0;
    const hel *e = &c->el[x];
    return e->area * 0.25 >= c->min_area / CONTACT_AREA && (e->child != NONE || e->touch > CONTACT_SHARE);
}

static inline double node_area(const hctx *c, uint32_t x) { return x & CLB ? c->cl[CL(x)].area : c->el[x].area; }
static inline double node_radius(const hctx *c, uint32_t x) { return x & CLB ? c->cl[CL(x)].radius : c->el[x].radius; }
static inline rr_vec3 node_ctr(const hctx *c, uint32_t x) { return x & CLB ? c->cl[CL(x)].ctr : c->el[x].ctr; }
/* The reflectance the oracle weighs a receiver's light by (rho_max A F B):
 * its diffuse reflectance, but at least RHO_FLOOR. The oracle bounds the
 * light a receiver sends on; the ledger also reads what it absorbs, and a
 * receiver that reflects nothing (a lamp, a mirror's diffuse part) had no
 * link refined for it: the bunny rooms' ceiling lamps took in 2.8 % less
 * than the light tracer counts (an empty room too, 4.4 SE) and came out
 * -0.3 % with the floor at a tenth, for 108 more links of 790 k
 * (notes/radiosity.md, "Black receivers"). */
#define RHO_FLOOR 0.1
static inline double node_rho(const hctx *c, uint32_t x)
{
    double r = x & CLB ? c->cl[CL(x)].rho_max : rr_rgb_max(el_rho(c, x));
    return r > RHO_FLOOR ? r : RHO_FLOOR;
}

/* Node x's corners: a cluster's box's 8, an element's 3. */
static inline void node_points(const hctx *c, uint32_t x, rr_vec3 pts[8], int *n)
{
    if (x & CLB) {
        const hcl *k = &c->cl[CL(x)];
        for (int i = 0; i < 8; i++)
            pts[i] = rr_v3(i & 1 ? k->hi.x : k->lo.x, i & 2 ? k->hi.y : k->lo.y, i & 4 ? k->hi.z : k->lo.z);
        *n = 8;
    } else {
        memcpy(pts, c->el[x].c, 3 * sizeof *pts);
        *n = 3;
    }
}

/* Node x's area as the row sums (B = 1 but for mirrors, rad__hier_sources)
 * weigh it: times 1 - the mirror reflectance, since what a mirror reflects
 * is carried on by the links by way of it. On a cluster that holds a mirror
 * the row sums read the rest of its surfaces: by the whole area, a furnace
 * with a mirror face came out 0.5 % off where such clusters sent. */
static inline double node_uarea(const hctx *c, uint32_t x)
{
    if (x & CLB)
        return c->cl[CL(x)].uarea;
    return c->el[x].area * (1.0 - c->R->p[c->el[x].root].mirror);
}

/* The 4 fixed points of an element (barycentrics): centroid, then halfway to
 * each corner. */
static const double k_pts[4][3] = {
    {1. / 3, 1. / 3, 1. / 3}, {2. / 3, 1. / 6, 1. / 6}, {1. / 6, 2. / 3, 1. / 6}, {1. / 6, 1. / 6, 2. / 3}};

/* Element e's fixed point q in barycentrics: k_pts[q], or, for an element
 * partly buried in slots and under no cover (hel.own), one of the open
 * points its burial probes found (hel.kb, rad_hier_bury.c el_probe). A slot
 * a few millimetres wide (between books, behind glazing bars, over a lamp's
 * body) takes in the light that falls on its mouth within a few widths of
 * it; the fixed pattern's points seldom land there, and an element
 * straddling the mouth read that open band from points deep inside it: 9 %
 * of what the light tracer counts on a book's side in the slot beside a
 * taller one (notes/radiosity.md, "Slots"). Open points drawn uniformly over
 * the element read it without that bias. */
static inline void el_kpt(const hel *e, int q, double b[3])
{
    if (!e->own) {
        b[0] = k_pts[q][0];
        b[1] = k_pts[q][1];
        b[2] = k_pts[q][2];
        return;
    }
    b[1] = e->kb[q][0] / 65535.0;
    b[2] = e->kb[q][1] / 65535.0;
    b[0] = 1.0 - b[1] - b[2];
}

/* Index of the k-th of element e's fixed points that is not buried (cyclic
 * in k), or -1 when all four are: receivers gather at open points only. */
static inline int open_pt(const hel *e, int k)
{
    int idx[4], m = 0;
    for (int q = 0; q < 4; q++)
        if (!(e->bur & (1u << q)))
            idx[m++] = q;
    return m ? idx[k % m] : -1;
}

static inline rr_vec3 tri_at(const rr_vec3 v[3], double a, double b, double g)
{
    return rr_v3_add(rr_v3_add(rr_v3_scale(v[0], a), rr_v3_scale(v[1], b)), rr_v3_scale(v[2], g));
}

static inline rr_vec3 tri_random(const rr_vec3 v[3], rr_rng *rng)
{
    double u = rr_rng_uniform(rng), w = rr_rng_uniform(rng);
    if (u + w > 1.0) {
        u = 1.0 - u;
        w = 1.0 - w;
    }
    return tri_at(v, 1.0 - u - w, u, w);
}


/* ---- the hierarchy and its links (rad_hier.c) ---- */

/* Element x's four children (made once); 0, or -1 when out of memory. */
int rad__hier_el_split(hctx *c, uint32_t x);
/* The power link r <- s by way w may carry (the oracle: rho_max(r) A_r
 * Fhat B_s), INFINITY where a cluster end is closer than admissible, except
 * a near link that a receiving leaf cluster keeps (rad_hier.c's header,
 * "Receiving leaf clusters"): its estimate without the admissibility. */
double rad__hier_link_power(const hctx *c, uint32_t r, uint32_t s, unsigned w);
/* Whether the centres of r and s are far enough apart for their sizes to
 * read a link at them (always, between two elements). */
int rad__hier_admissible(const hctx *c, uint32_t r, uint32_t s, unsigned w);
/* A new link r <- s by way w, to be evaluated (from c->first_new on). */
void rad__hier_link_add(hctx *c, uint32_t r, uint32_t s, unsigned w);
/* Whether the links have reached radiosity.max_links or the pass's share of
 * --max-memory (then c->by_memory is set). */
int rad__hier_past_cap(hctx *c);
/* Splits r or s (the larger that can be split, r first when receiver: 1, or
 * 2 for the uneven test, which may split a leaf at a contact below min_area;
 * s first for 3, the varying source's test) and refines the children's
 * links; 0 when neither can be split. */
int rad__hier_split_link(hctx *c, uint32_t r, uint32_t s, int receiver, unsigned w);

/* ---- the links evaluated and re-tested (rad_hier_rounds.c) ---- */

/* Evaluates the links from c->first_new on, and computes the data of fresh
 * leaves; then splits what the visibility and first-shot tests ask for, and
 * again, until nothing changes. */
rr_status rad__hier_settle(hctx *c, void (*progress)(void *, size_t, size_t), void *user, rr_error *err);
/* The visibility of every link whose rays a decision read (its power
 * without visibility at least half the partial test's) drawn afresh from
 * the estimate's own stream once the refinement has settled, the geometry
 * kept where it is held without visibility. */
rr_status rad__hier_estimate(hctx *c, void (*progress)(void *, size_t, size_t), void *user, rr_error *err);
/* Re-tests every link with the solved radiosity; those that now carry too
 * much are replaced by refined ones. Returns whether anything changed. */
int rad__hier_relink(hctx *c);
int rad__hier_object_powers(hctx *c); /* rad_hier_rounds.c: hctx.objpow from the last solve; -1 out of memory */

/* ---- buried parts and leaf data (rad_hier_bury.c) ---- */

/* Whether surface point xs (normal ns) of element e lies under another
 * surface, by the flat pass's rule (rad__ff_buried) for a probe along ns. */
int rad__hier_buried(const hctx *c, const hel *e, rr_vec3 xs, rr_vec3 ns);
/* Whether the surface point xs (normal ns) of e faces the front of another
 * surface that does not emit within e's thin-gap width: a point on one side
 * of a slot, open or buried (rad__ff_buried). */
int rad__hier_in_slot(const hctx *c, const hel *e, rr_vec3 xs, rr_vec3 ns);
/* The same for point x of e's flat triangle (on the true surface first). */
int rad__hier_point_buried(const hctx *c, const hel *e, rr_vec3 x);
/* Probes every element not yet probed, in parallel: its fixed points'
 * burial (hel.bur) and its open share (hel.open). */
void rad__hier_probe_new(hctx *c);
/* The data of the fresh leaves among elements 0 .. ne - 1, in parallel:
 * their first shot (H0, E, spread) and whether their CLOSED_RAYS
 * cosine-drawn rays all land on fronts of surfaces (closed; land, back:
 * the shares that landed on fronts and on backs). */
void rad__hier_leaves_data(hctx *c, size_t ne);
/* Every element's xlo and xhi from its leaves' back shares (rad_hier.c,
 * unevenly_exposed). */
void rad__hier_exposures(hctx *c);

/* ---- element links (rad_hier_link.c) ---- */

/* A shadow ray's end y (on root yr, normal ny, from x) where it lies on an
 * analytic sphere seen from outside: a facet of the sphere (a chord) faces
 * x while part of the cap over it, where the ray ends on the true surface,
 * does not, and the ray would cross the sphere itself. y moves to where the
 * segment first meets the sphere: a sphere does not shadow the light it
 * sends through its own facets. Measured: the floor under a sphere lamp
 * received 1.7 % too little (the light tracer's incident power; -2.9 % right
 * under it), now within 0.1 %. The same at the start of a ray from a sphere
 * (its end moved to where the segment leaves the sphere) made its leaves'
 * row sums 1, but a lit sphere's radiosity display worse (board-to-sphere,
 * block p90 14.5 -> 27.6 %): a cap point's own horizon is the truth that the
 * display is compared with, so rays still start on the true surface and a
 * sphere's row sums stay short (an emissive sphere's ledger row shows it as
 * escaped: 2.5 % of a sphere lamp's power in a closed box).
 * A solid's curved piece (a chord too, rad_solid.c) likewise, where the
 * segment enters the solid within twice the root's size of y (farther, the
 * solid's own other part hides y): test_transport's floor under a solid
 * sphere lamp -0.62 % -> -0.11 % (the analytic sphere's +0.12 %). */
void rad__hier_sphere_end(const hctx *c, uint32_t yr, rr_vec3 x, rr_vec3 *y, rr_vec3 *ny);

/* Which of element e's near-pair quadrature points are buried (bit k for
 * point k): probed once per partly buried element (rad__hier_probe_new), not
 * once per near link (they were a fifth of room.json's pass time). */
uint64_t rad__hier_near_buried(const hctx *c, const hel *e);

/* Element l->r <- element l->s: the factor (l->f, l->fa), visibility
 * (l->v, l->va, l->vis, l->partial) and the factor's spread over r (l->dF),
 * drawing the ends of per shadow rays from each point (1, 2, 4 or 8) from rng. */
void rad__hier_eval_ee(const hctx *c, hlink *l, rr_rng *rng, int per);
/* The same link's visibility drawn again from rng, the factor kept where it
 * is held without visibility (near pairs; a far pair's 4 points each count
 * only if their ray passes, so it is evaluated whole): the same rays and
 * values as rad__hier_eval_ee from that stream. */
void rad__hier_revis_ee(const hctx *c, hlink *l, rr_rng *rng, int per);

/* ---- clusters (rad_hier_cluster.c) ---- */

/* The bounding-volume hierarchy of clusters over the roots (c->el[0 ..
 * c->R->n), c->cl room for as many): the top node, NONE when out of memory
 * or interrupted. */
uint32_t rad__hier_clusters(hctx *c);
/* The solved hierarchy as sol (rad_hier_solve.c): the leaves as its patch set
 * (roots owned from here on), their B, and the gathers the ledger and the
 * hybrid read. */
rr_status rad__hier_output(hctx *c, rad_patches *roots, rad_solution *sol, rr_error *err);
/* Element l->r <- cluster l->s: geometry and visibility (rad_hier.c's header,
 * "Transport"), drawing from rng. */
void rad__hier_eval_cluster(const hctx *c, hlink *l, rr_rng *rng);
/* Its visibility drawn again from rng, the geometry kept. */
void rad__hier_revis_cluster(const hctx *c, hlink *l, rr_rng *rng);
/* The evaluated cluster links' geometry again for the current sources,
 * those that carry min_power or more without visibility (0: all). */
void rad__hier_regeo(hctx *c, double min_power);
/* A link into a receiving leaf cluster (l->r is_rlc): evaluated whole
 * (mode 0, and the estimate's redraw, 1), or the geometry of a cluster
 * source's power alone again (RLC_GEO, the kept links' regeo, for an
 * admissible cluster source only: read at the receiver's centroid, no point
 * drawn, no shadow ray: rng may be NULL) (rad_hier_cluster.c). */
#define RLC_GEO 2
void rad__hier_eval_rlc(const hctx *c, hlink *l, rr_rng *rng, int mode);
/* The unoccluded irradiance vector at point x from element s of unit
 * radiosity, s clipped to the front of x's plane for u (rad_hier_link.c). */
rr_vec3 rad__hier_rlc_vec(const hctx *c, rr_vec3 x, rr_vec3 u, uint32_t s);
/* The unoccluded point factor at x (normal n) from element s, its part in
 * front of x's plane, as an element link reads it (side_ff): a cluster's
 * frontier reads its roots so (rad_hier_cluster.c cluster_sums). */
double rad__hier_root_ff(const hctx *c, rr_vec3 x, rr_vec3 n, uint32_t s);
/* c->ln[0 .. nln) sorted by receiver (elements, then receiving leaf
 * clusters), then source, then way: the solve's fixed order (rad_hier_sort.c;
 * rad__hier_solve sorts them at its start). -1 when out of memory. */
int rad__hier_sort_links(hctx *c);
/* rad_hier_rlc.c: for the groups grp[c->rg0 .. ngrp) of the links into
 * receiving leaf clusters (they sort after the elements'), their direction
 * buckets' geometry (c->rg, c->rgi); -1 when out of memory. */
int rad__hier_rlc_prepare(hctx *c, const size_t *grp, size_t ngrp);
/* The most the receiving leaf clusters' tables hold (a direction table for
 * each marked cluster, the roots' order and light): the solve allocates
 * them, so the count of what the pass holds adds this from the marking on. */
double rad__hier_rlc_bytes(const hctx *c);
/* Their links' light, read by every root under them (adds to hel.H), after
 * the elements' gather. */
void rad__hier_rlc_gather(hctx *c, const size_t *grp);
/* What the roots under receiving leaf cluster group gi (an index into c->rg)
 * take in of a unit irradiance by link l (its bucket's): column_sums. */
double rad__hier_rlc_take(const hctx *c, size_t gi, const hlink *l);
/* Marks the receiving leaf clusters: the clusters of roots too small to
 * split (and no mirror) whose radius is at most `radius` (c->rlc, c->nrlc);
 * -1 when out of memory. */
int rad__hier_mark_rlc(hctx *c, double radius);
/* The clusters' packed records (hcf) from their hcl: after the sources
 * change, before links are evaluated or their geometry read again. */
void rad__hier_cl_pack(hctx *c);

/* ---- links by way of mirrors (rad_hier_mirror.c) ---- */

/* c->img from the planar mirrors of table M (c->M = M): every chain of up
 * to depth of them in which each can see the next, shortest first, at most
 * WAYS_MAX (*dropped: how many more there were); -1 when out of memory. */
int rad__hier_ways(hctx *c, const rt_lights *M, int depth, size_t *dropped);
/* Node r (receiver) and node s cannot exchange light by way w: at some
 * mirror of it, the images of the two that meet there lie on no common side
 * of its plane, or no segment between their bounding spheres passes through
 * the rectangle around it. */
int rad__hier_way_culled(const hctx *c, uint32_t r, uint32_t s, unsigned w);

/* ---- solving (rad_hier_solve.c) ---- */

/* What push does at the leaves: SOLVE sets B = E + rho k H (and returns the
 * largest change), SIGMA sets k from the row sum (k = 1 / sigma on closed
 * leaves), KEEP stores k H in H. */
typedef enum push_mode { PUSH_SOLVE, PUSH_SIGMA, PUSH_KEEP } push_mode;

/* Source values: every leaf's src = B (or B - its own emission when indirect,
 * or 1 when unit), area means up the trees, power and directional power up
 * the clusters. */
void rad__hier_sources(hctx *c, int unit, int indirect);
/* Receiver groups of the links sorted by receiver: grp[0..ngrp] (one past
 * the end); NULL when out of memory (free() it). With receiving leaf
 * clusters, also their groups' bucket geometry (c->rg, rad_hier_solve.c),
 * made again when prepare (else kept from the last call that made it). */
size_t *rad__hier_groups(hctx *c, size_t *ngrp, int prepare);
/* Every link's transport into its receiver's H (receivers are elements);
 * after a rad__hier_solve of the same hierarchy (which sizes c->sv). */
void rad__hier_gather(hctx *c, const size_t *grp, size_t ngrp);
/* Irradiance down to the leaves; at the leaves per mode. */
double rad__hier_push(hctx *c, push_mode mode);
/* Sorts the links, sets the row-sum scales k, then Jacobi sweeps (sources,
 * gather, push) until the largest change of B is under so->tolerance times
 * the largest B. */
rr_status rad__hier_solve(hctx *c, const rad_solve_opts *so, rad_solve_stats *st, rr_error *err);

#endif
