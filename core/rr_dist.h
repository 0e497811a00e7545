/* rr_dist.h - work spread over several processes (MPI ranks), as an
 * interface the passes call (part of core, see rr_core.h).
 *
 * The passes know nothing of MPI: the ray tracer's tiles and the radiosity
 * pass's form-factor rows come from a work list shared by every rank and
 * thread, and their results are combined by the operations below. app/mpi.c
 * implements them over Open MPI (built with -DRADRAY_MPI=ON); a NULL
 * rr_dist * everywhere means one process. Every pass's result is a
 * function of the seed and the work item alone, so that any split of the
 * items over ranks and threads gives the same bytes (notes/distributed.md).
 *
 * Collective calls (begin, end, merge, gather) must be made by every rank, in
 * the same order, from one thread; next may be called from any thread
 * between begin and end.
 */
#ifndef RR_DIST_H
#define RR_DIST_H

#include <stddef.h>

#include "rr_error.h"

typedef struct rr_dist rr_dist;

struct rr_dist {
    int rank, nranks;
    /* Starts a work list of n items (0 .. n-1), handed out on demand (rank
     * 0 schedules). */
    rr_status (*begin)(rr_dist *d, long long n, rr_error *err);
    /* The next item for the calling thread, each item to exactly one caller
     * over all ranks; -1 when the list is exhausted. */
    long long (*next)(rr_dist *d);
    /* Ends the list once this rank's threads have stopped asking. */
    rr_status (*end)(rr_dist *d, rr_error *err);
    /* Merges disjoint results: each of the n 32-bit words of buf is all
     * zero bits on every rank but at most one, and becomes that rank's word
     * on every rank (a bitwise OR: exact for any value, -0.0 and NaN
     * included, unlike a floating-point sum). */
    rr_status (*merge)(rr_dist *d, void *buf, size_t nwords, rr_error *err);
    /* Every rank's block of bytes, concatenated in rank order, into a
     * malloc'd *all (freed by the caller) of *total bytes. */
    rr_status (*gather)(rr_dist *d, const void *mine, size_t n, void **all, size_t *total, rr_error *err);
    void *impl;
};

/* The next item of a list of n for the calling thread: from d's shared
 * list, or (d NULL) from *local, a counter this process's threads share
 * (atomically). -1 when the list is done. */
static inline long long rr_dist_take(rr_dist *d, long long *local, long long n)
{
    long long i = d ? d->next(d) : __atomic_fetch_add(local, 1, __ATOMIC_RELAXED);
    return i >= 0 && i < n ? i : -1;
}

#endif
