/* Internal: the frame stage (docs/architecture.md §4). The renderer wrapper
 * compares the scene of each frame with the one it rendered last and hands
 * the method an lu_frame saying what changed; each cached product names the
 * inputs it depends on (lu_change bits) and is rebuilt only when one of them
 * changed. Every product is a pure function of the inputs it declares, so a
 * frame built from kept products equals a fresh renderer's frame bit for bit
 * (tests/test_frame.c). */
#ifndef LU_METHODS_FRAME_H
#define LU_METHODS_FRAME_H

#include <lucent/lucent.h>

#include "kernels/lu_camera.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"

#define LU_FRAME_MAX_PRODUCTS 24

/* A scene's kernel records (camera, media, lights), built once per frame by
 * the stage and read by every method and by the GPU scene upload. */
typedef struct lu_frame_records {
    lu_k_camera cam;
    lu_k_medium *media;              /* scene->medium_count */
    int medium_count, medium_cap;
    lu_k_light *lights;              /* lu_scene_kernel_lights: scene order, environment lights left out */
    int light_count, light_cap;
    lu_k_light *scene_lights;        /* every light in scene order, environments included (scene->light_count) */
} lu_frame_records;

/* Rebuilds *rec from scene (zero-initialised the first time). */
lu_result lu_frame_records_update(lu_frame_records *rec, const lu_scene *scene, lu_error *err);
void lu_frame_records_free(lu_frame_records *rec);

typedef struct lu_frame_stats {
    int count;
    struct {
        const char *name;            /* a string literal, "afm.maps" */
        uint64_t rebuilds;
    } product[LU_FRAME_MAX_PRODUCTS];
} lu_frame_stats;

struct lu_frame {
    const lu_scene *scene;
    unsigned changed;                /* lu_change bits since the previous frame; all of them on the first */
    uint64_t lights_changed;         /* bit l (l < 63): light l differs; bit 63: one of lights 63.. does;
                                      * all bits when the light count changed */
    lu_frame_stats *stats;
    const lu_frame_records *rec;     /* this frame's records */
    /* The pixel rows to render (lu_renderer_render_rows): NULL, every row. */
    lu_rows_fn rows;
    void *rows_user;
    double *rows_seconds;            /* where lu_frame_for_rows adds the time its bands took */
};

/* True when a product built before (valid) must be rebuilt for this frame. */
static inline bool lu_frame_stale(const lu_frame *f, bool valid, unsigned deps) {
    return !valid || (f->changed & deps) != 0;
}
/* True when light l (scene order) changed, or when the lights were added or removed. */
static inline bool lu_frame_light_changed(const lu_frame *f, int l) {
    return (f->changed & LU_CHANGE_LIGHTS) && ((f->lights_changed >> (l < 63 ? l : 63)) & 1u);
}
/* lights_changed re-indexed to kernel lights (lu_scene_kernel_lights: scene
 * order without environment lights). */
uint64_t lu_frame_kernel_lights_changed(const lu_frame *f);
/* Counts one rebuild of the named product (read back by lu_renderer_rebuilds). */
void lu_frame_rebuilt(const lu_frame *f, const char *product);

/* A method's pixel stage: fn over image rows [begin, end) of the camera's
 * height in parallel, or only over the bands of rows f->rows hands out
 * (asked for on the calling thread between bands). A row's pixels must not
 * depend on which other rows render (docs/distributed.md). progress_label
 * as lu_parallel_for's, for the whole image only. */
void lu_frame_for_rows(const lu_frame *f, int64_t grain, lu_range_fn fn, void *ctx, const char *progress_label);
/* The same for a stage that works by square tiles of `tile` pixels, tiles_x
 * to a row of tiles, indexed ty * tiles_x + tx: fn over every tile that
 * meets a band of rows (so rows next to a band may be rendered too). */
void lu_frame_for_tiles(const lu_frame *f, int tile, int tiles_x, int tiles_y, lu_range_fn fn, void *ctx);

/* ---- the wrapper's side ---- */

typedef struct lu_frame_stage lu_frame_stage;

lu_result lu_frame_stage_create(lu_frame_stage **out, lu_error *err);
void lu_frame_stage_destroy(lu_frame_stage *s);
/* Compares scene with the last frame that rendered, builds its records and fills *f. */
lu_result lu_frame_stage_begin(lu_frame_stage *s, const lu_scene *scene, lu_frame *f, lu_error *err);
/* After the method rendered: ok keeps scene as the new "last frame"; a
 * failed frame makes the next one rebuild everything. */
lu_result lu_frame_stage_end(lu_frame_stage *s, const lu_scene *scene, bool ok, lu_error *err);
void lu_frame_stage_invalidate(lu_frame_stage *s, unsigned what);
const lu_frame_stats *lu_frame_stage_stats(const lu_frame_stage *s);

#endif
