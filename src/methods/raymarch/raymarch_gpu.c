/* The raymarch method's GPU pass (see raymarch.h): the shared GPU scene plus
 * this frame's buffers at LU_SCENE_BINDING_FREE and above. */
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/common/gpu_method.h"
#include "methods/raymarch/raymarch.h"

enum { B_HITS, B_SPANS, B_VIEWS, B_TABLE, B_SHADOW, B_OUT, B_STATE, B_SURFVIS, B_COUNT };

struct lu_raymarch_gpu {
    lu_gpu_method m;                /* slots B_* */
};

lu_result lu_raymarch_gpu_create(const lu_scene *scene, lu_raymarch_gpu **out, lu_error *err) {
    static const lu_gpu_method_program programs[] = {{"methods/raymarch/raymarch.comp", NULL}, {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_raymarch_gpu), scene, programs, "raymarch", &m, err);
    *out = (lu_raymarch_gpu *)m;   /* NULL on failure */
    return r;
}

void lu_raymarch_gpu_destroy(lu_raymarch_gpu *g) {
    if (g) lu_gpu_method_destroy(&g->m);
}

lu_result lu_raymarch_gpu_render(lu_raymarch_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                                 const lu_view_march_frame *f, lu_image *out, lu_error *err) {
    size_t pixels = (size_t)f->width * f->height;
    size_t texels = (size_t)f->map_res * f->map_res;
    lu_result r = lu_gpu_scene_update(g->m.scene, scene, rec, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->m.scene, err);
    /* Each CPU input crosses the bus only in the frame its product was
     * rebuilt (media_ray.h: camera rays, shadow views and maps, surface
     * visibility). */
    if (r == LU_OK) r = lu_gpu_method_put_kept(&g->m, B_HITS, f->hits, pixels * 16 * sizeof(float), f->hits_version, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, B_SPANS, f->spans, pixels * (size_t)f->medium_count * 2 * sizeof(float), f->hits_version, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, B_VIEWS, f->views, (size_t)f->view_count * LU_RM_VIEW_FLOATS * sizeof(float), f->maps_version,
                     err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, B_TABLE, f->view_table, (size_t)f->light_count * 2 * sizeof(int), f->maps_version, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, B_SHADOW, f->shadow, (size_t)f->view_count * texels * sizeof(float), f->maps_version, err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_OUT, NULL, pixels * 3 * sizeof(float), err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_STATE, NULL, pixels * 8 * sizeof(float), err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, B_SURFVIS, f->surface_vis, pixels * (size_t)f->light_count * sizeof(float), f->vis_version,
                     err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->m.prog[0], "u_map_res", f->map_res);
    lu_gpu_uniform_float(g->m.prog[0], "u_step", f->step);
    lu_gpu_uniform_float(g->m.prog[0], "u_eps", f->eps);
    lu_gpu_uniform_int(g->m.prog[0], "u_jitter", f->jitter);
    lu_gpu_uniform_float(g->m.prog[0], "u_t_cut", f->t_cut);
    lu_gpu_uniform_vec4(g->m.prog[0], "u_ms", (float)f->ms.octaves, f->ms.a, f->ms.b, f->ms.c);
    lu_gpu_uniform_vec3(g->m.prog[0], "u_background", f->background.x, f->background.y, f->background.z);
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
        per_step += 12 + 6 * nm + (long)(f->ms.octaves + 1) * nm; /* + the octave loop per medium */
        for (int m = 0; m < scene->medium_count; m++) per_step += lu_view_march_shadow_iterations(&rec->media[m]);
    }
    int seg = (int)(LU_RM_LOOP_BUDGET / per_step) - 1;
    if (seg < 1) seg = 1;
    int total = f->max_steps + 1;
    unsigned gx = (unsigned)(f->width + 7) / 8, gy = (unsigned)(f->height + 7) / 8;
    for (int i0 = 0; r == LU_OK; i0 += seg) {
        int last = i0 + seg >= total;
        lu_gpu_uniform_int(g->m.prog[0], "u_seg_begin", i0);
        lu_gpu_uniform_int(g->m.prog[0], "u_seg_end", last ? 1 << 30 : i0 + seg);
        lu_gpu_uniform_int(g->m.prog[0], "u_finish", last);
        r = lu_gpu_dispatch(g->m.prog[0], gx, gy, 1, err);
        if (last) break;
    }
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[B_OUT], out->width, out->height, out->rgb, err);
    return r;
}
