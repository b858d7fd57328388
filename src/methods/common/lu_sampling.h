/* lu_sampling.h — random numbers and per-sample Monte Carlo math (kernel: C
 * and GLSL): PCG streams, sphere / cone / hemisphere sampling,
 * Henyey-Greenstein and Blinn-Phong importance sampling, the smooth
 * dielectric (Fresnel with total internal reflection, refraction direction),
 * equiangular and truncated-exponential distance sampling, MIS heuristics.
 *
 * Conventions follow lu_optics.h: for a phase function, `w` is the direction
 * a path travels when it reaches the scattering point and `wi` the direction
 * it leaves towards the light, so lu_k_phase_hg(dot(w, wi), g) is the density
 * of wi and g > 0 continues forward. Every sampler returns its pdf in solid
 * angle (or length for distances) so callers can form MIS weights. */
#ifndef LU_SAMPLING_H
#define LU_SAMPLING_H

#include "kernels/lu_hash.h"
#include "kernels/lu_kernel.h"
#include "kernels/lu_optics.h"

/* ---- random numbers -----------------------------------------------------
 * One 32-bit PCG stream per (seed, pixel, sample): the state is seeded by
 * hashing the three, so an image is the same for any thread count or order.
 * Output: PCG-RXS-M-XS 32 (O'Neill 2014); seeding hash: pcg_hash (Jarzynski
 * and Olano 2020, "Hash Functions for GPU Rendering"). */
struct lu_k_rng {
    uint state;
};
LU_TYPEDEF(lu_k_rng)

LU_FN lu_k_rng lu_k_rng_make(uint seed, uint pixel, uint sample_index) {
    lu_k_rng r;
    r.state = lu_k_hash_u32(seed ^ lu_k_hash_u32(pixel * 0x9E3779B9u ^ lu_k_hash_u32(sample_index + 0x632BE5ABu)));
    return r;
}

LU_FN uint lu_k_rng_u32(LU_INOUT(lu_k_rng) r) {
    uint s = LU_DEREF(r).state;
    LU_DEREF(r).state = s * 747796405u + 2891336453u;
    uint w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (w >> 22u) ^ w;
}

/* Uniform in [0, 1): the top 24 bits, exactly representable as a float. */
LU_FN float lu_k_rng_float(LU_INOUT(lu_k_rng) r) { return lu_float(lu_k_rng_u32(r) >> 8u) * (1.0f / 16777216.0f); }

/* ---- frames and directions ------------------------------------------------ */

/* Orthonormal t, b with (t, b, n) right-handed, branch-free in n.z's sign
 * (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). n is unit. */
LU_FN void lu_k_basis(vec3 n, LU_OUT(vec3) t, LU_OUT(vec3) b) {
    float sgn = n.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (sgn + n.z);
    float c = n.x * n.y * a;
    LU_DEREF(t) = lu_v3(1.0f + sgn * n.x * n.x * a, sgn * c, -sgn * n.x);
    LU_DEREF(b) = lu_v3(c, sgn + n.y * n.y * a, -n.y);
}

/* Direction at polar cosine cos_t about axis n, azimuth phi. */
LU_FN vec3 lu_k_dir_about(vec3 n, float cos_t, float phi) {
    vec3 t, b;
    lu_k_basis(n, LU_REF(t), LU_REF(b));
    float sin_t = lu_sqrt(lu_max(0.0f, 1.0f - cos_t * cos_t));
    return lu_v3_add(lu_v3_scale(n, cos_t),
                     lu_v3_add(lu_v3_scale(t, sin_t * lu_cos(phi)), lu_v3_scale(b, sin_t * lu_sin(phi))));
}

LU_FN vec3 lu_k_sample_sphere(float u1, float u2) {
    return lu_k_dir_about(lu_v3(0.0f, 0.0f, 1.0f), 1.0f - 2.0f * u1, 2.0f * LU_K_PI * u2);
}

/* Uniform in the cone of half-angle acos(cos_max) about n; pdf
 * 1 / (2 pi (1 - cos_max)) per steradian. */
LU_FN vec3 lu_k_sample_cone(vec3 n, float cos_max, float u1, float u2) {
    return lu_k_dir_about(n, 1.0f - u1 * (1.0f - cos_max), 2.0f * LU_K_PI * u2);
}
LU_FN float lu_k_cone_pdf(float cos_max) { return 1.0f / (2.0f * LU_K_PI * (1.0f - cos_max)); }

/* Cosine-weighted hemisphere about n; pdf cos / pi. */
LU_FN vec3 lu_k_sample_cosine(vec3 n, float u1, float u2) {
    return lu_k_dir_about(n, lu_sqrt(1.0f - u1), 2.0f * LU_K_PI * u2);
}

