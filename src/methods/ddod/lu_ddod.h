/* lu_ddod.h — the ddod method's per-sample and per-pixel math (kernel: C
 * and GLSL). Bernabei et al., "Real-time single scattering inside
 * inhomogeneous materials", Eq. 3:
 *
 *   L_ss(x, w) ~ sum_i  k sigma_s(b_i) psi_i(-w)  *  sum_l psi^F_i(w_l) E_l(b_i)  *  int_x^y gamma_i
 *                       (per sample, per frame: pass 1)                     (per pixel: pass 2)
 *
 * psi_i(w) = exp(-sigma_t tau(b_i, w)) is the attenuation from sample b_i to
 * the boundary along w, psi^F_i the same times the Fresnel transmittance of
 * the boundary crossings on the way (light entering the object, docs/architecture.md §1),
 * both stored as real SH (lu_sh.h) per colour channel; by default (an
 * extension, ddod.view_psi / light_psi = traced) the two values pass 1 needs,
 * towards the camera and towards each light, come exact from a table the
 * CPU traces when the camera or a light moves (methods/ddod/ddod.c), and the SH
 * serve environment light. gamma_i(x) =
 * A_i exp(-|x - b_i|^2 / (2 s_i^2)) is the sample's Gaussian, integrated in
 * closed form (erf) along the camera ray between the boundary's entry and
 * exit (or the first opaque hit), so the silhouette is the mesh's.
 *
 * Pass 1 (lu_k_ddod_sample_radiance), one per sample per frame: k sigma_s
 * D(b_i) psi_i(towards the camera) sum_l p psi^F_i(w_l) E_l. The view
 * direction is taken at the sample's centre: across one ball it turns by
 * about s_i / distance (under 2 degrees in the bundled scenes), the same
 * "constant over the ball" approximation the paper makes for f. Lights cost
 * one table read (or one SH evaluation) each here, never per pixel, hence
 * the sub-linear cost in the number of lights (the paper's Table 3).
 *
 * Pass 2 (lu_k_ddod_pixel), one per pixel: sum over the pixel's tile list of
 * f_i * int gamma_i. With `normalize` (an extension, on by default) the sum
 * is divided by sum_i int gamma_i and multiplied by the ray's length in the
 * medium: the Gaussians then act as a partition of unity along every ray
 * (Shepard weights), which removes the bias of sum_i gamma_i != 1 near the
 * boundary and between unevenly spaced samples.
 *
 * Hooks the backend defines before including this file:
 *   float lu_k_ddod_sample_f(LU_CTX_PARAM, int i, int k);  float k of sample i (LU_K_DDOD_SAMPLE_*)
 *   float lu_k_ddod_coeff(LU_CTX_PARAM, int index);        the flat SH array (sample-major)
 *   vec3 lu_k_ddod_radiance(LU_CTX_PARAM, int i);          pass 1's output for sample i
 *   float lu_k_ddod_pixel_f(LU_CTX_PARAM, int pixel, int k);  LU_K_DDOD_PIXEL_* of a pixel
 *   int lu_k_ddod_tile_start(LU_CTX_PARAM, int tile);  int lu_k_ddod_tile_item(LU_CTX_PARAM, int k);
 *   vec3 lu_k_ddod_env_coeff(LU_CTX_PARAM, int k);         environment SH (rgb), k < bands^2
 *   vec3 lu_k_ddod_traced(LU_CTX_PARAM, int k);            the CPU's traced table (rgb): per sample i
 *       1 + lights entries, k = i (1 + lights): psi towards the camera, k + 1 + l: psi^F towards light l
 *   int lu_k_medium_count / lu_k_medium_get, lu_k_light_count / lu_k_light_get (as lu_view_march.h). */
#ifndef LU_DDOD_H
#define LU_DDOD_H

#include "kernels/lu_kernel.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "methods/common/lu_sh.h"
#include "lu_ddod_layout.h"


/* erf by Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7): GLSL has no erf, and
 * one formula on both backends keeps them equal. */
LU_FN float lu_k_erf(float x) {
    float ax = lu_abs(x);
    float t = 1.0f / (1.0f + 0.3275911f * ax);
    float y = 1.0f - (((((1.061405429f * t - 1.453152027f) * t) + 1.421413741f) * t - 0.284496736f) * t +
                      0.254829592f) *
                         t * lu_exp(-ax * ax);
    return x < 0.0f ? -y : y;
}

