/* rt_bvh.c - bounding volume hierarchy over every primitive of a scene (the
 * queries are in rt_traverse.c).
 *
 * Build, in two steps:
 * 1. A binary tree by binned surface area heuristic (rt_bvh_binary.c: 16
 *    bins over the bounds of the box centres, as in Wald 2007, "On fast
 *    construction of SAH-based BVHs"), built on float references (rt_bref:
 *    each primitive's box rounded outward and its number), leaves of at
 *    most 8 primitives, nodes in one flat array in depth-first order (left
 *    child next, right child at `index`), bounds that still contain their
 *    primitives exactly. The references are left in leaf order.
 * 2. Collapsed into the wide tree the queries walk (W = 4, 8 or 16 children in
 *    SoA float boxes, rt_wnode4 / 8 / 16 in rt_internal.h; W chosen per
 *    build, rt__bvh_width_default) by the surface area heuristic over every
 *    way of spreading a subtree over up to W children (a table per binary
 *    node, Ylitie et al. 2017; see collapse_costs), small subtrees (up to
 *    RT_WIDE_LEAF_MAX primitives) merged into one leaf where that costs less.
 *    The binary tree's leaves stay leaves; their primitives become leaf
 *    packets (rt_pk, RT_PK lanes SoA, rt_internal.h) in leaf order,
 *    triangles with a float copy of their vertices (exact, or for the float
 *    test only, with a double copy in rt_accel.dverts), written into the
 *    pages of the binary tree and the collapse's table, dead by then (a
 *    fresh page costs 1.5-2 us on the project's VM: a fifth of room-100k's
 *    build, notes/performance.md).
 * Both steps run on render.threads threads for large scenes (subtrees of
 * RT_BUILD_TASK_MIN items and more as OpenMP tasks, written where the serial
 * build puts them): the same bytes for any thread count.
 *
 * Primitives: one small closed interface (bounds + intersect) over the kinds in
 * rt_prim_kind; every query calls the same per-kind intersection function, so
 * closest-hit and shadow rays cannot disagree about an epsilon.
 *
 * Triangles (rt_traverse.c): the watertight test of Woop, Benthin & Wald 2013 ("Watertight
 * ray/triangle intersection", JCGT 2(1)): the triangle is sheared into a space
 * where the ray is the +z axis, and the three edge functions are evaluated from
 * the shared, identically transformed vertices. A ray through an edge shared by
 * two triangles gets edge values of opposite sign in the two (same numbers,
 * swapped order), so it cannot slip between them. Exact zeros (ray through an
 * edge or vertex) are recomputed in long double as the paper advises.
 */
#include <math.h>
#include <omp.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "rt_kernel.h"

/* ---- collapse into the wide tree ---- */

/* The collapse by cost (Ylitie, Karras & Laine 2017, "Efficient incoherent
 * ray traversal on GPUs through compressed wide BVHs", section 3): for every
 * binary node n and every j <= W, the cheapest way to hand n's subtree to a
 * wide parent as at most j children, by the surface area heuristic with a
 * wide node's box test costing RT_COST_NODE and a leaf packet's float test
 * RT_COST_PK (areas relative to any common unit):
 *   leaf(n)    = A(n) RT_COST_PK ceil(cnt(n) / RT_PK), for a binary leaf or cnt(n) <= RT_WIDE_LEAF_MAX
 *   node(n)    = A(n) RT_COST_NODE + split(n, W)     (n a wide node of its own)
 *   C(n, 1)    = min(leaf(n), node(n))
 *   split(n, j) = min over k of C(left, k) + C(right, j - k)   (n opened in place)
 *   C(n, j)    = min(C(n, j - 1), split(n, j)),  j >= 2 (a binary leaf: C(n, 1))
 * One backward pass over the depth-first array (children after parents)
 * fills the table; the wide tree is then read from its choices. The greedy
 * collapse it replaces (open the child of largest area until W) left most
 * nodes near the leaves half empty (3.7 children of 8 on average). The exact
 * tests of the lanes a packet keeps are left out of leaf(n): their number
 * follows the triangles' areas, however they are grouped. Leaves of up to 8
 * primitives (two packets) and a node at 3 packet tests: 58-61 bytes per
 * triangle against 66-70 at 4 primitives and 2 (notes/performance.md). */
#define RT_WIDE_LEAF_MAX 8u
#define RT_COST_NODE 3.0f
#define RT_COST_PK 1.0f

