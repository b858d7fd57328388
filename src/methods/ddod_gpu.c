/* The ddod method's GPU passes (see ddod.h): not yet wired. */
#include "methods/ddod.h"

lu_result lu_ddod_gpu_create(const lu_scene *scene, lu_ddod_gpu **out, lu_error *err) {
    *out = NULL;
    return lu_fail(err, LU_ERR_UNSUPPORTED, "ddod: the GPU backend is not available yet");
}
lu_result lu_ddod_gpu_render(lu_ddod_gpu *g, const lu_scene *scene, const lu_ddod_frame *f, lu_image *out,
                             lu_error *err) {
    return lu_fail(err, LU_ERR_UNSUPPORTED, "ddod: the GPU backend is not available yet");
}
void lu_ddod_gpu_destroy(lu_ddod_gpu *g) { (void)g; }
