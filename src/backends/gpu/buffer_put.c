/* lu_gpu_buffer_put: grow-upload-bind of a per-frame storage buffer (and its
 * versioned form, which skips an upload of data the slot holds), on top
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

lu_result lu_gpu_buffer_put_versioned(lu_gpu_context *ctx, lu_gpu_buffer **slot, lu_gpu_upload *up, const void *data,
                                      size_t bytes, unsigned version, int binding, lu_error *err) {
    bool same = up->valid && up->version == version && up->bytes == bytes && *slot;
    up->valid = false;
    lu_result r = lu_gpu_buffer_put(ctx, slot, same ? NULL : data, bytes, binding, err);
    if (r != LU_OK) return r;
    up->valid = true;
    up->version = version;
    up->bytes = bytes;
    return LU_OK;
}
