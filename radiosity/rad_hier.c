/* rad_hier.c - hierarchical radiosity with clustering, the radiosity pass's
 * method "hierarchical", the default (the flat one: radiosity.method "flat")
 * (Hanrahan, Salzman & Aupperle 1991; clusters after Smits, Arvo & Greenberg
 * 1994 and Sillion 1995). notes/radiosity.md has the design and measurements.
 *
 * Elements. Every patch of a coarse patch set (the roots: the scene's
 * triangles at 16x the flat method's patch area, spheres and solids at that
 * area: rad__hier_root_limits) is the root of a quadtree of elements, split
 * on demand into four similar triangles (corners A, B, C, then the middle).
 *
 * Clusters. A binary bounding-volume hierarchy over the roots (median split
 * of the centroids on the longest axis). A cluster shoots with the intensity
 * I(u) = (1/pi) sum_b max(0, D_b . u) (plus, for a curved cluster, what its
 * buckets miss put back away from their mean normals), D_b its surfaces'
 * power times normal summed per normal bucket (the cube face a normal points
 * to; rad_hier_ctx.h, nbuckets), an element with (1/pi) P max(0, n . u):
 * exact for one flat surface, coplanar ones and surfaces facing along the
 * axes. The six-direction split it replaces (power over the axes in the
 * proportions n_a / |n|_1) was 33 % low along the axes for a sphere and 29 %
 * off for a facet at 45 degrees: a sphere lamp in a closed box came out 10 %
 * dark. Clusters only shoot: a cluster at the receiving end passes the link
 * to its children, so every receiver is an element and reads the link with its own normal
 * (as a Barnes-Hut walk does; links grow as N log N). Clusters that also
 * received (irradiance per axis direction, read with each element's normal)
 * lit the undersides of sphere-to-board's sphere from the lamp above:
 * radiosity-mode 90th-percentile block error 64 % there, 19 % without.
 * Links start from the top cluster's self-link, so the first linking is not
 * quadratic in the number of surfaces.
 *
 * Links and the oracle (BF refinement). A link r <- s gathers the radiosity of
 * s into the irradiance of r. It is refined while the power it may carry,
 * rho_max(r) A_r Fhat(r, s) B_s (Fhat an upper estimate of the form factor),
 * exceeds eps = tolerance x the power emitted in the scene, by splitting the
 * larger of the two (elements stop at min_area; slivers: SLIVER_R2). Two
 * tests split the receiver first (a shadow's edge or a gradient lies on it;
 * splitting the source there only shrinks the link's power until it passes):
 * a link whose rays see the source partly (0 < V < 1) while its power
 * exceeds eps / 8, and an uneven one, rho A_r (F_max - F_min) B_s > eps over
 * the receiver's quadrature points (for cluster sources, of the geometric term
 * at its corners). Without the first, sphere-to-board's
 * shadow was as coarse as the board's roots. A third splits the receiver
 * whose leaves see the backs of surfaces unevenly (unevenly_exposed: its
 * fixed points' rays cannot tell that the ceiling over a lamp is hidden).
 * A link with a cluster at either end is split, whatever it carries, while
 * the centres are closer than ADMISSIBLE times the sum of the radii: without
 * that, Cornell's rotated tall block came out 18.5 % dark (-2.0 % with it,
 * when a cluster was read at its centre). Since a cluster link is read over
 * its nodes three levels down (rad_hier_cluster.c), 1.5 holds the accuracy
 * of 2 with a quarter fewer links where both ends are flat (no curved
 * bucket); a curved cluster end keeps 2 (at 1.5 a bunny's radiosity came out
 * 1.2 % darker; notes/radiosity.md, "Admissibility by flatness").
 * From the second round, a link into an object that takes in little is
 * held to OBJ_SHARE of that object's intake instead of eps where that is
 * less, down to eps / OBJ_FLOOR (link_eps, rad_hier_ctx.h): room.json's
 * dark mirror frame was 7.9 % short of the light tracer under eps alone
 * (notes/radiosity.md, "Objects that take in little"). And from the second
 * round a link whose source element's open leaves send values spread by
 * more than SOURCE_SHARE of the receiver's eps (power x (B_max - B_min) /
 * B_s) splits the source first (rad_hier_rounds.c source_uneven): the link
 * reads the source's mean, while its receiver may see mostly one part of it
 * (bunny.json's bunny, its underside over the floor in its shadow, +3.0 %
 * without it; notes/radiosity.md, "Sources that vary"), or a near pair's
 * over SOURCE_REL of r's own power ("Slivers and sources seen close").
 * Rounds: link with the emission, solve, re-link with the solved radiosity
 * (what was kept is re-tested, all three tests), solve again, twice.
 *
 * Light near occluders. A link held at an element r gives all of r the
 * visibility its shadow rays found from r's fixed points (its children's
 * centroids). Where r reaches up to an occluder (the floor beside
 * Cornell's short block), the part of r close to it sees less of a far
 * source than those points do, yet all 4 rays pass, and the link carries
 * too little power for the partial-visibility split: the floor in the
 * block's shadow came out 26 % (up to 46 %) brighter than a final gather
 * of the same solution (test_hier test_near_occluders), and the hybrid's
 * error against secondary rays floors at 0.035 there. The split tests
 * compare with eps, a share of the emitted power, under which the power
 * such dark places receive lies. radiosity.relative_tolerance (off by
 * default) lowers the receiver-first tests' threshold to that share of the
 * receiver's own power, A_r B_r (receiver_eps, from the second round, once
 * B is known), and adds a fourth: a link goes to r's children while some
 * of r's leaves met a surface within OCCL_NEAR root radii with their
 * closedness rays and others did not (hel.olo, ohi), by as much of its
 * power as that spread carries. At 0.02 the floor is 4.7 % off on average.
 * What was left were the last units beside the contact, under min_area:
 * there a leaf whose closedness rays meet a surface within its own radius
 * (3 of 16: hel.touch) may split down to min_area / 16 for the uneven
 * test (contact_splittable). Cornell's hybrid error 0.034 -> 0.018 at 0.05
 * (cornell.json's); not the default, as in a furnished room nearly every
 * surface is dark by that measure (room.json: 12x the time; notes).
 *
 * Receiving leaf clusters. A receiver is an element, so every root gets
 * links from a frontier of sources covering the scene, about 200 per root
 * of a scanned mesh's triangles: a room of a million small triangles needs
 * more links than fit (the link cap). A cluster all of whose roots are too
 * small to split, within a radius of receiving_clusters x sqrt(min_area),
 * receives as one instead (rad__hier_mark_rlc; radiosity.receiving_clusters,
 * automatic by default: on where those roots number more than half the
 * cap over RLC_AUTO_LINKS, or where the first walk does not fit without
 * them). Its links are refined as a cluster end's: closer than admissible,
 * or carrying more than eps, the larger end splits (the receiver into its
 * children, which may receive as clusters again, down to the roots, which
 * are elements), but a near link carrying under RLC_NEAR_SHARE eps is kept,
 * that estimate its power for every later test (the partial-visibility
 * split, relink, regeo: split again by each relink, such links made a fifth
 * of the bunny rooms' links).
 * A link is evaluated at 4 points of roots that face the source (drawn by
 * the area they show it): the irradiance vector there (the contour
 * integral's vector form for an element or a near cluster, an admissible
 * cluster's cluster_vec once at the receiver's area centroid; its size per
 * unit of the source, its direction kept in hlink.dF) and a shadow ray to
 * the source. Each root under the cluster reads the links of every
 * receiving ancestor by direction bucket and its openness (rad_hier_rlc.c):
 * linear in the sources, so the ledger balances. On the bunny rooms the
 * bunnies' light comes out closer to the light tracer than with element
 * receivers (27 bunnies: within 3.8 % against 8.0 %), with a fifth of the
 * links; the 1M-triangle room completes (notes: "Receiving leaf clusters").
 *
 * Decide, then estimate. The partial-visibility split reads a link's own
 * shadow rays, so the links it keeps are those whose rays came out all
 * passing or all blocked: kept with those rays, their visibility leans
 * towards 0 or 1 (a link seen 70 % is kept at 1 with probability 0.7^4 and
 * split otherwise), and a room that is a closed furnace (every surface
 * E = 0.5, rho = 0.5, so B = 1 everywhere) came out 2.6 % dark on average.
 * Once the refinement has settled, the links' visibility is drawn again
 * (rad__hier_estimate, by the seed), and the last solve reads those: -1.4 %.
 * The refinement's rays and the burial probes do not read the seed, so the
 * tree is the scene's own (by the seed, a quarter of Cornell's back-wall
 * leaves differed between two seeds). The estimate takes far element links'
 * visibility between flat surfaces exactly (rad_vis.c), and casts 1 to 8 rays
 * a point on the others by power: all those leaves within 0.5 % (82 % before).
 * The split tests read nothing else of the rays: the uneven test reads the
 * factor's spread without visibility, the power test the power without it.
 * So a link that the partial test never found carrying VIS_SHARE eps
 * without visibility when it kept it was kept whatever its rays said, and
 * its draw is unbiased as it is: the estimate leaves it (LINK_READ, marked
 * by the tests that read the rays; 68 % of room.json's links; notes/radiosity.md,
 * "The estimate's redraw").
 *
 * Transport of a link, per channel (w the unit direction from r to s, V the
 * visibility by 4 shadow rays, q = 1 / (d^2 + A / pi) the disc formula that
 * saturates for near nodes, A the area a node shows r):
 *   element <- element: F = mean over points x of r (near pairs: a 7-point
 *                       rule of degree 5, or 28 points, rad_hier_link.c; 4
 *                       otherwise) of F_point(x, s clipped to r's front),
 *                       Lambert's contour integral, times V (4 rays: one per
 *                       point when 4 points, their pass share for near pairs);
 *                       H_r += F B_s
 *   element <- cluster: H_r += g P_s, g = V_p sum_n q_n cos_r,n I_n / P_s
 *                       over s's nodes n three levels down and further
 *                       where they are wide for their distance or cross
 *                       r's plane (rad_hier_cluster.c), each at the
 *                       centroid of its power (I_n its intensity towards r,
 *                       P_s the power of s; q_n = 1 / d^2 for a cluster
 *                       node, the disc formula for an element): the lamp
 *                       of a cluster that also holds the ceiling around it
 *                       is read where it is.
 * Shape. A link at an interior receiver gave all of its leaves its mean
 * factor: along a concave edge a leaf took its ancestors' mean of the far
 * sources, too much at the edge and too little inside (an empty furnace
 * cube without the row-sum scale: +8 % along its edges, -2 % inside), and
 * Cornell's walls came out in steps. The factor is known at points in each
 * of the receiver's four children (a near pair's 28 points, 7 in each, or
 * the 4 fixed points, the children's centroids, as far pairs and the
 * 7-point rule read it; for a cluster source
 * its whole-cluster term at those points), so a link keeps the linear field
 * (in barycentrics, without visibility) that meets the corner children's
 * means (hlink.sh, set_shape), the gather sums each receiver's fields at its
 * corners (hel.Hc), and the push-down carries the field to every level
 * below, interpolated at the children's corners; a leaf takes its mean.
 * Cornell at 128 px against 2048 spp: radiosity display block median / p90
 * 2.6 / 12.0 % -> 1.6 / 7.4 %, hybrid 2.0 / 8.6 % -> 1.1 / 4.8 % (a share
 * per child at one level only: 1.7 / 8.2 % and 1.2 / 5.2 %).
 * Interior nodes shoot the area mean of their leaves' current B (src): read
 * from the B they had when split, links from split elements never refined.
 * A cluster's shadow rays end on its surfaces, 3 drawn by the power they
 * send r (V_p, for the transport) and one by the area it shows r (V_a, for
 * the row sums, B = 1, which read g_a, the same sum by area): one visibility
 * for both lost a third of a room's lamp light (the ceiling above the lamp,
 * hidden by it, took the area-drawn rays) or, by power alone, scaled every
 * leaf down 10 % (the row sums counted that hidden ceiling). The kept links'
 * geometry is read again for the solved sources before each re-linking.
 * The shadow rays start at fixed points of the receiver and end at points
 * drawn from the link's own stream rr_rng_make(key, (r << 32) | s), the key
 * 0 while refining and the seed's in the estimate.
 *
 * Buried parts (rad.h; the flat pass's rule, rad__ff_buried). Where a
 * closed box stands on a surface, or a panel is mounted a hair in front of
 * it, the part under the cover can neither be lit nor seen. Every element is
 * probed once (el_probe): which of its 4 fixed points are buried, and its
 * open share from 16 rays. A receiver gathers at its open points only; a
 * shadow ray that ends on a buried part of a source does not pass, but the
 * partial-visibility split reads only the rays that end in the open (a
 * cover's shadow does not move with the receiver: re-drawn for the
 * receiver's children, it kept mostly the links whose rays missed it, and a
 * window pane under its glazing bars sent +7 %). Leaves whose buried share
 * carries more than eps of power split, and so do receivers whose fixed
 * points are all buried though part of them is open. The leaves' patch areas
 * are their open parts' (the ledger, the vertex means), as in the flat pass.
 * Both sides of a thin gap are buried too (rad_hier_bury.c gap_of); leaf
 * clusters' roots receive by their open areas (notes/radiosity.md, "Thin gaps").
 * Known gap: a face lying against a one-sided wall (a shelf's back panel on
 * the back wall) counts as open, since its probes leave into the void behind
 * the wall; it gathers nothing and is never seen, but its area is in the
 * ledger. (A face flush with another's front, a book on a board on the floor,
 * is caught: the two-sided walk gives such ties to the box, rt.h.)
 *
 * Solving (rad_hier_solve.c): Jacobi sweeps of gather (every link,
 * receivers in parallel, each receiver's links in one fixed order) and push-pull (irradiance down to the
 * leaves, B = E + rho k H there, radiosity back up as area means, power up
 * the clusters) until the largest change is under the solver tolerance;
 * where the largest change decays steadily over two sweeps, the slowest
 * error modes are extrapolated away (B_n + q / (1 - q) (B_n - B_{n-2})).
 *
 * Columns. What the links deliver of a leaf's light (its column sum, per
 * unit of what it sends) is exact in total (column_sums; the ledger reads
 * the same), but mixed levels of the trees make it differ from what rays
 * from the leaf say lands (hel.land, its 16 closedness rays), by a fraction
 * of a percent. Where nearly all the light lands (CS_OPEN), every leaf's
 * source is scaled by one factor per channel (hctx.cs) so that the links
 * deliver in total what the rays say; elsewhere 16 rays per leaf estimate
 * the landing share too loosely and nothing is scaled.
 *
 * Row sums. A leaf's share of the hemisphere that its links cover, sigma, is
 * what a gather of B = 1 everywhere gives it. Where the 16 cosine-distributed
 * rays of every leaf of the leaf's root all land on fronts of surfaces, the
 * leaf sees a closed part of the scene, whose true share is 1: k = 1 / sigma
 * there (so a closed furnace is exact; a leaf's own 16 rays passed at a
 * 3.6 % opening half the time, and scaled it up by 1 / 0.964), k = 1
 * elsewhere, and where any link of the leaf (or of
 * its ancestors) is partly visible: there sigma's error is the few shadow
 * rays' noise (9 % RMS per leaf in room.json), and 1 / sigma of noise is
 * biased (its walls +5 %).
 *
 * Mirrors: ways. Light from s that reaches r by way of planar mirrors is
 * what r's image in them gets from s straight (reflections are isometries):
 * a link of way w (hlink flags; hctx.img[w - 1], a chain of up to
 * render.max_depth mirrors, each able to see the next) reads its receiver
 * reflected (rview: corners, centre, normal) in every test and factor above,
 * times the mirrors' mean reflectances, and its shadow rays are folded at
 * the mirrors (rt_lights_via_mirrors: each leg must meet its mirror's
 * triangles first, the last reach s). The first walk runs once straight and
 * once per way; a way's walk is culled where its mirrors cannot pass light
 * between the two nodes (rad__hier_way_culled). The gather and the solve
 * read ways as any link. Row sums (B = 1) weigh each surface by 1 - its
 * mirror reflectance (node_uarea): what a mirror reflects arrives again by
 * its ways. A scene with a curved mirror takes the flat method
 * (rad__pass_method), whose form-factor rays follow mirrors of any shape.
 *
 * Files: this one builds and refines the hierarchy and runs the rounds;
 * rad_hier_rounds.c evaluates the links and re-tests them (settle, estimate,
 * relink); rad_hier_bury.c probes the elements for buried parts and leaf data;
 * rad_hier_link.c evaluates links between elements;
 * rad_hier_cluster.c builds the clusters and evaluates links from them;
 * rad_hier_mirror.c makes the ways and culls their walks;
 * rad_hier_solve.c solves on the hierarchy and writes the solution out
 * (rad_hier_ctx.h, their shared types); rad_leaves.c turns the final tree
 * into the leaves' patch set.
 *
 * Determinism: refinement is serial; links are evaluated in parallel, each
 * from its own stream; sums run in a fixed order. The same result for any
 * thread count, bit for bit.
 */
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"
#include "rad_hier_internal.h"
#include "rad_pass_internal.h"
#include "rad_ff_internal.h"
#include "rad_solve_internal.h"

