/* ddod — direction-dependent optical depth samples (Bernabei et al.) for
 * translucent bounded media, on the CPU and the GPU from one kernel
 * (methods/ddod/lu_ddod.h). Prepare runs (or loads from the cache) the
 * precomputation of ddod_precompute.c. Per frame the CPU builds what both
 * backends read: per pixel the medium span of the camera ray and the
 * surface term (the paper's Phong pass with its depth buffer, here by
 * Embree ray casts), and the samples' balls binned into screen tiles; when
 * the camera or a light moved, the traced table (each sample's exact
 * attenuation towards the camera and each light, lu_ddod_ray); then pass 1
 * (per sample) and pass 2 (per pixel) run on the chosen backend. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "methods/ddod/ddod.h"
#include "methods/common/gpu_scene.h"
#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/common/media_ray.h"
#include "methods/common/tile_bins.h"
#include "methods/common/kernel_ctx.h"
#include "methods/common/sh_env.h"

/* ---- kernel context: the hooks of lu_ddod.h on the CPU ---- */
struct lu_k_ctx {
    LU_K_CTX_SCENE_MEMBERS
    const float *samples, *sh, *radiance, *pixels, *env, *traced;
    const int *tile_start, *tile_list;
};

#include "methods/common/scene_hooks.h"

static inline float lu_k_ddod_sample_f(const struct lu_k_ctx *c, int i, int k) {
    return c->samples[(size_t)i * LU_K_DDOD_SAMPLE_FLOATS + k];
}
static inline float lu_k_ddod_coeff(const struct lu_k_ctx *c, int index) { return c->sh[index]; }
static inline lu_vec3 lu_k_ddod_radiance(const struct lu_k_ctx *c, int i) {
    const float *r = c->radiance + 4 * (size_t)i;
    return lu_v3(r[0], r[1], r[2]);
}
static inline float lu_k_ddod_pixel_f(const struct lu_k_ctx *c, int pixel, int k) {
    return c->pixels[(size_t)pixel * LU_K_DDOD_PIXEL_FLOATS + k];
}
static inline int lu_k_ddod_tile_start(const struct lu_k_ctx *c, int tile) { return c->tile_start[tile]; }
static inline int lu_k_ddod_tile_item(const struct lu_k_ctx *c, int k) { return c->tile_list[k]; }
static inline lu_vec3 lu_k_ddod_env_coeff(const struct lu_k_ctx *c, int k) {
    return lu_v3(c->env[3 * k], c->env[3 * k + 1], c->env[3 * k + 2]);
}
static inline lu_vec3 lu_k_ddod_traced(const struct lu_k_ctx *c, int k) {
    return lu_v3(c->traced[4 * k], c->traced[4 * k + 1], c->traced[4 * k + 2]);
}

#include "kernels/lu_camera.h"
#include "methods/ddod/lu_ddod.h"
#include "methods/common/lu_march.h"

enum {
    P_RES,
    P_DIRS,
    P_SAMPLES,
    P_BANDS,
    P_WIDTH,
    P_FIT,
    P_NORMALIZE,
    P_WINDOW,
    P_VIEW_PSI,
    P_LIGHT_PSI,
    P_CACHE,
    P_SEED,
    P_COUNT
};

