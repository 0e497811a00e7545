/* mpi.c - `mpirun -np N radray render ...`: the rr_dist interface
 * (core/rr_dist.h) over Open MPI, and the few rules that keep a job of N
 * ranks behaving like one process (notes/distributed.md).
 *
 * Built with -DRADRAY_MPI=ON (RADRAY_MPI defined); otherwise every function
 * here is the one-process answer and radray needs no MPI at all.
 *
 *  - Work lists: rank 0 holds the counter. Its own threads take items
 *    under a mutex; a scheduler thread (started by begin, joined by end)
 *    answers the other ranks' requests, one message each way, each for a
 *    chunk of items (n / (64 ranks), at least 1). MPI is
 *    called by one thread at a time on every rank (MPI_THREAD_SERIALIZED):
 *    on rank 0 only the scheduler while a list is open, on the others the
 *    worker threads under a mutex.
 *  - Output and messages: rank 0 alone prints and writes. The other ranks
 *    keep their last error message; app_mpi_agree makes every rank learn
 *    whether any failed before work starts, and a rank whose failure rank 0
 *    did not share prints its own message then.
 *  - After agreement a failure on one rank would leave the others waiting
 *    in a collective: app_mpi_abort ends the whole job (MPI_Abort).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app.h"

static int g_rank = 0, g_nranks = 1;
static char g_muted[RR_ERROR_MSG_MAX + 64]; /* the last message a rank other than 0 kept */

int app_mpi_rank(void) { return g_rank; }
int app_mpi_ranks(void) { return g_nranks; }

int app_mpi_muted(const char *msg)
{
    if (g_rank == 0)
        return 0;
    if (msg)
        snprintf(g_muted, sizeof g_muted, "%s", msg);
    return 1;
}

#ifndef RADRAY_MPI

int app_mpi_init(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    return 0;
}
void app_mpi_finalize(void) {}
rr_dist *app_mpi_dist(void) { return NULL; }
int app_mpi_agree(int rc) { return rc; }
void app_mpi_abort(int rc) { (void)rc; }
double app_mpi_traffic(void) { return 0; }

#else

#include <mpi.h>
#include <pthread.h>
#include <time.h>

enum { TAG_REQ = 11, TAG_REP = 12, TAG_DONE = 13 };

typedef struct mpi_impl {
    long long n, counter;     /* the open list: items 0..n-1, the next one (rank 0) */
    long long chunk;          /* items per request of the other ranks (>= 1) */
    long long have, have_end; /* other ranks: the items of the last answer not yet handed out */
    pthread_mutex_t lock;     /* rank 0: the counter; other ranks: their MPI calls */
    pthread_t sched;
    int sched_running;
    double bytes;             /* what this rank sent in merges and gathers (notes) */
} mpi_impl;

static mpi_impl g_impl = {0, 0, 1, 0, 0, PTHREAD_MUTEX_INITIALIZER, 0, 0, 0};
static rr_dist g_dist;
static int g_inited = 0;

/* Rank 0: the next k items [first, first + count) of the list; count 0
 * when it is exhausted. */
static long long take(mpi_impl *m, long long k, long long *count)
{
    pthread_mutex_lock(&m->lock);
    long long first = m->counter, left = m->n - m->counter;
    *count = left > 0 ? (left < k ? left : k) : 0;
    m->counter += *count;
    pthread_mutex_unlock(&m->lock);
    return first;
}

/* Rank 0's scheduler: answers requests until every other rank said done.
 * Polls (MPI_Iprobe, then a sleep) instead of a blocking receive, which in
 * Open MPI spins a core that rank 0's own workers need; the sleep doubles
 * while nothing comes, from 10 us to 500 us (measured: a fixed 20 us sleep
 * cost rank 0's worker ~10 % of its core). */
static void *scheduler(void *arg)
{
    mpi_impl *m = arg;
    int done = 0;
    long nap = 10000;
    while (done < g_nranks - 1) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st);
        if (!flag) {
            struct timespec ts = {0, nap};
            nanosleep(&ts, NULL);
            nap = nap < 250000 ? 2 * nap : 500000;
            continue;
        }
        nap = 10000;
        int dummy;
        MPI_Recv(&dummy, 1, MPI_INT, st.MPI_SOURCE, st.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (st.MPI_TAG == TAG_DONE) {
            done++;
            continue;
        }
        long long rep[2];
        rep[0] = take(m, m->chunk, &rep[1]);
        MPI_Send(rep, 2, MPI_LONG_LONG, st.MPI_SOURCE, TAG_REP, MPI_COMM_WORLD);
    }
    return NULL;
}

