/* Private to src/backends/gpu: the structs behind the opaque handles. */
#ifndef LU_GPU_INTERNAL_H
#define LU_GPU_INTERNAL_H

#include "backends/gpu.h"

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
};

struct lu_gpu_program {
    lu_gpu_context *ctx;
    GLuint id;
    int local_size[3];
};

struct lu_gpu_buffer {
    lu_gpu_context *ctx;
    GLuint id;
    size_t size;
};

struct lu_gpu_texture {
    lu_gpu_context *ctx;
    GLuint id;
    GLenum target;           /* GL_TEXTURE_3D (density) or GL_TEXTURE_2D (RGBA32F image) */
    int nx, ny, nz;
};

/* Makes ctx current if it is not; cheap when it already is. */
lu_result lu_gpu_bind_context(lu_gpu_context *ctx, lu_error *err);
/* Fails with the pending GL error (if any) naming `what`; clears the queue. */
lu_result lu_gpu_check_gl(const char *what, lu_error *err);
#endif

#endif
