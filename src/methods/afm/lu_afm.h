/* lu_afm.h — attenuation function maps (Delalandre et al.; kernel: C and GLSL).
 *
 * Map build (per light view, per texel): the texel's light ray (lu_lightview.h)
 * enters the media at depth K_in and leaves at K_out (union of every medium's
 * box clipped to its boundary span). The transmittance from the light,
 * f(s) = F(s) * exp(-sigma_t * tau(s)), s = (t - K_in) / (K_out - K_in), is
 * sampled at S points s_j = (j + 1/2) / S (exact cell-wise optical depth,
 * lu_march.h; F is the product of Fresnel transmittances of the boundary
 * crossings before s) and projected onto N DCT-II coefficients:
 *     c_0 = (1/S) sum_j f(s_j),  c_k = (2/S) sum_j f(s_j) cos(pi k s_j),
 *     f(s) ~ sum_k c_k cos(pi k s).
 * The cosine basis is the even extension of f, so a smooth monotone
 * transmittance has no end jump and converges fast; the Fresnel step at the
 * entry sits at s = 0, not inside the interval. Coloured extinction needs
 * one coefficient set per channel (C = 3); grey extinction (every medium's
 * sigma_t with equal channels) stores one (C = 1). Beside the coefficients
 * each texel keeps K_in, K_out and the transmittance past K_out (the
 * "tail": all crossings, exit Fresnel included), per channel.
 *
 * Lookup at a point x seen from light l: its view (cube face for point
 * lights), (u, v, depth); each of the 4 nearest texels gives
 *   depth <= K_in: 1;  depth >= K_out: tail;  else the DCT sum clamped to
 *   [tail, 1] (truncation ringing cannot leave the range a transmittance
 *   along that ray can take);
 * bilinearly weighted. Texels whose ray misses every medium store
 * K_in = K_out = LU_K_FAR (transmittance 1 everywhere); points outside every
 * view are outside the framed media's shadow volume: transmittance 1.
 *
 * Record of one texel (floats): [0] K_in, [1] K_out, [2..4] tail rgb,
 * [5] unused, then coefficient k of channel c at 6 + k * C + c.
 *
 * Hooks the backend defines before including this file (beside those of
 * lu_march.h and lu_medium.h: lu_k_density, lu_k_medium_count, lu_k_medium_get;
 * and lu_k_majorant of lu_march_blocks.h: the build skips empty blocks):
 *   build:  float lu_k_afm_lspan(LU_CTX_PARAM, int texel, int m, int k)
 *             k 0/1: start/end of medium m's first span on the texel's light ray
 *             (boundary mesh, from the CPU's ray tracer; unbounded: 0, LU_K_FAR),
 *             k 2/3: cosine between the ray and the boundary's normal at that
 *             start/end, or LU_K_AFM_NO_CROSSING where the span does not end on
 *             the boundary (the Fresnel factor is taken here with the medium's
 *             eta, so the spans depend on geometry and lights only);
 *           void lu_k_afm_store(LU_CTX_PARAM, int texel, int i, float value);
 *   lookup: float lu_k_afm_fetch(LU_CTX_PARAM, int texel, int i);
 *           int lu_k_afm_view_first(LU_CTX_PARAM, int l), lu_k_afm_view_count(LU_CTX_PARAM, int l);
 *           lu_k_lightview lu_k_afm_view(LU_CTX_PARAM, int v);
 *   render: int lu_k_afm_param(LU_CTX_PARAM, int i)  (i 0..3: res, coefs, samples, channels);
 *           float lu_k_afm_cam_normal(LU_CTX_PARAM, int pixel, int m, int k)
 *             (k 0..2: outward boundary normal where the camera ray enters medium m;
 *             zero when it does not enter), float lu_k_afm_surface(LU_CTX_PARAM, int m, int k)
 *             (medium m's boundary surface: 0..2 albedo, 3 shininess, 4..6 specular),
 *           float lu_k_afm_surface_vis(LU_CTX_PARAM, int pixel, int l)
 *             (opaque visibility of light l at the pixel's surface hit, traced exactly
 *             by the CPU: the seed reads the shadow map there, which leaks or
 *             bites at lit/shadowed edges on every pixel they cross),
 *           and the hooks of lu_view_march.h.
 * Texel index: (view * res + j) * res + i.
 *
 * Rendering reuses the raymarch method's view march (lu_view_march.h) with
 * the map lookup in place of its exact shadow-ray optical depth, plus the
 * boundary reflection of bounded media (Fresnel-weighted Blinn-Phong of the
 * boundary surface, lit through the maps), as the reference renders it. A
 * backend that only builds maps defines LU_K_AFM_MAP_ONLY (no lookup or
 * render hooks needed then). */
