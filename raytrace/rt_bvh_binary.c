/* rt_bvh_binary.c - the binary BVH builder (rt__bvh_build_binary,
 * rt_internal.h): binned surface area heuristic (16 bins over the box-centre
 * bounds per axis, Wald 2007, "On fast construction of SAH-based BVHs"),
 * leaves of at most 8 items (nodes of at most leaf_items items are leaves
 * whatever SAH says, unless their box is large: RT_BIG_NODE), nodes in one
 * array in depth-first order (left child next, right child at `index`). The
 * scene BVH collapses the tree into wide nodes (rt_bvh.c); the solids' mesh
 * leaves walk it as it is (rt_solid_mesh.c). The top of the tree (nodes of RT_BUILD_TASK_MIN items
 * and more) is built as OpenMP tasks, the subtrees below it by a parallel
 * loop, each written where the serial build puts it: the same nodes for any
 * thread count.
 *
 * The build reads 32-byte references (rt_bref: the item's box as floats
 * rounded outward, and its number), 4 floats per corner so that a box union
 * is two SIMD operations; items are binned by the centre of that box (lo +
 * hi, unhalved). A node's bounds are the union of its references' boxes,
 * which is the outward rounding of the union of the exact boxes (rounding
 * is monotonic): the nodes still contain their items exactly, as the
 * traversal's slab test requires. The split only has to be good, not
 * exact: the areas and bins in float change which split SAH picks in rare
 * near-ties, never what a ray hits (the walks' tie rules do not depend on
 * the order they meet the primitives in). */
#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rt_kernel.h"

#define RT_BINS 16
#define RT_LEAF_MAX 8
#define RT_STACK RT_BVH_STACK

/* ---- four floats: SSE2, or a scalar twin with the same IEEE results ---- */
#if defined(RT_SIMD) && RT_SIMD >= 1
#include <emmintrin.h>
typedef __m128 v4;
static inline v4 v4_load(const float *p) { return _mm_loadu_ps(p); }
static inline void v4_store(float *p, v4 a) { _mm_storeu_ps(p, a); }
static inline v4 v4_set1(float x) { return _mm_set1_ps(x); }
static inline v4 v4_set(float x, float y, float z, float w) { return _mm_setr_ps(x, y, z, w); }
static inline v4 v4_min(v4 a, v4 b) { return _mm_min_ps(a, b); }
static inline v4 v4_max(v4 a, v4 b) { return _mm_max_ps(a, b); }
static inline v4 v4_add(v4 a, v4 b) { return _mm_add_ps(a, b); }
static inline v4 v4_sub(v4 a, v4 b) { return _mm_sub_ps(a, b); }
static inline v4 v4_mul(v4 a, v4 b) { return _mm_mul_ps(a, b); }
/* The w lane of a reference's hi corner holds its number: zeroed before
 * arithmetic (its bits may be a denormal). */
static inline v4 v4_xyz(v4 a) { return _mm_and_ps(a, _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0))); }
/* Truncation of lanes already clamped to [0, RT_BINS - 1]. */
static inline void v4_trunc(v4 a, int k[4]) { _mm_storeu_si128((__m128i *)k, _mm_cvttps_epi32(a)); }
#else
typedef struct v4 {
    float f[4];
} v4;
static inline v4 v4_load(const float *p)
{
    v4 r;
    memcpy(r.f, p, sizeof r.f);
    return r;
}
static inline void v4_store(float *p, v4 a) { memcpy(p, a.f, sizeof a.f); }
static inline v4 v4_set(float x, float y, float z, float w) { return (v4){{x, y, z, w}}; }
static inline v4 v4_set1(float x) { return v4_set(x, x, x, x); }
#define RT_V4_OP(name, expr)                                                                                           \
    static inline v4 name(v4 a, v4 b)                                                                                  \
    {                                                                                                                  \
        v4 r;                                                                                                          \
        for (int i = 0; i < 4; i++) {                                                                                  \
            float x = a.f[i], y = b.f[i];                                                                              \
            r.f[i] = (expr);                                                                                           \
        }                                                                                                              \
        return r;                                                                                                      \
    }
RT_V4_OP(v4_min, x < y ? x : y) /* minps: the second operand unless x < y */
RT_V4_OP(v4_max, x > y ? x : y)
RT_V4_OP(v4_add, x + y)
RT_V4_OP(v4_sub, x - y)
RT_V4_OP(v4_mul, x * y)
#undef RT_V4_OP
static inline v4 v4_xyz(v4 a)
{
    a.f[3] = 0.0f;
    return a;
}
static inline void v4_trunc(v4 a, int k[4])
{
    for (int i = 0; i < 4; i++)
        k[i] = (int)a.f[i];
}
#endif