#define MAX_ROUNDS 3
#define REGEO_SHARE 0.0625 /* later rounds read again the geometry of cluster links carrying this share of eps */
/* The rounds' solves only guide the refinement: 1e-3 instead of 1e-4 left
 * Cornell's display and room.json's images the same (relMSE against
 * secondary rays within its standard error) and saved 0.23 s of
 * room.json's 1.94 s of solves (notes/radiosity.md, "The pass's
 * arithmetic"). */
#define ROUND_TOL 1e-3
#define ADMISSIBLE 1.5        /* cluster links need centres this many radii sums apart */
#define ADMISSIBLE_CURVED 2.0 /* where a cluster end has a curved bucket (admissible()) */

/* ---- the hierarchy ---- */


static uint32_t el_add(hctx *c, const rr_vec3 v[3], uint32_t root, uint32_t depth)
{
    if (c->nel == c->capel) {
        size_t cap = c->capel ? 2 * c->capel : 1024;
        hel *n = cap < UINT32_MAX / 2 ? realloc(c->el, cap * sizeof *n) : NULL;
        if (!n) {
            c->nomem = 1;
            return NONE;
        }
        c->el = n;
        c->capel = cap;
    }
    hel *e = &c->el[c->nel];
    memset(e, 0, sizeof *e);
    memcpy(e->c, v, sizeof e->c);
    e->ctr = rr_v3_scale(rr_v3_add(v[0], rr_v3_add(v[1], v[2])), 1.0 / 3.0);
    for (int k = 0; k < 3; k++)
        e->radius = rr_max(e->radius, rr_v3_len(rr_v3_sub(v[k], e->ctr)));
    e->area = ldexp(c->R->p[root].area, -2 * (int)depth);
    e->root = root;
    e->child = NONE;
    e->depth = depth;
    e->fresh = 1;
    e->open = 1.0;
    e->k = 1.0;
    return (uint32_t)c->nel++;
}