#ifndef LU_AFM_H
#define LU_AFM_H

#include "kernels/lu_kernel.h"
#include "methods/common/lu_lightview.h"
#include "methods/common/lu_march.h"
#include "methods/common/lu_march_blocks.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"

#define LU_K_AFM_MAX_COEFS 64
#define LU_K_AFM_MAX_SAMPLES 4096
#define LU_K_AFM_HEADER 6
/* Light-span cosine of a span end that is not a boundary crossing (|cos| <= 1 otherwise). */
#define LU_K_AFM_NO_CROSSING 2.0f

struct lu_k_afm_params {
    int res;        /* map resolution (res x res texels per view) */
    int coefs;      /* N */
    int samples;    /* S, transmittance samples along K_in..K_out */
    int channels;   /* C: 1 (grey extinction) or 3 */
};
LU_TYPEDEF(lu_k_afm_params)

/* One term of the cosine series by the Chebyshev recurrence
 * cos((k+1)a) = 2 cos(a) cos(ka) - cos((k-1)a) (one cosine per sample):
 * the build adds f cos(ka) to acc[k] (the lookup's terms: LU_K_AFM_T1).
 * Loops over k run these four at a time: llvmpipe stops a shader
 * invocation's loops after 65535 iterations in total, which a 500-step
 * march with two lights and 16 coefficients would otherwise pass. */
#define LU_K_AFM_ACC_TERM(k) \
    acc[k] = lu_v3_madd(acc[k], f, cur); \
    next = 2.0f * c1 * cur - prev; \
    prev = cur; \
    cur = next;

LU_FN int lu_k_afm_stride(lu_k_afm_params P) { return LU_K_AFM_HEADER + P.coefs * P.channels; }

/* Normalisation of summed projections over S samples: c_0 / S, c_k * 2 / S. */
LU_FN float lu_k_dct_norm(int k, int samples) { return (k == 0 ? 1.0f : 2.0f) / lu_float(samples); }

/* ---- map build ---- */

/* Unpolarised Fresnel transmittance where the texel's light ray crosses
 * medium m's boundary at span end k (2: start, 3: end), as the reference's
 * shadow rays (the cosine's sign does not matter); 1 without a crossing. */
LU_FN float lu_k_afm_crossing(LU_CTX_PARAM, int texel, int m, int k) {
    float c = lu_k_afm_lspan(LU_CTX, texel, m, k);
    return c == LU_K_AFM_NO_CROSSING ? 1.0f : lu_k_fresnel_transmittance(c, lu_k_medium_get(LU_CTX, m).eta);
}

/* sigma_t-weighted optical depth of every medium over (t0, t1] of the
 * texel's light ray, each clipped to its box and boundary span (exact per
 * cell, lu_march.h). */
