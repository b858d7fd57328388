/* The gradient family's GPU passes (see gradient.h): one program,
 * methods/gradient/gradient.comp, run as three passes over the shared GPU scene —
 * sample evaluation, radiance grid (gather per voxel), view march. The
 * splitting control between sample levels stays on the CPU (it reads back
 * E_j and the sample values, a few thousand records). */
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/common/gpu_method.h"
#include "methods/gradient/gradient.h"

/* Bindings above the scene: the media-ray inputs (as raymarch.comp), then this method's. */
enum { B_HITS, B_SPANS, B_VIEWS, B_TABLE, B_SHADOW, B_OUT, B_SAMPLES, B_CELLS, B_SURF, B_FIELD, B_PARAMS, B_ET, B_BMAP, B_COUNT };
enum { PASS_EVAL = 0, PASS_FIELD = 1, PASS_MARCH = 2, PASS_TAU = 3 };

struct lu_gradient_gpu {
    lu_gpu_method m;                /* slots B_* */
    /* What is on the GPU already: media-ray versions (methods/common/media_ray.h). */
    unsigned maps_version, bmap_version, hits_version, surf_hits_version, surf_vis_version;
    bool maps_uploaded, bmap_uploaded, hits_uploaded, surf_uploaded;
    size_t surf_bytes;
};

lu_result lu_gradient_gpu_create(const lu_scene *scene, lu_gradient_gpu **out, lu_error *err) {
    static const lu_gpu_method_program programs[] = {{"methods/gradient/gradient.comp", NULL}, {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_gradient_gpu), scene, programs, "gradient", &m, err);
    *out = (lu_gradient_gpu *)m;   /* NULL on failure */
    return r;
}

void lu_gradient_gpu_destroy(lu_gradient_gpu *g) {
    if (g) lu_gpu_method_destroy(&g->m);
}

static lu_result bind_common(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, lu_error *err) {
    lu_result r = lu_gpu_scene_update(g->m.scene, scene, f->rec, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->m.scene, err);
    const lu_media_rays *mr = f->mr;
    size_t pixels = (size_t)f->width * f->height, texels = (size_t)mr->shadow_res * mr->shadow_res;
    if (r == LU_OK) {
        /* Camera hits and spans change only with the camera and the geometry. */
        bool same = g->hits_uploaded && g->hits_version == mr->hits_version;
        r = lu_gpu_method_put(&g->m, B_HITS, same ? NULL : mr->hits, pixels * LU_MR_HIT_FLOATS * sizeof(float), err);
        if (r == LU_OK)
            r = lu_gpu_method_put(&g->m, B_SPANS, same ? NULL : mr->spans, pixels * (size_t)f->medium_count * 2 * sizeof(float), err);
        g->hits_uploaded = r == LU_OK;
        g->hits_version = mr->hits_version;
    }
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_VIEWS, mr->views_packed, (size_t)mr->view_count * LU_RM_VIEW_FLOATS * sizeof(float), err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_TABLE, mr->view_table, (size_t)f->light_count * 2 * sizeof(int), err);
    if (r == LU_OK) {
        /* Shadow maps change only with the lights. */
        bool same = g->maps_uploaded && g->maps_version == mr->maps_version;
        r = lu_gpu_method_put(&g->m, B_SHADOW, same ? NULL : mr->shadow, (size_t)mr->view_count * texels * sizeof(float), err);
        g->maps_uploaded = r == LU_OK;
        g->maps_version = mr->maps_version;
    }
    if (r == LU_OK) {
        /* Boundary maps, likewise. */
        bool same = g->bmap_uploaded && g->bmap_version == mr->bmap_version;
        r = lu_gpu_method_put(&g->m, B_BMAP, same ? NULL : mr->bmap, mr->bmap_floats * sizeof(float), err);
        g->bmap_uploaded = r == LU_OK;
        g->bmap_version = mr->bmap_version;
    }
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_PARAMS, &f->G, sizeof f->G, err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_float(g->m.prog[0], "u_step", f->step);
    lu_gpu_uniform_float(g->m.prog[0], "u_eps", f->eps);
    lu_gpu_uniform_float(g->m.prog[0], "u_t_cut", f->t_cut);
    lu_gpu_uniform_vec3(g->m.prog[0], "u_background", f->background.x, f->background.y, f->background.z);
    return LU_OK;
}

lu_result lu_gradient_gpu_eval(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, int first,
                               int count, int want_error, const float *tau_in, float *err_tau, lu_error *err) {
    size_t rec = LU_K_GR_SAMPLE_FLOATS * sizeof(float);
    lu_result r = bind_common(g, scene, f, err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_SAMPLES, f->samples + (size_t)first * LU_K_GR_SAMPLE_FLOATS, (size_t)count * rec, err);
    /* E/tau pairs: tau goes in, (E, tau) come out */
    float *et = lu_malloc((size_t)count * 2 * sizeof(float));
    if (!et) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory");
    for (int i = 0; i < count; i++) et[2 * i] = 0.0f, et[2 * i + 1] = tau_in[i];
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_ET, et, (size_t)count * 2 * sizeof(float), err);
    lu_free(et);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->m.prog[0], "u_pass", PASS_EVAL);
    lu_gpu_uniform_int(g->m.prog[0], "u_count", count);
    lu_gpu_uniform_int(g->m.prog[0], "u_want_error", want_error);
    r = lu_gpu_dispatch(g->m.prog[0], (unsigned)(count + 63) / 64, 1, 1, err);
    if (r == LU_OK)
        r = lu_gpu_buffer_download(g->m.buf[B_SAMPLES], 0, f->samples + (size_t)first * LU_K_GR_SAMPLE_FLOATS,
                                   (size_t)count * rec, err);
    if (r == LU_OK) r = lu_gpu_buffer_download(g->m.buf[B_ET], 0, err_tau, (size_t)count * 2 * sizeof(float), err);
    return r;
}

