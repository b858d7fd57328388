/* backends/gpu.h — internal GPU backend: headless OpenGL 4.5 compute through
 * EGL, shaders assembled from sources embedded in the binary at build time.
 *
 * Threading: a context is made current on the thread that creates it and every
 * call taking a context (or an object made from it) must come from that thread.
 * Several contexts may live on one thread; each call makes its own current.
 * Objects must be destroyed before the context they were made from. EGL
 * displays stay initialised for the life of the process (shared by all
 * contexts; see context.c for why they are never terminated).
 *
 * Built without EGL/epoxy (pkg-config), every call that needs GL fails with
 * LU_ERR_BACKEND "built without GPU support"; the source assembly functions
 * (pure C) work in both builds. */
#ifndef LU_BACKENDS_GPU_H
#define LU_BACKENDS_GPU_H

#include <lucent/core.h>

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* ---- embedded sources ----------------------------------------------------
 * Every kernel file (lu_*.h, *.glsl, *.comp) of src/kernels/ and of the
 * method rooms under src/methods/, named by its path relative to src/
 * ("kernels/lu_kernel.h", "methods/afm/afm_build.comp"), generated into the
 * build directory by cmake/embed_sources.cmake. */
typedef struct lu_gpu_source {
    const char *name;
    const char *text;      /* NUL-terminated */
} lu_gpu_source;

extern const lu_gpu_source lu_gpu_embedded_sources[];
extern const int lu_gpu_embedded_source_count;

/* Text of an embedded source by exact name, or NULL. */
const char *lu_gpu_source_find(const char *name);

/* True when the library was built with the GPU backend (EGL + epoxy found). */
bool lu_gpu_compiled_in(void);

/* ---- shader assembly (pure C, no GL) --------------------------------------
 * Output: "#version 450 core\n#define LU_GLSL 1\n" + defines, then the main
 * source with every `#include "x"` replaced by the text of x, recursively.
 * x is looked up relative to the including file's folder, then relative to
 * src/ (as C does with -Isrc); `overlay` entries are searched before the
 * embedded table (tests use it for in-memory sources). Each file is included
 * at most once (include guards become redundant but harmless); `#include <x>`
 * lines (C-only system headers) and `#version` lines become blank lines.
 * Every file N (names[N] in the returned map; N = 0 is the "<preamble>":
 * version and defines) starts with `#line N*S+1 N` and its includer resumes
 * with `#line N*S+L+1 N`, S = LU_GPU_LINE_STRIDE: the source-string number
 * names the file for drivers that keep it, and the line number names it too
 * because Mesa reports source string 0 for every error found after parsing
 * (its YYLLOC_DEFAULT resets the source). Files are limited to S-1 lines. */
#define LU_GPU_LINE_STRIDE 100000
typedef struct lu_gpu_source_map {
    int count;
    char names[64][128];
} lu_gpu_source_map;

lu_result lu_gpu_assemble(const char *main_name, const char *defines, const lu_gpu_source *overlay,
                          int overlay_count, char **out_text, lu_gpu_source_map *map, lu_error *err);

/* Rewrites a driver info log so source-string numbers become file names:
 * Mesa "N:L(C): error: m" -> "file:L:C: error: m", "ERROR: N:L: m" (glslang
 * style) -> "ERROR: file:L: m", NVIDIA "N(L) : error C0000: m" -> "file:L: error
 * C0000: m"; a line number >= LU_GPU_LINE_STRIDE is decoded into file and
 * line. Lines in no known form are copied unchanged. Always
 * NUL-terminates out (truncating). */
void lu_gpu_translate_log(const char *log, const lu_gpu_source_map *map, char *out, size_t out_size);

/* ---- context --------------------------------------------------------------- */

typedef enum lu_gpu_device_pref {
    LU_GPU_AUTO = 0,   /* hardware EGL devices first, then software, then surfaceless */
    LU_GPU_HARDWARE,   /* only a context whose renderer is not a software rasteriser */
    LU_GPU_SOFTWARE,   /* only a software rasteriser (Mesa llvmpipe) */
} lu_gpu_device_pref;

