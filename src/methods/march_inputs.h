/* Internal: the per-frame inputs of camera-ray march kernels that only the
 * CPU can build (it has the ray tracer), shared by every method that marches
 * camera rays on both backends (raymarch, gradient, ...):
 *   - per pixel, the camera ray's first opaque hit (normals, material) as an
 *     lu_k_rm_hit record (LU_K_RM_HIT_FLOATS floats), and each bounded
 *     medium's first span along the ray (Embree);
 *   - per light, its light views (lightview.h) packed as
 *     LU_MARCH_VIEW_FLOATS floats, shadow maps of the opaque objects, and,
 *     when a medium is bounded by a mesh, boundary maps: per view, medium
 *     and texel, the depths where the texel's light ray enters and leaves
 *     the boundary and the Fresnel transmittance at both crossings
 *     (LU_MARCH_BMAP_FLOATS), so shadow rays clip bounded media to their
 *     boundary (exactly for convex ones) and carry F_t as the reference does.
 * Both are cached: hits while the camera is unchanged, maps while the
 * lights are unchanged (maps_version counts rebuilds, for GPU re-uploads). */
#ifndef LU_METHODS_MARCH_INPUTS_H
#define LU_METHODS_MARCH_INPUTS_H

#include <lucent/lucent.h>

#include "backends/gpu.h"
#include "kernels/lu_camera.h"
#include "kernels/lu_lightview.h"
#include "kernels/lu_optics.h"

/* Packed light view: origin + ortho, axis_u + extent_u, axis_v + extent_v,
 * axis_w + depth_far (16 floats, std430 vec4[4]). */
#define LU_MARCH_VIEW_FLOATS 16
/* Floats per texel of a boundary map: depth a, depth b (a < b, the segment
 * of the light ray inside the boundary; b <= a: none), F_t at a, F_t at b
 * (1 where the segment ends at the light, not at a crossing). */
#define LU_MARCH_BMAP_FLOATS 4
/* Floats per pixel and medium in the span buffer: t0, t1 (the first span of
 * the camera ray inside the medium's boundary; 0, far for unbounded media),
 * entry flag (1 when the ray enters through the boundary at t0), -, the
 * boundary's geometric normal there (facing the viewer), the boundary
 * material's shininess, albedo, -, specular, - (for the reflection term). */
#define LU_MARCH_SPAN_FLOATS 16
/* Floats per pixel in the hit buffer (lu_k_rm_hit in kernels/lu_raymarch.h). */
#define LU_MARCH_HIT_FLOATS 16

typedef struct lu_march_inputs {
    const char *who;           /* method name for error messages */
    int res;                   /* shadow map resolution */
    lu_accel *opaque;          /* NULL without opaque objects */
    int *opaque_object;        /* accel mesh id -> scene object index */
    lu_accel **boundary;       /* per medium, NULL when unbounded */
    int medium_count;
    /* camera rays */
    float *hits, *spans;       /* pixels*LU_MARCH_HIT_FLOATS, pixels*medium_count*LU_MARCH_SPAN_FLOATS */
    size_t pixels_cap;
    lu_camera hits_cam;
    bool hits_valid;
    lu_k_camera cam;
    const lu_scene *scene;
    /* light views and shadow maps */
    lu_k_lightview *views;
    float *views_packed;       /* view_count*LU_MARCH_VIEW_FLOATS */
    int *view_table;           /* per kernel light: first view, view count */
    float *shadow;             /* view_count*res*res depths */
    float *bmaps;              /* view_count*medium_count*res*res*LU_MARCH_BMAP_FLOATS, or NULL (no bounded medium) */
    size_t bmap_floats;
    int view_count;
    lu_k_light *maps_lights;
    int maps_nl;
    bool maps_valid;
    unsigned maps_version;
} lu_march_inputs;

/* Builds the opaque and boundary accelerators of `scene`. */
lu_result lu_march_inputs_init(lu_march_inputs *mi, const lu_scene *scene, int shadow_res, const char *who,
                               lu_error *err);
/* Hits and spans for the scene's camera, views and maps for the kernel
 * lights kl[0..nl) (lu_scene_kernel_lights order), rebuilt only on change. */
lu_result lu_march_inputs_update(lu_march_inputs *mi, const lu_scene *scene, const lu_k_light *kl, int nl,
                                 lu_error *err);
void lu_march_inputs_free(lu_march_inputs *mi);

/* The same inputs on the GPU: six storage buffers bound at first_binding
 * .. first_binding + 5 (hits, spans, views, view table, shadow maps,
 * boundary maps); the maps are re-uploaded only after a rebuild. */
#define LU_MARCH_GPU_BUFFERS 6
typedef struct lu_march_inputs_gpu {
    lu_gpu_buffer *buf[LU_MARCH_GPU_BUFFERS];
    size_t size[LU_MARCH_GPU_BUFFERS];
    unsigned maps_version;
    bool maps_uploaded;
} lu_march_inputs_gpu;

lu_result lu_march_inputs_gpu_put(lu_march_inputs_gpu *g, lu_gpu_context *ctx, const lu_march_inputs *mi,
                                  const lu_scene *scene, int nl, int first_binding, lu_error *err);
void lu_march_inputs_gpu_free(lu_march_inputs_gpu *g);

#endif