/* The cost table. A subtree with L binary leaves cannot use more than L
 * slots: C(n, j) = C(n, L) for j >= L (split(n, j) can give neither child
 * more slots than it has leaves, and the costs do not rise with j). So
 * node i keeps cap[i] = min(L, W) entries, from off[i]: cost[off[i] + j -
 * 1] = C(i, j) and how[off[i] + j - 1] its choice (j = 1: 0 leaf, 1 wide
 * node; j >= 2: the slots k given to the left child, 0 = as with j - 1
 * slots), j > cap[i] reads as j = cap[i]. node_k[i] (inner nodes): the
 * slots split(i, W) gives the left child. Most nodes are near the leaves:
 * mesh-1m's 1.08M binary nodes keep 3.0 entries each, not W = 16. */
typedef struct collapse_table {
    float *cost;
    uint8_t *how, *node_k, *cap;
    size_t *off;
} collapse_table;

/* The collapse's scratch memory (its subtree counts and cost table): the
 * part of the binary nodes' block past the nodes (rt__accel_build_width),
 * so that the pages it touches are pages the leaf packets later fill (a
 * fresh page costs 1.5-2 us on the project's VM), or malloc'd when the
 * block has no room left. */
typedef struct scratch {
    unsigned char *p;
    size_t left;
    void *own[3];
    int nown;
} scratch;

static void *scratch_take(scratch *s, size_t bytes)
{
    bytes = (bytes + 63) / 64 * 64;
    if (bytes <= s->left) {
        void *r = s->p;
        s->p += bytes;
        s->left -= bytes;
        return r;
    }
    if (s->nown == 3)
        return NULL;
    return s->own[s->nown++] = malloc(bytes ? bytes : 1);
}

static void scratch_free(scratch *s)
{
    for (int i = 0; i < s->nown; i++)
        free(s->own[i]);
    s->nown = 0;
}

typedef struct collapser {
    const rt_node *bin;
    const uint32_t *cnt, *first; /* per binary node: primitives below it, the first one */
    collapse_table t;            /* the cost table */
    /* Per item: the primitive count of the wide leaf that starts at it (0:
     * none starts there), and that leaf's first packet. */
    uint32_t *lcnt, *lpk;
    int width;      /* W: 4, 8 or 16 */
    size_t nbytes;  /* rt__wnode_bytes(width) */
    unsigned char *w; /* the nodes, 64-byte aligned */
    size_t nw, cap;
} collapser;

/* A wide node being filled, at the widest layout; put_node stores it in the
 * layout of the build's width. */
typedef struct wstage {
    float b[6][RT_WIDE_MAX];
    uint32_t child[RT_WIDE_MAX];
} wstage;

/* Every width's node is b[6][W], then child[W], then padding to whole cache
 * lines (rt_internal.h), so one copy serves them all. */
_Static_assert(offsetof(rt_wnode4, child) == 6 * 4 * sizeof(float) &&
                   offsetof(rt_wnode8, child) == 6 * 8 * sizeof(float) &&
                   offsetof(rt_wnode16, child) == 6 * 16 * sizeof(float),
               "wide nodes: child[] right after the boxes");
static void put_node(collapser *c, size_t idx, const wstage *st)
{
    unsigned char *n = c->w + idx * c->nbytes;
    size_t w = (size_t)c->width;
    memset(n, 0, c->nbytes);
    for (int k = 0; k < 6; k++)
        memcpy(n + (size_t)k * w * sizeof(float), st->b[k], w * sizeof(float));
    memcpy(n + 6 * w * sizeof(float), st->child, w * sizeof(uint32_t));
}

static float node_area(const rt_node *n)
{
    float dx = n->hi[0] - n->lo[0], dy = n->hi[1] - n->lo[1], dz = n->hi[2] - n->lo[2];
    return dx * dy + dy * dz + dz * dx;
}

/* A leaf's cost: its packets' float tests (the exact tests of the lanes
 * they keep depend on the triangles' areas, not on how they are grouped). */
static float leaf_cost(uint32_t n) { return RT_COST_PK * (float)((n + RT_PK - 1) / RT_PK); }

/* The costs and choices of binary node i (see above), its children's
 * already set, W = width, cap and off set for all. split(n, j) tries
 * k <= cap(left) only: a k beyond it costs no less than k = cap(left), and
 * the first of equal costs is kept, so the choices are those of the full
 * table. */
