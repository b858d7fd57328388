#include "methods/common/gpu_method.h"

#include <stdio.h>
#include <string.h>

static void release(lu_gpu_method *m);

static lu_result init(lu_gpu_method *m, const lu_scene *scene, const lu_gpu_method_program *programs, lu_error *err) {
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
    if (r != LU_OK) release(m);
    return r;
}

static void release(lu_gpu_method *m) {
    for (int i = 0; i < LU_GPU_METHOD_MAX_SLOTS; i++) lu_gpu_buffer_destroy(m->buf[i]);
    lu_gpu_scene_destroy(m->scene);
    for (int i = 0; i < LU_GPU_METHOD_MAX_PROGRAMS; i++) lu_gpu_program_destroy(m->prog[i]);
    lu_gpu_context_destroy(m->ctx);
    memset(m, 0, sizeof *m);
}

lu_result lu_gpu_method_create(size_t size, const lu_scene *scene, const lu_gpu_method_program *programs,
                               const char *method, lu_gpu_method **out, lu_error *err) {
    *out = NULL;
    lu_gpu_method *m = size >= sizeof *m ? lu_calloc(1, size) : NULL;
    if (!m) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", method);
    lu_result r = init(m, scene, programs, err);
    if (r != LU_OK) {
        lu_free(m);
        return r;
    }
    *out = m;
    return LU_OK;
}

void lu_gpu_method_destroy(lu_gpu_method *m) {
    if (!m) return;
    release(m);
    lu_free(m);
}

lu_result lu_gpu_method_put(lu_gpu_method *m, int i, const void *data, size_t bytes, lu_error *err) {
    return lu_gpu_buffer_put(m->ctx, &m->buf[i], data, bytes, m->binding0 + i, err);
}

lu_result lu_gpu_method_put_kept(lu_gpu_method *m, int i, const void *data, size_t bytes, unsigned version,
                                 lu_error *err) {
    return lu_gpu_buffer_put_versioned(m->ctx, &m->buf[i], &m->up[i], data, bytes, version, m->binding0 + i, err);
}