static const lu_param_desc k_params[P_COUNT] = {
    [P_RES] = {"res", LU_PARAM_INT, 128, 8, 512, NULL,
               "precompute voxels along the longest side of each boundary's box (optical depth sweeps, divergence)"},
    [P_DIRS] = {"dirs", LU_PARAM_INT, 128, 8, 4096, NULL,
                "uniformly distributed directions of the optical depth (the paper's 32 / 128 / 512)"},
    [P_SAMPLES] = {"samples", LU_PARAM_INT, 50000, 64, 2000000, NULL,
                   "target number of Poisson-disk samples N_s (met within 5 %)"},
    [P_BANDS] = {"bands", LU_PARAM_INT, 5, 2, 8, NULL,
                 "SH bands per attenuation function: 3, 4, 5, 6, 7, 8 = 9, 16, 25, 36, 49, 64 coefficients"},
    [P_WIDTH] = {"width", LU_PARAM_FLOAT, 0.8, 0.2, 2.0, NULL,
                 "Gaussian standard deviation as a fraction of the sample's Poisson-disk radius"},
    [P_FIT] = {"fit", LU_PARAM_INT, 8, 0, 50, NULL,
               "partition-of-unity iterations on the Gaussians' amplitudes (0: each stands for its volume share, "
               "as in the paper)"},
    [P_NORMALIZE] = {"normalize", LU_PARAM_BOOL, 1, 0, 1, NULL,
                     "divide each pixel's sum by its Gaussians' line integrals times the ray length in the medium "
                     "(partition of unity; off = the paper's plain sum)"},
    [P_WINDOW] = {"window", LU_PARAM_CHOICE, 0, 0, 2, "none|hanning|lanczos",
                  "per-band SH window against ringing: none, Hanning, or Lanczos sigma factors"},
    [P_VIEW_PSI] = {"view_psi", LU_PARAM_CHOICE, 0, 0, 1, "traced|sh",
                    "attenuation towards the camera: traced per sample on the CPU when the camera moves (exact), or "
                    "sh = the paper's SH evaluation (smears the sharp falloff near flat faces)"},
    [P_LIGHT_PSI] = {"light_psi", LU_PARAM_CHOICE, 0, 0, 1, "traced|sh",
                     "attenuation towards point and directional lights: traced per sample on the CPU when a light "
                     "moves (exact), or sh = the paper's SH evaluation (smears sharp shadows of flat faces)"},
    [P_CACHE] = {"cache", LU_PARAM_BOOL, 1, 0, 1, NULL,
                 "load / store the precomputation in the cache folder (lu_host.cache_dir)"},
    [P_SEED] = {"seed", LU_PARAM_INT, 1, 0, 1000000, NULL, "seed of the Poisson-disk sampling"},
};

#define TILE 16

/* Products (frame.h) and what they are built from:
 *   ddod.set        the precomputation (media, geometry); prepare's counts as the first frame's
 *   ddod.view_psi   the traced table's view entries (camera position, media, geometry)
 *   ddod.light_psi  per light, its entries (the light's position or direction, media, geometry)
 *   ddod.env_sh     the environment lights' SH (the environment lights)
 *   ddod.pixels     per pixel: medium span and surface term (everything but nothing: still frames keep it)
 *   ddod.bins       the samples' screen tiles (camera, sample set)
 * passes 1 and 2 run every frame. */
typedef struct ddod_state {
    lu_backend backend;
    lu_ddod_params params;
    bool use_cache;
    int window;
    lu_ddod_set set;
    bool set_valid, set_from_prepare;
    uint64_t set_key;          /* lu_ddod_key of the scene prepare built the set for */
    unsigned set_version;      /* the GPU re-uploads samples and SH when it changes */
    float *sh;                 /* windowed copy of set.sh */
    int normalize;
    lu_media_rays mr;          /* opaque objects and boundary meshes (Embree) */
    int medium_count;
    float eps;
    const lu_k_medium *km;     /* the frame's records (frame.h) */
    const lu_k_light *kl;
    int nl;
    float *pixels, *radiance;
    size_t pixels_cap, samples_cap;
    bool pixels_valid, bins_valid;
    unsigned pixels_version, bins_version;
    lu_k_rect *rects;
    lu_tile_bins bins;
    float env[3 * LU_SH_MAX_COEFFS];
    int env_on, env_lights;
    const lu_scene *scene;
    lu_k_camera cam;
    struct lu_k_ctx kctx;
    lu_k_ddod_params P;
    lu_image *out;
    lu_ddod_stats stats;
    lu_ddod_gpu *gpu;
    /* traced table (LU_K_DDOD_TRACED_* in traced): per sample 1 + nl
     * entries of 4 floats, psi towards the camera at tab_cam, then psi^F
     * towards each light of tab_lights (methods/ddod/lu_ddod.h) */
    int traced;
    float *traced_tab;
    lu_k_light *tab_lights;
    bool *tab_retrace;         /* per light: retrace its entries this update */
    int tab_nl, tab_count;
    lu_vec3 tab_cam;
    bool tab_view_valid, tab_lights_valid;
    unsigned tab_version;
} ddod_state;

static void ddod_destroy(void *state) {
    ddod_state *st = state;
    if (!st) return;
    lu_ddod_gpu_destroy(st->gpu);
    lu_ddod_set_free(&st->set);
    lu_free(st->sh);
    lu_media_rays_free(&st->mr);
    lu_free(st->pixels);
    lu_free(st->radiance);
    lu_free(st->rects);
    lu_free(st->traced_tab);
    lu_free(st->tab_lights);
    lu_free(st->tab_retrace);
    lu_tile_bins_free(&st->bins);
    lu_free(st);
}

