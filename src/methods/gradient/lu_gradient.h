/* lu_gradient.h — gradient-based interpolation of source radiance (Ren et
 * al. 2008) and its baselines: the per-sample, per-voxel and per-pixel math
 * (kernel: C and GLSL).
 *
 * The source radiance towards the camera at a medium point x is
 *   J(x) = sum_l p(d(x), w_l) E_l(x) T_l(x) V_l(x)            (Ren Eq. 1)
 * with d(x) the camera ray direction through x, E_l the light's arrival
 * (lu_k_light_arrive), T_l the transmittance to the light (exact optical
 * depth, or the paper's fixed interval Delta1), V_l shadow-map visibility.
 * The interpolated field is F = J as in the paper (normalize = 0), or, an
 * extension (docs/gradient.md), F = J / N with the part of J known in
 * closed form divided out before interpolation and multiplied back at
 * every march step:
 *   normalize = 1 (falloff):  N = sum_l p I_l / d_l^2        (phase and 1/d^2 only)
 *   normalize = 2 (emission): N = sum_l p E_l                 (also the spot cone)
 * so a glow around a point light (1/d^2) or a shaft edge (the cone) is not
 * interpolated linearly; what is left, F = a weighted mean of T_l V_l, is
 * what samples are for (volumetric shadows, extinction). Where N = 0 (outside
 * every cone) F is the plain mean of T_l V_l, so F stays continuous.
 *
 * Samples j (position x_j, valid radius R_j, value F_j, gradient by central
 * differences with Delta2) are combined at a point x by
 *   gradient (Eq. 4): sum W_j (F_j + (x - x_j).grad F_j) / sum W_j,  W_j = R_j / |x - x_j|
 *   rbf (baseline):   sum w_j exp(-|x - x_j|^2 / r_j^2) F_j / sum (same)
 * over the samples whose valid sphere holds x. The combination is a gather
 * per voxel of a radiance grid over a cell list of samples, which computes
 * exactly the sums the paper's splatting accumulates (no float atomics on
 * the GPU). The local shading error E_j of Eq. 5 uses the six points
 * x_j +- R_j axes. The final view march is lu_view_march.h's with the source
 * term replaced by a trilinear lookup in the radiance grid.
 *
 * Hooks the backend defines before including this file, besides those of
 * lu_view_march.h:
 *   lu_k_gr_params lu_k_gr_get(LU_CTX_PARAM);
 *   vec3 lu_k_gr_field(LU_CTX_PARAM, int voxel);            (radiance grid, x fastest)
 *   int lu_k_gr_cell_begin(LU_CTX_PARAM, int cell);  int lu_k_gr_cell_end(LU_CTX_PARAM, int cell);
 *   int lu_k_gr_cell_item(LU_CTX_PARAM, int k);              (sample index)
 *   float lu_k_gr_sample_fetch(LU_CTX_PARAM, int j, int k);  (float k of sample j, LU_K_GR_SAMPLE_FLOATS)
 *   float lu_k_gr_bmap_at(LU_CTX_PARAM, int k);  (float k of the boundary-map buffer, methods/common/media_ray.h)
 *   float lu_k_gr_surf(LU_CTX_PARAM, int k);     (per medium 8 floats: boundary material albedo, shininess,
 *       specular, -; then from surf_normals_at per pixel and medium the span's boundary normals,
 *       LU_MR_NORMAL_FLOATS: entry, exit; outward, zero where the span has no such end;
 *       then from surf_vis_at per pixel and light the light's visibility at the camera
 *       ray's opaque hit, lu_media_rays_surface_vis)
 *
 * Shadow rays through a bounded medium use the lights' boundary maps: the
 * segment of the light ray inside the boundary and F_t at its crossings, as
 * the reference (exact for convex boundaries, to the map's resolution).
 */
#ifndef LU_GRADIENT_H
#define LU_GRADIENT_H

#include "kernels/lu_kernel.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"

#include "lu_gradient_params.h"
#include "methods/common/lu_lightview.h"
#include "methods/common/lu_march.h"

/* A sample as stored (LU_K_GR_SAMPLE_FLOATS floats, vec4-aligned for the
 * GPU's float buffer): x, R | wgt, rr, -, - | F, - | gx, - | gy, - | gz, -. */
