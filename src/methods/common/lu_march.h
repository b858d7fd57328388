/* lu_march.h — exact optical depth through a trilinear grid (kernel: C and GLSL).
 *
 * Why this is exact: inside one cell of the dual grid (corners at voxel
 * centres) trilinear density restricted to a line is a cubic in t, and
 * Simpson's rule integrates cubics exactly. So walking the cells with a 3D
 * DDA and applying Simpson per cell piece gives the optical depth to float
 * rounding, with no step size to tune. The backend supplies
 * lu_k_density(LU_CTX, medium, p_index) before including this file.
 *
 * All positions here are in the medium's index space: p(t) = o + t d, where
 * (o, d) is the world ray mapped by world_to_index, so t stays the world
 * ray parameter. */
#ifndef LU_MARCH_H
#define LU_MARCH_H

#include "kernels/lu_kernel.h"

struct lu_k_dda {
    vec3 t_next;    /* ray parameter of the next cell face crossing per axis */
    vec3 t_delta;   /* parameter advance per cell per axis */
    float t;        /* start of the current cell piece */
    float t_end;
};
LU_TYPEDEF(lu_k_dda)

LU_FN float lu_k_dda_axis_next(float o, float d, float t0) {
    if (d == 0.0f) return LU_K_FAR_MARCH;
    float p = o + t0 * d;
    float cell = lu_floor(p);
    float face = d > 0.0f ? cell + 1.0f : cell;
    if (d < 0.0f && face == p) face -= 1.0f;  /* sitting on a face going down: next face is below */
    return t0 + (face - p) / d;
}

LU_FN lu_k_dda lu_k_dda_begin(vec3 o, vec3 d, float t0, float t1) {
    lu_k_dda s;
    s.t = t0;
    s.t_end = t1;
    s.t_next = lu_v3(lu_k_dda_axis_next(o.x, d.x, t0), lu_k_dda_axis_next(o.y, d.y, t0),
                     lu_k_dda_axis_next(o.z, d.z, t0));
    s.t_delta = lu_v3(d.x != 0.0f ? 1.0f / lu_abs(d.x) : LU_K_FAR_MARCH, d.y != 0.0f ? 1.0f / lu_abs(d.y) : LU_K_FAR_MARCH,
                      d.z != 0.0f ? 1.0f / lu_abs(d.z) : LU_K_FAR_MARCH);
    return s;
}

/* End of the current cell piece; advances the state past it. Returns the
 * piece end (== t_end on the last piece). */
LU_FN float lu_k_dda_step(LU_INOUT(lu_k_dda) s) {
    vec3 tn = LU_DEREF(s).t_next;
    float m = lu_min(tn.x, lu_min(tn.y, tn.z));
    float end = lu_min(m, LU_DEREF(s).t_end);
    /* Advance every axis whose face is crossed here (corners cross two or three). */
    if (tn.x <= m) LU_DEREF(s).t_next.x = tn.x + LU_DEREF(s).t_delta.x;
    if (tn.y <= m) LU_DEREF(s).t_next.y = tn.y + LU_DEREF(s).t_delta.y;
    if (tn.z <= m) LU_DEREF(s).t_next.z = tn.z + LU_DEREF(s).t_delta.z;
    LU_DEREF(s).t = end;
    return end;
}

/* Simpson on one cell piece: exact for the cubic density inside a cell. */
LU_FN float lu_k_simpson(float len, float d0, float dm, float d1) { return len * (1.0f / 6.0f) * (d0 + 4.0f * dm + d1); }

/* Cubic through values at s = 0, 1/3, 2/3, 1 (monomial coefficients in s). */
struct lu_k_cubic {
    float c0, c1, c2, c3;
};
LU_TYPEDEF(lu_k_cubic)

LU_FN lu_k_cubic lu_k_cubic_fit(float f0, float f1, float f2, float f3) {
    lu_k_cubic c;
    c.c0 = f0;
    c.c1 = 0.5f * (-11.0f * f0 + 18.0f * f1 - 9.0f * f2 + 2.0f * f3);
    c.c2 = 4.5f * (2.0f * f0 - 5.0f * f1 + 4.0f * f2 - f3);
    c.c3 = 4.5f * (-f0 + 3.0f * f1 - 3.0f * f2 + f3);
    return c;
}

LU_FN float lu_k_cubic_eval(lu_k_cubic c, float s) { return c.c0 + s * (c.c1 + s * (c.c2 + s * c.c3)); }

/* Integral of the cubic over [0, s] (in units of s). */
LU_FN float lu_k_cubic_integral(lu_k_cubic c, float s) {
    return s * (c.c0 + s * (0.5f * c.c1 + s * (c.c2 * (1.0f / 3.0f) + s * 0.25f * c.c3)));
}

/* Exact optical depth (integral of density, not yet times sigma_t) over
 * [t0, t1] of the index-space ray; the caller clips to the grid's support.
 * max_pieces bounds the loop (nx + ny + nz + 3 always suffices). */
LU_FN float lu_k_optical_depth(LU_CTX_PARAM, int medium, vec3 o, vec3 d, float t0, float t1, int max_pieces) {
    if (!(t1 > t0)) return 0.0f;
    lu_k_dda s = lu_k_dda_begin(o, d, t0, t1);
    float ta = t0;
    float da = lu_k_density(LU_CTX, medium, lu_v3_madd(o, d, ta));
    float tau = 0.0f;
    for (int i = 0; i < max_pieces && ta < t1; i++) {
        float tb = lu_k_dda_step(LU_REF(s));
        float dm = lu_k_density(LU_CTX, medium, lu_v3_madd(o, d, 0.5f * (ta + tb)));
        float db = lu_k_density(LU_CTX, medium, lu_v3_madd(o, d, tb));
        tau += lu_k_simpson(tb - ta, da, dm, db);
        ta = tb;
        da = db;
    }
    return tau;
}

#endif
