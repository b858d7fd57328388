/* Internal: the ddod method's precomputation (ddod_precompute.c) and the
 * pieces tests call directly. See methods/ddod/lu_ddod.h for the rendering math
 * and docs/ddod.md for the measurements.
 *
 * Precompute, per bounded medium (Bernabei et al. §4):
 *   1. optical depth per voxel for n directions: for each direction, a sweep
 *      of the voxel grid (resolution `res` over the boundary's box) slice by
 *      slice against the direction, which is the paper's bundle of parallel
 *      rays with one ray per voxel: tau(x) = tau(x + h w) + h (D(x) + D(x + h w)) / 2,
 *      the upstream value bilinear in the previous slice; voxels outside the
 *      boundary have density 0, voxels inside opaque objects block;
 *   2. first moment T(x) = sum_w exp(-sigma_t tau(x, w)) w (4 pi / n) and
 *      rho = |div T| by central differences; T only steers the sample
 *      density, so its sum runs over at most 32 directions (its own
 *      spherical-Fibonacci set; the n directions are for step 4);
 *   3. weighted Poisson-disk sampling (dart throwing on a spatial hash grid)
 *      with base radius r = cbrt(V / (2 N_s)) and a local radius mapped
 *      linearly from 1/rho into [r/2, 2r], the radii scaled by a common factor
 *      until the count is within 5 % of N_s;
 *   4. per sample psi(w) = exp(-sigma_t tau(b, w)) and psi^F (times F_t at
 *      each boundary crossing) for the n directions, with the boundary from
 *      ray casts (Embree: exact, not voxelised) and the density integral
 *      exact for constant media and from an unmasked sweep for grids;
 *      projected onto bands^2 real SH by the n-point quadrature;
 *   5. (extension) amplitudes A_i fitted so that sum_j A_j gamma_j(b_i) ~ 1
 *      at every sample: `fit` damped Jacobi updates A_i <- A_i / S_i^0.7.
 * Results are cached on disk, in the cache folder (lu_cache_dir). */
#ifndef LU_METHODS_DDOD_H
#define LU_METHODS_DDOD_H

#include <lucent/lucent.h>

#include <stdint.h>

#include "methods/frame.h"
#include "methods/ddod/lu_ddod_layout.h"
#include "kernels/lu_kernel.h"
#include "methods/common/lu_sh.h"

typedef struct lu_ddod_params {
    int res;          /* voxels along the longest side of a boundary's box */
    int dirs;         /* directions n */
    int samples;      /* target sample count N_s (over all media, split by volume) */
    int bands;        /* SH bands (2..6: 4, 9, 16, 25, 36 coefficients) */
    float width;      /* Gaussian s_i as a fraction of the local Poisson radius */
    uint32_t seed;
    int fit;          /* partition-of-unity iterations on the amplitudes (0: volume shares only) */
} lu_ddod_params;

typedef struct lu_ddod_timing {
    double optical_depth_s, divergence_s, sampling_s, sh_s, total_s;
    double cpu_s;     /* processor time of the process over the precomputation (all threads) */
    bool from_cache;
} lu_ddod_timing;

typedef struct lu_ddod_set {
    int count;        /* samples */
    int bands, channels, stride;
    float *samples;   /* LU_K_DDOD_SAMPLE_FLOATS per sample */
    float *sh;        /* stride per sample: [set: view, light][channel][bands^2] */
    lu_ddod_timing timing;
} lu_ddod_set;

/* The precomputation with the on-disk cache: loads
 * <cache dir>/ddod-<key>.bin when it exists (a corrupt or foreign file is an
 * error naming it), otherwise computes and writes it. use_cache = false
 * computes without reading or writing. Fails with LU_ERR_UNSUPPORTED for
 * media without a boundary mesh. */
lu_result lu_ddod_prepare_set(const lu_scene *scene, const lu_ddod_params *p, bool use_cache, lu_ddod_set *out,
                              lu_error *err);
/* The computation alone. */
lu_result lu_ddod_compute(const lu_scene *scene, const lu_ddod_params *p, lu_ddod_set *out, lu_error *err);
void lu_ddod_set_free(lu_ddod_set *s);

/* ---- cache ---- */
/* 64-bit FNV-1a over everything the precomputation reads. */
uint64_t lu_ddod_key(const lu_scene *scene, const lu_ddod_params *p);
lu_result lu_ddod_cache_save(const char *path, uint64_t key, const lu_ddod_set *s, lu_error *err);
/* LU_ERR_IO when the file is missing; LU_ERR_FORMAT naming the file and
 * what is wrong (magic, version, key, sizes, truncation, checksum). */
lu_result lu_ddod_cache_load(const char *path, uint64_t key, lu_ddod_set *s, lu_error *err);

