/* rad_hier_sort.c - the hierarchical pass's links put in the solve's fixed
 * order (rad__hier_sort_links, rad_hier_ctx.h): by receiver (elements, then
 * receiving leaf clusters), then source, then way. In place (a radix sort
 * from the receiver key's top byte), or, where only the links after a
 * sorted prefix are new and a copy of them fits, those sorted into the copy
 * and merged in. The order is total: any sort gives the same array. */
#include <stdlib.h>
#include <string.h>

#include "rad_hier_ctx.h"
#include "rad_pass_internal.h"

/* By source, then way (a receiver-source pair has a link per way at most). */
static int cmp_source(const void *a, const void *b)
{
    const hlink *x = a, *y = b;
    if (x->s != y->s)
        return x->s < y->s ? -1 : 1;
    return (link_way(x) > link_way(y)) - (link_way(x) < link_way(y));
}

/* A receiver's bucket in the sorts: elements, then receiving leaf clusters
 * (the same order as link_less's). */
static inline size_t rkey(uint32_t r, size_t ne) { return r & CLB ? ne + CL(r) : r; }

static int link_less(const hlink *x, const hlink *y)
{
    return x->r < y->r || (x->r == y->r && (x->s < y->s || (x->s == y->s && link_way(x) < link_way(y))));
}

/* ln[0 .. n) by receiver key (rkey < 2^(shift + 8)) in place: a radix
 * sort from the top byte down (American flag sort), each pass's swaps
 * going to 256 places that stay in cache; the byte's buckets below the top
 * in parallel. The order within a receiver is left to sort_ranges. */
static inline size_t rdigit(const hlink *l, size_t ne, int shift) { return (rkey(l->r, ne) >> shift) & 255u; }

static void flag_sort(hlink *ln, size_t n, size_t ne, int shift, int top)
{
    if (n <= 16) { /* an insertion sort by key */
        for (size_t i = 1; i < n; i++) {
            hlink t = ln[i];
            size_t k = rkey(t.r, ne), j = i;
            while (j > 0 && rkey(ln[j - 1].r, ne) > k) {
                ln[j] = ln[j - 1];
                j--;
            }
            ln[j] = t;
        }
        return;
    }
    size_t cnt[256] = {0}, head[256], end[256];
    for (size_t i = 0; i < n; i++)
        cnt[rdigit(&ln[i], ne, shift)]++;
    for (size_t b = 0, acc = 0; b < 256; b++) {
        head[b] = acc;
        acc += cnt[b];
        end[b] = acc;
    }
    for (size_t b = 0; b < 256; b++)
        while (head[b] < end[b]) {
            hlink v = ln[head[b]];
            size_t d = rdigit(&v, ne, shift);
            while (d != b) { /* v to its bucket, taking out what was there */
                hlink t = ln[head[d]];
                ln[head[d]++] = v;
                v = t;
                d = rdigit(&v, ne, shift);
            }
            ln[head[b]++] = v;
        }
    if (shift == 0)
        return;
#pragma omp parallel for schedule(dynamic, 1) if (top)
    for (int b = 0; b < 256; b++)
        flag_sort(ln + end[b] - cnt[b], cnt[b], ne, shift - 8, 0);
}

/* ln[0 .. n) sorted by receiver, then source, in place: flag_sort, then
 * each receiver's links by source (sort_ranges). The order is total (a
 * receiver-source pair has a link per way at most): the same result as any
 * sort. A counting sort over every receiver, its swaps a cache miss each
 * (split between two threads by a partition at the median receiver), took
 * the 81-bunny room's second and third rounds 0.70 and 0.86 s of their
 * solves' 1.8 s; this, 0.53 and 0.55 s. -1 when out of memory. */
static void sort_ranges(hlink *ln, const size_t *start, size_t nk);

/* Where each receiver's links start among ln[0 .. n) once they are sorted
 * by receiver (start[0 .. nk], the last n); NULL when out of memory. */
static size_t *receiver_starts(const hlink *ln, size_t n, size_t ne, size_t nk)
{
    size_t *start = calloc(nk + 1, sizeof *start);
    if (!start)
        return NULL;
    for (size_t i = 0; i < n; i++)
        start[rkey(ln[i].r, ne) + 1]++;
    for (size_t e = 0; e < nk; e++)
        start[e + 1] += start[e];
    return start;
}

