/* raymarch — fixed-step single scattering sharing the reference's kernels
 * (exact optical depth to the lights, HG phase, light arrival), on the CPU
 * and the GPU from one kernel (kernels/lu_raymarch.h). Per frame the CPU
 * builds the inputs both backends read: the camera rays' first opaque hits
 * and bounded-media spans (Embree) and shadow maps of the opaque objects
 * (lightview.h), since the GPU has no ray tracer. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "methods/gpu_scene.h"
#include "methods/lightview.h"
#include "methods/methods.h"
#include "methods/opaque_accel.h"
#include "methods/raymarch.h"

/* ---- kernel context: the hooks of lu_raymarch.h on the CPU ---- */
struct lu_k_ctx {
    const lu_medium *media;
    const lu_k_medium *km;
    int nm;
    const lu_k_light *kl;
    int nl;
    const lu_raymarch_frame *f;
    const lu_k_lightview *views;
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const lu_medium *med = &c->media[m];
    return med->kind == LU_DENSITY_CONSTANT ? med->constant : lu_grid_sample(&med->grid, p);
}
static inline int lu_k_medium_count(const struct lu_k_ctx *c) { return c->nm; }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) { return c->km[m]; }
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return c->nl; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) { return c->kl[l]; }
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return c->f->shadow[((size_t)map * c->f->map_res + j) * c->f->map_res + i];
}
static inline int lu_k_rm_view_first(const struct lu_k_ctx *c, int l) { return c->f->view_table[2 * l]; }
static inline int lu_k_rm_view_count(const struct lu_k_ctx *c, int l) { return c->f->view_table[2 * l + 1]; }
static inline lu_k_lightview lu_k_rm_view(const struct lu_k_ctx *c, int v) { return c->views[v]; }
static inline float lu_k_rm_hit_fetch(const struct lu_k_ctx *c, int pixel, int k) {
    return c->f->hits[(size_t)pixel * 16 + k];
}
static inline float lu_k_rm_span(const struct lu_k_ctx *c, int pixel, int m, int end) {
    return c->f->spans[((size_t)pixel * c->nm + m) * 2 + end];
}

#include "kernels/lu_raymarch.h"

enum { P_STEPS, P_JITTER, P_SHADOW_RES, P_COUNT };

static const lu_param_desc k_params[P_COUNT] = {
    [P_STEPS] = {"steps", LU_PARAM_INT, 256, 4, 16384, NULL,
                 "march steps across the diagonal of the media's box (step length = diagonal / steps)"},
    [P_JITTER] = {"jitter", LU_PARAM_BOOL, 0, 0, 1, NULL,
                  "shift each pixel's samples by a per-pixel hash within a step (noise instead of banding)"},
    [P_SHADOW_RES] = {"shadow_res", LU_PARAM_INT, 512, 16, 4096, NULL,
                      "shadow map resolution per light view (opaque objects only; media use exact optical depth)"},
};

typedef struct rm_state {
    lu_backend backend;
    int steps, jitter, res;
    lu_accel *opaque;
    int *opaque_object;
    lu_accel **boundary;       /* per medium, NULL when unbounded */
    int medium_count;
    lu_k_medium *km;
    lu_k_light *kl;
    int nl;
    float eps;
    /* frame inputs, rebuilt when what they depend on changes */
    float *hits, *spans;
    size_t pixels_cap;
    lu_camera hits_cam;        /* camera the hits were cast for */
    bool hits_valid;
    lu_k_lightview *views;
    float *views_packed;
    int *view_table;
    float *shadow;
    int view_count;
    lu_k_light *maps_lights;   /* lights the maps were built for */
    bool maps_valid;
    unsigned maps_version;
    lu_raymarch_frame frame;
    const lu_scene *scene;
    struct lu_k_ctx kctx;
    lu_k_camera cam;
    lu_image *out;
    lu_raymarch_gpu *gpu;
} rm_state;

static void rm_destroy(void *state) {
    rm_state *st = state;
    if (!st) return;
    lu_raymarch_gpu_destroy(st->gpu);
    if (st->opaque) lu_accel_destroy(st->opaque);
    for (int m = 0; m < st->medium_count && st->boundary; m++)
        if (st->boundary[m]) lu_accel_destroy(st->boundary[m]);
    free(st->boundary);
    free(st->opaque_object);
    free(st->km);
    free(st->kl);
    free(st->hits);
    free(st->spans);
    free(st->views);
    free(st->views_packed);
    free(st->view_table);
    free(st->shadow);
    free(st->maps_lights);
    free(st);
}

