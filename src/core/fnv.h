/* Internal: the 64-bit FNV-1a hash, for the keys of on-disk caches (ddod's
 * precomputation, bench's truth images): a fingerprint of their inputs, not
 * a defence against crafted collisions. */
#ifndef LU_CORE_FNV_H
#define LU_CORE_FNV_H

#include <stddef.h>
#include <stdint.h>

typedef struct lu_fnv {
    uint64_t h;
} lu_fnv;

#define LU_FNV_INIT {0xcbf29ce484222325ull}

static inline void lu_fnv_bytes(lu_fnv *f, const void *data, size_t n) {
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        f->h ^= p[i];
        f->h *= 0x100000001b3ull;
    }
}

#endif
