/* The afm method's GPU passes (see afm.h): afm_build.comp fills the maps'
 * records on the GPU from the shared GPU scene (grids as 3D textures) and
 * the CPU's light views and bounded-media light spans; afm_render.comp
 * marches the view rays with the CPU's camera hits/spans/normals and shadow
 * maps. Both passes are dispatched in chunks (views, rows) so that no
 * single dispatch runs long on a software rasteriser. */
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/afm/afm.h"
#include "methods/common/gpu_method.h"

/* render-pass buffers after the shared raymarch ones (lu_raymarch_gpu.glsl) */
enum { R_HITS, R_SPANS, R_VIEWS, R_TABLE, R_SHADOW, R_NORMALS, R_AVIEWS, R_ATABLE, R_RECORDS, R_SURFACES, R_OUT, R_SURFVIS, R_COUNT };
/* build-pass bindings (relative to LU_SCENE_BINDING_FREE) */
enum { B_AVIEWS, B_LSPANS, B_RECORDS };

struct lu_afm_gpu {
    lu_gpu_method m;                /* programs: build, render; slots R_* */
    lu_gpu_buffer *lspans;
    lu_gpu_upload lspans_up;
};

lu_result lu_afm_gpu_create(const lu_scene *scene, lu_afm_gpu **out, lu_error *err) {
    static const lu_gpu_method_program programs[] = {
        {"methods/afm/afm_build.comp", NULL}, {"methods/afm/afm_render.comp", NULL}, {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_afm_gpu), scene, programs, "afm", &m, err);
    *out = (lu_afm_gpu *)m;   /* NULL on failure */
    return r;
}

void lu_afm_gpu_destroy(lu_afm_gpu *g) {
    if (!g) return;
    lu_gpu_buffer_destroy(g->lspans);
    lu_gpu_method_destroy(&g->m);
}

size_t lu_afm_gpu_limits(const lu_afm_gpu *g, bool *loop_cap) {
    lu_gpu_info info;
    lu_gpu_info_get(g->m.ctx, &info);
    *loop_cap = info.loop_cap;
    return info.max_ssbo_size > 0 ? (size_t)info.max_ssbo_size : 0;
}

static lu_result put(lu_afm_gpu *g, lu_gpu_buffer **slot, const void *data, size_t bytes, int binding, lu_error *err) {
    return lu_gpu_buffer_put(g->m.ctx, slot, data, bytes, LU_SCENE_BINDING_FREE + binding, err);
}

/* Render slot i, uploaded only when its product's version changed. */
static void set_map_uniforms(lu_gpu_program *p, const lu_afm_map *map) {
    lu_gpu_uniform_int(p, "u_res", map->res);
    lu_gpu_uniform_int(p, "u_coefs", map->coefs);
    lu_gpu_uniform_int(p, "u_samples", map->samples);
    lu_gpu_uniform_int(p, "u_channels", map->channels);
}

/* The records of the map->rebuild lights' views; the other views' records
 * stay in the buffer from earlier frames. */
static lu_result build_maps(lu_afm_gpu *g, const lu_afm_map *map, lu_error *err) {
    size_t texels = lu_afm_map_texels(map);
    size_t rec_bytes = texels * (size_t)lu_afm_map_stride(map) * sizeof(float);
    uint64_t lights = map->rebuild;
    /* A new (larger) records buffer keeps nothing. The map asks for every
     * light whenever its layout or stride changed, so this is a first build. */
    if (!g->m.buf[R_RECORDS] || lu_gpu_buffer_size(g->m.buf[R_RECORDS]) < rec_bytes) lights = ~0ull;
    lu_result r = lu_gpu_scene_bind(g->m.scene, err);
    if (r == LU_OK)
        r = lu_gpu_buffer_put_versioned(g->m.ctx, &g->m.buf[R_AVIEWS], &g->m.up[R_AVIEWS], map->views_packed,
                                        (size_t)map->view_count * LU_RM_VIEW_FLOATS * sizeof(float), map->version,
                                        LU_SCENE_BINDING_FREE + B_AVIEWS, err);
    if (r == LU_OK && map->bounded)
        r = lu_gpu_buffer_put_versioned(g->m.ctx, &g->lspans, &g->lspans_up, map->lspans,
                                        texels * (size_t)map->nm * LU_AFM_LSPAN_FLOATS * sizeof(float), map->version,
                                        LU_SCENE_BINDING_FREE + B_LSPANS, err);
    if (r == LU_OK && !map->bounded) r = put(g, &g->lspans, NULL, 16, B_LSPANS, err);
    if (r == LU_OK) r = put(g, &g->m.buf[R_RECORDS], NULL, rec_bytes, B_RECORDS, err);
    if (r != LU_OK) return r;
    set_map_uniforms(g->m.prog[0], map);
    lu_gpu_uniform_int(g->m.prog[0], "u_bounded", map->bounded ? 1 : 0);
    unsigned groups = (unsigned)(map->res + 7) / 8;
    for (int l = 0; l < map->nl && r == LU_OK; l++) {
        if (!lu_afm_has_light(lights, l)) continue;
        for (int v = map->view_table[2 * l]; v < map->view_table[2 * l] + map->view_table[2 * l + 1] && r == LU_OK; v++) {
            lu_gpu_uniform_int(g->m.prog[0], "u_view0", v);
            r = lu_gpu_dispatch(g->m.prog[0], groups, groups, 1, err);
        }
    }
    return r;
}

