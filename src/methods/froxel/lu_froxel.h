/* lu_froxel.h — the froxel method's math (kernel: C and GLSL): volumetric
 * fog on a camera-frustum grid in the manner of Wronski 2014 ("Volumetric
 * fog", SIGGRAPH Advances) and Hillaire 2015 ("Physically based and unified
 * volumetric rendering in Frostbite"), docs/froxel.md.
 *
 * Three passes per frame:
 *   1. light: each cell (column i, j; slice k) takes one sample on its
 *      column's centre ray at depth t(k + u) (u = 0.5, or the frame's jitter)
 *      and stores the source S = sum over media of the in-scattering of the
 *      shared view march (lu_view_march.h: sigma_s D phase E T_l V, with the
 *      exact optical depth to the light and the opaque shadow maps) plus
 *      emission sigma_a D Le, and the extinction sigma_t D. With reprojection
 *      the sample is blended with the previous frame's lit volume at the same
 *      world point (seen through the previous camera).
 *   2. integrate: front to back along each column, slice k adds
 *      T_k S (1 - exp(-sigma_t dz)) / sigma_t (the energy-conserving slice
 *      integral, Hillaire 2015, with S and sigma_t constant in the slice) and
 *      sigma_t dz to the optical depth; boundary k + 1 stores (L, tau).
 *   3. pixel: the integrated volume is read trilinearly (bilinear across
 *      columns, linear between slice boundaries) at the pixel's opaque hit
 *      (or past the far end) and composited over the surface or background
 *      with the view march's own surface term (lu_k_rm_finish).
 *
 * Depth is the distance t along each column's ray (not view-space z), and
 * the slices are uniform in log(t - t_lo + n0): t(s) = t_lo - n0 + n0 R^(s/nz)
 * with R = (t_hi - t_lo + n0) / n0. With the camera outside the media and
 * n0 = t_lo this is Wronski's t = t_near (t_far / t_near)^(s/nz); n0 keeps it
 * defined when the camera is inside (t_lo = 0).
 *
 * Hooks the backend defines (besides lu_view_march.h's):
 *   float lu_k_fx_span(LU_CTX_PARAM, int column, int m, int end);  (bounded-media span of a column's ray)
 *   vec3 lu_k_fx_hist(LU_CTX_PARAM, int cell, int part);  (previous lit volume: part 0 S, 1 sigma_t)
 *   float lu_k_fx_hist_valid(LU_CTX_PARAM, int cell);      (1: that cell was lit, 0: culled)
 *   float lu_k_fx_reach(LU_CTX_PARAM, int column);         (farthest ray end of the pixels reading the column)
 *   vec3 lu_k_fx_lit(LU_CTX_PARAM, int cell, int part);   (this frame's lit volume)
 *   vec3 lu_k_fx_int(LU_CTX_PARAM, int node, int part);   (integrated volume: part 0 L, 1 tau)
 *   void lu_k_fx_int_store(LU_CTX_PARAM, int node, vec3 L, vec3 tau);
 * Include lu_view_march.h's hooks first; this file includes it. */
#ifndef LU_FROXEL_H
#define LU_FROXEL_H

#include "methods/common/lu_view_march.h"
#include "lu_froxel_grid.h"


/* Depth t at slice coordinate s in [0, nz] (s = k: boundary k). */
LU_FN float lu_k_fx_slice_t(lu_k_fx_grid G, float s) {
    return G.t_lo - G.n0 + G.n0 * lu_exp(s / lu_float(G.nz) * G.log_r);
}

/* Slice coordinate of depth t, clamped to [0, nz]. */
LU_FN float lu_k_fx_slice_s(lu_k_fx_grid G, float t) {
    float q = (t - G.t_lo + G.n0) / G.n0;
    if (!(q > 1.0f)) return 0.0f;
    return lu_min(lu_float(G.nz) * lu_log(q) / G.log_r, lu_float(G.nz));
}

/* Unit direction of column (i, j)'s centre ray. */
LU_FN vec3 lu_k_fx_column_dir(lu_k_fx_grid G, int i, int j) {
    return lu_k_camera_dir(G.cam, (lu_float(i) + 0.5f) * lu_float(G.width) / lu_float(G.nx),
                           (lu_float(j) + 0.5f) * lu_float(G.height) / lu_float(G.ny));
}

