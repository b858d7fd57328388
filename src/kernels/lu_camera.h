/* lu_camera.h — pinhole camera rays (kernel: C and GLSL). Pixel (x, y) with
 * y = 0 at the top; pixel centres at +0.5, so one sample per pixel passes
 * through the centre (docs/architecture.md §7). */
#ifndef LU_CAMERA_H
#define LU_CAMERA_H

#include "lu_kernel.h"

struct lu_k_camera {
    vec3 right;    /* scaled so that px = width maps to the image's right edge */
    vec3 up;
    vec3 forward;
    float inv_width, inv_height;
};
LU_TYPEDEF(lu_k_camera)

LU_FN lu_k_camera lu_k_camera_make(vec3 position, vec3 look_at, vec3 up_hint, float fov_y_deg, int width,
                                   int height) {
    lu_k_camera k;
    vec3 f = lu_v3_norm(lu_v3_sub(look_at, position));
    vec3 r = lu_v3_norm(lu_v3_cross(f, up_hint));
    vec3 u = lu_v3_cross(r, f);
    float half_h = lu_sin(0.5f * fov_y_deg * (LU_K_PI / 180.0f)) / lu_cos(0.5f * fov_y_deg * (LU_K_PI / 180.0f));
    float aspect = lu_float(width) / lu_float(height);
    k.right = lu_v3_scale(r, half_h * aspect);
    k.up = lu_v3_scale(u, half_h);
    k.forward = f;
    k.inv_width = 1.0f / lu_float(width);
    k.inv_height = 1.0f / lu_float(height);
    return k;
}

/* Unit direction through image position (px, py) in pixels. */
LU_FN vec3 lu_k_camera_dir(lu_k_camera k, float px, float py) {
    float sx = 2.0f * px * k.inv_width - 1.0f;
    float sy = 1.0f - 2.0f * py * k.inv_height;
    return lu_v3_norm(lu_v3_add(k.forward, lu_v3_add(lu_v3_scale(k.right, sx), lu_v3_scale(k.up, sy))));
}

#endif
