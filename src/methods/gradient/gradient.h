/* Internal: the gradient method family (gradient, rbf, pervoxel; Ren et al.
 * 2008): what one frame hands to a backend, the GPU pass, and frame
 * statistics for benches and tests. The per-sample, per-voxel and per-pixel
 * math is methods/gradient/lu_gradient.h. */
#ifndef LU_METHODS_GRADIENT_H
#define LU_METHODS_GRADIENT_H

#include <lucent/lucent.h>

#include "methods/gradient/lu_gradient_params.h"
#include "methods/common/media_ray.h"
#include "methods/frame.h"

typedef struct lu_gradient_frame {
    lu_k_gr_params G;
    lu_vec3 background;              /* lu_k_rm_params of the march */
    float step, eps;
    int jitter;
    float t_cut;                     /* view march early termination (lu_view_march.h) */
    int width, height, medium_count, light_count;
    const lu_frame_records *rec;     /* the frame's camera, media and light records */
    const lu_media_rays *mr;         /* hits, spans, normals, views, shadow maps, boundary maps */
    const float *surf;               /* 8 floats per medium: boundary materials (lu_k_gr_surf) */
    /* samples being evaluated: n records of LU_K_GR_SAMPLE_FLOATS */
    float *samples;
    int sample_count;
    /* cell lists over the final samples */
    const int *cell_begin;           /* cells + 1 prefix offsets */
    const int *cell_items;
    int cell_item_count;
} lu_gradient_frame;

/* Frame statistics of the last render. */
typedef struct lu_gradient_stats {
    int samples;                 /* final samples (union over levels) */
    int root_samples;            /* initial samples (including the coverage fill) */
    int evaluated;               /* samples evaluated in the last frame (the others were kept) */
    int fill_samples;            /* coverage-fill samples among them */
    int level_samples[4];        /* samples evaluated per level */
    int split[4];                /* samples split per level */
    int gaussians;               /* fitted Gaussians (all media) */
    double fit_rel_l2;           /* |D - Gaussians| / |D| (worst medium) */
    double fit_ms, reconstruct_ms; /* prepare: fit, and one reconstruction of D */
    double ms_samples, ms_field, ms_march;
    long long cell_items;
    double uncovered;            /* CPU, with lu_host.debug: fraction of dense voxels with a zero field */
    int grid[3];                 /* radiance grid */
} lu_gradient_stats;

bool lu_gradient_last_stats(const lu_renderer *r, lu_gradient_stats *out);

typedef struct lu_gradient_gpu lu_gradient_gpu;
lu_result lu_gradient_gpu_create(const lu_scene *scene, lu_gradient_gpu **out, lu_error *err);
/* Evaluates f->samples[first .. first+count): fills F and the gradient in
 * place; E and tau (in: tau_in per sample, -1 = trace it) written to err_tau
 * as pairs. */
lu_result lu_gradient_gpu_eval(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, int first,
                               int count, int want_error, const float *tau_in, float *err_tau, lu_error *err);
/* tau_v (lu_k_gr_view_tau) of f->samples[0 .. count) into tau. */
lu_result lu_gradient_gpu_view_tau(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, int count,
                                   float *tau, lu_error *err);
/* Builds the radiance grid (interpolation or per-voxel tracing) when
 * rebuild is set, else keeps the one built last, and marches the camera rays
 * into out. */
lu_result lu_gradient_gpu_render(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, bool rebuild,
                                 lu_image *out, double *ms_field, double *ms_march, lu_error *err);
void lu_gradient_gpu_destroy(lu_gradient_gpu *g);

#endif