static void node_costs(const rt_node *bin, size_t i, const uint32_t *cnt, int width, collapse_table *t)
{
    float *cost = t->cost + t->off[i];
    uint8_t *how = t->how + t->off[i];
    float area = node_area(&bin[i]);
    if (bin[i].count) {
        cost[0] = area * leaf_cost(cnt[i]);
        how[0] = 0;
        t->node_k[i] = 0;
        return;
    }
    size_t li = i + 1, ri = bin[i].index;
    const float *l = t->cost + t->off[li], *r = t->cost + t->off[ri];
    int cl = t->cap[li], cr = t->cap[ri], cn = t->cap[i];
    float split[RT_WIDE_MAX];
    uint8_t split_k[RT_WIDE_MAX];
    for (int j = 2; j <= width; j++) {
        if (j > cn && j < width)
            continue; /* not needed: beyond cn only split(n, W), for node_k */
        /* The first k of the least cost, written as selects: the
         * comparison goes either way at random, and a branch on it was
         * mispredicted most of the time. */
        float best = INFINITY;
        int best_k = 1, kmax = j - 1 < cl ? j - 1 : cl;
        for (int k = 1; k <= kmax; k++) {
            int kr = j - k < cr ? j - k : cr;
            float v = l[k - 1] + r[kr - 1];
            int lower = v < best;
            best_k = lower ? k : best_k;
            best = lower ? v : best;
        }
        split[j - 1] = best;
        split_k[j - 1] = (uint8_t)best_k;
    }
    t->node_k[i] = split_k[width - 1];
    float as_node = area * RT_COST_NODE + split[width - 1];
    float as_leaf = cnt[i] <= RT_WIDE_LEAF_MAX ? area * leaf_cost(cnt[i]) : INFINITY;
    cost[0] = as_leaf <= as_node ? as_leaf : as_node;
    how[0] = as_leaf <= as_node ? 0 : 1;
    for (int j = 2; j <= cn; j++) {
        if (split[j - 1] < cost[j - 2]) {
            cost[j - 1] = split[j - 1];
            how[j - 1] = split_k[j - 1];
        } else {
            cost[j - 1] = cost[j - 2];
            how[j - 1] = 0;
        }
    }
}

/* A binary subtree, nodes [i, end). */
typedef struct bspan {
    size_t i, end;
} bspan;

static int larger_span_first(const void *a, const void *b)
{
    size_t x = ((const bspan *)a)->end - ((const bspan *)a)->i, y = ((const bspan *)b)->end - ((const bspan *)b)->i;
    return (x < y) - (x > y);
}

/* Appends v to the growable array *a of *n items (capacity *cap); -1 when
 * out of memory. */
static int bspan_push(bspan **a, size_t *n, size_t *cap, bspan v)
{
    if (*n == *cap) {
        size_t nc = *cap ? 2 * *cap : 64;
        bspan *g = realloc(*a, nc * sizeof *g);
        if (!g)
            return -1;
        *a = g;
        *cap = nc;
    }
    (*a)[(*n)++] = v;
    return 0;
}

/* The costs of binary nodes [0, nbin), children before parents. With
 * threads > 1 the subtrees below RT_BUILD_TASK_MIN items are costed by a
 * parallel loop, largest first, then the nodes above them in reverse
 * pre-order (as OpenMP tasks, libgomp ran them on one thread, as it did the
 * binary build's subtrees: bunny-1m's costs took as long at 2 threads as
 * at 1). The same table for any thread count. -1 when out of memory. */
static int collapse_costs(const rt_node *bin, size_t nbin, const uint32_t *cnt, int width, collapse_table *t,
                          int threads)
{
    if (threads <= 1 || cnt[0] < RT_BUILD_TASK_MIN) {
        for (size_t k = nbin; k-- > 0;)
            node_costs(bin, k, cnt, width, t);
        return 0;
    }
    bspan *top = NULL, *sub = NULL, *todo = NULL;
    size_t ntop = 0, ctop = 0, nsub = 0, csub = 0, ntodo = 0, ctodo = 0;
    int bad = bspan_push(&todo, &ntodo, &ctodo, (bspan){0, nbin});
    while (!bad && ntodo) { /* pre-order: a node before its subtrees */
        bspan x = todo[--ntodo];
        if (bin[x.i].count || cnt[x.i] < RT_BUILD_TASK_MIN) {
            bad = bspan_push(&sub, &nsub, &csub, x);
            continue;
        }
        size_t r = bin[x.i].index;
        bad = bspan_push(&top, &ntop, &ctop, x) || bspan_push(&todo, &ntodo, &ctodo, (bspan){r, x.end}) ||
              bspan_push(&todo, &ntodo, &ctodo, (bspan){x.i + 1, r});
    }
    if (!bad) {
        qsort(sub, nsub, sizeof *sub, larger_span_first); /* for the balance only */
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
        for (size_t k = 0; k < nsub; k++)
            for (size_t j = sub[k].end; j-- > sub[k].i;)
                node_costs(bin, j, cnt, width, t);
        for (size_t k = ntop; k-- > 0;)
            node_costs(bin, top[k].i, cnt, width, t);
    }
    free(top);
    free(sub);
    free(todo);
    return bad ? -1 : 0;
}