typedef struct lu_gpu_context lu_gpu_context;

typedef struct lu_gpu_info {
    char vendor[128], renderer[256], version[128], glsl_version[64];
    bool is_software;
    bool loop_cap;            /* Mesa llvmpipe: every loop of a shader invocation stops after 65535
                               * iterations in total, silently (tests/test_gpu.c, test_loop_budget) */
    char egl_path[16];        /* "device" (EGL_EXT_platform_device) or "surfaceless" */
    char device[256];         /* the chosen device, e.g. "EGL device 0 (software: EGL_MESA_device_software)" */
    char device_list[512];    /* every enumerated EGL device, "; "-separated */
    int max_3d_texture_size;
    int64_t max_ssbo_size;    /* GL_MAX_SHADER_STORAGE_BLOCK_SIZE, bytes */
    int max_ssbo_bindings;
    int max_work_group_count[3];
    int max_work_group_size[3];
    int max_work_group_invocations;
    int max_shared_memory;    /* GL_MAX_COMPUTE_SHARED_MEMORY_SIZE, bytes */
    int max_image_units;
    int max_texture_units;    /* GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS */
    double create_seconds;    /* wall time of lu_gpu_context_create */
} lu_gpu_info;

/* The process's GPU device for a preference: an OpenGL 4.5 core context (no
 * surface), made by the first create and shared by later ones (reference
 * counted; destroy releases one reference). Calls make it current on the
 * calling thread as they need it. The error names every candidate tried and
 * why it failed. */
lu_result lu_gpu_context_create(lu_gpu_context **out, lu_gpu_device_pref pref, lu_error *err);
void lu_gpu_context_destroy(lu_gpu_context *ctx);
/* Fault injection, for tests (docs/reliability.md, "Faults"): llvmpipe
 * neither fails to create a context nor loses one. CREATE: every context
 * creation fails from now on. LOSE: the `after`-th GL check from now (1: the
 * next) finds the current device lost, as glGetGraphicsResetStatus reports a
 * reset; a lost device fails every later call and is not handed to new
 * renderers (they get a fresh one). NONE clears the fault. */
typedef enum lu_gpu_fault { LU_GPU_FAULT_NONE = 0, LU_GPU_FAULT_CREATE, LU_GPU_FAULT_LOSE } lu_gpu_fault;
void lu_gpu_fault_inject(lu_gpu_fault fault, int after);
/* Serialised access to the shared devices: a GL context is current on one
 * thread at a time, so the renderer wrapper runs every GPU renderer's
 * prepare, render and destroy between enter and leave (recursive). Leave
 * releases lucent's context from the thread, so that another thread can
 * take it next; a caller's own context (a viewer's window) is theirs to make
 * current again. */
void lu_gpu_serial_enter(void);
void lu_gpu_serial_leave(void);
/* True when a hardware GPU can serve the GPU backend under lu_host.gpu and
 * gpu_device (the CLI's LUCENT_GPU, LUCENT_GPU_DEVICE): a non-software EGL
 * device that gives an OpenGL 4.5 core context. The context is made and
 * destroyed again, and the caller's current EGL context is restored. Where EGL enumerates its devices and none is
 * hardware, no driver is loaded. why receives the device found, or why there
 * is none (LUCENT_GPU=software counts as none). */
bool lu_gpu_hardware_probe(char *why, size_t why_size);
void lu_gpu_info_get(const lu_gpu_context *ctx, lu_gpu_info *out);
/* True when ctx is the calling thread's current context. */
bool lu_gpu_context_is_current(const lu_gpu_context *ctx);
/* Makes ctx current on the calling thread (every call below does this itself). */
lu_result lu_gpu_make_current(lu_gpu_context *ctx, lu_error *err);
/* glFinish: waits for all submitted work. */
void lu_gpu_finish(lu_gpu_context *ctx);
/* A timed section: t0 = lu_gpu_time_begin(ctx); ...; s = lu_gpu_time_end(ctx, t0).
 * Both call glFinish so the wall clock brackets the GPU work (GL timer queries
 * read 0 on llvmpipe). */
