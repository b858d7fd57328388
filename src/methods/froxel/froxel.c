/* froxel — volumetric fog on a camera-frustum grid (Wronski 2014, Hillaire
 * 2015; docs/froxel.md), the engines' real-time baseline: each cell of a
 * nx x ny x nz grid with exponential depth slices is lit once per frame with
 * the shared view march's in-scattering (exact optical depth to the lights,
 * opaque shadow maps), integrated front to back per column, and looked up
 * per pixel at its opaque hit. The math is one kernel for the CPU and the
 * GPU (lu_froxel.h); the CPU builds the inputs both read, as raymarch does
 * (media_ray.h: camera hits, shadow maps, exact surface visibility), plus
 * the bounded media's spans along each column's centre ray. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "methods/common/gpu_scene.h"
#include "methods/froxel/froxel.h"
#include "methods/frame.h"
#include "methods/methods.h"

#include "methods/common/kernel_ctx.h"

struct lu_k_ctx {
    LU_K_CTX_VIEW_MARCH_MEMBERS
    const float *reach;    /* per column: the farthest ray end of the pixels reading it */
    const float *cspans;   /* columns * nm * 2 */
    const float *lit;      /* this frame's lit volume */
    const float *hist;     /* the previous frame's */
    float *integ;          /* integrated volume (written by pass 2) */
};

#include "methods/common/view_march_hooks.h"

/* Surfaces are lit with the CPU's exact per-pixel visibility, as raymarch's are. */
static inline float lu_k_rm_surface_vis(const struct lu_k_ctx *c, int pixel, int l) {
    return c->f->surface_vis[(size_t)pixel * c->nl + l];
}
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_rm_surface_vis(LU_CTX, pixel, l)

static inline float lu_k_fx_span(const struct lu_k_ctx *c, int column, int m, int end) {
    return c->cspans[((size_t)column * c->nm + m) * 2 + end];
}
static inline float lu_k_fx_reach(const struct lu_k_ctx *c, int column) { return c->reach[column]; }
static inline float lu_k_fx_hist_valid(const struct lu_k_ctx *c, int cell) {
    return c->hist[(size_t)cell * LU_K_FX_CELL_FLOATS + 3];
}
static inline lu_vec3 lu_fx_read(const float *p) { return lu_v3(p[0], p[1], p[2]); }
static inline lu_vec3 lu_k_fx_lit(const struct lu_k_ctx *c, int cell, int part) {
    return lu_fx_read(c->lit + (size_t)cell * LU_K_FX_CELL_FLOATS + 4 * part);
}
static inline lu_vec3 lu_k_fx_hist(const struct lu_k_ctx *c, int cell, int part) {
    return lu_fx_read(c->hist + (size_t)cell * LU_K_FX_CELL_FLOATS + 4 * part);
}
static inline lu_vec3 lu_k_fx_int(const struct lu_k_ctx *c, int node, int part) {
    return lu_fx_read(c->integ + (size_t)node * LU_K_FX_CELL_FLOATS + 4 * part);
}
static inline void lu_k_fx_int_store(const struct lu_k_ctx *c, int node, lu_vec3 L, lu_vec3 tau) {
    float *p = c->integ + (size_t)node * LU_K_FX_CELL_FLOATS;
    p[0] = L.x, p[1] = L.y, p[2] = L.z, p[3] = 0.0f;
    p[4] = tau.x, p[5] = tau.y, p[6] = tau.z, p[7] = 0.0f;
}

#include "methods/froxel/lu_froxel.h"

_Static_assert(LU_MR_HIT_FLOATS == LU_K_RM_HIT_FLOATS, "camera hit layout");

enum { P_NX, P_NY, P_NZ, P_NEAR, P_JITTER, P_REPROJECT, P_BLEND, P_CULL, P_SHADOW_RES, P_T_CUT, P_COUNT };

