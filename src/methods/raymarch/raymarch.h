/* Internal: the raymarch method's GPU driver (raymarch_gpu.c); the frame it
 * renders is the shared view march's (methods/common/view_march.h). */
#ifndef LU_METHODS_RAYMARCH_H
#define LU_METHODS_RAYMARCH_H

#include "methods/common/view_march.h"
#include "methods/frame.h"

typedef struct lu_raymarch_gpu lu_raymarch_gpu;

lu_result lu_raymarch_gpu_create(const lu_scene *scene, lu_raymarch_gpu **out, lu_error *err);
lu_result lu_raymarch_gpu_render(lu_raymarch_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                                 const lu_view_march_frame *f, lu_image *out, lu_error *err);
void lu_raymarch_gpu_destroy(lu_raymarch_gpu *g);

#endif