/* The choice for binary node i with j slots. */
static int how_of(const collapser *c, uint32_t i, int j)
{
    int cap = c->t.cap[i];
    return c->t.how[c->t.off[i] + (size_t)(j < cap ? j : cap) - 1];
}

/* 1 when binary node i is a leaf of the wide tree (as one child). */
static int is_leaf(const collapser *c, uint32_t i) { return how_of(c, i, 1) == 0; }

/* The children that binary node bi, opened with j slots, hands its wide
 * parent, appended to out[*m]. */
static void emit(const collapser *c, uint32_t bi, int j, uint32_t out[RT_WIDE_MAX], int *m)
{
    while (j > 1 && how_of(c, bi, j) == 0)
        j--;
    if (j == 1) {
        out[(*m)++] = bi;
        return;
    }
    int k = how_of(c, bi, j);
    emit(c, bi + 1, k, out, m);
    emit(c, c->bin[bi].index, j - k, out, m);
}

/* Children of binary inner node bi as a wide node: its subtree split over
 * W slots as the cost table chose. */
static int gather(const collapser *c, uint32_t bi, uint32_t out[RT_WIDE_MAX])
{
    int m = 0, k = c->t.node_k[bi];
    emit(c, bi + 1, k, out, &m);
    emit(c, c->bin[bi].index, c->width - k, out, &m);
    return m;
}

static void wnode_clear(wstage *wn)
{
    for (int i = 0; i < RT_WIDE_MAX; i++) {
        wn->child[i] = RT_EMPTY;
        for (int k = 0; k < 3; k++) {
            wn->b[2 * k][i] = INFINITY; /* empty box: missed by every ray */
            wn->b[2 * k + 1][i] = -INFINITY;
        }
    }
}

/* Child slot i of wn := binary node bi as a leaf (its packets: lpk). */
static void set_leaf(collapser *c, wstage *wn, int i, uint32_t bi) { wn->child[i] = RT_LEAF | c->lpk[c->first[bi]]; }

/* The collapse's walks (count_rec, collapse_at) hand wide subtrees of this
 * many items and more to other threads as tasks. At RT_BUILD_TASK_MIN,
 * room-100k's (102 k items, two halves of 51 k under the root) ran on one
 * thread: 2.4 ms at 1 and 2 threads; at 8192, 1.5-1.8 ms at 2 (a throwaway
 * phase timer, radray-bench --quick); the 1M-item scenes, already split,
 * the same. The nodes' places come from the counts, so the same nodes. */
#define RT_COLLAPSE_TASK_MIN 8192

/* The wide nodes that collapse_at writes for binary inner node bi and its
 * subtree, into wc[bi] (and wc of every inner node below that becomes a wide
 * node); returns it. Large subtrees as tasks. */
static uint32_t count_rec(const collapser *c, uint32_t bi, uint32_t *wc)
{
    uint32_t kids[RT_WIDE_MAX], sub[RT_WIDE_MAX] = {0};
    int m = gather(c, bi, kids);
    for (int i = 0; i < m; i++) {
        if (is_leaf(c, kids[i])) {
            c->lcnt[c->first[kids[i]]] = c->cnt[kids[i]]; /* leaves: disjoint runs of items */
            continue;
        }
        uint32_t k = kids[i];
#pragma omp task shared(sub) firstprivate(i, k) if (omp_in_parallel() && c->cnt[k] >= RT_COLLAPSE_TASK_MIN)
        sub[i] = count_rec(c, k, wc);
    }
#pragma omp taskwait
    uint32_t n = 1;
    for (int i = 0; i < m; i++)
        n += sub[i];
    wc[bi] = n;
    return n;
}

/* Writes the wide node for binary inner node bi at idx and, depth first, its
 * subtree after it (the children's subtrees at the places the counts wc
 * give, so that large ones can be written as tasks). */
static void collapse_at(collapser *c, uint32_t bi, size_t idx, const uint32_t *wc)
{
    uint32_t kids[RT_WIDE_MAX];
    int m = gather(c, bi, kids);
    wstage wn;
    wnode_clear(&wn);
    size_t next = idx + 1;
    for (int i = 0; i < m; i++) {
        const rt_node *ch = &c->bin[kids[i]];
        for (int k = 0; k < 3; k++) {
            wn.b[2 * k][i] = ch->lo[k];
            wn.b[2 * k + 1][i] = ch->hi[k];
        }
        if (is_leaf(c, kids[i])) {
            set_leaf(c, &wn, i, kids[i]);
            continue;
        }
        uint32_t k = kids[i];
        size_t at = next;
        wn.child[i] = (uint32_t)at;
#pragma omp task firstprivate(k, at) if (omp_in_parallel() && c->cnt[k] >= RT_COLLAPSE_TASK_MIN)
        collapse_at(c, k, at, wc);
        next += wc[k];
    }
#pragma omp taskwait
    put_node(c, idx, &wn);
}