/* A box of floats in two corners (w lanes unused). */
typedef struct fbox {
    v4 lo, hi;
} fbox;

static fbox fbox_empty(void)
{
    fbox b = {v4_set1(INFINITY), v4_set1(-INFINITY)};
    return b;
}
static fbox fbox_union(fbox a, fbox b)
{
    fbox r = {v4_min(a.lo, b.lo), v4_max(a.hi, b.hi)};
    return r;
}
/* Surface area, in double from the float corners (a float product of a
 * large scene's extents could overflow). 0 for an empty box. The SSE2
 * version does the same operations in the same order (the same bits).
 * Once per node (RT_BIG_NODE); the SAH sweep uses fbox_harea_s. */
#if defined(RT_SIMD) && RT_SIMD >= 1
static inline double fbox_area(fbox b)
{
    __m128d d01 = _mm_sub_pd(_mm_cvtps_pd(b.hi), _mm_cvtps_pd(b.lo));
    __m128d d23 = _mm_sub_pd(_mm_cvtps_pd(_mm_movehl_ps(b.hi, b.hi)), _mm_cvtps_pd(_mm_movehl_ps(b.lo, b.lo)));
    __m128d zero = _mm_setzero_pd();
    if ((_mm_movemask_pd(_mm_cmplt_pd(d01, zero)) | (_mm_movemask_pd(_mm_cmplt_pd(d23, zero)) & 1)) != 0)
        return 0.0;
    /* (dx dy, dy dz) from d01 (dx, dy) times (dy, dz). */
    __m128d p = _mm_mul_pd(d01, _mm_shuffle_pd(d01, d23, 1));
    double dx = _mm_cvtsd_f64(d01), dz = _mm_cvtsd_f64(d23);
    return 2.0 * ((_mm_cvtsd_f64(p) + _mm_cvtsd_f64(_mm_unpackhi_pd(p, p))) + dz * dx);
}
#else
static double fbox_area(fbox b)
{
    float lo[4], hi[4];
    v4_store(lo, b.lo);
    v4_store(hi, b.hi);
    double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    if (dx < 0 || dy < 0 || dz < 0)
        return 0.0;
    return 2.0 * (dx * dy + dy * dz + dz * dx);
}
#endif

/* The SAH sweep's areas, in float: dx dy + dy dz + dz dx of a non-empty
 * box scaled by s (per node: 1 / its largest extent, so that the products
 * stay in float's range for any scene's coordinates), half the surface
 * area of the scaled box, which is all a cost ratio needs; the sum in the
 * order ((xy + zx) + yz) in both versions. The w lanes are masked before
 * the subtraction: a hi corner's w holds a reference's number, mostly a
 * denormal as a float, and arithmetic on denormals took this CPU's slow
 * path (the build 25 % slower than with double areas, until masked). The
 * sweep in double was a fifth of the build (notes/performance.md). */
#if defined(RT_SIMD) && RT_SIMD >= 1
static inline float fbox_harea_s(fbox b, v4 s)
{
    __m128 d = _mm_mul_ps(_mm_sub_ps(v4_xyz(b.hi), v4_xyz(b.lo)), s);
    __m128 p = _mm_mul_ps(d, _mm_shuffle_ps(d, d, _MM_SHUFFLE(3, 0, 2, 1))); /* (xy, yz, zx, -) */
    __m128 q = _mm_add_ss(p, _mm_movehl_ps(p, p));
    return _mm_cvtss_f32(_mm_add_ss(q, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1))));
}
#else
static inline float fbox_harea_s(fbox b, v4 s)
{
    v4 d = v4_mul(v4_sub(b.hi, b.lo), s);
    float xy = d.f[0] * d.f[1], yz = d.f[1] * d.f[2], zx = d.f[2] * d.f[0];
    return (xy + zx) + yz;
}
#endif

/* The scale for fbox_harea_s of the boxes inside box b: 1 / its largest
 * extent, at most 1e30 (1 for a box of no extent, whose sub-boxes' areas
 * are all 0). */
static inline v4 harea_scale(fbox b)
{
    float lo[4], hi[4];
    v4_store(lo, b.lo);
    v4_store(hi, b.hi);
    double e = 0.0;
    for (int a = 0; a < 3; a++)
        e = (double)hi[a] - lo[a] > e ? (double)hi[a] - lo[a] : e;
    float sc = e > 0.0 ? (float)(e > 1e-30 ? 1.0 / e : 1e30) : 1.0f;
    return v4_set(sc, sc, sc, 0.0f);
}