LU_FN vec3 lu_k_afm_tau(LU_CTX_PARAM, int texel, lu_k_lightray ray, float t0, float t1) {
    vec3 tau = lu_v3s(0.0f);
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float lo = lu_k_afm_lspan(LU_CTX, texel, m, 0), hi = lu_k_afm_lspan(LU_CTX, texel, m, 1);
        float a = 0.0f, b = 0.0f;
        if (!(hi > lo) ||
            !lu_k_box_clip(md.bounds_lo, md.bounds_hi, ray.origin, ray.dir, lu_max(lo, t0), lu_min(hi, t1), LU_REF(a), LU_REF(b)))
            continue;
        float od = md.constant != 0 ? md.density_scale * (b - a)
                                    : lu_k_optical_depth_blocks(LU_CTX, m, lu_k_medium_point(md, ray.origin),
                                                                lu_k_medium_vector(md, ray.dir), a, b, md.max_pieces);
        tau = lu_v3_madd(tau, lu_k_medium_sigma_t(md), od);
    }
    return tau;
}

/* Builds texel (i, j) of view vw (global index `texel`); returns nothing, writes
 * the record through lu_k_afm_store. */
LU_FN void lu_k_afm_build_texel(LU_CTX_PARAM, lu_k_afm_params P, lu_k_lightview vw, int texel, int i, int j) {
    lu_k_lightray ray = lu_k_lightview_ray(vw, (lu_float(i) + 0.5f) / lu_float(P.res), (lu_float(j) + 0.5f) / lu_float(P.res));
    int nm = lu_k_medium_count(LU_CTX);
    float k_in = LU_K_FAR, k_out = 0.0f;
    float fresnel_total = 1.0f;
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float a = 0.0f, b = 0.0f;
        float lo = lu_k_afm_lspan(LU_CTX, texel, m, 0), hi = lu_k_afm_lspan(LU_CTX, texel, m, 1);
        if (!(hi > lo) || !lu_k_box_clip(md.bounds_lo, md.bounds_hi, ray.origin, ray.dir, lo, hi, LU_REF(a), LU_REF(b)))
            continue;
        k_in = lu_min(k_in, a);
        k_out = lu_max(k_out, b);
        /* Fresnel counts where the boundary is crossed, even if the box clips
         * the density span shorter. */
        fresnel_total *= lu_k_afm_crossing(LU_CTX, texel, m, 2) * lu_k_afm_crossing(LU_CTX, texel, m, 3);
    }
    if (!(k_out > k_in)) {
        /* The ray misses every medium: transmittance 1 at every depth. */
        lu_k_afm_store(LU_CTX, texel, 0, LU_K_FAR);
        lu_k_afm_store(LU_CTX, texel, 1, LU_K_FAR);
        for (int c = 2; c < lu_k_afm_stride(P); c++) lu_k_afm_store(LU_CTX, texel, c, c < 5 ? 1.0f : 0.0f);
        return;
    }
    vec3 acc[LU_K_AFM_MAX_COEFS];
    for (int k = 0; k < LU_K_AFM_MAX_COEFS; k++) acc[k] = lu_v3s(0.0f);
    int S = P.samples;
    float len = k_out - k_in;
    vec3 tau = lu_v3s(0.0f);
    float t_prev = k_in;
    for (int s = 0; s < S; s++) {
        float u = (lu_float(s) + 0.5f) / lu_float(S);
        float t = k_in + u * len;
        float fres = 1.0f;
        for (int m = 0; m < nm; m++) {
            float lo = lu_k_afm_lspan(LU_CTX, texel, m, 0), hi = lu_k_afm_lspan(LU_CTX, texel, m, 1);
            if (!(hi > lo)) continue;
            if (t > lo) fres *= lu_k_afm_crossing(LU_CTX, texel, m, 2);
            if (t > hi) fres *= lu_k_afm_crossing(LU_CTX, texel, m, 3);
        }
        tau = lu_v3_add(tau, lu_k_afm_tau(LU_CTX, texel, ray, t_prev, t));
        t_prev = t;
        vec3 f = lu_v3_scale(lu_v3_exp(lu_v3_neg(tau)), fres);
        /* f * cos(pi k u) for every k by the Chebyshev recurrence
         * cos((k+1)a) = 2 cos(a) cos(ka) - cos((k-1)a): one cosine per sample. */
        float c1 = lu_cos(LU_K_PI * u);
        float prev = 1.0f, cur = c1;
        float next = 0.0f;
        acc[0] = lu_v3_add(acc[0], f);
        int k = 1;
        for (; k + 3 < P.coefs; k += 4) {
            LU_K_AFM_ACC_TERM(k) LU_K_AFM_ACC_TERM(k + 1) LU_K_AFM_ACC_TERM(k + 2) LU_K_AFM_ACC_TERM(k + 3)
        }
        for (; k < P.coefs; k++) {
            LU_K_AFM_ACC_TERM(k)
        }
    }
    /* The rest of the way to K_out, for the tail. */
    tau = lu_v3_add(tau, lu_k_afm_tau(LU_CTX, texel, ray, t_prev, k_out));
    vec3 tail = lu_v3_scale(lu_v3_exp(lu_v3_neg(tau)), fresnel_total);
    lu_k_afm_store(LU_CTX, texel, 0, k_in);
    lu_k_afm_store(LU_CTX, texel, 1, k_out);
    lu_k_afm_store(LU_CTX, texel, 2, tail.x);
    lu_k_afm_store(LU_CTX, texel, 3, tail.y);
    lu_k_afm_store(LU_CTX, texel, 4, tail.z);
    lu_k_afm_store(LU_CTX, texel, 5, 0.0f);
    for (int k = 0; k < P.coefs; k++) {
        vec3 c = lu_v3_scale(acc[k], lu_k_dct_norm(k, S));
        int base = LU_K_AFM_HEADER + k * P.channels;
        lu_k_afm_store(LU_CTX, texel, base, c.x);
        if (P.channels == 3) {
            lu_k_afm_store(LU_CTX, texel, base + 1, c.y);
            lu_k_afm_store(LU_CTX, texel, base + 2, c.z);
        }
    }
}