static rr_status d_begin(rr_dist *d, long long n, rr_error *err)
{
    mpi_impl *m = d->impl;
    m->n = n;
    m->counter = 0;
    m->have = m->have_end = 0;
    /* A request costs a round trip to rank 0 (tens of microseconds): the
     * other ranks take items in chunks, small enough that each rank still
     * gets ~64 of them (the load stays balanced), one when items are few. */
    m->chunk = n / (64LL * d->nranks);
    if (m->chunk < 1)
        m->chunk = 1;
    if (d->rank == 0 && d->nranks > 1) {
        if (pthread_create(&m->sched, NULL, scheduler, m) != 0)
            return rr_error_set(err, RR_ERR_INTERNAL, "MPI: cannot start the work scheduler thread");
        m->sched_running = 1;
    }
    return RR_OK;
}

static long long d_next(rr_dist *d)
{
    mpi_impl *m = d->impl;
    long long count;
    if (d->rank == 0) {
        long long v = take(m, 1, &count);
        return count ? v : -1;
    }
    pthread_mutex_lock(&m->lock);
    if (m->have == m->have_end) {
        int ask = 0;
        long long rep[2] = {0, 0};
        MPI_Send(&ask, 1, MPI_INT, 0, TAG_REQ, MPI_COMM_WORLD);
        MPI_Recv(rep, 2, MPI_LONG_LONG, 0, TAG_REP, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        m->have = rep[0], m->have_end = rep[0] + rep[1];
    }
    long long v = m->have < m->have_end ? m->have++ : -1;
    pthread_mutex_unlock(&m->lock);
    return v;
}

/* The barrier keeps the next list's requests from reaching this list's
 * scheduler. */
static rr_status d_end(rr_dist *d, rr_error *err)
{
    (void)err;
    mpi_impl *m = d->impl;
    if (d->rank != 0) {
        int done = 0;
        MPI_Send(&done, 1, MPI_INT, 0, TAG_DONE, MPI_COMM_WORLD);
    } else if (m->sched_running) {
        pthread_join(m->sched, NULL);
        m->sched_running = 0;
    }
    MPI_Barrier(MPI_COMM_WORLD);
    return RR_OK;
}

/* MPI counts are ints: big buffers go in pieces of 2^28 words. */
static rr_status d_merge(rr_dist *d, void *buf, size_t nwords, rr_error *err)
{
    (void)err;
    mpi_impl *m = d->impl;
    uint32_t *w = buf;
    for (size_t off = 0; off < nwords;) {
        int k = nwords - off > (1u << 28) ? (1 << 28) : (int)(nwords - off);
        MPI_Allreduce(MPI_IN_PLACE, w + off, k, MPI_UINT32_T, MPI_BOR, MPI_COMM_WORLD);
        off += (size_t)k;
    }
    m->bytes += 4.0 * (double)nwords;
    return RR_OK;
}

/* Blocks travel in units of 1 KiB (padded), so that counts stay ints up to
 * 2 TiB; the padding is dropped when the blocks are put together. */
static rr_status d_gather(rr_dist *d, const void *mine, size_t n, void **all, size_t *total, rr_error *err)
{
    mpi_impl *m = d->impl;
    const size_t unit = 1024;
    uint64_t mysize = n, *sizes = malloc((size_t)d->nranks * sizeof *sizes);
    int *counts = malloc((size_t)d->nranks * sizeof *counts), *displs = malloc((size_t)d->nranks * sizeof *displs);
    unsigned char *padded = NULL, *recv = NULL, *out = NULL;
    rr_status st = RR_OK;
    if (!sizes || !counts || !displs) {
        st = rr_error_set(err, RR_ERR_NOMEM, "MPI: out of memory for a gather");
        goto done;
    }
    MPI_Allgather(&mysize, 1, MPI_UINT64_T, sizes, 1, MPI_UINT64_T, MPI_COMM_WORLD);
    size_t units = 0, sum = 0;
    for (int r = 0; r < d->nranks; r++) {
        size_t u = (size_t)((sizes[r] + unit - 1) / unit);
        if (u > INT32_MAX || units + u > INT32_MAX) {
            st = rr_error_set(err, RR_ERR_LIMIT, "MPI: a gather of more than 2 TiB");
            goto done;
        }
        counts[r] = (int)u, displs[r] = (int)units;
        units += u, sum += (size_t)sizes[r];
    }
    padded = calloc((size_t)counts[d->rank] ? (size_t)counts[d->rank] * unit : 1, 1);
    recv = malloc(units ? units * unit : 1);
    out = malloc(sum ? sum : 1);
    if (!padded || !recv || !out) {
        st = rr_error_set(err, RR_ERR_NOMEM, "MPI: out of memory for a gather of %zu bytes", sum);
        goto done;
    }
    if (n)
        memcpy(padded, mine, n);
    MPI_Datatype kib;
    MPI_Type_contiguous((int)unit, MPI_BYTE, &kib);
    MPI_Type_commit(&kib);
    MPI_Allgatherv(padded, counts[d->rank], kib, recv, counts, displs, kib, MPI_COMM_WORLD);
    MPI_Type_free(&kib);
    size_t at = 0;
    for (int r = 0; r < d->nranks; r++) {
        memcpy(out + at, recv + (size_t)displs[r] * unit, (size_t)sizes[r]);
        at += (size_t)sizes[r];
    }
    m->bytes += (double)n * (d->nranks - 1);
    *all = out, *total = sum;
    out = NULL;
done:
    free(sizes);
    free(counts);
    free(displs);
    free(padded);
    free(recv);
    free(out);
    return st;
}

int app_mpi_init(int *argc, char ***argv)
{
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS) {
        fprintf(stderr, "radray: MPI_Init_thread failed\n");
        return -1;
    }
    g_inited = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_nranks);
    if (provided < MPI_THREAD_SERIALIZED) {
        if (g_rank == 0)
            fprintf(stderr, "radray: the MPI library gives thread level %d; radray needs MPI_THREAD_SERIALIZED\n",
                    provided);
        MPI_Finalize();
        g_inited = 0;
        return -1;
    }
    /* Rank 0 speaks for the job: the others' stdout (summaries, help) goes nowhere. */
    if (g_rank != 0 && !freopen("/dev/null", "w", stdout))
        fprintf(stderr, "radray: rank %d: cannot silence stdout\n", g_rank);
    g_dist.rank = g_rank, g_dist.nranks = g_nranks;
    g_dist.begin = d_begin, g_dist.next = d_next, g_dist.end = d_end;
    g_dist.merge = d_merge, g_dist.gather = d_gather;
    g_dist.impl = &g_impl;
    return 0;
}