struct lu_k_gr_sample {
    vec3 x;
    float R;       /* valid radius */
    float wgt;     /* rbf weight (the Gaussian's w_j; 1 for other samples) */
    float rr;      /* rbf radius r_j */
    vec3 F;        /* field value */
    vec3 gx, gy, gz; /* its gradient, per colour channel: dF/dx, dF/dy, dF/dz */
};
LU_TYPEDEF(lu_k_gr_sample)

LU_FN vec3 lu_k_gr_fetch3(LU_CTX_PARAM, int j, int k) {
    return lu_v3(lu_k_gr_sample_fetch(LU_CTX, j, k), lu_k_gr_sample_fetch(LU_CTX, j, k + 1),
                 lu_k_gr_sample_fetch(LU_CTX, j, k + 2));
}

LU_FN lu_k_gr_sample lu_k_gr_sample_get(LU_CTX_PARAM, int j) {
    lu_k_gr_sample s;
    s.x = lu_k_gr_fetch3(LU_CTX, j, 0);
    s.R = lu_k_gr_sample_fetch(LU_CTX, j, 3);
    s.wgt = lu_k_gr_sample_fetch(LU_CTX, j, 4);
    s.rr = lu_k_gr_sample_fetch(LU_CTX, j, 5);
    s.F = lu_k_gr_fetch3(LU_CTX, j, 8);
    s.gx = lu_k_gr_fetch3(LU_CTX, j, 12);
    s.gy = lu_k_gr_fetch3(LU_CTX, j, 16);
    s.gz = lu_k_gr_fetch3(LU_CTX, j, 20);
    return s;
}

/* ---- the normaliser N(x) ---- */

/* Light l's weight in N at x (phase times what arrives without transmittance or shadow). */
LU_FN vec3 lu_k_gr_norm_light(lu_k_gr_params G, lu_k_light L, vec3 x, vec3 d) {
    lu_k_light_sample ls = lu_k_light_arrive(L, x);
    vec3 E = ls.irradiance;
    if (G.normalize == 1 && L.type != LU_K_LIGHT_DIRECTIONAL) E = lu_v3_scale(L.intensity, 1.0f / (ls.dist * ls.dist));
    return lu_v3_scale(E, lu_k_phase_hg(lu_v3_dot(d, ls.wl), G.g));
}

LU_FN vec3 lu_k_gr_norm(LU_CTX_PARAM, lu_k_gr_params G, vec3 x) {
    vec3 d = lu_v3_norm(lu_v3_sub(x, G.cam));
    vec3 N = lu_v3s(0.0f);
    int nl = lu_k_light_count(LU_CTX);
    for (int l = 0; l < nl; l++) N = lu_v3_add(N, lu_k_gr_norm_light(G, lu_k_light_get(LU_CTX, l), x, d));
    return N;
}

/* ---- radiance grid lookup (trilinear between voxel centres, clamped at the edges) ---- */

LU_FN int lu_k_gr_clampi(int i, int n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); }

LU_FN vec3 lu_k_gr_lookup(LU_CTX_PARAM, lu_k_gr_params G, vec3 x) {
    vec3 q = lu_v3_sub(lu_v3_div(lu_v3_sub(x, G.lo), G.voxel), lu_v3s(0.5f));
    float fx = lu_floor(q.x), fy = lu_floor(q.y), fz = lu_floor(q.z);
    float ax = q.x - fx, ay = q.y - fy, az = q.z - fz;
    int x0 = lu_int(fx), y0 = lu_int(fy), z0 = lu_int(fz);
    vec3 acc = lu_v3s(0.0f);
    for (int k = 0; k < 2; k++) {
        int z = lu_k_gr_clampi(z0 + k, G.nz);
        float wz = k == 1 ? az : 1.0f - az;
        for (int j = 0; j < 2; j++) {
            int y = lu_k_gr_clampi(y0 + j, G.ny);
            float wy = j == 1 ? ay : 1.0f - ay;
            for (int i = 0; i < 2; i++) {
                int xi = lu_k_gr_clampi(x0 + i, G.nx);
                float w = (i == 1 ? ax : 1.0f - ax) * wy * wz;
                acc = lu_v3_madd(acc, lu_k_gr_field(LU_CTX, (z * G.ny + y) * G.nx + xi), w);
            }
        }
    }
    return acc;
}

/* The march's source term (hook LU_K_RM_INSCATTER of lu_view_march.h):
 * sum_m sigma_s,m D_m(x) J(x), J from the radiance grid. dens has
 * LU_K_RM_MAX_MEDIA (8) entries. The step's extent [sa, sb] is unused: J
 * is interpolated from the grid, with no 1/d^2 peak at the sample. */
