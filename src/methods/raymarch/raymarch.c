/* raymarch — fixed-step single scattering sharing the reference's kernels
 * (exact optical depth to the lights, HG phase, light arrival), on the CPU
 * and the GPU from one kernel (methods/common/lu_view_march.h). Per frame the CPU
 * builds the inputs both backends read: the camera rays' first opaque hits
 * and bounded-media spans (Embree), each light's exact visibility at those
 * hits (one Embree occlusion ray per pixel and light) and shadow maps of the
 * opaque objects (lightview.h) for the samples in the media, since the GPU
 * has no ray tracer. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "methods/common/gpu_scene.h"
#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/raymarch/raymarch.h"

/* ---- kernel context: the hooks of lu_view_march.h on the CPU ---- */
#include "methods/common/kernel_ctx.h"

struct lu_k_ctx {
    LU_K_CTX_VIEW_MARCH_MEMBERS
};

#include "methods/common/view_march_hooks.h"

/* A camera-visible surface is lit with the exact visibility the CPU traced
 * (media_ray.h), as afm does: a shadow map leaks light at the edges of thin
 * occluders (dusty_room's sun through the window: 0.32 rel-L2 with the map,
 * 0.015 without, docs/gpu.md). The samples in the media keep the maps. */
static inline float lu_k_rm_surface_vis(const struct lu_k_ctx *c, int pixel, int l) {
    return c->f->surface_vis[(size_t)pixel * c->nl + l];
}
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_rm_surface_vis(LU_CTX, pixel, l)

#include "methods/common/lu_view_march.h"

enum { P_STEPS, P_JITTER, P_SHADOW_RES, P_T_CUT, P_MS, P_COUNT = P_MS + LU_VIEW_MARCH_MS_PARAM_COUNT };

static const lu_param_desc k_params[P_COUNT] = {
    [P_STEPS] = {"steps", LU_PARAM_INT, 256, 4, 16384, NULL,
                 "march steps across the diagonal of the media's box (step length = diagonal / steps)"},
    [P_JITTER] = {"jitter", LU_PARAM_BOOL, 0, 0, 1, NULL,
                  "shift each pixel's samples by a per-pixel hash within a step (noise instead of banding)"},
    [P_SHADOW_RES] = {"shadow_res", LU_PARAM_INT, 512, 16, 4096, NULL,
                      "shadow map resolution per light view (opaque objects only; media use exact optical depth)"},
    [P_T_CUT] = LU_VIEW_MARCH_T_CUT_PARAM,
    LU_VIEW_MARCH_MS_PARAMS(P_MS)
};

typedef struct rm_state {
    lu_backend backend;
    int steps, jitter, res;
    float t_cut;
    lu_k_ms ms;
    lu_media_rays mr;          /* camera hits/spans, light views, shadow maps */
    float eps;
    lu_view_march_frame frame;
    struct lu_k_ctx kctx;
    lu_k_camera cam;
    lu_raymarch_gpu *gpu;
} rm_state;

_Static_assert(LU_MR_HIT_FLOATS == LU_K_RM_HIT_FLOATS, "camera hit layout");

static void rm_destroy(void *state) {
    rm_state *st = state;
    if (!st) return;
    lu_raymarch_gpu_destroy(st->gpu);
    lu_media_rays_free(&st->mr);
    lu_free(st);
}

static lu_result rm_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                            lu_error *err) {
    rm_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    st->backend = backend;
    st->steps = (int)params[P_STEPS];
    st->jitter = (int)params[P_JITTER];
    st->res = (int)params[P_SHADOW_RES];
    st->t_cut = (float)params[P_T_CUT];
    st->ms = lu_view_march_ms(params + P_MS);
    lu_result r = LU_OK;
    if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "raymarch: %d media (at most %d)", scene->medium_count, LU_K_RM_MAX_MEDIA);
    st->eps = lu_scene_ray_epsilon(scene);
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, st->res, false, err);
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_raymarch_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        rm_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

static lu_vec3 rm_pixel(void *state, lu_k_rm_params P, int pixel, lu_vec3 o, lu_vec3 d, float u) {
    return lu_k_rm_radiance(&((rm_state *)state)->kctx, P, pixel, o, d, u);
}

static lu_result rm_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    rm_state *st = state;
    if (scene->medium_count != st->mr.medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "raymarch: the scene's media changed since prepare");
    st->cam = frame->rec->cam;
    const lu_k_light *kl = frame->rec->lights;
    int nl = frame->rec->light_count;
    lu_result r = lu_media_rays_view_march(&st->mr, frame, st->cam, kl, nl, st->eps, err);
    if (r != LU_OK) return r;

    lu_view_march_frame *f = &st->frame;
    lu_view_march_frame_fill(f, scene, &st->mr, st->steps, st->eps, st->jitter, nl, st->t_cut);
    f->ms = st->ms;
    if (st->backend == LU_BACKEND_GPU) return lu_raymarch_gpu_render(st->gpu, scene, frame->rec, f, out, err);
    st->kctx = (struct lu_k_ctx){LU_K_CTX_SCENE(scene, frame->rec), f, st->mr.views};
    lu_view_march_render_rows(frame, f, st->cam, rm_pixel, st, out);
    return LU_OK;
}

const lu_method lu_method_raymarch = {
    .name = "raymarch",
    .summary = "fixed-step single scattering with exact shadow-ray optical depth, shadow maps in the media and "
               "exact surface visibility (CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .prepare = rm_prepare,
    .render = rm_render,
    .destroy = rm_destroy,
};
