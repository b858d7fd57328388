/* The ddod method's GPU passes (see ddod.h): the shared GPU scene plus this
 * method's buffers at LU_SCENE_BINDING_FREE and above; samples and SH are
 * uploaded once per sample set, the traced table when the camera or a
 * light moves, the pixel records and tile lists when ddod.c rebuilt them
 * (their versions in lu_ddod_frame). */
#include <stdio.h>
#include <stdlib.h>

#include "backends/gpu.h"
#include "methods/ddod/ddod.h"
#include "methods/common/gpu_method.h"

enum { B_SAMPLES, B_SH, B_RADIANCE, B_PIXELS, B_TILE_START, B_TILE_LIST, B_ENV, B_OUT, B_TRACED, B_COUNT };

struct lu_ddod_gpu {
    lu_gpu_method m;           /* programs: pass 1, pass 2; slots B_* */
    unsigned set_version, traced_version, pixels_version, bins_version;
    bool set_uploaded, traced_uploaded, pixels_uploaded, bins_uploaded;
    bool loop_cap;             /* llvmpipe: loop-iteration cap applies (lu_gpu_info) */
};

lu_result lu_ddod_gpu_create(const lu_scene *scene, lu_ddod_gpu **out, lu_error *err) {
    *out = NULL;
    static const lu_gpu_method_program programs[] = {{"methods/ddod/ddod.comp", "#define LU_DDOD_PASS 1\n"},
                                                     {"methods/ddod/ddod.comp", "#define LU_DDOD_PASS 2\n"},
                                                     {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_ddod_gpu), scene, programs, "ddod", &m, err);
    if (r != LU_OK) return r;
    lu_ddod_gpu *g = (lu_ddod_gpu *)m;
    lu_gpu_info info;
    lu_gpu_info_get(g->m.ctx, &info);
    g->loop_cap = info.loop_cap;
    *out = g;
    return LU_OK;
}

void lu_ddod_gpu_destroy(lu_ddod_gpu *g) {
    if (!g) return;
    lu_gpu_method_destroy(&g->m);
}

static void set_uniforms(lu_gpu_program *p, const lu_ddod_frame *f) {
    lu_gpu_uniform_int(p, "u_bands", f->P.bands);
    lu_gpu_uniform_int(p, "u_channels", f->P.channels);
    lu_gpu_uniform_int(p, "u_stride", f->P.stride);
    lu_gpu_uniform_int(p, "u_normalize", f->P.normalize);
    lu_gpu_uniform_int(p, "u_tile", f->P.tile);
    lu_gpu_uniform_int(p, "u_tiles_x", f->P.tiles_x);
    lu_gpu_uniform_int(p, "u_env", f->P.env);
    lu_gpu_uniform_int(p, "u_traced", f->P.traced);
    lu_gpu_uniform_int(p, "u_count", f->count);
}

lu_result lu_ddod_gpu_render(lu_ddod_gpu *g, const lu_scene *scene, const lu_frame_records *rec,
                             const lu_ddod_frame *f, lu_image *out, lu_error *err) {
    size_t pixels = (size_t)f->width * f->height;
    size_t n = (size_t)f->count;
    lu_result r = lu_gpu_scene_update(g->m.scene, scene, rec, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->m.scene, err);
    /* llvmpipe ends an invocation's loops after 65535 iterations in total
     * (tests/test_gpu.c); pass 2 loops once per Gaussian of the tile. */
    int longest = 0;
    for (int t = 0; t < f->P.tiles_x * f->tiles_y; t++)
        longest = f->tile_start[t + 1] - f->tile_start[t] > longest ? f->tile_start[t + 1] - f->tile_start[t] : longest;
    if (g->loop_cap && longest > 60000)
        return lu_fail(err, LU_ERR_LIMIT,
                       "ddod: a 16x16 tile holds %d Gaussians, past llvmpipe's 65535 loop iterations per invocation "
                       "(fewer ddod.samples or a larger image)",
                       longest);
    /* The sample set only changes with prepare: upload it once (NULL data keeps the contents). */
    bool same = g->set_uploaded && g->set_version == f->set_version;
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_SAMPLES, same ? NULL : f->samples,
                              n * LU_K_DDOD_SAMPLE_FLOATS * sizeof(float), err);
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_SH, same ? NULL : f->sh, n * (size_t)f->P.stride * sizeof(float), err);
    g->set_uploaded = r == LU_OK;
    g->set_version = f->set_version;
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_RADIANCE, NULL, n * 4 * sizeof(float), err);
    /* Pixel records and tile lists: only when ddod.c rebuilt them. */
    bool keep_px = g->pixels_uploaded && g->pixels_version == f->pixels_version;
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_PIXELS, keep_px ? NULL : f->pixels,
                              pixels * LU_K_DDOD_PIXEL_FLOATS * sizeof(float), err);
    g->pixels_uploaded = r == LU_OK;
    g->pixels_version = f->pixels_version;
    bool keep_bins = g->bins_uploaded && g->bins_version == f->bins_version;
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_TILE_START, keep_bins ? NULL : f->tile_start,
                              ((size_t)f->P.tiles_x * f->tiles_y + 1) * sizeof(int), err);
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_TILE_LIST, keep_bins ? NULL : f->tile_list,
                              f->list_count * sizeof(int), err);
    g->bins_uploaded = r == LU_OK;
    g->bins_version = f->bins_version;
    if (r == LU_OK)
        r = lu_gpu_method_put(&g->m, B_ENV, f->P.env ? f->env_sh : NULL,
                              f->P.env ? (size_t)f->P.bands * f->P.bands * 3 * sizeof(float) : 0, err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_OUT, NULL, pixels * 3 * sizeof(float), err);
    /* The traced table changes only when the camera or a light moves (ddod.c). */
    if (r == LU_OK) {
        bool keep = g->traced_uploaded && g->traced_version == f->traced_version;
        r = lu_gpu_method_put(&g->m, B_TRACED, keep ? NULL : f->traced,
                              f->P.traced ? n * (size_t)(f->lights + 1) * 4 * sizeof(float) : 0, err);
        g->traced_uploaded = r == LU_OK && f->P.traced;
        g->traced_version = f->traced_version;
    }
    if (r != LU_OK) return r;
    set_uniforms(g->m.prog[0], f);
    set_uniforms(g->m.prog[1], f);
    if (n > 0) r = lu_gpu_dispatch(g->m.prog[0], (unsigned)((n + 63) / 64), 1, 1, err);
    if (r == LU_OK) r = lu_gpu_dispatch(g->m.prog[1], (unsigned)f->P.tiles_x, (unsigned)f->tiles_y, 1, err);
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[B_OUT], out->width, out->height, out->rgb, err);
    return r;
}