LU_FN vec3 lu_k_gr_inscatter(LU_CTX_PARAM, int map_res, vec3 x, vec3 d, float sa, float sb, float dens[8], int nm) {
    lu_k_gr_params G = lu_k_gr_get(LU_CTX);
    vec3 J = lu_k_gr_lookup(LU_CTX, G, x);
    if (G.normalize != 0) J = lu_v3_mul(J, lu_k_gr_norm(LU_CTX, G, x));
    vec3 s = lu_v3s(0.0f);
    for (int m = 0; m < nm; m++) s = lu_v3_madd(s, lu_k_medium_get(LU_CTX, m).sigma_s, dens[m]);
    return lu_v3_mul(s, J);
}
/* ---- transmittance to a light through bounded and unbounded media ---- */

LU_FN lu_k_lightview lu_k_gr_bview(LU_CTX_PARAM, lu_k_gr_params G, int v) {
    int o = G.bviews_at + 16 * v;
    lu_k_lightview w;
    w.origin = lu_v3(lu_k_gr_bmap_at(LU_CTX, o), lu_k_gr_bmap_at(LU_CTX, o + 1), lu_k_gr_bmap_at(LU_CTX, o + 2));
    w.ortho = lu_int(lu_k_gr_bmap_at(LU_CTX, o + 3));
    w.axis_u = lu_v3(lu_k_gr_bmap_at(LU_CTX, o + 4), lu_k_gr_bmap_at(LU_CTX, o + 5), lu_k_gr_bmap_at(LU_CTX, o + 6));
    w.extent_u = lu_k_gr_bmap_at(LU_CTX, o + 7);
    w.axis_v = lu_v3(lu_k_gr_bmap_at(LU_CTX, o + 8), lu_k_gr_bmap_at(LU_CTX, o + 9), lu_k_gr_bmap_at(LU_CTX, o + 10));
    w.extent_v = lu_k_gr_bmap_at(LU_CTX, o + 11);
    w.axis_w = lu_v3(lu_k_gr_bmap_at(LU_CTX, o + 12), lu_k_gr_bmap_at(LU_CTX, o + 13), lu_k_gr_bmap_at(LU_CTX, o + 14));
    w.depth_far = lu_k_gr_bmap_at(LU_CTX, o + 15);
    return w;
}

/* Transmittance from x towards light l (unit wl, distance dist): exact
 * optical depth of every medium; unbounded ones clipped to their box,
 * bounded ones (when boundary maps exist) to the segment of the texel x
 * projects to, times F_t at each boundary crossing between x and the light. */
LU_FN vec3 lu_k_gr_light_transmittance(LU_CTX_PARAM, int l, vec3 x, vec3 wl, float dist) {
    lu_k_gr_params G = lu_k_gr_get(LU_CTX);
    int res = G.map_res;
    int count = G.bview_count > 0 ? lu_int(lu_k_gr_bmap_at(LU_CTX, 2 * l + 1)) : 0;
    int first = count > 0 ? lu_int(lu_k_gr_bmap_at(LU_CTX, 2 * l)) : 0;
    int face = 0;
    vec3 uvd = lu_v3s(-1.0f);
    if (count > 0) {
        lu_k_lightview v0 = lu_k_gr_bview(LU_CTX, G, first);
        face = count == 6 ? lu_k_cube_face(lu_v3_sub(x, v0.origin)) : 0;
        lu_k_lightview vw = face == 0 ? v0 : lu_k_gr_bview(LU_CTX, G, first + face);
        uvd = lu_k_lightview_project(vw, x);
    }
    bool in_view = count > 0 && lu_k_lightview_inside(uvd);
    int ti = lu_int(lu_clamp(uvd.x * lu_float(res), 0.0f, lu_float(res - 1)));
    int tj = lu_int(lu_clamp(uvd.y * lu_float(res), 0.0f, lu_float(res - 1)));
    vec3 tau = lu_v3s(0.0f);
    float ft = 1.0f;
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float lo = 0.0f, hi = dist;
        if (md.bounded != 0 && in_view) {
            int t0 = G.bmaps_at + ((((first + face) * nm + m) * res + tj) * res + ti) * 4; /* LU_MR_BMAP_FLOATS */
            float da = lu_k_gr_bmap_at(LU_CTX, t0), db = lu_k_gr_bmap_at(LU_CTX, t0 + 1);
            if (!(db > da)) continue;
            /* depth along the light ray falls by s as the shadow ray advances s towards the light */
            float dx = uvd.z, dl = uvd.z - dist;
            if (da > dl && da < dx) ft *= lu_k_gr_bmap_at(LU_CTX, t0 + 2);
            if (db > dl && db < dx) ft *= lu_k_gr_bmap_at(LU_CTX, t0 + 3);
            lo = dx - lu_min(db, dx);
            hi = dx - lu_max(da, dl);
            if (!(hi > lo)) continue;
        }
        float a = 0.0f, b = 0.0f;
        if (!lu_k_box_clip(md.bounds_lo, md.bounds_hi, x, wl, lo, hi, LU_REF(a), LU_REF(b))) continue;
        float od = md.constant != 0 ? md.density_scale * (b - a)
                                    : lu_k_optical_depth(LU_CTX, m, lu_k_medium_point(md, x), lu_k_medium_vector(md, wl), a, b,
                                                         md.max_pieces);
        tau = lu_v3_madd(tau, lu_k_medium_sigma_t(md), od);
    }
    return lu_v3_scale(lu_v3_exp(lu_v3_neg(tau)), ft);
}

