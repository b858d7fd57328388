/* lucent/method.h — one interface for every rendering method.
 *
 * A method is a table: named parameters (with defaults and ranges), a
 * prepare step (one-time / per-scene-change work, timed separately), a
 * render step (per-frame work, reads camera and lights from the scene it is
 * given), and destroy. All methods render the same lu_scene.
 *
 *   lu_renderer *r;
 *   lu_renderer_desc desc = {.method = "reference", .set = (const char *[]){"reference.spp=4", NULL}};
 *   lu_renderer_make(&desc, &scene, &r, &err);
 *   lu_renderer_render(r, &scene, &image, &err);
 *   lu_renderer_stats st;
 *   lu_renderer_get_stats(r, &st, &err);
 *   lu_renderer_destroy(r);
 *
 * Settings are "method.param" keys (e.g. "reference.spp" = 4). Keys naming
 * another method are ignored; unknown methods or parameters are errors. */
#ifndef LUCENT_METHOD_H
#define LUCENT_METHOD_H

#include "core.h"
#include "image.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Where a renderer runs. LU_BACKEND_AUTO (0, so a zero-initialised choice
 * means it): the GPU when this machine has a hardware GPU (see
 * lu_backend_auto), otherwise the CPU; a method without a GPU path runs on
 * the CPU. A software rasteriser (Mesa llvmpipe) is never chosen
 * automatically: it runs the same kernels slower than the CPU path
 * (docs/gpu.md). LU_BACKEND_GPU forces the GPU backend, llvmpipe included. */
typedef enum lu_backend { LU_BACKEND_AUTO = 0, LU_BACKEND_CPU = 1, LU_BACKEND_GPU = 2 } lu_backend;
const char *lu_backend_name(lu_backend b);   /* "auto", "cpu", "gpu" */
/* What AUTO means on this machine, LU_BACKEND_GPU or LU_BACKEND_CPU, decided
 * once per process: the first call looks for a hardware EGL device (under
 * lu_host.gpu and gpu_device) and confirms it with an OpenGL 4.5 context
 * that it destroys again. why, when not NULL, receives a text that lives as
 * long as the process: the device found, or why there is none. Thread-safe. */
lu_backend lu_backend_auto(const char **why);

typedef enum lu_param_type { LU_PARAM_INT = 0, LU_PARAM_FLOAT, LU_PARAM_BOOL, LU_PARAM_CHOICE } lu_param_type;

typedef struct lu_param_desc {
    const char *name;
    lu_param_type type;
    double def, lo, hi;     /* CHOICE: def is the index into choices */
    const char *choices;    /* CHOICE: "dipole|multipole|burley" */
    const char *help;
} lu_param_desc;

#define LU_MAX_PARAMS 32

/* Progressive output: a method that refines its image over passes (e.g.
 * pathtrace, one sample per pixel per pass) calls fn with the current
 * estimate after every `every` passes, except the last (render returns it). */
typedef void (*lu_progressive_fn)(void *user, const lu_image *partial, int passes_done, int passes_total);
typedef struct lu_progressive {
    lu_progressive_fn fn;
    void *user;
    int every;
} lu_progressive;

/* What can change between two frames of one renderer (lu_renderer_invalidate,
 * and the frame stage's record of a frame). */
typedef enum lu_change {
    LU_CHANGE_CAMERA = 1u << 0,      /* position, look_at, up, fov, size */
    LU_CHANGE_LIGHTS = 1u << 1,      /* any light: count, type, position, direction, intensity, cone, map */
    LU_CHANGE_MEDIA = 1u << 2,       /* a medium's coefficients, phase, density values (grid generation) */
    LU_CHANGE_GEOMETRY = 1u << 3,    /* objects and their materials, boundary meshes, media transforms and boxes */
    LU_CHANGE_BACKGROUND = 1u << 4,
    LU_CHANGE_ALL = (1u << 5) - 1u
} lu_change;

/* One frame: its scene and what changed since the renderer's previous frame
 * (defined by the library's frame stage, src/methods/frame.h). */
typedef struct lu_frame lu_frame;

/* A named set of parameter values, chosen with the setting "method.preset"
 * (e.g. "afm.preset" = "paper": the seed paper's settings). It replaces the
 * defaults; explicit settings still override it. */
typedef struct lu_preset {
    const char *name;
    const char *values;     /* "steps=500 map_res=1024": parameters of this method */
    const char *help;
} lu_preset;