LU_FN vec3 lu_k_reflect(vec3 d, vec3 n) { return lu_v3_sub(d, lu_v3_scale(n, 2.0f * lu_v3_dot(d, n))); }

/* ---- phase function --------------------------------------------------------- */

/* Cosine between w and the sampled direction, distributed as HG(g): the
 * inverse of the HG cumulative distribution in cos (e.g. pbrt, 3rd ed.,
 * eq. 15.7 with our sign: g > 0 samples forward). */
LU_FN float lu_k_sample_hg_cos(float g, float u) {
    if (lu_abs(g) < 1.0e-3f) return 1.0f - 2.0f * u;
    float s = (1.0f - g * g) / (1.0f - g + 2.0f * g * u);
    return lu_clamp((1.0f + g * g - s * s) / (2.0f * g), -1.0f, 1.0f);
}

/* A direction wi with density lu_k_phase_hg(dot(w, wi), g). */
LU_FN vec3 lu_k_sample_hg(vec3 w, float g, float u1, float u2) {
    return lu_k_dir_about(w, lu_k_sample_hg_cos(g, u1), 2.0f * LU_K_PI * u2);
}

/* ---- smooth dielectric ---------------------------------------------------------
 * eta_rel = eta_transmitted / eta_incident (1.3 entering glass-like matter from
 * air, 1 / 1.3 leaving it). lu_k_fresnel_reflectance (lu_optics.h) is written
 * for a relative index and returns 1 past the critical angle. */

/* Refracted direction of unit d at a surface with unit normal n facing the
 * incident side (dot(d, n) < 0). Returns false on total internal reflection. */
LU_FN bool lu_k_refract(vec3 d, vec3 n, float eta_rel, LU_OUT(vec3) t) {
    float r = 1.0f / eta_rel;
    float ci = -lu_v3_dot(n, d);
    float st2 = r * r * lu_max(0.0f, 1.0f - ci * ci);
    if (st2 >= 1.0f) {
        LU_DEREF(t) = lu_v3s(0.0f);
        return false;
    }
    float ct = lu_sqrt(1.0f - st2);
    LU_DEREF(t) = lu_v3_norm(lu_v3_add(lu_v3_scale(d, r), lu_v3_scale(n, r * ci - ct)));
    return true;
}

/* One sampled interaction with a smooth dielectric: reflect with probability
 * F (the Fresnel reflectance), else refract. `weight` multiplies a path's
 * radiance throughput: 1 on reflection and (eta_i / eta_t)^2 on refraction,
 * the radiance compression of a beam entering a denser medium (Veach 1997,
 * §5.2); light (flux) paths use 1 for both. */
struct lu_k_dielectric_sample {
    vec3 wi;
    float weight;
    bool refracted;
};
LU_TYPEDEF(lu_k_dielectric_sample)

/* d: unit direction of travel; ng: unit normal of the surface, either side;
 * eta: the object's index (outside is 1). */
LU_FN lu_k_dielectric_sample lu_k_sample_dielectric(vec3 d, vec3 ng, float eta, float u) {
    lu_k_dielectric_sample s;
    bool entering = lu_v3_dot(d, ng) < 0.0f;
    vec3 n = entering ? ng : lu_v3_neg(ng);
    float eta_rel = entering ? eta : 1.0f / eta;
    float f = lu_k_fresnel_reflectance(lu_v3_dot(d, n), eta_rel);
    vec3 t;
    bool ok = lu_k_refract(d, n, eta_rel, LU_REF(t));
    if (!ok || u < f) {
        s.wi = lu_k_reflect(d, n);
        s.weight = 1.0f;
        s.refracted = false;
    } else {
        s.wi = t;
        s.weight = 1.0f / (eta_rel * eta_rel);
        s.refracted = true;
    }
    return s;
}

/* ---- Blinn-Phong ------------------------------------------------------------------
 * The BRDF of lu_k_blinn_phong: albedo / pi + specular (s + 8) / (8 pi) cos^s(theta_h).
 * Sampling picks the Lambert lobe (cosine-weighted) or the specular lobe
 * (half vector with density (s + 1) / (2 pi) cos^s(theta_h), mapped to wi by the
 * reflection Jacobian 1 / (4 wo.h)) in proportion to the lobes' mean
 * coefficients; the pdf is the mixture, so weights f cos / pdf stay near
 * the lobes' albedos and never blow up (neither lobe's pdf is used alone). */

LU_FN float lu_k_blinn_phong_lobe_prob(vec3 albedo, vec3 specular) {
    float a = lu_v3_avg(albedo), s = lu_v3_avg(specular);
    return a + s > 0.0f ? a / (a + s) : 1.0f;
}