/* The wide tree over binary tree bin (nbin nodes, bin[0] the root, n items).
 * Per item, lcnt (zeroed by the caller) gets the primitive count of the leaf
 * that starts there and lpk that leaf's first packet (leaves in item order,
 * ceil(count / RT_PK) packets each); *npk the packets in all. A root that
 * is a leaf gets a wide node with that one child. The same nodes for any
 * thread count. */
static int collapse(const rt_node *bin, size_t nbin, size_t n, uint32_t *lcnt, uint32_t *lpk, int width, int threads,
                    scratch *sc, void **out, size_t *nout, size_t *npk)
{
    uint32_t *cnt = scratch_take(sc, 3 * nbin * sizeof *cnt);
    unsigned char *tb = scratch_take(sc, nbin * (2 + sizeof(size_t)));
    if (!cnt || !tb) {
        scratch_free(sc);
        return -1;
    }
    uint32_t *first = cnt + nbin, *wc = cnt + 2 * nbin;
    /* Children come after their parent (depth-first order), so one backward
     * pass sums the subtrees. */
    for (size_t i = nbin; i-- > 0;) {
        if (bin[i].count) {
            cnt[i] = bin[i].count;
            first[i] = bin[i].index;
        } else {
            cnt[i] = cnt[i + 1] + cnt[bin[i].index];
            first[i] = first[i + 1];
        }
    }
    collapse_table t = {NULL, NULL, tb + nbin * sizeof(size_t), tb + nbin * sizeof(size_t) + nbin, (size_t *)tb};
    size_t nent = 0;
    for (size_t i = nbin; i-- > 0;) {
        unsigned cn = bin[i].count ? 1u : (unsigned)t.cap[i + 1] + t.cap[bin[i].index];
        t.cap[i] = (uint8_t)(cn < (unsigned)width ? cn : (unsigned)width);
    }
    for (size_t i = 0; i < nbin; i++) {
        t.off[i] = nent;
        nent += t.cap[i];
    }
    t.cost = scratch_take(sc, nent * (sizeof *t.cost + 1));
    if (!t.cost) {
        scratch_free(sc);
        return -1;
    }
    t.how = (uint8_t *)(t.cost + nent);
    int par = threads > 1 && cnt[0] >= RT_BUILD_TASK_MIN;
    if (collapse_costs(bin, nbin, cnt, width, &t, threads) != 0) {
        scratch_free(sc);
        return -1;
    }
    collapser c = {bin, cnt, first, t, lcnt, lpk, width, rt__wnode_bytes(width), NULL, 0, 0};
    int root_leaf = is_leaf(&c, 0);
    size_t total = 1;
    if (!root_leaf) {
#pragma omp parallel num_threads(threads) if (par)
#pragma omp single
        total = count_rec(&c, 0, wc);
    } else {
        lcnt[0] = cnt[0];
    }
    size_t np = 0;
    for (size_t i = 0; i < n; i++) {
        lpk[i] = (uint32_t)np;
        np += (lcnt[i] + RT_PK - 1) / RT_PK;
    }
    *npk = np;
    /* Wide nodes are 64-byte aligned (whole cache lines, aligned SIMD loads
     * and stores): malloc promises only 16. */
    c.w = aligned_alloc(64, total * c.nbytes);
    if (!c.w) {
        scratch_free(sc);
        return -1;
    }
    c.nw = c.cap = total;
    if (root_leaf) {
        wstage wn;
        wnode_clear(&wn);
        for (int k = 0; k < 3; k++) {
            wn.b[2 * k][0] = bin[0].lo[k];
            wn.b[2 * k + 1][0] = bin[0].hi[k];
        }
        set_leaf(&c, &wn, 0, 0);
        put_node(&c, 0, &wn);
    } else {
#pragma omp parallel num_threads(threads) if (par)
#pragma omp single
        collapse_at(&c, 0, 0, wc);
    }
    scratch_free(sc);
    *out = c.w;
    *nout = c.nw;
    return 0;
}

/* Lane i of packet k := primitive pr (ref and vertices; the double copy
 * is written later). Returns the largest |coordinate| of a triangle's
 * vertices (0 for other kinds); *dbl is set for a DBL lane. */