/* Per-band window weights (Sloan, "Stupid SH Tricks" §: windowing). */
static float window_weight(int kind, int l, int bands) {
    if (kind == 1) return 0.5f * (1.0f + cosf(LU_PI * (float)l / (float)bands));
    if (kind == 2) {
        if (l == 0) return 1.0f;
        float x = LU_PI * (float)l / (float)bands;
        return sinf(x) / x;
    }
    return 1.0f;
}

static lu_vec3 env_radiance(const void *user, lu_vec3 d) {
    const lu_light *l = user;
    return lu_env_lookup(&l->env, l->env_scale, d);
}

/* Environment lights projected onto the SH of the samples, by a midpoint rule
 * over the map's own cells (at least 64 x 128). */
static void env_project(const lu_light *l, int bands, float *out) {
    int nt, np;
    lu_sh_env_grid(l->env.width, l->env.height, 1, &nt, &np);
    double acc[3 * LU_SH_MAX_COEFFS];
    lu_sh_env_project(env_radiance, l, nt, np, bands, LU_SH_ENV_ANGLES_FLOAT, acc);
    for (int k = 0; k < 3 * bands * bands; k++) out[k] += (float)acc[k];
}

/* The windowed copy of the set's SH. */
static lu_result window_sh(ddod_state *st, lu_error *err) {
    size_t n = (size_t)st->set.count * st->set.stride;
    lu_free(st->sh);
    st->sh = lu_malloc((n ? n : 1u) * sizeof *st->sh);
    if (!st->sh) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    int nc = st->set.bands * st->set.bands;
    for (size_t i = 0; i < n; i++) {
        int k = (int)(i % (size_t)nc), l = (int)sqrtf((float)k);
        st->sh[i] = st->set.sh[i] * window_weight(st->window, l, st->set.bands);
    }
    return LU_OK;
}

/* The environment lights' SH (ddod.env_sh). */
static void env_update(ddod_state *st, const lu_scene *scene) {
    memset(st->env, 0, sizeof st->env);
    st->env_on = 0;
    st->env_lights = 0;
    for (int l = 0; l < scene->light_count; l++)
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) {
            env_project(&scene->lights[l], st->set.bands, st->env);
            st->env_on = 1;
            st->env_lights++;
        }
}

static lu_result ddod_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                              lu_error *err) {
    {
        lu_result re = lu_refuse_emission(scene, "ddod", err);
        if (re != LU_OK) return re;
    }
    ddod_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    st->backend = backend;
    st->normalize = (int)params[P_NORMALIZE];
    st->traced = (params[P_VIEW_PSI] == 0.0 ? LU_K_DDOD_TRACED_VIEW : 0) |
                 (params[P_LIGHT_PSI] == 0.0 ? LU_K_DDOD_TRACED_LIGHTS : 0);
    lu_ddod_params p;
    memset(&p, 0, sizeof p);
    p.res = (int)params[P_RES];
    p.dirs = (int)params[P_DIRS];
    p.samples = (int)params[P_SAMPLES];
    p.bands = (int)params[P_BANDS];
    p.width = (float)params[P_WIDTH];
    p.seed = (uint32_t)params[P_SEED];
    p.fit = (int)params[P_FIT];
    st->params = p;
    st->use_cache = params[P_CACHE] != 0.0;
    st->window = (int)params[P_WINDOW];
    lu_result r = LU_OK;
    if (scene->medium_count > LU_SCENE_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "ddod: %d media (at most %d)", scene->medium_count, LU_SCENE_MAX_MEDIA);
    if (r == LU_OK) r = lu_ddod_prepare_set(scene, &p, st->use_cache, &st->set, err);
    if (r == LU_OK) r = window_sh(st, err);
    if (r == LU_OK) {
        st->set_valid = st->set_from_prepare = true;
        st->set_key = lu_ddod_key(scene, &p);
        st->set_version = 1;
        env_update(st, scene);
    }
    st->eps = lu_scene_ray_epsilon(scene);
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, 16, false, err);
    st->medium_count = scene->medium_count;
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_ddod_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        ddod_destroy(st);
        return r;
    }
    st->stats.samples = st->set.count;
    st->stats.precompute = st->set.timing;
    if (lu_log_enabled(LU_LOG_INFO)) {
        const lu_ddod_timing *t = &st->set.timing;
        lu_log_msg(LU_LOG_INFO,
                "ddod: %d samples, %d SH coefficients x %d channel(s); precompute %s%.2f s (optical depth %.2f, "
                "divergence %.2f, sampling %.2f, SH %.2f; processor time %.2f s)\n",
                st->set.count, st->set.bands * st->set.bands, st->set.channels, t->from_cache ? "loaded, took " : "",
                t->total_s, t->optical_depth_s, t->divergence_s, t->sampling_s, t->sh_s, t->cpu_s);
    }
    *out = st;
    return LU_OK;
}

