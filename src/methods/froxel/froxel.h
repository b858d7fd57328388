/* Internal: the froxel method's frame (froxel.c) and its GPU driver
 * (froxel_gpu.c); the math is lu_froxel.h. */
#ifndef LU_METHODS_FROXEL_H
#define LU_METHODS_FROXEL_H

#include "methods/common/view_march.h"
#include "methods/froxel/lu_froxel_grid.h"
#include "methods/frame.h"

/* What one frame of the grid hands to a backend besides the view march's
 * frame: this frame's grid, the previous one (for reprojection), and when
 * the column spans were last rebuilt. */
typedef struct lu_fx_frame {
    lu_k_fx_grid grid, prev;
    int history;                 /* 1: blend with the previous lit volume */
    float blend;
    int cull;                    /* 1: leave cells beyond their column's reach unlit */
    unsigned spans_version;      /* reach and spans */
} lu_fx_frame;

typedef struct lu_froxel_gpu lu_froxel_gpu;

lu_result lu_froxel_gpu_create(const lu_scene *scene, lu_froxel_gpu **out, lu_error *err);
/* relight: run the light and integration passes (else only the pixel pass
 * over the kept volume). */
lu_result lu_froxel_gpu_render(lu_froxel_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                               const lu_view_march_frame *f, const lu_fx_frame *fx, const float *cspans, bool relight,
                               lu_image *out, lu_error *err);
void lu_froxel_gpu_destroy(lu_froxel_gpu *g);

#endif
