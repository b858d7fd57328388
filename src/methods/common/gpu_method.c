#include "methods/common/gpu_method.h"

#include <stdio.h>
#include <string.h>

lu_result lu_gpu_method_init(lu_gpu_method *m, const lu_scene *scene, const lu_gpu_method_program *programs,
                             lu_error *err) {
    memset(m, 0, sizeof *m);
    m->binding0 = scene ? LU_SCENE_BINDING_FREE : 0;
    lu_result r = lu_gpu_context_create(&m->ctx, LU_GPU_AUTO, err);
    for (int i = 0; r == LU_OK && programs[i].name; i++) {
        char defines[1024];
        int n = snprintf(defines, sizeof defines, "%s%s", programs[i].defines ? programs[i].defines : "",
                         scene ? lu_gpu_scene_defines(scene) : "");
        if (i == LU_GPU_METHOD_MAX_PROGRAMS)
            r = lu_fail(err, LU_ERR_LIMIT, "gpu: more than %d programs for one method", LU_GPU_METHOD_MAX_PROGRAMS);
        else if (n < 0 || (size_t)n >= sizeof defines)
            r = lu_fail(err, LU_ERR_LIMIT, "gpu: %s: defines longer than %zu bytes", programs[i].name, sizeof defines - 1);
        else
            r = lu_gpu_program_create(m->ctx, programs[i].name, n ? defines : NULL, &m->prog[i], err);
    }
    if (r == LU_OK && scene) r = lu_gpu_scene_create(m->ctx, scene, &m->scene, err);
    if (r != LU_OK) lu_gpu_method_release(m);
    return r;
}

void lu_gpu_method_release(lu_gpu_method *m) {
    for (int i = 0; i < LU_GPU_METHOD_MAX_SLOTS; i++) lu_gpu_buffer_destroy(m->buf[i]);
    lu_gpu_scene_destroy(m->scene);
    for (int i = 0; i < LU_GPU_METHOD_MAX_PROGRAMS; i++) lu_gpu_program_destroy(m->prog[i]);
    lu_gpu_context_destroy(m->ctx);
    memset(m, 0, sizeof *m);
}

lu_result lu_gpu_method_put(lu_gpu_method *m, int i, const void *data, size_t bytes, lu_error *err) {
    return lu_gpu_buffer_put(m->ctx, &m->buf[i], data, bytes, m->binding0 + i, err);
}

lu_result lu_gpu_method_put_kept(lu_gpu_method *m, int i, const void *data, size_t bytes, unsigned version,
                                 lu_error *err) {
    return lu_gpu_buffer_put_versioned(m->ctx, &m->buf[i], &m->up[i], data, bytes, version, m->binding0 + i, err);
}
