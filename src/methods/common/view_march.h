/* Internal: the view march shared by raymarch, afm and the gradient family —
 * what one frame of it hands to a backend (CPU loop or GPU pass). The CPU
 * builds it (Embree hits, spans, shadow maps) so both backends read
 * identical inputs; the per-pixel math is methods/common/lu_view_march.h. */
#ifndef LU_METHODS_VIEW_MARCH_H
#define LU_METHODS_VIEW_MARCH_H

#include <lucent/lucent.h>

#include "kernels/lu_camera.h"
#include "methods/common/lu_lightview.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "methods/common/media_ray.h"
#include "methods/common/lu_ms.h"

/* Loop iterations one GPU invocation may run: Mesa's llvmpipe ends every
 * loop of an invocation after 65535 in total (tests/test_gpu.c), so the GPU
 * march is dispatched in segments that stay below this. */
#define LU_RM_LOOP_BUDGET 60000

typedef struct lu_view_march_frame {
    int width, height;
    /* lu_k_rm_params fields */
    lu_vec3 background;
    float step, eps;
    int jitter, map_res;
    float t_cut;                     /* early termination bound (lu_view_march.h) */
    lu_k_ms ms;                      /* multiple-scattering octaves (lu_ms.h); fill sets them off */
    int medium_count, light_count;   /* light_count: non-environment lights */
    const float *hits;               /* width*height*LU_K_RM_HIT_FLOATS */
    const float *spans;              /* width*height*medium_count*2 */
    int view_count;
    const float *views;              /* view_count*LU_RM_VIEW_FLOATS */
    const int *view_table;           /* light_count*2: first view, view count */
    const float *shadow;             /* view_count*map_res*map_res depths */
    const float *surface_vis;        /* width*height*light_count: exact opaque visibility of each light
                                      * at each camera hit (lu_media_rays_surface_vis) */
    unsigned maps_version;           /* changes whenever views or shadow maps are rebuilt */
    unsigned hits_version;           /* ... hits and spans (lu_media_rays.hits_version) */
    unsigned vis_version;            /* ... surface_vis (lu_media_rays.vis_version) */
    const lu_majorant *majorants;    /* per medium (lu_media_rays_majorants) */
    int max_steps;                   /* most march steps any camera ray takes (media diagonal / step) */
} lu_view_march_frame;

/* The frame of one view march over mr's inputs: step = media-box diagonal / steps. */
void lu_view_march_frame_fill(lu_view_march_frame *f, const lu_scene *scene, const lu_media_rays *mr, int steps, float eps,
                            int jitter, int nl, float t_cut);

/* The t_cut parameter every view-march method takes (lu_param_desc fields:
 * name, type, default, range, help). */
#define LU_VIEW_MARCH_T_CUT_PARAM                                                                                     \
    {"t_cut", LU_PARAM_FLOAT, 1e-3, 0, 1, NULL,                                                                       \
     "early termination: the view march stops once the camera ray's transmittance is below this; the radiance "      \
     "left out is at most t_cut times the largest radiance beyond (0: march to the end)"}

/* The multiple-scattering settings every view-march method takes, at
 * parameter indices first .. first + LU_VIEW_MARCH_MS_PARAM_COUNT - 1 of its
 * table (docs/multiple-scattering.md; defaults from the fit there). */
#define LU_VIEW_MARCH_MS_PARAM_COUNT 5
#define LU_VIEW_MARCH_MS_PARAMS(first)                                                                                \
    [(first)] = {"ms", LU_PARAM_CHOICE, 0, 0, 1, "off|octaves",                                                       \
                 "multiple scattering: off (single scattering) or Wrenninge's octaves (docs/multiple-scattering.md)"}, \
    [(first) + 1] = {"ms_octaves", LU_PARAM_INT, LU_VIEW_MARCH_MS_N, 1, 16, NULL,                                     \
                     "ms=octaves: number of octaves N (1: single scattering)"},                                        \
    [(first) + 2] = {"ms_a", LU_PARAM_FLOAT, LU_VIEW_MARCH_MS_A, 0.01, 1, NULL,                                       \
                     "ms=octaves: octave i sees the extinction towards the light scaled by a^i"},                     \
    [(first) + 3] = {"ms_b", LU_PARAM_FLOAT, LU_VIEW_MARCH_MS_B, 0, 1, NULL,                                          \
                     "ms=octaves: octave i contributes b^i"},                                                         \
    [(first) + 4] = {"ms_c", LU_PARAM_FLOAT, LU_VIEW_MARCH_MS_C, 0, 1, NULL,                                          \
                     "ms=octaves: octave i has phase eccentricity c^i g"},
#define LU_VIEW_MARCH_MS_N 3
#define LU_VIEW_MARCH_MS_A 0.5
#define LU_VIEW_MARCH_MS_B 0.2
#define LU_VIEW_MARCH_MS_C 0.25

/* The octave record of the values at params[first ..] (LU_VIEW_MARCH_MS_PARAMS):
 * one octave (single scattering) when ms = off. */
lu_k_ms lu_view_march_ms(const double *params_first);

/* A view-march method's CPU pixel: the radiance along the camera ray o + t d
 * of `pixel` (u: where in each step the sample sits), from its kernel. */
struct lu_k_rm_params;   /* lu_view_march.h, the kernel */
typedef lu_vec3 (*lu_view_march_pixel_fn)(void *state, struct lu_k_rm_params P, int pixel, lu_vec3 o, lu_vec3 d,
                                          float u);
/* The CPU pixel stage of a view-march frame f: every pixel's camera ray
 * (cam, from the camera's position) through fn into out, over the frame's
 * rows (lu_frame_for_rows). */
void lu_view_march_render_rows(const lu_frame *frame, const lu_view_march_frame *f, lu_k_camera cam,
                               lu_view_march_pixel_fn fn, void *state, lu_image *out);

/* Upper bound of the loop iterations one shadow ray through medium k takes
 * in the view march (lu_k_optical_depth_blocks), for GPU segment sizes. */
long lu_view_march_shadow_iterations(const lu_k_medium *k);

#endif
