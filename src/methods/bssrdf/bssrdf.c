/* bssrdf — translucent objects by diffusion profiles and splatting
 * (Rohat 2011; docs/bssrdf.md).
 *
 * prepare: per translucent object, its profile table (dipole / normalised
 *   diffusion / photon beam diffusion 1D, multipole 2D, coated stacks by FFT; r_max by Simpson,
 *   eps), and for environment lights: the SH9 projection of the maps and
 *   surface samples (area CDF, N_s = A / (pi l_u^2), repulsion relaxation)
 *   with their Fresnel-weighted SH irradiance as flux.
 * render, per frame:
 *   1. light pass: per light view (lightview.c framing the objects), the
 *      texels over the objects' region are ray cast (Embree stands in for
 *      the thesis' rasteriser): depth (the shadow map), object id (the
 *      validity flag), position, normal, and the exit point behind
 *      translucent surfaces (thickness);
 *   2. samples: an N x M grid over each translucent object's region of
 *      interest in each view, jittered within its cell, read from the map
 *      (bilinear like GL_LINEAR where the 4 texels agree, else the nearest);
 *      each valid sample becomes a splat with flux = irradiance * F_t *
 *      the area its cell covers (A_vis / N_s * E(x_s));
 *   3. eye pass: the G-buffer of the camera's pixel-centre rays;
 *   4. binning: every splat's screen-aligned bounding rectangle
 *      (lu_k_ball_screen_rect) into 16 x 16 pixel tiles, in splat order;
 *   5. splat + deferred pass (CPU loop or the GPU shader, same kernel):
 *      per pixel, the sum over its tile's splats of the same object, then
 *      lu_k_bssrdf_shade (F_t exit_norm / pi weighting, Blinn-Phong highlight, shadows
 *      for opaque objects from the same light-space maps, SH9 irradiance).
 * Steps 1-2 read the lights and never the camera: they are kept across
 * camera moves and redone per light that changed; 3-4 are redone when the
 * camera moved (4 also when a splat changed); 5 runs every frame.
 * Media other than the translucent objects' own are not rendered.
 * Over 800 lines because steps 1-5 all read one private state (the objects'
 * tables, the per-light map slots and splat lists); the profile tables
 * (bssrdf_profile.c), sampling (bssrdf_sampling.c) and the GPU pass
 * (bssrdf_gpu.c) are already rooms of their own. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "methods/bssrdf/bssrdf.h"
#include "core/quadrature.h"
#include "methods/common/tile_bins.h"
#include "methods/bssrdf/bssrdf_gpu.h"
#include "methods/bssrdf/bssrdf_profile.h"
#include "methods/bssrdf/bssrdf_sampling.h"
#include "methods/common/lightview.h"
#include "methods/common/sh_env.h"
#include "methods/frame.h"
#include "methods/methods.h"

/* ---- kernel context: flat arrays on the CPU --------------------------------------- */
struct lu_k_ctx {
    const float *buf[6];
    const float *shadow;
    int res;
};

static inline float lu_k_bssrdf_fetch(const struct lu_k_ctx *c, int b, int i) { return c->buf[b][i]; }
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return c->shadow[((size_t)map * c->res + j) * c->res + i];
}

#include "methods/bssrdf/lu_bssrdf.h"
#include "kernels/lu_camera.h"
#include "methods/common/lu_sh.h"

/* The GPU reads these arrays with the std430 layout of the same structs. */
_Static_assert(sizeof(lu_k_splat) == 80, "lu_k_splat must match its std430 layout");
_Static_assert(sizeof(lu_k_gbuf) == 32, "lu_k_gbuf must match its std430 layout");

enum {
    P_PROFILE,
    P_SPLATS,
    P_MAP_RES,
    P_JITTER,
    P_TABLE_SIZE,
    P_THICKNESS_STEPS,
    P_PAIRS,
    P_EPSILON,
    P_D_MIN,
    P_D_MAX,
    P_FFT_SIZE,
    P_SPLAT_SCALE,
    P_THICKNESS_SCALE,
    P_ENV_SAMPLES,
    P_ENV_MAX,
    P_ENV_SPACING,
    P_RELAX_ITERS,
    P_RELAX_STEP,
    P_RELAX_TOL,
    P_PREFILTER,
    P_SEED,
    P_STATS,
    P_COUNT
};

static const lu_param_desc k_params[P_COUNT] = {
    [P_PROFILE] = {"profile", LU_PARAM_CHOICE, 0, 0, 3, "dipole|multipole|burley|pbd",
                   "diffusion profile: Jensen dipole (1D), Donner-Jensen multipole R and T over thickness (2D), "
                   "Christensen-Burley normalised diffusion (1D), photon beam diffusion plus single scattering "
                   "(1D, tabulated); coated materials always use multipole layers"},
    [P_SPLATS] = {"splats", LU_PARAM_INT, 4096, 1, 16777216, NULL,
                  "light samples per light and translucent object (an N x M grid over its region of interest)"},
    [P_MAP_RES] = {"map_res", LU_PARAM_INT, 512, 16, 8192, NULL,
                   "side of each light-space map (sample map and shadow map; a point light has six)"},
    [P_JITTER] = {"jitter", LU_PARAM_FLOAT, 0, 0, 1, NULL,
                  "random offset of each sample within its grid cell (0: cell centres; with prefiltered profiles "
                  "the regular grid is a midpoint rule and jitter only adds grain)"},
    [P_TABLE_SIZE] = {"table_size", LU_PARAM_INT, 512, 16, 65536, NULL, "profile table entries along r"},
    [P_THICKNESS_STEPS] = {"thickness_steps", LU_PARAM_INT, 32, 2, 1024, NULL, "2D profiles: rows along thickness"},
    [P_PAIRS] = {"pairs", LU_PARAM_INT, 10, 0, 200, NULL, "multipole: dipole pairs -n..n"},
    [P_EPSILON] = {"epsilon", LU_PARAM_FLOAT, 0.01, 1e-6, 0.5, NULL,
                   "splat radius r_max: fraction of the reflected power left outside it"},
    [P_D_MIN] = {"d_min", LU_PARAM_FLOAT, 4, 0.5, 1000, NULL, "2D profiles: thinnest row, in mean free paths"},
    [P_D_MAX] = {"d_max", LU_PARAM_FLOAT, 64, 1, 10000, NULL, "2D profiles: thickest row, in mean free paths"},
    [P_FFT_SIZE] = {"fft_size", LU_PARAM_INT, 256, 16, 4096, NULL,
                    "coated materials: FFT grid side (even); rows keep the exact stacked totals at any size"},
    [P_SPLAT_SCALE] = {"splat_scale", LU_PARAM_FLOAT, 1, 0.05, 20, NULL,
                       "scales every length of the profiles (splat size and look-up radius; thesis Fig. 6.11)"},
    [P_THICKNESS_SCALE] = {"thickness_scale", LU_PARAM_FLOAT, 1, 0.01, 100, NULL,
                           "scales the light-space thickness fed to 2D profiles (thesis Fig. 6.10)"},
    [P_ENV_SAMPLES] = {"env_samples", LU_PARAM_INT, 0, 0, 16777216, NULL,
                       "environment: surface samples per object (0: A / (pi l_u^2), l_u the mean free path)"},
    [P_ENV_MAX] = {"env_max", LU_PARAM_INT, 50000, 1, 16777216, NULL, "environment: cap on the automatic sample count"},
    [P_ENV_SPACING] = {"env_spacing", LU_PARAM_FLOAT, 1, 0.01, 100, NULL,
                       "environment: l_u in mean free paths for the automatic count"},
    [P_RELAX_ITERS] = {"relax_iters", LU_PARAM_INT, 100, 0, 100000, NULL, "environment: most relaxation iterations"},
    [P_RELAX_STEP] = {"relax_step", LU_PARAM_FLOAT, 0.01, 0, 10, NULL,
                      "environment: scale of the repulsion force per iteration (thesis Table 5.4)"},
    [P_RELAX_TOL] = {"relax_tol", LU_PARAM_FLOAT, 0.01, 1e-9, 1, NULL,
                     "environment: converged when the nearest-neighbour spread improves by less than this over 5 "
                     "iterations (and points move < 1 % of the repulsion radius)"},
    [P_PREFILTER] = {"prefilter", LU_PARAM_INT, 12, 0, 32, NULL,
                     "profile levels averaged over each sample's surface cell (discs growing by sqrt 2 from mfp / 4); "
                     "0: the thesis' point evaluation"},
    [P_SEED] = {"seed", LU_PARAM_INT, 1, 0, 2147483647, NULL, "random seed of the jitter and the surface samples"},
    [P_STATS] = {"stats", LU_PARAM_BOOL, 0, 0, 1, NULL, "print per-pass timings and counts on stderr"},
};