#ifndef LU_K_AFM_MAP_ONLY
/* ---- lookup ---- */

/* The lookup evaluates the 4 texels of a bilinear footprint together: the
 * series of one texel is a chain of dependent multiply-adds (the Chebyshev
 * recurrence and the sum), so four of them run side by side, one per lane
 * of a vec4 (measured: docs/afm.md, "Speed"). Each texel's arithmetic is
 * the one a texel evaluated alone would do, in the same order: only the
 * schedule changes, not the result. */

/* Where depth falls on the light ray of the texel record at `base`:
 * s = (depth - K_in) / (K_out - K_in) in (0, 1) where the series applies;
 * -1 at or before K_in (transmittance 1), -2 at or after K_out (the tail). */
LU_FN float lu_k_afm_depth_s(LU_CTX_PARAM, int base, float depth) {
    float k_in = lu_k_afm_fetch(LU_CTX, base, 0);
    if (depth <= k_in) return -1.0f;
    float k_out = lu_k_afm_fetch(LU_CTX, base, 1);
    if (depth >= k_out) return -2.0f;
    return (depth - k_in) / (k_out - k_in);
}

/* cos(pi s) for s in [0, 1] as sin(x), x = pi (1/2 - s) in [-pi/2, pi/2],
 * by its Taylor polynomial to x^13: the remainder is below
 * (pi/2)^15 / 15! = 7e-10, so the result is cos to float rounding (~1e-7),
 * inline, without libm's range reduction (cosf was ~5 % of an afm frame). */
LU_FN float lu_k_afm_cos_pi(float s) {
    float x = LU_K_PI * (0.5f - s), x2 = x * x;
    float p = 1.0f / 6227020800.0f;
    p = p * x2 - 1.0f / 39916800.0f;
    p = p * x2 + 1.0f / 362880.0f;
    p = p * x2 - 1.0f / 5040.0f;
    p = p * x2 + 1.0f / 120.0f;
    p = p * x2 - 1.0f / 6.0f;
    return x + x * x2 * p;
}