/* Element x's four children (made once); 0, or -1 when out of memory. */
int rad__hier_el_split(hctx *c, uint32_t x)
{
    if (c->el[x].child != NONE)
        return 0;
    rr_vec3 A = c->el[x].c[0], B = c->el[x].c[1], C = c->el[x].c[2];
    rr_vec3 ab = rr_v3_scale(rr_v3_add(A, B), 0.5), bc = rr_v3_scale(rr_v3_add(B, C), 0.5),
            ca = rr_v3_scale(rr_v3_add(C, A), 0.5);
    const rr_vec3 ch[4][3] = {{A, ab, ca}, {ab, B, bc}, {ca, bc, C}, {bc, ca, ab}};
    uint32_t first = NONE;
    for (int k = 0; k < 4; k++) {
        uint32_t e = el_add(c, ch[k], c->el[x].root, c->el[x].depth + 1);
        if (e == NONE)
            return -1;
        if (k == 0)
            first = e;
        c->el[e].B = c->el[x].B;
        c->el[e].src = c->el[x].src;
    }
    c->el[x].child = first;
    return 0;
}

/* ---- clusters ---- */

/* ---- refinement ---- */

static double plane_side_max(const rr_vec3 *pts, int n, rr_vec3 nrm, rr_vec3 p0)
{
    double m = -INFINITY;
    for (int k = 0; k < n; k++)
        m = rr_max(m, rr_v3_dot(nrm, rr_v3_sub(pts[k], p0)));
    return m;
}