static inline fbox ref_box(const rt_bref *r)
{
    fbox b = {v4_load(r->lo), v4_load(r->hi)};
    return b;
}
/* lo + hi: twice the box's centre, the point an item is binned by. */
static inline v4 ref_c2(fbox b) { return v4_add(v4_xyz(b.lo), v4_xyz(b.hi)); }

/* The nodes go into one array of 2 n - 1 (a binary tree whose leaves hold
 * at least one item each has at most that many), allocated once: a subtree
 * of c items owns the 2 c - 1 slots from its root, so the two subtrees of a
 * task-built node are written in place side by side (the left one's from
 * the node's slot + 1, the right one's from + 2 c_left), and only one
 * compaction into depth-first order follows. The pages the slack never
 * touches are never mapped. (Building each task's subtree into an array of
 * its own and appending it to its parent's copied the nodes once per level
 * of tasks, fresh pages each time: about 4 copies of 35 MB for 1M triangles.) */
typedef struct builder {
    rt_bref *refs;
    rt_node *nodes;
    size_t next; /* the next free slot of this builder's subtree */
    size_t leaf; /* nodes of at most this many items are leaves (rt__bvh_build_binary)... */
    double big;  /* ...unless their box's area exceeds this (RT_BIG_NODE of the root's) */
} builder;

/* A node of at most `leaf` items is a leaf unless its box has more than this
 * fraction of the root box's area: such a node (a few walls of a room, each
 * as large as the scene, in one leaf whose box is the whole room) is
 * entered by a good share of all rays, and SAH decides whether to split it
 * as for any larger node. The rest (nearly all of a mesh's) are leaves
 * without binning, which is what makes leaves of one packet cheap to build
 * (notes/performance.md, "Large nodes of few items"). */
#define RT_BIG_NODE 0x1p-8

/* The bin grid of one SAH step: bin k of axis a holds the items whose
 * (c2[a] - lo[a]) * scale[a] truncates to k (clamped to the grid). An axis
 * whose centroids all coincide has scale 0 (everything in bin 0) and is not
 * split on. */
typedef struct grid {
    v4 lo, scale;
    float lo_a[4], scale_a[4];
} grid;

static inline void grid_bins(const grid *g, v4 c2, int k[4])
{
    v4 t = v4_mul(v4_sub(c2, g->lo), g->scale);
    v4_trunc(v4_min(v4_max(t, v4_set1(0.0f)), v4_set1((float)(RT_BINS - 1))), k);
}

/* Bins of one SAH step: per axis, the count and bounds of the items in each
 * bin. Only the bins in `used` (bit k: bin k holds an item) are set: a node
 * of a few items touches a few bins, and most of the build's nodes are such
 * nodes (the tree goes down to leaves of 1-2 items), so neither the set-up
 * nor the sweep walks the empty ones. */
typedef struct bins3 {
    fbox box[3][RT_BINS];
    uint32_t cnt[3][RT_BINS];
    unsigned used[3];
} bins3;

static void bin_put(bins3 *b, int axis, int k, fbox box, uint32_t n)
{
    if (b->used[axis] >> k & 1u) {
        b->cnt[axis][k] += n;
        b->box[axis][k] = fbox_union(b->box[axis][k], box);
    } else {
        b->used[axis] |= 1u << k;
        b->cnt[axis][k] = n;
        b->box[axis][k] = box;
    }
}

/* Below this many items a node sets empty only the bins its items use;
 * from it on, all of them (and bins twice, see bin_items). */
#define RT_BIN_DENSE 48

/* One item's box into a bin. */
static inline void bin_add(fbox *d, uint32_t *cnt, fbox box)
{
    d->lo = v4_min(d->lo, box.lo);
    d->hi = v4_max(d->hi, box.hi);
    (*cnt)++;
}

