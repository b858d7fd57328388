/* afm — attenuation function maps (Delalandre et al. 2010; docs/afm.md)
 * on the CPU and the GPU from one kernel (methods/afm/lu_afm.h).
 *
 * Per frame and per light: light views framing the media's box (lightview.h:
 * perspective for spot lights, six cube faces for point lights, orthographic
 * for directional lights); per texel the light ray's K_in/K_out in the media
 * (boxes clipped to boundary meshes, Fresnel at boundary crossings) and its
 * transmittance sampled at `samples` points and projected onto `coefs` DCT
 * coefficients per colour channel; a classic shadow map of the opaque
 * objects (media_ray.h). The view rays then march `steps` steps across the
 * media (raymarch's march, lu_view_march.h) and read the light's reduced
 * intensity from the maps instead of marching towards the light.
 *
 * What is rebuilt when (the frame stage, methods/frame.h): camera hits and
 * spans with the camera; shadow maps, light views and light-ray spans with
 * the lights; the attenuation maps with the lights and the media. A change
 * of some lights rebuilds only their views, spans and maps (each light's
 * views are a contiguous run of the map, view_table), so a camera orbit
 * marches the views against kept maps. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "methods/afm/afm.h"
#include "methods/common/gpu_scene.h"
#include "methods/common/lightview.h"
#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/raymarch/raymarch.h"
#include "methods/common/kernel_ctx.h"

/* ---- kernel context: the hooks of lu_afm.h and lu_view_march.h on the CPU ---- */
struct lu_k_ctx {
    LU_K_CTX_VIEW_MARCH_MEMBERS
    /* afm */
    const lu_afm_map *map;
    float *records;               /* written by the build, read by lookups */
    int res, coefs, samples, channels, stride;   /* lu_k_afm_params (defined by the kernel below) */
    const float *cam_normals;
    const float *surfaces;
    const float *surface_vis;
};

#include "methods/common/view_march_hooks.h"

static inline float lu_k_afm_lspan(const struct lu_k_ctx *c, int texel, int m, int k) {
    /* unbounded: the whole ray, no crossing (2 = LU_K_AFM_NO_CROSSING) */
    if (!c->map->bounded) return k == 1 ? LU_K_FAR : (k == 0 ? 0.0f : 2.0f);
    return c->map->lspans[((size_t)texel * c->nm + m) * LU_AFM_LSPAN_FLOATS + k];
}
static inline void lu_k_afm_store(const struct lu_k_ctx *c, int texel, int i, float v) {
    c->records[(size_t)texel * c->stride + i] = v;
}
static inline float lu_k_afm_fetch(const struct lu_k_ctx *c, int base, int i) { return c->records[(size_t)base + i]; }
static inline int lu_k_afm_view_first(const struct lu_k_ctx *c, int l) { return c->map->view_table[2 * l]; }
static inline int lu_k_afm_view_count(const struct lu_k_ctx *c, int l) { return c->map->view_table[2 * l + 1]; }
static inline lu_k_lightview lu_k_afm_view(const struct lu_k_ctx *c, int v) { return c->map->views[v]; }
static inline float lu_k_afm_cam_normal(const struct lu_k_ctx *c, int pixel, int m, int k) {
    return c->cam_normals[((size_t)pixel * c->nm + m) * LU_MR_NORMAL_FLOATS + k];
}
static inline float lu_k_afm_surface_vis(const struct lu_k_ctx *c, int pixel, int l) {
    return c->surface_vis[(size_t)pixel * c->nl + l];
}
static inline float lu_k_afm_surface(const struct lu_k_ctx *c, int m, int k) {
    return c->surfaces[m * LU_AFM_SURFACE_FLOATS + k];
}

static inline int lu_k_afm_param(const struct lu_k_ctx *c, int i) {
    return i == 0 ? c->res : i == 1 ? c->coefs : i == 2 ? c->samples : c->channels;
}

#include "methods/afm/lu_afm.h"