/* r and s cannot exchange light (by way w): one lies wholly behind the
 * other's plane (r read as its image by way of a mirror), or the way's
 * mirror cannot pass light between them (rad__hier_way_culled). */
static int culled(const hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    rr_vec3 pts[8];
    int n;
    if (w && rad__hier_way_culled(c, r, s, w))
        return 1;
    if (!(r & CLB)) {
        node_points(c, s, pts, &n);
        if (plane_side_max(pts, n, way_dir(c, w, el_normal(c, r)), way_point(c, w, c->el[r].ctr)) <= c->plane_tol)
            return 1;
    }
    if (!(s & CLB)) {
        node_points(c, r, pts, &n);
        for (int k = 0; w && k < n; k++)
            pts[k] = way_point(c, w, pts[k]);
        if (plane_side_max(pts, n, el_normal(c, s), c->el[s].ctr) <= c->plane_tol)
            return 1;
    }
    return 0;
}

/* An upper estimate of the form factor from r to s: a disc of s's area at
 * the centres' distance, with cosines raised by the nodes' angular size
 * (d from r's centre to s's, L its length). */
static double ff_estimate(const hctx *c, uint32_t r, uint32_t s, unsigned w, rr_vec3 d, double L)
{
    double As = node_area(c, s);
    double spread = L > 0 ? (node_radius(c, r) + node_radius(c, s)) / L : 1.0;
    double cr = 1.0, cs = 1.0;
    if (!(r & CLB) && L > 0)
        cr = rr_min(1.0, rr_max(0.0, rr_v3_dot(way_dir(c, w, el_normal(c, r)), d) / L) + spread);
    if (!(s & CLB) && L > 0)
        cs = rr_min(1.0, rr_max(0.0, -rr_v3_dot(el_normal(c, s), d) / L) + spread);
    return As * cr * cs / (RR_PI * L * L + As);
}

/* How far apart (in sums of radii) the centres of r and s must be for a
 * link between them with a cluster end: ADMISSIBLE, or ADMISSIBLE_CURVED
 * where a cluster end has a curved bucket (its buckets' intensity is then
 * approximate, the shortfall put back by rule). */
static double admissible(const hctx *c, uint32_t r, uint32_t s)
{
    int curved = ((r & CLB) && !cl_flat(&c->cl[CL(r)])) || ((s & CLB) && !cl_flat(&c->cl[CL(s)]));
    return curved ? ADMISSIBLE_CURVED : ADMISSIBLE;
}

/* The same estimate without the admissibility: what a link between nodes
 * close for their size carries at most, about (the disc's saturation keeps
 * it finite). */
