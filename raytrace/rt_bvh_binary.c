/* rt_bvh_binary.c - the binary BVH builder (rt__bvh_build_binary,
 * rt_internal.h): binned surface area heuristic (16 bins over the centroid
 * bounds per axis, Wald 2007, "On fast construction of SAH-based BVHs"),
 * leaves of at most 8 items, nodes in one array in depth-first order (left
 * child next, right child at `index`), bounds as floats rounded outward so a
 * node still contains its items exactly. The scene BVH collapses the tree
 * into wide nodes (rt_bvh.c); the solids' mesh leaves walk it as it is
 * (rt_solid_mesh.c). Large subtrees are built as OpenMP tasks
 * (RT_BUILD_TASK_MIN), written where the serial build puts them: the same
 * nodes for any thread count. */
#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rt_internal.h"

#define RT_BINS 16
#define RT_LEAF_MAX 8
#define RT_STACK RT_BVH_STACK

static float round_down(double x)
{
    float f = (float)x;
    return (double)f > x ? nextafterf(f, -INFINITY) : f;
}
static float round_up(double x)
{
    float f = (float)x;
    return (double)f < x ? nextafterf(f, INFINITY) : f;
}

typedef rt_box box3;

static box3 box_empty(void)
{
    box3 b = {rr_v3(INFINITY, INFINITY, INFINITY), rr_v3(-INFINITY, -INFINITY, -INFINITY)};
    return b;
}
/* Plain comparisons, not rr_v3_min/max: fmin/fmax are library calls (kept
 * for their NaN rule) and were a third of the build time; primitive bounds
 * are never NaN (the scene loader rejects non-finite input). */
static rr_vec3 v3_min(rr_vec3 a, rr_vec3 b)
{
    return rr_v3(a.x < b.x ? a.x : b.x, a.y < b.y ? a.y : b.y, a.z < b.z ? a.z : b.z);
}
static rr_vec3 v3_max(rr_vec3 a, rr_vec3 b)
{
    return rr_v3(a.x > b.x ? a.x : b.x, a.y > b.y ? a.y : b.y, a.z > b.z ? a.z : b.z);
}
static box3 box_union(box3 a, box3 b)
{
    box3 r = {v3_min(a.lo, b.lo), v3_max(a.hi, b.hi)};
    return r;
}
static box3 box_add(box3 a, rr_vec3 p)
{
    box3 r = {v3_min(a.lo, p), v3_max(a.hi, p)};
    return r;
}
static double box_area(box3 b)
{
    rr_vec3 d = rr_v3_sub(b.hi, b.lo);
    if (d.x < 0 || d.y < 0 || d.z < 0)
        return 0.0;
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
}

typedef rt_build_item build_item;

typedef struct builder {
    build_item *items;
    rt_node *nodes;
    size_t nnodes, cap;
} builder;

static int push_node(builder *b, size_t *idx)
{
    if (b->nnodes == b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 256;
        rt_node *n = realloc(b->nodes, cap * sizeof *n);
        if (!n)
            return -1;
        b->nodes = n;
        b->cap = cap;
    }
    *idx = b->nnodes++;
    return 0;
}

static void set_bounds(rt_node *n, box3 box)
{
    n->lo[0] = round_down(box.lo.x);
    n->lo[1] = round_down(box.lo.y);
    n->lo[2] = round_down(box.lo.z);
    n->hi[0] = round_up(box.hi.x);
    n->hi[1] = round_up(box.hi.y);
    n->hi[2] = round_up(box.hi.z);
}

/* Bins of one SAH step: per axis, the count and bounds of the items whose
 * centroid falls in each of RT_BINS slices of the centroids' box. Only the
 * bins in `used` (bit k: bin k holds an item) are set: a node of a few items
 * touches a few bins, and most of the build's nodes are such nodes (the
 * tree goes down to leaves of 1-2 items), so neither the set-up nor the
 * sweep walks the empty ones. */
typedef struct bins3 {
    box3 box[3][RT_BINS];
    size_t cnt[3][RT_BINS];
    unsigned used[3];
} bins3;

static int bin_of(const build_item *it, int axis, double lo, double scale)
{
    int k = (int)((rr_v3_get(it->centroid, axis) - lo) * scale);
    return k < 0 ? 0 : (k >= RT_BINS ? RT_BINS - 1 : k);
}

static void bin_put(bins3 *b, int axis, int k, const box3 *box, size_t n)
{
    if (b->used[axis] >> k & 1u) {
        b->cnt[axis][k] += n;
        b->box[axis][k] = box_union(b->box[axis][k], *box);
    } else {
        b->used[axis] |= 1u << k;
        b->cnt[axis][k] = n;
        b->box[axis][k] = *box;
    }
}