/* ---- attenuation along one ray (precompute step 4 and the traced light term) ---- */
/* Density integral (not yet times sigma_t) of b + t w over [t0, t1]. */
typedef float (*lu_ddod_span_fn)(void *user, lu_vec3 b, lu_vec3 w, float t0, float t1);
/* From b inside a medium's boundary along unit w over (0, tmax) (tmax >= 1e29:
 * unbounded): *tau = the sum of span() over the parts inside the boundary
 * (INFINITY when an opaque object blocks), *ft = the product of the
 * dielectric F_t (index eta) at every boundary crossing. psi^F along w is
 * then exp(-sigma_t tau) ft. False when the ray query ran out of memory. */
bool lu_ddod_ray(const lu_accel *boundary, const lu_accel *opaque, float eta, lu_vec3 b, lu_vec3 w, float tmax,
                 lu_ddod_span_fn span, void *user, float *tau, float *ft);

/* ---- pieces (tests) ---- */
/* n near-uniform unit directions (spherical Fibonacci); the quadrature
 * weight of each is 4 pi / n. */
void lu_ddod_directions(int n, lu_vec3 *out);
/* c[k] = (4 pi / n) sum_j f_j Y_k(w_j), k < bands^2. */
void lu_ddod_sh_project(int n, const lu_vec3 *dirs, const float *f, int bands, float *c);

/* Weighted Poisson-disk sampling over a voxel field: radius[v] > 0 is the
 * local disk radius in voxel v (0: no samples there); voxel v = (i, j, k)
 * spans lo + [i, i+1] h per axis. Points are drawn voxel by voxel with
 * probability ~ 1/radius^3 and accepted when no accepted point q has
 * |p - q| < max(r_p, r_q). Writes *count points (xyz) and their radii. */
typedef struct lu_ddod_field {
    int n[3];
    lu_vec3 lo;
    float h;
    const float *radius;
} lu_ddod_field;
lu_result lu_ddod_poisson(const lu_ddod_field *f, float scale, int candidates, uint32_t seed, float **points,
                          float **radii, int *count, lu_error *err);

/* ---- rendering: one frame as both backends see it (built in ddod.c) ---- */
typedef struct lu_ddod_frame {
    int width, height, tiles_y;
    lu_k_ddod_params P;
    int count;                 /* samples */
    const float *samples;      /* count * LU_K_DDOD_SAMPLE_FLOATS */
    const float *sh;           /* count * stride (windowed) */
    const float *pixels;       /* width * height * LU_K_DDOD_PIXEL_FLOATS */
    const int *tile_start;     /* tiles + 1 */
    const int *tile_list;
    size_t list_count;
    const float *env_sh;       /* bands^2 rgb triples (when env) */
    unsigned set_version;      /* changes when samples / sh change (GPU re-uploads) */
    const float *traced;       /* P.traced != 0: count * (1 + lights) * 4 floats (methods/ddod/lu_ddod.h) */
    int lights;                /* kernel lights (environment lights excluded) */
    unsigned traced_version;   /* changes when the traced table is recomputed (GPU re-uploads) */
    unsigned pixels_version;   /* changes when the pixel records are recomputed */
    unsigned bins_version;     /* changes when the tile lists are recomputed */
} lu_ddod_frame;

typedef struct lu_ddod_gpu lu_ddod_gpu;
lu_result lu_ddod_gpu_create(const lu_scene *scene, lu_ddod_gpu **out, lu_error *err);
/* Runs both passes into out (the pixel records, tiles and samples come from the CPU). */
lu_result lu_ddod_gpu_render(lu_ddod_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                             const lu_ddod_frame *f, lu_image *out, lu_error *err);
void lu_ddod_gpu_destroy(lu_ddod_gpu *g);

/* Statistics of a renderer's last frame (false if it is not a ddod renderer). */
typedef struct lu_ddod_stats {
    int samples;
    long long list_entries;
    double ms_pixels, ms_samples, ms_binning, ms_gather;
    double ms_traced_view;     /* traced psi towards the camera this frame (0: the camera did not move) */
    double ms_traced_lights;   /* traced psi^F towards the lights this frame (0: no light moved) */
    int traced_view_updates, traced_light_updates;  /* recomputations of the traced table so far */
    int traced_lights_retraced;                     /* lights whose entries those recomputed, summed */
    lu_ddod_timing precompute;
} lu_ddod_stats;
bool lu_ddod_last_stats(const lu_renderer *r, lu_ddod_stats *out);
/* The traced table of a ddod renderer's last frame: per sample 1 + *lights
 * entries of 4 floats (psi towards the camera, then psi^F towards each
 * kernel light; methods/ddod/lu_ddod.h), the *count samples' records in
 * *samples. NULL when the renderer traces nothing. */
const float *lu_ddod_traced_table(const lu_renderer *r, int *lights, int *count, const float **samples);

#endif