#define TILE 16

/* One texel of a light-space map inside its cast region. */
typedef struct lmap_texel {
    lu_vec3 pos, nrm, back;
    float thick;
    int object;
} lmap_texel;

typedef struct lmap {
    lu_k_lightview view;
    int light;
    int x0, y0, x1, y1;        /* cast region [x0, x1) x [y0, y1) */
    lmap_texel *tex;
    int *roi;                  /* per translucent object: its texels' bounding rectangle (the region of interest) */
} lmap;

typedef struct lslot {        /* one scene light's share of the frame's products */
    int first_view, view_count;
    lu_k_splat *splats;       /* finished (lu_k_bssrdf_splat_finish), in the order a full pass makes them */
    int splat_count, splat_cap;
    long long texels;
} lslot;

typedef struct tobject {      /* a translucent object */
    int object;
    lu_bssrdf_profile prof;
    int table_offset;         /* rgb entries */
    lu_accel *own;
    lu_aabb bounds;
    float eta_top;
    lu_k_splat *env;          /* environment splats: positions from prepare, flux from the environment lights */
    int env_count;
    double env_area;          /* the mesh area the samples share */
    lu_relax_stats relax;
} tobject;

typedef struct bssrdf_state {
    double p[P_COUNT];
    lu_backend backend;
    int object_count;
    lu_accel *all;            /* every object, mesh id = object index */
    tobject *t;
    int tcount;
    int *tindex;              /* scene object -> translucent index or -1 */
    float eps;
    lu_aabb objects_box;
    /* fetch buffers */
    float *table;
    size_t table_floats;
    float *materials;
    float *lights;
    float *views;
    float *env;
    size_t env_floats;
    float scene[LU_K_BSSRDF_SCENE_FLOATS];
    int light_count, view_count;
    /* per frame; the products and what they are built from (frame.h):
     *   bssrdf.maps    per light: its views, light-space maps, shadow maps (the light, the geometry)
     *   bssrdf.splats  per light: its splats (its maps, the light, the materials)
     *   bssrdf.env     the environment data and splat fluxes (the environment lights)
     *   bssrdf.gbuffer the camera rays' hits (the camera, the geometry)
     *   bssrdf.bins    the splats' screen tiles (the camera, every splat)
     * the splat gather and deferred shading run every frame. */
    lslot *slots;             /* per scene light */
    int slot_count;
    bool lights_valid, env_valid, splats_valid, gbuf_valid, bins_valid;
    int env_lights;           /* environment lights fill_env last saw */
    lmap *maps;
    float *shadow;
    size_t shadow_cap;
    lu_k_splat *splats;
    int splat_count, splat_cap;
    lu_k_gbuf *gbuf;
    size_t gbuf_cap;
    lu_tile_bins bins;
    lu_k_rect *rects;         /* per splat, for binning */
    size_t rects_cap;
    struct lu_k_ctx kctx;
    lu_bssrdf_gpu *gpu;
    lu_bssrdf_frame_stats stats;
} bssrdf_state;

/* ---- environment: SH projection ---------------------------------------------------- */

static double legendre(int l, double x) { return l == 0 ? 1.0 : (l == 1 ? x : 0.5 * (3.0 * x * x - 1.0)); }

void lu_bssrdf_sh_kernel(float eta, double a[3]) {
    /* Gauss-Legendre, 48 nodes on [0, 1]: the integrand is smooth. Computed
     * per call (cheap, and safe with renderers on several threads). */
    enum { N = 48 };
    double gx[N], gw[N];
    lu_gauss_legendre(N, gx, gw);
    for (int i = 0; i < N; i++) {
        gx[i] = 0.5 * (gx[i] + 1.0);
        gw[i] *= 0.5;
    }
    for (int l = 0; l < 3; l++) {
        double s = 0.0;
        for (int i = 0; i < N; i++) {
            double mu = gx[i], w = eta > 0.0f ? 1.0 - lu_k_fresnel_reflectance((float)mu, eta) : 1.0;
            s += gw[i] * w * mu * legendre(l, mu);
        }
        a[l] = 2.0 * M_PI * s;
    }
}

lu_vec3 lu_bssrdf_sh_irradiance(const double L[27], const double k[3], lu_vec3 n) {
    float y[LU_SH_MAX_COEFFS];
    lu_k_sh_eval(lu_v3_norm(n), 3, y);
    double e[3] = {0, 0, 0};
    for (int i = 0; i < 9; i++) {
        int l = i == 0 ? 0 : (i < 4 ? 1 : 2);
        for (int c = 0; c < 3; c++) e[c] += k[l] * L[3 * i + c] * y[i];
    }
    return lu_v3((float)fmax(e[0], 0.0), (float)fmax(e[1], 0.0), (float)fmax(e[2], 0.0));
}

/* One environment map through the kernel's own lookup. */
static lu_vec3 env_radiance(const void *user, lu_vec3 d) {
    return lu_k_bssrdf_env((const struct lu_k_ctx *)user, 0, d);
}

void lu_bssrdf_env_project(const lu_light *l, double L[27]) {
    float scene[LU_K_BSSRDF_SCENE_FLOATS] = {0};
    scene[LU_K_BSSRDF_SCENE_ENVS] = 1;
    scene[LU_K_BSSRDF_SCENE_ENV_INFO] = 0;
    scene[LU_K_BSSRDF_SCENE_ENV_INFO + 1] = (float)l->env.width;
    scene[LU_K_BSSRDF_SCENE_ENV_INFO + 2] = (float)l->env.height;
    scene[LU_K_BSSRDF_SCENE_ENV_INFO + 3] = l->env_scale;
    struct lu_k_ctx ctx = {{NULL, NULL, NULL, NULL, l->env.rgb, scene}, NULL, 0};
    int nt, np;   /* two cells per texel per axis, at least 128 x 256 */
    lu_sh_env_grid(l->env.width, l->env.height, 2, &nt, &np);
    lu_sh_env_project(env_radiance, &ctx, nt, np, 3, LU_SH_ENV_ANGLES_DOUBLE, L);
}

/* ---- prepare ----------------------------------------------------------------------- */

static void bssrdf_destroy(void *state) {
    bssrdf_state *st = state;
    if (!st) return;
    if (st->gpu) lu_bssrdf_gpu_destroy(st->gpu);
    if (st->all) lu_accel_destroy(st->all);
    for (int i = 0; st->t && i < st->tcount; i++) {
        lu_bssrdf_profile_destroy(&st->t[i].prof);
        if (st->t[i].own) lu_accel_destroy(st->t[i].own);
        lu_free(st->t[i].env);
    }
    if (st->maps)
        for (int v = 0; v < st->view_count; v++) {
            lu_free(st->maps[v].tex);
            lu_free(st->maps[v].roi);
        }
    lu_free(st->maps);
    lu_free(st->t);
    lu_free(st->tindex);
    lu_free(st->table);
    lu_free(st->materials);
    lu_free(st->lights);
    lu_free(st->views);
    lu_free(st->env);
    lu_free(st->shadow);
    lu_free(st->splats);
    for (int l = 0; l < st->slot_count; l++) lu_free(st->slots[l].splats);
    lu_free(st->slots);
    lu_free(st->gbuf);
    lu_tile_bins_free(&st->bins);
    lu_free(st->rects);
    lu_free(st);
}

static lu_bssrdf_profile_desc profile_desc(const bssrdf_state *st) {
    lu_bssrdf_profile_desc d;
    lu_bssrdf_profile_desc_default(&d);
    d.model = (lu_bssrdf_model)(int)st->p[P_PROFILE];
    d.table_size = (int)st->p[P_TABLE_SIZE];
    d.thickness_steps = (int)st->p[P_THICKNESS_STEPS];
    d.pairs = (int)st->p[P_PAIRS];
    d.epsilon = st->p[P_EPSILON];
    d.d_min_mfp = st->p[P_D_MIN];
    d.d_max_mfp = st->p[P_D_MAX];
    d.fft_size = (int)st->p[P_FFT_SIZE];
    return d;
}