LU_FN int lu_k_fx_cell(lu_k_fx_grid G, int i, int j, int k) { return (k * G.ny + j) * G.nx + i; }

/* Trilinear read of the previous lit volume at cell coordinates (gx, gy,
 * gz) (cell centres at integers, clamped to the grid), over the cells that
 * were lit (culled cells, behind every pixel's ray end, have no history):
 * the weights are renormalised over those; returns their total weight (0:
 * no history there). */
LU_FN float lu_k_fx_hist_at(LU_CTX_PARAM, lu_k_fx_grid G, float gx, float gy, float gz, LU_OUT(vec3) S_out,
                            LU_OUT(vec3) sig_out) {
    gx = lu_clamp(gx, 0.0f, lu_float(G.nx - 1));
    gy = lu_clamp(gy, 0.0f, lu_float(G.ny - 1));
    gz = lu_clamp(gz, 0.0f, lu_float(G.nz - 1));
    int i0 = lu_min(lu_int(gx), G.nx - 1), j0 = lu_min(lu_int(gy), G.ny - 1), k0 = lu_min(lu_int(gz), G.nz - 1);
    float ax = gx - lu_float(i0), ay = gy - lu_float(j0), az = gz - lu_float(k0);
    int i1 = lu_min(i0 + 1, G.nx - 1), j1 = lu_min(j0 + 1, G.ny - 1), k1 = lu_min(k0 + 1, G.nz - 1);
    vec3 S = lu_v3s(0.0f), sig = lu_v3s(0.0f);
    float wsum = 0.0f;
    for (int c = 0; c < 8; c++) {
        int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
        float w = (di != 0 ? ax : 1.0f - ax) * (dj != 0 ? ay : 1.0f - ay) * (dk != 0 ? az : 1.0f - az);
        if (w <= 0.0f) continue;
        int cell = lu_k_fx_cell(G, di != 0 ? i1 : i0, dj != 0 ? j1 : j0, dk != 0 ? k1 : k0);
        if (lu_k_fx_hist_valid(LU_CTX, cell) <= 0.0f) continue;
        S = lu_v3_madd(S, lu_k_fx_hist(LU_CTX, cell, 0), w);
        sig = lu_v3_madd(sig, lu_k_fx_hist(LU_CTX, cell, 1), w);
        wsum += w;
    }
    if (wsum > 0.0f) {
        S = lu_v3_scale(S, 1.0f / wsum);
        sig = lu_v3_scale(sig, 1.0f / wsum);
    }
    LU_DEREF(S_out) = S;
    LU_DEREF(sig_out) = sig;
    return wsum;
}

/* Where world point x lies in grid Gp (cell coordinates): false when it is
 * behind the camera or outside the grid (more than half a cell past an edge). */
LU_FN bool lu_k_fx_locate(lu_k_fx_grid Gp, vec3 x, LU_OUT(vec3) g) {
    vec3 q = lu_v3_sub(x, Gp.origin);
    float f = lu_v3_dot(q, Gp.cam.forward);
    if (!(f > 0.0f)) return false;
    float sx = lu_v3_dot(q, Gp.cam.right) / (f * lu_v3_dot(Gp.cam.right, Gp.cam.right));
    float sy = lu_v3_dot(q, Gp.cam.up) / (f * lu_v3_dot(Gp.cam.up, Gp.cam.up));
    float gx = 0.5f * (sx + 1.0f) * lu_float(Gp.nx) - 0.5f;
    float gy = 0.5f * (1.0f - sy) * lu_float(Gp.ny) - 0.5f;
    float t = lu_v3_len(q);
    float qz = (t - Gp.t_lo + Gp.n0) / Gp.n0;
    if (!(qz > 0.0f)) return false;
    float gz = lu_float(Gp.nz) * lu_log(qz) / Gp.log_r - 0.5f;
    if (gx < -0.5f || gy < -0.5f || gz < -0.5f || gx > lu_float(Gp.nx) - 0.5f || gy > lu_float(Gp.ny) - 0.5f ||
        gz > lu_float(Gp.nz) - 0.5f)
        return false;
    LU_DEREF(g) = lu_v3(gx, gy, gz);
    return true;
}

