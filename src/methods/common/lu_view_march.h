/* lu_view_march.h — the raymarch method's per-pixel math (kernel: C and GLSL).
 *
 * Fixed-step single scattering: the camera ray is walked through the union
 * of the media's boxes in steps of one length (midpoint of each step, or a
 * per-pixel jittered point); at each sample every light's contribution
 * uses the EXACT optical depth to the light (lu_march.h, the reference's
 * transmittance kernel) times shadow-map visibility of opaque objects
 * (lu_shadowmap.h with light views, lu_lightview.h). Inside a step the
 * extinction is taken as constant, so the step's in-scattering integrates
 * analytically: T_a * S * (1 - exp(-sigma_t h)) / sigma_t. The camera ray's
 * first opaque hit and each bounded medium's span along it come from
 * per-pixel buffers the CPU fills with Embree, read identically by both
 * backends.
 *
 * Hooks the backend defines before including this file:
 *   float lu_k_density(LU_CTX_PARAM, int m, vec3 p_index);
 *   int lu_k_medium_count(LU_CTX_PARAM);  lu_k_medium lu_k_medium_get(LU_CTX_PARAM, int m);
 *   int lu_k_light_count(LU_CTX_PARAM);   lu_k_light lu_k_light_get(LU_CTX_PARAM, int l);
 *   float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j);
 *   int lu_k_rm_view_first(LU_CTX_PARAM, int l);  int lu_k_rm_view_count(LU_CTX_PARAM, int l);
 *   lu_k_lightview lu_k_rm_view(LU_CTX_PARAM, int v);
 *   float lu_k_rm_hit_fetch(LU_CTX_PARAM, int pixel, int k);   (float k of the pixel's lu_k_rm_hit)
 *   float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int end);   (end 0: start t, 1: end t)
 *   float lu_k_majorant(LU_CTX_PARAM, int m, int bx, int by, int bz);   (lu_march_blocks.h)
 *   vec3 lu_k_emission(LU_CTX_PARAM, int m, vec3 p_index);   (Le before sigma_a and density)
 *
 * Emission (media with md.emission != 0) joins the source term: each step's
 * S gains sum over media of density sigma_a Le at the sample, integrated
 * with the same step weight as the in-scattering (include/lucent/scene.h's
 * sigma_a Le convention). It is added outside LU_K_RM_INSCATTER, so a method
 * with its own in-scattering estimate (gradient) adds exact emission.
 *
 * Two savings leave the integral as it is or within a stated bound:
 *   - empty-space skipping: march steps whose sample lies in a block of zero
 *     majorant for every medium present are not taken (their density is
 *     exactly 0, so they added nothing), and shadow rays integrate only the
 *     blocks with density (lu_k_optical_depth_blocks);
 *   - early termination: once the camera ray's transmittance T (largest
 *     channel) is below P.t_cut the march stops and the ray's end (surface or
 *     background) is left out. What is dropped is T(t_c) L(t_c), the radiance
 *     arriving at the cut point from beyond it, attenuated by T(t_c) < t_cut:
 *     at most t_cut * max(L_end, max over the rest of the ray of
 *     albedo * phase * E_in + (sigma_a / sigma_t) Le), since the source left behind is
 *     int T S dt <= max(S / sigma_t) int sigma_t T dt <= T(t_c) max(S / sigma_t)
 *     with S / sigma_t = albedo * phase * E * T_l * V (single scattering)
 *     plus (sigma_a / sigma_t) Le for emission: an emissive region behind an
 *     opaque-looking one is dropped with at most T(t_c) times its Le, so
 *     with bright emission the cut's absolute error scales with Le_max
 *     (docs/volumes.md states the bound for the explosion scene).
 *     A march that ends with T < t_cut drops its end term by the same rule.
 *     t_cut = 0 is the full march.
 *
 * Multiple scattering, when P.ms asks for it, is approximated by
 * Wrenninge's octaves in the in-scattering (lu_ms.h, lu_k_rm_inscatter_ms;
 * docs/multiple-scattering.md); the early-termination bound then holds with
 * the octaves' sum in place of the phase.
 *
 * Simplifications against the reference (stated in docs/gpu.md): shadow rays
 * clip media to their world boxes, not to boundary meshes, and carry no
 * Fresnel factor; boundary reflection and environment lights are not
 * rendered; a bounded medium is present on the camera ray in its first span. */
