/* The raymarch method's GPU pass (see raymarch.h): the shared GPU scene plus
 * this frame's buffers at LU_SCENE_BINDING_FREE and above. */
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "methods/gpu_scene.h"
#include "methods/raymarch.h"

/* Bindings above the scene: the march inputs (LU_MARCH_GPU_BUFFERS), then the image. */
#define B_OUT_BINDING (LU_SCENE_BINDING_FREE + LU_MARCH_GPU_BUFFERS)

struct lu_raymarch_gpu {
    lu_gpu_context *ctx;
    lu_gpu_program *prog;
    lu_gpu_scene *scene;
    lu_march_inputs_gpu in;
    lu_gpu_buffer *out;
    size_t out_size;
};

lu_result lu_raymarch_gpu_create(const lu_scene *scene, lu_raymarch_gpu **out, lu_error *err) {
    *out = NULL;
    lu_raymarch_gpu *g = calloc(1, sizeof *g);
    if (!g) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    lu_result r = lu_gpu_context_create(&g->ctx, LU_GPU_AUTO, err);
    if (r == LU_OK) r = lu_gpu_program_create(g->ctx, "raymarch.comp", NULL, &g->prog, err);
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
    lu_march_inputs_gpu_free(&g->in);
    lu_gpu_buffer_destroy(g->out);
    lu_gpu_scene_destroy(g->scene);
    lu_gpu_program_destroy(g->prog);
    lu_gpu_context_destroy(g->ctx);
    free(g);
}

lu_result lu_raymarch_gpu_render(lu_raymarch_gpu *g, const lu_scene *scene, const lu_raymarch_frame *f, lu_image *out,
                                 lu_error *err) {
    size_t pixels = (size_t)f->width * f->height;
    lu_result r = lu_gpu_scene_update(g->scene, scene, err);
    if (r == LU_OK) r = lu_gpu_scene_bind(g->scene, err);
    if (r == LU_OK) r = lu_march_inputs_gpu_put(&g->in, g->ctx, f->in, scene, f->light_count, LU_SCENE_BINDING_FREE, err);
    if (r == LU_OK) r = lu_gpu_slot_put(g->ctx, &g->out, &g->out_size, B_OUT_BINDING, NULL, pixels * 3 * sizeof(float), err);
    if (r != LU_OK) return r;
    lu_gpu_uniform_int(g->prog, "u_map_res", f->map_res);
    lu_gpu_uniform_float(g->prog, "u_step", f->step);
    lu_gpu_uniform_float(g->prog, "u_eps", f->eps);
    lu_gpu_uniform_int(g->prog, "u_jitter", f->jitter);
    lu_gpu_uniform_vec3(g->prog, "u_background", f->background.x, f->background.y, f->background.z);
    r = lu_gpu_dispatch(g->prog, (unsigned)(f->width + 7) / 8, (unsigned)(f->height + 7) / 8, 1, err);
    if (r == LU_OK) r = lu_gpu_buffer_download(g->out, 0, out->rgb, pixels * 3 * sizeof(float), err);
    return r;
}