/* Density integral of medium mi over [t0, t1] of o + t d: exact for a
 * constant medium, the kernel's cell walk (lu_march.h) for a grid. */
static float medium_depth(const ddod_state *st, int mi, lu_vec3 o, lu_vec3 d, float t0, float t1) {
    const lu_medium *med = &st->scene->media[mi];
    if (med->kind == LU_DENSITY_CONSTANT) return med->constant * (t1 - t0);
    lu_k_medium km = st->km[mi];
    float a = 0.0f, b = 0.0f;
    return lu_k_box_clip(km.bounds_lo, km.bounds_hi, o, d, t0, t1, &a, &b)
               ? lu_k_optical_depth(&st->kctx, mi, lu_k_medium_point(km, o), lu_k_medium_vector(km, d), a, b,
                                    km.max_pieces)
               : 0.0f;
}

/* ---- traced terms: psi of every sample towards the camera and psi^F
 * towards every light, on the CPU (lu_ddod_ray: the precomputation's own
 * ray walk), cached until the camera or a light moves ---- */

typedef struct trace_span {
    const ddod_state *st;
    int mi;
} trace_span;

static float trace_span_depth(void *user, lu_vec3 b, lu_vec3 w, float t0, float t1) {
    const trace_span *t = user;
    return medium_depth(t->st, t->mi, b, w, t0, t1);
}

/* exp(-sigma_t tau) * (fresnel ? F_t : 1) of sample i's medium from b
 * towards w over (0, dist). A ray query that ran out of memory leaves its
 * spans short: psi too bright there, never a crash. */
static lu_vec3 traced_psi(const ddod_state *st, int mi, lu_vec3 b, lu_vec3 w, float dist, bool fresnel) {
    const lu_medium *med = &st->scene->media[mi];
    trace_span ts = {st, mi};
    float tau, ft;
    (void)lu_ddod_ray(st->mr.boundary[mi], st->mr.opaque, med->eta, b, w, dist, trace_span_depth, &ts, &tau, &ft);
    if (isinf(tau)) return lu_v3s(0.0f);
    lu_vec3 psi = lu_v3_exp(lu_v3_scale(lu_v3_add(med->sigma_a, med->sigma_s), -tau));
    return fresnel ? lu_v3_scale(psi, ft) : psi;
}

static void put4(float *o, lu_vec3 v) {
    o[0] = v.x;
    o[1] = v.y;
    o[2] = v.z;
    o[3] = 0.0f;
}

/* thread ranges of samples: entry 0 (view) or entries 1..nl (lights) */
static void traced_view_range(void *ctx, int64_t begin, int64_t end, int thread) {
    ddod_state *st = ctx;
    (void)thread;
    lu_vec3 cam = st->scene->camera.position;
    for (int64_t i = begin; i < end; i++) {
        const float *s = st->set.samples + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        lu_vec3 b = lu_v3(s[0], s[1], s[2]), to = lu_v3_sub(cam, b);
        float dist = lu_v3_len(to);
        lu_vec3 psi = dist > 0.0f ? traced_psi(st, (int)s[LU_K_DDOD_SAMPLE_MEDIUM], b, lu_v3_scale(to, 1.0f / dist),
                                               dist, false)
                                  : lu_v3s(1.0f);
        put4(st->traced_tab + (size_t)i * (st->nl + 1) * 4, psi);
    }
}

static void traced_light_range(void *ctx, int64_t begin, int64_t end, int thread) {
    ddod_state *st = ctx;
    (void)thread;
    for (int64_t i = begin; i < end; i++) {
        const float *s = st->set.samples + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        lu_vec3 b = lu_v3(s[0], s[1], s[2]);
        for (int l = 0; l < st->nl; l++) {
            if (!st->tab_retrace[l]) continue;
            lu_k_light_sample ls = lu_k_light_arrive(st->kl[l], b);
            lu_vec3 psi = traced_psi(st, (int)s[LU_K_DDOD_SAMPLE_MEDIUM], b, ls.wl, ls.dist, true);
            put4(st->traced_tab + ((size_t)i * (st->nl + 1) + 1 + l) * 4, psi);
        }
    }
}

/* psi^F depends on where a light is, not on its colour or strength:
 * point and spot lights by position, directional lights by direction. */