/* 2 cos(pi s), the Chebyshev recurrence's factor, for s from lu_k_afm_depth_s
 * (0 where no series is needed: the texel's loop then runs on zeros). */
LU_FN float lu_k_afm_rec_factor(float s) { return s >= 0.0f ? 2.0f * lu_k_afm_cos_pi(s) : 0.0f; }

/* The texel's transmittance from its summed series f: 1 before K_in, the
 * tail after K_out, else f clamped into [tail, 1] (truncation ringing cannot
 * leave the range a transmittance along that ray can take). */
LU_FN vec3 lu_k_afm_texel_value(LU_CTX_PARAM, int base, float s, vec3 f) {
    if (s == -1.0f) return lu_v3s(1.0f);
    vec3 tail = lu_v3(lu_k_afm_fetch(LU_CTX, base, 2), lu_k_afm_fetch(LU_CTX, base, 3), lu_k_afm_fetch(LU_CTX, base, 4));
    if (s < 0.0f) return tail;
    return lu_v3(lu_clamp(f.x, tail.x, 1.0f), lu_clamp(f.y, tail.y, 1.0f), lu_clamp(f.z, tail.z, 1.0f));
}

/* The 4 texels' series run side by side in the lanes of a vec4 (one SSE
 * register on the CPU): coefficient i of the 4 records, and term k of the
 * grey (g) or coloured (r, gg, bb) series with its Chebyshev step
 * cos((k+1)a) = 2 cos(a) cos(ka) - cos((k-1)a), m = 2 cos(a) per lane. */
#define LU_K_AFM_COEF4(i) \
    lu_v4(lu_k_afm_fetch(LU_CTX, b0, i), lu_k_afm_fetch(LU_CTX, b1, i), lu_k_afm_fetch(LU_CTX, b2, i), \
          lu_k_afm_fetch(LU_CTX, b3, i))
#define LU_K_AFM_REC4 \
    nx = m * cur - prev; \
    prev = cur; \
    cur = nx;
#define LU_K_AFM_T1X4(k) \
    g = g + LU_K_AFM_COEF4(LU_K_AFM_HEADER + (k)) * cur; \
    LU_K_AFM_REC4
#define LU_K_AFM_T3X4(k) \
    r = r + LU_K_AFM_COEF4(LU_K_AFM_HEADER + 3 * (k)) * cur; \
    gg = gg + LU_K_AFM_COEF4(LU_K_AFM_HEADER + 3 * (k) + 1) * cur; \
    bb = bb + LU_K_AFM_COEF4(LU_K_AFM_HEADER + 3 * (k) + 2) * cur; \
    LU_K_AFM_REC4

