/* Compute programs, shader storage buffers, 3D density textures and RGBA32F
 * output images: thin GL 4.5 (direct state access) wrappers that fail with
 * messages instead of leaving GL errors queued. */
#ifdef LU_HAVE_GPU
#include "backends/gpu/gpu_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- programs ----------------------------------------------------------------- */

/* Driver logs can be long; the lu_error keeps what fits. */
#define LU_GPU_LOG_MAX 8192

static char *info_log(GLuint obj, bool is_program) {
    GLint len = 0;
    if (is_program) glGetProgramiv(obj, GL_INFO_LOG_LENGTH, &len);
    else glGetShaderiv(obj, GL_INFO_LOG_LENGTH, &len);
    if (len < 1) len = 1;
    if (len > LU_GPU_LOG_MAX) len = LU_GPU_LOG_MAX;
    char *log = lu_calloc((size_t)len + 1, 1);
    if (!log) return NULL;
    if (is_program) glGetProgramInfoLog(obj, len, NULL, log);
    else glGetShaderInfoLog(obj, len, NULL, log);
    return log;
}

/* Trims trailing whitespace so messages end cleanly. */
static void rstrip(char *s) {
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\n' || s[n - 1] == ' ' || s[n - 1] == '\r')) s[--n] = '\0';
}

lu_result lu_gpu_program_create_ex(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                   const lu_gpu_source *overlay, int overlay_count, lu_gpu_program **out,
                                   lu_error *err) {
    *out = NULL;
    lu_result r = lu_gpu_bind_context(ctx, err);
    if (r != LU_OK) return r;
    char *text = NULL;
    lu_gpu_source_map *map = lu_malloc(sizeof *map);
    if (!map) return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    r = lu_gpu_assemble(comp_name, defines, overlay, overlay_count, &text, map, err);
    if (r != LU_OK) {
        lu_free(map);
        return r;
    }
    const char *main_name = map->count > 1 ? map->names[1] : comp_name;

    GLuint sh = glCreateShader(GL_COMPUTE_SHADER);
    const GLchar *src = text;
    glShaderSource(sh, 1, &src, NULL);
    glCompileShader(sh);
    GLint ok = 0;
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char *log = info_log(sh, false);
        char *translated = lu_malloc(LU_GPU_LOG_MAX);
        if (log && translated) {
            lu_gpu_translate_log(log, map, translated, LU_GPU_LOG_MAX);
            rstrip(translated);
        }
        r = lu_fail(err, LU_ERR_BACKEND, "%s: GLSL compile failed:\n%s", main_name,
                    translated ? translated : "(out of memory for the info log)");
        lu_free(log);
        lu_free(translated);
        glDeleteShader(sh);
        lu_free(text);
        lu_free(map);
        return r;
    }
    GLuint prog = glCreateProgram();
    glAttachShader(prog, sh);
    glLinkProgram(prog);
    glDetachShader(prog, sh);
    glDeleteShader(sh);
    lu_free(text);
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        char *log = info_log(prog, true);
        char *translated = lu_malloc(LU_GPU_LOG_MAX);
        if (log && translated) {
            lu_gpu_translate_log(log, map, translated, LU_GPU_LOG_MAX);
            rstrip(translated);
        }
        r = lu_fail(err, LU_ERR_BACKEND, "%s: GLSL link failed:\n%s", main_name,
                    translated ? translated : "(out of memory for the info log)");
        lu_free(log);
        lu_free(translated);
        glDeleteProgram(prog);
        lu_free(map);
        return r;
    }
    lu_free(map);
    lu_gpu_program *p = lu_calloc(1, sizeof *p);
    if (!p) {
        glDeleteProgram(prog);
        return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    }
    p->ctx = ctx;
    p->id = prog;
    glGetProgramiv(prog, GL_COMPUTE_WORK_GROUP_SIZE, p->local_size);
    r = lu_gpu_check_gl(comp_name, err);
    if (r != LU_OK) {
        lu_gpu_program_destroy(p);
        return r;
    }
    *out = p;
    return LU_OK;
}

lu_result lu_gpu_program_create(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                lu_gpu_program **out, lu_error *err) {
    return lu_gpu_program_create_ex(ctx, comp_name, defines, NULL, 0, out, err);
}

void lu_gpu_program_destroy(lu_gpu_program *prog) {
    if (!prog) return;
    if (lu_gpu_bind_context(prog->ctx, NULL) == LU_OK) glDeleteProgram(prog->id);
    lu_free(prog);
}