/* The march uses this source term only when lu_view_march.h was not included
 * before (a driver includes lu_gradient.h alone). */
#ifndef LU_RAYMARCH_H
#define LU_K_RM_INSCATTER(ctx, P, x, d, sa, sb, dens, nm) lu_k_gr_inscatter(ctx, P.map_res, x, d, sa, sb, dens, nm)
#define LU_K_RM_LIGHT_TR(l, x, ls) lu_k_gr_light_transmittance(LU_CTX, l, x, ls.wl, ls.dist)
/* Camera-visible surfaces take the exact visibility the CPU traced per pixel
 * and light (methods/common/media_ray.h), as in raymarch and afm: a shadow map leaks
 * light at thin occluders (dusty_room's window: 0.34 rel-L2 with the map). */
LU_FN float lu_k_gr_surface_vis(LU_CTX_PARAM, int pixel, int l) {
    return lu_k_gr_surf(LU_CTX, lu_k_gr_get(LU_CTX).surf_vis_at + pixel * lu_k_light_count(LU_CTX) + l);
}
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_gr_surface_vis(LU_CTX, pixel, l)
#endif
#include "methods/common/lu_view_march.h"

/* ---- tracing the source radiance at a point ---- */

/* Transmittance from x along w over (0, dist): exact, or the paper's sum of
 * densities at interval Delta1 (midpoints of equal pieces no longer than
 * Delta1 across each medium's box). */
LU_FN vec3 lu_k_gr_transmittance(LU_CTX_PARAM, vec3 x, vec3 w, float dist, float delta1) {
    if (delta1 <= 0.0f) return lu_k_rm_transmittance(LU_CTX, x, w, dist);
    vec3 tau = lu_v3s(0.0f);
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float a = 0.0f, b = 0.0f;
        if (!lu_k_box_clip(md.bounds_lo, md.bounds_hi, x, w, 0.0f, dist, LU_REF(a), LU_REF(b))) continue;
        int n = lu_int(lu_min(lu_ceil((b - a) / delta1), 65536.0f));
        n = n < 1 ? 1 : n;
        float h = (b - a) / lu_float(n);
        float od = 0.0f;
        for (int k = 0; k < n; k++) {
            vec3 u = lu_v3_madd(x, w, a + (lu_float(k) + 0.5f) * h);
            od += md.constant != 0 ? md.density_scale : lu_k_density(LU_CTX, m, lu_k_medium_point(md, u));
        }
        tau = lu_v3_madd(tau, lu_k_medium_sigma_t(md), od * h);
    }
    return lu_v3_exp(lu_v3_neg(tau));
}

/* F(x), the interpolated field (see the top): J, or J / N. One pass over
 * the lights traces each transmittance once. */
