/* The raymarch method's GPU pass (see raymarch.h): the shared GPU scene plus
 * this frame's buffers at LU_SCENE_BINDING_FREE and above. */
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/common/gpu_scene.h"
#include "methods/raymarch/raymarch.h"

enum { B_HITS, B_SPANS, B_VIEWS, B_TABLE, B_SHADOW, B_OUT, B_STATE, B_SURFVIS, B_COUNT };

struct lu_raymarch_gpu {
    lu_gpu_context *ctx;
    lu_gpu_program *prog;
    lu_gpu_scene *scene;
    lu_gpu_buffer *buf[B_COUNT];
    lu_gpu_upload up[B_COUNT];      /* what each slot holds (versions of the CPU products) */
};

lu_result lu_raymarch_gpu_create(const lu_scene *scene, lu_raymarch_gpu **out, lu_error *err) {
    *out = NULL;
    lu_raymarch_gpu *g = lu_calloc(1, sizeof *g);
    if (!g) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    lu_result r = lu_gpu_context_create(&g->ctx, LU_GPU_AUTO, err);
    if (r == LU_OK) r = lu_gpu_program_create(g->ctx, "methods/raymarch/raymarch.comp", lu_gpu_scene_defines(scene), &g->prog, err);
    if (r == LU_OK) r = lu_gpu_scene_create(g->ctx, scene, &g->scene, err);
    if (r != LU_OK) {
        lu_raymarch_gpu_destroy(g);
        return r;
    }
    *out = g;
    return LU_OK;
}

void lu_raymarch_gpu_destroy(lu_raymarch_gpu *g) {
    if (!g) return;
    for (int i = 0; i < B_COUNT; i++) lu_gpu_buffer_destroy(g->buf[i]);
    lu_gpu_scene_destroy(g->scene);
    lu_gpu_program_destroy(g->prog);
    lu_gpu_context_destroy(g->ctx);
    lu_free(g);
}

/* Uploads into slot i (growing it when needed) and binds it above the scene's bindings. */
static lu_result put(lu_raymarch_gpu *g, int i, const void *data, size_t bytes, lu_error *err) {
    return lu_gpu_buffer_put(g->ctx, &g->buf[i], data, bytes, LU_SCENE_BINDING_FREE + i, err);
}

/* put, skipped when slot i holds this version of its CPU product. */
static lu_result put_kept(lu_raymarch_gpu *g, int i, const void *data, size_t bytes, unsigned version, lu_error *err) {
    return lu_gpu_buffer_put_versioned(g->ctx, &g->buf[i], &g->up[i], data, bytes, version, LU_SCENE_BINDING_FREE + i,
                                       err);
}

lu_result lu_raymarch_gpu_render(lu_raymarch_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                                 const lu_view_march_frame *f, lu_image *out, lu_error *err) {
    size_t pixels = (size_t)f->width * f->height;
    size_t texels = (size_t)f->map_res * f->map_res;
    lu_result r = lu_gpu_scene_update(g->scene, scene, rec, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->scene, err);
    /* Each CPU input crosses the bus only in the frame its product was
     * rebuilt (media_ray.h: camera rays, shadow views and maps, surface
     * visibility). */
    if (r == LU_OK) r = put_kept(g, B_HITS, f->hits, pixels * 16 * sizeof(float), f->hits_version, err);
    if (r == LU_OK)
        r = put_kept(g, B_SPANS, f->spans, pixels * (size_t)f->medium_count * 2 * sizeof(float), f->hits_version, err);
    if (r == LU_OK)
        r = put_kept(g, B_VIEWS, f->views, (size_t)f->view_count * LU_RM_VIEW_FLOATS * sizeof(float), f->maps_version,
                     err);
    if (r == LU_OK)
        r = put_kept(g, B_TABLE, f->view_table, (size_t)f->light_count * 2 * sizeof(int), f->maps_version, err);
    if (r == LU_OK)
        r = put_kept(g, B_SHADOW, f->shadow, (size_t)f->view_count * texels * sizeof(float), f->maps_version, err);
    if (r == LU_OK) r = put(g, B_OUT, NULL, pixels * 3 * sizeof(float), err);
    if (r == LU_OK) r = put(g, B_STATE, NULL, pixels * 8 * sizeof(float), err);
    if (r == LU_OK)
        r = put_kept(g, B_SURFVIS, f->surface_vis, pixels * (size_t)f->light_count * sizeof(float), f->vis_version,
                     err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->prog, "u_map_res", f->map_res);
    lu_gpu_uniform_float(g->prog, "u_step", f->step);
    lu_gpu_uniform_float(g->prog, "u_eps", f->eps);
    lu_gpu_uniform_int(g->prog, "u_jitter", f->jitter);
    lu_gpu_uniform_float(g->prog, "u_t_cut", f->t_cut);
    lu_gpu_uniform_vec3(g->prog, "u_background", f->background.x, f->background.y, f->background.z);
    /* Steps per dispatch: an upper bound of the loop iterations one step runs
     * (llvmpipe counts each pass through a loop body plus one per loop
     * entered): the step itself, the media loop, the block look-up (a media
     * loop with a 3-axis loop each), the light loop, and per light the 2x2
     * PCF taps, two more media loops, a 3-axis box clip per medium and each
     * shadow ray's block and cell walks. Kept under llvmpipe's 65535
     * iterations per invocation (lu_k_rm_segment) with one step's worth left
     * for the finishing surface term (tests/test_gpu.c measures the cap). */
    long nm = f->medium_count;
    long per_step = 4 + 6 * nm;
    for (int l = 0; l < f->light_count; l++) {
        per_step += 12 + 6 * nm;
        for (int m = 0; m < scene->medium_count; m++) per_step += lu_view_march_shadow_iterations(&rec->media[m]);
    }
    int seg = (int)(LU_RM_LOOP_BUDGET / per_step) - 1;
    if (seg < 1) seg = 1;
    int total = f->max_steps + 1;
    unsigned gx = (unsigned)(f->width + 7) / 8, gy = (unsigned)(f->height + 7) / 8;
    for (int i0 = 0; r == LU_OK; i0 += seg) {
        int last = i0 + seg >= total;
        lu_gpu_uniform_int(g->prog, "u_seg_begin", i0);
        lu_gpu_uniform_int(g->prog, "u_seg_end", last ? 1 << 30 : i0 + seg);
        lu_gpu_uniform_int(g->prog, "u_finish", last);
        r = lu_gpu_dispatch(g->prog, gx, gy, 1, err);
        if (last) break;
    }
    if (r == LU_OK) r = lu_gpu_output(g->buf[B_OUT], out->width, out->height, out->rgb, err);
    return r;
}