static void fill_material(bssrdf_state *st, int o, const lu_object *ob) {
    float *m = st->materials + (size_t)o * LU_K_BSSRDF_MAT_FLOATS;
    const lu_material *mat = &ob->material;
    int ti = st->tindex[o];
    m[0] = ti >= 0 ? 1.0f : 0.0f;
    if (ti >= 0) {
        const tobject *t = &st->t[ti];
        m[1] = (float)t->prof.kind;
        m[2] = (float)t->table_offset;
        m[3] = (float)t->prof.nr;
        m[4] = (float)t->prof.nd;
        m[5] = t->prof.r_max;
        m[6] = t->prof.kind ? t->prof.d_lo : 1.0f;
        m[7] = t->prof.kind ? t->prof.d_hi : 2.0f;
        m[8] = t->eta_top;
        m[18] = t->prof.t_decay[0];
        m[19] = t->prof.t_decay[1];
        m[20] = t->prof.t_decay[2];
        m[21] = t->prof.kind ? t->prof.r_max_t : 0.0f;
        m[22] = t->prof.kind ? t->prof.d_t_cut : 0.0f;
        m[23] = (float)lu_bssrdf_profile_level_entries(&t->prof);
        double k[3];   /* k[0] = 2 pi int F_t mu dmu = pi (1 - F_dr,ext) */
        lu_bssrdf_sh_kernel(t->eta_top, k);
        m[24] = (float)(M_PI / k[0]);
    }
    m[9] = mat->shininess;
    m[10] = ti >= 0 ? 0.0f : mat->albedo.x;
    m[11] = ti >= 0 ? 0.0f : mat->albedo.y;
    m[12] = ti >= 0 ? 0.0f : mat->albedo.z;
    m[13] = mat->specular.x;
    m[14] = mat->specular.y;
    m[15] = mat->specular.z;
    m[16] = (float)st->p[P_THICKNESS_SCALE];
    m[17] = (float)st->p[P_SPLAT_SCALE];
}

static float splat_level(const bssrdf_state *st, const tobject *t, double area);

/* Flux of t's environment splats: the Fresnel-weighted SH irradiance L of
 * the environment lights over each sample's share of the area. */
static void env_flux(tobject *t, const double L[27]) {
    double k[3];
    lu_bssrdf_sh_kernel(t->eta_top, k);
    double dA = t->env_area / (double)t->env_count;
    for (int i = 0; i < t->env_count; i++)
        t->env[i].flux = lu_v3_scale(lu_bssrdf_sh_irradiance(L, k, t->env[i].normal), (float)dA);
}

/* Environment splats of translucent object t: samples on its mesh, relaxed,
 * with the Fresnel-weighted SH irradiance as flux and the thickness along -n. */
static lu_result prepare_env_samples(bssrdf_state *st, const lu_scene *scene, tobject *t, const double L[27],
                                     lu_error *err) {
    const lu_mesh *mesh = &scene->objects[t->object].mesh;
    double area = lu_mesh_area(mesh);
    double lu = st->p[P_ENV_SPACING] * t->prof.mfp * st->p[P_SPLAT_SCALE];
    long long n = (long long)st->p[P_ENV_SAMPLES];
    if (n == 0) {
        n = (long long)ceil(area / (M_PI * lu * lu));
        if (n > (long long)st->p[P_ENV_MAX]) n = (long long)st->p[P_ENV_MAX];
    }
    if (n < 16) n = 16;
    lu_surface_points pts;
    lu_result r = lu_surface_sample(mesh, (int)n, (uint64_t)st->p[P_SEED] * 7919u + (uint64_t)t->object, &pts, err);
    if (r != LU_OK) return r;
    double radius = 2.0 * sqrt(area / (double)n); /* Turk 1991 */
    if ((int)st->p[P_RELAX_ITERS] > 0)
        r = lu_surface_relax(mesh, &pts, radius, st->p[P_RELAX_STEP], (int)st->p[P_RELAX_ITERS], st->p[P_RELAX_TOL],
                             &t->relax, err);
    if (r == LU_OK) {
        t->env = lu_calloc((size_t)n, sizeof *t->env);
        if (!t->env) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for %lld environment samples", n);
    }
    if (r == LU_OK) {
        double dA = area / (double)n;
        float far_len = 10.0f * t->prof.r_max * (float)st->p[P_SPLAT_SCALE];
        for (int i = 0; i < (int)n; i++) {
            lu_k_splat *s = &t->env[i];
            s->position = pts.position[i];
            s->normal = pts.normal[i];
            s->object = t->object;
            s->level = splat_level(st, t, dA);
            lu_vec3 inward = lu_v3_neg(pts.normal[i]);
            lu_hit h;
            if (lu_accel_closest(t->own, lu_v3_madd(s->position, inward, st->eps), inward, st->eps, 1e30f, &h)) {
                s->thickness = h.t + st->eps;
                s->back = lu_v3_madd(s->position, inward, s->thickness);
            } else {
                s->thickness = 1e9f;
                s->back = lu_v3_madd(s->position, inward, far_len);
            }
        }
        t->env_count = (int)n;
        t->env_area = area;
        env_flux(t, L);
    }
    lu_surface_points_destroy(&pts);
    return r;
}

/* The environment lights' maps (texels for the lookups), the scene constants
 * describing them, and the sum of their SH9 projections. */
static lu_result fill_env(bssrdf_state *st, const lu_scene *scene, double Lsum[27], int *envs_out, lu_error *err) {
    int envs = 0;
    size_t env_texels = 0;
    for (int l = 0; l < scene->light_count; l++)
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) {
            envs++;
            env_texels += (size_t)scene->lights[l].env.width * scene->lights[l].env.height;
        }
    if (envs > (LU_K_BSSRDF_SCENE_FLOATS - LU_K_BSSRDF_SCENE_ENV_INFO) / 4)
        return lu_fail(err, LU_ERR_LIMIT, "bssrdf: %d environment lights (at most %d)", envs,
                       (LU_K_BSSRDF_SCENE_FLOATS - LU_K_BSSRDF_SCENE_ENV_INFO) / 4);
    size_t floats = 3 * (env_texels ? env_texels : 1);
    if (floats != st->env_floats || !st->env) {
        lu_free(st->env);
        st->env_floats = 0;
        st->env = lu_calloc(floats, sizeof *st->env);
        if (!st->env) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the environment maps");
        st->env_floats = floats;
    }
    if (!env_texels) memset(st->env, 0, floats * sizeof *st->env);
    for (int i = 0; i < 27; i++) Lsum[i] = 0.0;
    for (int i = LU_K_BSSRDF_SCENE_ENVS; i < LU_K_BSSRDF_SCENE_FLOATS; i++) st->scene[i] = 0.0f;
    st->scene[LU_K_BSSRDF_SCENE_ENVS] = (float)envs;
    size_t at = 0;
    int e = 0;
    for (int l = 0; l < scene->light_count; l++) {
        const lu_light *li = &scene->lights[l];
        if (li->type != LU_LIGHT_ENVIRONMENT) continue;
        size_t n = (size_t)li->env.width * li->env.height;
        memcpy(st->env + 3 * at, li->env.rgb, 3 * n * sizeof(float));
        float *info = st->scene + LU_K_BSSRDF_SCENE_ENV_INFO + 4 * e;
        info[0] = (float)at;
        info[1] = (float)li->env.width;
        info[2] = (float)li->env.height;
        info[3] = li->env_scale;
        double L[27];
        lu_bssrdf_env_project(li, L);
        for (int i = 0; i < 27; i++) Lsum[i] += L[i];
        at += n;
        e++;
    }
    double a[3];
    lu_bssrdf_sh_kernel(0.0f, a);
    for (int i = 0; i < 9; i++) {
        int band = i == 0 ? 0 : (i < 4 ? 1 : 2);
        for (int c = 0; c < 3; c++) st->scene[LU_K_BSSRDF_SCENE_SH + 3 * i + c] = (float)(a[band] * Lsum[3 * i + c]);
    }
    *envs_out = envs;
    return LU_OK;
}