double lu_gpu_time_begin(lu_gpu_context *ctx);
double lu_gpu_time_end(lu_gpu_context *ctx, double t0);

/* ---- the caller's own context and textures ---------------------------------
 * An embedding program (an engine, the viewer's window) may have lucent's GPU
 * methods work in its own OpenGL 4.5 context, current on its thread, so that
 * frames land in its textures with no copy through the CPU: lucent's
 * headless EGL device context cannot share objects with a GLX or window
 * context. The renderer wrapper does this (lu_renderer_desc.gl_caller_context):
 *   - lu_gpu_caller_context_create wraps the context current on this thread
 *     (EGL or GLX; GL 4.5 or later). lucent never makes it current, never
 *     releases it, and fails a call made while it is not current;
 *   - lu_gpu_caller_use(ctx) makes every lu_gpu_context_create on this
 *     thread hand out ctx (another reference) until lu_gpu_caller_use(NULL);
 *   - lu_gpu_output_target(texture) names the caller's texture the frame
 *     being rendered on this thread goes to; the methods end their frame
 *     with lu_gpu_output, which writes it there (or, without a target,
 *     downloads into CPU memory as before). */
lu_result lu_gpu_caller_context_create(lu_gpu_context **out, lu_error *err);
void lu_gpu_caller_use(lu_gpu_context *ctx);
void lu_gpu_output_target(unsigned texture);
/* True once lu_gpu_output wrote the current target (cleared by lu_gpu_output_target). */
bool lu_gpu_output_written(void);
typedef struct lu_gpu_buffer lu_gpu_buffer;
/* A frame's image, width*height RGB floats in `rgb` (rows top to bottom):
 * into the target texture when one is set and rgb's context is the
 * caller's, else downloaded into `out` (width*height*3 floats). */
lu_result lu_gpu_output(lu_gpu_buffer *rgb, int width, int height, float *out, lu_error *err);
/* Uploads width*height RGB floats (rows top to bottom) into `texture` of the
 * context current on this thread, the caller's, as lu_gpu_output writes it:
 * for frames rendered in CPU memory. */
lu_result lu_gpu_texture_put_rgb(unsigned texture, const float *rgb, int width, int height, lu_error *err);

/* ---- programs ------------------------------------------------------------- */

typedef struct lu_gpu_program lu_gpu_program;

/* Compiles and links a compute program from an embedded source: comp_name is
 * its path under src/, e.g. "methods/afm/afm_build.comp". `defines` is
 * extra "#define X 1\n" lines or NULL. Compile errors name the original file
 * and line (see lu_gpu_translate_log). */
lu_result lu_gpu_program_create(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                lu_gpu_program **out, lu_error *err);
/* Same, with in-memory sources searched before the embedded table. */
lu_result lu_gpu_program_create_ex(lu_gpu_context *ctx, const char *comp_name, const char *defines,
                                   const lu_gpu_source *overlay, int overlay_count,
                                   lu_gpu_program **out, lu_error *err);
void lu_gpu_program_destroy(lu_gpu_program *prog);
unsigned lu_gpu_program_gl_name(const lu_gpu_program *prog);
/* The local size declared by the shader (glGetProgramiv GL_COMPUTE_WORK_GROUP_SIZE). */
void lu_gpu_program_local_size(const lu_gpu_program *prog, int size[3]);
/* Uniform setters by name; a name the linker removed (or never existed) is a
 * no-op, as in GL, so kernels may drop unused inputs under some #defines. */
void lu_gpu_uniform_int(lu_gpu_program *prog, const char *name, int v);
void lu_gpu_uniform_uint(lu_gpu_program *prog, const char *name, unsigned v);
void lu_gpu_uniform_float(lu_gpu_program *prog, const char *name, float v);
void lu_gpu_uniform_vec3(lu_gpu_program *prog, const char *name, float x, float y, float z);
void lu_gpu_uniform_vec4(lu_gpu_program *prog, const char *name, float x, float y, float z, float w);
/* glDispatchCompute(gx, gy, gz) then a full memory barrier, so downloads and
 * later dispatches see the writes. Checks counts against the device limits. */
