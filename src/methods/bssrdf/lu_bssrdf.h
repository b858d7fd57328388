/* lu_bssrdf.h — the per-splat and per-pixel math of the bssrdf method
 * (Rohat 2011, sections 4.4, 5.1-5.3; kernel: C and GLSL).
 *
 * A splat is one sample x_s of light entering a translucent object: its
 * flux Phi_s (W, already through the entry Fresnel F_t(w_i) and standing for
 * the surface area the sample represents: A_vis / N_s times E(x_s) in the
 * thesis' Eq. 4.6), its normal, and the light-space thickness of the object
 * behind it. A visible point x_o of the same object receives
 *     L(x_o) = F_t(eta, w_o) / (pi (1 - F_dr,ext)) * sum_s Phi_s P_s(x_o),
 * 1 - F_dr,ext = 2 int_0^1 F_t(eta, mu) mu dmu being what that exit term lets
 * out over the hemisphere: the profiles are exitances already past the
 * boundary (the dipole's net flux, the random walk's tally of what leaves), so
 * the exit term only distributes them over directions and must integrate to 1
 * (pbrt's c = 1 - 2 FM1(1/eta)); without it 6 % is lost at eta 1.3.
 * P = R_d(|x_s - x_o|) for a 1D profile (dipole, normalised diffusion), and
 * P = (1 + n_s.n_o)/2 R(|x_s - x_o|, d) + (1 - n_s.n_o)/2 T(|x_b - x_o|, d)
 * for the multipole / multi-layer 2D profiles (Donner and Jensen's
 * weighting), where x_b is where the light ray through x_s leaves the
 * object and d = |x_b - x_s|. Measuring T from x_b (not from x_s, as the
 * thesis does) makes r the lateral distance the transmittance profile is
 * defined over. A splat's support is the ball of radius r_max around x_s
 * (and x_b); its screen-aligned bounding rectangle is lu_k_bssrdf_splat_rect.
 *
 * The backend defines, before including this file,
 *   float lu_k_bssrdf_fetch(LU_CTX_PARAM, int buffer, int index)
 * returning float `index` of one of the flat arrays LU_K_BSSRDF_BUF_*, and
 *   float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j)
 * (lu_shadowmap.h) for the light-space maps, which double as shadow maps. */
#ifndef LU_BSSRDF_H
#define LU_BSSRDF_H

#include "kernels/lu_kernel.h"
#include "methods/common/lu_lightview.h"
#include "kernels/lu_optics.h"
#include "methods/common/lu_sh.h"
#include "methods/common/lu_screen_rect.h"
#include "methods/common/lu_shadowmap.h"

/* Flat arrays behind the fetch hook. */
#define LU_K_BSSRDF_BUF_TABLE 0     /* profile tables: rgb triples */
#define LU_K_BSSRDF_BUF_MATERIAL 1  /* per scene object: LU_K_BSSRDF_MAT_FLOATS */
#define LU_K_BSSRDF_BUF_LIGHT 2     /* per light: LU_K_BSSRDF_LIGHT_FLOATS */
#define LU_K_BSSRDF_BUF_VIEW 3      /* per light view: LU_K_BSSRDF_VIEW_FLOATS */
#define LU_K_BSSRDF_BUF_ENV 4       /* environment maps: rgb texels, row 0 at the top */
#define LU_K_BSSRDF_BUF_SCENE 5     /* scene constants, LU_K_BSSRDF_SCENE_* below */
#define LU_K_BSSRDF_MAT_FLOATS 28
#define LU_K_BSSRDF_LIGHT_FLOATS 16
#define LU_K_BSSRDF_VIEW_FLOATS 16
/* Scene constants: */
#define LU_K_BSSRDF_SCENE_LIGHTS 0      /* light count */
#define LU_K_BSSRDF_SCENE_MAP_RES 1     /* side of every light-space map */
#define LU_K_BSSRDF_SCENE_BACKGROUND 2  /* rgb */
#define LU_K_BSSRDF_SCENE_SH 5          /* 9 rgb irradiance coefficients E_lm = A_l L_lm (27 floats) */
#define LU_K_BSSRDF_SCENE_ENVS 32       /* environment map count, then 4 floats each from ENV_INFO */
#define LU_K_BSSRDF_SCENE_ENV_INFO 33   /* per map: first texel, width, height, scale */
#define LU_K_BSSRDF_SCENE_FLOATS 64     /* (up to 7 environment maps) */

