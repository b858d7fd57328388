/* lu_shadowmap.h — percentage-closer lookup in a shadow map (kernel: C and
 * GLSL). A shadow map stores, per texel of a light view, the depth of the
 * first opaque surface along the texel's centre ray (lu_lightview.h depth;
 * a huge value where nothing is hit).
 *
 * The backend defines, before including this file,
 *   float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j)
 * returning the stored depth of texel (i, j) (clamped to the map by the
 * caller's indices being in range). */
#ifndef LU_SHADOWMAP_H
#define LU_SHADOWMAP_H

#include "kernels/lu_kernel.h"
#include "lu_lightview.h"

/* Fraction of light reaching a point at (u, v, depth): bilinear-weighted
 * comparison of the 4 nearest texels (percentage-closer filtering), with a
 * depth bias that absorbs the map's discretisation on lit surfaces. */
LU_FN float lu_k_shadow_visibility(LU_CTX_PARAM, int map, int res, vec3 uvd, float bias) {
    float x = uvd.x * lu_float(res) - 0.5f, y = uvd.y * lu_float(res) - 0.5f;
    float fx = lu_floor(x), fy = lu_floor(y);
    float ax = x - fx, ay = y - fy;
    int x0 = lu_int(fx), y0 = lu_int(fy);
    float vis = 0.0f;
    for (int j = 0; j < 2; j++) {
        for (int i = 0; i < 2; i++) {
            int xi = lu_int(lu_clamp(lu_float(x0 + i), 0.0f, lu_float(res - 1)));
            int yj = lu_int(lu_clamp(lu_float(y0 + j), 0.0f, lu_float(res - 1)));
            float w = (i == 1 ? ax : 1.0f - ax) * (j == 1 ? ay : 1.0f - ay);
            float lit = uvd.z <= lu_k_shadow_depth(LU_CTX, map, xi, yj) + bias ? 1.0f : 0.0f;
            vis += w * lit;
        }
    }
    return vis;
}

/* Visibility of x in view vw (map index `map`, res x res): offset along n
 * (zero for points in a medium) by 1.5 texel footprints, PCF with a depth
 * bias of 2 footprints, so lit surfaces do not shadow themselves. Points
 * outside the view are lit. Whether x is in the view is decided before the
 * offset, and the offset point is clamped onto the map: near the seam of two
 * cube faces the offset can cross into the neighbouring face, and treating
 * it as outside drew lit lines through shadows along every seam. */
LU_FN float lu_k_shadow_lookup(LU_CTX_PARAM, lu_k_lightview vw, int map, int res, vec3 x, vec3 n) {
    vec3 uvd0 = lu_k_lightview_project(vw, x);
    if (!lu_k_lightview_inside(uvd0)) return 1.0f;
    float depth = vw.ortho != 0 ? 1.0f : uvd0.z;
    float texel = 2.0f * lu_max(vw.extent_u, vw.extent_v) * depth / lu_float(res);
    /* A point in a medium (n = 0) would project to uvd0 again: skip that. */
    vec3 uvd = uvd0;
    if (lu_v3_dot(n, n) > 0.0f) {
        uvd = lu_k_lightview_project(vw, lu_v3_madd(x, n, 1.5f * texel));
        if (uvd.z <= 0.0f) uvd = uvd0;
    }
    uvd.x = lu_clamp(uvd.x, 0.0f, 1.0f);
    uvd.y = lu_clamp(uvd.y, 0.0f, 1.0f);
    return lu_k_shadow_visibility(LU_CTX, map, res, uvd, 2.0f * texel);
}

#endif