static lu_result rm_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                            lu_error *err) {
    rm_state *st = calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    st->backend = backend;
    st->steps = (int)params[P_STEPS];
    st->jitter = (int)params[P_JITTER];
    st->res = (int)params[P_SHADOW_RES];
    lu_result r = LU_OK;
    if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "raymarch: %d media (at most %d)", scene->medium_count, LU_K_RM_MAX_MEDIA);
    lu_aabb bounds = lu_scene_bounds(scene);
    float size = lu_aabb_valid(bounds) ? lu_v3_maxc(lu_v3_sub(bounds.hi, bounds.lo)) : 1.0f;
    st->eps = 1e-5f * fmaxf(size, 1e-3f);

    if (r == LU_OK) r = lu_opaque_accel_build(scene, &st->opaque, &st->opaque_object, err);
    st->medium_count = scene->medium_count;
    size_t nm = scene->medium_count ? (size_t)scene->medium_count : 1u;
    st->boundary = calloc(nm, sizeof *st->boundary);
    st->km = calloc(nm, sizeof *st->km);
    if ((!st->boundary || !st->km) && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++)
        if (scene->media[m].has_boundary) r = lu_mesh_accel_build(&scene->media[m].boundary, &st->boundary[m], err);
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_raymarch_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        rm_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

/* ---- per-pixel hits and spans (Embree) ---- */

static void hit_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    rm_state *st = ctx;
    const lu_scene *s = st->scene;
    const lu_camera *c = &s->camera;
    int nm = st->medium_count;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < c->width; x++) {
            size_t px = (size_t)y * c->width + x;
            lu_vec3 o = c->position, d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
            float *h = st->hits + px * LU_K_RM_HIT_FLOATS;
            memset(h, 0, LU_K_RM_HIT_FLOATS * sizeof *h);
            h[3] = -1.0f;
            lu_hit hit;
            float t_end = LU_K_FAR;
            if (st->opaque && lu_accel_closest(st->opaque, o, d, 0.0f, LU_K_FAR, &hit)) {
                const lu_object *ob = &s->objects[st->opaque_object[hit.mesh_id]];
                lu_vec3 n, ng;
                lu_hit_normals(&ob->mesh, &hit, d, &n, &ng);
                const lu_material *mt = &ob->material;
                memcpy(h, &n, 12);
                h[3] = hit.t;
                memcpy(h + 4, &ng, 12);
                memcpy(h + 8, &mt->albedo, 12);
                h[11] = mt->shininess;
                memcpy(h + 12, &mt->specular, 12);
                t_end = hit.t;
            }
            float *sp = st->spans + px * (size_t)nm * 2;
            for (int m = 0; m < nm; m++) {
                sp[2 * m] = 0.0f;
                sp[2 * m + 1] = LU_K_FAR;
                if (!st->boundary[m]) continue;
                /* The first span inside the boundary along the ray (all of it
                 * for a convex boundary). */
                lu_hit hs[2];
                int n = lu_accel_all_hits(st->boundary[m], o, d, 0.0f, t_end, hs, 2);
                bool inside = lu_accel_inside(st->boundary[m], o);
                if (inside) {
                    sp[2 * m + 1] = n > 0 ? hs[0].t : LU_K_FAR;
                } else if (n > 0) {
                    sp[2 * m] = hs[0].t;
                    sp[2 * m + 1] = n > 1 ? hs[1].t : LU_K_FAR;
                } else {
                    sp[2 * m + 1] = 0.0f;
                }
            }
        }
    }
}

static lu_result build_hits(rm_state *st, const lu_scene *scene, lu_error *err) {
    const lu_camera *c = &scene->camera;
    size_t pixels = (size_t)c->width * c->height;
    if (pixels > st->pixels_cap) {
        free(st->hits);
        free(st->spans);
        st->hits = malloc(pixels * LU_K_RM_HIT_FLOATS * sizeof(float));
        st->spans = malloc(pixels * (size_t)(st->medium_count ? st->medium_count : 1) * 2 * sizeof(float));
        st->pixels_cap = st->hits && st->spans ? pixels : 0;
        st->hits_valid = false;
        if (!st->hits || !st->spans) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory for %zu pixels", pixels);
    }
    if (st->hits_valid && memcmp(&st->hits_cam, c, sizeof *c) == 0) return LU_OK;
    lu_parallel_for(c->height, 4, hit_rows, st, NULL);
    st->hits_cam = *c;
    st->hits_valid = true;
    return LU_OK;
}

/* ---- shadow maps of the opaque objects, per light view ---- */