static int sort_in_place(hlink *ln, size_t n, size_t ne, size_t nk)
{
    int shift = 0;
    while (shift < 56 && nk > 0 && (nk - 1) >> shift >> 8)
        shift += 8;
    flag_sort(ln, n, ne, shift, 1);
    size_t *start = receiver_starts(ln, n, ne, nk);
    if (!start)
        return -1;
    sort_ranges(ln, start, nk);
    free(start);
    return 0;
}

/* Each receiver's range ln[start[e] .. start[e + 1]) sorted by source, the
 * receivers in parallel (a serial qsort of room.json's 3.7 M links took 0.4 s
 * a solve). */
static void sort_ranges(hlink *ln, const size_t *start, size_t nk)
{
#pragma omp parallel for schedule(dynamic, 256)
    for (long e = 0; e < (long)nk; e++) {
        size_t lo = start[e], hi = start[e + 1];
        if (hi - lo > 64) {
            qsort(ln + lo, hi - lo, sizeof *ln, cmp_source);
            continue;
        }
        /* an insertion sort: a receiver's links come mostly in order of
         * their sources (the walk visits the clusters in the order they
         * are numbered), and qsort's calls cost more than the moves */
        for (size_t i = lo + 1; i < hi; i++) {
            hlink t = ln[i];
            size_t j = i;
            while (j > lo && cmp_source(&t, &ln[j - 1]) < 0) {
                ln[j] = ln[j - 1];
                j--;
            }
            ln[j] = t;
        }
    }
}

/* ln[0 .. n) copied to out sorted by receiver, then source: a counting
 * sort by receiver writing straight into the copy that sort_links merges
 * from, then each receiver's range by source. -1 when out of memory. */
static int scatter_sort(const hlink *ln, size_t n, hlink *out, size_t ne, size_t nk)
{
    size_t *start = receiver_starts(ln, n, ne, nk);
    if (!start)
        return -1;
    for (size_t i = 0; i < n; i++)
        out[start[rkey(ln[i].r, ne)]++] = ln[i];
    for (size_t e = nk; e > 0; e--) /* back to each range's start */
        start[e] = start[e - 1];
    start[0] = 0;
    sort_ranges(out, start, nk);
    free(start);
    return 0;
}

/* The links sorted by receiver, then source (the gather's fixed order). In
 * place, and the array trimmed to its links first: the counting sort into a
 * second array held every link twice, as re-linking's copy did (rad_hier.c,
 * relink); with both in place 27 bunnies' pass peaked at 0.84 GB instead of
 * 1.44 GB. But re-linking keeps the kept links in order at the front and
 * adds the new ones behind them (room.json: 81 % and 99 % of the links in
 * order in the second and third rounds), and the in-place sort moved every
 * link again (0.5-0.7 s a round, serial: a tenth of the pass). So the links
 * after the longest sorted prefix are sorted alone into a copy of them
 * (scatter_sort) and merged in from the back, where that copy is no larger
 * than what the output adds later (three quarters of a patch-set entry per element,
 * rad__hier_bytes): the pass's peak stays where it was. A link is a
 * receiver-source pair, so the order is total and the result the same. -1
 * when out of memory. */
int rad__hier_sort_links(hctx *c)
{
    size_t n = c->nln, ne = c->nel, nk = ne + (c->rlc ? c->ncl : 0);
    if (n && c->capln > n) {
        hlink *t = realloc(c->ln, n * sizeof *t);
        if (t) {
            c->ln = t;
            c->capln = n;
        }
    }
    hlink *ln = c->ln;
    size_t k = n ? 1 : 0;
    while (k < n && link_less(&ln[k - 1], &ln[k]))
        k++;
    size_t m = n - k;
    if (m == 0)
        return 0;
    hlink *tail = k > 0 && (double)m * sizeof *ln <= 0.75 * RAD_PATCH_BYTES * (double)ne ? malloc(m * sizeof *tail)
                                                                                        : NULL;
    if (!tail)
        return sort_in_place(ln, n, ne, nk);
    if (scatter_sort(ln + k, m, tail, ne, nk) != 0) {
        free(tail);
        return -1;
    }
    size_t i = k, j = m, w = n; /* from the back: w > i always while j > 0 */
    while (j > 0) {
        if (i > 0 && link_less(&tail[j - 1], &ln[i - 1]))
            ln[--w] = ln[--i];
        else
            ln[--w] = tail[--j];
    }
    free(tail);
    return 0;
}