static double near_power(const hctx *c, uint32_t r, uint32_t s)
{
    rr_vec3 d = rr_v3_sub(node_ctr(c, s), node_ctr(c, r));
    return node_rho(c, r) * node_area(c, r) * ff_estimate(c, r, s, 0, d, rr_v3_len(d)) * node_B(c, s);
}

#define RLC_NEAR_SHARE 0.125 /* a receiving leaf cluster keeps a link closer than admissible under this share of eps */

/* r and s, centres L apart, may be linked as they are: no cluster end, or
 * far enough for their sizes. */
static int far_enough(const hctx *c, uint32_t r, uint32_t s, double L)
{
    return !((r & CLB) || (s & CLB)) || L >= admissible(c, r, s) * (node_radius(c, r) + node_radius(c, s));
}

int rad__hier_admissible(const hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    return far_enough(c, r, s, rr_v3_len(rr_v3_sub(node_ctr(c, s), way_point(c, w, node_ctr(c, r)))));
}

double rad__hier_link_power(const hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    /* A cluster link reads directions and distances at the centres: only
     * between nodes well apart for their size (admissible, as in the fast
     * multipole method) is that accurate whatever power it carries. */
    rr_vec3 d = rr_v3_sub(node_ctr(c, s), way_point(c, w, node_ctr(c, r)));
    double L = rr_v3_len(d);
    if (!far_enough(c, r, s, L)) {
        /* a receiving leaf cluster takes a near link that carries little as
         * it is, read at its points (rad__hier_eval_rlc): its near estimate
         * is then its power for every test, the rounds' and relink's too */
        if (is_rlc(c, r) && !w) {
            double q = near_power(c, r, s);
            if (q <= RLC_NEAR_SHARE * c->eps)
                return q;
        }
        return INFINITY;
    }
    return node_rho(c, r) * node_area(c, r) * ff_estimate(c, r, s, w, d, L) * node_B(c, s) * way_rho(c, w);
}

void rad__hier_link_add(hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    if (c->nln == c->capln) {
        size_t cap = c->capln ? 2 * c->capln : 4096;
        hlink *n = realloc(c->ln, cap * sizeof *n);
        if (!n) {
            c->nomem = 1;
            return;
        }
        c->ln = n;
        c->capln = cap;
    }
    hlink *l = &c->ln[c->nln++];
    memset(l, 0, sizeof *l);
    l->r = r;
    l->s = s;
    l->flags = (unsigned char)(w << 1);
    l->f = NAN; /* evaluated later (eval_link) */
}

double rad__hier_bytes(double links, double elements, double clusters)
{
    return links * (double)sizeof(hlink) +
           elements * ((double)sizeof(hel) + (double)sizeof(rr_rgb) + (double)sizeof(size_t) + 0.75 * RAD_PATCH_BYTES) +
           clusters * ((double)sizeof(hcl) + (double)sizeof(hcf) + (double)sizeof(rr_rgb) + (double)sizeof(hroot));
}

/* Whether the links have reached radiosity.max_links or the pass's bytes
 * (receiving clusters' tables included) BYTES_HEADROOM of max_bytes
 * (--max-memory's share: then by_memory is set, for the messages). The
 * headroom is for the splits under way at the cap, which still link their
 * children as admissibility needs: Cornell and room.json went up to 8 % past
 * a cap at max_bytes itself, Cornell with its relative tests 11 % past one at
 * 0.9 of it (6 MiB: 6.31 MB held). */
#define BYTES_HEADROOM 0.85
int rad__hier_past_cap(hctx *c)
{
    if (c->nln >= c->max_links)
        return 1;
    double held = rad__hier_bytes((double)c->nln, (double)c->nel, (double)c->ncl) + c->rlc_bytes;
    if (c->max_bytes > 0 && held >= BYTES_HEADROOM * c->max_bytes) {
        c->by_memory = 1;
        return 1;
    }
    return 0;
}

static void refine(hctx *c, uint32_t r, uint32_t s, unsigned w);

#define RLC_AUTO_LINKS 200.0 /* links a root too small to split takes as an element receiver, about */

/* Splits r or s (the larger that can be split, or r first when receiver) and
 * refines the children's links; 0 when neither can be split. A shadow's edge
 * lies on the receiver: splitting the source there only shrinks the link's
 * power until it passes, leaving the shadow as coarse as the receiver.
 * receiver 2: the uneven test's, for which a leaf at a contact may go below
 * min_area (contact_splittable); 3: s first (what s sends varies over it:
 * rad_hier_rounds.c source_uneven), r when s cannot be split. */
int rad__hier_split_link(hctx *c, uint32_t r, uint32_t s, int receiver, unsigned w)
{
    int rl = is_rlc(c, r) && !w; /* a receiving leaf cluster: the larger end splits */
    int sr = splittable(c, r) || (receiver == 2 && contact_splittable(c, r)), ss = splittable(c, s);
    if (!sr && !ss)
        return 0;
    int side = receiver == 3 ? ss : receiver && sr && !rl ? 0 : (sr && ss ? node_radius(c, s) > node_radius(c, r) : ss);
    if ((r & CLB) && !rl)
        side = 0; /* receivers are elements (or receiving leaf clusters) */
    uint32_t x = side ? s : r;
    uint32_t kids[4];
    int nk;
    if (x & CLB) {
        kids[0] = c->cl[CL(x)].child[0];
        kids[1] = c->cl[CL(x)].child[1];
        nk = 2;
    } else {
        if (rad__hier_el_split(c, x) != 0)
            return 1;
        for (int k = 0; k < 4; k++)
            kids[k] = c->el[x].child + (uint32_t)k;
        nk = 4;
    }
    for (int k = 0; k < nk && !c->nomem; k++) {
        if (side)
            refine(c, r, kids[k], w);
        else
            refine(c, kids[k], s, w);
    }
    return 1;
}