static lu_result build_maps(rm_state *st, const lu_scene *scene, lu_error *err) {
    if (st->maps_valid && memcmp(st->maps_lights, st->kl, (size_t)st->nl * sizeof *st->kl) == 0) return LU_OK;
    size_t nl = st->nl ? (size_t)st->nl : 1u;
    free(st->views);
    free(st->views_packed);
    free(st->view_table);
    free(st->shadow);
    free(st->maps_lights);
    st->views = calloc(nl * 6, sizeof *st->views);
    st->views_packed = calloc(nl * 6 * LU_RM_VIEW_FLOATS, sizeof(float));
    st->view_table = calloc(nl * 2, sizeof(int));
    st->maps_lights = malloc(nl * sizeof *st->maps_lights);
    st->shadow = NULL;
    st->view_count = 0;
    st->maps_valid = false;
    if (!st->views || !st->views_packed || !st->view_table || !st->maps_lights)
        return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    /* Without opaque objects nothing casts: no views, visibility 1. */
    if (st->opaque) {
        lu_aabb region = lu_scene_bounds(scene);
        int k = 0;
        for (int l = 0; l < scene->light_count; l++) {
            if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) continue;
            lu_lightviews lv;
            lu_lightviews_for_light(&scene->lights[l], region, &lv);
            st->view_table[2 * k] = st->view_count;
            st->view_table[2 * k + 1] = lv.count;
            for (int v = 0; v < lv.count; v++) {
                const lu_k_lightview *w = &lv.view[v];
                float *p = st->views_packed + (size_t)st->view_count * LU_RM_VIEW_FLOATS;
                memcpy(p, &w->origin, 12);
                p[3] = (float)w->ortho;
                memcpy(p + 4, &w->axis_u, 12);
                p[7] = w->extent_u;
                memcpy(p + 8, &w->axis_v, 12);
                p[11] = w->extent_v;
                memcpy(p + 12, &w->axis_w, 12);
                p[15] = w->depth_far;
                st->views[st->view_count++] = *w;
            }
            k++;
        }
        size_t texels = (size_t)st->res * st->res;
        st->shadow = malloc((st->view_count ? (size_t)st->view_count : 1u) * texels * sizeof(float));
        if (!st->shadow) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory for shadow maps");
        for (int v = 0; v < st->view_count; v++) {
            lu_result r = lu_shadow_map_build(st->opaque, &st->views[v], st->res, 1e30f, st->shadow + v * texels, err);
            if (r != LU_OK) return r;
        }
    } else {
        st->shadow = calloc(1, sizeof(float));
        if (!st->shadow) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    }
    memcpy(st->maps_lights, st->kl, (size_t)st->nl * sizeof *st->kl);
    st->maps_valid = true;
    st->maps_version++;
    return LU_OK;
}

static void render_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    rm_state *st = ctx;
    const lu_camera *c = &st->scene->camera;
    lu_k_rm_params P;
    P.background = st->frame.background;
    P.step = st->frame.step;
    P.eps = st->frame.eps;
    P.jitter = st->frame.jitter;
    P.map_res = st->frame.map_res;
    P.pad = 0;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < c->width; x++) {
            int px = (int)(y * c->width + x);
            lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_vec3 L = lu_k_rm_radiance(&st->kctx, P, px, c->position, d, lu_k_rm_jitter(P.jitter, px));
            float *o = lu_image_px(st->out, x, (int)y);
            o[0] = L.x;
            o[1] = L.y;
            o[2] = L.z;
        }
    }
}

static lu_result rm_render(void *state, const lu_scene *scene, lu_image *out, lu_error *err) {
    rm_state *st = state;
    if (scene->medium_count != st->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "raymarch: the scene's media changed since prepare");
    st->scene = scene;
    st->out = out;
    const lu_camera *c = &scene->camera;
    st->cam = lu_k_camera_make(c->position, c->look_at, c->up, c->fov_y_deg, c->width, c->height);
    for (int m = 0; m < scene->medium_count; m++) st->km[m] = lu_medium_to_kernel(&scene->media[m]);
    lu_k_light *kl = realloc(st->kl, (scene->light_count ? (size_t)scene->light_count : 1u) * sizeof *kl);
    if (!kl) return lu_fail(err, LU_ERR_NOMEM, "raymarch: out of memory");
    st->kl = kl;
    int nl = lu_scene_kernel_lights(scene, kl);
    if (nl != st->nl) st->maps_valid = false;
    st->nl = nl;
    lu_result r = build_hits(st, scene, err);
    if (r == LU_OK) r = build_maps(st, scene, err);
    if (r != LU_OK) return r;

    lu_aabb mb = lu_scene_media_bounds(scene);
    float diag = lu_aabb_valid(mb) ? lu_v3_len(lu_v3_sub(mb.hi, mb.lo)) : 1.0f;
    lu_raymarch_frame *f = &st->frame;
    f->width = c->width;
    f->height = c->height;
    f->background = scene->background;
    f->step = fmaxf(diag, 1e-6f) / (float)st->steps;
    f->eps = st->eps;
    f->jitter = st->jitter;
    f->map_res = st->res;
    f->medium_count = scene->medium_count;
    f->light_count = nl;
    f->hits = st->hits;
    f->spans = st->spans;
    f->view_count = st->view_count;
    f->views = st->views_packed;
    f->view_table = st->view_table;
    f->shadow = st->shadow;
    f->maps_version = st->maps_version;
    if (st->backend == LU_BACKEND_GPU) return lu_raymarch_gpu_render(st->gpu, scene, f, out, err);
    st->kctx = (struct lu_k_ctx){scene->media, st->km, scene->medium_count, st->kl, nl, f, st->views};
    lu_parallel_for(c->height, 1, render_rows, st, NULL);
    return LU_OK;
}

const lu_method lu_method_raymarch = {
    .name = "raymarch",
    .summary = "fixed-step single scattering with exact shadow-ray optical depth and shadow maps (CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .prepare = rm_prepare,
    .render = rm_render,
    .destroy = rm_destroy,
};