/* refs[0, count) into the bins of the three axes, in one pass over them. */
static void bin_items(const rt_bref *refs, size_t count, const grid *g, bins3 *b)
{
    int k[4];
    b->used[0] = b->used[1] = b->used[2] = 0;
    if (count < RT_BIN_DENSE) {
        /* The items' bins first, then only the bins they use set empty, then
         * the unions: no branch on whether a bin is in use yet (it went
         * either way at random). */
        int kk[RT_BIN_DENSE][4];
        for (size_t i = 0; i < count; i++) {
            grid_bins(g, ref_c2(ref_box(&refs[i])), kk[i]);
            for (int a = 0; a < 3; a++)
                b->used[a] |= 1u << kk[i][a];
        }
        for (int a = 0; a < 3; a++)
            for (unsigned u = b->used[a]; u; u &= u - 1) {
                int j = __builtin_ctz(u);
                b->box[a][j] = fbox_empty();
                b->cnt[a][j] = 0;
            }
        for (size_t i = 0; i < count; i++) {
            fbox box = ref_box(&refs[i]);
            for (int a = 0; a < 3; a++)
                bin_add(&b->box[a][kk[i][a]], &b->cnt[a][kk[i][a]], box);
        }
        return;
    }
    /* Even items into one set of bins, odd ones into a second, united at
     * the end (exactly: the same bins): neighbours in the array tend to
     * fall into the same bin, and one set would make each item's update
     * wait for the previous one's through memory. */
    fbox box2[3][RT_BINS];
    uint32_t cnt2[3][RT_BINS];
    for (int a = 0; a < 3; a++)
        for (int j = 0; j < RT_BINS; j++) {
            b->box[a][j] = box2[a][j] = fbox_empty();
            b->cnt[a][j] = cnt2[a][j] = 0;
        }
    size_t i = 0;
    for (; i + 1 < count; i += 2) {
        fbox x = ref_box(&refs[i]), y = ref_box(&refs[i + 1]);
        int ky[4];
        grid_bins(g, ref_c2(x), k);
        grid_bins(g, ref_c2(y), ky);
        for (int a = 0; a < 3; a++) {
            bin_add(&b->box[a][k[a]], &b->cnt[a][k[a]], x);
            bin_add(&box2[a][ky[a]], &cnt2[a][ky[a]], y);
        }
    }
    if (i < count) {
        fbox x = ref_box(&refs[i]);
        grid_bins(g, ref_c2(x), k);
        for (int a = 0; a < 3; a++)
            bin_add(&b->box[a][k[a]], &b->cnt[a][k[a]], x);
    }
    for (int a = 0; a < 3; a++)
        for (int j = 0; j < RT_BINS; j++) {
            b->box[a][j] = fbox_union(b->box[a][j], box2[a][j]);
            b->cnt[a][j] += cnt2[a][j];
            b->used[a] |= (b->cnt[a][j] != 0) << j;
        }
}

/* Chunks of items binned as tasks when the build runs in parallel (counts
 * add and boxes unite exactly: the same bins in any order). */
#define RT_BIN_CHUNK 32768
#define RT_BIN_CHUNKS_MAX 64
static void bin_all(const rt_bref *refs, size_t count, const grid *g, bins3 *out)
{
    size_t nch = count / RT_BIN_CHUNK;
    if (nch < 2 || !omp_in_parallel()) {
        bin_items(refs, count, g, out);
        return;
    }
    if (nch > RT_BIN_CHUNKS_MAX)
        nch = RT_BIN_CHUNKS_MAX;
    bins3 *part = malloc(nch * sizeof *part);
    if (!part) { /* fall back to one pass */
        bin_items(refs, count, g, out);
        return;
    }
    for (size_t c = 0; c < nch; c++) {
        size_t a = count * c / nch, e = count * (c + 1) / nch;
#pragma omp task firstprivate(a, e, c) shared(part)
        bin_items(refs + a, e - a, g, &part[c]);
    }
#pragma omp taskwait
    *out = part[0];
    for (size_t c = 1; c < nch; c++)
        for (int axis = 0; axis < 3; axis++)
            for (int k = 0; k < RT_BINS; k++)
                if (part[c].used[axis] >> k & 1u)
                    bin_put(out, axis, k, part[c].box[axis][k], part[c].cnt[axis][k]);
    free(part);
}

/* References [first, first + count) of the build, the union of their boxes
 * and the bounds of their c2 points. A node's span comes from its parent's
 * partition pass (or, at the root, one pass), so each node reads its items
 * twice: to bin them and to partition them. */
typedef struct span {
    size_t first, count;
    fbox box, cb;
} span;

/* Reference r into the bounds of a span's boxes and of its c2 points. */
static inline void span_add(fbox *box, fbox *cb, const rt_bref *r)
{
    fbox b = ref_box(r);
    v4 c = ref_c2(b);
    *box = fbox_union(*box, b);
    cb->lo = v4_min(cb->lo, c);
    cb->hi = v4_max(cb->hi, c);
}