/* One splat, 80 bytes (std430-compatible: every vec3 is followed by a 4-byte scalar). */
struct lu_k_splat {
    vec3 position;
    float thickness;   /* light-space thickness behind x_s (2D profiles) */
    vec3 normal;       /* outward */
    int object;        /* scene object index */
    vec3 back;         /* where the light ray leaves the object */
    float level;       /* profile level: 0 point-sampled, k >= 1 averaged over the sample's cell */
    vec3 flux;         /* W per channel, entry Fresnel included */
    float row;         /* 2D profiles: thickness as a row coordinate (lu_k_bssrdf_splat_finish) */
    vec3 flux_t;       /* 2D profiles: flux times e^{-t_decay d}, what the T rows multiply; 0 past d_t_cut */
    float pad0;
};
LU_TYPEDEF(lu_k_splat)

/* One G-buffer texel: the first surface along the pixel's centre ray. */
struct lu_k_gbuf {
    vec3 position;
    int object;        /* scene object, -1 where the ray leaves the scene */
    vec3 normal;       /* shading normal facing the camera */
    float pad0;
};
LU_TYPEDEF(lu_k_gbuf)

/* A material as the shader sees it (from LU_K_BSSRDF_BUF_MATERIAL). */
struct lu_k_bssrdf_mat {
    int translucent;   /* 0: Lambert + Blinn-Phong; 1: diffusion profile */
    int kind;          /* 0: 1D table; 1: 2D tables R(r, d) then T(r, d) */
    int offset, nr, nd;
    float r_max, d_lo, d_hi;
    float eta, shininess;
    float thickness_scale;  /* multiplies every thickness (thesis Fig. 6.10) */
    float r_scale;          /* every length of the profile times this: P(r) -> P(r / s) / s^2 */
    vec3 albedo, specular;
    vec3 t_decay;           /* 2D: T rows are stored times e^{min(t_decay d, 40)} (flat along d) */
    float r_max_t;          /* 2D: radius of the T rows */
    float d_t_cut;          /* 2D: no transmission through anything thicker */
    int level_size;         /* entries in one prefilter level (levels follow each other) */
    float exit_norm;        /* 1 / (1 - F_dr,ext(eta)): makes the exit term integrate to 1 */
};
LU_TYPEDEF(lu_k_bssrdf_mat)

LU_FN vec3 lu_k_bssrdf_fetch3(LU_CTX_PARAM, int buf, int i) {
    return lu_v3(lu_k_bssrdf_fetch(LU_CTX, buf, i), lu_k_bssrdf_fetch(LU_CTX, buf, i + 1),
                 lu_k_bssrdf_fetch(LU_CTX, buf, i + 2));
}

LU_FN lu_k_bssrdf_mat lu_k_bssrdf_mat_load(LU_CTX_PARAM, int object) {
    int b = LU_K_BSSRDF_BUF_MATERIAL, o = object * LU_K_BSSRDF_MAT_FLOATS;
    lu_k_bssrdf_mat m;
    m.translucent = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o));
    m.kind = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 1));
    m.offset = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 2));
    m.nr = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 3));
    m.nd = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 4));
    m.r_max = lu_k_bssrdf_fetch(LU_CTX, b, o + 5);
    m.d_lo = lu_k_bssrdf_fetch(LU_CTX, b, o + 6);
    m.d_hi = lu_k_bssrdf_fetch(LU_CTX, b, o + 7);
    m.eta = lu_k_bssrdf_fetch(LU_CTX, b, o + 8);
    m.shininess = lu_k_bssrdf_fetch(LU_CTX, b, o + 9);
    m.albedo = lu_k_bssrdf_fetch3(LU_CTX, b, o + 10);
    m.specular = lu_k_bssrdf_fetch3(LU_CTX, b, o + 13);
    m.thickness_scale = lu_k_bssrdf_fetch(LU_CTX, b, o + 16);
    m.r_scale = lu_k_bssrdf_fetch(LU_CTX, b, o + 17);
    m.t_decay = lu_k_bssrdf_fetch3(LU_CTX, b, o + 18);
    m.r_max_t = lu_k_bssrdf_fetch(LU_CTX, b, o + 21);
    m.d_t_cut = lu_k_bssrdf_fetch(LU_CTX, b, o + 22);
    m.level_size = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 23));
    m.exit_norm = lu_k_bssrdf_fetch(LU_CTX, b, o + 24);
    return m;
}

