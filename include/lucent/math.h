/* lucent/math.h — 3-vectors, affine maps, boxes, rays.
 *
 * The same function names (lu_v3_add, lu_v3_dot, ...) are defined for GLSL in
 * src/kernels/lu_kernel.h (its GLSL branch), so kernel headers written against them
 * compile for both backends. */
#ifndef LUCENT_MATH_H
#define LUCENT_MATH_H

#include <math.h>
#include <stdbool.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LU_PI 3.14159265358979323846f
#define LU_INV_4PI 0.0795774715459476679f

typedef struct lu_vec3 { float x, y, z; } lu_vec3;

static inline lu_vec3 lu_v3(float x, float y, float z) { lu_vec3 r = {x, y, z}; return r; }
static inline lu_vec3 lu_v3s(float s) { return lu_v3(s, s, s); }
static inline lu_vec3 lu_v3_add(lu_vec3 a, lu_vec3 b) { return lu_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline lu_vec3 lu_v3_sub(lu_vec3 a, lu_vec3 b) { return lu_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline lu_vec3 lu_v3_mul(lu_vec3 a, lu_vec3 b) { return lu_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline lu_vec3 lu_v3_div(lu_vec3 a, lu_vec3 b) { return lu_v3(a.x / b.x, a.y / b.y, a.z / b.z); }
static inline lu_vec3 lu_v3_scale(lu_vec3 a, float s) { return lu_v3(a.x * s, a.y * s, a.z * s); }
static inline lu_vec3 lu_v3_madd(lu_vec3 a, lu_vec3 b, float s) { return lu_v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline lu_vec3 lu_v3_neg(lu_vec3 a) { return lu_v3(-a.x, -a.y, -a.z); }
static inline float lu_v3_dot(lu_vec3 a, lu_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline lu_vec3 lu_v3_cross(lu_vec3 a, lu_vec3 b) {
    return lu_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float lu_v3_len(lu_vec3 a) { return sqrtf(lu_v3_dot(a, a)); }
static inline lu_vec3 lu_v3_norm(lu_vec3 a) {
    float l = lu_v3_len(a);
    return l > 0.0f ? lu_v3_scale(a, 1.0f / l) : a;
}
static inline lu_vec3 lu_v3_min(lu_vec3 a, lu_vec3 b) { return lu_v3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)); }
static inline lu_vec3 lu_v3_max(lu_vec3 a, lu_vec3 b) { return lu_v3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)); }
static inline lu_vec3 lu_v3_exp(lu_vec3 a) { return lu_v3(expf(a.x), expf(a.y), expf(a.z)); }
static inline float lu_v3_maxc(lu_vec3 a) { return fmaxf(a.x, fmaxf(a.y, a.z)); }
static inline float lu_v3_avg(lu_vec3 a) { return (a.x + a.y + a.z) * (1.0f / 3.0f); }
static inline bool lu_v3_finite(lu_vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
static inline float lu_v3_get(lu_vec3 a, int i) { return i == 0 ? a.x : (i == 1 ? a.y : a.z); }

/* Affine map p' = M p + t, rows of m are [M | t]. */
typedef struct lu_affine { float m[3][4]; } lu_affine;

lu_affine lu_affine_identity(void);
lu_affine lu_affine_translate(lu_vec3 t);
lu_affine lu_affine_scale(lu_vec3 s);
/* Rotation by Euler angles in degrees, applied X then Y then Z. */
lu_affine lu_affine_rotate_xyz_deg(lu_vec3 deg);
lu_affine lu_affine_mul(const lu_affine *a, const lu_affine *b);  /* a after b */
/* Returns false if the linear part is singular. */
bool lu_affine_invert(const lu_affine *a, lu_affine *inv);
lu_vec3 lu_affine_point(const lu_affine *a, lu_vec3 p);
lu_vec3 lu_affine_vector(const lu_affine *a, lu_vec3 v);
/* Transforms a normal by the inverse transpose of the linear part (unnormalised). */
lu_vec3 lu_affine_normal(const lu_affine *a, lu_vec3 n);

typedef struct lu_aabb { lu_vec3 lo, hi; } lu_aabb;

static inline lu_aabb lu_aabb_empty(void) {
    lu_aabb b = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
    return b;
}
static inline void lu_aabb_grow(lu_aabb *b, lu_vec3 p) { b->lo = lu_v3_min(b->lo, p); b->hi = lu_v3_max(b->hi, p); }
static inline bool lu_aabb_valid(lu_aabb b) { return b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z; }
/* Image of a box under an affine map (box of the 8 transformed corners). */
lu_aabb lu_aabb_transform(const lu_affine *a, lu_aabb b);
/* Slab test; on hit returns true with [*t0, *t1] clipped to [tmin, tmax]. */
bool lu_aabb_ray(lu_aabb b, lu_vec3 o, lu_vec3 d, float tmin, float tmax, float *t0, float *t1);

#ifdef __cplusplus
}
#endif
#endif
