/* lu_screen_rect.h — screen-space support of a ball (kernel: C and GLSL):
 * the pixel rectangle a splat or Gaussian ball can touch, for binning into
 * tiles (methods/common/tile_bins.h). Shared by bssrdf (splats) and ddod (Gaussian
 * balls). */
#ifndef LU_SCREEN_RECT_H
#define LU_SCREEN_RECT_H

#include "kernels/lu_kernel.h"

struct lu_k_rect {
    int x0, y0, x1, y1;   /* pixels [x0, x1) x [y0, y1); empty when x1 <= x0 or y1 <= y0 */
};
LU_TYPEDEF(lu_k_rect)

/* Bounding rectangle on screen of the ball (centre, radius): the box of its
 * cube's eight projected corners, which contains the ball's projection; the
 * whole screen when a corner is at or behind the camera plane. */
LU_FN lu_k_rect lu_k_ball_screen_rect(vec3 cam_pos, vec3 right, vec3 up, vec3 forward, int width, int height,
                                      vec3 centre, float radius) {
    lu_k_rect rc;
    float rr = 1.0f / lu_v3_dot(right, right), ru = 1.0f / lu_v3_dot(up, up);
    float xmin = 1.0e30f, xmax = -1.0e30f, ymin = 1.0e30f, ymax = -1.0e30f;
    bool behind = false;
    for (int k = 0; k < 8; k++) {
        vec3 c = lu_v3(centre.x + ((k & 1) != 0 ? radius : -radius), centre.y + ((k & 2) != 0 ? radius : -radius),
                       centre.z + ((k & 4) != 0 ? radius : -radius));
        vec3 v = lu_v3_sub(c, cam_pos);
        float z = lu_v3_dot(v, forward);
        if (z <= 1.0e-6f * radius) behind = true;
        float sx = lu_v3_dot(v, right) * rr / lu_max(z, 1.0e-30f), sy = lu_v3_dot(v, up) * ru / lu_max(z, 1.0e-30f);
        float px = (sx + 1.0f) * 0.5f * lu_float(width), py = (1.0f - sy) * 0.5f * lu_float(height);
        xmin = lu_min(xmin, px);
        xmax = lu_max(xmax, px);
        ymin = lu_min(ymin, py);
        ymax = lu_max(ymax, py);
    }
    if (behind) {
        rc.x0 = 0;
        rc.y0 = 0;
        rc.x1 = width;
        rc.y1 = height;
        return rc;
    }
    /* Pixel p is covered when its centre p + 0.5 lies inside. */
    rc.x0 = lu_int(lu_clamp(lu_floor(xmin - 0.5f) + 1.0f, 0.0f, lu_float(width)));
    rc.x1 = lu_int(lu_clamp(lu_floor(xmax - 0.5f) + 1.0f, 0.0f, lu_float(width)));
    rc.y0 = lu_int(lu_clamp(lu_floor(ymin - 0.5f) + 1.0f, 0.0f, lu_float(height)));
    rc.y1 = lu_int(lu_clamp(lu_floor(ymax - 0.5f) + 1.0f, 0.0f, lu_float(height)));
    return rc;
}

#endif