unsigned lu_gpu_program_gl_name(const lu_gpu_program *prog) { return prog->id; }

void lu_gpu_program_local_size(const lu_gpu_program *prog, int size[3]) {
    for (int i = 0; i < 3; i++) size[i] = prog->local_size[i];
}

static GLint uniform_location(lu_gpu_program *prog, const char *name) {
    if (lu_gpu_bind_context(prog->ctx, NULL) != LU_OK) return -1;
    return glGetUniformLocation(prog->id, name);
}

void lu_gpu_uniform_int(lu_gpu_program *prog, const char *name, int v) {
    GLint loc = uniform_location(prog, name);
    if (loc >= 0) glProgramUniform1i(prog->id, loc, v);
}

void lu_gpu_uniform_uint(lu_gpu_program *prog, const char *name, unsigned v) {
    GLint loc = uniform_location(prog, name);
    if (loc >= 0) glProgramUniform1ui(prog->id, loc, v);
}

void lu_gpu_uniform_float(lu_gpu_program *prog, const char *name, float v) {
    GLint loc = uniform_location(prog, name);
    if (loc >= 0) glProgramUniform1f(prog->id, loc, v);
}

void lu_gpu_uniform_vec3(lu_gpu_program *prog, const char *name, float x, float y, float z) {
    GLint loc = uniform_location(prog, name);
    if (loc >= 0) glProgramUniform3f(prog->id, loc, x, y, z);
}

void lu_gpu_uniform_vec4(lu_gpu_program *prog, const char *name, float x, float y, float z, float w) {
    GLint loc = uniform_location(prog, name);
    if (loc >= 0) glProgramUniform4f(prog->id, loc, x, y, z, w);
}

lu_result lu_gpu_dispatch(lu_gpu_program *prog, unsigned gx, unsigned gy, unsigned gz, lu_error *err) {
    if (!prog) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: dispatch of a NULL program");
    lu_result r = lu_gpu_bind_context(prog->ctx, err);
    if (r != LU_OK) return r;
    const int *lim = prog->ctx->info.max_work_group_count;
    if (gx < 1 || gy < 1 || gz < 1 || gx > (unsigned)lim[0] || gy > (unsigned)lim[1] || gz > (unsigned)lim[2])
        return lu_fail(err, LU_ERR_LIMIT, "gpu: dispatch %ux%ux%u outside [1, %dx%dx%d] work groups", gx, gy, gz,
                       lim[0], lim[1], lim[2]);
    glUseProgram(prog->id);
    glDispatchCompute(gx, gy, gz);
    /* every later reader (download, texture fetch, next dispatch) must see the writes */
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    return lu_gpu_check_gl("glDispatchCompute", err);
}

/* ---- shader storage buffers ------------------------------------------------------ */

lu_result lu_gpu_buffer_create(lu_gpu_context *ctx, size_t bytes, const void *data, lu_gpu_buffer **out,
                               lu_error *err) {
    *out = NULL;
    lu_result r = lu_gpu_bind_context(ctx, err);
    if (r != LU_OK) return r;
    if (bytes == 0 || bytes > (size_t)PTRDIFF_MAX)
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: buffer size %zu bytes is invalid", bytes);
    lu_gpu_buffer *b = lu_calloc(1, sizeof *b);
    if (!b) return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    b->ctx = ctx;
    b->size = bytes;
    b->account = lu_mem_charge(LU_MEM_GPU, bytes);
    glCreateBuffers(1, &b->id);
    glNamedBufferData(b->id, (GLsizeiptr)bytes, data, GL_DYNAMIC_COPY);
    if (!data) {
        GLubyte zero = 0;
        glClearNamedBufferData(b->id, GL_R8UI, GL_RED_INTEGER, GL_UNSIGNED_BYTE, &zero);
    }
    r = lu_gpu_check_gl("buffer create", err);
    if (r != LU_OK) {
        lu_gpu_buffer_destroy(b);
        return r;
    }
    *out = b;
    return LU_OK;
}

void lu_gpu_buffer_destroy(lu_gpu_buffer *buf) {
    if (!buf) return;
    if (lu_gpu_bind_context(buf->ctx, NULL) == LU_OK) glDeleteBuffers(1, &buf->id);
    lu_mem_discharge(buf->account, LU_MEM_GPU, buf->size);
    lu_free(buf);
}

size_t lu_gpu_buffer_size(const lu_gpu_buffer *buf) { return buf->size; }

