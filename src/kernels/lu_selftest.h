/* lu_selftest.h — one evaluation of many prelude functions, compiled as C by
 * tests/test_gpu.c and as GLSL by kernels/kernel_selftest.comp, so the test
 * compares the two backends on the very same expressions.
 *
 * A case is LU_SELFTEST_IN floats: a.xyz, b.xyz, s, t, u, w. Operation k
 * (0 <= k < LU_SELFTEST_OPS) yields a vec3 (scalar results in x, y = z = 0;
 * the last op exercises a struct with inout/out parameters).
 * Inputs are mapped into each function's domain here (e.g. log of |s| + 0.1),
 * so the test may draw them freely from [-4, 4]; w feeds only lu_isfinite and
 * may be inf or NaN. */
#ifndef LU_SELFTEST_H
#define LU_SELFTEST_H

#include "lu_kernel.h"

#define LU_SELFTEST_IN 10
#define LU_SELFTEST_OPS 38

/* structs, inout and out parameters: the prelude's pointer-free conventions */
struct lu_k_selftest_acc {
    float sum;
    vec3 v;
};
LU_TYPEDEF(lu_k_selftest_acc)

LU_FN void lu_k_selftest_accumulate(LU_INOUT(lu_k_selftest_acc) acc, float x, LU_OUT(float) old_sum) {
    LU_DEREF(old_sum) = LU_DEREF(acc).sum;
    LU_DEREF(acc).sum += x;
    LU_DEREF(acc).v = lu_v3_madd(LU_DEREF(acc).v, lu_v3s(1.0f), x);
}

LU_FN vec3 lu_k_selftest_op(int k, vec3 a, vec3 b, float s, float t, float u, float w) {
    vec3 r = lu_v3s(0.0f);
    float pos = lu_abs(s) + 0.1f;                                 /* (0.1, 4.1] */
    vec3 bpos = lu_v3_add(lu_v3_mul(b, b), lu_v3s(0.25f));        /* nonzero divisor */
    float u01 = lu_clamp(u * 0.25f + 0.5f, 0.0f, 1.0f);
    switch (k) {
    case 0: r = lu_v3_add(a, b); break;
    case 1: r = lu_v3_sub(a, b); break;
    case 2: r = lu_v3_mul(a, b); break;
    case 3: r = lu_v3_div(a, bpos); break;
    case 4: r = lu_v3_scale(a, s); break;
    case 5: r = lu_v3_madd(a, b, s); break;
    case 6: r = lu_v3_neg(a); break;
    case 7: r = lu_v3_cross(a, b); break;
    case 8: r = lu_v3_norm(a); break;
    case 9: r = lu_v3_min(a, b); break;
    case 10: r = lu_v3_max(a, b); break;
    case 11: r = lu_v3_exp(a); break;
    case 12: r = lu_v3(lu_v3_dot(a, b), 0.0f, 0.0f); break;
    case 13: r = lu_v3(lu_v3_len(a), 0.0f, 0.0f); break;
    case 14: r = lu_v3(lu_v3_maxc(a), 0.0f, 0.0f); break;
    case 15: r = lu_v3(lu_v3_avg(a), 0.0f, 0.0f); break;
    case 16: r = lu_v3(lu_v3_get(a, lu_int(lu_abs(t) * 3.0f) % 3), 0.0f, 0.0f); break;
    case 17: r = lu_v3(lu_exp(s), 0.0f, 0.0f); break;
    case 18: r = lu_v3(lu_log(pos), 0.0f, 0.0f); break;
    case 19: r = lu_v3(lu_sqrt(pos), 0.0f, 0.0f); break;
    case 20: r = lu_v3(lu_pow(pos, t * 0.5f), 0.0f, 0.0f); break;
    case 21: r = lu_v3(lu_abs(s), 0.0f, 0.0f); break;
    case 22: r = lu_v3(lu_floor(s), 0.0f, 0.0f); break;
    case 23: r = lu_v3(lu_ceil(s), 0.0f, 0.0f); break;
    case 24: r = lu_v3(lu_min(s, t), 0.0f, 0.0f); break;
    case 25: r = lu_v3(lu_max(s, t), 0.0f, 0.0f); break;
    case 26: r = lu_v3(lu_sin(s), 0.0f, 0.0f); break;
    case 27: r = lu_v3(lu_cos(s), 0.0f, 0.0f); break;
    case 28: r = lu_v3(lu_acos(lu_clamp(t * 0.25f, -1.0f, 1.0f)), 0.0f, 0.0f); break;
    case 29: r = lu_v3(lu_atan2(s, t), 0.0f, 0.0f); break;
    case 30: r = lu_v3(lu_clamp(s, -0.5f, 0.5f), 0.0f, 0.0f); break;
    case 31: r = lu_v3(lu_mix(s, t, u01), 0.0f, 0.0f); break;
    case 32: r = lu_v3(lu_smoothstep(-1.0f, 1.5f, s), 0.0f, 0.0f); break;
    case 33: r = lu_v3(lu_isfinite(w) ? 1.0f : 0.0f, 0.0f, 0.0f); break;
    case 34: r = lu_v3(LU_K_PI, LU_K_INV_PI, LU_K_INV_4PI); break;
    case 35: r = lu_v3(lu_float(lu_int(s * 10.0f)), 0.0f, 0.0f); break;
    case 36: r = lu_v3(lu_v3_finite(lu_v3(w, s, t)) ? 1.0f : 0.0f, 0.0f, 0.0f); break;
    default: {
        lu_k_selftest_acc acc;
        acc.sum = s;
        acc.v = a;
        float old_sum = 0.0f;
        lu_k_selftest_accumulate(LU_REF(acc), t, LU_REF(old_sum));
        lu_k_selftest_accumulate(LU_REF(acc), u, LU_REF(old_sum));
        r = lu_v3(acc.sum, old_sum, acc.v.y);
        break;
    }
    }
    return r;
}

#endif