static double fill_lane(const scene *s, rt_prim pr, rt_pk *k, int i, int *dbl)
{
    if (pr.kind != RT_PRIM_TRIANGLE) {
        k->ref[i] = pr.index << RT_REF_SHIFT | RT_REF_PRIM;
        for (int r = 0; r < 9; r++)
            k->v[r][i] = NAN; /* never rejected by the float test: rt__prim_hit decides */
        return 0.0;
    }
    const scene_tri *t = &s->tris[pr.index];
    int exact = 1;
    double vm = 0.0;
    for (int c = 0; c < 3; c++) {
        rr_vec3 v = s->verts[t->v[c]];
        exact = exact && (double)(float)v.x == v.x && (double)(float)v.y == v.y && (double)(float)v.z == v.z;
        double ax = fabs(v.x), ay = fabs(v.y), az = fabs(v.z); /* not fmax: a libm call per use */
        double m = ax > ay ? ax : ay;
        m = az > m ? az : m;
        vm = m > vm ? m : vm;
        k->v[3 * c][i] = (float)v.x;
        k->v[3 * c + 1][i] = (float)v.y;
        k->v[3 * c + 2][i] = (float)v.z;
    }
    k->ref[i] = pr.index << RT_REF_SHIFT | (exact ? RT_REF_FAST : RT_REF_DBL) |
                (s->objects[t->object].cull_backfaces ? RT_REF_CULL : 0);
    *dbl |= !exact;
    return vm;
}

/* The primitives by item number (rt__prim_count's order) without a list
 * of them: item i < ntris is triangle i, the rest (one per sphere or solid
 * object, few) follow in `others` (a list of all n cost 8 bytes an item of
 * fresh memory per build). */
typedef struct prim_map {
    size_t ntris;
    const rt_prim *others;
} prim_map;

static inline rt_prim prim_at(const prim_map *m, uint32_t item)
{
    if (item < m->ntris) {
        rt_prim p = {RT_PRIM_TRIANGLE, item};
        return p;
    }
    return m->others[item - m->ntris];
}

/* The packets read their primitives in leaf order, not in the order of
 * the scene's arrays: the triangle and its vertices are each a cache miss
 * that waits for the one before. So the lanes ahead are fetched in two
 * stages, the second reading what the first brought in: RT_PF_MID lanes
 * ahead the triangle, RT_PF_NEAR the triangle's vertices. */
#define RT_PF_MID 16
#define RT_PF_NEAR 8
/* The vertices of primitive pr, if it is a triangle (its scene_tri read). */
static inline void prefetch_verts(const scene *s, rt_prim pr)
{
    if (pr.kind != RT_PRIM_TRIANGLE)
        return;
    const scene_tri *t = &s->tris[pr.index];
    for (int c = 0; c < 3; c++)
        __builtin_prefetch(&s->verts[t->v[c]]);
}
static inline void prefetch_lane(const scene *s, const rt_bref *refs, const prim_map *m, size_t p, size_t n)
{
    if (p + RT_PF_MID < n) {
        rt_prim pr = prim_at(m, rt__bref_item(&refs[p + RT_PF_MID]));
        if (pr.kind == RT_PRIM_TRIANGLE)
            __builtin_prefetch(&s->tris[pr.index]);
    }
    if (p + RT_PF_NEAR < n)
        prefetch_verts(s, prim_at(m, rt__bref_item(&refs[p + RT_PF_NEAR])));
}

/* The leaf packets (rt_internal.h) from the primitives in leaf order
 * (prim_at(m, rt__bref_item(&refs[j])), j = 0 .. n - 1) and the leaves collapse
 * found (lcnt, lpk), the double copies of the triangles whose vertices are
 * not all floats, and rt_accel.vmax. The packets go into block (64-byte
 * aligned, block_bytes, the binary nodes' pages, now dead) when they fit,
 * else into memory of their own (block freed): either way the block is
 * taken. 0, or -1 when out of memory. */
static int fill_packets(const scene *s, const rt_bref *refs, const prim_map *m, size_t n, const uint32_t *lcnt,
                        const uint32_t *lpk, size_t npk, int threads, void *block, size_t block_bytes, rt_accel *a)
{
    size_t bytes = (npk * sizeof(rt_pk) + 63) / 64 * 64;
    if (bytes <= block_bytes) {
        a->pks = block;
    } else {
        free(block);
        if (!(a->pks = aligned_alloc(64, bytes)))
            return -1;
    }
    /* Every packet belongs to one leaf and is zeroed with it below, by the
     * thread that fills it: its pages are first touched in parallel (a
     * fresh 4 KiB page costs 3-5 us on the project's VM, 40 MB of packets 25-50 ms). */
    memset((char *)a->pks + npk * sizeof(rt_pk), 0, bytes - npk * sizeof(rt_pk));
    a->npks = npk;
    a->nprims = n;
    int dbl = 0;
    double vmax = 0.0;
#pragma omp parallel for schedule(static) num_threads(threads) if (n >= RT_BUILD_TASK_MIN) reduction(|                 \
                                                                                                     : dbl)            \
    reduction(max                                                                                                      \
              : vmax)
    for (size_t j = 0; j < n; j++) {
        if (!lcnt[j])
            continue;
        rt_pk *k = a->pks + lpk[j];
        memset(k, 0, (lcnt[j] + RT_PK - 1) / RT_PK * sizeof *k);
        for (uint32_t q = 0; q < lcnt[j]; q++) {
            prefetch_lane(s, refs, m, j + q, n);
            double vm = fill_lane(s, prim_at(m, rt__bref_item(&refs[j + q])), k + q / RT_PK, (int)(q % RT_PK), &dbl);
            vmax = vm > vmax ? vm : vmax;
        }
        k[(lcnt[j] - 1) / RT_PK].ref[0] |= RT_REF_LAST;
    }
    a->vmax = rt__f_up(vmax * (1.0 + 1e-6));
    if (!dbl)
        return 0;
    a->ndverts = npk * RT_PK;
    if (!(a->dverts = malloc(a->ndverts * 9 * sizeof *a->dverts)))
        return -1;