LU_FN vec3 lu_k_gr_field_at(LU_CTX_PARAM, lu_k_gr_params G, vec3 x) {
    vec3 d = lu_v3_norm(lu_v3_sub(x, G.cam));
    vec3 J = lu_v3s(0.0f), N = lu_v3s(0.0f), A = lu_v3s(0.0f);
    int nl = lu_k_light_count(LU_CTX);
    for (int l = 0; l < nl; l++) {
        lu_k_light L = lu_k_light_get(LU_CTX, l);
        lu_k_light_sample ls = lu_k_light_arrive(L, x);
        vec3 w = G.normalize != 0 ? lu_k_gr_norm_light(G, L, x, d) : lu_v3s(0.0f);
        N = lu_v3_add(N, w);
        /* Outside the light's reach only the N = 0 fallback needs T V. */
        bool lit = lu_v3_maxc(ls.irradiance) > 0.0f;
        if (!lit && (G.normalize != 2 || lu_v3_maxc(w) > 0.0f)) continue;
        float vis = lu_k_rm_visibility(LU_CTX, l, x, lu_v3s(0.0f), G.map_res);
        vec3 Tl = lu_v3s(0.0f), T = lu_v3s(0.0f);
        if (vis > 0.0f) {
            Tl = G.delta1 > 0.0f ? lu_k_gr_transmittance(LU_CTX, x, ls.wl, ls.dist, G.delta1)
                                 : lu_k_gr_light_transmittance(LU_CTX, l, x, ls.wl, ls.dist);
            T = lu_v3_scale(Tl, vis);
        }
        A = lu_v3_add(A, T);
        float cos_t = lu_v3_dot(d, ls.wl);
        J = lu_v3_add(J, lu_v3_scale(lu_v3_mul(ls.irradiance, T), lu_k_phase_hg(cos_t, G.g)));
        /* Multiple-scattering octaves (lu_ms.h) on the transmittance alone,
         * as lu_k_rm_inscatter_ms does: visibility is not raised to a^i. */
        if (G.ms.octaves > 1 && vis > 0.0f)
            J = lu_v3_add(J, lu_v3_mul(lu_v3_scale(ls.irradiance, vis), lu_k_ms_extra(G.ms, cos_t, G.g, Tl)));
    }
    if (G.normalize == 0) return J;
    float inv = 1.0f / lu_max(lu_float(nl), 1.0f);
    return lu_v3(N.x > 0.0f ? J.x / N.x : A.x * inv, N.y > 0.0f ? J.y / N.y : A.y * inv,
                 N.z > 0.0f ? J.z / N.z : A.z * inv);
}

LU_FN float lu_k_gr_total_density(LU_CTX_PARAM, vec3 x) {
    float D = 0.0f;
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        vec3 p = lu_k_medium_point(md, x);
        bool inside = x.x >= md.bounds_lo.x && x.y >= md.bounds_lo.y && x.z >= md.bounds_lo.z &&
                      x.x <= md.bounds_hi.x && x.y <= md.bounds_hi.y && x.z <= md.bounds_hi.z;
        if (!inside) continue;
        D += md.constant != 0 ? md.density_scale : lu_k_density(LU_CTX, m, p);
    }
    return D;
}

LU_FN vec3 lu_k_gr_axis(int k) { return lu_v3(k == 0 ? 1.0f : 0.0f, k == 1 ? 1.0f : 0.0f, k == 2 ? 1.0f : 0.0f); }

/* tau_v of Eq. 5: the transmittance from x to the camera, mean over colour channels. */
LU_FN float lu_k_gr_view_tau(LU_CTX_PARAM, lu_k_gr_params G, vec3 x) {
    vec3 tv = lu_v3_sub(G.cam, x);
    float dist = lu_v3_len(tv);
    return lu_v3_avg(lu_k_gr_transmittance(LU_CTX, x, lu_v3_scale(tv, 1.0f / lu_max(dist, 1e-20f)), dist, G.delta1));
}

/* Evaluates sample j at x with valid radius R: field value, gradient by
 * central differences (Delta2), and when want_error != 0 the local shading
 * error of Eq. 5,
 *   E = R^3 sum_i |F~_i - F_i| N_i / 6 * D(x_i) * tau_v,
 * over x_i = x +- R axes, F~_i = F + (x_i - x).grad F (the sample alone),
 * |.| the mean over colour channels, N_i the normaliser (1 without
 * normalising, so the error is in J). tau_v: transmittance from x to the
 * camera; when tau_in < 0 it is traced here (a root sample), otherwise the
 * ancestor's value is reused, as the paper does. With tau_in = 1, E is the
 * view-free part, exactly: E with tau_v is that times tau_v. */