#ifndef LU_RAYMARCH_H
#define LU_RAYMARCH_H

#include "kernels/lu_hash.h"
#include "kernels/lu_kernel.h"
#include "lu_lightview.h"
#include "lu_march.h"
#include "lu_march_blocks.h"
#include "kernels/lu_medium.h"
#include "lu_ms.h"
#include "lu_near_light.h"
#include "kernels/lu_optics.h"
#include "lu_shadowmap.h"

#define LU_K_RM_MAX_MEDIA 8
#define LU_K_RM_MAX_STEPS 65536
#ifdef LU_GLSL
#define LU_K_RM_UINT(x) uint(x)
#else
#define LU_K_RM_UINT(x) ((uint)(x))
#endif

/* Camera-ray hit of an opaque object: 16 floats (every vec3 followed by a
 * scalar), so the CPU array is also the GPU's float buffer. */
struct lu_k_rm_hit {
    vec3 n;            /* shading normal facing the viewer */
    float t;           /* < 0: no opaque hit */
    vec3 ng;           /* geometric normal facing the viewer */
    float pad0;
    vec3 albedo;
    float shininess;
    vec3 specular;
    float pad1;
};
LU_TYPEDEF(lu_k_rm_hit)
#define LU_K_RM_HIT_FLOATS 16

LU_FN vec3 lu_k_rm_hit_fetch3(LU_CTX_PARAM, int pixel, int k) {
    return lu_v3(lu_k_rm_hit_fetch(LU_CTX, pixel, k), lu_k_rm_hit_fetch(LU_CTX, pixel, k + 1),
                 lu_k_rm_hit_fetch(LU_CTX, pixel, k + 2));
}

LU_FN lu_k_rm_hit lu_k_rm_hit_get(LU_CTX_PARAM, int pixel) {
    lu_k_rm_hit h;
    h.n = lu_k_rm_hit_fetch3(LU_CTX, pixel, 0);
    h.t = lu_k_rm_hit_fetch(LU_CTX, pixel, 3);
    h.ng = lu_k_rm_hit_fetch3(LU_CTX, pixel, 4);
    h.pad0 = 0.0f;
    h.albedo = lu_k_rm_hit_fetch3(LU_CTX, pixel, 8);
    h.shininess = lu_k_rm_hit_fetch(LU_CTX, pixel, 11);
    h.specular = lu_k_rm_hit_fetch3(LU_CTX, pixel, 12);
    h.pad1 = 0.0f;
    return h;
}

struct lu_k_rm_params {
    vec3 background;
    float step;        /* world length of one march step */
    float eps;         /* offset off surfaces */
    int jitter;        /* 1: each pixel's samples shifted by a hash in [0, 1) of a step */
    int map_res;       /* shadow map resolution */
    float t_cut;       /* early termination: stop once the view transmittance is below this (0: never) */
    lu_k_ms ms;        /* multiple-scattering octaves of the in-scattering (lu_ms.h; octaves 1: off) */
};
LU_TYPEDEF(lu_k_rm_params)

/* Transmittance from x along unit w over (0, dist) through every medium
 * (exact optical depth per medium box). */
LU_FN vec3 lu_k_rm_transmittance(LU_CTX_PARAM, vec3 x, vec3 w, float dist) {
    vec3 tau = lu_v3s(0.0f);
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float a = 0.0f, b = 0.0f;
        if (!lu_k_box_clip(md.bounds_lo, md.bounds_hi, x, w, 0.0f, dist, LU_REF(a), LU_REF(b))) continue;
        float od = 0.0f;
        if (md.constant != 0) {
            od = md.density_scale * (b - a);
        } else {
            od = lu_k_optical_depth_blocks(LU_CTX, m, lu_k_medium_point(md, x), lu_k_medium_vector(md, w), a, b,
                                           md.max_pieces);
        }
        tau = lu_v3_madd(tau, lu_k_medium_sigma_t(md), od);
    }
    return lu_v3_exp(lu_v3_neg(tau));
}