typedef struct lu_method {
    const char *name;
    const char *summary;
    unsigned backends;                  /* LU_BACKEND_CPU | LU_BACKEND_GPU */
    const lu_param_desc *params;
    int param_count;
    const lu_preset *presets;           /* NULL or preset_count entries */
    int preset_count;
    /* lu_change bits whose change makes the renderer prepare again (new
     * geometry always does): for methods that read those inputs only in
     * prepare instead of keeping products of them. */
    unsigned prepare_deps;
    /* params: resolved values in descriptor order (choices as indices). */
    lu_result (*prepare)(const lu_scene *scene, const double *params, lu_backend backend, void **state,
                         lu_error *err);
    /* out is created by the caller at the camera's size; frame->scene is the
     * scene to render, frame->changed what changed since the previous frame. */
    lu_result (*render)(void *state, const lu_frame *frame, lu_image *out, lu_error *err);
    void (*destroy)(void *state);
    /* Optional (NULL for one-shot methods): render with progressive output. */
    lu_result (*render_progressive)(void *state, const lu_frame *frame, lu_image *out, const lu_progressive *prog,
                                    lu_error *err);
} lu_method;

const lu_method *const *lu_methods(int *count);
/* The backend a renderer of m asked for b runs on: b itself when it is CPU or
 * GPU; AUTO: lu_backend_auto() when m has a GPU path, else the CPU. */
lu_backend lu_backend_resolve(lu_backend b, const lu_method *m);
const lu_method *lu_method_find(const char *name);

/* Resolves settings for method m into values[] (defaults, then the preset
 * "m.preset" names, then explicit overrides); checks ranges, integer-ness,
 * choice and preset names. */
lu_result lu_method_resolve_params(const lu_method *m, const lu_kvlist *settings, double *values, lu_error *err);
/* Validates every key of settings against the registry (method exists, param exists). */
lu_result lu_settings_validate(const lu_kvlist *settings, lu_error *err);

/* ---- the renderer ---------------------------------------------------------
 * An opaque handle: one method prepared for one scene, rendering frames of it
 * (docs/architecture.md §4). Its layout is the library's own, so it can grow
 * without breaking a program built against an older header. */
typedef struct lu_renderer lu_renderer;

/* What lu_renderer_make builds; zero-initialised is the default of every
 * field (lu_renderer_desc_resolve fills them in). */
typedef struct lu_renderer_desc {
    const char *method;            /* NULL: LU_DEFAULT_METHOD */
    lu_backend backend;            /* LU_BACKEND_AUTO: a hardware GPU, else the CPU */
    const lu_kvlist *settings;     /* NULL: none; "method.param" keys (core.h) */
    const char *const *set;        /* NULL, or "method.param=value" texts ending with NULL, after settings */
    lu_progressive progressive;    /* zero: off (lu_renderer_set_progressive) */
    /* true: a GPU renderer works in the OpenGL (4.5 or later) context that
     * is current on the calling thread at make, the caller's own (a window's,
     * an engine's), instead of lucent's headless device context, so that it
     * can render into the caller's textures (lu_renderer_render_texture).
     * That context must be current at every later call on the renderer
     * (else LU_ERR_BACKEND); lucent leaves the program and the buffer,
     * texture and image bindings it used changed. CPU renderers ignore it. */
    bool gl_caller_context;
} lu_renderer_desc;

#define LU_DEFAULT_METHOD "reference"

/* The descriptor with its defaults filled in: the method's name, and the
 * backend a renderer of it would run on (CPU or GPU, never AUTO). Fails like
 * lu_renderer_make for an unknown method or a backend the method lacks. */
lu_result lu_renderer_desc_resolve(const lu_renderer_desc *desc, lu_renderer_desc *out, lu_error *err);

/* Resolves desc, validates the settings, prepares the method for scene. */
lu_result lu_renderer_make(const lu_renderer_desc *desc, const lu_scene *scene, lu_renderer **out, lu_error *err);

/* What a renderer did, read at any time between calls. Times are wall
 * milliseconds of the latest call of each stage. */