static lu_result bssrdf_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                                lu_error *err) {
    {
        lu_result re = lu_refuse_emission(scene, "bssrdf", err);
        if (re != LU_OK) return re;
    }
    bssrdf_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    memcpy(st->p, params, sizeof st->p);
    st->backend = backend;
    st->object_count = scene->object_count;
    lu_result r = LU_OK;
    if ((int)st->p[P_FFT_SIZE] & 1) r = lu_fail(err, LU_ERR_RANGE, "bssrdf.fft_size must be even");
    if (st->p[P_D_MAX] <= st->p[P_D_MIN] && r == LU_OK)
        r = lu_fail(err, LU_ERR_RANGE, "bssrdf.d_max must exceed bssrdf.d_min");

    st->eps = lu_scene_ray_epsilon(scene);
    st->objects_box = lu_aabb_empty();
    st->tindex = lu_malloc((size_t)(scene->object_count ? scene->object_count : 1) * sizeof *st->tindex);
    if (!st->tindex && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    for (int i = 0; i < scene->object_count && r == LU_OK; i++) {
        st->tindex[i] = scene->objects[i].material.type == LU_MATERIAL_TRANSLUCENT ? st->tcount++ : -1;
        lu_aabb b = lu_mesh_bounds(&scene->objects[i].mesh);
        lu_aabb_grow(&st->objects_box, b.lo);
        lu_aabb_grow(&st->objects_box, b.hi);
    }
    if (r == LU_OK && scene->object_count) {
        r = lu_accel_create(&st->all, err);
        for (int i = 0; i < scene->object_count && r == LU_OK; i++) {
            uint32_t id;
            r = lu_accel_add_mesh(st->all, &scene->objects[i].mesh, &id, err);
        }
        if (r == LU_OK) r = lu_accel_commit(st->all, err);
    }
    if (r == LU_OK && st->tcount) {
        st->t = lu_calloc((size_t)st->tcount, sizeof *st->t);
        if (!st->t) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    }
    /* Profiles, one table per translucent object. */
    lu_bssrdf_profile_desc desc = profile_desc(st);
    for (int i = 0, k = 0; i < scene->object_count && r == LU_OK; i++) {
        if (st->tindex[i] < 0) continue;
        tobject *t = &st->t[k++];
        const lu_object *ob = &scene->objects[i];
        t->object = i;
        t->bounds = lu_mesh_bounds(&ob->mesh);
        lu_bssrdf_layer layers[LU_MAX_COATINGS + 1];
        int nl = lu_bssrdf_material_layers(&ob->material, layers, LU_MAX_COATINGS + 1);
        t->eta_top = layers[0].eta;
        r = lu_bssrdf_profile_build(layers, nl, &desc, &t->prof, err);
        if (r == LU_OK && (int)st->p[P_PREFILTER] > 0)
            r = lu_bssrdf_profile_prefilter(&t->prof, 1 + (int)st->p[P_PREFILTER], 0.25f * t->prof.mfp, err);
        if (r != LU_OK) {
            char inner[sizeof err->message];
            snprintf(inner, sizeof inner, "%s", err->message);
            r = lu_fail(err, r, "bssrdf: object %d: %s", i, inner);
            break;
        }
        r = lu_accel_create(&t->own, err);
        uint32_t id;
        if (r == LU_OK) r = lu_accel_add_mesh(t->own, &ob->mesh, &id, err);
        if (r == LU_OK) r = lu_accel_commit(t->own, err);
    }
    /* One table array for every object. */
    size_t entries = 0;
    for (int i = 0; st->t && i < st->tcount; i++) {
        st->t[i].table_offset = (int)entries;
        entries += lu_bssrdf_profile_level_entries(&st->t[i].prof) * st->t[i].prof.levels;
    }
    if (r == LU_OK) {
        st->table_floats = 3 * (entries ? entries : 1);
        st->table = lu_calloc(st->table_floats, sizeof *st->table);
        st->materials = lu_calloc((size_t)(scene->object_count ? scene->object_count : 1) * LU_K_BSSRDF_MAT_FLOATS,
                               sizeof *st->materials);
        if (!st->table || !st->materials) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    }
    for (int i = 0; i < st->tcount && r == LU_OK; i++) {
        const lu_bssrdf_profile *pr = &st->t[i].prof;
        memcpy(st->table + 3 * (size_t)st->t[i].table_offset, pr->table,
               3 * sizeof(float) * lu_bssrdf_profile_level_entries(pr) * pr->levels);
    }
    for (int i = 0; i < scene->object_count && r == LU_OK; i++) fill_material(st, i, &scene->objects[i]);

    /* Environment maps: texels for the lookups, SH9 for the irradiance. */
    double Lsum[27] = {0};
    int envs = 0;
    if (r == LU_OK) r = fill_env(st, scene, Lsum, &envs, err);
    if (r == LU_OK) {
        st->env_lights = envs;
        st->scene[LU_K_BSSRDF_SCENE_BACKGROUND] = scene->background.x;
        st->scene[LU_K_BSSRDF_SCENE_BACKGROUND + 1] = scene->background.y;
        st->scene[LU_K_BSSRDF_SCENE_BACKGROUND + 2] = scene->background.z;
        st->scene[LU_K_BSSRDF_SCENE_MAP_RES] = (float)(int)st->p[P_MAP_RES];
    }
    for (int i = 0; i < st->tcount && r == LU_OK && envs > 0; i++) {
        r = prepare_env_samples(st, scene, &st->t[i], Lsum, err);
        if (r == LU_OK && st->p[P_STATS] != 0.0) {
            const lu_relax_stats *rs = &st->t[i].relax;
            lu_log_msg(LU_LOG_INFO,
                    "bssrdf: object %d: %d environment samples, relaxation %d iterations (%s, last RMS move %.2e r) in "
                    "%.2f s, nearest-neighbour CV %.3f -> %.3f\n",
                    st->t[i].object, st->t[i].env_count, rs->iterations, rs->converged ? "converged" : "not converged",
                    rs->last_rms_move, rs->seconds, rs->nn_cv_before, rs->nn_cv_after);
        }
    }
    st->env_valid = r == LU_OK;
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_bssrdf_gpu_create(&st->gpu, err);
    if (r == LU_OK && st->p[P_STATS] != 0.0)
        for (int i = 0; i < st->tcount; i++)
            lu_log_msg(LU_LOG_INFO,
                    "bssrdf: object %d: %s profile, %dx%d table, r_max %.4g (T: %.4g up to d = %.4g) scene units, "
                    "mfp %.4g\n",
                    st->t[i].object, st->t[i].prof.kind ? "2D" : "1D", st->t[i].prof.nr, st->t[i].prof.nd,
                    st->t[i].prof.r_max, st->t[i].prof.r_max_t, st->t[i].prof.d_t_cut, st->t[i].prof.mfp);
    if (r != LU_OK) {
        bssrdf_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

/* The prefilter level for a sample standing for surface area `area`: a
 * disc of twice that area (radius sqrt(2 area / pi)), so that neighbouring
 * samples' discs overlap instead of leaving the gaps discs leave between
 * square cells; levels sit at rho0 sqrt(2)^(k-1) (in the table's units,
 * world / r_scale), nearest in log. */
static float splat_level(const bssrdf_state *st, const tobject *t, double area) {
    if (t->prof.levels <= 1 || !(area > 0.0)) return 0.0f;
    double rho = sqrt(2.0 * area / M_PI) / st->p[P_SPLAT_SCALE];
    double k = 1.0 + 2.0 * log2(rho / t->prof.rho0);
    if (k < 0.5) return 0.0f;
    return (float)fmin(floor(k + 0.5), t->prof.levels - 1);
}

/* ---- per frame: lights and light-space maps ------------------------------------------------ */

/* Texel rectangle of box b in view v; false if b is entirely behind it. */
static bool project_box(const lu_k_lightview *v, lu_aabb b, int res, int rect[4]) {
    float umin = 1e30f, umax = -1e30f, vmin = 1e30f, vmax = -1e30f;
    int behind = 0;
    for (int k = 0; k < 8; k++) {
        lu_vec3 c = lu_v3(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z);
        lu_vec3 uvd = lu_k_lightview_project(*v, c);
        if (!v->ortho && uvd.z < 0.0f) {
            behind++;
            continue;
        }
        umin = fminf(umin, uvd.x);
        umax = fmaxf(umax, uvd.x);
        vmin = fminf(vmin, uvd.y);
        vmax = fmaxf(vmax, uvd.y);
    }
    if (behind == 8) return false;
    if (behind > 0) umin = vmin = 0.0f, umax = vmax = 1.0f; /* straddles the light: the whole face */
    rect[0] = (int)fmaxf(0.0f, floorf(umin * res));
    rect[1] = (int)fmaxf(0.0f, floorf(vmin * res));
    rect[2] = (int)fminf((float)res, ceilf(umax * res));
    rect[3] = (int)fminf((float)res, ceilf(vmax * res));
    return rect[2] > rect[0] && rect[3] > rect[1];
}

typedef struct cast_job {
    bssrdf_state *st;
    const lu_scene *scene;
    lmap *map;
    float *depth;     /* res^2 */
    int res;
} cast_job;

static void cast_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    cast_job *j = ctx;
    bssrdf_state *st = j->st;
    lmap *m = j->map;
    int w = m->x1 - m->x0;
    for (int64_t y = begin + m->y0; y < end + m->y0; y++) {
        for (int x = m->x0; x < m->x1; x++) {
            lmap_texel *tx = &m->tex[(size_t)(y - m->y0) * w + (x - m->x0)];
            tx->object = -1;
            lu_k_lightray ray = lu_k_lightview_ray(m->view, ((float)x + 0.5f) / (float)j->res, ((float)y + 0.5f) / (float)j->res);
            lu_hit h;
            if (!lu_accel_closest(st->all, ray.origin, ray.dir, 0.0f, 1e30f, &h)) continue;
            j->depth[(size_t)y * j->res + x] = h.t;
            const lu_object *ob = &j->scene->objects[h.mesh_id];
            lu_vec3 ng = h.ng;
            if (lu_v3_dot(ng, ray.dir) > 0.0f) continue; /* a back face: the light is inside */
            int ti = st->tindex[h.mesh_id];
            if (ti < 0) continue;
            const uint32_t *tri = &ob->mesh.indices[3u * h.prim_id];
            float w0 = 1.0f - h.u - h.v;
            lu_vec3 n = lu_v3_norm(lu_v3_add(lu_v3_add(lu_v3_scale(ob->mesh.normals[tri[0]], w0),
                                                       lu_v3_scale(ob->mesh.normals[tri[1]], h.u)),
                                             lu_v3_scale(ob->mesh.normals[tri[2]], h.v)));
            if (lu_v3_dot(n, ng) < 0.0f) n = ng;
            tx->object = (int)h.mesh_id;
            tx->pos = lu_v3_madd(ray.origin, ray.dir, h.t);
            tx->nrm = n;
            /* Thickness: where the light ray leaves this object again. */
            lu_hit e;
            const tobject *t = &st->t[ti];
            if (lu_accel_closest(t->own, tx->pos, ray.dir, 2.0f * st->eps, 1e30f, &e)) {
                tx->thick = e.t;
                tx->back = lu_v3_madd(tx->pos, ray.dir, e.t);
            } else {
                tx->thick = 1e9f;
                tx->back = lu_v3_madd(tx->pos, ray.dir, 10.0f * t->prof.r_max * (float)st->p[P_SPLAT_SCALE]);
            }
        }
    }
}

static lu_result grow(void **p, size_t *cap, size_t need, size_t elem, lu_error *err) {
    if (need <= *cap) return LU_OK;
    size_t n = *cap ? *cap : 1024;
    while (n < need) n *= 2;
    void *q = lu_realloc(*p, n * elem);
    if (!q) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory (%zu bytes)", n * elem);
    *p = q;
    *cap = n;
    return LU_OK;
}

/* View vi's light-space map: the texels over the objects' region ray cast
 * into its shadow map (reset to "nothing") and its regions of interest. */
static lu_result cast_view(bssrdf_state *st, const lu_scene *scene, int vi, lslot *slot, lu_error *err) {
    int res = (int)st->p[P_MAP_RES];
    lmap *m = &st->maps[vi];
    float *depth = st->shadow + (size_t)vi * res * res;
    for (size_t i = 0; i < (size_t)res * res; i++) depth[i] = 1e30f;
    int rect[4];
    if (!lu_aabb_valid(st->objects_box) || !project_box(&m->view, st->objects_box, res, rect)) return LU_OK;
    m->x0 = rect[0], m->y0 = rect[1], m->x1 = rect[2], m->y1 = rect[3];
    m->tex = lu_malloc((size_t)(m->x1 - m->x0) * (m->y1 - m->y0) * sizeof *m->tex);
    if (!m->tex) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for a light-space map");
    cast_job j = {st, scene, m, depth, res};
    lu_parallel_for(m->y1 - m->y0, 4, cast_rows, &j, NULL);
    slot->texels += (long long)(m->x1 - m->x0) * (m->y1 - m->y0);
    /* Regions of interest: where each translucent object shows in the map
     * (tighter than the projected bounding box of the thesis, and exact
     * for cube faces the box straddles). */
    m->roi = lu_malloc((size_t)(st->tcount ? st->tcount : 1) * 4 * sizeof *m->roi);
    if (!m->roi) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    for (int t = 0; t < st->tcount; t++) {
        m->roi[4 * t] = m->roi[4 * t + 1] = INT32_MAX;
        m->roi[4 * t + 2] = m->roi[4 * t + 3] = INT32_MIN;
    }
    for (int y = m->y0; y < m->y1; y++)
        for (int x = m->x0; x < m->x1; x++) {
            int o = m->tex[(size_t)(y - m->y0) * (m->x1 - m->x0) + (x - m->x0)].object;
            if (o < 0) continue;
            int *rc = &m->roi[4 * st->tindex[o]];
            rc[0] = x < rc[0] ? x : rc[0];
            rc[1] = y < rc[1] ? y : rc[1];
            rc[2] = x + 1 > rc[2] ? x + 1 : rc[2];
            rc[3] = y + 1 > rc[3] ? y + 1 : rc[3];
        }
    return LU_OK;
}

static void free_maps(bssrdf_state *st) {
    if (st->maps)
        for (int v = 0; v < st->view_count; v++) {
            lu_free(st->maps[v].tex);
            lu_free(st->maps[v].roi);
        }
    lu_free(st->maps);
    st->maps = NULL;
}

/* Light l's record, views and maps (bssrdf.maps). Its views keep the slots
 * [slot->first_view, + count) a full pass gives them. */
static lu_result build_light(bssrdf_state *st, const lu_frame *f, int l, const lu_lightviews *lv, lu_error *err) {
    const lu_scene *scene = f->scene;
    const lu_light *li = &scene->lights[l];
    lslot *slot = &st->slots[l];
    float *L = st->lights + (size_t)l * LU_K_BSSRDF_LIGHT_FLOATS;
    slot->texels = 0;
    slot->view_count = lv->count;
    if (li->type == LU_LIGHT_ENVIRONMENT) {
        L[3] = -1.0f;
        return LU_OK;
    }
    lu_k_light k = f->rec->scene_lights[l];
    L[0] = k.position.x, L[1] = k.position.y, L[2] = k.position.z, L[3] = (float)k.type;
    L[4] = k.direction.x, L[5] = k.direction.y, L[6] = k.direction.z, L[7] = k.cos_inner;
    L[8] = k.intensity.x, L[9] = k.intensity.y, L[10] = k.intensity.z, L[11] = k.cos_outer;
    L[12] = (float)slot->first_view;
    L[13] = (float)lv->count;
    for (int fi = 0; fi < lv->count; fi++) {
        int vi = slot->first_view + fi;
        const lu_k_lightview *v = &lv->view[fi];
        float *V = st->views + (size_t)vi * LU_K_BSSRDF_VIEW_FLOATS;
        V[0] = v->origin.x, V[1] = v->origin.y, V[2] = v->origin.z, V[3] = (float)v->ortho;
        V[4] = v->axis_u.x, V[5] = v->axis_u.y, V[6] = v->axis_u.z, V[7] = v->extent_u;
        V[8] = v->axis_v.x, V[9] = v->axis_v.y, V[10] = v->axis_v.z, V[11] = v->extent_v;
        V[12] = v->axis_w.x, V[13] = v->axis_w.y, V[14] = v->axis_w.z, V[15] = v->depth_far;
        lmap *m = &st->maps[vi];
        lu_free(m->tex);
        lu_free(m->roi);
        memset(m, 0, sizeof *m);
        m->view = *v;
        m->light = l;
        lu_result r = cast_view(st, scene, vi, slot, err);
        if (r != LU_OK) return r;
    }
    lu_frame_rebuilt(f, "bssrdf.maps");
    return LU_OK;
}

/* Brings the lights' records and maps up to date: every light when the
 * lights were added or removed, the geometry changed or a light's view count
 * changed (the view slots move), else only the lights that changed.
 * redo[l] says which were rebuilt. */
static lu_result build_lights(bssrdf_state *st, const lu_frame *f, bool redo[64], lu_error *err) {
    const lu_scene *scene = f->scene;
    int res = (int)st->p[P_MAP_RES];
    if (scene->light_count > 64) return lu_fail(err, LU_ERR_LIMIT, "bssrdf: %d lights (at most 64)", scene->light_count);
    lu_lightviews lv[64];
    int total = 0;
    bool all = !st->lights_valid || scene->light_count != st->light_count || (f->changed & LU_CHANGE_GEOMETRY);
    for (int l = 0; l < scene->light_count; l++) {
        lu_lightviews_for_light(&scene->lights[l], st->objects_box, &lv[l]);
        total += lv[l].count;
        if (!all && lv[l].count != st->slots[l].view_count) all = true;
    }
    bool any = all;
    for (int l = 0; l < scene->light_count; l++) any |= redo[l] = all || lu_frame_light_changed(f, l);
    st->scene[LU_K_BSSRDF_SCENE_LIGHTS] = (float)scene->light_count;
    if (!any) return LU_OK;
    st->lights_valid = false;
    if (all) {
        free_maps(st);
        lu_free(st->lights);
        lu_free(st->views);
        st->light_count = scene->light_count;
        st->view_count = 0;
        size_t nl = scene->light_count > 0 ? (size_t)scene->light_count : 1u;
        st->lights = lu_calloc(nl * LU_K_BSSRDF_LIGHT_FLOATS, sizeof(float));
        size_t nv = total > 0 ? (size_t)total : 1u;
        st->views = lu_calloc(nv * LU_K_BSSRDF_VIEW_FLOATS, sizeof(float));
        st->maps = lu_calloc(nv, sizeof *st->maps);
        if (!st->lights || !st->views || !st->maps) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
        if ((int)nl > st->slot_count) {
            lslot *sl = lu_realloc(st->slots, nl * sizeof *sl);
            if (!sl) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
            memset(sl + st->slot_count, 0, (nl - (size_t)st->slot_count) * sizeof *sl);
            st->slots = sl;
            st->slot_count = (int)nl;
        }
        lu_result r = grow((void **)&st->shadow, &st->shadow_cap, nv * (size_t)res * (size_t)res, sizeof(float), err);
        if (r != LU_OK) return r;
        if (total == 0)
            for (size_t i = 0; i < (size_t)res * res; i++) st->shadow[i] = 1e30f;
        for (int l = 0; l < scene->light_count; l++) {
            st->slots[l].first_view = st->view_count;
            st->view_count += lv[l].count;
        }
    }
    for (int l = 0; l < scene->light_count; l++) {
        if (!redo[l]) continue;
        lu_result r = build_light(st, f, l, &lv[l], err);
        if (r != LU_OK) return r;
    }
    st->stats.map_texels = 0;
    for (int l = 0; l < scene->light_count; l++) st->stats.map_texels += st->slots[l].texels;
    st->lights_valid = true;
    return LU_OK;
}

/* ---- per frame: samples -> splats ------------------------------------------------------------ */

static uint32_t hash3(uint32_t a, uint32_t b, uint32_t c) {
    uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u ^ (c + 0x165667B1u) * 0xC2B2AE3Du;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 12;
    h *= 0x297A2D39u;
    h ^= h >> 15;
    return h;
}

static const lmap_texel *texel_at(const lmap *m, int x, int y) {
    if (x < m->x0 || x >= m->x1 || y < m->y0 || y >= m->y1) return NULL;
    return &m->tex[(size_t)(y - m->y0) * (m->x1 - m->x0) + (x - m->x0)];
}

/* Reads the map at (u, v) for object `obj`: bilinear where the four texels
 * around it all show obj at similar depths (GL_LINEAR, thesis 5.2.2), else
 * the texel under (u, v); false where that is not obj (the flag). */
static bool read_map(const lmap *m, int res, int obj, float u, float v, lmap_texel *out) {
    float fx = u * (float)res - 0.5f, fy = v * (float)res - 0.5f;
    int x0 = (int)floorf(fx), y0 = (int)floorf(fy);
    float ax = fx - (float)x0, ay = fy - (float)y0;
    const lmap_texel *t[4] = {texel_at(m, x0, y0), texel_at(m, x0 + 1, y0), texel_at(m, x0, y0 + 1),
                              texel_at(m, x0 + 1, y0 + 1)};
    bool ok = true;
    for (int i = 0; i < 4; i++) ok = ok && t[i] && t[i]->object == obj;
    if (ok) {
        /* Neighbouring texels on different folds of the surface must not blend. */
        float spread = 0.0f;
        for (int i = 1; i < 4; i++) spread = fmaxf(spread, lu_v3_len(lu_v3_sub(t[i]->pos, t[0]->pos)));
        float dist = m->view.ortho ? 1.0f : lu_v3_len(lu_v3_sub(t[0]->pos, m->view.origin));
        float footprint = 2.0f * fmaxf(m->view.extent_u, m->view.extent_v) * dist / (float)res;
        ok = spread < 8.0f * footprint;
    }
    if (ok) {
        float w[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
        lmap_texel r = {lu_v3s(0), lu_v3s(0), lu_v3s(0), 0.0f, obj};
        for (int i = 0; i < 4; i++) {
            r.pos = lu_v3_madd(r.pos, t[i]->pos, w[i]);
            r.nrm = lu_v3_madd(r.nrm, t[i]->nrm, w[i]);
            r.back = lu_v3_madd(r.back, t[i]->back, w[i]);
            r.thick += w[i] * t[i]->thick;
        }
        r.nrm = lu_v3_norm(r.nrm);
        *out = r;
        return true;
    }
    const lmap_texel *n = texel_at(m, (int)floorf(u * (float)res), (int)floorf(v * (float)res));
    if (!n || n->object != obj) return false;
    *out = *n;
    return true;
}

static lu_result push_splat(lu_k_splat **splats, int *count, int *cap_io, const lu_k_splat *s, lu_error *err) {
    size_t cap = (size_t)*cap_io;
    lu_result r = grow((void **)splats, &cap, (size_t)*count + 1, sizeof **splats, err);
    *cap_io = (int)cap;
    if (r != LU_OK) return r;
    (*splats)[(*count)++] = *s;
    return LU_OK;
}

/* Light l's splats (bssrdf.splats), finished for their objects' materials. */
static lu_result light_splats(bssrdf_state *st, const lu_frame *frame, int l, lu_error *err) {
    int res = (int)st->p[P_MAP_RES];
    float jitter = (float)st->p[P_JITTER];
    uint32_t seed = (uint32_t)st->p[P_SEED];
    lslot *slot = &st->slots[l];
    slot->splat_count = 0;
    {
        const float *L = st->lights + (size_t)l * LU_K_BSSRDF_LIGHT_FLOATS;
        if (L[3] < 0.0f) return LU_OK;
        int first = (int)L[12], count = (int)L[13];
        lu_k_light kl = frame->rec->scene_lights[l];
        for (int ti = 0; ti < st->tcount; ti++) {
            const tobject *t = &st->t[ti];
            int rects[6][4];
            bool vis[6];
            double area = 0.0;
            for (int f = 0; f < count; f++) {
                const lmap *m = &st->maps[first + f];
                vis[f] = m->tex && m->roi;
                if (!vis[f]) continue;
                memcpy(rects[f], &m->roi[4 * ti], sizeof rects[f]);
                vis[f] = rects[f][2] > rects[f][0] && rects[f][3] > rects[f][1];
                if (vis[f]) area += (double)(rects[f][2] - rects[f][0]) * (rects[f][3] - rects[f][1]);
            }
            if (area <= 0.0) continue;
            for (int f = 0; f < count; f++) {
                if (!vis[f]) continue;
                const lmap *m = &st->maps[first + f];
                const lu_k_lightview *v = &m->view;
                double w = rects[f][2] - rects[f][0], h = rects[f][3] - rects[f][1];
                double n = st->p[P_SPLATS] * w * h / area;
                int nx = (int)fmax(1.0, floor(sqrt(n * w / h) + 0.5)), ny = (int)fmax(1.0, floor(n / nx + 0.5));
                double du = w / ((double)res * nx), dv = h / ((double)res * ny);
                for (int j = 0; j < ny; j++)
                    for (int i = 0; i < nx; i++) {
                        uint32_t hsh = hash3(seed * 977u + (uint32_t)(first + f), (uint32_t)t->object * 65537u + (uint32_t)j,
                                             (uint32_t)i);
                        float jx = jitter * ((float)(hsh & 0xffff) / 65536.0f - 0.5f);
                        float jy = jitter * ((float)(hsh >> 16) / 65536.0f - 0.5f);
                        float u = (float)(rects[f][0] / (double)res + (i + 0.5 + jx) * du);
                        float vv = (float)(rects[f][1] / (double)res + (j + 0.5 + jy) * dv);
                        lmap_texel tx;
                        if (!read_map(m, res, t->object, u, vv, &tx)) continue;
                        lu_k_light_sample ls = lu_k_light_arrive(kl, tx.pos);
                        float cos_i = fmaxf(lu_v3_dot(tx.nrm, ls.wl), 0.0f);
                        float ft = 1.0f - lu_k_fresnel_reflectance(cos_i, t->eta_top);
                        /* Area of the cell projected perpendicular to the light:
                         * its solid angle times distance^2 (point, spot), or its
                         * plane area (directional). */
                        double aperp = 4.0 * v->extent_u * v->extent_v * du * dv;
                        if (!v->ortho) {
                            double su = (2.0 * u - 1.0) * v->extent_u, sv = (2.0 * vv - 1.0) * v->extent_v;
                            double q = 1.0 + su * su + sv * sv;
                            aperp *= (double)ls.dist * ls.dist / (q * sqrt(q));
                        }
                        lu_k_splat s;
                        memset(&s, 0, sizeof s);
                        s.position = tx.pos;
                        s.normal = tx.nrm;
                        s.thickness = tx.thick;
                        s.back = tx.back;
                        s.object = t->object;
                        s.flux = lu_v3_scale(ls.irradiance, (float)(ft * aperp));
                        if (lu_v3_maxc(s.flux) <= 0.0f) continue;
                        /* the surface area of the cell: its projection over the cosine */
                        s.level = splat_level(st, t, aperp / fmax(cos_i, 0.05));
                        lu_result r = push_splat(&slot->splats, &slot->splat_count, &slot->splat_cap, &s, err);
                        if (r != LU_OK) return r;
                    }
            }
        }
    }
    for (int i = 0; i < slot->splat_count; i++)
        slot->splats[i] = lu_k_bssrdf_splat_finish(lu_k_bssrdf_mat_load(&st->kctx, slot->splats[i].object), slot->splats[i]);
    lu_frame_rebuilt(frame, "bssrdf.splats");
    return LU_OK;
}

/* Every light's splats in scene order, then the environment splats: the
 * order of the binning and of the per-pixel sums. */
static lu_result gather_splats(bssrdf_state *st, const lu_scene *scene, lu_error *err) {
    st->splat_count = 0;
    for (int l = 0; l < scene->light_count; l++) {
        const lslot *slot = &st->slots[l];
        for (int i = 0; i < slot->splat_count; i++) {
            lu_result r = push_splat(&st->splats, &st->splat_count, &st->splat_cap, &slot->splats[i], err);
            if (r != LU_OK) return r;
        }
    }
    st->stats.env_splats = 0;
    for (int ti = 0; ti < st->tcount; ti++)
        for (int i = 0; i < st->t[ti].env_count; i++) {
            lu_k_splat s = lu_k_bssrdf_splat_finish(lu_k_bssrdf_mat_load(&st->kctx, st->t[ti].object), st->t[ti].env[i]);
            lu_result r = push_splat(&st->splats, &st->splat_count, &st->splat_cap, &s, err);
            if (r != LU_OK) return r;
            st->stats.env_splats++;
        }
    st->stats.splats = st->splat_count;
    return LU_OK;
}

/* ---- per frame: G-buffer, binning, splat + shade ------------------------------------------------ */

typedef struct frame_job {
    bssrdf_state *st;
    const lu_scene *scene;
    lu_k_camera cam;
    int width, height, tiles_x, tiles_y;
    lu_image *out;
} frame_job;

static void gbuffer_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    frame_job *j = ctx;
    bssrdf_state *st = j->st;
    lu_vec3 o = j->scene->camera.position;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->width; x++) {
            lu_k_gbuf *g = &st->gbuf[(size_t)y * j->width + x];
            memset(g, 0, sizeof *g);
            g->object = -1;
            lu_vec3 d = lu_k_camera_dir(j->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_hit h;
            if (!st->all || !lu_accel_closest(st->all, o, d, 0.0f, 1e30f, &h)) continue;
            const lu_object *ob = &j->scene->objects[h.mesh_id];
            const uint32_t *tri = &ob->mesh.indices[3u * h.prim_id];
            float w0 = 1.0f - h.u - h.v;
            lu_vec3 n = lu_v3_norm(lu_v3_add(lu_v3_add(lu_v3_scale(ob->mesh.normals[tri[0]], w0),
                                                       lu_v3_scale(ob->mesh.normals[tri[1]], h.u)),
                                             lu_v3_scale(ob->mesh.normals[tri[2]], h.v)));
            lu_vec3 ng = h.ng;
            if (lu_v3_dot(ng, d) > 0.0f) ng = lu_v3_neg(ng);
            if (lu_v3_dot(n, ng) < 0.0f) n = lu_v3_neg(n);
            g->object = (int)h.mesh_id;
            g->position = lu_v3_madd(o, d, h.t);
            g->normal = n;
        }
}

static lu_k_rect splat_rect(const frame_job *j, const lu_k_splat *s, lu_k_bssrdf_mat m) {
    lu_vec3 cp = j->scene->camera.position;
    float radius = lu_k_bssrdf_radius(m), radius_t = lu_k_bssrdf_radius_t(m, s->thickness);
    lu_k_rect r = lu_k_ball_screen_rect(cp, j->cam.right, j->cam.up, j->cam.forward, j->width, j->height, s->position,
                                         radius);
    if (radius_t > 0.0f) {
        lu_k_rect b = lu_k_ball_screen_rect(cp, j->cam.right, j->cam.up, j->cam.forward, j->width, j->height, s->back,
                                             radius_t);
        if (b.x1 > b.x0 && b.y1 > b.y0) {
            if (r.x1 <= r.x0 || r.y1 <= r.y0) r = b;
            r.x0 = r.x0 < b.x0 ? r.x0 : b.x0;
            r.y0 = r.y0 < b.y0 ? r.y0 : b.y0;
            r.x1 = r.x1 > b.x1 ? r.x1 : b.x1;
            r.y1 = r.y1 > b.y1 ? r.y1 : b.y1;
        }
    }
    return r;
}

/* Per tile, splats in index order (tile_bins.h). */
static lu_result bin_splats(bssrdf_state *st, frame_job *j, lu_error *err) {
    lu_result r = grow((void **)&st->rects, &st->rects_cap, st->splat_count ? (size_t)st->splat_count : 1u,
                       sizeof *st->rects, err);
    if (r != LU_OK) return r;
    for (int i = 0; i < st->splat_count; i++)
        st->rects[i] = splat_rect(j, &st->splats[i], lu_k_bssrdf_mat_load(&st->kctx, st->splats[i].object));
    r = lu_tile_bins_build(&st->bins, j->width, j->height, TILE, st->splat_count, st->rects, err);
    st->stats.list_entries = st->bins.entries;
    return r;
}

/* Per tile: splat-major (each splat of the tile's list over the tile's
 * pixels, which stay in L1), then the deferred pass per pixel. The GPU
 * shader runs pixel-major; the sums differ only in float rounding order. */
static void splat_tiles(void *ctx, int64_t begin, int64_t end, int thread) {
    frame_job *j = ctx;
    bssrdf_state *st = j->st;
    const struct lu_k_ctx *kc = &st->kctx;
    lu_k_gbuf g[TILE * TILE];
    lu_vec3 scatter[TILE * TILE];
    lu_k_bssrdf_mat mat[TILE * TILE];
    for (int64_t tile = begin; tile < end; tile++) {
        int tx = (int)(tile % j->tiles_x), ty = (int)(tile / j->tiles_x);
        int x0 = tx * TILE, y0 = ty * TILE;
        int w = j->width - x0 < TILE ? j->width - x0 : TILE, h = j->height - y0 < TILE ? j->height - y0 : TILE;
        int n = 0, any = 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++, n++) {
                g[n] = st->gbuf[(size_t)(y0 + y) * j->width + (x0 + x)];
                scatter[n] = lu_v3s(0.0f);
                mat[n].translucent = 0;
                if (g[n].object >= 0) mat[n] = lu_k_bssrdf_mat_load(kc, g[n].object);
                any |= g[n].object >= 0 && mat[n].translucent;
            }
        for (int k = st->bins.start[tile]; any && k < st->bins.start[tile + 1]; k++) {
            const lu_k_splat s = st->splats[st->bins.list[k]];
            for (int i = 0; i < n; i++) {
                if (g[i].object != s.object || !mat[i].translucent) continue;
                scatter[i] = lu_v3_add(scatter[i], lu_k_bssrdf_splat_eval(kc, mat[i], s, g[i].position, g[i].normal));
            }
        }
        n = 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++, n++) {
                lu_vec3 d = lu_k_camera_dir(j->cam, (float)(x0 + x) + 0.5f, (float)(y0 + y) + 0.5f);
                lu_vec3 c = lu_k_bssrdf_shade(kc, g[n], scatter[n], d);
                float *px = lu_image_px(j->out, x0 + x, y0 + y);
                px[0] = c.x;
                px[1] = c.y;
                px[2] = c.z;
            }
    }
}