/* Largest channel with plain comparisons: lu_v3_maxc's fmaxf is an
 * out-of-line libm call on baseline x86-64 (1-5 % of the march's samples). */
LU_FN float lu_k_rm_maxc(vec3 v) { return lu_max(v.x, lu_max(v.y, v.z)); }

/* (1 - exp(-x)) / x for x >= 0, accurate in float for every x. */
LU_FN float lu_k_rm_step_weight(float x) {
    if (x < 0.03f) return 1.0f - x * (0.5f - x * (1.0f / 6.0f - x * (1.0f / 24.0f)));
    return (1.0f - lu_exp(-x)) / x;
}

/* Transmittance from x to light l (arrival ls): exact optical depth here;
 * a method that reuses this march with another estimate (afm: attenuation
 * function maps) defines LU_K_RM_LIGHT_TR(l, x, ls) before including this
 * file. */
#ifndef LU_K_RM_LIGHT_TR
#define LU_K_RM_LIGHT_TR(l, x, ls) lu_k_rm_transmittance(LU_CTX, x, ls.wl, ls.dist)
#endif

/* Opaque visibility of light l at the camera ray's surface hit: the shadow
 * map here; raymarch, afm and gradient define LU_K_RM_SURFACE_VIS(l, pixel, x, n)
 * first to read exact per-pixel visibility the CPU traced (a shadow map
 * cannot be exact at a lit/shadowed edge seen in a pixel). */
#ifndef LU_K_RM_SURFACE_VIS
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_rm_visibility(LU_CTX, l, x, n, P.map_res)
#endif

/* Shadow-map visibility of light l at x (n: surface normal, or zero in a medium). */
LU_FN float lu_k_rm_visibility(LU_CTX_PARAM, int l, vec3 x, vec3 n, int res) {
    int count = lu_k_rm_view_count(LU_CTX, l);
    if (count <= 0) return 1.0f;
    int first = lu_k_rm_view_first(LU_CTX, l);
    lu_k_lightview v0 = lu_k_rm_view(LU_CTX, first);
    int face = count == 6 ? lu_k_cube_face(lu_v3_sub(x, v0.origin)) : 0;
    lu_k_lightview vw = face == 0 ? v0 : lu_k_rm_view(LU_CTX, first + face);
    return lu_k_shadow_lookup(LU_CTX, vw, first + face, res, x, n);
}

/* In-scattered radiance per unit length at x towards -d (before the
 * step's extinction): sum over media and lights of sigma_s D phase E T V,
 * the step covering x + s d for s in [sa, sb] (point and spot lights take
 * the step's mean of 1/d^2, lu_k_rm_near_light). dens[m]: medium m's
 * density at x. With ms.octaves > 1 each (light, medium) pair adds the
 * octaves above the first (lu_ms.h): the transmittance T to the light,
 * whichever estimate LU_K_RM_LIGHT_TR gives, is raised to a^i, so afm's map
 * lookup takes the octaves as the exact shadow ray does. The single-
 * scattering term is computed as without octaves (N = 1 is bit-identical).
 * A method that precomputes the source term (gradient: a radiance grid)
 * defines LU_K_RM_INSCATTER(ctx, P, x, d, sa, sb, dens, nm) to its own
 * lookup before including this file; the march stays this one. */
