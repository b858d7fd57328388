/* Private to src/backends/gpu: the structs behind the opaque handles. */
#ifndef LU_GPU_INTERNAL_H
#define LU_GPU_INTERNAL_H

#include "backends/gpu.h"
#include "core/memory.h"

#ifdef LU_HAVE_GPU
#include <epoxy/egl.h>
#include <epoxy/gl.h>

struct lu_gpu_context {
    EGLDisplay display;
    EGLContext context;
    lu_gpu_info info;
    int refs;                /* renderers holding this device (context.c's table) */
    int slot;                /* its preference: the table's index */
    bool lost;               /* reset (or an injected loss): every call fails; new renderers get a fresh device */
    /* The caller's own context (caller.c): not made, not in the table, never
     * made current by lucent; `native` is its EGLContext or GLXContext. */
    bool caller;
    void *native;
    struct lu_gpu_program *output[3];   /* caller.c's texture writers, one per format, made on first use */
};

struct lu_gpu_program {
    lu_gpu_context *ctx;
    GLuint id;
    int local_size[3];
};

/* Each object charges its storage to the memory account in use where it
 * was made (core/memory.h) until it is destroyed. */
struct lu_gpu_buffer {
    lu_gpu_context *ctx;
    GLuint id;
    size_t size;
    lu_mem_account *account;
};

struct lu_gpu_texture {
    lu_gpu_context *ctx;
    GLuint id;
    GLenum target;           /* GL_TEXTURE_3D (density) or GL_TEXTURE_2D (RGBA32F image) */
    int nx, ny, nz;
    size_t bytes;            /* its storage: R32F or RGBA32F texels */
    lu_mem_account *account;
};

/* The GL limits and strings of the current context. */
void lu_gpu_query_info(lu_gpu_info *info);
/* caller.c: true when ctx (a caller's context) is current on this thread. */
bool lu_gpu_caller_is_current(const lu_gpu_context *ctx);
/* caller.c: the context lu_gpu_context_create hands out on this thread
 * (lu_gpu_caller_use), or NULL. */
lu_gpu_context *lu_gpu_caller_in_use(void);
/* caller.c: frees a caller context's own objects once its last holder let go. */
void lu_gpu_caller_release(lu_gpu_context *ctx);

/* Makes ctx current if it is not; cheap when it already is. */
lu_result lu_gpu_bind_context(lu_gpu_context *ctx, lu_error *err);
/* Fails with the pending GL error (if any) naming `what`; clears the queue. */
lu_result lu_gpu_check_gl(const char *what, lu_error *err);
#endif

#endif