/* Transmittance from light l to x, bilinear over the 4 nearest texels. */
LU_FN vec3 lu_k_afm_transmittance(LU_CTX_PARAM, lu_k_afm_params P, int l, vec3 x) {
    int count = lu_k_afm_view_count(LU_CTX, l);
    if (count <= 0) return lu_v3s(1.0f);
    int first = lu_k_afm_view_first(LU_CTX, l);
    lu_k_lightview v0 = lu_k_afm_view(LU_CTX, first);
    int face = count == 6 ? lu_k_cube_face(lu_v3_sub(x, v0.origin)) : 0;
    lu_k_lightview vw = face == 0 ? v0 : lu_k_afm_view(LU_CTX, first + face);
    vec3 uvd = lu_k_lightview_project(vw, x);
    if (!lu_k_lightview_inside(uvd)) return lu_v3s(1.0f);
    float fx = uvd.x * lu_float(P.res) - 0.5f, fy = uvd.y * lu_float(P.res) - 0.5f;
    float x0 = lu_floor(fx), y0 = lu_floor(fy);
    float ax = fx - x0, ay = fy - y0;
    int view_base = (first + face) * P.res * P.res;
    float hi = lu_float(P.res - 1);
    int xa = lu_int(lu_clamp(x0, 0.0f, hi)), xb = lu_int(lu_clamp(x0 + 1.0f, 0.0f, hi));
    int ya = view_base + P.res * lu_int(lu_clamp(y0, 0.0f, hi)), yb = view_base + P.res * lu_int(lu_clamp(y0 + 1.0f, 0.0f, hi));
    int stride = lu_k_afm_stride(P);
    /* Texels (xa, ya), (xb, ya), (xa, yb), (xb, yb); a texel of weight 0
     * (ax or ay exactly 0) is evaluated but not added. */
    int b0 = (ya + xa) * stride, b1 = (ya + xb) * stride, b2 = (yb + xa) * stride, b3 = (yb + xb) * stride;
    float s0 = lu_k_afm_depth_s(LU_CTX, b0, uvd.z), s1 = lu_k_afm_depth_s(LU_CTX, b1, uvd.z);
    float s2 = lu_k_afm_depth_s(LU_CTX, b2, uvd.z), s3 = lu_k_afm_depth_s(LU_CTX, b3, uvd.z);
    vec3 f0 = lu_v3s(0.0f), f1 = lu_v3s(0.0f), f2 = lu_v3s(0.0f), f3 = lu_v3s(0.0f);
    if (lu_max(lu_max(s0, s1), lu_max(s2, s3)) >= 0.0f) {
        vec4 m = lu_v4(lu_k_afm_rec_factor(s0), lu_k_afm_rec_factor(s1), lu_k_afm_rec_factor(s2), lu_k_afm_rec_factor(s3));
        vec4 prev = lu_v4s(1.0f), cur = 0.5f * m, nx = lu_v4s(0.0f);
        /* Loops run four terms per iteration: llvmpipe stops a shader
         * invocation's loops after 65535 iterations in total, which a
         * 500-step march with two lights would otherwise pass. */
        int k = 1;
        if (P.channels == 3) {
            vec4 r = LU_K_AFM_COEF4(6), gg = LU_K_AFM_COEF4(7), bb = LU_K_AFM_COEF4(8);
            for (; k + 3 < P.coefs; k += 4) {
                LU_K_AFM_T3X4(k) LU_K_AFM_T3X4(k + 1) LU_K_AFM_T3X4(k + 2) LU_K_AFM_T3X4(k + 3)
            }
            for (; k < P.coefs; k++) {
                LU_K_AFM_T3X4(k)
            }
            f0 = lu_v3(r[0], gg[0], bb[0]);
            f1 = lu_v3(r[1], gg[1], bb[1]);
            f2 = lu_v3(r[2], gg[2], bb[2]);
            f3 = lu_v3(r[3], gg[3], bb[3]);
        } else {
            vec4 g = LU_K_AFM_COEF4(6);
            for (; k + 3 < P.coefs; k += 4) {
                LU_K_AFM_T1X4(k) LU_K_AFM_T1X4(k + 1) LU_K_AFM_T1X4(k + 2) LU_K_AFM_T1X4(k + 3)
            }
            for (; k < P.coefs; k++) {
                LU_K_AFM_T1X4(k)
            }
            f0 = lu_v3s(g[0]);
            f1 = lu_v3s(g[1]);
            f2 = lu_v3s(g[2]);
            f3 = lu_v3s(g[3]);
        }
    }
    vec3 T = lu_v3_scale(lu_k_afm_texel_value(LU_CTX, b0, s0, f0), (1.0f - ax) * (1.0f - ay));
    if (ax > 0.0f) T = lu_v3_madd(T, lu_k_afm_texel_value(LU_CTX, b1, s1, f1), ax * (1.0f - ay));
    if (ay > 0.0f) T = lu_v3_madd(T, lu_k_afm_texel_value(LU_CTX, b2, s2, f2), (1.0f - ax) * ay);
    if (ax > 0.0f && ay > 0.0f) T = lu_v3_madd(T, lu_k_afm_texel_value(LU_CTX, b3, s3, f3), ax * ay);
    return T;
}