static void span_of(const rt_bref *refs, size_t a, size_t e, span *out)
{
    out->first = a;
    out->count = e - a;
    out->box = fbox_empty();
    out->cb = fbox_empty();
    for (size_t i = a; i < e; i++)
        span_add(&out->box, &out->cb, &refs[i]);
}

/* The bins per unit of an axis whose c2 extent is ext: finite and above 0,
 * or 0 (the axis is not split on). */
static inline float axis_scale(float ext)
{
    float sc = ext > 0.0f && ext <= FLT_MAX ? (float)RT_BINS / ext : 0.0f;
    return sc <= FLT_MAX ? sc : 0.0f;
}

static void grid_of(const span *sp, grid *g)
{
    float lo[4], hi[4];
    v4_store(lo, sp->cb.lo);
    v4_store(hi, sp->cb.hi);
    for (int a = 0; a < 3; a++)
        g->scale_a[a] = axis_scale(hi[a] - lo[a]);
    g->scale_a[3] = 0.0f;
    g->lo = v4_set(lo[0], lo[1], lo[2], 0.0f);
    memcpy(g->lo_a, lo, sizeof lo);
    g->lo_a[3] = 0.0f;
    g->scale = v4_load(g->scale_a);
}

/* sah_partition for a node of two items, with the same result: each axis
 * whose two c2 differ puts them in bins 0 and RT_BINS - 1, so every such
 * axis offers the same split at the same cost, and the first one wins the
 * tie; no such axis, or a cost not below the leaf's 2: a leaf. Most inner
 * nodes of a large build are nodes of two items. */
static size_t sah_pair(rt_bref *all, const span *sp, int *axis_out, span *l, span *r)
{
    float lo[4], hi[4];
    v4_store(lo, sp->cb.lo);
    v4_store(hi, sp->cb.hi);
    int axis = 0;
    while (axis < 3 && !(axis_scale(hi[axis] - lo[axis]) > 0.0f))
        axis++;
    if (axis == 3)
        return 0;
    rt_bref *refs = all + sp->first;
    fbox a = ref_box(&refs[0]), b = ref_box(&refs[1]);
    float ca[4], cb[4];
    v4_store(ca, ref_c2(a));
    v4_store(cb, ref_c2(b));
    int swap = ca[axis] > cb[axis];
    v4 hs = harea_scale(sp->box);
    float ha = fbox_harea_s(sp->box, hs), inv_area = 1.0f / (ha > FLT_MIN ? ha : FLT_MIN);
    float cost = 1.0f + (fbox_harea_s(swap ? b : a, hs) * 1.0f + fbox_harea_s(swap ? a : b, hs) * 1.0f) * inv_area;
    if (!(cost < 2.0f))
        return 0;
    if (swap) {
        rt_bref t = refs[0];
        refs[0] = refs[1];
        refs[1] = t;
        fbox t2 = a;
        a = b;
        b = t2;
    }
    v4 c = ref_c2(a);
    *l = (span){sp->first, 1, a, {c, c}};
    c = ref_c2(b);
    *r = (span){sp->first + 1, 1, b, {c, c}};
    *axis_out = axis;
    return 1;
}

/* Partitions refs[0, count) by the split: bin >= split of axis on grid g
 * goes right. Returns the left side's count; the two sides' box and c2
 * bounds in *l and *r (their first and count set by the caller). */
static size_t partition(rt_bref *refs, size_t count, const grid *g, int best_axis, int best_split, span *l, span *r)
{
    fbox lb = fbox_empty(), lc = fbox_empty(), rb = fbox_empty(), rc = fbox_empty();
    /* Partition from both ends (Hoare): an item already on its side is not
     * moved; the two sides' bounds are gathered on the way. */
    size_t i = 0, j = count;
    /* Right of the split: bin >= best_split, which for a split in
     * [1, RT_BINS - 1] is t >= best_split for grid_bins' t (the clamps
     * and the truncation do not move t across an integer above 0), the
     * same float operations on one lane. */
    float glo = g->lo_a[best_axis], gscale = g->scale_a[best_axis], gsplit = (float)best_split;
#define RT_RIGHT(ref) (((ref)->lo[best_axis] + (ref)->hi[best_axis] - glo) * gscale >= gsplit)
    for (;;) {
        for (; i < j && !RT_RIGHT(&refs[i]); i++)
            span_add(&lb, &lc, &refs[i]);
        for (; i < j && RT_RIGHT(&refs[j - 1]); j--)
            span_add(&rb, &rc, &refs[j - 1]);
        if (i >= j)
            break;
        /* refs[i] belongs right, refs[j - 1] left: swap and take both. */
        rt_bref t = refs[i];
        refs[i] = refs[j - 1];
        refs[j - 1] = t;
        span_add(&lb, &lc, &refs[i]);
        span_add(&rb, &rc, &refs[j - 1]);
        i++;
        j--;
    }
#undef RT_RIGHT
    l->box = lb;
    l->cb = lc;
    r->box = rb;
    r->cb = rc;
    return i;
}