/* ---- profile tables ------------------------------------------------------------
 * A row of nr rgb entries at r = r_max (i / (nr - 1))^2 (square-root spacing:
 * entries crowd where the profile is steep), linear in between, 0 beyond. */
LU_FN vec3 lu_k_bssrdf_row(LU_CTX_PARAM, int base, int nr, float r, float r_max) {
    if (r >= r_max) return lu_v3s(0.0f);
    float x = lu_sqrt(lu_max(r, 0.0f) / r_max) * lu_float(nr - 1);
    int i = lu_int(x);
    if (i > nr - 2) i = nr - 2;
    float w = x - lu_float(i);
    vec3 a = lu_k_bssrdf_fetch3(LU_CTX, LU_K_BSSRDF_BUF_TABLE, 3 * (base + i));
    vec3 b = lu_k_bssrdf_fetch3(LU_CTX, LU_K_BSSRDF_BUF_TABLE, 3 * (base + i + 1));
    return lu_v3_add(lu_v3_scale(a, 1.0f - w), lu_v3_scale(b, w));
}

/* Row coordinate of thickness d (table units) in a 2D table: rows at d_lo
 * (d_hi / d_lo)^(j / (nd - 1)), clamped at both ends. */
LU_FN float lu_k_bssrdf_row_coord(lu_k_bssrdf_mat m, float d) {
    float y = lu_log(lu_max(d, m.d_lo) / m.d_lo) / lu_log(m.d_hi / m.d_lo) * lu_float(m.nd - 1);
    return lu_clamp(y, 0.0f, lu_float(m.nd - 1));
}

/* A 2D table (R block, or the T block when transmit != 0) at r and row
 * coordinate y, in the table's own units; T rows come out still multiplied
 * by e^{t_decay d} (the splat's flux_t carries the inverse). */
LU_FN vec3 lu_k_bssrdf_profile2(LU_CTX_PARAM, lu_k_bssrdf_mat m, float r, float y, int transmit) {
    int j = lu_int(y);
    if (j > m.nd - 2) j = m.nd - 2;
    float w = y - lu_float(j);
    int block = m.offset + (transmit != 0 ? m.nr * m.nd : 0);
    float rm = transmit != 0 ? m.r_max_t : m.r_max;
    vec3 a = lu_k_bssrdf_row(LU_CTX, block + j * m.nr, m.nr, r, rm);
    vec3 b = lu_k_bssrdf_row(LU_CTX, block + (j + 1) * m.nr, m.nr, r, rm);
    return lu_v3_add(lu_v3_scale(a, 1.0f - w), lu_v3_scale(b, w));
}

/* Fills the per-splat terms of 2D profiles (row, flux_t) once, so the
 * per-pixel loop does no logarithm or exponential. */
LU_FN lu_k_splat lu_k_bssrdf_splat_finish(lu_k_bssrdf_mat m, lu_k_splat s) {
    s.row = 0.0f;
    s.flux_t = lu_v3s(0.0f);
    if (m.kind == 0) return s;
    float d = s.thickness * m.thickness_scale / m.r_scale;
    s.row = lu_k_bssrdf_row_coord(m, d);
    if (d > m.d_t_cut) return s;
    vec3 k = lu_v3_scale(m.t_decay, d);
    s.flux_t = lu_v3_mul(s.flux, lu_v3(lu_exp(-lu_min(k.x, 40.0f)), lu_exp(-lu_min(k.y, 40.0f)), lu_exp(-lu_min(k.z, 40.0f))));
    return s;
}

