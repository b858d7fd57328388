/* Internal: the bssrdf method's GPU pass (splat gather + deferred shading,
 * src/methods/bssrdf/bssrdf.comp), written straight against src/backends/gpu.h:
 * everything it needs is uploaded here, in one place, so it can move onto a
 * shared GPU scene module later. The light-space maps, the G-buffer, the
 * splats and their tile lists are made on the CPU (Embree ray casts; the GL
 * backend has no rasteriser or BVH) and are the same for both backends. */
#ifndef LU_METHODS_BSSRDF_GPU_H
#define LU_METHODS_BSSRDF_GPU_H

#include <lucent/lucent.h>

typedef struct lu_bssrdf_gpu lu_bssrdf_gpu;

/* lu_bssrdf_gpu_frame.changed: the inputs that differ from the previous
 * frame's; the others stay on the GPU as uploaded then. */
enum {
    LU_BSSRDF_GPU_DATA = 1u << 0,     /* buf[] (lights, views, environment, scene constants) */
    LU_BSSRDF_GPU_SHADOW = 1u << 1,
    LU_BSSRDF_GPU_SPLATS = 1u << 2,
    LU_BSSRDF_GPU_GBUF = 1u << 3,
    LU_BSSRDF_GPU_TILES = 1u << 4,    /* tile_start and tile_list */
};

typedef struct lu_bssrdf_gpu_frame {
    const float *buf[6];        /* the LU_K_BSSRDF_BUF_* arrays */
    size_t count[6];            /* floats in each */
    const float *shadow;        /* light-space depth maps, map_res^2 each */
    size_t shadow_count;
    int map_res;
    const void *splats;         /* lu_k_splat[splat_count] */
    int splat_count;
    size_t splat_bytes;         /* sizeof(lu_k_splat) */
    const void *gbuf;           /* lu_k_gbuf[width * height], 32 bytes each */
    int width, height;
    const int *tile_start;      /* tiles_x * tiles_y + 1 offsets into tile_list */
    int tiles_x, tiles_y, tile;
    const int *tile_list;
    size_t list_count;
    lu_vec3 cam_right, cam_up, cam_forward;   /* lu_k_camera */
    unsigned changed;           /* LU_BSSRDF_GPU_* */
} lu_bssrdf_gpu_frame;

lu_result lu_bssrdf_gpu_create(lu_bssrdf_gpu **out, lu_error *err);
lu_result lu_bssrdf_gpu_render(lu_bssrdf_gpu *g, const lu_bssrdf_gpu_frame *f, lu_image *out, lu_error *err);
void lu_bssrdf_gpu_destroy(lu_bssrdf_gpu *g);

#endif
