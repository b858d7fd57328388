/* lu_ms.h — Wrenninge's octave approximation of multiple scattering
 * (kernel: C and GLSL; no hooks).
 *
 * Wrenninge, "Art-directable multiple volumetric scattering" (SIGGRAPH 2013
 * talk; "Oz: the great and volumetric"): the single-scattering source
 *   sigma_s p(cos, g) E T_l
 * is replaced by a sum of N octaves
 *   sum_{i=0}^{N-1} b^i sigma_s p(cos, c^i g) E T_l^(a^i)
 * where octave i sees the extinction towards the light scaled by a^i (so its
 * transmittance is T_l^(a^i)), contributes b^i and has eccentricity c^i g.
 * Light that has scattered several times has gone less far through the
 * medium on the straight line to the light, is dimmer and more isotropic;
 * the octaves mimic those three trends without tracing it. Octave 0 is
 * single scattering itself, so N = 1 is exactly the single-scattering march.
 *
 * The record is part of the view march's parameters (lu_k_rm_params) and of
 * the gradient kernel's (lu_k_gr_params, a GPU buffer record: four 4-byte
 * scalars, std430-compatible at any 4-byte offset). */
#ifndef LU_MS_H
#define LU_MS_H

#include "kernels/lu_kernel.h"
#include "kernels/lu_optics.h"

struct lu_k_ms {
    int octaves;   /* N; 1 (or less): single scattering */
    float a;       /* extinction scale per octave */
    float b;       /* contribution scale per octave */
    float c;       /* eccentricity scale per octave */
};
LU_TYPEDEF(lu_k_ms)

LU_FN lu_k_ms lu_k_ms_make(int octaves, float a, float b, float c) {
    lu_k_ms ms;
    ms.octaves = octaves;
    ms.a = a;
    ms.b = b;
    ms.c = c;
    return ms;
}

/* log T for T in [0, 1]; T = 0 gives a value whose product with any
 * a^i >= 1e-30 (a >= 0.01, N <= 16) still makes exp underflow to 0 (GLSL's
 * log(0) is undefined). */
LU_FN float lu_k_ms_log(float T) { return T > 0.0f ? lu_log(T) : -3.0e38f; }

/* The octaves above the first: sum_{i=1}^{N-1} b^i p(cos_t, c^i g) T^(a^i),
 * what multiplies sigma_s E (E without the transmittance T to the light)
 * on top of single scattering. Zero for N <= 1. T^(a^i) = exp(a^i log T):
 * one log per channel (one for grey T) and one exp per octave, cheaper than
 * a pow per octave; an isotropic phase is not evaluated per octave. */
LU_FN vec3 lu_k_ms_extra(lu_k_ms ms, float cos_t, float g, vec3 T) {
    vec3 s = lu_v3s(0.0f);
    if (ms.octaves <= 1) return s;
    bool grey = T.y == T.x && T.z == T.x;
    float lx = lu_k_ms_log(T.x);
    float ly = grey ? lx : lu_k_ms_log(T.y), lz = grey ? lx : lu_k_ms_log(T.z);
    float ai = 1.0f, bi = 1.0f, ci = 1.0f;
    for (int i = 1; i < ms.octaves; i++) {
        ai *= ms.a;
        bi *= ms.b;
        ci *= ms.c;
        float w = bi * (g == 0.0f ? LU_K_INV_4PI : lu_k_phase_hg(cos_t, ci * g));
        float tx = lu_exp(ai * lx);
        vec3 Ti = grey ? lu_v3s(tx) : lu_v3(tx, lu_exp(ai * ly), lu_exp(ai * lz));
        s = lu_v3_madd(s, Ti, w);
    }
    return s;
}

#endif