/* World radius of a splat of material m around x_s (reflection), and around
 * x_b for a splat of light-space thickness d (transmission; 0 where none). */
LU_FN float lu_k_bssrdf_radius(lu_k_bssrdf_mat m) { return m.r_max * m.r_scale; }
LU_FN float lu_k_bssrdf_radius_t(lu_k_bssrdf_mat m, float d) {
    if (m.kind == 0 || d * m.thickness_scale / m.r_scale > m.d_t_cut) return 0.0f;
    return m.r_max_t * m.r_scale;
}

/* Phi_s P_s(x_o): what splat s (finished by lu_k_bssrdf_splat_finish)
 * adds at visible point x_o (normal n_o). */
LU_FN vec3 lu_k_bssrdf_splat_eval(LU_CTX_PARAM, lu_k_bssrdf_mat m, lu_k_splat s, vec3 xo, vec3 no) {
    float inv = 1.0f / m.r_scale;
    float rmax2 = m.r_max * m.r_max * m.r_scale * m.r_scale;
    m.offset += lu_int(s.level) * m.level_size;
    vec3 dv = lu_v3_sub(xo, s.position);
    float r2 = lu_v3_dot(dv, dv);
    if (m.kind == 0) {
        if (r2 >= rmax2) return lu_v3s(0.0f);
        vec3 p = lu_k_bssrdf_row(LU_CTX, m.offset, m.nr, lu_sqrt(r2) * inv, m.r_max);
        return lu_v3_scale(lu_v3_mul(s.flux, p), inv * inv);
    }
    float c = lu_clamp(lu_v3_dot(s.normal, no), -1.0f, 1.0f);
    vec3 acc = lu_v3s(0.0f);
    if (r2 < rmax2 && c > -1.0f)
        acc = lu_v3_scale(lu_v3_mul(s.flux, lu_k_bssrdf_profile2(LU_CTX, m, lu_sqrt(r2) * inv, s.row, 0)), 0.5f * (1.0f + c));
    if (c < 1.0f && lu_v3_maxc(s.flux_t) > 0.0f) {
        vec3 dt = lu_v3_sub(xo, s.back);
        float t2 = lu_v3_dot(dt, dt);
        if (t2 < m.r_max_t * m.r_max_t * m.r_scale * m.r_scale)
            acc = lu_v3_add(acc, lu_v3_scale(lu_v3_mul(s.flux_t, lu_k_bssrdf_profile2(LU_CTX, m, lu_sqrt(t2) * inv, s.row, 1)),
                                              0.5f * (1.0f - c)));
    }
    return lu_v3_scale(acc, inv * inv);
}

/* ---- lights, light views, environment -------------------------------------------------- */

LU_FN lu_k_light lu_k_bssrdf_light(LU_CTX_PARAM, int l) {
    int b = LU_K_BSSRDF_BUF_LIGHT, o = l * LU_K_BSSRDF_LIGHT_FLOATS;
    lu_k_light k;
    k.position = lu_k_bssrdf_fetch3(LU_CTX, b, o);
    k.type = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 3));
    k.direction = lu_k_bssrdf_fetch3(LU_CTX, b, o + 4);
    k.cos_inner = lu_k_bssrdf_fetch(LU_CTX, b, o + 7);
    k.intensity = lu_k_bssrdf_fetch3(LU_CTX, b, o + 8);
    k.cos_outer = lu_k_bssrdf_fetch(LU_CTX, b, o + 11);
    return k;
}