/* int_{t0}^{t1} exp(-|o + t d - b|^2 / (2 s^2)) dt for unit d: with tc the
 * ray parameter closest to b and h its distance, the integrand is
 * exp(-h^2/2s^2) exp(-(t - tc)^2/2s^2), whose integral is erf. */
LU_FN float lu_k_ddod_gauss_line(vec3 o, vec3 d, vec3 b, float s, float t0, float t1) {
    if (!(t1 > t0)) return 0.0f;
    vec3 ob = lu_v3_sub(b, o);
    float tc = lu_v3_dot(ob, d);
    float h2 = lu_max(lu_v3_dot(ob, ob) - tc * tc, 0.0f);
    float k = 0.70710678f / s;
    return lu_exp(-0.5f * h2 / (s * s)) * s * 1.25331414f * (lu_k_erf((t1 - tc) * k) - lu_k_erf((t0 - tc) * k));
}

/* sum_k c[base + k] Y_k(dir) over bands^2 coefficients. */
LU_FN float lu_k_ddod_sh_dot(LU_CTX_PARAM, int base, int bands, vec3 dir) {
    float y[LU_SH_MAX_COEFFS];
    lu_k_sh_eval(dir, bands, y);
    float acc = 0.0f;
    for (int k = 0; k < bands * bands; k++) acc += lu_k_ddod_coeff(LU_CTX, base + k) * y[k];
    return acc;
}

/* psi (set 0) or psi^F (set 1) of sample i towards unit dir, per channel,
 * clamped to [0, 1] (SH truncation rings below 0 and above 1). */
LU_FN vec3 lu_k_ddod_psi(LU_CTX_PARAM, lu_k_ddod_params P, int i, int set, vec3 dir) {
    float y[LU_SH_MAX_COEFFS];
    lu_k_sh_eval(dir, P.bands, y);
    int n = P.bands * P.bands;
    float v[LU_K_DDOD_MAX_CHANNELS];
    for (int c = 0; c < P.channels; c++) {
        int base = i * P.stride + (set * P.channels + c) * n;
        float acc = 0.0f;
        for (int k = 0; k < n; k++) acc += lu_k_ddod_coeff(LU_CTX, base + k) * y[k];
        v[c] = lu_clamp(acc, 0.0f, 1.0f);
    }
    if (P.channels == 1) return lu_v3s(v[0]);
    return lu_v3(v[0], v[1], v[2]);
}

/* Pass 1: radiance factor f_i of sample i seen from cam (everything of
 * Eq. 3 but the line integral). */
LU_FN vec3 lu_k_ddod_sample_radiance(LU_CTX_PARAM, lu_k_ddod_params P, int i, vec3 cam) {
    vec3 b = lu_v3(lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X), lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X + 1),
                   lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X + 2));
    float dens = lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_DENSITY);
    lu_k_medium md = lu_k_medium_get(LU_CTX, lu_int(lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_MEDIUM)));
    if (dens <= 0.0f || lu_v3_maxc(md.sigma_s) <= 0.0f) return lu_v3s(0.0f);
    vec3 to_cam = lu_v3_norm(lu_v3_sub(cam, b));
    vec3 w = lu_v3_neg(to_cam);  /* the camera ray's direction at the sample */
    int nl = lu_k_light_count(LU_CTX);
    int row = i * (nl + 1);
    /* Traced (the default, an extension): psi exactly at this sample's
     * camera and light directions, from the CPU's table. psi near a flat
     * face falls from ~1 to the far side's value within a few degrees of the
     * face's plane, and a light just outside a face switches psi^F from ~F_t
     * to ~0 there: 25 SH coefficients smear both (docs/ddod.md). The SH
     * sets stay for environment light and for ddod.*_psi = sh. */
    vec3 view = (P.traced & LU_K_DDOD_TRACED_VIEW) != 0 ? lu_k_ddod_traced(LU_CTX, row) : lu_k_ddod_psi(LU_CTX, P, i, 0, to_cam);
    if (lu_v3_maxc(view) <= 0.0f) return lu_v3s(0.0f);
    vec3 S = lu_v3s(0.0f);
    for (int l = 0; l < nl; l++) {
        lu_k_light_sample ls = lu_k_light_arrive(lu_k_light_get(LU_CTX, l), b);
        if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        vec3 att = (P.traced & LU_K_DDOD_TRACED_LIGHTS) != 0 ? lu_k_ddod_traced(LU_CTX, row + 1 + l)
                                                             : lu_k_ddod_psi(LU_CTX, P, i, 1, ls.wl);
        S = lu_v3_add(S, lu_v3_scale(lu_v3_mul(att, ls.irradiance), lu_k_phase_hg(lu_v3_dot(w, ls.wl), md.g)));
    }
    if (P.env != 0) {
        /* Environment light: int psi^F L_env / (4 pi) = dot of the two SH
         * vectors (isotropic phase; a g != 0 medium is treated as g = 0 here). */
        int n = P.bands * P.bands;
        vec3 e = lu_v3s(0.0f);
        for (int c = 0; c < 3; c++) {
            int cc = P.channels == 1 ? 0 : c;
            int base = i * P.stride + (P.channels + cc) * n;
            float acc = 0.0f;
            for (int k = 0; k < n; k++) acc += lu_k_ddod_coeff(LU_CTX, base + k) * lu_v3_get(lu_k_ddod_env_coeff(LU_CTX, k), c);
            if (c == 0) e.x = acc;
            else if (c == 1) e.y = acc;
            else e.z = acc;
        }
        S = lu_v3_add(S, lu_v3_scale(lu_v3_max(e, lu_v3s(0.0f)), LU_K_INV_4PI));
    }
    return lu_v3_scale(lu_v3_mul(lu_v3_mul(md.sigma_s, view), S), dens);
}