static bool light_moved(const lu_k_light *a, const lu_k_light *b) {
    if (a->type != b->type) return true;
    lu_vec3 x = a->type == LU_K_LIGHT_DIRECTIONAL ? a->direction : a->position;
    lu_vec3 y = b->type == LU_K_LIGHT_DIRECTIONAL ? b->direction : b->position;
    return x.x != y.x || x.y != y.y || x.z != y.z;
}

/* Brings the traced table up to date: every entry when the media, the
 * geometry or the sample set changed or lights were added or removed; else
 * the view entries when the camera moved and a light's entries when that
 * light moved. The frame says what changed; the stored camera position and
 * light placements narrow that to what psi reads (a light's colour, the
 * camera's direction and field of view do not enter it). */
static lu_result update_traced(ddod_state *st, const lu_frame *f, bool set_changed, lu_error *err) {
    st->stats.ms_traced_view = st->stats.ms_traced_lights = 0.0;
    if (!st->traced) return LU_OK;
    bool fresh = st->tab_nl != st->nl || st->tab_count != st->set.count || !st->traced_tab || set_changed ||
                 (f->changed & (LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY));
    if (fresh) {
        size_t need = (size_t)(st->set.count ? st->set.count : 1) * (size_t)(st->nl + 1) * 4;
        float *t = lu_realloc(st->traced_tab, need * sizeof *t);
        lu_k_light *pl = lu_realloc(st->tab_lights, (st->nl ? (size_t)st->nl : 1u) * sizeof *pl);
        bool *rt = lu_realloc(st->tab_retrace, (st->nl ? (size_t)st->nl : 1u) * sizeof *rt);
        if (t) st->traced_tab = t;
        if (pl) st->tab_lights = pl;
        if (rt) st->tab_retrace = rt;
        st->tab_view_valid = st->tab_lights_valid = false;
        if (!t || !pl || !rt) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for the traced table");
        st->tab_nl = st->nl;
        st->tab_count = st->set.count;
    }
    st->kctx.traced = st->traced_tab;
    lu_vec3 cam = st->scene->camera.position;
    bool view = (st->traced & LU_K_DDOD_TRACED_VIEW) &&
                (!st->tab_view_valid || ((f->changed & LU_CHANGE_CAMERA) && (cam.x != st->tab_cam.x ||
                                                                              cam.y != st->tab_cam.y ||
                                                                              cam.z != st->tab_cam.z)));
    /* every light on a fresh table, else only the lights that moved */
    bool all = (st->traced & LU_K_DDOD_TRACED_LIGHTS) && !st->tab_lights_valid, lights = all;
    uint64_t changed = lu_frame_kernel_lights_changed(f);
    for (int l = 0; (st->traced & LU_K_DDOD_TRACED_LIGHTS) && l < st->nl; l++) {
        st->tab_retrace[l] = all || (((changed >> (l < 63 ? l : 63)) & 1u) && light_moved(&st->kl[l], &st->tab_lights[l]));
        lights = lights || st->tab_retrace[l];
    }
    if (view) {
        double t0 = lu_time_seconds();
        st->tab_view_valid = false;
        lu_parallel_for(st->set.count, 0, traced_view_range, st, NULL);
        st->tab_cam = cam;
        st->tab_view_valid = true;
        st->stats.ms_traced_view = 1e3 * (lu_time_seconds() - t0);
        st->stats.traced_view_updates++;
        lu_frame_rebuilt(f, "ddod.view_psi");
    }
    if (lights) {
        double t0 = lu_time_seconds();
        st->tab_lights_valid = false;
        if (st->nl > 0) lu_parallel_for(st->set.count, 0, traced_light_range, st, NULL);
        memcpy(st->tab_lights, st->kl, (size_t)st->nl * sizeof *st->tab_lights);
        st->tab_lights_valid = true;
        st->stats.ms_traced_lights = 1e3 * (lu_time_seconds() - t0);
        st->stats.traced_light_updates++;
        for (int l = 0; l < st->nl; l++) {
            st->stats.traced_lights_retraced += st->tab_retrace[l];
            if (st->tab_retrace[l]) lu_frame_rebuilt(f, "ddod.light_psi");
        }
    }
    if (view || lights) st->tab_version++;
    return LU_OK;
}

/* The precomputation for this frame's media and geometry (ddod.set): the one
 * prepare made when the first frame's scene is the one it was made for
 * (same lu_ddod_key: everything the precomputation reads), else made again
 * (through the cache, like prepare). */
