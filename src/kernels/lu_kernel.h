/* lu_kernel.h — the common subset of C11 and GLSL 4.50 that kernel headers
 * are written in (the way PNanoVDB.h is one file for both).
 *
 * Rules for kernel headers (lu_*.h in src/kernels and the method rooms):
 *   - include this file first; guard with #ifndef/#define (GLSL has them);
 *   - functions are declared `LU_FN float f(...)`; no pointers: use
 *     LU_INOUT(T)/LU_OUT(T) parameters, pass with LU_REF(x), read with LU_DEREF(x);
 *   - vectors are `vec3` with .x .y .z; arithmetic through lu_v3_* (lucent/math.h
 *     in C, defined below for GLSL); scalars through lu_exp, lu_sqrt, ...;
 *     `vec4` (built by lu_v4/lu_v4s) takes + - * directly and v[i], nothing else;
 *   - structs: `struct lu_k_x { ... };` followed by LU_TYPEDEF(lu_k_x) (no semicolon:
 *     GLSL 4.50 rejects a lone one at global scope);
 *   - float literals with an f suffix (valid in both); no recursion, no
 *     variable-length arrays, no library calls beyond the macros below;
 *   - no identifiers that are GLSL keywords or reserved words (`sample`,
 *     `input`, `output`, `filter`, `common`, `partition`, `active`, `half`,
 *     `fixed`, `long`, `short`, `unsigned`, `double`, `patch`, `smooth`, ...),
 *     none containing `__`, none starting `gl_`;
 *   - include other kernel headers with `#include "name.h"` (same folder) or by their path
 *     under src/ (`"methods/common/lu_march.h"`);
 *     `#include <...>` only inside `#ifndef LU_GLSL` (the assembler drops them).
 * The GPU backend (src/backends/gpu) prepends "#version 450 core" and
 * "#define LU_GLSL 1", resolves #include "..." lines from the sources embedded
 * at build time (each file once) and maps compile errors back to file:line. */
#ifndef LU_KERNEL_H
#define LU_KERNEL_H

#ifdef LU_GLSL
/* ---------------------------------------------------------------- GLSL */
#define LU_FN
#define LU_INOUT(T) inout T
#define LU_OUT(T) out T
#define LU_OUT_ARRAY(T) out T   /* LU_OUT_ARRAY(float) y[36]: an array filled by the callee */
#define LU_REF(x) x
#define LU_DEREF(x) x
#define LU_TYPEDEF(name)
#define LU_CONST const
#define lu_exp exp
#define lu_log log
#define lu_sqrt sqrt
#define lu_pow pow
#define lu_abs abs
#define lu_floor floor
#define lu_ceil ceil
#define lu_min min
#define lu_max max
#define lu_sin sin
#define lu_cos cos
#define lu_clamp clamp
#define lu_mix mix
#define lu_int(x) int(x)
#define lu_float(x) float(x)
#define lu_isfinite(x) (!isnan(x) && !isinf(x))

/* GLSL leaves atan/acos precision to the driver, and Mesa lowers them to short
 * polynomials (measured on llvmpipe: atan(y, x) off by 3e-6, acos by 2e-4
 * rad). These follow Cephes' atanf (three-interval reduction, degree-4
 * polynomial in x^2; ~2e-7 relative), so both backends agree to ~1e-6. */
float lu_glsl_atan(float x) {
    float ax = abs(x), base = 0.0f, t = ax;
    if (ax > 2.414213562373095f) {
        base = 1.570796326794897f;
        t = -1.0f / ax;
    } else if (ax > 0.414213562373095f) {
        base = 0.785398163397448f;
        t = (ax - 1.0f) / (ax + 1.0f);
    }
    float z = t * t;
    float p = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z - 3.33329491539e-1f) * z;
    return sign(x) * (base + (p * t + t));
}
/* atan2 with C's quadrants (atan2(-0, x < 0) gives +pi here, -pi in C) */
float lu_atan2(float y, float x) {
    if (x == 0.0f) return y > 0.0f ? 1.570796326794897f : (y < 0.0f ? -1.570796326794897f : 0.0f);
    float r = lu_glsl_atan(y / x);
    if (x < 0.0f) r += y >= 0.0f ? 3.141592653589793f : -3.141592653589793f;
    return r;
}
float lu_acos(float x) { return lu_atan2(sqrt((1.0f - x) * (1.0f + x)), x); }

#define lu_v4(a, b, c, d) vec4(a, b, c, d)
#define lu_v4s(s) vec4(s)

