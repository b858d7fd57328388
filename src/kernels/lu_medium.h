/* lu_medium.h — a participating medium as kernels see it (kernel: C and GLSL).
 *
 * One record per lu_medium: the world->index affine map, the index-space
 * support of its density (where it can be non-zero), its world box,
 * coefficients, phase and emission kind. Density (and Le) itself comes from the backend hook
 * lu_k_density(LU_CTX, m, p_index) (lu_kernel.h); constant media return
 * `density_scale` there; Le comes from lu_k_emission(LU_CTX, m, p_index). CPU drivers build records with lu_medium_to_kernel
 * (methods/common/gpu_scene.h); the GPU reads the same fields from the scene buffer
 * (kernels/lu_scene_gpu.glsl), so both backends see identical numbers. */
#ifndef LU_MEDIUM_H
#define LU_MEDIUM_H

#include "lu_kernel.h"

struct lu_k_medium {
    vec3 w2i_x, w2i_y, w2i_z;   /* rows of the linear part: index.x = dot(w2i_x, p) + w2i_t.x */
    vec3 w2i_t;
    vec3 support_lo, support_hi; /* index space; a constant medium: its index box (unused) */
    vec3 bounds_lo, bounds_hi;   /* world box containing all non-zero density */
    vec3 sigma_a, sigma_s;       /* per unit length at density 1 */
    float g;                     /* Henyey-Greenstein */
    float density_scale;         /* grids: 1 (multiplies the texture); constant media: the density */
    float eta;                   /* boundary index of refraction (bounded media) */
    int constant;                /* 1: density_scale everywhere, no grid */
    int bounded;                 /* 1: the medium exists only inside a boundary mesh */
    int max_pieces;              /* DDA bound for lu_k_optical_depth along any ray */
    vec3 le;                     /* le_scale * le_color (include/lucent/scene.h) */
    int emission;                /* lu_emission_kind: 0 none, 1 constant Le = le, 2 grid, 3 blackbody */
};
LU_TYPEDEF(lu_k_medium)

LU_FN vec3 lu_k_medium_point(lu_k_medium m, vec3 p) {
    return lu_v3(lu_v3_dot(m.w2i_x, p) + m.w2i_t.x, lu_v3_dot(m.w2i_y, p) + m.w2i_t.y, lu_v3_dot(m.w2i_z, p) + m.w2i_t.z);
}

LU_FN vec3 lu_k_medium_vector(lu_k_medium m, vec3 d) {
    return lu_v3(lu_v3_dot(m.w2i_x, d), lu_v3_dot(m.w2i_y, d), lu_v3_dot(m.w2i_z, d));
}

LU_FN vec3 lu_k_medium_sigma_t(lu_k_medium m) { return lu_v3_add(m.sigma_a, m.sigma_s); }

/* Slab test of the ray o + t d against box [lo, hi], clipped to [t0, t1].
 * Returns false when the clipped range is empty; *ta, *tb otherwise. */
LU_FN bool lu_k_box_clip(vec3 lo, vec3 hi, vec3 o, vec3 d, float t0, float t1, LU_OUT(float) ta, LU_OUT(float) tb) {
    float a = t0, b = t1;
    for (int i = 0; i < 3; i++) {
        float oi = lu_v3_get(o, i), di = lu_v3_get(d, i), l = lu_v3_get(lo, i), h = lu_v3_get(hi, i);
        if (di == 0.0f) {
            if (oi < l || oi > h) return false;
            continue;
        }
        float inv = 1.0f / di;
        float u = (l - oi) * inv, v = (h - oi) * inv;
        a = lu_max(a, lu_min(u, v));
        b = lu_min(b, lu_max(u, v));
    }
    LU_DEREF(ta) = a;
    LU_DEREF(tb) = b;
    return b > a;
}

#endif