static const lu_param_desc k_params[P_COUNT] = {
    [P_NX] = {"nx", LU_PARAM_INT, 160, 1, 4096, NULL, "grid columns across the image"},
    [P_NY] = {"ny", LU_PARAM_INT, 90, 1, 4096, NULL, "grid rows down the image"},
    [P_NZ] = {"nz", LU_PARAM_INT, 64, 1, LU_K_FX_MAX_NZ, NULL,
              "depth slices between the media's nearest and farthest points, exponentially spaced"},
    [P_NEAR] = {"near", LU_PARAM_FLOAT, 0.05, 1e-4, 1e4, NULL,
                "slices are uniform in log(t - t_lo + n0), n0 = max(t_lo, near * (t_hi - t_lo)): small is "
                "strongly exponential, large is uniform; t_lo, t_hi: the media's nearest and farthest distance"},
    [P_JITTER] = {"jitter", LU_PARAM_BOOL, 1, 0, 1, NULL,
                  "move each frame's samples within their slices (golden-ratio sequence; the first frame "
                  "samples slice centres)"},
    [P_REPROJECT] = {"reproject", LU_PARAM_BOOL, 1, 0, 1, NULL,
                     "blend each cell with the previous frame's lit volume at the same world point"},
    [P_BLEND] = {"blend", LU_PARAM_FLOAT, 0.9, 0, 0.99, NULL,
                 "weight of the previous frame in the reprojection blend"},
    [P_CULL] = {"cull", LU_PARAM_BOOL, 1, 0, 1, NULL,
                "leave unlit the cells beyond the farthest opaque hit of the pixels that read their column (the "
                "image is the same; culled cells give no history)"},
    [P_SHADOW_RES] = {"shadow_res", LU_PARAM_INT, 512, 16, 4096, NULL,
                      "shadow map resolution per light view (opaque objects only; media use exact optical depth)"},
    [P_T_CUT] = LU_VIEW_MARCH_T_CUT_PARAM,
};

typedef struct fx_state {
    lu_backend backend;
    int nx, ny, nz, jitter, reproject, cull, res;
    float near, blend, t_cut;
    lu_media_rays mr;
    float eps;
    lu_view_march_frame frame;
    const lu_scene *scene;
    struct lu_k_ctx kctx;
    lu_image *out;
    /* the grid: per column its reach then its spans (camera, geometry), lit
     * volumes (ping-pong), integrated volume */
    float *cspans, *lit[2], *integ;
    bool cspans_valid, volume_valid;
    int cur;                      /* lit[cur] is this frame's */
    unsigned frames;              /* frames lit, for the jitter sequence */
    lu_fx_frame fx;
    lu_froxel_gpu *gpu;
} fx_state;

static void fx_destroy(void *state) {
    fx_state *st = state;
    if (!st) return;
    lu_froxel_gpu_destroy(st->gpu);
    lu_media_rays_free(&st->mr);
    lu_free(st->cspans);
    lu_free(st->lit[0]);
    lu_free(st->lit[1]);
    lu_free(st->integ);
    lu_free(st);
}

static lu_result fx_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                            lu_error *err) {
    fx_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "froxel: out of memory");
    st->backend = backend;
    st->nx = (int)params[P_NX];
    st->ny = (int)params[P_NY];
    st->nz = (int)params[P_NZ];
    st->near = (float)params[P_NEAR];
    st->jitter = (int)params[P_JITTER];
    st->reproject = (int)params[P_REPROJECT];
    st->blend = (float)params[P_BLEND];
    st->cull = (int)params[P_CULL];
    st->res = (int)params[P_SHADOW_RES];
    st->t_cut = (float)params[P_T_CUT];
    st->eps = lu_scene_ray_epsilon(scene);
    lu_result r = LU_OK;
    size_t cells = (size_t)st->nx * st->ny * st->nz;
    if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "froxel: %d media (at most %d)", scene->medium_count, LU_K_RM_MAX_MEDIA);
    else if (cells > ((size_t)1 << 26))
        r = lu_fail(err, LU_ERR_RANGE, "froxel: a %dx%dx%d grid has %zu cells (at most %d: nx*ny*nz)", st->nx, st->ny,
                    st->nz, cells, 1 << 26);
    if (r == LU_OK) {
        size_t columns = (size_t)st->nx * st->ny;
        st->cspans = lu_malloc(columns * (1 + (size_t)scene->medium_count * 2) * sizeof(float));
        /* The cell grids live where the cells are lit: on the GPU, only there. */
        bool cpu = backend == LU_BACKEND_CPU;
        for (int b = 0; b < 2 && cpu; b++) st->lit[b] = lu_calloc(cells * LU_K_FX_CELL_FLOATS, sizeof(float));
        if (cpu) st->integ = lu_calloc((cells + columns) * LU_K_FX_CELL_FLOATS, sizeof(float));
        if (!st->cspans || (cpu && (!st->lit[0] || !st->lit[1] || !st->integ)))
            r = lu_fail(err, LU_ERR_NOMEM, "froxel: out of memory for a %dx%dx%d grid", st->nx, st->ny, st->nz);
    }
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, st->res, false, err);
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_froxel_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        fx_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