LU_FN vec3 lu_k_rm_inscatter_ms(LU_CTX_PARAM, int map_res, lu_k_ms ms, vec3 x, vec3 d, float sa, float sb,
                                float dens[LU_K_RM_MAX_MEDIA], int nm) {
    vec3 S = lu_v3s(0.0f);
    int nl = lu_k_light_count(LU_CTX);
    for (int l = 0; l < nl; l++) {
        lu_k_light lk = lu_k_light_get(LU_CTX, l);
        lu_k_light_sample ls = lu_k_light_arrive(lk, x);
        if (lu_k_rm_maxc(ls.irradiance) <= 0.0f) continue;
        if (lk.type != LU_K_LIGHT_DIRECTIONAL)
            ls.irradiance = lu_v3_scale(ls.irradiance, lu_k_rm_near_light(lk.position, x, d, sa, sb));
        float vis = lu_k_rm_visibility(LU_CTX, l, x, lu_v3s(0.0f), map_res);
        if (vis <= 0.0f) continue;
        vec3 Tl = LU_K_RM_LIGHT_TR(l, x, ls);
        vec3 E = lu_v3_scale(lu_v3_mul(ls.irradiance, Tl), vis);
        vec3 E0 = lu_v3_scale(ls.irradiance, vis);
        float cos_t = lu_v3_dot(d, ls.wl);
        for (int m = 0; m < nm; m++) {
            if (dens[m] <= 0.0f) continue;
            lu_k_medium md = lu_k_medium_get(LU_CTX, m);
            S = lu_v3_add(S, lu_v3_scale(lu_v3_mul(md.sigma_s, E), dens[m] * lu_k_phase_hg(cos_t, md.g)));
            if (ms.octaves > 1)
                S = lu_v3_add(S, lu_v3_mul(lu_v3_scale(lu_v3_mul(md.sigma_s, E0), dens[m]),
                                           lu_k_ms_extra(ms, cos_t, md.g, Tl)));
        }
    }
    return S;
}
#ifndef LU_K_RM_INSCATTER
#define LU_K_RM_INSCATTER(ctx, P, x, d, sa, sb, dens, nm) lu_k_rm_inscatter_ms(ctx, P.map_res, P.ms, x, d, sa, sb, dens, nm)
#endif

/* Range [t0, t1] of medium m on the camera ray of `pixel`, clipped to [0, t_end]. */
LU_FN bool lu_k_rm_medium_range(LU_CTX_PARAM, lu_k_medium md, int m, int pixel, vec3 o, vec3 d, float t_end,
                                LU_OUT(float) t0, LU_OUT(float) t1) {
    float lo = lu_k_rm_span(LU_CTX, pixel, m, 0), hi = lu_min(lu_k_rm_span(LU_CTX, pixel, m, 1), t_end);
    if (!(hi > lo)) return false;
    return lu_k_box_clip(md.bounds_lo, md.bounds_hi, o, d, lo, hi, t0, t1);
}

/* The march is split into segments of steps so a backend can run a long
 * march as several short passes: Mesa's llvmpipe silently stops every loop
 * of a shader invocation once 65535 loop iterations have run in it (all
 * loops together; tests/test_gpu.c proves it), and hardware drivers kill
 * long dispatches. A segment carries the in-scattered radiance L and the
 * camera ray's optical depth tau so far.
 *
 * lu_k_rm_segment marches steps [i0, i1) (clamped to the ray's step count)
 * of the camera ray o + t d of `pixel`; u in [0, 1) is where in each step the
 * sample sits (0.5: midpoint). Returns the ray's total step count. */
