/* The caller's own OpenGL context and its textures (backends/gpu.h, "the
 * caller's own context and textures"). The context is recognised by its
 * native handle: EGL's current context, else GLX's, looked up in the libGLX
 * a window library already loaded (lucent itself never loads GLX). */
#ifdef LU_HAVE_GPU
#include "backends/gpu/gpu_internal.h"

#include <dlfcn.h>
#include <stdio.h>
#include <string.h>

static void *current_glx(void) {
    static const char *const libs[] = {"libGLX.so.0", "libGL.so.1"};
    for (size_t i = 0; i < sizeof libs / sizeof libs[0]; i++) {
        void *h = dlopen(libs[i], RTLD_LAZY | RTLD_NOLOAD);
        if (!h) continue;
        void *(*get)(void) = (void *(*)(void))dlsym(h, "glXGetCurrentContext");
        void *c = get ? get() : NULL;
        dlclose(h);
        if (c) return c;
    }
    return NULL;
}

/* The native handle of this thread's current context, or NULL. */
static void *current_native(void) {
    EGLContext e = eglGetCurrentContext();
    return e != EGL_NO_CONTEXT ? (void *)e : current_glx();
}

static _Thread_local lu_gpu_context *t_caller;
static _Thread_local unsigned t_target;
static _Thread_local bool t_written;

bool lu_gpu_caller_is_current(const lu_gpu_context *ctx) { return ctx->native && current_native() == ctx->native; }
lu_gpu_context *lu_gpu_caller_in_use(void) { return t_caller; }
void lu_gpu_caller_use(lu_gpu_context *ctx) { t_caller = ctx; }

lu_result lu_gpu_caller_context_create(lu_gpu_context **out, lu_error *err) {
    *out = NULL;
    void *native = current_native();
    if (!native)
        return lu_fail(err, LU_ERR_BACKEND, "gpu: no OpenGL context is current on this thread (the caller's context "
                                            "must be current to render in it)");
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    while (glGetError() != GL_NO_ERROR) {
    }
    if (major * 10 + minor < 45)
        return lu_fail(err, LU_ERR_BACKEND, "gpu: the caller's OpenGL context is version %d.%d; lucent needs 4.5",
                       (int)major, (int)minor);
    lu_gpu_context *ctx = lu_calloc(1, sizeof *ctx);
    if (!ctx) return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    ctx->caller = true;
    ctx->native = native;
    ctx->refs = 1;
    lu_gpu_query_info(&ctx->info);
    ctx->info.is_software = strstr(ctx->info.renderer, "llvmpipe") || strstr(ctx->info.renderer, "softpipe") ||
                            strstr(ctx->info.renderer, "swrast");
    ctx->info.loop_cap = strstr(ctx->info.renderer, "llvmpipe") != NULL;
    snprintf(ctx->info.device, sizeof ctx->info.device, "the caller's context");
    *out = ctx;
    return LU_OK;
}

void lu_gpu_caller_release(lu_gpu_context *ctx) {
    for (int i = 0; i < 3; i++) lu_gpu_program_destroy(ctx->output[i]);
    lu_free(ctx);
}

void lu_gpu_output_target(unsigned texture) {
    t_target = texture;
    t_written = false;
}
bool lu_gpu_output_written(void) { return t_written; }

/* The texture's internal format as an index into k_formats, after checking
 * that it is a texture of the current context and has the frame's size. */
static const struct {
    GLenum format;
    const char *glsl;
} k_formats[3] = {{GL_RGBA32F, "rgba32f"}, {GL_RGBA16F, "rgba16f"}, {GL_RGBA8, "rgba8"}};