static void ctx_set_map(struct lu_k_ctx *c, const lu_afm_map *map) {
    c->map = map;
    c->records = map->records;
    c->res = map->res;
    c->coefs = map->coefs;
    c->samples = map->samples;
    c->channels = map->channels;
    c->stride = LU_K_AFM_HEADER + map->coefs * map->channels;
}

/* ---- the map (shared with the GPU pass and the tests) ---- */

static lu_k_afm_params map_params(const lu_afm_map *map) {
    lu_k_afm_params P;
    P.res = map->res;
    P.coefs = map->coefs;
    P.samples = map->samples;
    P.channels = map->channels;
    return P;
}

size_t lu_afm_map_texels(const lu_afm_map *map) { return (size_t)map->view_count * map->res * map->res; }
int lu_afm_map_stride(const lu_afm_map *map) { return lu_k_afm_stride(map_params(map)); }

/* 1 when every medium's sigma_t is grey, else 3. */
static int map_channels(const lu_scene *scene) {
    for (int m = 0; m < scene->medium_count; m++) {
        lu_vec3 st = lu_v3_add(scene->media[m].sigma_a, scene->media[m].sigma_s);
        if (st.x != st.y || st.y != st.z) return 3;
    }
    return 1;
}

void lu_afm_map_init(lu_afm_map *map, const lu_scene *scene, int res, int coefs, int samples) {
    memset(map, 0, sizeof *map);
    map->res = res;
    map->coefs = coefs;
    map->samples = samples;
    map->nm = scene->medium_count;
    map->channels = map_channels(scene);
    for (int m = 0; m < scene->medium_count; m++)
        if (scene->media[m].has_boundary) map->bounded = true;
}

void lu_afm_map_free(lu_afm_map *map) {
    lu_free(map->views);
    lu_free(map->views_packed);
    lu_free(map->view_table);
    lu_free(map->lspans);
    lu_free(map->records);
    memset(map, 0, sizeof *map);
}

typedef struct lspan_job {
    lu_afm_map *map;
    const lu_media_rays *mr;
    int view0;                    /* rows start at this view's first row */
} lspan_job;

/* Light-ray spans of the bounded media, one row of one view per job index. */
static void lspan_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lspan_job *j = ctx;
    lu_afm_map *map = j->map;
    int res = map->res, nm = map->nm;
    float sp[2 * LU_K_RM_MAX_MEDIA], nrm[LU_MR_NORMAL_FLOATS * LU_K_RM_MAX_MEDIA];
    for (int64_t row = begin + (int64_t)j->view0 * res; row < end + (int64_t)j->view0 * res; row++) {
        int v = (int)(row / res), y = (int)(row % res);
        for (int x = 0; x < res; x++) {
            lu_k_lightray r = lu_k_lightview_ray(map->views[v], ((float)x + 0.5f) / (float)res, ((float)y + 0.5f) / (float)res);
            lu_media_ray_spans(j->mr, r.origin, r.dir, LU_K_FAR, sp, nrm);
            float *out = map->lspans + ((size_t)row * res + x) * nm * LU_AFM_LSPAN_FLOATS;
            for (int m = 0; m < nm; m++) {
                lu_vec3 n_in, n_out;
                memcpy(&n_in, nrm + m * LU_MR_NORMAL_FLOATS, 12);
                memcpy(&n_out, nrm + m * LU_MR_NORMAL_FLOATS + 3, 12);
                bool has_in = lu_v3_dot(n_in, n_in) > 0.0f, has_out = lu_v3_dot(n_out, n_out) > 0.0f;
                out[4 * m] = sp[2 * m];
                out[4 * m + 1] = sp[2 * m + 1];
                /* The cosines, not the Fresnel factors: eta is a medium
                 * value, so the build takes F_t and these stay geometry. */
                out[4 * m + 2] = has_in ? lu_v3_dot(n_in, r.dir) : LU_K_AFM_NO_CROSSING;
                out[4 * m + 3] = has_out ? lu_v3_dot(n_out, r.dir) : LU_K_AFM_NO_CROSSING;
            }
        }
    }
}