lu_result lu_afm_gpu_render(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_gpu_frame *f, lu_image *out,
                            lu_error *err) {
    const lu_media_rays *mr = f->mr;
    const lu_afm_map *map = f->map;
    int w = scene->camera.width, h = scene->camera.height;
    size_t pixels = (size_t)w * h;
    size_t nm = (size_t)scene->medium_count;
    size_t shadow_texels = (size_t)mr->shadow_res * mr->shadow_res;
    lu_result r = lu_gpu_scene_update(g->m.scene, scene, f->rec, err);
    if (r == LU_OK) r = build_maps(g, map, err);
    /* render pass */
    /* Each CPU input crosses the bus only in the frame its product was
     * rebuilt: camera rays (hits_version), shadow views and maps
     * (maps_version), surface visibility (vis_version), afm views (version). */
    if (r == LU_OK) r = lu_gpu_scene_bind(g->m.scene, err);
    if (r == LU_OK) r = lu_gpu_method_put_kept(&g->m, R_HITS, mr->hits, pixels * LU_MR_HIT_FLOATS * sizeof(float), mr->hits_version, err);
    if (r == LU_OK) r = lu_gpu_method_put_kept(&g->m, R_SPANS, mr->spans, pixels * nm * 2 * sizeof(float), mr->hits_version, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, R_VIEWS, mr->views_packed, (size_t)mr->view_count * LU_RM_VIEW_FLOATS * sizeof(float),
                     mr->maps_version, err);
    if (r == LU_OK) r = lu_gpu_method_put_kept(&g->m, R_TABLE, mr->view_table, (size_t)f->nl * 2 * sizeof(int), mr->maps_version, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, R_SHADOW, mr->shadow, (size_t)mr->view_count * shadow_texels * sizeof(float), mr->maps_version,
                     err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, R_NORMALS, mr->normals, pixels * nm * LU_MR_NORMAL_FLOATS * sizeof(float), mr->hits_version,
                     err);
    if (r == LU_OK) r = lu_gpu_buffer_bind(g->m.buf[R_AVIEWS], LU_SCENE_BINDING_FREE + R_AVIEWS, err);
    if (r == LU_OK) r = lu_gpu_method_put_kept(&g->m, R_ATABLE, map->view_table, (size_t)f->nl * 2 * sizeof(int), map->version, err);
    if (r == LU_OK) r = lu_gpu_buffer_bind(g->m.buf[R_RECORDS], LU_SCENE_BINDING_FREE + R_RECORDS, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, R_SURFACES, f->surfaces, nm * LU_AFM_SURFACE_FLOATS * sizeof(float), f->surfaces_version, err);
    if (r == LU_OK) r = put(g, &g->m.buf[R_OUT], NULL, pixels * 3 * sizeof(float), R_OUT, err);
    if (r == LU_OK)
        r = lu_gpu_method_put_kept(&g->m, R_SURFVIS, mr->surface_vis, pixels * (size_t)f->nl * sizeof(float), mr->vis_version, err);
    if (r != LU_OK) return r;
    lu_gpu_program *p = g->m.prog[1];
    set_map_uniforms(p, map);
    lu_gpu_uniform_int(p, "u_map_res", f->shadow_res);
    lu_gpu_uniform_float(p, "u_step", f->step);
    lu_gpu_uniform_float(p, "u_eps", f->eps);
    lu_gpu_uniform_int(p, "u_jitter", f->jitter);
    lu_gpu_uniform_float(p, "u_t_cut", f->t_cut);
    lu_gpu_uniform_vec4(p, "u_ms", (float)f->ms.octaves, f->ms.a, f->ms.b, f->ms.c);
    lu_gpu_uniform_vec3(p, "u_background", f->background.x, f->background.y, f->background.z);
    const int rows = 64;
    for (int y0 = 0; y0 < h && r == LU_OK; y0 += rows) {
        lu_gpu_uniform_int(p, "u_row0", y0);
        int n = h - y0 < rows ? h - y0 : rows;
        r = lu_gpu_dispatch(p, (unsigned)(w + 7) / 8, (unsigned)(n + 7) / 8, 1, err);
    }
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[R_OUT], out->width, out->height, out->rgb, err);
    return r;
}

lu_result lu_afm_gpu_build_download(lu_afm_gpu *g, const lu_scene *scene, const lu_afm_map *map, float *records,
                                    lu_error *err) {
    lu_frame_records rec = {0};
    lu_result r = lu_frame_records_update(&rec, scene, err);
    if (r == LU_OK) r = lu_gpu_scene_update(g->m.scene, scene, &rec, err);
    lu_frame_records_free(&rec);
    if (r == LU_OK) r = build_maps(g, map, err);
    if (r == LU_OK)
        r = lu_gpu_buffer_download(g->m.buf[R_RECORDS], 0, records,
                                   lu_afm_map_texels(map) * (size_t)lu_afm_map_stride(map) * sizeof(float), err);
    return r;
}