/* Chooses a split of the items of sp by binned SAH and partitions them;
 * returns the number put on the left (0 = make a leaf) with the two sides'
 * spans in *l and *r. A node of at most `leaf` items is a leaf when its
 * area is at most `big` (builder). */
static size_t sah_partition(rt_bref *all, const span *sp, size_t leaf, double big, int *axis_out, span *l, span *r)
{
    rt_bref *refs = all + sp->first;
    size_t count = sp->count;
    if (count <= leaf && !(fbox_area(sp->box) > big))
        return 0;
    if (count <= 2) /* one item: no axis to split on */
        return count == 2 ? sah_pair(all, sp, axis_out, l, r) : 0;
    grid g;
    grid_of(sp, &g);
    bins3 bins;
    bin_all(refs, count, &g, &bins);
    float best_cost = (float)count; /* cost of a leaf, in intersection units */
    int best_axis = -1, best_split = 0;
    v4 hs = harea_scale(sp->box);
    float ha = fbox_harea_s(sp->box, hs), inv_area = 1.0f / (ha > FLT_MIN ? ha : FLT_MIN);
    for (int axis = 0; axis < 3; axis++) {
        if (!(g.scale_a[axis] > 0.0f))
            continue;
        /* Sweep the used bins from the right, then from the left. A split
         * after an empty bin has the cost of the split before it, which
         * wins ties, so only splits right after a used bin are tried: the
         * same choice as a sweep over every bin. */
        int k_used[RT_BINS], m = 0;
        for (unsigned u = bins.used[axis]; u; u &= u - 1)
            k_used[m++] = __builtin_ctz(u);
        float right_area[RT_BINS];
        uint32_t right_cnt[RT_BINS];
        fbox acc = fbox_empty();
        uint32_t n = 0;
        for (int j = m - 1; j > 0; j--) {
            acc = fbox_union(acc, bins.box[axis][k_used[j]]);
            n += bins.cnt[axis][k_used[j]];
            right_area[j] = fbox_harea_s(acc, hs);
            right_cnt[j] = n;
        }
        acc = fbox_empty();
        n = 0;
        for (int j = 0; j + 1 < m; j++) {
            acc = fbox_union(acc, bins.box[axis][k_used[j]]);
            n += bins.cnt[axis][k_used[j]];
            /* Traversal cost 1 relative to one primitive test. */
            float cost = 1.0f + (fbox_harea_s(acc, hs) * (float)n + right_area[j + 1] * (float)right_cnt[j + 1]) * inv_area;
            if (cost < best_cost) {
                best_cost = cost;
                best_axis = axis;
                best_split = k_used[j] + 1;
            }
        }
    }
    if (best_axis < 0) {
        if (count <= RT_LEAF_MAX)
            return 0;
        /* All centroids coincide (or SAH prefers a leaf that is too big): split in the middle. */
        *axis_out = 0;
        span_of(all, sp->first, sp->first + count / 2, l);
        span_of(all, sp->first + count / 2, sp->first + count, r);
        return count / 2;
    }
    size_t i = partition(refs, count, &g, best_axis, best_split, l, r);
    l->first = sp->first;
    l->count = i;
    r->first = sp->first + i;
    r->count = count - i;
    *axis_out = best_axis;
    return i;
}

static void set_bounds(rt_node *n, fbox box)
{
    float lo[4], hi[4];
    v4_store(lo, box.lo);
    v4_store(hi, box.hi);
    memcpy(n->lo, lo, sizeof n->lo);
    memcpy(n->hi, hi, sizeof n->hi);
}

/* Node *idx (the next slot) for the items of sp: a leaf (l->count = 0), or
 * an inner node whose children get the spans *l and *r (its right child's
 * index is set by the caller). */
