/* Internal: splitmix64, the library's small seeded generator (Steele et al.
 * 2014): deterministic, one 64-bit state, good enough for sample placement. */
#ifndef LU_CORE_RNG_H
#define LU_CORE_RNG_H

#include <stdint.h>

static inline uint64_t lu_rng_next(uint64_t *s) {
    uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1) with 53 random bits. */
static inline double lu_rng_unit(uint64_t *s) { return (double)(lu_rng_next(s) >> 11) * (1.0 / 9007199254740992.0); }

#endif