lu_result lu_afm_map_views(lu_afm_map *map, const lu_frame *f, const lu_media_rays *mr, int nl, lu_error *err) {
    const lu_scene *scene = f->scene;
    uint64_t maps = 0;
    if (!map->maps_valid || (f->changed & (LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY))) maps = ~0ull;
    if ((f->changed & LU_CHANGE_MEDIA) && map_channels(scene) != map->channels) {
        map->channels = map_channels(scene);
        maps = ~0ull;
    }
    uint64_t views = ~0ull;
    if (map->views_valid && nl == map->nl && !(f->changed & LU_CHANGE_GEOMETRY)) views = lu_frame_kernel_lights_changed(f);
    if (views) {
        map->views_valid = false;
        map->maps_valid = false;
        /* Every light's views are remade (a few multiplies each): a light
         * that did not change gets the views it had. */
        int *old_table = map->view_table, old_count = map->view_count;
        map->view_table = NULL;
        /* Cube faces get a guard band of 1.5 texels: a point near a face edge is
         * then interpolated from its own face's texels, so either face answers
         * alike where rounding could pick one or the other. */
        lu_result r = lu_lightviews_for_scene(scene, lu_scene_media_bounds(scene), 1.0f + 3.0f / (float)map->res,
                                              &map->views, &map->views_packed, &map->view_table, &map->view_count, err);
        /* A light that now has another number of views moves the others'. */
        if (r != LU_OK || !old_table || nl != map->nl || old_count != map->view_count ||
            memcmp(old_table, map->view_table, (size_t)nl * 2 * sizeof *old_table) != 0)
            views = ~0ull;
        lu_free(old_table);
        if (r != LU_OK) return r;
        size_t texels = lu_afm_map_texels(map);
        if (map->bounded) {
            size_t ls = (texels ? texels : 1u) * (size_t)map->nm * LU_AFM_LSPAN_FLOATS;
            if (ls > map->lspans_cap) {
                lu_free(map->lspans);
                map->lspans = lu_malloc(ls * sizeof(float));
                map->lspans_cap = map->lspans ? ls : 0;
                if (!map->lspans) return lu_fail(err, LU_ERR_NOMEM, "afm: out of memory for light-ray spans");
                views = ~0ull;    /* a new buffer keeps nothing */
            }
            for (int l = 0; l < nl; l++) {
                if (!lu_afm_has_light(views, l)) continue;
                lspan_job j = {map, mr, map->view_table[2 * l]};
                lu_parallel_for((int64_t)map->view_table[2 * l + 1] * map->res, 4, lspan_rows, &j, NULL);
            }
        }
        map->nl = nl;
        map->views_valid = true;
        map->version++;
        for (int l = 0; l < nl; l++)
            if (lu_afm_has_light(views, l)) lu_frame_rebuilt(f, "afm.views");
        maps |= views;
    }
    if (maps) map->maps_valid = false;
    map->rebuild = maps;
    return LU_OK;
}

void lu_afm_map_built(lu_afm_map *map, const lu_frame *f) {
    for (int l = 0; l < map->nl; l++)
        if (lu_afm_has_light(map->rebuild, l)) lu_frame_rebuilt(f, "afm.maps");
    map->rebuild = 0;
    map->maps_valid = true;
}

typedef struct build_job {
    struct lu_k_ctx ctx;
    int view0;                    /* rows start at this view's first row */
} build_job;

static void build_rows(void *vctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    build_job *j = vctx;
    const lu_afm_map *map = j->ctx.map;
    int res = map->res;
    for (int64_t row = begin + (int64_t)j->view0 * res; row < end + (int64_t)j->view0 * res; row++) {
        int v = (int)(row / res), y = (int)(row % res);
        for (int x = 0; x < res; x++)
            lu_k_afm_build_texel(&j->ctx, lu_k_afm_params_get(&j->ctx), map->views[v], (int)(row * res + x), x, y);
    }
}