LU_FN int lu_k_rm_segment(LU_CTX_PARAM, lu_k_rm_params P, int pixel, vec3 o, vec3 d, float u, int i0, int i1,
                          LU_INOUT(vec3) L_io, LU_INOUT(vec3) tau_io) {
    lu_k_rm_hit hit = lu_k_rm_hit_get(LU_CTX, pixel);
    float t_end = hit.t >= 0.0f ? hit.t : LU_K_FAR;
    int nm = lu_min(lu_k_medium_count(LU_CTX), LU_K_RM_MAX_MEDIA);
    float ra[LU_K_RM_MAX_MEDIA];
    float rb[LU_K_RM_MAX_MEDIA];
    float t0 = LU_K_FAR, t1 = 0.0f;
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float a = 0.0f, b = 0.0f;
        if (lu_k_rm_medium_range(LU_CTX, md, m, pixel, o, d, t_end, LU_REF(a), LU_REF(b))) {
            t0 = lu_min(t0, a);
            t1 = lu_max(t1, b);
        } else {
            a = 1.0f;
            b = 0.0f;
        }
        ra[m] = a;
        rb[m] = b;
    }
    if (!(t1 > t0)) return 0;
    int steps = lu_int(lu_min(lu_ceil((t1 - t0) / P.step), lu_float(LU_K_RM_MAX_STEPS)));
    float h = (t1 - t0) / lu_float(steps);
    vec3 L = LU_DEREF(L_io);
    vec3 tau = LU_DEREF(tau_io);
    vec3 T = lu_v3_exp(lu_v3_neg(tau));
    int iend = lu_min(i1, steps);
    /* Below t_dense a sample is known to lie in a block with density (no
     * need to look again); from there the blocks are looked up. */
    float t_dense = -LU_K_FAR_MARCH;
    for (int i = i0; i < iend; i++) {
        if (lu_k_rm_maxc(T) < P.t_cut) break;
        float t = t0 + (lu_float(i) + u) * h;
        if (t >= t_dense) {
            /* Empty space: every medium present at t in a block of zero
             * majorant. The next step that may see density is the first at
             * or after t_skip (the nearest exit from those blocks or entry
             * into another medium's range). */
            bool empty = true;
            float t_skip = t1;
            for (int m = 0; m < nm && empty; m++) {
                if (t > rb[m]) continue;
                if (t < ra[m]) {
                    t_skip = lu_min(t_skip, ra[m]);
                    continue;
                }
                lu_k_medium md = lu_k_medium_get(LU_CTX, m);
                float t_exit = rb[m];
                float dmax = md.constant != 0 ? md.density_scale
                                              : lu_k_block_at(LU_CTX, m, lu_k_medium_point(md, o), lu_k_medium_vector(md, d), t,
                                                              LU_REF(t_exit));
                if (dmax != 0.0f) {
                    empty = false;
                    t_dense = dmax > 0.0f ? t_exit : t;
                } else {
                    t_skip = lu_min(t_skip, t_exit);
                }
            }
            if (empty) {
                /* floor: resume at or before the first step past t_skip (the
                 * steps skipped lie a full step before it, far beyond rounding). */
                int next = lu_int(lu_floor(lu_min((t_skip - t0) / h - u, lu_float(iend))));
                if (next > i + 1) i = next - 1;
                continue;
            }
        }
        vec3 x = lu_v3_madd(o, d, t);
        vec3 sig_t = lu_v3s(0.0f);
        float dens[LU_K_RM_MAX_MEDIA];
        bool scatters = false, emits = false;
        vec3 Se = lu_v3s(0.0f);
        for (int m = 0; m < nm; m++) {
            dens[m] = 0.0f;
            if (t < ra[m] || t > rb[m]) continue;
            lu_k_medium md = lu_k_medium_get(LU_CTX, m);
            vec3 pm = lu_k_medium_point(md, x);
            float dm = md.constant != 0 ? md.density_scale : lu_k_density(LU_CTX, m, pm);
            dens[m] = dm;
            sig_t = lu_v3_madd(sig_t, lu_k_medium_sigma_t(md), dm);
            scatters = scatters || (dm > 0.0f && lu_k_rm_maxc(md.sigma_s) > 0.0f);
            if (md.emission != 0 && dm > 0.0f) {
                Se = lu_v3_madd(Se, lu_v3_mul(md.sigma_a, lu_k_emission(LU_CTX, m, pm)), dm);
                emits = true;
            }
        }
        if (lu_k_rm_maxc(sig_t) <= 0.0f) continue;
        vec3 S = lu_v3s(0.0f);
        if (scatters) S = LU_K_RM_INSCATTER(LU_CTX, P, x, d, -u * h, (1.0f - u) * h, dens, nm);
        if (emits) S = lu_v3_add(S, Se);
        /* The step's in-scattering weight, the integral of exp(-sigma s)
         * over [0, h] = h (1 - exp(-x)) / x with x = sigma h (series for
         * small x: 1 - exp(-x) cancels in float at fine steps). The camera
         * ray's transmittance is exp of the summed optical depth, not a
         * product of per-step factors, for the same reason. */
        vec3 xs = lu_v3_scale(sig_t, h);
        /* Grey extinction (equal channels, every bundled scene but one):
         * one weight and one exp instead of three equal ones. */
        bool grey = xs.y == xs.x && xs.z == xs.x;
        float wx = lu_k_rm_step_weight(xs.x);
        vec3 w = grey ? lu_v3s(wx) : lu_v3(wx, lu_k_rm_step_weight(xs.y), lu_k_rm_step_weight(xs.z));
        L = lu_v3_add(L, lu_v3_mul(lu_v3_mul(T, S), lu_v3_scale(w, h)));
        tau = lu_v3_add(tau, xs);
        T = tau.y == tau.x && tau.z == tau.x ? lu_v3s(lu_exp(-tau.x)) : lu_v3_exp(lu_v3_neg(tau));
    }
    LU_DEREF(L_io) = L;
    LU_DEREF(tau_io) = tau;
    return steps;
}