/* The grid of this frame: slices from the media boxes' nearest to their
 * farthest point seen from the camera. */
static lu_k_fx_grid fx_grid(const fx_state *st, const lu_frame *frame, float u) {
    const lu_scene *scene = frame->scene;
    lu_vec3 o = scene->camera.position;
    float t_lo = LU_K_FAR, t_hi = 0.0f;
    for (int m = 0; m < frame->rec->medium_count; m++) {
        const lu_k_medium *md = &frame->rec->media[m];
        lu_vec3 lo = md->bounds_lo, hi = md->bounds_hi;
        lu_vec3 q = lu_v3(fmaxf(fmaxf(lo.x - o.x, 0.0f), o.x - hi.x), fmaxf(fmaxf(lo.y - o.y, 0.0f), o.y - hi.y),
                          fmaxf(fmaxf(lo.z - o.z, 0.0f), o.z - hi.z));
        t_lo = fminf(t_lo, lu_v3_len(q));
        lu_vec3 f = lu_v3(fmaxf(fabsf(lo.x - o.x), fabsf(hi.x - o.x)), fmaxf(fabsf(lo.y - o.y), fabsf(hi.y - o.y)),
                          fmaxf(fabsf(lo.z - o.z), fabsf(hi.z - o.z)));
        t_hi = fmaxf(t_hi, lu_v3_len(f));
    }
    if (!(t_hi > t_lo)) t_lo = 0.0f, t_hi = 1.0f;   /* no media: an empty grid */
    float depth = fmaxf(t_hi - t_lo, 1e-6f * fmaxf(t_hi, 1.0f));
    float n0 = fmaxf(t_lo, st->near * depth);
    lu_k_fx_grid G;
    G.cam = frame->rec->cam;
    G.origin = o;
    G.t_lo = t_lo;
    G.n0 = n0;
    G.log_r = logf((depth + n0) / n0);
    G.u = u;
    G.nx = st->nx, G.ny = st->ny, G.nz = st->nz;
    G.width = scene->camera.width, G.height = scene->camera.height;
    return G;
}

static void column_spans(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    fx_state *st = ctx;
    int nm = st->mr.medium_count;
    for (int64_t c = begin; c < end; c++) {
        lu_vec3 d = lu_k_fx_column_dir(st->fx.grid, (int)(c % st->nx), (int)(c / st->nx));
        lu_media_ray_spans(&st->mr, st->fx.grid.origin, d, LU_K_FAR,
                           st->cspans + (size_t)st->nx * st->ny + (size_t)c * nm * 2, NULL);
    }
}

static void light_cells(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    fx_state *st = ctx;
    lu_k_rm_params P = lu_view_march_frame_params(&st->frame);
    const lu_fx_frame *fx = &st->fx;
    float *lit = st->lit[st->cur];
    int per_slice = st->nx * st->ny;
    for (int64_t c = begin; c < end; c++) {
        int k = (int)(c / per_slice), ij = (int)(c % per_slice);
        lu_vec3 S, sig;
        float lit_flag = lu_k_fx_light(&st->kctx, P, fx->grid, ij % st->nx, ij / st->nx, k, fx->history, fx->prev,
                                       fx->blend, fx->cull, &S, &sig);
        float *p = lit + (size_t)c * LU_K_FX_CELL_FLOATS;
        p[0] = S.x, p[1] = S.y, p[2] = S.z, p[3] = lit_flag;
        p[4] = sig.x, p[5] = sig.y, p[6] = sig.z, p[7] = 0.0f;
    }
}

static void integrate_columns(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    fx_state *st = ctx;
    for (int64_t c = begin; c < end; c++) lu_k_fx_integrate(&st->kctx, st->fx.grid, (int)(c % st->nx), (int)(c / st->nx));
}

static void render_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    fx_state *st = ctx;
    lu_k_rm_params P = lu_view_march_frame_params(&st->frame);
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < st->fx.grid.width; x++) {
            lu_vec3 L = lu_k_fx_pixel(&st->kctx, P, st->fx.grid, x, (int)y);
            float *o = lu_image_px(st->out, x, (int)y);
            o[0] = L.x, o[1] = L.y, o[2] = L.z;
        }
}

/* Each column's reach: the farthest ray end (opaque hit, or LU_K_FAR) of
 * the pixels whose lookup reads it (lu_k_fx_pixel_columns). */