LU_FN void lu_k_gr_eval(LU_CTX_PARAM, lu_k_gr_params G, vec3 x, float R, float tau_in, int want_error, LU_OUT(vec3) F,
                        LU_OUT(vec3) gx, LU_OUT(vec3) gy, LU_OUT(vec3) gz, LU_OUT(float) E, LU_OUT(float) tau_out) {
    /* Point 0: x; 1..6: x +- Delta2 axes; 7..12: x +- R axes (error only).
     * One call site of the tracer, so the GPU program stays small. */
    vec3 f[13];
    int npts = want_error != 0 ? 13 : 7;
    for (int i = 0; i < 13; i++) f[i] = lu_v3s(0.0f);
    for (int i = 0; i < npts; i++) {
        int k = (i + 5) % 6; /* axis 2k or 2k+1: +, - */
        float sgn = (k % 2) == 0 ? 1.0f : -1.0f;
        float len = i == 0 ? 0.0f : (i <= 6 ? G.delta2 : R);
        vec3 p = lu_v3_madd(x, lu_k_gr_axis(k / 2), sgn * len);
        f[i] = lu_k_gr_field_at(LU_CTX, G, p);
    }
    vec3 g0 = lu_v3_scale(lu_v3_sub(f[1], f[2]), 0.5f / G.delta2);
    vec3 g1 = lu_v3_scale(lu_v3_sub(f[3], f[4]), 0.5f / G.delta2);
    vec3 g2 = lu_v3_scale(lu_v3_sub(f[5], f[6]), 0.5f / G.delta2);
    LU_DEREF(F) = f[0];
    LU_DEREF(gx) = g0;
    LU_DEREF(gy) = g1;
    LU_DEREF(gz) = g2;
    float tau = tau_in;
    float err = 0.0f;
    if (want_error != 0) {
        if (tau < 0.0f) tau = lu_k_gr_view_tau(LU_CTX, G, x);
        for (int i = 7; i < 13; i++) {
            int k = (i + 5) % 6; /* axis 2k or 2k+1: +, - */
            float sgn = (k % 2) == 0 ? 1.0f : -1.0f;
            vec3 xi = lu_v3_madd(x, lu_k_gr_axis(k / 2), sgn * R);
            vec3 gk = k / 2 == 0 ? g0 : (k / 2 == 1 ? g1 : g2);
            vec3 ft = lu_v3_madd(f[0], gk, sgn * R);
            vec3 N = G.normalize != 0 ? lu_k_gr_norm(LU_CTX, G, xi) : lu_v3s(1.0f);
            vec3 dif = lu_v3_sub(ft, f[i]);
            vec3 ad = lu_v3(lu_abs(dif.x) * N.x, lu_abs(dif.y) * N.y, lu_abs(dif.z) * N.z);
            err += lu_v3_avg(ad) * lu_k_gr_total_density(LU_CTX, xi);
        }
        err = R * R * R * err * (1.0f / 6.0f) * tau;
    }
    LU_DEREF(E) = err;
    LU_DEREF(tau_out) = tau;
}

/* ---- boundary reflection ---- */

/* Where the camera ray of `pixel` enters bounded medium m (its span starts
 * on the boundary, in front of any opaque hit), the boundary reflects F_r
 * times its material's Blinn-Phong radiance, lit through the media: the
 * reference's term. The camera transmittance in front of the entry is taken
 * as 1 (exact for the first medium along the ray). */
LU_FN vec3 lu_k_gr_reflection(LU_CTX_PARAM, lu_k_rm_params P, int pixel, vec3 o, vec3 d) {
    lu_k_gr_params G = lu_k_gr_get(LU_CTX);
    vec3 L = lu_v3s(0.0f);
    if (G.reflect == 0) return L;
    lu_k_rm_hit hit = lu_k_rm_hit_get(LU_CTX, pixel);
    int nm = lu_k_medium_count(LU_CTX);
    for (int m = 0; m < nm; m++) {
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        int nb = G.surf_normals_at + (pixel * nm + m) * 6;
        vec3 n = lu_v3(lu_k_gr_surf(LU_CTX, nb), lu_k_gr_surf(LU_CTX, nb + 1), lu_k_gr_surf(LU_CTX, nb + 2));
        float t = lu_k_rm_span(LU_CTX, pixel, m, 0);
        if (md.bounded == 0 || lu_v3_dot(n, n) == 0.0f || (hit.t >= 0.0f && t >= hit.t)) continue;
        if (lu_v3_dot(n, d) > 0.0f) n = lu_v3_neg(n);
        lu_k_rm_hit b;
        b.n = n;
        b.t = t;
        b.ng = n;
        b.pad0 = 0.0f;
        b.albedo = lu_v3(lu_k_gr_surf(LU_CTX, 8 * m), lu_k_gr_surf(LU_CTX, 8 * m + 1), lu_k_gr_surf(LU_CTX, 8 * m + 2));
        b.shininess = lu_k_gr_surf(LU_CTX, 8 * m + 3);
        b.specular = lu_v3(lu_k_gr_surf(LU_CTX, 8 * m + 4), lu_k_gr_surf(LU_CTX, 8 * m + 5), lu_k_gr_surf(LU_CTX, 8 * m + 6));
        b.pad1 = 0.0f;
        float fr = lu_k_fresnel_reflectance(lu_v3_dot(n, d), md.eta);
        L = lu_v3_madd(L, lu_k_rm_surface(LU_CTX, P, pixel, b, o, d), fr);
    }
    return L;
}