LU_FN lu_k_lightview lu_k_bssrdf_view(LU_CTX_PARAM, int v) {
    int b = LU_K_BSSRDF_BUF_VIEW, o = v * LU_K_BSSRDF_VIEW_FLOATS;
    lu_k_lightview w;
    w.origin = lu_k_bssrdf_fetch3(LU_CTX, b, o);
    w.ortho = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 3));
    w.axis_u = lu_k_bssrdf_fetch3(LU_CTX, b, o + 4);
    w.extent_u = lu_k_bssrdf_fetch(LU_CTX, b, o + 7);
    w.axis_v = lu_k_bssrdf_fetch3(LU_CTX, b, o + 8);
    w.extent_v = lu_k_bssrdf_fetch(LU_CTX, b, o + 11);
    w.axis_w = lu_k_bssrdf_fetch3(LU_CTX, b, o + 12);
    w.depth_far = lu_k_bssrdf_fetch(LU_CTX, b, o + 15);
    return w;
}

/* Light l's visibility at x (normal n facing the light side being shaded):
 * PCF in its light-space map, with a normal offset and a depth bias of a few
 * texel footprints. Points outside every view are lit. */
LU_FN float lu_k_bssrdf_shadow(LU_CTX_PARAM, int l, vec3 x, vec3 n) {
    int b = LU_K_BSSRDF_BUF_LIGHT, o = l * LU_K_BSSRDF_LIGHT_FLOATS;
    int first = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 12)), count = lu_int(lu_k_bssrdf_fetch(LU_CTX, b, o + 13));
    if (count <= 0) return 1.0f;
    int res = lu_int(lu_k_bssrdf_fetch(LU_CTX, LU_K_BSSRDF_BUF_SCENE, LU_K_BSSRDF_SCENE_MAP_RES));
    lu_k_lightview v0 = lu_k_bssrdf_view(LU_CTX, first);
    int face = count == 6 ? lu_k_cube_face(lu_v3_sub(x, v0.origin)) : 0;
    lu_k_lightview vw = face == 0 ? v0 : lu_k_bssrdf_view(LU_CTX, first + face);
    return lu_k_shadow_lookup(LU_CTX, vw, first + face, res, x, n);
}

/* Radiance of environment map e in direction d (bilinear, wrapping in u),
 * the same lookup the reference makes. */
LU_FN vec3 lu_k_bssrdf_env(LU_CTX_PARAM, int e, vec3 d) {
    int s = LU_K_BSSRDF_BUF_SCENE, o = LU_K_BSSRDF_SCENE_ENV_INFO + 4 * e;
    int first = lu_int(lu_k_bssrdf_fetch(LU_CTX, s, o)), w = lu_int(lu_k_bssrdf_fetch(LU_CTX, s, o + 1));
    int h = lu_int(lu_k_bssrdf_fetch(LU_CTX, s, o + 2));
    float scale = lu_k_bssrdf_fetch(LU_CTX, s, o + 3);
    float u = lu_k_env_u(d) * lu_float(w) - 0.5f, v = lu_k_env_v(d) * lu_float(h) - 0.5f;
    float fx = lu_floor(u), fy = lu_floor(v);
    float ax = u - fx, ay = v - fy;
    vec3 acc = lu_v3s(0.0f);
    for (int j = 0; j < 2; j++) {
        int y = lu_int(lu_clamp(fy + lu_float(j), 0.0f, lu_float(h - 1)));
        for (int i = 0; i < 2; i++) {
            int x = lu_int(fx) + i;
            x = x - (x >= 0 ? x / w : (x - w + 1) / w) * w;
            float wt = (i == 1 ? ax : 1.0f - ax) * (j == 1 ? ay : 1.0f - ay);
            acc = lu_v3_madd(acc, lu_k_bssrdf_fetch3(LU_CTX, LU_K_BSSRDF_BUF_ENV, 3 * (first + y * w + x)), wt);
        }
    }
    return lu_v3_scale(acc, scale);
}

LU_FN vec3 lu_k_bssrdf_env_all(LU_CTX_PARAM, vec3 d) {
    int n = lu_int(lu_k_bssrdf_fetch(LU_CTX, LU_K_BSSRDF_BUF_SCENE, LU_K_BSSRDF_SCENE_ENVS));
    vec3 acc = lu_v3s(0.0f);
    for (int e = 0; e < n; e++) acc = lu_v3_add(acc, lu_k_bssrdf_env(LU_CTX, e, d));
    return acc;
}

