/* lu_hash.h — integer hashes shared by C and GLSL (one definition each):
 *   lu_k_hash_u32: pcg_hash (Jarzynski and Olano 2020, "Hash Functions for
 *     GPU Rendering"), the seeding hash of lu_sampling.h's generator;
 *   lu_k_mix32: a 32-bit avalanche finaliser (xorshift-multiply with the
 *     "lowbias32" constants): every input bit flips each output bit with
 *     probability close to 1/2; per-pixel jitter, lattice noise. */
#ifndef LU_HASH_H
#define LU_HASH_H

#include "kernels/lu_kernel.h"

LU_FN uint lu_k_hash_u32(uint v) {
    uint s = v * 747796405u + 2891336453u;
    uint w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (w >> 22u) ^ w;
}

LU_FN uint lu_k_mix32(uint x) {
    x = x ^ (x >> 16);
    x = x * 0x7feb352du;
    x = x ^ (x >> 15);
    x = x * 0x846ca68bu;
    x = x ^ (x >> 16);
    return x;
}

#endif