static lu_result update_set(ddod_state *st, const lu_frame *f, bool *changed, lu_error *err) {
    *changed = false;
    if (!lu_frame_stale(f, st->set_valid, LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY)) return LU_OK;
    bool keep = st->set_valid && st->set_from_prepare && lu_ddod_key(f->scene, &st->params) == st->set_key;
    st->set_from_prepare = false;
    if (!keep) {
        st->set_valid = false;
        lu_ddod_set ns;
        lu_result r = lu_ddod_prepare_set(f->scene, &st->params, st->use_cache, &ns, err);
        if (r != LU_OK) return r;
        lu_ddod_set_free(&st->set);
        st->set = ns;
        r = window_sh(st, err);
        if (r != LU_OK) return r;
        st->set_valid = true;
        st->set_version++;
        st->stats.samples = st->set.count;
        st->stats.precompute = st->set.timing;
        *changed = true;
    }
    lu_frame_rebuilt(f, "ddod.set");
    return LU_OK;
}

/* ---- per pixel: medium span and surface term (CPU, both backends) ---- */

/* Blinn-Phong of a surface lit by every point/spot/directional light,
 * unshadowed (the paper's surface pass). */
static lu_vec3 surface_shade(const ddod_state *st, const lu_material *mat, lu_vec3 x, lu_vec3 n, lu_vec3 wo) {
    lu_vec3 sum = lu_v3s(0.0f);
    for (int l = 0; l < st->nl; l++) {
        lu_k_light_sample ls = lu_k_light_arrive(st->kl[l], x);
        lu_vec3 f = lu_k_blinn_phong(mat->albedo, mat->specular, mat->shininess, n, wo, ls.wl);
        sum = lu_v3_add(sum, lu_v3_mul(f, ls.irradiance));
    }
    return sum;
}

static void pixel_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    ddod_state *st = ctx;
    const lu_scene *s = st->scene;
    const lu_camera *c = &s->camera;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < c->width; x++) {
            float *px = st->pixels + ((size_t)y * c->width + x) * LU_K_DDOD_PIXEL_FLOATS;
            memset(px, 0, LU_K_DDOD_PIXEL_FLOATS * sizeof *px);
            lu_vec3 o = c->position, d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_hit hit;
            bool has_hit = st->mr.opaque && lu_accel_closest(st->mr.opaque, o, d, 0.0f, LU_K_FAR, &hit);
            float t_end = has_hit ? hit.t : LU_K_FAR;
            /* The nearest medium's first span along the ray (media_ray.h). */
            float sp[2 * LU_SCENE_MAX_MEDIA], nrm[LU_MR_NORMAL_FLOATS * LU_SCENE_MAX_MEDIA];
            lu_media_ray_spans(&st->mr, o, d, t_end, sp, nrm);
            float t0 = 0.0f, t1 = 0.0f;
            int mi = -1;
            for (int m = 0; m < st->medium_count; m++) {
                if (!(sp[2 * m + 1] > sp[2 * m]) || (mi >= 0 && sp[2 * m] >= t0)) continue;
                mi = m;
                t0 = sp[2 * m];
                t1 = sp[2 * m + 1];
            }
            lu_vec3 entry_n = mi >= 0 ? lu_v3(nrm[LU_MR_NORMAL_FLOATS * mi], nrm[LU_MR_NORMAL_FLOATS * mi + 1],
                                              nrm[LU_MR_NORMAL_FLOATS * mi + 2])
                                      : lu_v3s(0.0f);
            bool has_entry = lu_v3_dot(entry_n, entry_n) > 0.0f;  /* zero when the camera is inside */
            lu_vec3 surf = lu_v3s(0.0f);
            lu_vec3 T = lu_v3s(1.0f);
            if (mi >= 0 && t0 < t_end) {
                const lu_medium *med = &s->media[mi];
                if (has_entry) {
                    /* Reflection at the entry, weighted by (1 - F_t) (Eq. 4). */
                    lu_vec3 n = entry_n;
                    if (lu_v3_dot(n, d) > 0.0f) n = lu_v3_neg(n);
                    lu_vec3 xe = lu_v3_madd(lu_v3_madd(o, d, t0), n, st->eps);
                    float fr = lu_k_fresnel_reflectance(lu_v3_dot(n, d), med->eta);
                    surf = lu_v3_scale(surface_shade(st, &med->surface, xe, n, lu_v3_neg(d)), fr);
                }
                t1 = fminf(t1, t_end);
                /* Exact transmittance of the camera ray through the span,
                 * for whatever lies behind it. */
                float od = medium_depth(st, mi, o, d, t0, t1);
                T = lu_v3_exp(lu_v3_scale(lu_v3_add(med->sigma_a, med->sigma_s), -od));
                px[LU_K_DDOD_PIXEL_T0] = t0;
                px[LU_K_DDOD_PIXEL_T1] = t1;
            }
            lu_vec3 end_rad = s->background;
            if (has_hit) {
                const lu_object *ob = &s->objects[st->mr.opaque_object[hit.mesh_id]];
                lu_vec3 n, ng;
                lu_hit_normals(&ob->mesh, &hit, d, &n, &ng);
                lu_vec3 xh = lu_v3_madd(lu_v3_madd(o, d, hit.t), ng, st->eps);
                end_rad = surface_shade(st, &ob->material, xh, n, lu_v3_neg(d));
            } else {
                for (int l = 0; l < s->light_count; l++)
                    if (s->lights[l].type == LU_LIGHT_ENVIRONMENT)
                        end_rad = lu_v3_add(end_rad, lu_env_lookup(&s->lights[l].env, s->lights[l].env_scale, d));
            }
            surf = lu_v3_add(surf, lu_v3_mul(T, end_rad));
            px[LU_K_DDOD_PIXEL_SURFACE] = surf.x;
            px[LU_K_DDOD_PIXEL_SURFACE + 1] = surf.y;
            px[LU_K_DDOD_PIXEL_SURFACE + 2] = surf.z;
        }
}

