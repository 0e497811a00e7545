/* rr_rng.h - seeded random numbers with independent streams (part of core).
 *
 * PCG32 (O'Neill 2014, "PCG: a family of simple fast space-efficient
 * statistically good algorithms"): 64-bit state, 64-bit stream selector. Every
 * unit of work (a pixel, a patch) seeds its own generator from (seed, stream id),
 * never from a shared generator, so the numbers a pixel sees do not depend on
 * which thread renders it or in what order: output is identical for any
 * thread count. */
#ifndef RR_RNG_H
#define RR_RNG_H

#include <stdint.h>

typedef struct rr_rng {
    uint64_t state;
    uint64_t inc; /* odd: selects the stream */
} rr_rng;

static inline uint32_t rr_rng_u32(rr_rng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31u));
}

/* SplitMix64 finaliser: spreads nearby seeds/stream ids over the state space. */
static inline uint64_t rr_hash64(uint64_t x)
{
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

/* Generator for stream `stream` of the sequence chosen by `seed`. */
static inline rr_rng rr_rng_make(uint64_t seed, uint64_t stream)
{
    rr_rng r;
    r.state = 0u;
    r.inc = (rr_hash64(stream ^ 0x5851f42d4c957f2dULL) << 1u) | 1u;
    rr_rng_u32(&r);
    r.state += rr_hash64(seed);
    rr_rng_u32(&r);
    return r;
}

/* Uniform double in [0, 1): 32 random bits are plenty for sampling. */
static inline double rr_rng_uniform(rr_rng *r) { return (double)rr_rng_u32(r) * (1.0 / 4294967296.0); }

/* Uniform integer in [0, n), n > 0, without modulo bias (Lemire's method). */
static inline uint32_t rr_rng_below(rr_rng *r, uint32_t n)
{
    uint64_t m = (uint64_t)rr_rng_u32(r) * n;
    uint32_t l = (uint32_t)m;
    if (l < n) {
        uint32_t t = (uint32_t)(-n) % n;
        while (l < t) {
            m = (uint64_t)rr_rng_u32(r) * n;
            l = (uint32_t)m;
        }
    }
    return (uint32_t)(m >> 32);
}

#endif
