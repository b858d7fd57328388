/* lu_tracking.h — null-collision tracking through a trilinear grid over a
 * coarse majorant grid (kernel: C and GLSL).
 *
 * The majorant grid stores, per block of B^3 voxels, the largest density the
 * trilinear field takes anywhere in that block's index-space region, so a
 * tentative-collision process of rate sigma_max * block_max dominates the
 * real one everywhere (a single global majorant would waste most collisions
 * in sparse smoke). A 3D DDA over the blocks (lu_march.h's, on a grid B times
 * coarser) walks the ray; inside each block the process is homogeneous, and
 * when an exponential step leaves the block the walk restarts at the block
 * face (memorylessness makes this exact).
 *
 *   - free-flight sampling: delta tracking generalised to RGB by spectral
 *     tracking (Kutz, Habel, Li and Novák 2017, "Spectral and Decomposition
 *     Tracking for Rendering Heterogeneous Volumes", §5.1): one grey majorant
 *     (the largest channel), event probabilities from the throughput-weighted
 *     channel averages, and per-channel weights that keep every channel
 *     unbiased;
 *   - transmittance: ratio tracking (Novák, Selle and Jarosz 2014, "Residual
 *     Ratio Tracking for Estimating Attenuation in Participating Media",
 *     §3) against the same majorants, per channel, with Russian roulette once
 *     the estimate falls below 0.1 (unbiased: survivors are divided by the
 *     survival probability).
 *
 * Block block-space coordinates: q = (p_index + 1) / B, so block k along an
 * axis covers index coordinates [k B - 1, (k + 1) B - 1] and the grid's support
 * [-1, n] starts at block 0. t is the caller's ray parameter throughout.
 *
 * The backend defines, before including this file (see lu_kernel.h):
 *   float lu_k_density(LU_CTX_PARAM, int medium, vec3 p_index);
 *   float lu_k_majorant(LU_CTX_PARAM, int medium, int bx, int by, int bz);  (0 outside)
 */
#ifndef LU_TRACKING_H
#define LU_TRACKING_H

#include "kernels/lu_kernel.h"
#include "methods/common/lu_march.h"
#include "methods/common/lu_sampling.h"

struct lu_k_walk {
    lu_k_dda dda;
    vec3 oq, dq;  /* the ray in block space */
    float ta, tb; /* current block piece */
    float t_end;
    float dmax; /* majorant density of the current piece */
};
LU_TYPEDEF(lu_k_walk)

/* o, d: the ray in the medium's index space (t = caller's parameter). */
LU_FN lu_k_walk lu_k_walk_begin(vec3 o, vec3 d, float t0, float t1, float block) {
    lu_k_walk w;
    float inv = 1.0f / block;
    w.oq = lu_v3_scale(lu_v3_add(o, lu_v3s(1.0f)), inv);
    w.dq = lu_v3_scale(d, inv);
    w.dda = lu_k_dda_begin(w.oq, w.dq, t0, t1);
    w.ta = t0;
    w.tb = t0;
    w.t_end = t1;
    w.dmax = 0.0f;
    return w;
}

/* Moves to the next block piece; false when the walk has reached t_end. */
LU_FN bool lu_k_walk_next(LU_CTX_PARAM, int medium, LU_INOUT(lu_k_walk) w) {
    if (!(LU_DEREF(w).tb < LU_DEREF(w).t_end)) return false;
    float a = LU_DEREF(w).tb;
    float b = lu_k_dda_step(LU_REF(LU_DEREF(w).dda));
    LU_DEREF(w).ta = a;
    LU_DEREF(w).tb = b;
    vec3 q = lu_v3_madd(LU_DEREF(w).oq, LU_DEREF(w).dq, 0.5f * (a + b));
    LU_DEREF(w).dmax =
        lu_k_majorant(LU_CTX, medium, lu_int(lu_floor(q.x)), lu_int(lu_floor(q.y)), lu_int(lu_floor(q.z)));
    return true;
}

/* Next tentative collision after t for a process of rate sigma_max * dmax;
 * returns LU_K_FAR_MARCH when the walk ends first. On return the walk's
 * current piece contains the collision (its rate: sigma_max * w.dmax). */
LU_FN float lu_k_walk_tentative(LU_CTX_PARAM, int medium, LU_INOUT(lu_k_walk) w, float t, float sigma_max,
                                LU_INOUT(lu_k_rng) rng) {
    for (int guard = 0; guard < 1000000; guard++) {
        float mu = sigma_max * LU_DEREF(w).dmax;
        if (mu > 0.0f) {
            float tn = t - lu_log(1.0f - lu_k_rng_float(rng)) / mu;
            if (tn < LU_DEREF(w).tb) return tn;
        }
        t = LU_DEREF(w).tb;
        if (!lu_k_walk_next(LU_CTX, medium, w)) return LU_K_FAR_MARCH;
    }
    return LU_K_FAR_MARCH;
}

/* Ratio-tracking estimate of exp(-sigma_t * integral of density) over
 * [t0, t1] of the index-space ray, per channel. sigma_max = max channel of
 * sigma_t. Unbiased for each channel. */
