/* lu_gpu_buffer_put: grow-upload-bind of a per-frame storage buffer, on top
 * of the buffer calls (works with the stub backend too, failing as it does). */
#include "backends/gpu.h"

lu_result lu_gpu_buffer_put(lu_gpu_context *ctx, lu_gpu_buffer **slot, const void *data, size_t bytes, int binding,
                            lu_error *err) {
    if (bytes == 0) bytes = 16, data = NULL;
    if (!*slot || lu_gpu_buffer_size(*slot) < bytes) {
        lu_gpu_buffer_destroy(*slot);
        *slot = NULL;
        lu_result r = lu_gpu_buffer_create(ctx, bytes, NULL, slot, err);
        if (r != LU_OK) return r;
    }
    if (data) {
        lu_result r = lu_gpu_buffer_upload(*slot, 0, data, bytes, err);
        if (r != LU_OK) return r;
    }
    return lu_gpu_buffer_bind(*slot, binding, err);
}
