/* The view march's frame (view_march.h): step length and the per-pixel
 * buffers of one frame, and its kernel parameter record. */
#include <lucent/lucent.h>

#include "methods/common/view_march.h"
#include "methods/common/kernel_ctx.h"

/* The kernel is included only for its records; no hook is called here. */
struct lu_k_ctx {
    LU_K_CTX_VIEW_MARCH_MEMBERS
};

#include "methods/common/view_march_hooks.h"
#include "methods/common/lu_view_march.h"

void lu_view_march_frame_fill(lu_view_march_frame *f, const lu_scene *scene, const lu_media_rays *mr, int steps, float eps,
                            int jitter, int nl, float t_cut) {
    lu_aabb mb = lu_scene_media_bounds(scene);
    float diag = lu_aabb_valid(mb) ? lu_v3_len(lu_v3_sub(mb.hi, mb.lo)) : 1.0f;
    f->width = scene->camera.width;
    f->height = scene->camera.height;
    f->background = scene->background;
    f->step = fmaxf(diag, 1e-6f) / (float)steps;
    f->eps = eps;
    f->jitter = jitter;
    f->map_res = mr->shadow_res;
    f->medium_count = scene->medium_count;
    f->light_count = nl;
    f->hits = mr->hits;
    f->spans = mr->spans;
    f->view_count = mr->view_count;
    f->views = mr->views_packed;
    f->view_table = mr->view_table;
    f->shadow = mr->shadow;
    f->surface_vis = mr->surface_vis;
    f->maps_version = mr->maps_version;
    f->hits_version = mr->hits_version;
    f->vis_version = mr->vis_version;
    f->max_steps = steps;
    f->t_cut = t_cut;
    f->ms = lu_k_ms_make(1, 1.0f, 1.0f, 1.0f);
    f->majorants = mr->majorants;
}

long lu_view_march_shadow_iterations(const lu_k_medium *k) {
    /* The block walk, and per block entered its cell walk: every cell piece
     * once, plus one restart piece and one loop entry per block. */
    long blocks = k->max_pieces / LU_SCENE_MAJORANT_BLOCK + 4;
    return 1 + k->max_pieces + 3 * blocks;
}

lu_k_rm_params lu_view_march_frame_params(const lu_view_march_frame *f) {
    lu_k_rm_params P;
    P.background = f->background;
    P.step = f->step;
    P.eps = f->eps;
    P.jitter = f->jitter;
    P.map_res = f->map_res;
    P.t_cut = f->t_cut;
    P.ms = f->ms;
    return P;
}

lu_k_ms lu_view_march_ms(const double *p) {
    if ((int)p[0] == 0) return lu_k_ms_make(1, 1.0f, 1.0f, 1.0f);
    return lu_k_ms_make((int)p[1], (float)p[2], (float)p[3], (float)p[4]);
}

typedef struct rows_job {
    lu_k_rm_params P;
    lu_k_camera cam;
    lu_vec3 origin;
    lu_view_march_pixel_fn fn;
    void *state;
    lu_image *out;
} rows_job;

static void march_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    const rows_job *j = ctx;
    int w = j->out->width;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < w; x++) {
            int px = (int)(y * w + x);
            lu_vec3 d = lu_k_camera_dir(j->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_vec3 L = j->fn(j->state, j->P, px, j->origin, d, lu_k_rm_jitter(j->P.jitter, px));
            float *o = lu_image_px(j->out, x, (int)y);
            o[0] = L.x;
            o[1] = L.y;
            o[2] = L.z;
        }
    }
}

void lu_view_march_render_rows(const lu_frame *frame, const lu_view_march_frame *f, lu_k_camera cam,
                               lu_view_march_pixel_fn fn, void *state, lu_image *out) {
    rows_job j = {lu_view_march_frame_params(f), cam, frame->scene->camera.position, fn, state, out};
    lu_frame_for_rows(frame, 1, march_rows, &j, NULL);
}