static void column_reach(fx_state *st) {
    const lu_k_fx_grid *G = &st->fx.grid;
    float *reach = st->cspans;
    for (int c = 0; c < G->nx * G->ny; c++) reach[c] = 0.0f;
    for (int y = 0; y < G->height; y++)
        for (int x = 0; x < G->width; x++) {
            float t = st->mr.hits[((size_t)y * G->width + x) * LU_MR_HIT_FLOATS + 3];
            float t_end = t >= 0.0f ? t : LU_K_FAR;
            int i0, i1, j0, j1;
            float ax, ay;
            lu_k_fx_pixel_columns(*G, x, y, &i0, &i1, &j0, &j1, &ax, &ay);
            int cols[4] = {j0 * G->nx + i0, j0 * G->nx + i1, j1 * G->nx + i0, j1 * G->nx + i1};
            for (int q = 0; q < 4; q++) reach[cols[q]] = fmaxf(reach[cols[q]], t_end);
        }
}

/* The frame's jitter: slice centres first, then the golden-ratio sequence
 * (each new offset falls in the largest gap the earlier ones left). */
static float fx_jitter(unsigned n) {
    double u = 0.5 + 0.6180339887498949 * (double)n;
    return (float)(u - floor(u));
}

static lu_result fx_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    fx_state *st = state;
    if (scene->medium_count != st->mr.medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "froxel: the scene's media changed since prepare");
    st->scene = scene;
    st->out = out;
    const lu_k_light *kl = frame->rec->lights;
    int nl = frame->rec->light_count;
    lu_k_camera cam = frame->rec->cam;
    lu_result r = lu_media_rays_view_march(&st->mr, frame, cam, kl, nl, st->eps, err);
    if (r != LU_OK) return r;
    lu_view_march_frame *f = &st->frame;
    lu_view_march_frame_fill(f, scene, &st->mr, 1, st->eps, 0, nl, st->t_cut);

    /* The volume is a function of the camera, lights, media and geometry;
     * jitter and reprojection make every frame a new one. */
    bool relight = st->jitter || st->reproject || !st->volume_valid ||
                   (frame->changed & (LU_CHANGE_CAMERA | LU_CHANGE_LIGHTS | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY));
    lu_fx_frame *fx = &st->fx;
    if (relight) {
        lu_k_fx_grid prev = fx->grid;
        fx->history = st->reproject && st->volume_valid;
        fx->prev = prev;
        fx->blend = st->blend;
        fx->cull = st->cull;
        fx->grid = fx_grid(st, frame, st->jitter ? fx_jitter(st->frames) : 0.5f);
        st->frames++;
        st->cur ^= 1;
    }
    bool spans_stale = lu_frame_stale(frame, st->cspans_valid, LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY);
    if (spans_stale) {
        st->cspans_valid = false;
        lu_parallel_for((int64_t)st->nx * st->ny, 64, column_spans, st, NULL);
        column_reach(st);
        st->cspans_valid = true;
        fx->spans_version++;
    }
    if (st->backend == LU_BACKEND_GPU) {
        r = lu_froxel_gpu_render(st->gpu, scene, frame->rec, f, fx, st->cspans, relight, out, err);
        st->volume_valid = r == LU_OK;
        return r;
    }
    st->kctx = (struct lu_k_ctx){LU_K_CTX_SCENE(scene, frame->rec), f, st->mr.views, st->cspans,
                                 st->cspans + (size_t)st->nx * st->ny, st->lit[st->cur], st->lit[st->cur ^ 1], st->integ};
    if (relight) {
        lu_parallel_for((int64_t)st->nx * st->ny * st->nz, 256, light_cells, st, NULL);
        lu_parallel_for((int64_t)st->nx * st->ny, 16, integrate_columns, st, NULL);
        lu_frame_rebuilt(frame, "froxel.volume");
        st->volume_valid = true;
    }
    lu_frame_for_rows(frame, 1, render_rows, st, NULL);
    return LU_OK;
}

const lu_method lu_method_froxel = {
    .name = "froxel",
    .summary = "volumetric fog on a camera-frustum grid (Wronski 2014, Hillaire 2015): cells lit once per frame, "
               "integrated front to back, looked up per pixel; jittered slices with temporal reprojection "
               "(CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .prepare = fx_prepare,
    .render = fx_render,
    .destroy = fx_destroy,
};