/* Pass 2: in-scattered radiance plus the pixel's surface term, for the
 * camera ray o + t d (unit d) of `pixel` in `tile`. */
LU_FN vec3 lu_k_ddod_pixel(LU_CTX_PARAM, lu_k_ddod_params P, int pixel, int tile, vec3 o, vec3 d) {
    float t0 = lu_k_ddod_pixel_f(LU_CTX, pixel, LU_K_DDOD_PIXEL_T0);
    float t1 = lu_k_ddod_pixel_f(LU_CTX, pixel, LU_K_DDOD_PIXEL_T1);
    vec3 surface = lu_v3(lu_k_ddod_pixel_f(LU_CTX, pixel, LU_K_DDOD_PIXEL_SURFACE),
                         lu_k_ddod_pixel_f(LU_CTX, pixel, LU_K_DDOD_PIXEL_SURFACE + 1),
                         lu_k_ddod_pixel_f(LU_CTX, pixel, LU_K_DDOD_PIXEL_SURFACE + 2));
    if (!(t1 > t0)) return surface;
    vec3 acc = lu_v3s(0.0f);
    float wsum = 0.0f;
    int k1 = lu_k_ddod_tile_start(LU_CTX, tile + 1);
    for (int k = lu_k_ddod_tile_start(LU_CTX, tile); k < k1; k++) {
        int i = lu_k_ddod_tile_item(LU_CTX, k);
        vec3 b = lu_v3(lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X), lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X + 1),
                       lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_X + 2));
        float s = lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_S);
        /* The ball of radius CUTOFF s: clip the ray to it (the paper's
         * max(surface depth, ball entry) .. ball exit) and to [t0, t1]. */
        vec3 ob = lu_v3_sub(b, o);
        float tc = lu_v3_dot(ob, d);
        float r = LU_K_DDOD_CUTOFF * s;
        float h2 = lu_v3_dot(ob, ob) - tc * tc;
        if (h2 >= r * r) continue;
        float half_chord = lu_sqrt(r * r - h2);
        float a = lu_max(t0, tc - half_chord), e = lu_min(t1, tc + half_chord);
        if (!(e > a)) continue;
        float g = lu_k_ddod_sample_f(LU_CTX, i, LU_K_DDOD_SAMPLE_AMP) * lu_k_ddod_gauss_line(o, d, b, s, a, e);
        acc = lu_v3_madd(acc, lu_k_ddod_radiance(LU_CTX, i), g);
        wsum += g;
    }
    if (P.normalize != 0) acc = wsum > 0.0f ? lu_v3_scale(acc, (t1 - t0) / wsum) : lu_v3s(0.0f);
    return lu_v3_add(surface, acc);
}

#endif