static void make_node(builder *b, const span *sp, int depth, size_t *idx, span *l, span *r)
{
    *idx = b->next++;
    int axis = 0;
    l->count = depth >= RT_STACK - 2 ? 0 : sah_partition(b->refs, sp, b->leaf, b->big, &axis, l, r);
    rt_node *n = &b->nodes[*idx];
    set_bounds(n, sp->box);
    if (l->count == 0 || l->count == sp->count) {
        RR_CHECK(sp->count <= UINT16_MAX);
        n->index = (uint32_t)sp->first;
        n->count = (uint16_t)sp->count;
        n->axis = 0;
        l->count = 0;
        return;
    }
    n->count = 0;
    n->axis = (uint16_t)axis;
}

static void build_rec(builder *b, const span *sp, int depth)
{
    size_t idx;
    span l, r;
    make_node(b, sp, depth, &idx, &l, &r);
    if (l.count == 0)
        return;
    build_rec(b, &l, depth + 1);
    b->nodes[idx].index = (uint32_t)b->next; /* right child follows the whole left subtree */
    build_rec(b, &r, depth + 1);
}

/* A subtree below RT_BUILD_TASK_MIN left by build_par for the loop that
 * builds them (rt__bvh_build_binary): its span, its slots, its depth. */
typedef struct subtree {
    span sp;
    builder b;
    int depth;
} subtree;
typedef struct subtrees {
    subtree *it;
    size_t n, cap;
} subtrees;

/* The top of the tree: nodes of RT_BUILD_TASK_MIN items and more, their two
 * subtrees as tasks, each in its slots (see builder: the right child's index
 * is its slot, until compact() moves it); the subtrees below that size are
 * set aside in *f. Built here as tasks, the idle thread did not take them up
 * (libgomp ran both 50 k-item halves of room-100k's tree on one thread, one
 * after the other: 2 threads built it no faster than 1). */
static void build_par(builder *b, const span *sp, int depth, subtrees *f)
{
    if (sp->count < RT_BUILD_TASK_MIN) {
        size_t k;
#pragma omp atomic capture
        k = f->n++;
        RR_CHECK(k < f->cap);
        f->it[k] = (subtree){*sp, *b, depth};
        return;
    }
    size_t idx;
    span l, r;
    make_node(b, sp, depth, &idx, &l, &r);
    if (l.count == 0)
        return;
    builder L = {b->refs, b->nodes, idx + 1, b->leaf, b->big};
    builder R = {b->refs, b->nodes, idx + 2 * l.count, b->leaf, b->big};
    b->nodes[idx].index = (uint32_t)R.next;
#pragma omp task shared(L, l) if (omp_in_parallel())
    build_par(&L, &l, depth + 1, f);
#pragma omp task shared(R, r) if (omp_in_parallel())
    build_par(&R, &r, depth + 1, f);
#pragma omp taskwait
}

static int larger_first(const void *a, const void *b)
{
    size_t x = ((const subtree *)a)->sp.count, y = ((const subtree *)b)->sp.count;
    return (x < y) - (x > y);
}

/* The tree build_par left with gaps, moved down into depth-first order in
 * place: the walk meets the nodes in rising slot order and puts each at the
 * next free place, never above its slot, so nothing unread is overwritten.
 * Returns the node count. */
static size_t compact(rt_node *nodes)
{
    size_t pending[2 * RT_STACK]; /* per open inner node: its place, then its right child's slot */
    int sp = 0;
    size_t at = 0, out = 0;
    for (;;) {
        rt_node nd = nodes[at];
        nodes[out] = nd;
        if (nd.count == 0) {
            RR_CHECK(sp + 2 <= 2 * RT_STACK);
            pending[sp++] = out;
            pending[sp++] = nd.index;
            at++;
            out++;
            continue;
        }
        out++;
        if (sp == 0)
            return out;
        at = pending[--sp];
        nodes[pending[--sp]].index = (uint32_t)out;
    }
}

void rt__bref_set(rt_bref *r, rr_vec3 lo, rr_vec3 hi, uint32_t item)
{
    r->lo[0] = rt__f_down(lo.x);
    r->lo[1] = rt__f_down(lo.y);
    r->lo[2] = rt__f_down(lo.z);
    r->lo[3] = 0.0f;
    r->hi[0] = rt__f_up(hi.x);
    r->hi[1] = rt__f_up(hi.y);
    r->hi[2] = rt__f_up(hi.z);
    memcpy(&r->hi[3], &item, sizeof item);
}

#if defined(RT_SIMD) && RT_SIMD >= 1
/* (float)x per lane of (x01, x2), stepped one ulp where the rounding went
 * below x (up != 0) or above it (up == 0): rt__f_up / rt__f_down on three
 * lanes, the same bits (the step of rt__prepare_axes). Lane 3 is 0. */
