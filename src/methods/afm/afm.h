/* Internal: attenuation function maps (methods/afm/lu_afm.h) as data the CPU
 * driver, the GPU pass and the tests share. */
#ifndef LU_METHODS_AFM_H
#define LU_METHODS_AFM_H

#include <lucent/lucent.h>

#include "methods/common/lu_lightview.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "methods/common/media_ray.h"
#include "methods/common/view_march.h"

/* Floats per medium of a boundary surface record: albedo, shininess, specular, pad. */
#define LU_AFM_SURFACE_FLOATS 8
/* Floats per texel and medium of the light-ray spans: start, end, F_t at start, F_t at end. */
#define LU_AFM_LSPAN_FLOATS 4

typedef struct lu_afm_map {
    int res, coefs, samples, channels;
    int nm, nl;
    bool bounded;               /* some medium has a boundary mesh: lspans are used */
    /* views framing the media's box, per light (first, count in view_table) */
    lu_k_lightview *views;
    float *views_packed;        /* view_count * LU_RM_VIEW_FLOATS */
    int *view_table;
    int view_count;
    float *lspans;              /* view_count * res^2 * nm * LU_AFM_LSPAN_FLOATS (bounded only) */
    float *records;             /* view_count * res^2 * stride: what the map build writes */
    size_t records_cap, lspans_cap;
    lu_k_light *lights;         /* lights the views and lspans were made for */
    bool views_valid;
    unsigned version;           /* changes whenever views/lspans change */
} lu_afm_map;

/* Map settings from the method's parameters; channels follow the media
 * (1 when every medium's sigma_t is grey, else 3). */
void lu_afm_map_init(lu_afm_map *map, const lu_scene *scene, int res, int coefs, int samples);
void lu_afm_map_free(lu_afm_map *map);

/* Light views over the media's box and, for bounded media, the light rays'
 * boundary spans and Fresnel factors (Embree through mr's boundary
 * accelerations). Kept while the lights do not change. */
lu_result lu_afm_map_views(lu_afm_map *map, const lu_scene *scene, const lu_media_rays *mr, const lu_k_light *kl,
                           int nl, lu_error *err);

/* Views (all lights) the scene's non-environment lights need: 6 per point light. */
int lu_afm_view_count(const lu_scene *scene);

/* The map's records on the CPU (kernel lu_k_afm_build_texel per texel). */
/* f: the frame whose majorants let the build skip empty blocks (NULL: none skipped). */
lu_result lu_afm_map_build_cpu(lu_afm_map *map, const lu_scene *scene, const lu_k_medium *km,
                               const lu_view_march_frame *f, lu_error *err);

/* Transmittance from kernel light l to x looked up in a CPU-built map. */
lu_vec3 lu_afm_map_transmittance(const lu_afm_map *map, int l, lu_vec3 x);

size_t lu_afm_map_texels(const lu_afm_map *map);
int lu_afm_map_stride(const lu_afm_map *map);

/* The GPU side (afm_gpu.c): builds the map with methods/afm/afm_build.comp and
 * renders with methods/afm/afm_render.comp over the shared GPU scene. */
typedef struct lu_afm_gpu lu_afm_gpu;
typedef struct lu_afm_gpu_frame {
    const lu_media_rays *mr;    /* camera hits/spans/normals, shadow views and maps */
    const lu_afm_map *map;      /* views, lspans (records are built on the GPU) */
    const float *surfaces;      /* nm * LU_AFM_SURFACE_FLOATS */
    lu_vec3 background;
    float step, eps;
    int jitter, shadow_res, nl;
    float t_cut;                /* view march early termination (lu_view_march.h) */
} lu_afm_gpu_frame;

lu_result lu_afm_gpu_create(const lu_scene *scene, lu_afm_gpu **out, lu_error *err);
lu_result lu_afm_gpu_render(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_gpu_frame *f, lu_image *out,
                            lu_error *err);
void lu_afm_gpu_destroy(lu_afm_gpu *g);
/* Builds only the maps (afm_build.comp) for map's views and downloads the
 * records into `records` (lu_afm_map_texels * lu_afm_map_stride floats). */
lu_result lu_afm_gpu_build_download(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_map *map, float *records,
                                    lu_error *err);
/* The device's largest storage buffer (bytes), which bounds the map's
 * records; *loop_cap: the device is llvmpipe, whose shader invocations stop
 * looping after 65535 loop iterations in total. */
size_t lu_afm_gpu_limits(const lu_afm_gpu *g, bool *loop_cap);

#endif