typedef struct lu_renderer_stats {
    const char *method;            /* the method's name */
    lu_backend backend;            /* resolved: CPU or GPU */
    double prepare_ms;             /* the latest prepare: at make, or again for new geometry */
    double frame_update_ms;        /* the frame stage: comparing the latest frame with the one before, recording it */
    double render_ms;              /* the latest frame's method render */
    double frame_ms;               /* the latest lu_renderer_render in total: update, any prepare, render */
    uint64_t frames;               /* frames rendered since make */
    uint64_t prepares;             /* prepares since make, the first included */
    unsigned changed;              /* lu_change bits the latest frame saw */
    int products;                  /* cached products; names and rebuild counts: lu_renderer_products */
    double rows_ms;                /* the latest lu_renderer_render_rows: time in its bands of rows;
                                    * render_ms minus this is the frame's global stages */
    bool texture_direct;           /* the latest lu_renderer_render_texture wrote the texture on the GPU,
                                    * with no copy through the CPU */
    /* What the renderer holds now (peak_bytes: the most at once since make):
     * what its calls allocated, its worker threads' share included, and
     * have not freed. Not the images the caller passes to render (a frame
     * rendered into a texture is counted: the renderer keeps it), nor the
     * GPU device that every renderer shares. A renderer's figures summed
     * with the rest of the process make lu_memory_get. */
    lu_memory memory;
} lu_renderer_stats;

lu_result lu_renderer_get_stats(const lu_renderer *r, lu_renderer_stats *out, lu_error *err);
/* The method table and the resolved parameter values (descriptor order). */
lu_result lu_renderer_get_method(const lu_renderer *r, const lu_method **method, lu_error *err);
lu_result lu_renderer_get_params(const lu_renderer *r, double *values, int cap, int *count, lu_error *err);

/* The short form of lu_renderer_make: method, settings and backend only. */
lu_result lu_renderer_create(const char *method, const lu_scene *scene, const lu_kvlist *settings,
                             lu_backend backend, lu_renderer **out, lu_error *err);
/* Creates `out` at the camera size if it is empty (width 0), else requires that size. */
lu_result lu_renderer_render(lu_renderer *r, const lu_scene *scene, lu_image *out, lu_error *err);
/* Renders the frame into `texture`: a GL_TEXTURE_2D of the OpenGL context
 * current on the calling thread, of the camera's size, with internal format
 * GL_RGBA32F, GL_RGBA16F or GL_RGBA8. Linear radiance as lu_renderer_render
 * gives it, alpha 1, rows bottom to top as GL stores them (the image is
 * upright when texture y points up). A GPU renderer made with
 * gl_caller_context writes it on the GPU, with no copy through the CPU; a
 * CPU renderer renders into CPU memory and uploads. A GPU renderer in
 * lucent's own context fails with LU_ERR_UNSUPPORTED: its objects cannot be
 * shared with the caller's context. */
lu_result lu_renderer_render_texture(lu_renderer *r, const lu_scene *scene, unsigned texture, lu_error *err);
void lu_renderer_destroy(lu_renderer *r);

/* Part of an image, for dividing one frame among processes
 * (docs/distributed.md). A source of pixel rows: it stores the next band of
 * rows [*y0, *y1) and returns true, or returns false when there are no more.
 * Rows outside the image are clipped; an empty band is skipped. */
typedef bool (*lu_rows_fn)(void *user, int *y0, int *y1);
/* lu_renderer_render, except that the pixel stage renders only the bands
 * `next` hands out, asking for each on the calling thread after the one
 * before is done, until it returns false. The frame's global stages (maps,
 * sample sets, light passes: what every pixel reads) run whole, once per
 * call. Every row of a band holds the values lu_renderer_render would give
 * it, bit for bit; other rows are unspecified (a method that works by tiles
 * also fills the rest of the tiles a band meets). A progressive method
 * runs all its passes for each band and makes no progressive calls. CPU
 * backend only: a GPU renderer fails with LU_ERR_UNSUPPORTED. */
lu_result lu_renderer_render_rows(lu_renderer *r, const lu_scene *scene, lu_rows_fn next, void *user, lu_image *out,
                                  lu_error *err);
/* Asks for the current image every `every` passes during lu_renderer_render
 * (fn NULL or every <= 0: off). Returns false if the method renders in one
 * shot (it then ignores the request). */
bool lu_renderer_set_progressive(lu_renderer *r, lu_progressive_fn fn, void *user, int every);

/* Change tracking needs no calls: each render compares its scene with the
 * previous frame's and rebuilds only what depends on a change. Invalidate
 * declares a change it cannot see (lu_change bits), e.g. grid values written
 * through grid.data instead of lu_grid_set_values, or mesh vertices moved in
 * place. */
void lu_renderer_invalidate(lu_renderer *r, unsigned what);
/* How often the named cached product (e.g. "afm.maps", "media_rays.camera")
 * was built since create; 0 for a product this method does not have. */
uint64_t lu_renderer_rebuilds(const lu_renderer *r, const char *product);
/* The products' names and counts, up to max of them; returns how many exist. */
int lu_renderer_products(const lu_renderer *r, const char **names, uint64_t *counts, int max);

#ifdef __cplusplus
}
#endif
#endif