int lu_afm_view_count(const lu_scene *scene) {
    int n = 0;
    for (int l = 0; l < scene->light_count; l++)
        n += scene->lights[l].type == LU_LIGHT_POINT ? 6 : scene->lights[l].type == LU_LIGHT_ENVIRONMENT ? 0 : 1;
    return n;
}

lu_result lu_afm_map_build_cpu(lu_afm_map *map, const lu_scene *scene, const lu_k_medium *km,
                               const lu_view_march_frame *f, lu_error *err) {
    size_t texels = lu_afm_map_texels(map);
    size_t need = (texels ? texels : 1u) * (size_t)lu_afm_map_stride(map);
    if (need > map->records_cap) {
        lu_free(map->records);
        map->records = lu_malloc(need * sizeof(float));
        map->records_cap = map->records ? need : 0;
        if (!map->records) return lu_fail(err, LU_ERR_NOMEM, "afm: out of memory for %zu map texels", texels);
        /* nothing is kept in a new buffer (the stage rebuilds everything
         * when the layout or the stride changed, so this is a first build) */
        map->rebuild = ~0ull;
    }
    build_job j;
    memset(&j, 0, sizeof j);
    j.ctx.media = scene->media;
    j.ctx.km = km;
    j.ctx.nm = scene->medium_count;
    j.ctx.f = f;
    ctx_set_map(&j.ctx, map);
    for (int l = 0; l < map->nl; l++) {
        if (!lu_afm_has_light(map->rebuild, l)) continue;
        j.view0 = map->view_table[2 * l];
        lu_parallel_for((int64_t)map->view_table[2 * l + 1] * map->res, 1, build_rows, &j, NULL);
    }
    return LU_OK;
}

lu_vec3 lu_afm_map_transmittance(const lu_afm_map *map, int l, lu_vec3 x) {
    struct lu_k_ctx c;
    memset(&c, 0, sizeof c);
    ctx_set_map(&c, map);
    c.nm = map->nm;
    return lu_k_afm_transmittance(&c, lu_k_afm_params_get(&c), l, x);
}

/* ---- the method ---- */

enum { P_COEFS, P_SAMPLES, P_MAP_RES, P_STEPS, P_JITTER, P_SHADOW_RES, P_T_CUT, P_MS, P_COUNT = P_MS + LU_VIEW_MARCH_MS_PARAM_COUNT };

static const lu_param_desc k_params[P_COUNT] = {
    [P_COEFS] = {"coefs", LU_PARAM_INT, 16, 1, LU_K_AFM_MAX_COEFS, NULL,
                 "DCT coefficients per texel and colour channel (the seed uses 16)"},
    [P_SAMPLES] = {"samples", LU_PARAM_INT, 64, 2, LU_K_AFM_MAX_SAMPLES, NULL,
                   "transmittance samples K_j per texel along K_in..K_out, projected onto the coefficients"},
    [P_MAP_RES] = {"map_res", LU_PARAM_INT, 0, 0, 4096, NULL,
                   "attenuation map resolution per light view (0: 256 on the CPU, 512 on the GPU)"},
    [P_STEPS] = {"steps", LU_PARAM_INT, 250, 4, 16384, NULL,
                 "view-ray march steps across the diagonal of the media's box (the seed uses 500: afm.preset=paper)"},
    [P_JITTER] = {"jitter", LU_PARAM_BOOL, 0, 0, 1, NULL,
                  "shift each pixel's samples by a per-pixel hash within a step (noise instead of banding)"},
    [P_SHADOW_RES] = {"shadow_res", LU_PARAM_INT, 512, 16, 4096, NULL,
                      "shadow map resolution per light view (opaque objects)"},
    [P_T_CUT] = LU_VIEW_MARCH_T_CUT_PARAM,
    LU_VIEW_MARCH_MS_PARAMS(P_MS)
};

typedef struct afm_state {
    lu_backend backend;
    int steps, jitter;
    float t_cut;
    lu_k_ms ms;
    lu_media_rays mr;
    lu_afm_map map;
    float *surfaces;
    unsigned surfaces_version;      /* changes whenever the media (their boundary surfaces) changed */
    float eps;
    lu_view_march_frame frame;
    struct lu_k_ctx kctx;
    lu_k_camera cam;
    lu_afm_gpu *gpu;
} afm_state;