/* Irradiance from 9 SH coefficients E_lm = A_l L_lm (Ramamoorthi-Hanrahan). */
LU_FN vec3 lu_k_bssrdf_sh9(LU_CTX_PARAM, int first, vec3 n) {
    float y[LU_SH_MAX_COEFFS];
    lu_k_sh_eval(n, 3, y);
    vec3 e = lu_v3s(0.0f);
    for (int i = 0; i < 9; i++) e = lu_v3_madd(e, lu_k_bssrdf_fetch3(LU_CTX, LU_K_BSSRDF_BUF_SCENE, first + 3 * i), y[i]);
    return lu_v3_max(e, lu_v3s(0.0f));
}

/* ---- the deferred pass ------------------------------------------------------------------- */

/* Final radiance of a pixel: g is its G-buffer texel, scatter the splat sum
 * sum_s Phi_s P_s there, view_dir the unit camera ray. Translucent surfaces:
 * F_t(w_o) exit_norm / pi times the scatter, plus the boundary's Blinn-Phong highlight
 * weighted by F_r(w_o) (as the reference weights boundary reflection) and a
 * mirror reflection of the environment times F_r. Opaque surfaces: Lambert +
 * Blinn-Phong per light, shadowed through the light-space maps, and the SH9
 * irradiance of the environment. */
LU_FN vec3 lu_k_bssrdf_shade(LU_CTX_PARAM, lu_k_gbuf g, vec3 scatter, vec3 view_dir) {
    int s = LU_K_BSSRDF_BUF_SCENE;
    if (g.object < 0) return lu_v3_add(lu_k_bssrdf_fetch3(LU_CTX, s, LU_K_BSSRDF_SCENE_BACKGROUND),
                                       lu_k_bssrdf_env_all(LU_CTX, view_dir));
    lu_k_bssrdf_mat m = lu_k_bssrdf_mat_load(LU_CTX, g.object);
    vec3 n = g.normal, wo = lu_v3_neg(view_dir);
    float cos_o = lu_max(lu_v3_dot(n, wo), 0.0f);
    vec3 L = lu_v3s(0.0f);
    vec3 albedo = m.albedo;
    float spec_weight = 1.0f;
    if (m.translucent != 0) {
        float fr = lu_k_fresnel_reflectance(cos_o, m.eta);
        L = lu_v3_scale(scatter, (1.0f - fr) * m.exit_norm * LU_K_INV_PI);
        albedo = lu_v3s(0.0f);
        spec_weight = fr;
        vec3 refl = lu_v3_sub(view_dir, lu_v3_scale(n, 2.0f * lu_v3_dot(view_dir, n)));
        L = lu_v3_add(L, lu_v3_scale(lu_v3_mul(m.specular, lu_k_bssrdf_env_all(LU_CTX, refl)), fr));
    } else {
        L = lu_v3_mul(lu_v3_scale(albedo, LU_K_INV_PI), lu_k_bssrdf_sh9(LU_CTX, LU_K_BSSRDF_SCENE_SH, n));
    }
    int lights = lu_int(lu_k_bssrdf_fetch(LU_CTX, s, LU_K_BSSRDF_SCENE_LIGHTS));
    for (int l = 0; l < lights; l++) {
        lu_k_light k = lu_k_bssrdf_light(LU_CTX, l);
        if (k.type < 0) continue;   /* environment lights are not point-like */
        lu_k_light_sample ls = lu_k_light_arrive(k, g.position);
        vec3 f = lu_k_blinn_phong(albedo, m.specular, m.shininess, n, wo, ls.wl);
        if (lu_v3_maxc(f) <= 0.0f || lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        float vis = lu_k_bssrdf_shadow(LU_CTX, l, g.position, n);
        L = lu_v3_add(L, lu_v3_scale(lu_v3_mul(f, ls.irradiance), vis * spec_weight));
    }
    return L;
}

#endif