lu_result lu_gpu_dispatch(lu_gpu_program *prog, unsigned gx, unsigned gy, unsigned gz, lu_error *err);

/* ---- shader storage buffers ------------------------------------------------ */

/* bytes > 0; data may be NULL (the buffer is then zero-filled). */
lu_result lu_gpu_buffer_create(lu_gpu_context *ctx, size_t bytes, const void *data, lu_gpu_buffer **out,
                               lu_error *err);
void lu_gpu_buffer_destroy(lu_gpu_buffer *buf);
size_t lu_gpu_buffer_size(const lu_gpu_buffer *buf);
lu_result lu_gpu_buffer_upload(lu_gpu_buffer *buf, size_t offset, const void *data, size_t bytes, lu_error *err);
lu_result lu_gpu_buffer_download(lu_gpu_buffer *buf, size_t offset, void *data, size_t bytes, lu_error *err);
/* layout(std430, binding = b) buffer ... */
lu_result lu_gpu_buffer_bind(lu_gpu_buffer *buf, int binding, lu_error *err);
/* A method's per-frame buffer in one call: (re)creates *slot when it is
 * missing or smaller than `bytes` (bytes 0 counts as 16), uploads `data`
 * unless it is NULL (then the contents are kept, or zero when just made),
 * and binds it at `binding`. */
lu_result lu_gpu_buffer_put(lu_gpu_context *ctx, lu_gpu_buffer **slot, const void *data, size_t bytes, int binding,
                            lu_error *err);
/* What a slot of lu_gpu_buffer_put_versioned holds: `bytes` bytes of the
 * version `version` of its CPU product (valid: an upload succeeded). */
typedef struct lu_gpu_upload {
    unsigned version;
    size_t bytes;
    bool valid;
} lu_gpu_upload;
/* lu_gpu_buffer_put of a CPU product that carries a version (a counter its
 * builder bumps on every rebuild): uploads only when *up says the slot holds
 * another version or size, so a kept product crosses the bus once. */
lu_result lu_gpu_buffer_put_versioned(lu_gpu_context *ctx, lu_gpu_buffer **slot, lu_gpu_upload *up, const void *data,
                                      size_t bytes, unsigned version, int binding, lu_error *err);

/* ---- textures and images ----------------------------------------------------
 * Density grids: GL_R32F 3D textures with GL_LINEAR filtering and
 * GL_CLAMP_TO_BORDER (border 0), which is exactly lu_grid_sample's convention
 * (voxel centre i at texture coordinate (i + 0.5) / n, zero outside [0, n-1],
 * support [-1, n]); kernels/lu_grid_sample.glsl does the mapping.
 * Outputs: GL_RGBA32F 2D images, zero-filled at creation. */

typedef struct lu_gpu_texture lu_gpu_texture;

/* data: nx*ny*nz floats, x fastest (lu_grid layout). */
lu_result lu_gpu_texture3d_create(lu_gpu_context *ctx, int nx, int ny, int nz, const float *data,
                                  lu_gpu_texture **out, lu_error *err);
lu_result lu_gpu_texture3d_upload(lu_gpu_texture *tex, const float *data, lu_error *err);
lu_result lu_gpu_image2d_create(lu_gpu_context *ctx, int width, int height, lu_gpu_texture **out,
                                lu_error *err);
/* rgba: width*height*4 floats, rows bottom to top as GL stores them (row 0 is y = 0). */
lu_result lu_gpu_image2d_download(lu_gpu_texture *tex, float *rgba, lu_error *err);
void lu_gpu_texture_destroy(lu_gpu_texture *tex);
/* A sampler (sampler3D) on texture unit `unit`. */
lu_result lu_gpu_texture_bind(lu_gpu_texture *tex, int unit, lu_error *err);
/* An image (layout(rgba32f, binding = unit) image2D), read-write. */
lu_result lu_gpu_image_bind(lu_gpu_texture *tex, int unit, lu_error *err);

#endif
