/* The froxel method's GPU passes (see froxel.h): the shared GPU scene, the
 * view march's frame buffers at LU_SCENE_BINDING_FREE + 0..4 (as raymarch
 * binds them) and the grid's buffers above them; one program runs the three
 * passes of lu_froxel.h, chosen by u_pass. The two lit volumes alternate
 * as this frame's and the previous one's (reprojection). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/common/gpu_method.h"
#include "methods/froxel/froxel.h"

enum { B_HITS, B_SPANS, B_VIEWS, B_TABLE, B_SHADOW, B_OUT, B_SURFVIS, B_CSPANS, B_LIT, B_HIST, B_INT, B_COUNT };

struct lu_froxel_gpu {
    lu_gpu_method m;                 /* slots B_* except the lit volumes */
    lu_gpu_buffer *lit[2];           /* lit volumes: lit[cur] is this frame's */
    int cur;
};

lu_result lu_froxel_gpu_create(const lu_scene *scene, lu_froxel_gpu **out, lu_error *err) {
    static const lu_gpu_method_program programs[] = {{"methods/froxel/froxel.comp", NULL}, {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_froxel_gpu), scene, programs, "froxel", &m, err);
    *out = (lu_froxel_gpu *)m;   /* NULL on failure */
    return r;
}

void lu_froxel_gpu_destroy(lu_froxel_gpu *g) {
    if (!g) return;
    for (int i = 0; i < 2; i++) lu_gpu_buffer_destroy(g->lit[i]);
    lu_gpu_method_destroy(&g->m);
}

static lu_result put(lu_froxel_gpu *g, int i, const void *data, size_t bytes, lu_error *err) {
    return lu_gpu_method_put(&g->m, i, data, bytes, err);
}

static lu_result put_kept(lu_froxel_gpu *g, int i, const void *data, size_t bytes, unsigned version, lu_error *err) {
    return lu_gpu_method_put_kept(&g->m, i, data, bytes, version, err);
}

/* The uniform struct `name` (lu_k_fx_grid) set from G. */
static void set_grid(lu_gpu_program *p, const char *name, const lu_k_fx_grid *G) {
    char key[64];
#define FX_KEY(field) (snprintf(key, sizeof key, "%s.%s", name, field), key)
    lu_gpu_uniform_vec3(p, FX_KEY("cam.right"), G->cam.right.x, G->cam.right.y, G->cam.right.z);
    lu_gpu_uniform_vec3(p, FX_KEY("cam.up"), G->cam.up.x, G->cam.up.y, G->cam.up.z);
    lu_gpu_uniform_vec3(p, FX_KEY("cam.forward"), G->cam.forward.x, G->cam.forward.y, G->cam.forward.z);
    lu_gpu_uniform_float(p, FX_KEY("cam.inv_width"), G->cam.inv_width);
    lu_gpu_uniform_float(p, FX_KEY("cam.inv_height"), G->cam.inv_height);
    lu_gpu_uniform_vec3(p, FX_KEY("origin"), G->origin.x, G->origin.y, G->origin.z);
    lu_gpu_uniform_float(p, FX_KEY("t_lo"), G->t_lo);
    lu_gpu_uniform_float(p, FX_KEY("n0"), G->n0);
    lu_gpu_uniform_float(p, FX_KEY("log_r"), G->log_r);
    lu_gpu_uniform_float(p, FX_KEY("u"), G->u);
    lu_gpu_uniform_int(p, FX_KEY("nx"), G->nx);
    lu_gpu_uniform_int(p, FX_KEY("ny"), G->ny);
    lu_gpu_uniform_int(p, FX_KEY("nz"), G->nz);
    lu_gpu_uniform_int(p, FX_KEY("width"), G->width);
    lu_gpu_uniform_int(p, FX_KEY("height"), G->height);
#undef FX_KEY
}

lu_result lu_froxel_gpu_render(lu_froxel_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                               const lu_view_march_frame *f, const lu_fx_frame *fx, const float *cspans, bool relight,
                               lu_image *out, lu_error *err) {
    const lu_k_fx_grid *G = &fx->grid;
    size_t pixels = (size_t)f->width * f->height;
    size_t texels = (size_t)f->map_res * f->map_res;
    size_t columns = (size_t)G->nx * G->ny, cells = columns * (size_t)G->nz;
    lu_result r = lu_gpu_scene_update(g->m.scene, scene, rec, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->m.scene, err);
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
    if (r == LU_OK)
        r = put_kept(g, B_SURFVIS, f->surface_vis, pixels * (size_t)f->light_count * sizeof(float), f->vis_version,
                     err);
    if (r == LU_OK) r = put_kept(g, B_CSPANS, cspans, columns * (1 + (size_t)f->medium_count * 2) * sizeof(float),
                                  fx->spans_version, err);
    if (r == LU_OK && relight) g->cur ^= 1;
    if (r == LU_OK)
        r = lu_gpu_buffer_put(g->m.ctx, &g->lit[g->cur], NULL, cells * LU_K_FX_CELL_FLOATS * sizeof(float),
                              g->m.binding0 + B_LIT, err);
    if (r == LU_OK)
        r = lu_gpu_buffer_put(g->m.ctx, &g->lit[g->cur ^ 1], NULL, cells * LU_K_FX_CELL_FLOATS * sizeof(float),
                              g->m.binding0 + B_HIST, err);
    if (r == LU_OK) r = put(g, B_INT, NULL, (cells + columns) * LU_K_FX_CELL_FLOATS * sizeof(float), err);
    if (r != LU_OK) return r;
    lu_gpu_program *p = g->m.prog[0];
    lu_gpu_uniform_int(p, "u_map_res", f->map_res);
    lu_gpu_uniform_float(p, "u_eps", f->eps);
    lu_gpu_uniform_float(p, "u_t_cut", f->t_cut);
    lu_gpu_uniform_vec4(p, "u_ms", (float)f->ms.octaves, f->ms.a, f->ms.b, f->ms.c);
    lu_gpu_uniform_vec3(p, "u_background", f->background.x, f->background.y, f->background.z);
    set_grid(p, "u_g", G);
    set_grid(p, "u_p", &fx->prev);
    lu_gpu_uniform_int(p, "u_history", fx->history);
    lu_gpu_uniform_float(p, "u_blend", fx->blend);
    lu_gpu_uniform_int(p, "u_cull", fx->cull);
    unsigned cx = (unsigned)(G->nx + 7) / 8, cy = (unsigned)(G->ny + 7) / 8;
    /* One cell (pass 0) runs one sample of the view march's in-scattering,
     * and one column (pass 1) nz slices: both far below llvmpipe's loop
     * budget per invocation (LU_RM_LOOP_BUDGET) for nz <= LU_K_FX_MAX_NZ. */
    if (relight) {
        lu_gpu_uniform_int(p, "u_pass", 0);
        r = lu_gpu_dispatch(p, cx, cy, (unsigned)G->nz, err);
        if (r == LU_OK) {
            lu_gpu_uniform_int(p, "u_pass", 1);
            r = lu_gpu_dispatch(p, cx, cy, 1, err);
        }
    }
    if (r == LU_OK) {
        lu_gpu_uniform_int(p, "u_pass", 2);
        r = lu_gpu_dispatch(p, (unsigned)(f->width + 7) / 8, (unsigned)(f->height + 7) / 8, 1, err);
    }
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[B_OUT], out->width, out->height, out->rgb, err);
    return r;
}