static void afm_destroy(void *state) {
    afm_state *st = state;
    if (!st) return;
    lu_afm_gpu_destroy(st->gpu);
    lu_media_rays_free(&st->mr);
    lu_afm_map_free(&st->map);
    lu_free(st->surfaces);
    lu_free(st);
}

static lu_result afm_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                             lu_error *err) {
    afm_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "afm: out of memory");
    st->backend = backend;
    st->steps = (int)params[P_STEPS];
    st->jitter = (int)params[P_JITTER];
    st->t_cut = (float)params[P_T_CUT];
    st->ms = lu_view_march_ms(params + P_MS);
    int res = (int)params[P_MAP_RES];
    if (res == 0) res = backend == LU_BACKEND_GPU ? 512 : 256;
    lu_result r = LU_OK;
    if (res < 4) r = lu_fail(err, LU_ERR_RANGE, "afm: map_res = %d is below 4 (0 picks the default)", res);
    if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "afm: %d media (at most %d)", scene->medium_count, LU_K_RM_MAX_MEDIA);
    /* A translucent object is a dense bounded medium (mean free path ~1/100
     * of the object): its light-ray transmittance falls to nothing in a
     * sliver of K_in..K_out, far beyond what tens of cosine terms can hold,
     * and its look is multiple scattering anyway (bssrdf, pathtrace). */
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++)
        if (scene->media[m].from_object >= 0)
            r = lu_fail(err, LU_ERR_UNSUPPORTED,
                        "afm: object %d is a translucent solid; attenuation function maps render participating media "
                        "only (use bssrdf or pathtrace for translucent objects)",
                        scene->media[m].from_object);
    lu_afm_map_init(&st->map, scene, res, (int)params[P_COEFS], (int)params[P_SAMPLES]);
    st->eps = lu_scene_ray_epsilon(scene);
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, (int)params[P_SHADOW_RES], true, err);
    size_t nm = scene->medium_count ? (size_t)scene->medium_count : 1u;
    st->surfaces = lu_calloc(nm * LU_AFM_SURFACE_FLOATS, sizeof(float));
    if (!st->surfaces && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "afm: out of memory");
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_afm_gpu_create(scene, &st->gpu, err);
    if (r == LU_OK && backend == LU_BACKEND_GPU) {
        /* The records of every view live in one storage buffer: halve the
         * default resolution until they fit the device's limit. */
        bool loop_cap = false;
        size_t max = lu_afm_gpu_limits(st->gpu, &loop_cap), views = (size_t)lu_afm_view_count(scene);
        size_t stride = (size_t)lu_afm_map_stride(&st->map) * sizeof(float);
        while (params[P_MAP_RES] == 0 && st->map.res > 16 && views * st->map.res * st->map.res * stride > max)
            st->map.res /= 2;
        size_t bytes = views * st->map.res * st->map.res * stride;
        if (bytes > max)
            r = lu_fail(err, LU_ERR_LIMIT,
                        "afm: maps of %zu views at map_res = %d need %zu bytes, over the GPU's %zu-byte storage buffer "
                        "limit (lower afm.map_res or afm.coefs)",
                        views, st->map.res, bytes, max);
        /* Loop iterations of one invocation, generously counted: the march
         * (steps x lights x (series in fours + PCF and medium loops)) and
         * the build (samples x (series in fours + medium loops) + DDA). */
        int quads = (st->map.coefs + 2) / 4 + 1, nlights = lu_afm_view_count(scene) ? scene->light_count : 0;
        double march = (double)st->steps *
                       (1 + nlights * (4 * quads + 10 + (2 + st->ms.octaves + 1) * scene->medium_count));
        double build = (double)st->map.samples * (quads + 2 + 2 * scene->medium_count) + 1024.0;
        if (r == LU_OK && loop_cap && (march > 65000 || build > 65000))
            r = lu_fail(err, LU_ERR_LIMIT,
                        "afm: on llvmpipe a shader invocation stops after 65535 loop iterations; %s needs about %.0f "
                        "(lower afm.%s or afm.coefs, or use the CPU backend)",
                        march > 65000 ? "the view march" : "the map build", march > 65000 ? march : build,
                        march > 65000 ? "steps" : "samples");
    }
    if (r != LU_OK) {
        afm_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

static lu_vec3 afm_pixel(void *state, lu_k_rm_params P, int pixel, lu_vec3 o, lu_vec3 d, float u) {
    afm_state *st = state;
    return lu_k_afm_radiance(&st->kctx, lu_k_afm_params_get(&st->kctx), P, pixel, o, d, u);
}

static lu_result afm_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    afm_state *st = state;
    if (scene->medium_count != st->mr.medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "afm: the scene's media changed since prepare");
    st->cam = frame->rec->cam;
    if (frame->changed & LU_CHANGE_MEDIA) st->surfaces_version++;
    for (int m = 0; m < scene->medium_count; m++) {
        const lu_material *s = &scene->media[m].surface;
        float *sf = st->surfaces + m * LU_AFM_SURFACE_FLOATS;
        memcpy(sf, &s->albedo, 12);
        sf[3] = s->shininess;
        memcpy(sf + 4, &s->specular, 12);
        sf[7] = 0.0f;
    }
    const lu_k_light *kl = frame->rec->lights;
    int nl = frame->rec->light_count;
    lu_result r = lu_media_rays_view_march(&st->mr, frame, st->cam, kl, nl, st->eps, err);
    if (r == LU_OK) r = lu_afm_map_views(&st->map, frame, &st->mr, nl, err);
    if (r != LU_OK) return r;

    lu_view_march_frame *f = &st->frame;
    lu_view_march_frame_fill(f, scene, &st->mr, st->steps, st->eps, st->jitter, nl, st->t_cut);
    f->ms = st->ms;
    if (st->backend == LU_BACKEND_GPU) {
        lu_afm_gpu_frame g = {frame->rec, &st->mr, &st->map, st->surfaces, st->surfaces_version, scene->background, f->step,
                              f->eps, st->jitter, st->mr.shadow_res, nl, st->t_cut, st->ms};
        r = lu_afm_gpu_render(st->gpu, scene, &g, out, err);
        if (r == LU_OK) lu_afm_map_built(&st->map, frame);
        return r;
    }
    r = lu_afm_map_build_cpu(&st->map, scene, frame->rec->media, f, err);
    if (r != LU_OK) return r;
    lu_afm_map_built(&st->map, frame);
    memset(&st->kctx, 0, sizeof st->kctx);
    st->kctx.media = scene->media;
    st->kctx.km = frame->rec->media;
    st->kctx.nm = scene->medium_count;
    st->kctx.kl = kl;
    st->kctx.nl = nl;
    st->kctx.f = f;
    st->kctx.views = st->mr.views;
    ctx_set_map(&st->kctx, &st->map);
    st->kctx.cam_normals = st->mr.normals;
    st->kctx.surfaces = st->surfaces;
    st->kctx.surface_vis = st->mr.surface_vis;
    lu_view_march_render_rows(frame, f, st->cam, afm_pixel, st, out);
    return LU_OK;
}

/* Delalandre et al.'s set-up (Fig. 1: 1280x720 on a GTX 280). The defaults
 * above are the cheapest swept settings that keep every volume scene's error
 * at 640x360 within the gate (docs/performance.md, "Error-budgeted defaults"). */
static const lu_preset k_presets[] = {
    {"paper", "map_res=1024 coefs=16 steps=500", "the seed paper's settings: a 1024^2 map, 16 coefficients, 500 steps"},
};

const lu_method lu_method_afm = {
    .name = "afm",
    .summary = "attenuation function maps: DCT-compressed light transmittance per light texel, fixed-step view march (CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .presets = k_presets,
    .preset_count = 1,
    .prepare = afm_prepare,
    .render = afm_render,
    .destroy = afm_destroy,
};