/* Blinn-Phong radiance towards the camera of surface record `hit` (t >= 0)
 * on the camera ray of `pixel`, lit through the media and the shadow maps. */
LU_FN vec3 lu_k_rm_surface(LU_CTX_PARAM, lu_k_rm_params P, int pixel, lu_k_rm_hit hit, vec3 o, vec3 d) {
    int nl = lu_k_light_count(LU_CTX);
    vec3 end = lu_v3s(0.0f);
    vec3 x = lu_v3_madd(lu_v3_madd(o, d, hit.t), hit.ng, P.eps);
    vec3 wo = lu_v3_neg(d);
    for (int l = 0; l < nl; l++) {
        lu_k_light_sample ls = lu_k_light_arrive(lu_k_light_get(LU_CTX, l), x);
        vec3 f = lu_k_blinn_phong(hit.albedo, hit.specular, hit.shininess, hit.n, wo, ls.wl);
        if (lu_v3_maxc(f) <= 0.0f || lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        float vis = LU_K_RM_SURFACE_VIS(l, pixel, x, hit.n);
        if (vis <= 0.0f) continue;
        vec3 tr = LU_K_RM_LIGHT_TR(l, x, ls);
        end = lu_v3_add(end, lu_v3_scale(lu_v3_mul(lu_v3_mul(f, ls.irradiance), tr), vis));
    }
    return end;
}

/* The end of the camera ray of `pixel` (lit opaque surface or background),
 * seen through the optical depth tau the march accumulated, added to L. */
LU_FN vec3 lu_k_rm_finish(LU_CTX_PARAM, lu_k_rm_params P, int pixel, vec3 o, vec3 d, vec3 L, vec3 tau) {
    lu_k_rm_hit hit = lu_k_rm_hit_get(LU_CTX, pixel);
    vec3 T = lu_v3_exp(lu_v3_neg(tau));
    if (lu_v3_maxc(T) < P.t_cut) return L;  /* early termination (lu_k_rm_segment) */
    vec3 end = hit.t >= 0.0f ? lu_k_rm_surface(LU_CTX, P, pixel, hit, o, d) : P.background;
    return lu_v3_add(L, lu_v3_mul(T, end));
}

/* Radiance along the camera ray o + t d of `pixel` in one pass. */
LU_FN vec3 lu_k_rm_radiance(LU_CTX_PARAM, lu_k_rm_params P, int pixel, vec3 o, vec3 d, float u) {
    vec3 L = lu_v3s(0.0f);
    vec3 tau = lu_v3s(0.0f);
    lu_k_rm_segment(LU_CTX, P, pixel, o, d, u, 0, LU_K_RM_MAX_STEPS, LU_REF(L), LU_REF(tau));
    return lu_k_rm_finish(LU_CTX, P, pixel, o, d, L, tau);
}

/* Per-pixel jitter in [0, 1) (integer hash), or 0.5 without jitter. */
LU_FN float lu_k_rm_jitter(int jitter, int pixel) {
    if (jitter == 0) return 0.5f;
    uint x = lu_k_mix32(LU_K_RM_UINT(pixel) * 2654435761u + 12345u);
    return lu_float(x & 0xffffffu) * (1.0f / 16777216.0f);
}

#endif