static void refine(hctx *c, uint32_t r, uint32_t s, unsigned w)
{
    if (c->nomem || c->over || interrupted(c))
        return; /* over: the first walk is started again coarser (first_refine) */
    if (r == s && !w) { /* (by way of a mirror a node may see its own image) */
        if (!(r & CLB))
            return; /* a planar element does not see itself */
        uint32_t a = c->cl[CL(r)].child[0], b = c->cl[CL(r)].child[1];
        refine(c, a, a, 0);
        refine(c, a, b, 0);
        refine(c, b, a, 0);
        refine(c, b, b, 0);
        return;
    }
    if (culled(c, r, s, w))
        return;
    if ((r & CLB) && !(is_rlc(c, r) && !w)) { /* receivers are elements: a cluster passes the link to its children */
        refine(c, c->cl[CL(r)].child[0], s, w);
        refine(c, c->cl[CL(r)].child[1], s, w);
        return;
    }
    /* A cluster end closer than admissible is split whatever the cap: its
     * geometry, read at power centroids, is not a bound there (the 1M room's
     * links past radiosity.max_links held form factors up to 3300, and its
     * solve diverged). The cap stops only the refinement for accuracy; the
     * first walk stops at it (first_refine). */
    int past = rad__hier_past_cap(c);
    if (c->first && past) {
        c->over = 1; /* a link, or a split, past the cap */
        return;
    }
    double p = rad__hier_link_power(c, r, s, w); /* INFINITY where not admissible (but near links kept) */
    double le = link_eps(c, r);
    if (past && p > le)
        c->capped = 1;
    if ((isinf(p) || (p > le && !past)) && rad__hier_split_link(c, r, s, 0, w))
        return;
    rad__hier_link_add(c, r, s, w);
}

/* The walk's links and the elements it split given back, before it is
 * started again (not kept resident for the next try). */
static void unwalk(hctx *c)
{
    size_t nroots = c->R->n;
    free(c->ln);
    c->ln = NULL;
    c->nln = c->capln = 0;
    c->nel = nroots;
    hel *el = realloc(c->el, nroots * sizeof *el);
    if (el) {
        c->el = el;
        c->capel = nroots;
    }
    for (size_t i = 0; i < nroots; i++)
        c->el[i].child = NONE;
}

/* The first round's walk from the top cluster. Where it would pass
 * radiosity.max_links, it is tried once at its coarsest (eps at the emitted
 * power: no refinement for accuracy, only the links that admissibility
 * needs), and the pass stops with an error where even that does not fit;
 * else it is started again with eps 4 times larger at a time until it fits:
 * the cap coarsens the solution evenly, or says that it cannot. Stopped
 * where it reached the cap instead, the walk refined the first clusters in
 * its order fully and left the rest unlinked (a lamp cube's floor black at
 * 30000 links; notes/radiosity.md). The 1M-triangle room's error came after
 * 205 s of walks stepping 4x at a time; the coarsest first makes it two. */
static rr_status first_refine(hctx *c, double power, rr_error *err)
{
    double asked = c->eps;
    int coarsest_fits = 0;
    for (;;) {
        c->first_new = 0;
        c->capped = c->over = 0;
        c->first = 1;
        for (unsigned w = 0; w <= c->nimg; w++) /* straight, then by way of each mirror */
            refine(c, c->top, c->top, w);
        c->first = 0;
        if (c->nomem || interrupted(c))
            return RR_OK;
        if (c->over && c->eps >= power && c->rlc_auto) {
            /* even the coarsest does not fit: roots too small to split
             * receive as clusters (radiosity.receiving_clusters, automatic),
             * and the walk starts again at its coarsest */
            c->rlc_auto = 0;
            if (rad__hier_mark_rlc(c, c->rlc_radius) != 0)
                return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", c->s->path);
            if (c->rlc) {
                c->by_memory = 0;
                unwalk(c);
                continue;
            }
        }
        if (!c->over) {
            if (coarsest_fits || c->eps < power || asked * 4.0 >= power)
                return RR_OK;
            coarsest_fits = 1; /* the coarsest fits: back to 4x what was asked */
            c->eps = asked * 4.0;
        } else if (c->eps >= power && c->by_memory) {
            char b[32];
            return rr_error_set(err, RR_ERR_INVALID, /* a setting that cannot be met: exit 2 */
                                "%s: radiosity: the hierarchical method needs more than the %s that --max-memory "
                                "leaves it for this scene's %zu surfaces, even at its coarsest; raise --max-memory "
                                "or use radiosity.method \"flat\"",
                                c->s->path, rr_size_text(c->max_bytes, b, sizeof b), c->R->n);
        } else if (c->eps >= power) {
            return rr_error_set(err, RR_ERR_INVALID, /* a setting that cannot be met: exit 2 */
                                "%s: radiosity: the hierarchical method needs more than %zu links for this scene's "
                                "%zu surfaces even at its coarsest; raise radiosity.max_links (%zu bytes each) or "
                                "use radiosity.method \"flat\"",
                                c->s->path, c->max_links, c->R->n, sizeof(hlink));
        } else {
            c->eps = coarsest_fits ? fmin(power, c->eps * 4.0) : power;
        }
        unwalk(c);
    }
}

static double emitted_power(const hctx *c)
{
    double P = 0.0;
    for (size_t i = 0; i < c->R->n; i++)
        P += rr_rgb_max(c->el[i].E) * c->el[i].area * c->el[i].open;
    return P;
}

static rr_status hier_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, rad_solution *sol, rr_error *err);

/* Seconds since *mark, which moves to now. */
static double lap(double *mark)
{
    double t = rr_now_seconds(), d = t - *mark;
    *mark = t;
    return d;
}

/* rad__hier_solve, its time added to *seconds. */
static rr_status timed_solve(hctx *c, const rad_solve_opts *so, rad_solution *sol, double *seconds, rr_error *err)
{
    double t = rr_now_seconds();
    rr_status st = rad__hier_solve(c, so, &sol->stats, err);
    *seconds += rr_now_seconds() - t;
    return st;
}