#pragma omp parallel for schedule(static) num_threads(threads) if (n >= RT_BUILD_TASK_MIN)
    for (size_t q = 0; q < npk; q++) {
        for (int i = 0; i < RT_PK; i++) {
            double *d = a->dverts + 9 * (q * RT_PK + (size_t)i);
            uint32_t ref = a->pks[q].ref[i];
            if ((ref & RT_REF_LANE) != RT_REF_DBL) {
                memset(d, 0, 9 * sizeof *d);
                continue;
            }
            const scene_tri *t = &s->tris[ref >> RT_REF_SHIFT];
            for (int c = 0; c < 3; c++) {
                rr_vec3 v = s->verts[t->v[c]];
                d[3 * c] = v.x;
                d[3 * c + 1] = v.y;
                d[3 * c + 2] = v.z;
            }
        }
    }
    return 0;
}

/* Why an environment variable and not a parameter: it is for comparing the
 * two widths in benchmarks and tests of one binary, not a setting of the
 * renderer (both widths give the same hits). */
int rt__bvh_width_default(void)
{
    const char *env = getenv("RADRAY_BVH_WIDTH");
    if (env && strcmp(env, "4") == 0)
        return 4;
    if (env && strcmp(env, "8") == 0 && rt__bvh_width_ok(8))
        return 8;
    return rt__bvh_width_ok(16) ? 16 : rt__bvh_width_ok(8) ? 8 : 4;
}

int rt__bvh_width_ok(int width)
{
    if (width == 4)
        return 1;
#if RT_HAVE_W8 && RT_SIMD == 3
    /* Dispatching build: rt__walk8 is AVX2 code, rt__walk16 AVX-512 code, in
     * an SSE2 binary. */
    __builtin_cpu_init();
    if (width == 16)
        return RT_HAVE_W16 && __builtin_cpu_supports("avx512f");
    return width == 8 && __builtin_cpu_supports("avx2");
#elif RT_HAVE_W8
    return width == 8; /* the whole binary needs AVX2 anyway */
#else
    return 0;
#endif
}

rr_status rt_accel_build(const scene *s, rt_accel **out, rr_error *err)
{
    return rt__accel_build_width(s, 0, out, err);
}