lu_result lu_gradient_gpu_view_tau(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, int count,
                                   float *tau, lu_error *err) {
    if (count <= 0) return LU_OK;
    lu_result r = bind_common(g, scene, f, err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_SAMPLES, f->samples, (size_t)count * LU_K_GR_SAMPLE_FLOATS * sizeof(float), err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_ET, NULL, (size_t)count * 2 * sizeof(float), err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->m.prog[0], "u_pass", PASS_TAU);
    lu_gpu_uniform_int(g->m.prog[0], "u_count", count);
    r = lu_gpu_dispatch(g->m.prog[0], (unsigned)(count + 63) / 64, 1, 1, err);
    float *et = r == LU_OK ? lu_malloc((size_t)count * 2 * sizeof(float)) : NULL;
    if (r == LU_OK && !et) r = lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory");
    if (r == LU_OK) r = lu_gpu_buffer_download(g->m.buf[B_ET], 0, et, (size_t)count * 2 * sizeof(float), err);
    for (int i = 0; r == LU_OK && i < count; i++) tau[i] = et[2 * i + 1];
    lu_free(et);
    return r;
}

lu_result lu_gradient_gpu_render(lu_gradient_gpu *g, const lu_scene *scene, const lu_gradient_frame *f, bool rebuild,
                                 lu_image *out, double *ms_field, double *ms_march, lu_error *err) {
    const lu_k_gr_params *G = &f->G;
    const lu_media_rays *mr = f->mr;
    size_t pixels = (size_t)f->width * f->height;
    size_t nv = (size_t)G->nx * G->ny * G->nz;
    size_t nc = (size_t)G->cx * G->cy * G->cz;
    double t0 = lu_gpu_time_begin(g->m.ctx);
    lu_result r = bind_common(g, scene, f, err);
    /* Samples and cell lists: uploaded with a rebuilt sample set, otherwise
     * the ones on the GPU are the frame's (only bound again). */
    size_t sample_bytes = (size_t)f->sample_count * LU_K_GR_SAMPLE_FLOATS * sizeof(float);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_SAMPLES, rebuild ? f->samples : NULL, sample_bytes, err);
    /* cell begins then items in one buffer (the shader's storage-block count stays at 16) */
    size_t items = (size_t)f->cell_item_count;
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_CELLS, NULL, (nc + 1 + items) * sizeof(int), err);
    if (r == LU_OK && rebuild) r = lu_gpu_buffer_upload(g->m.buf[B_CELLS], 0, f->cell_begin, (nc + 1) * sizeof(int), err);
    if (r == LU_OK && rebuild && items)
        r = lu_gpu_buffer_upload(g->m.buf[B_CELLS], (nc + 1) * sizeof(int), f->cell_items, items * sizeof(int), err);
    /* boundary materials, the camera rays' span normals, then each light's
     * visibility at the camera rays' opaque hits (one buffer, same reason);
     * the per-pixel parts only when the media rays rebuilt them */
    size_t mats = (size_t)f->G.surf_normals_at * sizeof(float);
    size_t nrm = pixels * (size_t)f->medium_count * LU_MR_NORMAL_FLOATS * sizeof(float);
    size_t vis = pixels * (size_t)f->light_count * sizeof(float);
    bool same = g->surf_uploaded && g->surf_bytes == mats + nrm + vis && g->surf_hits_version == mr->hits_version &&
                g->surf_vis_version == mr->vis_version;
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_SURF, NULL, mats + nrm + vis, err);
    if (r == LU_OK) r = lu_gpu_buffer_upload(g->m.buf[B_SURF], 0, f->surf, mats, err);
    if (r == LU_OK && !same && mr->normals) r = lu_gpu_buffer_upload(g->m.buf[B_SURF], mats, mr->normals, nrm, err);
    if (r == LU_OK && !same && vis) r = lu_gpu_buffer_upload(g->m.buf[B_SURF], mats + nrm, mr->surface_vis, vis, err);
    g->surf_uploaded = r == LU_OK;
    g->surf_bytes = mats + nrm + vis;
    g->surf_hits_version = mr->hits_version;
    g->surf_vis_version = mr->vis_version;
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_FIELD, NULL, nv * 3 * sizeof(float), err);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_ET, NULL, 16, err);
    if (r != LU_OK) return r;
    if (rebuild) {
        lu_gpu_uniform_int(g->m.prog[0], "u_pass", PASS_FIELD);
        lu_gpu_uniform_int(g->m.prog[0], "u_count", (int)nv);
        r = lu_gpu_dispatch(g->m.prog[0], (unsigned)((nv + 63) / 64), 1, 1, err);
    }
    double t1 = lu_gpu_time_end(g->m.ctx, t0);
    *ms_field = 1e3 * t1;
    double t2 = lu_gpu_time_begin(g->m.ctx);
    if (r == LU_OK) r = lu_gpu_method_put(&g->m, B_OUT, NULL, pixels * 3 * sizeof(float), err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->m.prog[0], "u_pass", PASS_MARCH);
    lu_gpu_uniform_int(g->m.prog[0], "u_count", (int)pixels);
    r = lu_gpu_dispatch(g->m.prog[0], (unsigned)((pixels + 63) / 64), 1, 1, err);
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[B_OUT], out->width, out->height, out->rgb, err);
    *ms_march = 1e3 * lu_gpu_time_end(g->m.ctx, t2);
    return r;
}