void app_mpi_finalize(void)
{
    if (g_inited)
        MPI_Finalize();
    g_inited = 0;
}

rr_dist *app_mpi_dist(void) { return g_inited && g_nranks > 1 ? &g_dist : NULL; }

int app_mpi_agree(int rc)
{
    if (!g_inited || g_nranks == 1)
        return rc;
    int mine[2] = {rc, g_rank == 0 ? rc : 0}, all[2] = {0, 0};
    MPI_Allreduce(mine, all, 2, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    /* Rank 0 said it already when it failed too; otherwise this rank says why. */
    if (rc != 0 && all[1] == 0 && g_muted[0])
        fprintf(stderr, "radray: rank %d of %d: %s\n", g_rank, g_nranks, g_muted);
    return all[0];
}

void app_mpi_abort(int rc)
{
    if (!g_inited || g_nranks == 1 || rc == 0)
        return;
    if (g_muted[0])
        fprintf(stderr, "radray: rank %d of %d: %s\n", g_rank, g_nranks, g_muted);
    fprintf(stderr, "radray: rank %d of %d failed (exit code %d): stopping every rank\n", g_rank, g_nranks, rc);
    MPI_Abort(MPI_COMM_WORLD, rc);
}

double app_mpi_traffic(void) { return g_impl.bytes; }

#endif