rr_status rt__accel_build_width(const scene *s, int width, rt_accel **out, rr_error *err)
{
    if (width == 0)
        width = rt__bvh_width_default();
    if (!rt__bvh_width_ok(width))
        return rr_error_set(err, RR_ERR_INVALID, "%s: %d-wide BVH nodes are not available in this build or on this CPU",
                            s->path, width);
    size_t n = rt__prim_count(s);
    if (n >= RT_REF_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: %zu primitives exceed the BVH limit of %u", s->path, n,
                            RT_REF_MAX - 1);
    /* The scene's render.threads (0: OpenMP's default, all cores). */
    int threads = s->settings.threads > 0 ? s->settings.threads : omp_get_max_threads();
    rt_accel *a = calloc(1, sizeof *a);
    /* refs: the primitives' boxes and numbers, in leaf order after the
     * binary build; block: the binary nodes, then the collapse's scratch,
     * then (the nodes and scratch dead) the leaf packets, in the same pages
     * (scratch, fill_packets); lcnt, lpk: per item, the collapse's leaves
     * for fill_packets. Freed (but for the packets) once they are filled. */
    struct {
        rt_bref *refs;
        rt_prim *others;
        void *block;
        size_t block_bytes, nnodes;
        uint32_t *lcnt;
    } b = {NULL, NULL, NULL, 0, 0, NULL};
    size_t nothers = n - s->ntris;
    prim_map m = {s->ntris, NULL};
    b.refs = n ? malloc(n * sizeof *b.refs) : NULL;
    b.others = malloc((nothers ? nothers : 1) * sizeof *b.others);
    b.block_bytes = ((2 * n + 1) * sizeof(rt_node) + 63) / 64 * 64;
    b.block = n ? aligned_alloc(64, b.block_bytes) : NULL;
    b.lcnt = n ? calloc(2 * n, sizeof *b.lcnt) : NULL;
    if (!a || !b.others || (n && (!b.refs || !b.block || !b.lcnt)))
        goto nomem;
    rt__prim_others(s, b.others);
    m.others = b.others;
#pragma omp parallel for schedule(static) num_threads(threads) if (n >= RT_BUILD_TASK_MIN)
    for (size_t i = 0; i < n; i++) {
        if (i + RT_PF_NEAR < n) /* the triangles are read in order, their vertices are not */
            prefetch_verts(s, prim_at(&m, (uint32_t)(i + RT_PF_NEAR)));
        rt_prim pr = prim_at(&m, (uint32_t)i);
        if (pr.kind == RT_PRIM_TRIANGLE) {
            const scene_tri *t = &s->tris[pr.index];
            rt__bref_tri(&b.refs[i], &s->verts[t->v[0]], &s->verts[t->v[1]], &s->verts[t->v[2]], (uint32_t)i);
            continue;
        }
        rr_vec3 lo, hi;
        rt__prim_bounds(s, pr, &lo, &hi);
        rt__bref_set(&b.refs[i], lo, hi, (uint32_t)i);
    }
    /* Nodes of at most RT_PK items are leaves: they fill one packet, and
     * splitting them can only add packets; the collapse, which costs a leaf
     * by its packets, mostly kept them whole anyway. Not splitting them
     * takes 40-46 % of the binary tree's nodes away (notes/performance.md,
     * "Binary leaves of one packet"). */
    rt_node *nodes = b.block;
    if (n && rt__bvh_build_binary(b.refs, n, RT_PK, threads, &nodes, &b.nnodes))
        goto nomem;
    a->scene = s;
    a->width = width;
    if (n) {
        size_t used = (b.nnodes * sizeof(rt_node) + 63) / 64 * 64;
        scratch sc = {(unsigned char *)b.block + used, b.block_bytes - used, {NULL, NULL, NULL}, 0};
        uint32_t *lpk = b.lcnt + n;
        size_t npk = 0;
        if (collapse(nodes, b.nnodes, n, b.lcnt, lpk, width, threads, &sc, &a->wnodes, &a->nwnodes, &npk))
            goto nomem;
        void *block = b.block;
        b.block = NULL; /* fill_packets takes it */
        if (fill_packets(s, b.refs, &m, n, b.lcnt, lpk, npk, threads, block, b.block_bytes, a))
            goto nomem;
    }
    free(b.refs);
    free(b.others);
    free(b.lcnt);
    rr_status st = rt__solids_build(s, &a->solids, err);
    if (st != RR_OK) {
        rt_accel_destroy(a);
        return st;
    }
    *out = a;
    return RR_OK;
nomem:
    free(b.refs);
    free(b.others);
    free(b.block);
    free(b.lcnt);
    if (a) {
        free(a->pks);
        free(a->dverts);
        free(a->wnodes);
    }
    free(a);
    return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory building the BVH over %zu primitives", s->path, n);
}

rr_status rt_accel_build_solids(const scene *s, rt_accel **out, rr_error *err)
{
    rt_accel *a = calloc(1, sizeof *a);
    if (!a)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory building the solids' BVHs", s->path);
    a->scene = s;
    a->width = rt__bvh_width_default();
    rr_status st = rt__solids_build(s, &a->solids, err);
    if (st != RR_OK) {
        rt_accel_destroy(a);
        return st;
    }
    *out = a;
    return RR_OK;
}

void rt_accel_destroy(rt_accel *a)
{
    if (!a)
        return;
    free(a->wnodes);
    free(a->pks);
    free(a->dverts);
    rt__solids_destroy(a->solids);
    free(a);
}

size_t rt_accel_node_count(const rt_accel *a) { return a->nwnodes; }

rt_accel_stats rt_accel_stats_of(const rt_accel *a)
{
    rt_accel_stats st;
    st.width = a->width;
    st.nodes = a->nwnodes;
    st.node_bytes = rt__wnode_bytes(a->width);
    st.records = a->npks;
    st.record_bytes = sizeof(rt_pk);
    st.bytes = st.nodes * st.node_bytes + st.records * st.record_bytes + a->ndverts * 9 * sizeof(double) +
               rt__solids_bytes(a->solids);
    return st;
}