LU_FN float lu_k_blinn_phong_pdf(vec3 albedo, vec3 specular, float shininess, vec3 n, vec3 wo, vec3 wi) {
    float cl = lu_v3_dot(n, wi);
    if (cl <= 0.0f || lu_v3_dot(n, wo) <= 0.0f) return 0.0f;
    float pd = lu_k_blinn_phong_lobe_prob(albedo, specular);
    float pdf = pd * cl * LU_K_INV_PI;
    if (pd < 1.0f) {
        vec3 h = lu_v3_norm(lu_v3_add(wo, wi));
        float ch = lu_max(lu_v3_dot(n, h), 0.0f);
        float oh = lu_v3_dot(wo, h);
        if (oh > 0.0f)
            pdf += (1.0f - pd) * (shininess + 1.0f) * (0.5f * LU_K_INV_PI) * lu_pow(ch, shininess) / (4.0f * oh);
    }
    return pdf;
}

/* Returns wi; pdf 0 means the sample fell below the surface (no contribution). */
LU_FN vec3 lu_k_sample_blinn_phong(vec3 albedo, vec3 specular, float shininess, vec3 n, vec3 wo, float u_lobe, float u1,
                                   float u2, LU_OUT(float) pdf) {
    float pd = lu_k_blinn_phong_lobe_prob(albedo, specular);
    vec3 wi;
    if (u_lobe < pd) {
        wi = lu_k_sample_cosine(n, u1, u2);
    } else {
        float ch = lu_pow(u1, 1.0f / (shininess + 1.0f));
        vec3 h = lu_k_dir_about(n, ch, 2.0f * LU_K_PI * u2);
        wi = lu_k_reflect(lu_v3_neg(wo), h);
    }
    LU_DEREF(pdf) = lu_k_blinn_phong_pdf(albedo, specular, shininess, n, wo, wi);
    return wi;
}

/* ---- distances along a segment ---------------------------------------------------
 * For connecting a point x to a light-carrying segment b + s u, s in [0, len]
 * (Kulla and Fajardo 2012, "Importance Sampling Techniques for Path Tracing in
 * Participating Media"): equiangular sampling makes pdf(s) proportional to
 * 1 / |x - (b + s u)|^2, cancelling the inverse-square fall-off. */
struct lu_k_equiangular {
    float s0; /* parameter of x's foot on the line */
    float h;  /* distance from x to the line */
    float th_a, th_b;
};
LU_TYPEDEF(lu_k_equiangular)

LU_FN float lu_k_atan(float x) { return lu_atan2(x, 1.0f); }

LU_FN lu_k_equiangular lu_k_equiangular_make(vec3 x, vec3 b, vec3 u, float len) {
    lu_k_equiangular e;
    vec3 bx = lu_v3_sub(x, b);
    e.s0 = lu_v3_dot(bx, u);
    e.h = lu_max(lu_v3_len(lu_v3_sub(bx, lu_v3_scale(u, e.s0))), 1.0e-7f * (1.0f + lu_abs(e.s0)));
    e.th_a = lu_k_atan((0.0f - e.s0) / e.h);
    e.th_b = lu_k_atan((len - e.s0) / e.h);
    return e;
}

LU_FN float lu_k_equiangular_sample(lu_k_equiangular e, float u) {
    float th = lu_mix(e.th_a, e.th_b, u);
    return e.s0 + e.h * lu_sin(th) / lu_cos(th);
}

LU_FN float lu_k_equiangular_pdf(lu_k_equiangular e, float s) {
    float ds = s - e.s0;
    return e.h / ((e.th_b - e.th_a) * (e.h * e.h + ds * ds));
}

/* Exponential with rate lambda truncated to [0, len]. */
LU_FN float lu_k_trunc_exp_sample(float lambda, float len, float u) {
    float m = 1.0f - lu_exp(-lambda * len);
    return lu_min(-lu_log(1.0f - u * m) / lambda, len);
}
LU_FN float lu_k_trunc_exp_pdf(float lambda, float len, float s) {
    return lambda * lu_exp(-lambda * s) / (1.0f - lu_exp(-lambda * len));
}

/* ---- MIS ------------------------------------------------------------------------ */
LU_FN float lu_k_power_heuristic(float pa, float pb) {
    float a = pa * pa, b = pb * pb;
    return a + b > 0.0f ? a / (a + b) : 0.0f;
}

/* Equirectangular pdf conversion: a density over (u, v) in [0,1]^2 to solid
 * angle (the map spans 2 pi in u and pi in v; dw = 2 pi^2 sin(theta) du dv). */
LU_FN float lu_k_env_pdf_solid_angle(float pdf_uv, float v) {
    float st = lu_sin(v * LU_K_PI);
    return st > 0.0f ? pdf_uv / (2.0f * LU_K_PI * LU_K_PI * st) : 0.0f;
}

#endif