rr_status rad__hier_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, rad_solution *sol, rr_error *err)
{
    /* ff.threads for every parallel region of the pass (0: OpenMP's default);
     * the result is the same for any count. */
    int before = omp_get_max_threads();
    if (o->ff.threads > 0)
        omp_set_num_threads(o->ff.threads);
    rr_status st = hier_run(s, a, o, sol, err);
    omp_set_num_threads(before);
    return st;
}

static rr_status hier_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, rad_solution *sol, rr_error *err)
{
    double t0 = rr_now_seconds(), t_solve = 0.0;
    hctx c;
    memset(&c, 0, sizeof c);
    c.cs = rr_rgb_make(1, 1, 1);
    c.s = s;
    c.a = a;
    c.seed = o->ff.seed;
    c.interrupt = o->ff.interrupt;
    c.ext = rt_scene_scale(s);
    rr_vec3 bmax = rr_v3_max(rr_v3(fabs(s->bbox_min.x), fabs(s->bbox_min.y), fabs(s->bbox_min.z)),
                             rr_v3(fabs(s->bbox_max.x), fabs(s->bbox_max.y), fabs(s->bbox_max.z)));
    double mabs = fmax(bmax.x, fmax(bmax.y, bmax.z));
    c.plane_tol = 1e-9 * ((isfinite(mabs) ? mabs : 0.0) + c.ext);
    c.min_area = rad__hier_min_area(s, o);
    c.gap = RAD_FF_BURY * sqrt(rad_pass_patch_limits(s, o).max_area); /* thin gaps (gap_of) */
    double rel = o->hier.relative > 0 ? o->hier.relative : s->radiosity.relative_tolerance;
    double tol = o->hier.tolerance > 0 ? o->hier.tolerance : s->radiosity.refine_tolerance;
    c.max_links = o->hier.max_links > 0 ? o->hier.max_links : (size_t)s->radiosity.max_links;
    c.max_bytes = o->hier.max_bytes > 0 ? o->hier.max_bytes : 0.0;
    rad_patch_opts po = rad__hier_root_limits(s, o);
    po.accel = a;
    rad_patches *roots = NULL;
    rt_lights *L = NULL;
    rr_status st = rad_patches_build(s, &po, &roots, err);
    if (st == RR_OK && (st = rad_reflectance_check(roots, o->solve.allow_rho_ge_1, err)) != RR_OK) {
        rad_patches_destroy(roots);
        roots = NULL;
    }
    /* ways by mirrors: planar ones only (rad__pass_method sends scenes with a
     * curved one to the flat method), up to render.max_depth of them in turn */
    int depth = o->ff.mirror_depth > 0 ? o->ff.mirror_depth : s->settings.max_depth; /* as the flat pass's */
    int mirrors = depth >= 1 && rt_scene_mirror_kind(s) == RT_MIRRORS_PLANAR;
    if (st == RR_OK && (s->nlights || mirrors))
        st = rt_lights_build(s, a, s->settings.max_depth, &L, err);
    if (st != RR_OK) {
        rad_patches_destroy(roots);
        return st;
    }
    c.R = roots;
    c.L = rt_lights_delta_count(L) ? L : NULL;
    size_t nr = roots->n;
    c.cl = malloc((nr ? nr : 1) * sizeof *c.cl);
    c.cf = aligned_alloc(64, (nr ? nr : 1) * sizeof *c.cf); /* 256 bytes each: four whole cache lines */
    c.rt = malloc((nr ? nr : 1) * sizeof *c.rt);
    size_t dropped = 0;
    if (mirrors && rad__hier_ways(&c, L, depth, &dropped) != 0)
        c.nomem = 1;
    if (dropped)
        rr_warn(&o->warn, "%s: radiosity: %zu chains of mirrors past the first %d are left out of the hierarchical "
                          "pass: light that meets their mirrors in that order is missing (lower render.max_depth, "
                          "or use radiosity.method \"flat\")",
                s->path, dropped, WAYS_MAX);
    for (size_t i = 0; i < nr && c.cl && c.cf && !c.nomem; i++) {
        const rad_patch *p = &roots->p[i];
        rr_vec3 v[3] = {roots->verts[p->v[0]], roots->verts[p->v[1]], roots->verts[p->v[2]]};
        el_add(&c, v, (uint32_t)i, 0);
    }
    for (size_t i = 0; i < c.nel && c.rt; i++) {
        const hel *e = &c.el[i];
        c.rt[i] = (hroot){roots->p[i].normal, e->ctr, e->area, 1.0 - roots->p[i].mirror, 0.0, (int)roots->p[i].flat};
    }
    if (c.cl && !c.nomem)
        rad__hier_probe_new(&c); /* the roots' burial, which their leaf data reads */
    if (!c.cl || !c.cf || !c.rt || c.nomem || nr == 0 || interrupted(&c) || (c.top = rad__hier_clusters(&c)) == NONE) {
        free(c.img);
        free(c.cl);
        free(c.cf);
        free(c.rt);
        free(c.el);
        rt_lights_destroy(L);
        rad_patches_destroy(roots);
        return nr == 0           ? rr_error_set(err, RR_ERR_INVALID, "%s: radiosity: the scene has no surfaces", s->path)
               : interrupted(&c) ? rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (links)", s->path)
                                 : rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", s->path);
    }
    rad_solve_opts so = o->solve;
    if (!(so.tolerance > 0))
        so.tolerance = s->radiosity.tolerance > 0 ? s->radiosity.tolerance : RAD_HIER_TOLERANCE;
    if (!so.interrupt)
        so.interrupt = o->ff.interrupt;
    /* The roots' data, their radiosity E to start from, and eps. */
    rad__hier_leaves_data(&c, nr); /* the roots, all fresh leaves */
    for (size_t i = 0; i < c.nel; i++)
        c.el[i].B = c.el[i].E;
    double t_mark = rr_now_seconds();
    sol->hier_seconds.setup = t_mark - t0;
    if (st == RR_OK && interrupted(&c))
        st = rr_error_set(err, RR_ERR_INTERRUPTED, "%s: radiosity pass interrupted (links)", s->path);
    double power = st == RR_OK ? emitted_power(&c) : 0.0;
    if (st == RR_OK && !(power > 0))
        st = rr_error_set(err, RR_ERR_INVALID, "%s: radiosity: nothing emits light", s->path);
    c.eps = c.eps_asked = tol * power;
    c.power = power;
    /* Receiving leaf clusters: asked for, or (automatic) where the roots too
     * small to split are so many that their links would not fit (about 200
     * a root, measured on the bunny rooms), or the first walk does not fit
     * without them (first_refine). */
    double rcl = s->radiosity.receiving_clusters;
    c.rlc_radius = (rcl > 0 ? rcl : 1.0) * sqrt(c.min_area);
    c.rlc_auto = rcl == 0.0;
    size_t nsmall = 0;
    for (size_t i = 0; i < nr; i++)
        nsmall += !splittable(&c, (uint32_t)i);
    if (st == RR_OK && (rcl > 0 || (c.rlc_auto && (double)nsmall * RLC_AUTO_LINKS > 0.5 * (double)c.max_links))) {
        c.rlc_auto = 0;
        if (rad__hier_mark_rlc(&c, c.rlc_radius) != 0)
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", s->path);
    }
    for (int round = 0; round < MAX_ROUNDS && st == RR_OK; round++) {
        rad__hier_sources(&c, 0, 0);
        rad__hier_cl_pack(&c);
        int more = 1;
        if (round == 0) {
            st = first_refine(&c, power, err);
        } else {
            c.rel = rel; /* the receivers' B is known from the first solve on */
            if (rad__hier_object_powers(&c) != 0) {
                st = rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory", s->path);
                break;
            }
            /* every kept cluster link after the first round (its sources
             * were the lamps alone); after the second, those that carry
             * REGEO_SHARE eps: the rest moved room.json's images by less
             * than their noise, and were 0.57 s of its pass */
            rad__hier_regeo(&c, round == 1 ? 0.0 : REGEO_SHARE * c.eps);
            sol->hier_seconds.regeo += lap(&t_mark);
            more = rad__hier_relink(&c);
        }
        sol->hier_seconds.link += lap(&t_mark);
        if (!more)
            break;
        if (c.nomem)
            st = rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory for %zu links", s->path, c.nln);
        if (st == RR_OK)
            st = rad__hier_settle(&c, o->ff.progress, o->ff.progress_user, err);
        sol->hier_seconds.settle += lap(&t_mark);
        /* The rounds only guide the refinement: a loose solve (ROUND_TOL) is
         * enough there; the estimate's goes to the tolerance. */
        rad_solve_opts ro = so;
        if (so.tolerance < ROUND_TOL)
            ro.tolerance = ROUND_TOL;
        if (st == RR_OK)
            st = timed_solve(&c, &ro, sol, &t_solve, err);
        sol->refine_rounds = round + 1;
        lap(&t_mark);
    }
    if (st == RR_OK) {
        rad__hier_sources(&c, 0, 0);
        rad__hier_cl_pack(&c);
        st = rad__hier_estimate(&c, o->ff.progress, o->ff.progress_user, err);
    }
    sol->hier_seconds.estimate = lap(&t_mark);
    c.last_solve = 1;
    if (st == RR_OK)
        st = timed_solve(&c, &so, sol, &t_solve, err);
    lap(&t_mark);
    char cap[96], b[32];
    if (c.by_memory)
        snprintf(cap, sizeof cap, "%s (what --max-memory leaves the pass)", rr_size_text(c.max_bytes, b, sizeof b));
    else
        snprintf(cap, sizeof cap, "%zu links (radiosity.max_links)", c.max_links);
    if (st == RR_OK && c.eps > c.eps_asked)
        rr_warn(&o->warn, "%s: radiosity: refined to a tolerance of %g instead of %g to stay under %s: the "
                          "solution is coarser than radiosity.refine_tolerance asks",
                s->path, tol * c.eps / c.eps_asked, tol, cap);
    if (st == RR_OK && c.capped)
        rr_warn(&o->warn, "%s: radiosity: refinement stopped at %s: the solution is coarser than "
                          "radiosity.refine_tolerance asks",
                s->path, cap);
    sol->memory_bound = c.by_memory && (c.eps > c.eps_asked || c.capped);
    sol->pass_bytes = rad__hier_bytes((double)c.nln, (double)c.nel, (double)c.ncl) + c.rlc_bytes;
    sol->ff_rays = c.rays;
    sol->links = c.nln;
    sol->receiving_clusters = c.nrlc;
    sol->elements = c.nel + c.ncl;
    sol->nnz = c.nln;
    if (st == RR_OK) {
        st = rad__hier_output(&c, roots, sol, err);
        roots = NULL; /* rad__hier_output owns it */
    }
    sol->hier_seconds.output = lap(&t_mark);
    sol->hier_seconds.solve = t_solve;
    rad_patches_destroy(roots);
    rt_lights_destroy(L);
    free(c.img);
    free(c.el);
    free(c.objpow);
    free(c.cl);
    free(c.cf);
    free(c.rlc);
    free(c.rg);
    free(c.rgi);
    free(c.rt);
    free(c.rdfs);
    free(c.rpos);
    free(c.rn);
    free(c.rH);
    free(c.rf);
    free(c.ln);
    free(c.sv);
    sol->stats.used = RAD_SOLVER_ITERATIVE;
    /* the refinement (linking, estimates, output) as the form factors' time;
     * the Jacobi solves of every round as the solve's */
    sol->seconds_patches = 0.0;
    sol->seconds_solve = t_solve;
    sol->seconds_ff = rr_now_seconds() - t0 - t_solve;
    return st;
}