static lu_result texture_format(unsigned texture, int width, int height, int *index, lu_error *err) {
    /* An error the caller's own calls left pending is not this call's. */
    while (glGetError() != GL_NO_ERROR) {
    }
    if (!texture || !glIsTexture(texture))
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: %u is not a texture of the current OpenGL context", texture);
    GLint w = 0, h = 0, format = 0;
    glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_WIDTH, &w);
    glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_HEIGHT, &h);
    glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_INTERNAL_FORMAT, &format);
    lu_result r = lu_gpu_check_gl("texture query", err);
    if (r != LU_OK) return r;
    if (w != width || h != height)
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: texture %u is %dx%d but the frame is %dx%d", texture, (int)w,
                       (int)h, width, height);
    for (int i = 0; i < 3; i++)
        if ((GLenum)format == k_formats[i].format) {
            *index = i;
            return LU_OK;
        }
    return lu_fail(err, LU_ERR_UNSUPPORTED,
                   "gpu: texture %u has internal format 0x%04x; lucent writes GL_RGBA32F, GL_RGBA16F or GL_RGBA8",
                   texture, (unsigned)format);
}

/* One invocation per pixel: the frame's RGB floats (rows top to bottom)
 * into the texture, bottom to top as GL stores rows, alpha 1. */
static const char k_output_comp[] =
    "layout(local_size_x = 8, local_size_y = 8) in;\n"
    "layout(std430, binding = 0) readonly buffer Rgb { float rgb[]; };\n"
    "layout(LU_OUTPUT_FORMAT, binding = 0) uniform writeonly image2D target;\n"
    "uniform ivec2 size;\n"
    "void main() {\n"
    "    ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (p.x >= size.x || p.y >= size.y) return;\n"
    "    int i = 3 * (p.y * size.x + p.x);\n"
    "    imageStore(target, ivec2(p.x, size.y - 1 - p.y), vec4(rgb[i], rgb[i + 1], rgb[i + 2], 1.0));\n"
    "}\n";

lu_result lu_gpu_output(lu_gpu_buffer *rgb, int width, int height, float *out, lu_error *err) {
    lu_gpu_context *ctx = rgb->ctx;
    if (!t_target || !ctx->caller) return lu_gpu_buffer_download(rgb, 0, out, (size_t)width * height * 3 * sizeof(float), err);
    lu_result r = lu_gpu_bind_context(ctx, err);
    int f = 0;
    if (r == LU_OK) r = texture_format(t_target, width, height, &f, err);
    if (r == LU_OK && !ctx->output[f]) {
        char defines[64];
        snprintf(defines, sizeof defines, "#define LU_OUTPUT_FORMAT %s\n", k_formats[f].glsl);
        const lu_gpu_source src = {"backends/gpu/output.comp", k_output_comp};
        r = lu_gpu_program_create_ex(ctx, src.name, defines, &src, 1, &ctx->output[f], err);
    }
    if (r != LU_OK) return r;
    lu_gpu_program *prog = ctx->output[f];
    glUseProgram(lu_gpu_program_gl_name(prog));
    glUniform2i(glGetUniformLocation(lu_gpu_program_gl_name(prog), "size"), width, height);
    r = lu_gpu_buffer_bind(rgb, 0, err);
    if (r != LU_OK) return r;
    glBindImageTexture(0, t_target, 0, GL_FALSE, 0, GL_WRITE_ONLY, k_formats[f].format);
    r = lu_gpu_dispatch(prog, (unsigned)(width + 7) / 8, (unsigned)(height + 7) / 8, 1, err);
    glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, k_formats[f].format);
    if (r == LU_OK) t_written = true;
    return r;
}

lu_result lu_gpu_texture_put_rgb(unsigned texture, const float *rgb, int width, int height, lu_error *err) {
    if (!current_native()) return lu_fail(err, LU_ERR_BACKEND, "gpu: no OpenGL context is current on this thread");
    int f = 0;
    lu_result r = texture_format(texture, width, height, &f, err);
    if (r != LU_OK) return r;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    /* RGB into an RGBA texture sets alpha to 1; rows flipped one at a time. */
    for (int y = 0; y < height; y++)
        glTextureSubImage2D(texture, 0, 0, height - 1 - y, width, 1, GL_RGB, GL_FLOAT, rgb + (size_t)y * width * 3);
    return lu_gpu_check_gl("texture upload", err);
}

#endif
