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
#include "methods/frame.h"

/* Floats per medium of a boundary surface record: albedo, shininess, specular, pad. */
#define LU_AFM_SURFACE_FLOATS 8
/* Floats per texel and medium of the light-ray spans: start, end, and the
 * cosines at the boundary crossings there (lu_k_afm_lspan in lu_afm.h). */
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
    /* Each product is rebuilt only when the frame (methods/frame.h) changed
     * what it depends on, and per light when only some lights changed:
     *   views and light-ray spans ("afm.views"): lights, geometry;
     *   maps ("afm.maps"): lights, media, geometry. */
    bool views_valid, maps_valid;
    unsigned version;           /* changes whenever views/lspans change */
    uint64_t rebuild;           /* kernel lights (bit l; bit 63: 63 and up) whose maps this frame builds */
} lu_afm_map;

/* Bit l of a kernel-light set such as lu_afm_map.rebuild (bit 63 stands for lights 63 and up). */
static inline bool lu_afm_has_light(uint64_t set, int l) { return (set >> (l < 63 ? l : 63)) & 1u; }

/* Map settings from the method's parameters; channels follow the media
 * (1 when every medium's sigma_t is grey, else 3). */
void lu_afm_map_init(lu_afm_map *map, const lu_scene *scene, int res, int coefs, int samples);
void lu_afm_map_free(lu_afm_map *map);

/* Light views over the media's box for the frame's nl kernel lights and,
 * for bounded media, the light rays' boundary spans and crossing cosines
 * (Embree through mr's boundary accelerations), rebuilt for the lights
 * whose inputs changed; sets map->rebuild to the lights whose maps must be
 * built this frame (their views changed, or the media did). */
lu_result lu_afm_map_views(lu_afm_map *map, const lu_frame *f, const lu_media_rays *mr, int nl, lu_error *err);

/* After the backend built the map->rebuild lights' maps: counts the
 * rebuilds ("afm.maps", one per light) and keeps the maps. */
void lu_afm_map_built(lu_afm_map *map, const lu_frame *f);

/* Views (all lights) the scene's non-environment lights need: 6 per point light. */
int lu_afm_view_count(const lu_scene *scene);

/* The records of the map->rebuild lights' views on the CPU (kernel
 * lu_k_afm_build_texel per texel); the other views' records are kept.
 * f: the frame whose majorants let the build skip empty blocks (NULL: none skipped). */
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
    const lu_frame_records *rec;  /* the frame's camera, media and light records */
    const lu_media_rays *mr;    /* camera hits/spans/normals, shadow views and maps */
    const lu_afm_map *map;      /* views, lspans (records are built on the GPU) */
    const float *surfaces;      /* nm * LU_AFM_SURFACE_FLOATS */
    unsigned surfaces_version;  /* changes whenever surfaces do */
    lu_vec3 background;
    float step, eps;
    int jitter, shadow_res, nl;
    float t_cut;                /* view march early termination (lu_view_march.h) */
    lu_k_ms ms;                 /* multiple-scattering octaves (lu_ms.h) */
} lu_afm_gpu_frame;

lu_result lu_afm_gpu_create(const lu_scene *scene, lu_afm_gpu **out, lu_error *err);
/* Builds the map->rebuild lights' maps on the GPU, then renders; each CPU
 * input is uploaded only when it changed (its media-rays or map version). */
lu_result lu_afm_gpu_render(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_gpu_frame *f, lu_image *out,
                            lu_error *err);
void lu_afm_gpu_destroy(lu_afm_gpu *g);
/* Builds only the maps (afm_build.comp) of the map->rebuild lights' views
 * and downloads all records into `records` (lu_afm_map_texels *
 * lu_afm_map_stride floats). */
lu_result lu_afm_gpu_build_download(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_map *map, float *records,
                                    lu_error *err);
/* The device's largest storage buffer (bytes), which bounds the map's
 * records; *loop_cap: the device is llvmpipe, whose shader invocations stop
 * looping after 65535 loop iterations in total. */
size_t lu_afm_gpu_limits(const lu_afm_gpu *g, bool *loop_cap);

#endif