/* Processor time of the whole process (all threads, llvmpipe's included):
 * on a shared machine it varies far less than wall time. */
static double cpu_seconds(void) {
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
    return (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec +
           1e-6 * ((double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_usec);
}

/* The environment data and the environment splats' flux (bssrdf.env), when
 * an environment light changed or one was added or removed; the samples'
 * positions depend on the meshes alone and are kept. */
static lu_result update_env(bssrdf_state *st, const lu_frame *f, bool *changed, lu_error *err) {
    const lu_scene *scene = f->scene;
    *changed = false;
    int envs = 0;
    bool stale = !st->env_valid;
    for (int l = 0; l < scene->light_count; l++)
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) envs++, stale |= lu_frame_light_changed(f, l);
    if (!stale && envs == st->env_lights) return LU_OK;
    st->env_valid = false;
    double L[27];
    lu_result r = fill_env(st, scene, L, &envs, err);
    for (int i = 0; i < st->tcount && r == LU_OK; i++) {
        tobject *t = &st->t[i];
        if (envs > 0 && t->env) env_flux(t, L);
        else if (envs > 0) r = prepare_env_samples(st, scene, t, L, err);
        else {
            lu_free(t->env);
            t->env = NULL;
            t->env_count = 0;
        }
    }
    if (r != LU_OK) return r;
    st->env_lights = envs;
    st->env_valid = true;
    *changed = true;
    if (envs) lu_frame_rebuilt(f, "bssrdf.env");
    return LU_OK;
}

static lu_result bssrdf_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    bssrdf_state *st = state;
    if (scene->object_count != st->object_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "bssrdf: the scene's objects changed since prepare");
    const lu_camera *c = &scene->camera;
    frame_job j = {st, scene, frame->rec->cam,
                   c->width, c->height, (c->width + TILE - 1) / TILE, (c->height + TILE - 1) / TILE, out};
    double t0 = lu_time_seconds(), c0 = cpu_seconds();
    /* Light side: none of it depends on the camera. */
    bool redo[64] = {false}, env = false;
    lu_result r = build_lights(st, frame, redo, err);
    if (r == LU_OK) r = update_env(st, frame, &env, err);
    if (r != LU_OK) return r;
    bool lights = env;
    for (int l = 0; l < scene->light_count; l++) lights |= redo[l];
    st->scene[LU_K_BSSRDF_SCENE_BACKGROUND] = scene->background.x;
    st->scene[LU_K_BSSRDF_SCENE_BACKGROUND + 1] = scene->background.y;
    st->scene[LU_K_BSSRDF_SCENE_BACKGROUND + 2] = scene->background.z;
    unsigned dirty = (lights || (frame->changed & LU_CHANGE_BACKGROUND) ? LU_BSSRDF_GPU_DATA : 0u) |
                     (lights ? LU_BSSRDF_GPU_SHADOW : 0u);
    st->kctx = (struct lu_k_ctx){{st->table, st->materials, st->lights, st->views, st->env, st->scene},
                                 st->shadow, (int)st->p[P_MAP_RES]};
    double t1 = lu_time_seconds();
    if (lights || !st->splats_valid) {
        st->splats_valid = false;
        for (int l = 0; l < scene->light_count && r == LU_OK; l++)
            if (redo[l]) r = light_splats(st, frame, l, err);
        if (r == LU_OK) r = gather_splats(st, scene, err);
        if (r != LU_OK) return r;
        st->splats_valid = true;
        dirty |= LU_BSSRDF_GPU_SPLATS;
    }
    double t2 = lu_time_seconds();
    /* Camera side. */
    if (lu_frame_stale(frame, st->gbuf_valid, LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY)) {
        st->gbuf_valid = false;
        r = grow((void **)&st->gbuf, &st->gbuf_cap, (size_t)c->width * c->height, sizeof *st->gbuf, err);
        if (r != LU_OK) return r;
        lu_parallel_for(c->height, 4, gbuffer_rows, &j, NULL);
        st->gbuf_valid = true;
        dirty |= LU_BSSRDF_GPU_GBUF;
        lu_frame_rebuilt(frame, "bssrdf.gbuffer");
    }
    double t3 = lu_time_seconds();
    if ((dirty & LU_BSSRDF_GPU_SPLATS) || lu_frame_stale(frame, st->bins_valid, LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY)) {
        st->bins_valid = false;
        r = bin_splats(st, &j, err);
        if (r != LU_OK) return r;
        st->bins_valid = true;
        dirty |= LU_BSSRDF_GPU_TILES;
        lu_frame_rebuilt(frame, "bssrdf.bins");
    }
    double t4 = lu_time_seconds();
    if (st->backend == LU_BACKEND_GPU) {
        lu_bssrdf_gpu_frame f;
        memset(&f, 0, sizeof f);
        const float *bufs[6] = {st->table, st->materials, st->lights, st->views, st->env, st->scene};
        size_t counts[6] = {st->table_floats, (size_t)(scene->object_count ? scene->object_count : 1) * LU_K_BSSRDF_MAT_FLOATS,
                            (size_t)(scene->light_count ? scene->light_count : 1) * LU_K_BSSRDF_LIGHT_FLOATS,
                            (size_t)(st->view_count ? st->view_count : 1) * LU_K_BSSRDF_VIEW_FLOATS, st->env_floats,
                            LU_K_BSSRDF_SCENE_FLOATS};
        memcpy(f.buf, bufs, sizeof bufs);
        memcpy(f.count, counts, sizeof counts);
        int res = (int)st->p[P_MAP_RES];
        f.shadow = st->shadow;
        f.shadow_count = (size_t)(st->view_count ? st->view_count : 1) * res * res;
        f.map_res = res;
        f.splats = st->splats;
        f.splat_count = st->splat_count;
        f.splat_bytes = sizeof(lu_k_splat);
        f.gbuf = st->gbuf;
        f.width = c->width;
        f.height = c->height;
        f.tile_start = st->bins.start;
        f.tiles_x = j.tiles_x;
        f.tiles_y = j.tiles_y;
        f.tile = TILE;
        f.tile_list = st->bins.list;
        f.list_count = (size_t)st->bins.start[j.tiles_x * j.tiles_y];
        f.cam_right = j.cam.right;
        f.cam_up = j.cam.up;
        f.cam_forward = j.cam.forward;
        f.changed = dirty;
        r = lu_bssrdf_gpu_render(st->gpu, &f, out, err);
        if (r != LU_OK) return r;
    } else {
        lu_frame_for_tiles(frame, TILE, j.tiles_x, j.tiles_y, splat_tiles, &j);
    }
    double t5 = lu_time_seconds();
    st->stats.cpu_ms = 1e3 * (cpu_seconds() - c0);
    st->stats.ms_maps = 1e3 * (t1 - t0);
    st->stats.ms_samples = 1e3 * (t2 - t1);
    st->stats.ms_gbuffer = 1e3 * (t3 - t2);
    st->stats.ms_binning = 1e3 * (t4 - t3);
    st->stats.ms_splat = 1e3 * (t5 - t4);
    if (st->p[P_STATS] != 0.0)
        lu_log_msg(LU_LOG_INFO,
                "bssrdf: frame %dx%d (%s): maps %.1f ms (%lld texels), samples %.1f ms (%d splats, %d environment), "
                "G-buffer %.1f ms, binning %.1f ms (%lld splat-tile pairs), splat+shade %.1f ms; processor time %.1f ms\n",
                c->width, c->height, lu_backend_name(st->backend), st->stats.ms_maps, st->stats.map_texels,
                st->stats.ms_samples, st->stats.splats, st->stats.env_splats, st->stats.ms_gbuffer, st->stats.ms_binning,
                st->stats.list_entries, st->stats.ms_splat, st->stats.cpu_ms);
    return LU_OK;
}

bool lu_bssrdf_last_stats(const lu_renderer *r, lu_bssrdf_frame_stats *out) {
    if (!r || strcmp(r->method->name, "bssrdf") != 0 || !r->state) return false;
    *out = ((const bssrdf_state *)r->state)->stats;
    return true;
}

const lu_method lu_method_bssrdf = {
    .name = "bssrdf",
    .summary = "translucent objects by diffusion profiles (dipole, multipole, coated stacks, normalised diffusion, "
               "photon beam diffusion) and "
               "splatting from light-space sample maps; environment light by SH9 and relaxed surface samples",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params,
    .param_count = P_COUNT,
    .prepare = bssrdf_prepare,
    .render = bssrdf_render,
    .destroy = bssrdf_destroy,
};