LU_FN vec3 lu_k_ratio_tracking(LU_CTX_PARAM, int medium, vec3 o, vec3 d, float t0, float t1, float block, vec3 sigma_t,
                               float sigma_max, LU_INOUT(lu_k_rng) rng) {
    vec3 tr = lu_v3s(1.0f);
    if (!(t1 > t0) || !(sigma_max > 0.0f)) return tr;
    lu_k_walk w = lu_k_walk_begin(o, d, t0, t1, block);
    float t = t0;
    for (int guard = 0; guard < 1000000; guard++) {
        t = lu_k_walk_tentative(LU_CTX, medium, LU_REF(w), t, sigma_max, rng);
        if (!(t < t1)) break;
        float mu = sigma_max * w.dmax;
        float dens = lu_k_density(LU_CTX, medium, lu_v3_madd(o, d, t));
        vec3 ratio = lu_v3_sub(lu_v3s(1.0f), lu_v3_scale(sigma_t, dens / mu));
        tr = lu_v3_mul(tr, lu_v3_max(ratio, lu_v3s(0.0f)));
        float m = lu_v3_maxc(tr);
        if (m < 0.1f) {
            if (lu_k_rng_float(rng) >= m) return lu_v3s(0.0f);
            tr = lu_v3_scale(tr, 1.0f / m);
        }
    }
    return tr;
}

/* Spectral tracking at a tentative collision: sigma_a, sigma_s are the local
 * coefficients (density applied), mu the majorant there. Absorption is not
 * sampled but folded into the weights (paths end by Russian roulette
 * instead, which keeps long high-albedo walks such as marble from dying at
 * random): a real scattering (returns LU_K_EVENT_SCATTER) or a null
 * collision (LU_K_EVENT_NULL) is chosen with probabilities proportional to
 * avg(beta * sigma_s) and avg(beta * sigma_n), and beta is updated so that
 * each channel's expectation is the analog one. LU_K_EVENT_ABSORB: nothing
 * left to carry (beta set to 0). */
LU_CONST int LU_K_EVENT_ABSORB = 0;
LU_CONST int LU_K_EVENT_SCATTER = 1;
LU_CONST int LU_K_EVENT_NULL = 2;

LU_FN int lu_k_spectral_event(LU_INOUT(vec3) beta, vec3 sigma_a, vec3 sigma_s, float mu, float u) {
    vec3 b = LU_DEREF(beta);
    vec3 sigma_n = lu_v3_max(lu_v3_sub(lu_v3s(mu), lu_v3_add(sigma_a, sigma_s)), lu_v3s(0.0f));
    float ps = lu_v3_avg(lu_v3_mul(b, sigma_s));
    float pn = lu_v3_avg(lu_v3_mul(b, sigma_n));
    float c = ps + pn;
    if (!(c > 0.0f)) {
        LU_DEREF(beta) = lu_v3s(0.0f);
        return LU_K_EVENT_ABSORB;
    }
    if (u * c < ps) {
        LU_DEREF(beta) = lu_v3_scale(lu_v3_mul(b, sigma_s), c / (mu * ps));
        return LU_K_EVENT_SCATTER;
    }
    LU_DEREF(beta) = lu_v3_scale(lu_v3_mul(b, sigma_n), c / (mu * pn));
    return LU_K_EVENT_NULL;
}

/* Hero-channel null-collision sampling with spectral MIS (the balance
 * heuristic over the three channels: Wilkie et al. 2014, "Hero Wavelength
 * Spectral Sampling"; Miller, Georgiev and Jarosz 2019, "A Null-Scattering
 * Path Integral Formulation of Light Transport", §5). The hero channel's
 * coefficients choose a real collision (probability sigma_t / mu) or a null
 * one (sigma_n / mu) under the grey majorant mu, whose transmittance then
 * cancels between channels. Per channel c, beta (= f / p_hero) takes
 * sigma_s_c / sigma_t_hero on a real collision (absorption folded in, as
 * above) and sigma_n_c / sigma_n_hero on a null one, and r (= p_c / p_hero)
 * takes sigma_t_c / sigma_t_hero or the same null ratio. A contribution is
 * beta / avg(r) = f / avg_c(p_c): bounded by three times the channel's own
 * f / p however long the path. */
LU_FN int lu_k_hero_event(LU_INOUT(vec3) beta, LU_INOUT(vec3) r, vec3 sigma_a, vec3 sigma_s, float mu, int hero,
                          float u) {
    vec3 sigma_t = lu_v3_add(sigma_a, sigma_s);
    float st = lu_v3_get(sigma_t, hero);
    if (u * mu < st) {
        LU_DEREF(beta) = lu_v3_mul(LU_DEREF(beta), lu_v3_scale(sigma_s, 1.0f / st));
        LU_DEREF(r) = lu_v3_mul(LU_DEREF(r), lu_v3_scale(sigma_t, 1.0f / st));
        return LU_K_EVENT_SCATTER;
    }
    vec3 sigma_n = lu_v3_max(lu_v3_sub(lu_v3s(mu), sigma_t), lu_v3s(0.0f));
    float sn = lu_v3_get(sigma_n, hero);
    if (!(sn > 0.0f)) { /* only reachable by rounding: u * mu >= st = mu */
        LU_DEREF(beta) = lu_v3_mul(LU_DEREF(beta), lu_v3_scale(sigma_s, 1.0f / st));
        LU_DEREF(r) = lu_v3_mul(LU_DEREF(r), lu_v3_scale(sigma_t, 1.0f / st));
        return LU_K_EVENT_SCATTER;
    }
    vec3 k = lu_v3_scale(sigma_n, 1.0f / sn);
    LU_DEREF(beta) = lu_v3_mul(LU_DEREF(beta), k);
    LU_DEREF(r) = lu_v3_mul(LU_DEREF(r), k);
    return LU_K_EVENT_NULL;
}

#endif
