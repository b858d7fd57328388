/* The afm method's GPU passes (see afm.h): placeholder until the shaders land. */
#include <stdlib.h>

#include "methods/afm.h"

struct lu_afm_gpu {
    int unused;
};

lu_result lu_afm_gpu_create(const lu_scene *scene, lu_afm_gpu **out, lu_error *err) {
    (void)scene;
    *out = NULL;
    return lu_fail(err, LU_ERR_UNSUPPORTED, "afm: the GPU backend is not implemented yet");
}

lu_result lu_afm_gpu_render(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_gpu_frame *f, lu_image *out,
                            lu_error *err) {
    (void)g, (void)scene, (void)f, (void)out;
    return lu_fail(err, LU_ERR_UNSUPPORTED, "afm: the GPU backend is not implemented yet");
}

void lu_afm_gpu_destroy(lu_afm_gpu *g) { free(g); }
