/* Internal: what every GPU method driver holds, made and released in one
 * place: the device (lu_gpu_context_create: lucent's shared one, or the
 * caller's), the method's programs, the shared GPU scene (for methods that
 * read the scene's records) and its per-frame buffers in numbered slots,
 * slot i bound at binding0 + i (above the scene's bindings when there is a
 * scene). A driver embeds one and adds what is its own. */
#ifndef LU_METHODS_GPU_METHOD_H
#define LU_METHODS_GPU_METHOD_H

#include "backends/gpu.h"
#include "methods/common/gpu_scene.h"

#define LU_GPU_METHOD_MAX_PROGRAMS 4
#define LU_GPU_METHOD_MAX_SLOTS 16

typedef struct lu_gpu_method {
    lu_gpu_context *ctx;
    lu_gpu_program *prog[LU_GPU_METHOD_MAX_PROGRAMS];
    lu_gpu_scene *scene;                       /* NULL: the method reads no scene records */
    lu_gpu_buffer *buf[LU_GPU_METHOD_MAX_SLOTS];
    lu_gpu_upload up[LU_GPU_METHOD_MAX_SLOTS]; /* what each slot holds (lu_gpu_method_put_kept) */
    int binding0;
} lu_gpu_method;

/* One program: an embedded .comp and "#define ..." lines of its own (or NULL). */
typedef struct lu_gpu_method_program {
    const char *name, *defines;
} lu_gpu_method_program;

/* Makes a driver of `size` bytes, zeroed, whose first member is its
 * lu_gpu_method, with the device, the programs and the GPU scene made.
 * programs: a list ending with a NULL name, each compiled with its own
 * defines and then the scene's (lu_gpu_scene_defines); scene NULL: no GPU
 * scene, no scene defines, slots from binding 0. `method` names it in the
 * out-of-memory error. On failure everything made so far is released. */
lu_result lu_gpu_method_create(size_t size, const lu_scene *scene, const lu_gpu_method_program *programs,
                               const char *method, lu_gpu_method **out, lu_error *err);
/* Releases the slots, the GPU scene, the programs and the device, then the
 * driver (what the driver adds of its own it releases first). */
void lu_gpu_method_destroy(lu_gpu_method *m);
/* lu_gpu_buffer_put into slot i. */
lu_result lu_gpu_method_put(lu_gpu_method *m, int i, const void *data, size_t bytes, lu_error *err);
/* lu_gpu_buffer_put_versioned into slot i: uploads only a new version. */
lu_result lu_gpu_method_put_kept(lu_gpu_method *m, int i, const void *data, size_t bytes, unsigned version,
                                 lu_error *err);

#endif
