/* lu_sh.h — real spherical harmonics up to band 7 (64 coefficients), kernel:
 * C and GLSL.
 *
 * Convention (Sloan's "Stupid SH Tricks", Ramamoorthi-Hanrahan): z is the
 * polar axis, no Condon-Shortley phase, index i = l (l + 1) + m, so
 *   Y_00 = 0.282095, Y_1-1 = 0.488603 y, Y_10 = 0.488603 z, Y_11 = 0.488603 x.
 * Y_lm = sqrt(2) K_lm cos(m phi) P_l^m(cos theta) for m > 0, the sin form for
 * m < 0, K_l0 P_l^0 for m = 0, with K_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!).
 * Evaluated in Cartesian form: sin^m(theta) cos(m phi) = Re((x + i y)^m), and
 * P_l^m = sin^m(theta) Q_l^m(z) with Q from the standard three-term recurrence,
 * so no trigonometry is needed. */
#ifndef LU_SH_H
#define LU_SH_H

#include "kernels/lu_kernel.h"

#define LU_SH_MAX_BANDS 8
#define LU_SH_MAX_COEFFS 64

LU_FN int lu_k_sh_count(int bands) { return bands * bands; }

/* sqrt((2l+1)/(4 pi) * (l-m)!/(l+m)!) for 0 <= m <= l. */
LU_FN float lu_k_sh_norm(int l, int m) {
    float ratio = 1.0f;
    for (int k = l - m + 1; k <= l + m; k++) ratio /= lu_float(k);
    return lu_sqrt(lu_float(2 * l + 1) * LU_K_INV_4PI * ratio);
}

/* y[0 .. bands^2 - 1] = Y_i(d) for unit d, bands in [1, 8]. */
LU_FN void lu_k_sh_eval(vec3 d, int bands, LU_OUT_ARRAY(float) y[LU_SH_MAX_COEFFS]) {
    float cm = 1.0f, sm = 0.0f;       /* Re, Im of (x + i y)^m */
    float qmm = 1.0f;                 /* Q_m^m = (2m-1)!! */
    for (int m = 0; m < bands; m++) {
        float q_prev = 0.0f, q = qmm; /* Q_{l-1}^m, Q_l^m starting at l = m */
        for (int l = m; l < bands; l++) {
            if (l > m) {
                float q_next = l == m + 1 ? lu_float(2 * m + 1) * d.z * q
                                          : (lu_float(2 * l - 1) * d.z * q - lu_float(l + m - 1) * q_prev) /
                                                lu_float(l - m);
                q_prev = q;
                q = q_next;
            }
            float k = lu_k_sh_norm(l, m);
            if (m == 0) {
                y[l * (l + 1)] = k * q;
            } else {
                y[l * (l + 1) + m] = 1.41421356237f * k * q * cm;
                y[l * (l + 1) - m] = 1.41421356237f * k * q * sm;
            }
        }
        float c2 = cm * d.x - sm * d.y;
        sm = cm * d.y + sm * d.x;
        cm = c2;
        qmm *= lu_float(2 * m + 1);
    }
}

/* Zonal coefficient of the clamped cosine max(cos theta, 0) convolved as in
 * Ramamoorthi & Hanrahan 2001: irradiance E_lm = A_l L_lm with
 * A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4, A_odd>1 = 0,
 * A_l(even) = 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2). */
LU_FN float lu_k_sh_lambert_band(int l) {
    if (l == 0) return LU_K_PI;
    if (l == 1) return 2.0f * LU_K_PI / 3.0f;
    if ((l & 1) == 1) return 0.0f;
    float fact_l = 1.0f, fact_h = 1.0f;
    for (int k = 2; k <= l; k++) fact_l *= lu_float(k);
    for (int k = 2; k <= l / 2; k++) fact_h *= lu_float(k);
    float sign = ((l / 2 - 1) & 1) == 1 ? -1.0f : 1.0f;
    return 2.0f * LU_K_PI * sign / (lu_float(l + 2) * lu_float(l - 1)) * fact_l /
           (lu_pow(2.0f, lu_float(l)) * fact_h * fact_h);
}

#endif
