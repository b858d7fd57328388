/* lu_optics.h — phase functions, Fresnel, surface reflection, light arrival
 * (kernel: C and GLSL). Conventions: `w` is a camera ray direction (from the
 * camera), `wl` the unit direction from a point towards a light. */
#ifndef LU_OPTICS_H
#define LU_OPTICS_H

#include "lu_kernel.h"

/* Henyey-Greenstein with cos_theta = dot(w, wl): light travelling along -wl
 * scatters into -w (towards the camera); g > 0 peaks when looking into the
 * light. g = 0 gives the isotropic 1/(4 pi). Normalised over the sphere. */
LU_FN float lu_k_phase_hg(float cos_theta, float g) {
    float denom = 1.0f + g * g - 2.0f * g * cos_theta;
    return LU_K_INV_4PI * (1.0f - g * g) / (denom * lu_sqrt(denom));
}

/* Unpolarised Fresnel reflectance of a smooth dielectric for light arriving
 * from outside (index 1) at |cos_i| onto a medium of index eta. */
LU_FN float lu_k_fresnel_reflectance(float cos_i, float eta) {
    float ci = lu_clamp(lu_abs(cos_i), 0.0f, 1.0f);
    float sin_t2 = (1.0f - ci * ci) / (eta * eta);
    if (sin_t2 >= 1.0f) return 1.0f;
    float ct = lu_sqrt(1.0f - sin_t2);
    float rs = (ci - eta * ct) / (ci + eta * ct);
    float rp = (eta * ci - ct) / (eta * ci + ct);
    return 0.5f * (rs * rs + rp * rp);
}

LU_FN float lu_k_fresnel_transmittance(float cos_i, float eta) { return 1.0f - lu_k_fresnel_reflectance(cos_i, eta); }

/* Lambert + energy-normalised Blinn-Phong BRDF times cos(theta_l).
 * n: unit normal facing the viewer, wo: unit direction to the viewer. */
LU_FN vec3 lu_k_blinn_phong(vec3 albedo, vec3 specular, float shininess, vec3 n, vec3 wo, vec3 wl) {
    float cl = lu_v3_dot(n, wl);
    if (cl <= 0.0f) return lu_v3s(0.0f);
    vec3 h = lu_v3_norm(lu_v3_add(wo, wl));
    float ch = lu_max(lu_v3_dot(n, h), 0.0f);
    float spec = (shininess + 8.0f) * (1.0f / (8.0f * LU_K_PI)) * lu_pow(ch, shininess);
    vec3 f = lu_v3_add(lu_v3_scale(albedo, LU_K_INV_PI), lu_v3_scale(specular, spec));
    return lu_v3_scale(f, cl);
}

/* Light types, matching lu_light_type. */
LU_CONST int LU_K_LIGHT_POINT = 0;
LU_CONST int LU_K_LIGHT_SPOT = 1;
LU_CONST int LU_K_LIGHT_DIRECTIONAL = 2;

struct lu_k_light {
    vec3 position;
    vec3 direction;     /* directional: towards the light; spot: where it shines */
    vec3 intensity;     /* W/sr, or irradiance for directional */
    float cos_inner, cos_outer;
    int type;
};
LU_TYPEDEF(lu_k_light)

/* What a light delivers at point x: unit direction to it, distance (a huge
 * number for directional lights) and the irradiance on a surface facing it
 * (before any transmittance or visibility). */
struct lu_k_light_sample {
    vec3 wl;
    float dist;
    vec3 irradiance;
};
LU_TYPEDEF(lu_k_light_sample)

LU_CONST float LU_K_FAR = 1.0e30f;

LU_FN lu_k_light_sample lu_k_light_arrive(lu_k_light l, vec3 x) {
    lu_k_light_sample s;
    if (l.type == LU_K_LIGHT_DIRECTIONAL) {
        s.wl = l.direction;
        s.dist = LU_K_FAR;
        s.irradiance = l.intensity;
        return s;
    }
    vec3 to = lu_v3_sub(l.position, x);
    float d2 = lu_max(lu_v3_dot(to, to), 1.0e-12f);
    s.dist = lu_sqrt(d2);
    s.wl = lu_v3_scale(to, 1.0f / s.dist);
    float falloff = 1.0f;
    if (l.type == LU_K_LIGHT_SPOT)
        falloff = lu_smoothstep(l.cos_outer, l.cos_inner, -lu_v3_dot(s.wl, l.direction));
    s.irradiance = lu_v3_scale(l.intensity, falloff / d2);
    return s;
}

/* Equirectangular mapping of a direction (u = 0.5 + atan2(x, -z)/2pi,
 * v = acos(y)/pi, v = 0 at the top) and back. */
LU_FN float lu_k_env_u(vec3 d) { return 0.5f + lu_atan2(d.x, -d.z) * (0.5f * LU_K_INV_PI); }
LU_FN float lu_k_env_v(vec3 d) { return lu_acos(lu_clamp(d.y, -1.0f, 1.0f)) * LU_K_INV_PI; }
LU_FN vec3 lu_k_env_dir(float u, float v) {
    float phi = (u - 0.5f) * 2.0f * LU_K_PI, theta = v * LU_K_PI;
    float st = lu_sin(theta);
    return lu_v3(st * lu_sin(phi), lu_cos(theta), -st * lu_cos(phi));
}

#endif