LU_FN lu_k_afm_params lu_k_afm_params_get(LU_CTX_PARAM) {
    lu_k_afm_params P;
    P.res = lu_k_afm_param(LU_CTX, 0);
    P.coefs = lu_k_afm_param(LU_CTX, 1);
    P.samples = lu_k_afm_param(LU_CTX, 2);
    P.channels = lu_k_afm_param(LU_CTX, 3);
    return P;
}

/* Include this file, not lu_view_march.h, first: the march must see the hook.
 * (Only a compile check that includes every kernel reaches the #else.) */
#ifndef LU_RAYMARCH_H
#define LU_K_RM_LIGHT_TR(l, x, ls) lu_k_afm_transmittance(LU_CTX, lu_k_afm_params_get(LU_CTX), l, x)
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_afm_surface_vis(LU_CTX, pixel, l)
#endif
#include "methods/common/lu_view_march.h"

/* Light reflected by the boundaries of bounded media where the camera ray
 * enters them: F_r * Blinn-Phong of the boundary surface, lit through the
 * maps and the shadow maps. The camera transmittance before the entry is
 * taken as 1 (exact when no other medium lies in front). */
LU_FN vec3 lu_k_afm_boundary_reflection(LU_CTX_PARAM, lu_k_afm_params P, lu_k_rm_params R, int pixel, vec3 o, vec3 d) {
    vec3 L = lu_v3s(0.0f);
    int nm = lu_k_medium_count(LU_CTX);
    int nl = lu_k_light_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        if (md.bounded == 0) continue;
        vec3 n = lu_v3(lu_k_afm_cam_normal(LU_CTX, pixel, m, 0), lu_k_afm_cam_normal(LU_CTX, pixel, m, 1),
                       lu_k_afm_cam_normal(LU_CTX, pixel, m, 2));
        if (lu_v3_dot(n, n) <= 0.0f) continue;
        float te = lu_k_rm_span(LU_CTX, pixel, m, 0);
        vec3 x = lu_v3_madd(lu_v3_madd(o, d, te), n, R.eps);
        float fr = lu_k_fresnel_reflectance(lu_v3_dot(n, d), md.eta);
        vec3 albedo = lu_v3(lu_k_afm_surface(LU_CTX, m, 0), lu_k_afm_surface(LU_CTX, m, 1), lu_k_afm_surface(LU_CTX, m, 2));
        vec3 spec = lu_v3(lu_k_afm_surface(LU_CTX, m, 4), lu_k_afm_surface(LU_CTX, m, 5), lu_k_afm_surface(LU_CTX, m, 6));
        float shin = lu_k_afm_surface(LU_CTX, m, 3);
        vec3 wo = lu_v3_neg(d);
        for (int l = 0; l < nl; l++) {
            lu_k_light_sample ls = lu_k_light_arrive(lu_k_light_get(LU_CTX, l), x);
            vec3 f = lu_k_blinn_phong(albedo, spec, shin, n, wo, ls.wl);
            if (lu_v3_maxc(f) <= 0.0f || lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
            float vis = lu_k_rm_visibility(LU_CTX, l, x, n, R.map_res);
            if (vis <= 0.0f) continue;
            vec3 T = lu_k_afm_transmittance(LU_CTX, P, l, x);
            L = lu_v3_add(L, lu_v3_scale(lu_v3_mul(lu_v3_mul(f, ls.irradiance), T), vis * fr));
        }
    }
    return L;
}

/* Radiance along the camera ray of `pixel` (u: where in each step the sample sits). */
LU_FN vec3 lu_k_afm_radiance(LU_CTX_PARAM, lu_k_afm_params P, lu_k_rm_params R, int pixel, vec3 o, vec3 d, float u) {
    return lu_v3_add(lu_k_rm_radiance(LU_CTX, R, pixel, o, d, u), lu_k_afm_boundary_reflection(LU_CTX, P, R, pixel, o, d));
}
#endif

#endif