/* Pass 1 for cell (i, j, k): source S and extinction sig at the cell's
 * sample; with history (Gp: the previous frame's grid) both are blended
 * with the previous lit volume at the same world point, weight alpha.
 * A cell that starts beyond its column's reach (the farthest ray end of the
 * pixels that read the column; cull != 0) is never seen: it is left unlit
 * (returns 0; lit cells return 1). */
LU_FN float lu_k_fx_light(LU_CTX_PARAM, lu_k_rm_params P, lu_k_fx_grid G, int i, int j, int k, int history,
                          lu_k_fx_grid Gp, float alpha, int cull, LU_OUT(vec3) S_out, LU_OUT(vec3) sig_out) {
    LU_DEREF(S_out) = lu_v3s(0.0f);
    LU_DEREF(sig_out) = lu_v3s(0.0f);
    if (cull != 0 && lu_float(k) > lu_k_fx_slice_s(G, lu_k_fx_reach(LU_CTX, j * G.nx + i))) return 0.0f;
    vec3 d = lu_k_fx_column_dir(G, i, j);
    int column = j * G.nx + i;
    float ta = lu_k_fx_slice_t(G, lu_float(k)), tb = lu_k_fx_slice_t(G, lu_float(k + 1));
    float t = lu_k_fx_slice_t(G, lu_float(k) + G.u);
    vec3 x = lu_v3_madd(G.origin, d, t);
    int nm = lu_min(lu_k_medium_count(LU_CTX), LU_K_RM_MAX_MEDIA);
    float dens[LU_K_RM_MAX_MEDIA];
    vec3 sig = lu_v3s(0.0f);
    vec3 Se = lu_v3s(0.0f);
    bool scatters = false;
    for (int m = 0; m < nm; m++) {
        dens[m] = 0.0f;
        lu_k_medium md = lu_k_medium_get(LU_CTX, m);
        float lo = lu_k_fx_span(LU_CTX, column, m, 0), hi = lu_k_fx_span(LU_CTX, column, m, 1);
        float a = 0.0f, b = 0.0f;
        if (!(t >= lo && t <= hi)) continue;
        if (!lu_k_box_clip(md.bounds_lo, md.bounds_hi, G.origin, d, lo, hi, LU_REF(a), LU_REF(b))) continue;
        if (t < a || t > b) continue;
        vec3 pm = lu_k_medium_point(md, x);
        float dm = md.constant != 0 ? md.density_scale : lu_k_density(LU_CTX, m, pm);
        dens[m] = dm;
        sig = lu_v3_madd(sig, lu_k_medium_sigma_t(md), dm);
        scatters = scatters || (dm > 0.0f && lu_k_rm_maxc(md.sigma_s) > 0.0f);
        if (md.emission != 0 && dm > 0.0f) Se = lu_v3_madd(Se, lu_v3_mul(md.sigma_a, lu_k_emission(LU_CTX, m, pm)), dm);
    }
    vec3 S = Se;
    if (scatters) S = lu_v3_add(S, LU_K_RM_INSCATTER(LU_CTX, P, x, d, ta - t, tb - t, dens, nm));
    if (history != 0) {
        vec3 g = lu_v3s(0.0f), Sh = lu_v3s(0.0f), sh = lu_v3s(0.0f);
        if (lu_k_fx_locate(Gp, x, LU_REF(g)) && lu_k_fx_hist_at(LU_CTX, Gp, g.x, g.y, g.z, LU_REF(Sh), LU_REF(sh)) > 0.0f) {
            S = lu_v3_add(lu_v3_scale(S, 1.0f - alpha), lu_v3_scale(Sh, alpha));
            sig = lu_v3_add(lu_v3_scale(sig, 1.0f - alpha), lu_v3_scale(sh, alpha));
        }
    }
    LU_DEREF(S_out) = S;
    LU_DEREF(sig_out) = sig;
    return 1.0f;
}

/* Pass 2 for column (i, j): nodes k = 0..nz of the integrated volume (node
 * k at boundary k; node 0 is zero). The optical depth is summed, not the
 * transmittance multiplied, so thin slices lose nothing to rounding. */