static inline __m128 round_out(__m128d x01, __m128d x2, int up)
{
    __m128 f = _mm_movelh_ps(_mm_cvtpd_ps(x01), _mm_cvtpd_ps(x2));
    __m128d f01 = _mm_cvtps_pd(f), f2 = _mm_cvtps_pd(_mm_movehl_ps(f, f));
    __m128d m01 = up ? _mm_cmplt_pd(f01, x01) : _mm_cmpgt_pd(f01, x01);
    __m128d m2 = up ? _mm_cmplt_sd(f2, x2) : _mm_cmpgt_sd(f2, x2);
    __m128i m = _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(m01), _mm_castpd_ps(m2), _MM_SHUFFLE(2, 0, 2, 0)));
    __m128i u = _mm_castps_si128(f);
    /* +1 for a float with the sign bit clear, -1 with it set: one ulp up in
     * value for up, down for !up (lane 3's 0 never steps: its compare is
     * with the 0 that _mm_load_sd put above x2). */
    __m128i dir = _mm_or_si128(_mm_srai_epi32(u, 31), _mm_set1_epi32(1));
    u = up ? _mm_add_epi32(u, _mm_and_si128(m, dir)) : _mm_sub_epi32(u, _mm_and_si128(m, dir));
    return _mm_castsi128_ps(u);
}
#endif

void rt__bref_tri(rt_bref *r, const rr_vec3 *a, const rr_vec3 *b, const rr_vec3 *c, uint32_t item)
{
#if defined(RT_SIMD) && RT_SIMD >= 1
    __m128d a01 = _mm_loadu_pd(&a->x), b01 = _mm_loadu_pd(&b->x), c01 = _mm_loadu_pd(&c->x);
    __m128d a2 = _mm_load_sd(&a->z), b2 = _mm_load_sd(&b->z), c2 = _mm_load_sd(&c->z);
    __m128 lo = round_out(_mm_min_pd(_mm_min_pd(a01, b01), c01), _mm_min_sd(_mm_min_sd(a2, b2), c2), 0);
    __m128 hi = round_out(_mm_max_pd(_mm_max_pd(a01, b01), c01), _mm_max_sd(_mm_max_sd(a2, b2), c2), 1);
    hi = _mm_or_ps(hi, _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, (int)item)));
    _mm_storeu_ps(r->lo, lo);
    _mm_storeu_ps(r->hi, hi);
#else
    rt__bref_set(r, rr_v3_min(rr_v3_min(*a, *b), *c), rr_v3_max(rr_v3_max(*a, *b), *c), item);
#endif
}

uint32_t rt__bref_item(const rt_bref *r)
{
    uint32_t item;
    memcpy(&item, &r->hi[3], sizeof item);
    return item;
}

int rt__bvh_build_binary(rt_bref *refs, size_t n, size_t leaf_items, int threads, rt_node **nodes, size_t *nnodes)
{
    int own = *nodes == NULL;
    builder b = {refs, own ? malloc((2 * n - 1) * sizeof *b.nodes) : *nodes, 0, leaf_items, 0.0};
    if (!b.nodes)
        return -1;
    if (threads <= 0)
        threads = omp_get_max_threads();
    span root;
    span_of(refs, 0, n, &root);
    b.big = fbox_area(root.box) * RT_BIG_NODE;
    size_t count;
    if (n < RT_BUILD_TASK_MIN || threads == 1) {
        build_rec(&b, &root, 0);
        count = b.next;
    } else {
        /* At most two subtrees per node of the top, and at most n /
         * RT_BUILD_TASK_MIN such nodes per level. */
        subtrees f = {NULL, 0, 2 * (n / RT_BUILD_TASK_MIN + 1) * RT_STACK};
        f.it = malloc(f.cap * sizeof *f.it);
        if (!f.it) {
            if (own)
                free(b.nodes);
            return -1;
        }
#pragma omp parallel num_threads(threads)
        {
#pragma omp single
            {
                build_par(&b, &root, 0, &f);
                qsort(f.it, f.n, sizeof *f.it, larger_first); /* for the balance only */
            }
#pragma omp for schedule(dynamic, 1)
            for (size_t i = 0; i < f.n; i++)
                build_rec(&f.it[i].b, &f.it[i].sp, f.it[i].depth);
        }
        free(f.it);
        count = compact(b.nodes);
    }
    rt_node *shrunk = own ? realloc(b.nodes, count * sizeof *b.nodes) : NULL;
    *nodes = shrunk ? shrunk : b.nodes;
    *nnodes = count;
    return 0;
}