/* items[0, count) into the bins of the three axes, in one pass over them. */
static void bin_items(const build_item *items, size_t count, const double lo[3], const double scale[3], bins3 *b)
{
    b->used[0] = b->used[1] = b->used[2] = 0;
    /* An axis with scale 0 (a flat slab) puts everything in bin 0 and is
     * not used. */
    for (size_t i = 0; i < count; i++) {
        const build_item *it = &items[i];
        bin_put(b, 0, bin_of(it, 0, lo[0], scale[0]), &it->box, 1);
        bin_put(b, 1, bin_of(it, 1, lo[1], scale[1]), &it->box, 1);
        bin_put(b, 2, bin_of(it, 2, lo[2], scale[2]), &it->box, 1);
    }
}

/* Chunks of items binned as tasks when the build runs in parallel (counts
 * add and boxes unite exactly: the same bins in any order). */
#define RT_BIN_CHUNK 32768
#define RT_BIN_CHUNKS_MAX 64
static void bin_all(const build_item *items, size_t count, const double lo[3], const double scale[3], bins3 *out)
{
    size_t nch = count / RT_BIN_CHUNK;
    if (nch < 2 || !omp_in_parallel()) {
        bin_items(items, count, lo, scale, out);
        return;
    }
    if (nch > RT_BIN_CHUNKS_MAX)
        nch = RT_BIN_CHUNKS_MAX;
    bins3 *part = malloc(nch * sizeof *part);
    if (!part) { /* fall back to one pass */
        bin_items(items, count, lo, scale, out);
        return;
    }
    for (size_t c = 0; c < nch; c++) {
        size_t a = count * c / nch, e = count * (c + 1) / nch;
#pragma omp task firstprivate(a, e, c) shared(part)
        bin_items(items + a, e - a, lo, scale, &part[c]);
    }
#pragma omp taskwait
    *out = part[0];
    for (size_t c = 1; c < nch; c++)
        for (int axis = 0; axis < 3; axis++)
            for (int k = 0; k < RT_BINS; k++)
                if (part[c].used[axis] >> k & 1u)
                    bin_put(out, axis, k, &part[c].box[axis][k], part[c].cnt[axis][k]);
    free(part);
}

/* Items [first, first + count) of the build, the union of their boxes and
 * the bounds of their centroids. A node's span comes from its parent's
 * partition pass (or, at the root, one pass), so each node reads its items
 * twice: to bin them and to partition them. */
typedef struct span {
    size_t first, count;
    box3 box, cb;
} span;

/* The spans of items[a, e) (one pass). */
static void span_of(const build_item *items, size_t a, size_t e, span *out)
{
    out->first = a;
    out->count = e - a;
    out->box = box_empty();
    out->cb = box_empty();
    for (size_t i = a; i < e; i++) {
        out->box = box_union(out->box, items[i].box);
        out->cb = box_add(out->cb, items[i].centroid);
    }
}

/* Chooses a split of the items of sp by binned SAH and partitions them;
 * returns the number put on the left (0 = make a leaf) with the two sides'
 * spans in *l and *r. */