/* The camera ray's radiance: the march with the grid's source term, plus the boundary reflection. */
LU_FN vec3 lu_k_gr_radiance(LU_CTX_PARAM, lu_k_rm_params P, int pixel, vec3 o, vec3 d) {
    return lu_v3_add(lu_k_rm_radiance(LU_CTX, P, pixel, o, d, 0.5f), lu_k_gr_reflection(LU_CTX, P, pixel, o, d));
}

/* ---- interpolation at a radiance-grid voxel ---- */

LU_FN vec3 lu_k_gr_voxel_pos(lu_k_gr_params G, int i) {
    int x = i % G.nx, y = (i / G.nx) % G.ny, z = i / (G.nx * G.ny);
    return lu_v3_add(G.lo, lu_v3_mul(lu_v3(lu_float(x) + 0.5f, lu_float(y) + 0.5f, lu_float(z) + 0.5f), G.voxel));
}

/* Weighted combination (Eq. 4, or the rbf baseline) of the samples whose
 * valid sphere holds p, from the cell list. Points no sphere holds get 0. */
LU_FN vec3 lu_k_gr_interpolate(LU_CTX_PARAM, lu_k_gr_params G, vec3 p) {
    vec3 q = lu_v3_div(lu_v3_sub(p, G.lo), G.cell);
    int cx = lu_k_gr_clampi(lu_int(lu_floor(q.x)), G.cx), cy = lu_k_gr_clampi(lu_int(lu_floor(q.y)), G.cy),
        cz = lu_k_gr_clampi(lu_int(lu_floor(q.z)), G.cz);
    int c = (cz * G.cy + cy) * G.cx + cx;
    vec3 num = lu_v3s(0.0f);
    float den = 0.0f;
    int end = lu_k_gr_cell_end(LU_CTX, c);
    for (int k = lu_k_gr_cell_begin(LU_CTX, c); k < end; k++) {
        lu_k_gr_sample s = lu_k_gr_sample_get(LU_CTX, lu_k_gr_cell_item(LU_CTX, k));
        vec3 dx = lu_v3_sub(p, s.x);
        float dist = lu_v3_len(dx);
        if (dist >= s.R) continue;
        float w = 0.0f;
        vec3 v = s.F;
        if (G.mode == LU_K_GR_RBF) {
            w = s.wgt * lu_exp(-(dist * dist) / (s.rr * s.rr));
            if (w < G.rbf_floor) continue;
        } else {
            /* W = R/|x - x_j|, capped where p sits on the sample (the sample's own value wins). */
            w = s.R / lu_max(dist, 1.0e-4f * s.R);
            v = lu_v3_add(v, lu_v3_add(lu_v3_add(lu_v3_scale(s.gx, dx.x), lu_v3_scale(s.gy, dx.y)), lu_v3_scale(s.gz, dx.z)));
        }
        num = lu_v3_madd(num, v, w);
        den += w;
    }
    return den > 0.0f ? lu_v3_scale(num, 1.0f / den) : lu_v3s(0.0f);
}

/* Value of radiance-grid voxel i: traced (per-voxel baseline) or interpolated. */
LU_FN vec3 lu_k_gr_voxel(LU_CTX_PARAM, lu_k_gr_params G, int i) {
    vec3 p = lu_k_gr_voxel_pos(G, i);
    if (G.mode == LU_K_GR_PERVOXEL) return lu_k_gr_field_at(LU_CTX, G, p);
    return lu_k_gr_interpolate(LU_CTX, G, p);
}

#endif
