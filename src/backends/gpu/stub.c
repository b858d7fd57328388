/* The GPU API in a build without EGL/epoxy: every call that needs GL fails
 * with one clear reason, so callers (CLI, bench, tests) can report it. */
#ifndef LU_HAVE_GPU
#include "backends/gpu.h"

#include <stdio.h>
#include <stdlib.h>

#define LU_GPU_NO(err) lu_fail(err, LU_ERR_BACKEND, "gpu: built without GPU support (EGL/epoxy not found by pkg-config)")

lu_result lu_gpu_context_create(lu_gpu_context **out, lu_gpu_device_pref pref, lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
void lu_gpu_context_destroy(lu_gpu_context *ctx) {}
void lu_gpu_fault_inject(lu_gpu_fault fault, int after) { (void)fault, (void)after; }
void lu_gpu_serial_enter(void) {}
void lu_gpu_serial_leave(void) {}
bool lu_gpu_hardware_probe(char *why, size_t why_size) {
    snprintf(why, why_size, "built without GPU support (EGL/epoxy not found by pkg-config)");
    return false;
}
bool lu_gpu_context_is_current(const lu_gpu_context *ctx) { return false; }
void lu_gpu_info_get(const lu_gpu_context *ctx, lu_gpu_info *out) { *out = (lu_gpu_info){0}; }
lu_result lu_gpu_make_current(lu_gpu_context *ctx, lu_error *err) { return LU_GPU_NO(err); }
void lu_gpu_finish(lu_gpu_context *ctx) {}
double lu_gpu_time_begin(lu_gpu_context *ctx) { return lu_time_seconds(); }
double lu_gpu_time_end(lu_gpu_context *ctx, double t0) { return lu_time_seconds() - t0; }

lu_result lu_gpu_program_create(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                lu_gpu_program **out, lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
lu_result lu_gpu_program_create_ex(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                   const lu_gpu_source *overlay, int overlay_count, lu_gpu_program **out,
                                   lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
void lu_gpu_program_destroy(lu_gpu_program *prog) {}
unsigned lu_gpu_program_gl_name(const lu_gpu_program *prog) { return 0; }
void lu_gpu_program_local_size(const lu_gpu_program *prog, int size[3]) { size[0] = size[1] = size[2] = 0; }
void lu_gpu_uniform_int(lu_gpu_program *prog, const char *name, int v) {}
void lu_gpu_uniform_uint(lu_gpu_program *prog, const char *name, unsigned v) {}
void lu_gpu_uniform_float(lu_gpu_program *prog, const char *name, float v) {}
void lu_gpu_uniform_vec3(lu_gpu_program *prog, const char *name, float x, float y, float z) {}
void lu_gpu_uniform_vec4(lu_gpu_program *prog, const char *name, float x, float y, float z, float w) {}
lu_result lu_gpu_dispatch(lu_gpu_program *prog, unsigned gx, unsigned gy, unsigned gz, lu_error *err) {
    return LU_GPU_NO(err);
}

lu_result lu_gpu_buffer_create(lu_gpu_context *ctx, size_t bytes, const void *data, lu_gpu_buffer **out,
                               lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
void lu_gpu_buffer_destroy(lu_gpu_buffer *buf) {}
size_t lu_gpu_buffer_size(const lu_gpu_buffer *buf) { return 0; }
lu_result lu_gpu_buffer_upload(lu_gpu_buffer *buf, size_t offset, const void *data, size_t bytes, lu_error *err) {
    return LU_GPU_NO(err);
}
lu_result lu_gpu_buffer_download(lu_gpu_buffer *buf, size_t offset, void *data, size_t bytes, lu_error *err) {
    return LU_GPU_NO(err);
}
lu_result lu_gpu_buffer_bind(lu_gpu_buffer *buf, int binding, lu_error *err) { return LU_GPU_NO(err); }

lu_result lu_gpu_texture3d_create(lu_gpu_context *ctx, int nx, int ny, int nz, const float *data,
                                  lu_gpu_texture **out, lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
lu_result lu_gpu_texture3d_upload(lu_gpu_texture *tex, const float *data, lu_error *err) { return LU_GPU_NO(err); }
lu_result lu_gpu_image2d_create(lu_gpu_context *ctx, int width, int height, lu_gpu_texture **out, lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
lu_result lu_gpu_image2d_download(lu_gpu_texture *tex, float *rgba, lu_error *err) { return LU_GPU_NO(err); }
void lu_gpu_texture_destroy(lu_gpu_texture *tex) {}
lu_result lu_gpu_texture_bind(lu_gpu_texture *tex, int unit, lu_error *err) { return LU_GPU_NO(err); }
lu_result lu_gpu_image_bind(lu_gpu_texture *tex, int unit, lu_error *err) { return LU_GPU_NO(err); }
lu_result lu_gpu_caller_context_create(lu_gpu_context **out, lu_error *err) {
    *out = NULL;
    return LU_GPU_NO(err);
}
void lu_gpu_caller_use(lu_gpu_context *ctx) { (void)ctx; }
void lu_gpu_output_target(unsigned texture) { (void)texture; }
bool lu_gpu_output_written(void) { return false; }
lu_result lu_gpu_output(lu_gpu_buffer *rgb, int width, int height, float *out, lu_error *err) { return LU_GPU_NO(err); }
lu_result lu_gpu_texture_put_rgb(unsigned texture, const float *rgb, int width, int height, lu_error *err) {
    return LU_GPU_NO(err);
}
#endif