static size_t sah_partition(build_item *all, const span *sp, int *axis_out, span *l, span *r)
{
    build_item *items = all + sp->first;
    size_t count = sp->count;
    box3 box = sp->box, cb = sp->cb;
    double blo[3], scale[3];
    for (int axis = 0; axis < 3; axis++) {
        double lo = rr_v3_get(cb.lo, axis), hi = rr_v3_get(cb.hi, axis);
        blo[axis] = lo;
        scale[axis] = hi > lo ? RT_BINS / (hi - lo) : 0.0;
    }
    bins3 bins;
    bin_all(items, count, blo, scale, &bins);
    double best_cost = (double)count; /* cost of a leaf, in intersection units */
    int best_axis = -1, best_split = 0;
    double inv_area = 1.0 / fmax(box_area(box), DBL_MIN);
    for (int axis = 0; axis < 3; axis++) {
        if (!(scale[axis] > 0.0))
            continue;
        /* Sweep the used bins from the right, then from the left. A split
         * after an empty bin has the cost of the split before it, which
         * wins ties, so only splits right after a used bin are tried: the
         * same choice as a sweep over every bin. */
        int k_used[RT_BINS], m = 0;
        for (unsigned u = bins.used[axis]; u; u &= u - 1)
            k_used[m++] = __builtin_ctz(u);
        double right_area[RT_BINS];
        size_t right_cnt[RT_BINS];
        box3 acc = box_empty();
        size_t n = 0;
        for (int j = m - 1; j > 0; j--) {
            acc = box_union(acc, bins.box[axis][k_used[j]]);
            n += bins.cnt[axis][k_used[j]];
            right_area[j] = box_area(acc);
            right_cnt[j] = n;
        }
        acc = box_empty();
        n = 0;
        for (int j = 0; j + 1 < m; j++) {
            acc = box_union(acc, bins.box[axis][k_used[j]]);
            n += bins.cnt[axis][k_used[j]];
            /* Traversal cost 1 relative to one primitive test. */
            double cost = 1.0 + (box_area(acc) * (double)n + right_area[j + 1] * (double)right_cnt[j + 1]) * inv_area;
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
    size_t left = 0;
    box3 lb = box_empty(), lc = box_empty(), rb = box_empty(), rc = box_empty();
    for (size_t i = 0; i < count; i++) {
        if (bin_of(&items[i], best_axis, blo[best_axis], scale[best_axis]) < best_split) {
            lb = box_union(lb, items[i].box);
            lc = box_add(lc, items[i].centroid);
            build_item t = items[i];
            items[i] = items[left];
            items[left++] = t;
        } else {
            rb = box_union(rb, items[i].box);
            rc = box_add(rc, items[i].centroid);
        }
    }
    *l = (span){sp->first, left, lb, lc};
    *r = (span){sp->first + left, count - left, rb, rc};
    *axis_out = best_axis;
    return left;
}

/* Node *idx for the items of sp: a leaf (l->count = 0), or an inner node
 * whose children get the spans *l and *r (its right child's index is set by
 * the caller). 0, or -1 when out of memory. */
static int make_node(builder *b, const span *sp, int depth, size_t *idx, span *l, span *r)
{
    if (push_node(b, idx))
        return -1;
    int axis = 0;
    l->count = depth >= RT_STACK - 2 ? 0 : sah_partition(b->items, sp, &axis, l, r);
    rt_node *n = &b->nodes[*idx];
    set_bounds(n, sp->box);
    if (l->count == 0 || l->count == sp->count) {
        RR_CHECK(sp->count <= UINT16_MAX);
        n->index = (uint32_t)sp->first;
        n->count = (uint16_t)sp->count;
        n->axis = 0;
        l->count = 0;
        return 0;
    }
    n->count = 0;
    n->axis = (uint16_t)axis;
    return 0;
}

static int build_rec(builder *b, const span *sp, int depth)
{
    size_t idx;
    span l, r;
    if (make_node(b, sp, depth, &idx, &l, &r))
        return -1;
    if (l.count == 0)
        return 0;
    if (build_rec(b, &l, depth + 1))
        return -1;
    b->nodes[idx].index = (uint32_t)b->nnodes; /* right child follows the whole left subtree */
    return build_rec(b, &r, depth + 1);
}

/* Appends sub's nodes to b's (interior nodes' right-child indices moved by
 * the offset; a leaf's index is an item index and stays). */
static int append_nodes(builder *b, const builder *sub)
{
    size_t off = b->nnodes;
    if (off + sub->nnodes > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < off + sub->nnodes)
            cap *= 2;
        rt_node *n = realloc(b->nodes, cap * sizeof *n);
        if (!n)
            return -1;
        b->nodes = n;
        b->cap = cap;
    }
    memcpy(b->nodes + off, sub->nodes, sub->nnodes * sizeof *sub->nodes);
    for (size_t k = off; k < off + sub->nnodes; k++)
        if (b->nodes[k].count == 0)
            b->nodes[k].index += (uint32_t)off;
    b->nnodes += sub->nnodes;
    return 0;
}

/* build_rec with the two subtrees of a large node built as tasks. */
static int build_par(builder *b, const span *sp, int depth)
{
    if (sp->count < RT_BUILD_TASK_MIN)
        return build_rec(b, sp, depth);
    size_t idx;
    span l, r;
    if (make_node(b, sp, depth, &idx, &l, &r))
        return -1;
    if (l.count == 0)
        return 0;
    builder L = {b->items, NULL, 0, 0}, R = {b->items, NULL, 0, 0};
    int fl = 0, fr = 0;
#pragma omp task shared(L, fl, l) if (omp_in_parallel())
    fl = build_par(&L, &l, depth + 1);
#pragma omp task shared(R, fr, r) if (omp_in_parallel())
    fr = build_par(&R, &r, depth + 1);
#pragma omp taskwait
    int failed = fl || fr || append_nodes(b, &L);
    if (!failed)
        b->nodes[idx].index = (uint32_t)b->nnodes; /* right child follows the whole left subtree */
    failed = failed || append_nodes(b, &R);
    free(L.nodes);
    free(R.nodes);
    return failed ? -1 : 0;
}

int rt__bvh_build_binary(rt_build_item *items, size_t n, int threads, rt_node **nodes, size_t *nnodes)
{
    builder b = {items, NULL, 0, 0};
    int failed = 0;
    if (threads <= 0)
        threads = omp_get_max_threads();
    span root;
    span_of(items, 0, n, &root);
    if (n < RT_BUILD_TASK_MIN || threads == 1) {
        failed = build_rec(&b, &root, 0);
    } else {
#pragma omp parallel num_threads(threads)
#pragma omp single
        failed = build_par(&b, &root, 0);
    }
    if (failed) {
        free(b.nodes);
        return -1;
    }
    *nodes = b.nodes;
    *nnodes = b.nnodes;
    return 0;
}
