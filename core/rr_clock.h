/* rr_clock.h - the monotonic wall clock (part of core): one definition for
 * every pass that reports its time. */
#ifndef RR_CLOCK_H
#define RR_CLOCK_H

#include <time.h>

/* Seconds on the monotonic clock (for differences only). */
static inline double rr_now_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

#endif