static lu_result check_range(const lu_gpu_buffer *buf, size_t offset, size_t bytes, const char *what,
                             lu_error *err) {
    if (offset > buf->size || bytes > buf->size - offset)
        return lu_fail(err, LU_ERR_RANGE, "gpu: buffer %s of %zu bytes at offset %zu exceeds its %zu bytes", what,
                       bytes, offset, buf->size);
    return LU_OK;
}

lu_result lu_gpu_buffer_upload(lu_gpu_buffer *buf, size_t offset, const void *data, size_t bytes, lu_error *err) {
    lu_result r = check_range(buf, offset, bytes, "upload", err);
    if (r == LU_OK) r = lu_gpu_bind_context(buf->ctx, err);
    if (r != LU_OK || bytes == 0) return r;
    glNamedBufferSubData(buf->id, (GLintptr)offset, (GLsizeiptr)bytes, data);
    return lu_gpu_check_gl("buffer upload", err);
}

lu_result lu_gpu_buffer_download(lu_gpu_buffer *buf, size_t offset, void *data, size_t bytes, lu_error *err) {
    lu_result r = check_range(buf, offset, bytes, "download", err);
    if (r == LU_OK) r = lu_gpu_bind_context(buf->ctx, err);
    if (r != LU_OK || bytes == 0) return r;
    glGetNamedBufferSubData(buf->id, (GLintptr)offset, (GLsizeiptr)bytes, data);
    return lu_gpu_check_gl("buffer download", err);
}

lu_result lu_gpu_buffer_bind(lu_gpu_buffer *buf, int binding, lu_error *err) {
    lu_result r = lu_gpu_bind_context(buf->ctx, err);
    if (r != LU_OK) return r;
    if (binding < 0 || binding >= buf->ctx->info.max_ssbo_bindings)
        return lu_fail(err, LU_ERR_RANGE, "gpu: storage buffer binding %d outside [0, %d)", binding,
                       buf->ctx->info.max_ssbo_bindings);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, (GLuint)binding, buf->id);
    return lu_gpu_check_gl("buffer bind", err);
}

/* ---- textures and images ---------------------------------------------------------- */