LU_FN void lu_k_fx_integrate(LU_CTX_PARAM, lu_k_fx_grid G, int i, int j) {
    vec3 L = lu_v3s(0.0f), tau = lu_v3s(0.0f);
    int nodes = G.nx * G.ny;
    int column = j * G.nx + i;
    lu_k_fx_int_store(LU_CTX, column, L, tau);
    float ta = lu_k_fx_slice_t(G, 0.0f);
    for (int k = 0; k < G.nz; k++) {
        float tb = lu_k_fx_slice_t(G, lu_float(k + 1));
        float dz = tb - ta;
        ta = tb;
        int cell = lu_k_fx_cell(G, i, j, k);
        vec3 S = lu_k_fx_lit(LU_CTX, cell, 0), sig = lu_k_fx_lit(LU_CTX, cell, 1);
        vec3 xs = lu_v3_scale(sig, dz);
        vec3 w = lu_v3(lu_k_rm_step_weight(xs.x), lu_k_rm_step_weight(xs.y), lu_k_rm_step_weight(xs.z));
        vec3 T = lu_v3_exp(lu_v3_neg(tau));
        L = lu_v3_add(L, lu_v3_mul(lu_v3_mul(T, S), lu_v3_scale(w, dz)));
        tau = lu_v3_add(tau, xs);
        lu_k_fx_int_store(LU_CTX, (k + 1) * nodes + column, L, tau);
    }
}

/* The columns pixel (x, y) reads (i0..i1, j0..j1) and its bilinear weights
 * towards i1, j1 (the lookup of pass 3, and the CPU's column reach). */
LU_FN void lu_k_fx_pixel_columns(lu_k_fx_grid G, int x, int y, LU_OUT(int) i0, LU_OUT(int) i1, LU_OUT(int) j0,
                                 LU_OUT(int) j1, LU_OUT(float) ax, LU_OUT(float) ay) {
    float gx = lu_clamp((lu_float(x) + 0.5f) * lu_float(G.nx) / lu_float(G.width) - 0.5f, 0.0f, lu_float(G.nx - 1));
    float gy = lu_clamp((lu_float(y) + 0.5f) * lu_float(G.ny) / lu_float(G.height) - 0.5f, 0.0f, lu_float(G.ny - 1));
    int a = lu_min(lu_int(gx), G.nx - 1), b = lu_min(lu_int(gy), G.ny - 1);
    LU_DEREF(i0) = a;
    LU_DEREF(j0) = b;
    LU_DEREF(i1) = lu_min(a + 1, G.nx - 1);
    LU_DEREF(j1) = lu_min(b + 1, G.ny - 1);
    LU_DEREF(ax) = gx - lu_float(a);
    LU_DEREF(ay) = gy - lu_float(b);
}

/* Pass 3 for image pixel (x, y): the integrated volume at the pixel's ray
 * end, over the surface or background (lu_k_rm_finish). */
LU_FN vec3 lu_k_fx_pixel(LU_CTX_PARAM, lu_k_rm_params P, lu_k_fx_grid G, int x, int y) {
    int pixel = y * G.width + x;
    vec3 d = lu_k_camera_dir(G.cam, lu_float(x) + 0.5f, lu_float(y) + 0.5f);
    lu_k_rm_hit hit = lu_k_rm_hit_get(LU_CTX, pixel);
    float s = lu_k_fx_slice_s(G, hit.t >= 0.0f ? hit.t : LU_K_FAR);
    int i0 = 0, i1 = 0, j0 = 0, j1 = 0;
    float ax = 0.0f, ay = 0.0f;
    lu_k_fx_pixel_columns(G, x, y, LU_REF(i0), LU_REF(i1), LU_REF(j0), LU_REF(j1), LU_REF(ax), LU_REF(ay));
    int k0 = lu_min(lu_int(s), G.nz - 1);
    float az = s - lu_float(k0);
    int nodes = G.nx * G.ny;
    vec3 L = lu_v3s(0.0f), tau = lu_v3s(0.0f);
    for (int c = 0; c < 8; c++) {
        int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
        float w = (di != 0 ? ax : 1.0f - ax) * (dj != 0 ? ay : 1.0f - ay) * (dk != 0 ? az : 1.0f - az);
        if (w <= 0.0f) continue;
        int node = (k0 + dk) * nodes + (dj != 0 ? j1 : j0) * G.nx + (di != 0 ? i1 : i0);
        L = lu_v3_madd(L, lu_k_fx_int(LU_CTX, node, 0), w);
        tau = lu_v3_madd(tau, lu_k_fx_int(LU_CTX, node, 1), w);
    }
    return lu_k_rm_finish(LU_CTX, P, pixel, G.origin, d, L, tau);
}

#endif