vec3 lu_v3(float x, float y, float z) { return vec3(x, y, z); }
vec3 lu_v3s(float s) { return vec3(s); }
vec3 lu_v3_add(vec3 a, vec3 b) { return a + b; }
vec3 lu_v3_sub(vec3 a, vec3 b) { return a - b; }
vec3 lu_v3_mul(vec3 a, vec3 b) { return a * b; }
vec3 lu_v3_div(vec3 a, vec3 b) { return a / b; }
vec3 lu_v3_scale(vec3 a, float s) { return a * s; }
vec3 lu_v3_madd(vec3 a, vec3 b, float s) { return a + b * s; }
vec3 lu_v3_neg(vec3 a) { return -a; }
float lu_v3_dot(vec3 a, vec3 b) { return dot(a, b); }
vec3 lu_v3_cross(vec3 a, vec3 b) { return cross(a, b); }
float lu_v3_len(vec3 a) { return length(a); }
vec3 lu_v3_norm(vec3 a) { float l = length(a); return l > 0.0 ? a / l : a; }
vec3 lu_v3_min(vec3 a, vec3 b) { return min(a, b); }
vec3 lu_v3_max(vec3 a, vec3 b) { return max(a, b); }
vec3 lu_v3_exp(vec3 a) { return exp(a); }
float lu_v3_maxc(vec3 a) { return max(a.x, max(a.y, a.z)); }
float lu_v3_avg(vec3 a) { return (a.x + a.y + a.z) * (1.0 / 3.0); }
float lu_v3_get(vec3 a, int i) { return a[i]; }
bool lu_v3_finite(vec3 a) { return !any(isnan(a)) && !any(isinf(a)); }

#else
/* ------------------------------------------------------------------- C */
#include <lucent/math.h>
#include <math.h>
#include <stdbool.h>

#define LU_C 1
#define LU_FN static inline
#define LU_INOUT(T) T *
#define LU_OUT(T) T *
#define LU_OUT_ARRAY(T) T       /* arrays are passed by pointer in C anyway */
#define LU_REF(x) (&(x))
#define LU_DEREF(x) (*(x))
#define LU_TYPEDEF(name) typedef struct name name;
#define LU_CONST static const
#define lu_exp expf
#define lu_log logf
#define lu_sqrt sqrtf
#define lu_pow powf
#define lu_abs fabsf
#define lu_floor floorf
#define lu_ceil ceilf
#define lu_sin sinf
#define lu_cos cosf
#define lu_acos acosf
#define lu_atan2 atan2f
#define lu_int(x) ((int)(x))
#define lu_float(x) ((float)(x))
#define lu_isfinite(x) isfinite(x)
typedef lu_vec3 vec3;
typedef unsigned int uint;
/* vec4: four floats with elementwise + - * (a scalar operand is broadcast)
 * and components v[i], as in GLSL; in C the GCC/Clang vector extension, one
 * SSE register, so four independent chains of arithmetic written as one
 * run four-wide. Build with lu_v4 / lu_v4s. */
typedef float vec4 __attribute__((vector_size(16)));
static inline vec4 lu_v4(float a, float b, float c, float d) {
    vec4 v = {a, b, c, d};
    return v;
}
static inline vec4 lu_v4s(float s) { return lu_v4(s, s, s, s); }
/* Plain comparisons, like GLSL's min/max (whose NaN behaviour is undefined):
 * fminf/fmaxf are out-of-line libm calls on baseline x86-64. */
static inline float lu_min(float a, float b) { return a < b ? a : b; }
static inline float lu_max(float a, float b) { return a > b ? a : b; }
static inline float lu_clamp(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
static inline float lu_mix(float a, float b, float t) { return a + (b - a) * t; }
#endif

/* Kernels that read media take the backend's context as first parameter:
 *   LU_FN float f(LU_CTX_PARAM, ...) { ... lu_k_density(LU_CTX, medium, p_index) ... }
 * Before including such a kernel, the backend defines
 *   float lu_k_density(LU_CTX_PARAM, int medium, vec3 p_index)
 * (C: trilinear lu_grid_sample over a context struct; GLSL: textureLod on a
 * sampler3D, where the context parameter is an unused int). */
#ifdef LU_GLSL
#define LU_CTX_PARAM int lu_ctx_
#define LU_CTX lu_ctx_
#else
struct lu_k_ctx;
#define LU_CTX_PARAM const struct lu_k_ctx *lu_ctx_
#define LU_CTX lu_ctx_
#endif

/* ------------------------------------------------------------ shared */
LU_CONST float LU_K_PI = 3.14159265358979323846f;
LU_CONST float LU_K_INV_PI = 0.318309886183790671538f;
LU_CONST float LU_K_INV_4PI = 0.0795774715459476679f;
LU_CONST float LU_K_FAR_MARCH = 3.0e38f;  /* "never" for a DDA axis parallel to the ray */

LU_FN float lu_smoothstep(float e0, float e1, float x) {
    float t = lu_clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

#endif