lu_result lu_gpu_texture3d_create(lu_gpu_context *ctx, int nx, int ny, int nz, const float *data,
                                  lu_gpu_texture **out, lu_error *err) {
    *out = NULL;
    lu_result r = lu_gpu_bind_context(ctx, err);
    if (r != LU_OK) return r;
    int lim = ctx->info.max_3d_texture_size;
    if (nx < 1 || ny < 1 || nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: 3D texture %dx%dx%d is empty", nx, ny, nz);
    if (nx > lim || ny > lim || nz > lim)
        return lu_fail(err, LU_ERR_LIMIT, "gpu: 3D texture %dx%dx%d exceeds GL_MAX_3D_TEXTURE_SIZE %d", nx, ny,
                       nz, lim);
    if ((unsigned long long)nx * ny * nz > LU_MAX_GRID_VOXELS)
        return lu_fail(err, LU_ERR_LIMIT, "gpu: 3D texture %dx%dx%d exceeds LU_MAX_GRID_VOXELS", nx, ny, nz);
    if (!data) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: 3D texture without data");
    lu_gpu_texture *t = lu_calloc(1, sizeof *t);
    if (!t) return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    t->ctx = ctx;
    t->target = GL_TEXTURE_3D;
    t->nx = nx;
    t->ny = ny;
    t->nz = nz;
    t->bytes = (size_t)nx * ny * nz * sizeof(float);
    t->account = lu_mem_charge(LU_MEM_GPU, t->bytes);
    glCreateTextures(GL_TEXTURE_3D, 1, &t->id);
    glTextureStorage3D(t->id, 1, GL_R32F, nx, ny, nz);
    /* zero-outside convention of lu_grid_sample: a zero border, linear filter */
    static const float border[4] = {0, 0, 0, 0};
    glTextureParameteri(t->id, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(t->id, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(t->id, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
    glTextureParameteri(t->id, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
    glTextureParameteri(t->id, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_BORDER);
    glTextureParameterfv(t->id, GL_TEXTURE_BORDER_COLOR, border);
    r = lu_gpu_check_gl("3D texture create", err);
    if (r == LU_OK) r = lu_gpu_texture3d_upload(t, data, err);
    if (r != LU_OK) {
        lu_gpu_texture_destroy(t);
        return r;
    }
    *out = t;
    return LU_OK;
}

lu_result lu_gpu_texture3d_upload(lu_gpu_texture *tex, const float *data, lu_error *err) {
    if (tex->target != GL_TEXTURE_3D) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: not a 3D texture");
    lu_result r = lu_gpu_bind_context(tex->ctx, err);
    if (r != LU_OK) return r;
    /* rows of floats are 4-byte aligned; reset any unpack state a caller changed */
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, 0);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    glTextureSubImage3D(tex->id, 0, 0, 0, 0, tex->nx, tex->ny, tex->nz, GL_RED, GL_FLOAT, data);
    return lu_gpu_check_gl("3D texture upload", err);
}

lu_result lu_gpu_image2d_create(lu_gpu_context *ctx, int width, int height, lu_gpu_texture **out, lu_error *err) {
    *out = NULL;
    lu_result r = lu_gpu_bind_context(ctx, err);
    if (r != LU_OK) return r;
    if (width < 1 || height < 1 || width > LU_MAX_IMAGE_DIM || height > LU_MAX_IMAGE_DIM)
        return lu_fail(err, LU_ERR_LIMIT, "gpu: image %dx%d outside [1, %d]", width, height, LU_MAX_IMAGE_DIM);
    lu_gpu_texture *t = lu_calloc(1, sizeof *t);
    if (!t) return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    t->ctx = ctx;
    t->target = GL_TEXTURE_2D;
    t->nx = width;
    t->ny = height;
    t->nz = 1;
    t->bytes = (size_t)width * height * 4 * sizeof(float);
    t->account = lu_mem_charge(LU_MEM_GPU, t->bytes);
    glCreateTextures(GL_TEXTURE_2D, 1, &t->id);
    glTextureStorage2D(t->id, 1, GL_RGBA32F, width, height);
    static const float zero[4] = {0, 0, 0, 0};
    glClearTexImage(t->id, 0, GL_RGBA, GL_FLOAT, zero);
    r = lu_gpu_check_gl("image create", err);
    if (r != LU_OK) {
        lu_gpu_texture_destroy(t);
        return r;
    }
    *out = t;
    return LU_OK;
}

lu_result lu_gpu_image2d_download(lu_gpu_texture *tex, float *rgba, lu_error *err) {
    if (tex->target != GL_TEXTURE_2D) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: not a 2D image");
    lu_result r = lu_gpu_bind_context(tex->ctx, err);
    if (r != LU_OK) return r;
    size_t bytes = (size_t)tex->nx * (size_t)tex->ny * 4u * sizeof(float);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glPixelStorei(GL_PACK_ROW_LENGTH, 0);
    glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    glGetTextureImage(tex->id, 0, GL_RGBA, GL_FLOAT, (GLsizei)bytes, rgba);
    return lu_gpu_check_gl("image download", err);
}

void lu_gpu_texture_destroy(lu_gpu_texture *tex) {
    if (!tex) return;
    if (lu_gpu_bind_context(tex->ctx, NULL) == LU_OK) glDeleteTextures(1, &tex->id);
    lu_mem_discharge(tex->account, LU_MEM_GPU, tex->bytes);
    lu_free(tex);
}

lu_result lu_gpu_texture_bind(lu_gpu_texture *tex, int unit, lu_error *err) {
    lu_result r = lu_gpu_bind_context(tex->ctx, err);
    if (r != LU_OK) return r;
    if (unit < 0 || unit >= tex->ctx->info.max_texture_units)
        return lu_fail(err, LU_ERR_RANGE, "gpu: texture unit %d outside [0, %d)", unit,
                       tex->ctx->info.max_texture_units);
    glBindTextureUnit((GLuint)unit, tex->id);
    return lu_gpu_check_gl("texture bind", err);
}

lu_result lu_gpu_image_bind(lu_gpu_texture *tex, int unit, lu_error *err) {
    if (tex->target != GL_TEXTURE_2D) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: not a 2D image");
    lu_result r = lu_gpu_bind_context(tex->ctx, err);
    if (r != LU_OK) return r;
    if (unit < 0 || unit >= tex->ctx->info.max_image_units)
        return lu_fail(err, LU_ERR_RANGE, "gpu: image unit %d outside [0, %d)", unit,
                       tex->ctx->info.max_image_units);
    glBindImageTexture((GLuint)unit, tex->id, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
    return lu_gpu_check_gl("image bind", err);
}

#endif