static void sample_range(void *ctx, int64_t begin, int64_t end, int thread) {
    ddod_state *st = ctx;
    lu_vec3 cam = st->scene->camera.position;
    for (int64_t i = begin; i < end; i++) {
        put4(st->radiance + 4 * (size_t)i, lu_k_ddod_sample_radiance(&st->kctx, st->P, (int)i, cam));
    }
}

static void gather_tiles(void *ctx, int64_t begin, int64_t end, int thread) {
    ddod_state *st = ctx;
    const lu_camera *c = &st->scene->camera;
    for (int64_t tile = begin; tile < end; tile++) {
        int tx = (int)(tile % st->bins.tiles_x), ty = (int)(tile / st->bins.tiles_x);
        for (int y = ty * TILE; y < (ty + 1) * TILE && y < c->height; y++)
            for (int x = tx * TILE; x < (tx + 1) * TILE && x < c->width; x++) {
                lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
                lu_vec3 L = lu_k_ddod_pixel(&st->kctx, st->P, y * c->width + x, (int)tile, c->position, d);
                float *o = lu_image_px(st->out, x, y);
                o[0] = L.x;
                o[1] = L.y;
                o[2] = L.z;
            }
    }
}

static lu_result ddod_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    ddod_state *st = state;
    if (scene->medium_count != st->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "ddod: the scene's media changed since prepare");
    st->scene = scene;
    st->out = out;
    const lu_camera *c = &scene->camera;
    st->cam = frame->rec->cam;
    st->km = frame->rec->media;
    st->kl = frame->rec->lights;
    st->nl = frame->rec->light_count;
    bool set_changed = false;
    lu_result rs = update_set(st, frame, &set_changed, err);
    if (rs != LU_OK) return rs;
    int envs = 0;
    bool env = false;
    for (int l = 0; l < scene->light_count; l++)
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) envs++, env |= lu_frame_light_changed(frame, l);
    if (env || envs != st->env_lights) {
        env_update(st, scene);
        lu_frame_rebuilt(frame, "ddod.env_sh");
    }
    size_t pixels = (size_t)c->width * c->height;
    if (pixels > st->pixels_cap) {
        lu_free(st->pixels);
        st->pixels = lu_malloc(pixels * LU_K_DDOD_PIXEL_FLOATS * sizeof(float));
        st->pixels_cap = st->pixels ? pixels : 0;
        st->pixels_valid = false;
        if (!st->pixels) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for %zu pixels", pixels);
    }
    size_t samples = st->set.count ? (size_t)st->set.count : 1u;
    if (samples > st->samples_cap) {
        lu_free(st->radiance);
        lu_free(st->rects);
        st->radiance = lu_malloc(samples * 4 * sizeof(float));
        st->rects = lu_malloc(samples * sizeof *st->rects);
        st->samples_cap = st->radiance && st->rects ? samples : 0;
        st->bins_valid = false;
        if (!st->samples_cap) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for %zu samples", samples);
    }
    st->kctx = (struct lu_k_ctx){scene->media, st->km, scene->medium_count, st->kl, st->nl, st->set.samples, st->sh,
                                 st->radiance, st->pixels, st->env, st->traced_tab, NULL, NULL};
    lu_result rt = update_traced(st, frame, set_changed, err);
    if (rt != LU_OK) return rt;
    double t0 = lu_time_seconds();
    if (lu_frame_stale(frame, st->pixels_valid, LU_CHANGE_ALL)) {
        st->pixels_valid = false;
        lu_parallel_for(c->height, 1, pixel_rows, st, NULL);
        st->pixels_valid = true;
        st->pixels_version++;
        lu_frame_rebuilt(frame, "ddod.pixels");
    }
    double t1 = lu_time_seconds();
    if (set_changed || lu_frame_stale(frame, st->bins_valid, LU_CHANGE_CAMERA | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY)) {
        st->bins_valid = false;
        for (int i = 0; i < st->set.count; i++) {
            const float *s = st->set.samples + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
            lu_vec3 b = lu_v3(s[0], s[1], s[2]);
            st->rects[i] = lu_k_ball_screen_rect(c->position, st->cam.right, st->cam.up, st->cam.forward, c->width,
                                                 c->height, b, LU_K_DDOD_CUTOFF * s[LU_K_DDOD_SAMPLE_S]);
        }
        lu_result rb = lu_tile_bins_build(&st->bins, c->width, c->height, TILE, st->set.count, st->rects, err);
        if (rb != LU_OK) return rb;
        st->bins_valid = true;
        st->bins_version++;
        lu_frame_rebuilt(frame, "ddod.bins");
    }
    lu_result r = LU_OK;
    double t2 = lu_time_seconds();
    st->kctx.tile_start = st->bins.start;
    st->kctx.tile_list = st->bins.list;
    lu_k_ddod_params P;
    memset(&P, 0, sizeof P);
    P.bands = st->set.bands;
    P.channels = st->set.channels;
    P.stride = st->set.stride;
    P.normalize = st->normalize;
    P.tile = TILE;
    P.tiles_x = st->bins.tiles_x;
    P.env = st->env_on;
    P.traced = st->traced;
    st->P = P;
    double t3 = t2;
    if (st->backend == LU_BACKEND_GPU) {
        lu_ddod_frame f = {c->width, c->height, st->bins.tiles_y, P, st->set.count, st->set.samples, st->sh,
                           st->pixels, st->bins.start, st->bins.list, (size_t)st->bins.entries, st->env,
                           st->set_version, st->traced_tab, st->nl, st->tab_version, st->pixels_version,
                           st->bins_version};
        r = lu_ddod_gpu_render(st->gpu, scene, frame->rec, &f, out, err);
        if (r != LU_OK) return r;
    } else {
        lu_parallel_for(st->set.count, 0, sample_range, st, NULL);
        t3 = lu_time_seconds();
        lu_frame_for_tiles(frame, TILE, st->bins.tiles_x, st->bins.tiles_y, gather_tiles, st);
    }
    double t4 = lu_time_seconds();
    st->stats.list_entries = st->bins.entries;
    st->stats.ms_pixels = 1e3 * (t1 - t0);
    st->stats.ms_binning = 1e3 * (t2 - t1);
    st->stats.ms_samples = 1e3 * (t3 - t2);
    st->stats.ms_gather = 1e3 * (t4 - t3);
    lu_log_msg(LU_LOG_DEBUG, "ddod: frame ms: traced view %.1f, traced lights %.1f (%d), pixels %.1f, binning %.1f, samples %.1f, gather %.1f\n",
                st->stats.ms_traced_view, st->stats.ms_traced_lights, st->nl, st->stats.ms_pixels, st->stats.ms_binning,
                st->stats.ms_samples, st->stats.ms_gather);
    return LU_OK;
}

bool lu_ddod_last_stats(const lu_renderer *r, lu_ddod_stats *out) {
    if (!r || strcmp(r->method->name, "ddod") != 0 || !r->state) return false;
    *out = ((const ddod_state *)r->state)->stats;
    return true;
}

const float *lu_ddod_traced_table(const lu_renderer *r, int *lights, int *count, const float **samples) {
    if (!r || strcmp(r->method->name, "ddod") != 0 || !r->state) return NULL;
    const ddod_state *st = r->state;
    if (!st->traced || !st->traced_tab) return NULL;
    *lights = st->tab_nl;
    *count = st->set.count;
    *samples = st->set.samples;
    return st->traced_tab;
}

const lu_method lu_method_ddod = {
    .name = "ddod",
    .summary = "direction-dependent optical depth samples with SH attenuation and Gaussian line integrals "
               "(Bernabei et al.; translucent bounded media; CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .prepare = ddod_prepare,
    .render = ddod_render,
    .destroy = ddod_destroy,
};
