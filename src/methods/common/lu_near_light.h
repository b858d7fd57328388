/* lu_near_light.h — the mean of a point light's 1/d^2 over a march step
 * (kernel: C and GLSL), used by the raymarch view march (lu_view_march.h) and
 * so by every method that reuses it (afm, gradient).
 *
 * A point or spot light at p and the march step x + s d, s in [sa, sb]
 * (h = sb - sa, d unit): the factor that turns the light's 1/|p - x|^2 at
 * the sample x into the step's mean of 1/|p - x - s d|^2,
 *   mean = (atan((sb - tc)/b) - atan((sa - tc)/b)) / (b h),
 * tc the closest approach to p along the line and b the line's distance to
 * p. A fixed step passing a light inside a medium otherwise hits or misses
 * the 1/d^2 peak (smoke_glow: one pixel 50x too bright, 15 % rel-L2 at
 * 512x512). The difference of the two atans is one atan2 (both scaled by
 * b^2):
 *   factor = atan2(b h, D) d2 / (b h),   D = b^2 + (sb - tc)(sa - tc),
 * d2 = |p - x|^2, exact in float at every distance. b is kept >= 1e-3 of
 * the step so a light exactly on the ray (whose mean diverges) gives a large
 * finite value; there is no cutoff, hence no seam.
 *
 * Away from the light the same factor needs no sqrt and no atan: with
 * D > 0 and z = b h / D, atan2(b h, D) = atan(z), so exactly
 *   factor = (atan(z) / z) d2 / D,   atan(z)/z = 1 - z^2/3 + z^4/5 - z^6/7 + ...
 * an alternating series with falling terms for z < 1: cut after z^6/7 its
 * error is below z^8/9, i.e. < 1.2e-9 relative for z^2 <= 0.01, far below
 * float rounding. z ~ h / |p - x|, so this branch covers every step more
 * than ~10 steps from the light: nearly all of them. Only b^2 enters it (no
 * sqrt), and b^2 = d2 - tc^2 may cancel when the ray points at the light,
 * but its absolute error ~1e-7 d2 moves D by ~1e-7 relative and z^2 by
 * ~1e-7 (h/d)^2: the factor stays good to a few ulps.
 * tests/test_raymarch.c checks both branches against the mean in double
 * and against each other at the switch. */
#ifndef LU_NEAR_LIGHT_H
#define LU_NEAR_LIGHT_H

#include "kernels/lu_kernel.h"

#define LU_K_RM_NEAR_SERIES_Z2 0.01f

/* The atan2 form, for any distance. */
LU_FN float lu_k_rm_near_light_atan(vec3 p, vec3 x, vec3 d, float sa, float sb) {
    vec3 op = lu_v3_sub(p, x);
    float d2 = lu_v3_dot(op, op);
    float tc = lu_v3_dot(op, d);
    float h = sb - sa;
    float b = lu_max(lu_sqrt(lu_max(d2 - tc * tc, 0.0f)), 1e-3f * h);
    return lu_atan2(b * h, b * b + (sb - tc) * (sa - tc)) * d2 / (b * h);
}

/* The factor: the series where z^2 = (b h / D)^2 <= z2_max, else the atan2
 * form (z2_max <= 0: always the atan2 form; tests compare the two). */
LU_FN float lu_k_rm_near_light_cut(vec3 p, vec3 x, vec3 d, float sa, float sb, float z2_max) {
    vec3 op = lu_v3_sub(p, x);
    float d2 = lu_v3_dot(op, op);
    float tc = lu_v3_dot(op, d);
    float h = sb - sa;
    float b2 = lu_max(d2 - tc * tc, 1e-6f * h * h);
    float D = b2 + (sb - tc) * (sa - tc);
    if (D > 0.0f) {
        float inv = 1.0f / D;
        float z2 = b2 * h * h * inv * inv;
        if (z2 <= z2_max) return (1.0f - z2 * (1.0f / 3.0f - z2 * (1.0f / 5.0f - z2 * (1.0f / 7.0f)))) * d2 * inv;
    }
    return lu_k_rm_near_light_atan(p, x, d, sa, sb);
}

LU_FN float lu_k_rm_near_light(vec3 p, vec3 x, vec3 d, float sa, float sb) {
    return lu_k_rm_near_light_cut(p, x, d, sa, sb, LU_K_RM_NEAR_SERIES_Z2);
}

#endif
