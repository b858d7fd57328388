/* gradient — gradient-based interpolation and dynamic sampling of source
 * radiance in single-scattering media (Ren, Zhou, Lin, Guo 2008), with its
 * two baselines as methods of their own:
 *   gradient  samples (Gaussian centres or stratified) + recursive splitting
 *             by the local shading error (Eq. 5), Eq. 4 interpolation;
 *   rbf       the same initial samples, RBF interpolation without gradients
 *             and without splitting (the paper's Fig. 3a, after Zhou et al.);
 *   pervoxel  source radiance traced at every voxel of the radiance grid
 *             (the paper's Table 2 "per-voxel").
 * All three end in the same view march (lu_view_march.h with the source term
 * from the radiance grid). Per frame: sample set and evaluation (the sample
 * tracing on the backend, the splitting control here), cell lists of the
 * final samples, the radiance grid (one gather per voxel on the backend),
 * the march. The density is a sum of Gaussians plus residual fitted at
 * prepare (gradient_fit.h); the CPU traces the reconstruction, the GPU the
 * scene's grid textures (equal to it up to float rounding). */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "methods/common/gpu_scene.h"
#include "methods/gradient/gradient.h"
#include "methods/gradient/gradient_fit.h"
#include "methods/common/media_ray.h"
#include "methods/common/view_march.h"
#include "methods/frame.h"
#include "methods/methods.h"

/* ---- kernel context: the hooks of lu_gradient.h / lu_view_march.h on the CPU ---- */
struct lu_k_ctx {
    const lu_grid *dens;          /* per medium: the reconstructed density (NULL: constant) */
    const lu_k_medium *km;
    int nm;
    const lu_k_light *kl;
    int nl;
    const lu_media_rays *mr;
    lu_k_gr_params G;
    const float *field;
    const int *cell_begin, *cell_items;
    const float *samples;
    const float *surf;            /* 8 floats per medium: boundary material */
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    return c->dens[m].data ? lu_grid_sample(&c->dens[m], p) : c->km[m].density_scale;
}
static inline int lu_k_medium_count(const struct lu_k_ctx *c) { return c->nm; }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) { return c->km[m]; }
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return c->nl; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) { return c->kl[l]; }
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return c->mr->shadow[((size_t)map * c->mr->shadow_res + j) * c->mr->shadow_res + i];
}
static inline int lu_k_rm_view_first(const struct lu_k_ctx *c, int l) { return c->mr->view_table[2 * l]; }
static inline int lu_k_rm_view_count(const struct lu_k_ctx *c, int l) { return c->mr->view_table[2 * l + 1]; }
static inline lu_k_lightview lu_k_rm_view(const struct lu_k_ctx *c, int v) { return c->mr->views[v]; }
static inline float lu_k_rm_hit_fetch(const struct lu_k_ctx *c, int pixel, int k) {
    return c->mr->hits[(size_t)pixel * LU_MR_HIT_FLOATS + k];
}
static inline float lu_k_rm_span(const struct lu_k_ctx *c, int pixel, int m, int end) {
    return c->mr->spans[((size_t)pixel * c->nm + m) * 2 + end];
}
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    return c->dens[m].data ? lu_majorant_at(&c->mr->majorants[m], bx, by, bz) : c->km[m].density_scale;
}
static inline lu_k_gr_params lu_k_gr_get(const struct lu_k_ctx *c) { return c->G; }
static inline lu_vec3 lu_k_gr_field(const struct lu_k_ctx *c, int i) {
    const float *f = c->field + 3 * (size_t)i;
    return lu_v3(f[0], f[1], f[2]);
}
static inline float lu_k_gr_bmap_at(const struct lu_k_ctx *c, int k) { return c->mr->bmap[k]; }
static inline float lu_k_gr_surf(const struct lu_k_ctx *c, int k) {
    if (k < c->G.surf_normals_at) return c->surf[k];
    if (k < c->G.surf_vis_at) return c->mr->normals[k - c->G.surf_normals_at];
    return c->mr->surface_vis[k - c->G.surf_vis_at];
}
static inline int lu_k_gr_cell_begin(const struct lu_k_ctx *c, int cell) { return c->cell_begin[cell]; }
static inline int lu_k_gr_cell_end(const struct lu_k_ctx *c, int cell) { return c->cell_begin[cell + 1]; }
static inline int lu_k_gr_cell_item(const struct lu_k_ctx *c, int k) { return c->cell_items[k]; }
static inline float lu_k_gr_sample_fetch(const struct lu_k_ctx *c, int j, int k) {
    return c->samples[(size_t)j * LU_K_GR_SAMPLE_FLOATS + k];
}

#include "methods/gradient/lu_gradient.h"
#include "methods/common/lu_sampling.h"

_Static_assert(LU_K_RM_HIT_FLOATS == LU_MR_HIT_FLOATS, "hit record size");
_Static_assert(LU_MR_BMAP_FLOATS == 4, "lu_k_gr_light_transmittance reads 4 floats per texel");
_Static_assert(LU_K_RM_MAX_MEDIA == 8, "lu_k_gr_inscatter takes dens[8]");

/* ---- parameters: pervoxel's are the first P_PERVOXEL_COUNT ---- */
enum {
    P_STEPS, P_SHADOW_RES, P_GRID, P_DELTA1, P_NORMALIZE, P_T_CUT, P_PERVOXEL_COUNT,
    P_GAUSSIANS = P_PERVOXEL_COUNT, P_MAX_RADIUS, P_SEEDS, P_DELTA2, P_LEVELS, P_EPSILON, P_COUNT
};

#define GR_COMMON_PARAMS                                                                                              \
    [P_STEPS] = {"steps", LU_PARAM_INT, 256, 4, 16384, NULL,                                                          \
                 "view march steps across the diagonal of the media's box"},                                          \
    [P_SHADOW_RES] = {"shadow_res", LU_PARAM_INT, 512, 16, 4096, NULL,                                                \
                      "shadow map resolution per light view (opaque objects; plain depth maps with 2x2 PCF)"},        \
    [P_GRID] = {"grid", LU_PARAM_INT, 0, 0, 512, NULL,                                                                \
                "radiance grid voxels along the media box's longest side (0: the density grid's resolution)"},        \
    [P_DELTA1] = {"delta1", LU_PARAM_FLOAT, 0, 0, 16, NULL,                                                           \
                  "volume tracing interval in density voxels (0: exact optical depth through the trilinear grid)"},   \
    [P_NORMALIZE] = {"normalize", LU_PARAM_CHOICE, 2, 0, 2, "none|falloff|emission",                                  \
                     "none: interpolate J as in the paper; falloff: J / (phase I/d^2); emission: J / (phase times "   \
                     "what the light emits, spot cone included), multiplied back per march step (extensions)"},   \
    [P_T_CUT] = LU_VIEW_MARCH_T_CUT_PARAM,

static const lu_param_desc k_params_pervoxel[P_PERVOXEL_COUNT] = {GR_COMMON_PARAMS};

#define GR_SAMPLE_PARAMS(levels_default)                                                                              \
    GR_COMMON_PARAMS                                                                                                  \
    [P_GAUSSIANS] = {"gaussians", LU_PARAM_INT, 512, 1, 65536, NULL,                                                  \
                     "Gaussians fitted to each grid (their centres are the initial samples, R = 3 r)"},               \
    [P_MAX_RADIUS] = {"max_radius", LU_PARAM_FLOAT, 4, 1, 16, NULL,                                                  \
                      "largest Gaussian radius r_j the fit may choose, in density voxels"},                           \
    [P_SEEDS] = {"seeds", LU_PARAM_CHOICE, 0, 0, 2, "auto|gaussians|stratified",                                      \
                 "initial samples: Gaussian centres (grids) or jittered stratified (auto: stratified for constant "  \
                 "media)"},                                                                                           \
    [P_DELTA2] = {"delta2", LU_PARAM_FLOAT, 0.5, 0.01, 8, NULL,                                                       \
                  "central-difference offset for the gradient, in radiance-grid voxels"},                             \
    [P_LEVELS] = {"levels", LU_PARAM_INT, levels_default, 0, 3, NULL,                                                 \
                  "splitting levels (grids 16^3, 32^3, 64^3; at most half the density resolution)"},                  \
    [P_EPSILON] = {"epsilon", LU_PARAM_FLOAT, 0.02, 0, 1e6, NULL,                                                     \
                   "split threshold on E_j (Eq. 5), relative to the mean shading magnitude of the initial samples"},

static const lu_param_desc k_params_gradient[P_COUNT] = {GR_SAMPLE_PARAMS(3)};
static const lu_param_desc k_params_rbf[P_COUNT] = {GR_SAMPLE_PARAMS(0)};

typedef struct gr_state {
    int mode;                  /* LU_K_GR_* */
    lu_backend backend;
    double p[P_COUNT];
    const char *who;           /* method name for messages */
    lu_media_rays mr;          /* camera hits/spans, light views, shadow maps */
    int nm;
    lu_grid *dens;             /* per medium: reconstructed density (data NULL for constant media) */
    lu_gauss_fit *fits;        /* per medium */
    lu_k_medium *km;
    lu_k_light *kl;
    int nl;
    float eps;
    float density_voxel;       /* world size of the finest density voxel */
    int density_res;           /* largest density grid dimension */
    lu_aabb box;               /* radiance grid box */
    /* samples: all evaluated this frame; active ones form the final set */
    float *smp;
    float *tau, *E;
    unsigned char *active;
    int n, cap;
    float *final;              /* compacted final samples */
    int nfinal;
    int *cell_begin, *cell_items;
    size_t cells_cap, items_cap;
    float *field;
    size_t field_cap;
    float surf[8 * LU_K_RM_MAX_MEDIA]; /* boundary materials (lu_k_gr_surf) */
    lu_gradient_stats stats;
    struct lu_k_ctx kctx;
    lu_gradient_frame frame;
    lu_k_camera cam;
    const lu_scene *scene;
    lu_image *out;
    lu_gradient_gpu *gpu;
} gr_state;

static void gr_destroy(void *state) {
    gr_state *st = state;
    if (!st) return;
    lu_gradient_gpu_destroy(st->gpu);
    lu_media_rays_free(&st->mr);
    for (int m = 0; m < st->nm; m++) {
        if (st->dens) lu_grid_destroy(&st->dens[m]);
        if (st->fits) lu_gauss_fit_free(&st->fits[m]);
    }
    free(st->dens);
    free(st->fits);
    free(st->km);
    free(st->kl);
    free(st->smp);
    free(st->tau);
    free(st->E);
    free(st->active);
    free(st->final);
    free(st->cell_begin);
    free(st->cell_items);
    free(st->field);
    free(st);
}

/* World length of one index unit of a medium (cube root of the map's volume scale). */
static float index_scale(const lu_affine *a) {
    const float(*m)[4] = a->m;
    float det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    return cbrtf(fabsf(det));
}

static lu_result gr_prepare_mode(const lu_scene *scene, const double *params, int param_count, lu_backend backend,
                                 int mode, void **out, lu_error *err) {
    const char *who = mode == LU_K_GR_GRADIENT ? "gradient" : mode == LU_K_GR_RBF ? "rbf" : "pervoxel";
    gr_state *st = calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
    st->mode = mode;
    st->backend = backend;
    /* Defaults for the sample parameters pervoxel does not have. */
    for (int i = 0; i < P_COUNT; i++) st->p[i] = k_params_gradient[i].def;
    for (int i = 0; i < param_count; i++) st->p[i] = params[i];
    st->nm = scene->medium_count;
    lu_result r = LU_OK;
    if (scene->medium_count < 1)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "%s: the scene has no participating medium (it renders media only)", who);
    else if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "%s: %d media (at most %d)", who, scene->medium_count, LU_K_RM_MAX_MEDIA);
    for (int m = 1; m < scene->medium_count && r == LU_OK; m++)
        if (scene->media[m].phase_g != scene->media[0].phase_g)
            r = lu_fail(err, LU_ERR_UNSUPPORTED,
                        "%s: media %d and 0 have different phase_g (%g vs %g); the source radiance field holds one phase",
                        who, m, scene->media[m].phase_g, scene->media[0].phase_g);
    st->eps = lu_scene_ray_epsilon(scene);
    st->who = who;
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, (int)st->p[P_SHADOW_RES], true, err);
    size_t nm = scene->medium_count ? (size_t)scene->medium_count : 1u;
    st->dens = calloc(nm, sizeof *st->dens);
    st->fits = calloc(nm, sizeof *st->fits);
    st->km = calloc(nm, sizeof *st->km);
    if ((!st->dens || !st->fits || !st->km) && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
    st->box = lu_scene_media_bounds(scene);
    st->density_voxel = 0.0f;
    double worst_fit = 0.0;
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        const lu_medium *med = &scene->media[m];
        if (med->kind != LU_DENSITY_GRID) continue;
        float vs = index_scale(&med->index_to_world);
        if (st->density_voxel == 0.0f || vs < st->density_voxel) st->density_voxel = vs;
        int dm = med->grid.nx > med->grid.ny ? med->grid.nx : med->grid.ny;
        if (med->grid.nz > dm) dm = med->grid.nz;
        if (dm > st->density_res) st->density_res = dm;
        /* pervoxel traces the scene's grid; the sample methods the Gaussian representation. */
        if (mode == LU_K_GR_PERVOXEL) {
            r = lu_grid_alloc(&st->dens[m], med->grid.nx, med->grid.ny, med->grid.nz, err);
            if (r == LU_OK) {
                memcpy(st->dens[m].data, med->grid.data, (size_t)med->grid.nx * med->grid.ny * med->grid.nz * 4);
                st->dens[m].index_to_world = med->grid.index_to_world;
            }
            continue;
        }
        r = lu_gauss_fit_grid(&med->grid, (int)st->p[P_GAUSSIANS], (float)st->p[P_MAX_RADIUS], &st->fits[m], err);
        if (r != LU_OK) break;
        st->stats.gaussians += st->fits[m].count;
        st->stats.fit_ms += st->fits[m].ms;
        if (st->fits[m].rel_l2 > worst_fit) worst_fit = st->fits[m].rel_l2;
        double t0 = lu_time_seconds();
        r = lu_gauss_reconstruct(&st->fits[m], &st->dens[m], err);
        st->stats.reconstruct_ms += 1e3 * (lu_time_seconds() - t0);
    }
    st->stats.fit_rel_l2 = worst_fit;
    if (st->density_res == 0) st->density_res = 64;
    if (st->density_voxel == 0.0f && lu_aabb_valid(st->box))
        st->density_voxel = lu_v3_maxc(lu_v3_sub(st->box.hi, st->box.lo)) / 64.0f;
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_gradient_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        gr_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

/* ---- samples ---- */

static lu_result grow(gr_state *st, int need, lu_error *err) {
    if (need <= st->cap) return LU_OK;
    int cap = st->cap ? st->cap : 1024;
    while (cap < need) cap *= 2;
    float *s = realloc(st->smp, (size_t)cap * LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    if (s) st->smp = s;
    float *t = realloc(st->tau, (size_t)cap * sizeof(float));
    if (t) st->tau = t;
    float *e = realloc(st->E, (size_t)cap * sizeof(float));
    if (e) st->E = e;
    unsigned char *a = realloc(st->active, (size_t)cap);
    if (a) st->active = a;
    if (!s || !t || !e || !a) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for %d samples", need);
    st->cap = cap;
    return LU_OK;
}

static lu_result add_sample(gr_state *st, lu_vec3 x, float R, float wgt, float rr, float tau, lu_error *err) {
    lu_result r = grow(st, st->n + 1, err);
    if (r != LU_OK) return r;
    float *s = st->smp + (size_t)st->n * LU_K_GR_SAMPLE_FLOATS;
    memset(s, 0, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    s[0] = x.x, s[1] = x.y, s[2] = x.z, s[3] = R, s[4] = wgt, s[5] = rr;
    st->tau[st->n] = tau;
    st->E[st->n] = 0.0f;
    st->active[st->n] = 1;
    st->n++;
    return LU_OK;
}

static uint32_t hash3(uint32_t a, uint32_t b, uint32_t c) {
    return lu_k_hash_u32(a * 73856093u ^ b * 19349663u ^ c * 83492791u);
}

/* Coverage fill (an extension): the paper assumes the Gaussians' valid
 * spheres cover every point with density; a greedy fit with small radii
 * leaves gaps, which would render black. Vertices of the 16^3 grid G1 with
 * density within half an interval and outside every root sphere become
 * samples of valid radius one interval (every point of a covered G1 cell is
 * within sqrt(3)/2 interval of a vertex). */
static lu_result coverage_fill(gr_state *st, lu_error *err) {
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = lu_v3_maxc(ext) / 16.0f;
    int n[3] = {(int)floorf(ext.x / h) + 1, (int)floorf(ext.y / h) + 1, (int)floorf(ext.z / h) + 1};
    int roots = st->n;
    for (int k = 0; k < n[2]; k++)
        for (int j = 0; j < n[1]; j++)
            for (int i = 0; i < n[0]; i++) {
                lu_vec3 q = lu_v3_add(st->box.lo, lu_v3((float)i * h, (float)j * h, (float)k * h));
                bool dense = false;
                for (int c = 0; c < 27 && !dense; c++) {
                    lu_vec3 o = lu_v3((float)(c % 3 - 1), (float)(c / 3 % 3 - 1), (float)(c / 9 - 1));
                    dense = lu_k_gr_total_density(&st->kctx, lu_v3_madd(q, o, 0.5f * h)) > 0.0f;
                }
                if (!dense) continue;
                bool covered = false;
                for (int s = 0; s < roots && !covered; s++) {
                    const float *p = st->smp + (size_t)s * LU_K_GR_SAMPLE_FLOATS;
                    lu_vec3 d = lu_v3_sub(q, lu_v3(p[0], p[1], p[2]));
                    float R = p[3] - 0.87f * h;
                    covered = R > 0.0f && lu_v3_dot(d, d) < R * R;
                }
                if (covered) continue;
                lu_result r = add_sample(st, q, h, 1.0f, h / 3.0f, -1.0f, err);
                if (r != LU_OK) return r;
            }
    st->stats.fill_samples = st->n - roots;
    return LU_OK;
}

static lu_result root_samples(gr_state *st, const lu_scene *scene, lu_error *err) {
    int seeds = (int)st->p[P_SEEDS];
    bool any_grid = false;
    for (int m = 0; m < scene->medium_count; m++) any_grid = any_grid || scene->media[m].kind == LU_DENSITY_GRID;
    bool stratified = seeds == 2 || (seeds == 0 && !any_grid);
    if (!stratified) {
        for (int m = 0; m < scene->medium_count; m++) {
            const lu_medium *med = &scene->media[m];
            float vs = index_scale(&med->index_to_world);
            for (int j = 0; j < st->fits[m].count; j++) {
                const lu_gauss *q = &st->fits[m].g[j];
                float rw = q->r * vs;
                lu_result r = add_sample(st, lu_affine_point(&med->index_to_world, q->c), 3.0f * rw, q->w, rw, -1.0f, err);
                if (r != LU_OK) return r;
            }
        }
        return coverage_fill(st, err);
    }
    /* Jittered stratified: cubic cells of volume V / count over the media box. */
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = cbrtf(ext.x * ext.y * ext.z / (float)st->p[P_GAUSSIANS]);
    int n[3] = {(int)ceilf(ext.x / h), (int)ceilf(ext.y / h), (int)ceilf(ext.z / h)};
    for (int z = 0; z < n[2]; z++)
        for (int y = 0; y < n[1]; y++)
            for (int x = 0; x < n[0]; x++) {
                uint32_t hsh = hash3((uint32_t)x, (uint32_t)y, (uint32_t)z);
                float jx = ((float)(hsh & 1023u) / 1023.0f - 0.5f) * 0.5f;
                float jy = ((float)((hsh >> 10) & 1023u) / 1023.0f - 0.5f) * 0.5f;
                float jz = ((float)((hsh >> 20) & 1023u) / 1023.0f - 0.5f) * 0.5f;
                lu_vec3 c = lu_v3(fminf(st->box.lo.x + ((float)x + 0.5f + jx) * h, st->box.hi.x),
                                  fminf(st->box.lo.y + ((float)y + 0.5f + jy) * h, st->box.hi.y),
                                  fminf(st->box.lo.z + ((float)z + 0.5f + jz) * h, st->box.hi.z));
                /* Jitter of a quarter cell: every point is within 1.2 h of a sample. */
                lu_result r = add_sample(st, c, 1.5f * h, 1.0f, 0.5f * h, -1.0f, err);
                if (r != LU_OK) return r;
            }
    return LU_OK;
}

typedef struct eval_job {
    gr_state *st;
    int first, want_error;
} eval_job;

static void eval_range(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    eval_job *job = ctx;
    gr_state *st = job->st;
    for (int64_t i = begin; i < end; i++) {
        int j = job->first + (int)i;
        float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 F, gx, gy, gz;
        float E, tau;
        lu_k_gr_eval(&st->kctx, st->kctx.G, lu_v3(s[0], s[1], s[2]), s[3], st->tau[j], job->want_error, &F, &gx, &gy,
                     &gz, &E, &tau);
        memcpy(s + 8, &F, 12);
        memcpy(s + 12, &gx, 12);
        memcpy(s + 16, &gy, 12);
        memcpy(s + 20, &gz, 12);
        st->E[j] = E;
        st->tau[j] = tau;
    }
}

static lu_result eval_samples(gr_state *st, const lu_scene *scene, int first, int count, int want_error, lu_error *err) {
    if (count <= 0) return LU_OK;
    if (st->backend == LU_BACKEND_GPU) {
        st->frame.samples = st->smp;
        st->frame.sample_count = st->n;
        float *et = malloc((size_t)count * 2 * sizeof(float));
        if (!et) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory");
        lu_result r = lu_gradient_gpu_eval(st->gpu, scene, &st->frame, first, count, want_error, st->tau + first, et, err);
        for (int i = 0; r == LU_OK && i < count; i++) {
            st->E[first + i] = et[2 * i];
            st->tau[first + i] = et[2 * i + 1];
        }
        free(et);
        return r;
    }
    eval_job job = {st, first, want_error};
    lu_parallel_for(count, 16, eval_range, &job, NULL);
    return LU_OK;
}

/* Mean shading magnitude of the root samples, R^3 avg(F N) D tau: the unit
 * of the relative split threshold. */
static double error_unit(gr_state *st, int count) {
    double sum = 0.0;
    for (int j = 0; j < count; j++) {
        const float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 x = lu_v3(s[0], s[1], s[2]);
        lu_vec3 N = st->kctx.G.normalize ? lu_k_gr_norm(&st->kctx, st->kctx.G, x) : lu_v3s(1.0f);
        lu_vec3 F = lu_v3(s[8], s[9], s[10]);
        double mag = lu_v3_avg(lu_v3_mul(F, N));
        sum += (double)s[3] * s[3] * s[3] * mag * lu_k_gr_total_density(&st->kctx, x) * st->tau[j];
    }
    return count ? sum / count : 0.0;
}

/* Recursive splitting (Sec. 5): samples of the last level whose E_j exceeds
 * the threshold are replaced by the vertices of the next grid inside their
 * valid sphere (valid radius = that grid's interval), each vertex once. */
static lu_result split_level(gr_state *st, int level, int first, int count, double threshold, bool *added,
                             lu_error *err) {
    *added = false;
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = lu_v3_maxc(ext) / (float)(16 << level);
    int n[3] = {(int)floorf(ext.x / h) + 1, (int)floorf(ext.y / h) + 1, (int)floorf(ext.z / h) + 1};
    size_t nv = (size_t)n[0] * n[1] * n[2];
    unsigned char *mark = calloc(nv, 1);
    if (!mark) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory splitting");
    int splits = 0;
    lu_result r = LU_OK;
    for (int j = first; j < first + count && r == LU_OK; j++) {
        if (!(st->E[j] > threshold)) continue;
        splits++;
        st->active[j] = 0;
        const float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 x = lu_v3(s[0], s[1], s[2]);
        float R = s[3], tau = st->tau[j];
        int lo[3], hi[3];
        float xc[3] = {x.x, x.y, x.z}, bl[3] = {st->box.lo.x, st->box.lo.y, st->box.lo.z};
        for (int a = 0; a < 3; a++) {
            lo[a] = (int)ceilf((xc[a] - R - bl[a]) / h);
            hi[a] = (int)floorf((xc[a] + R - bl[a]) / h);
            if (lo[a] < 0) lo[a] = 0;
            if (hi[a] > n[a] - 1) hi[a] = n[a] - 1;
        }
        for (int k = lo[2]; k <= hi[2] && r == LU_OK; k++)
            for (int jj = lo[1]; jj <= hi[1] && r == LU_OK; jj++)
                for (int i = lo[0]; i <= hi[0] && r == LU_OK; i++) {
                    lu_vec3 q = lu_v3(bl[0] + (float)i * h, bl[1] + (float)jj * h, bl[2] + (float)k * h);
                    lu_vec3 dq = lu_v3_sub(q, x);
                    if (lu_v3_dot(dq, dq) >= R * R) continue;
                    size_t id = ((size_t)k * n[1] + jj) * n[0] + i;
                    if (mark[id]) continue;
                    mark[id] = 1;
                    r = add_sample(st, q, h, 1.0f, h / 3.0f, tau, err);
                    *added = true;
                }
    }
    free(mark);
    if (level < 4) st->stats.split[level] = splits;
    return r;
}

/* ---- cell lists of the final samples ---- */

static lu_result build_cells(gr_state *st, lu_error *err) {
    lu_k_gr_params *G = &st->kctx.G;
    int nc = G->cx * G->cy * G->cz;
    if ((size_t)nc + 1 > st->cells_cap) {
        free(st->cell_begin);
        st->cell_begin = malloc(((size_t)nc + 1) * sizeof(int));
        st->cells_cap = st->cell_begin ? (size_t)nc + 1 : 0;
        if (!st->cell_begin) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
    }
    memset(st->cell_begin, 0, ((size_t)nc + 1) * sizeof(int));
    /* Two passes: count, then fill; a sample enters every cell its sphere touches. */
    for (int pass = 0; pass < 2; pass++) {
        int *fillp = NULL;
        if (pass == 1) {
            for (int c = 0; c < nc; c++) st->cell_begin[c + 1] += st->cell_begin[c];
            size_t items = (size_t)st->cell_begin[nc];
            if (items > st->items_cap) {
                free(st->cell_items);
                st->cell_items = malloc((items ? items : 1) * sizeof(int));
                st->items_cap = st->cell_items ? items : 0;
                if (!st->cell_items) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
            }
            fillp = calloc((size_t)nc, sizeof(int));
            if (!fillp) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
        }
        for (int j = 0; j < st->nfinal; j++) {
            const float *s = st->final + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
            float R = s[3];
            float xc[3] = {s[0], s[1], s[2]}, lo[3] = {G->lo.x, G->lo.y, G->lo.z},
                  cs[3] = {G->cell.x, G->cell.y, G->cell.z};
            int cn[3] = {G->cx, G->cy, G->cz}, a0[3], a1[3];
            for (int a = 0; a < 3; a++) {
                a0[a] = (int)floorf((xc[a] - R - lo[a]) / cs[a]);
                a1[a] = (int)floorf((xc[a] + R - lo[a]) / cs[a]);
                if (a0[a] < 0) a0[a] = 0;
                if (a1[a] > cn[a] - 1) a1[a] = cn[a] - 1;
            }
            for (int z = a0[2]; z <= a1[2]; z++)
                for (int y = a0[1]; y <= a1[1]; y++)
                    for (int x = a0[0]; x <= a1[0]; x++) {
                        /* distance from the sample to the cell's box */
                        float d2 = 0.0f;
                        int idx[3] = {x, y, z};
                        for (int a = 0; a < 3; a++) {
                            float b0 = lo[a] + (float)idx[a] * cs[a], b1 = b0 + cs[a];
                            float dd = xc[a] < b0 ? b0 - xc[a] : (xc[a] > b1 ? xc[a] - b1 : 0.0f);
                            d2 += dd * dd;
                        }
                        if (d2 >= R * R) continue;
                        int c = (z * G->cy + y) * G->cx + x;
                        if (pass == 0) st->cell_begin[c + 1]++;
                        else st->cell_items[st->cell_begin[c] + fillp[c]++] = j;
                    }
        }
        free(fillp);
    }
    st->stats.cell_items = st->cell_begin[nc];
    return LU_OK;
}

/* ---- radiance grid and march on the CPU ---- */

static void field_range(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    gr_state *st = ctx;
    for (int64_t i = begin; i < end; i++) {
        lu_vec3 v = lu_k_gr_voxel(&st->kctx, st->kctx.G, (int)i);
        memcpy(st->field + 3 * (size_t)i, &v, 12);
    }
}

static void march_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    gr_state *st = ctx;
    const lu_camera *c = &st->scene->camera;
    lu_k_rm_params P;
    P.background = st->frame.background;
    P.step = st->frame.step;
    P.eps = st->frame.eps;
    P.jitter = 0;
    P.map_res = st->kctx.G.map_res;
    P.t_cut = st->frame.t_cut;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < c->width; x++) {
            int px = (int)(y * c->width + x);
            lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_vec3 L = lu_k_gr_radiance(&st->kctx, P, px, c->position, d);
            float *o = lu_image_px(st->out, x, (int)y);
            o[0] = L.x;
            o[1] = L.y;
            o[2] = L.z;
        }
}

/* Fraction of radiance voxels with density whose field is exactly 0 (no
 * valid sphere holds them, or every light is blocked there); every 7th
 * voxel, only when the stats are printed. */
static double uncovered_fraction(gr_state *st) {
    if (st->mode == LU_K_GR_PERVOXEL) return 0.0;
    const lu_k_gr_params *G = &st->kctx.G;
    size_t nv = (size_t)G->nx * G->ny * G->nz, dense = 0, bare = 0;
    for (size_t i = 0; i < nv; i += 7) {
        lu_vec3 p = lu_k_gr_voxel_pos(*G, (int)i);
        if (!(lu_k_gr_total_density(&st->kctx, p) > 0.0f)) continue;
        dense++;
        const float *f = st->field + 3 * i;
        if (f[0] == 0.0f && f[1] == 0.0f && f[2] == 0.0f) bare++;
    }
    return dense ? (double)bare / (double)dense : 0.0;
}

static lu_result gr_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    gr_state *st = state;
    if (scene->medium_count != st->nm)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: the scene's media changed since prepare", st->who);
    st->scene = scene;
    st->out = out;
    const lu_camera *c = &scene->camera;
    st->cam = lu_k_camera_make(c->position, c->look_at, c->up, c->fov_y_deg, c->width, c->height);
    for (int m = 0; m < scene->medium_count; m++) st->km[m] = lu_medium_to_kernel(&scene->media[m]);
    lu_k_light *kl = realloc(st->kl, (scene->light_count ? (size_t)scene->light_count : 1u) * sizeof *kl);
    if (!kl) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", st->who);
    st->kl = kl;
    st->nl = lu_scene_kernel_lights(scene, kl);
    lu_result r = lu_media_rays_camera(&st->mr, frame, st->cam, err);
    if (r == LU_OK) r = lu_media_rays_maps(&st->mr, frame, kl, st->nl, err);
    if (r == LU_OK) r = lu_media_rays_boundary_maps(&st->mr, frame, kl, st->nl, err);
    if (r == LU_OK) r = lu_media_rays_surface_vis(&st->mr, frame, st->cam, kl, st->nl, st->eps, err);
    /* The CPU marches the reconstruction st->dens: its majorants are of it. */
    if (r == LU_OK) r = lu_media_rays_majorants(&st->mr, frame, st->dens, err);
    if (r != LU_OK) return r;
    lu_gradient_stats keep = st->stats;
    memset(&st->stats, 0, sizeof st->stats);
    st->stats.gaussians = keep.gaussians;
    st->stats.fit_rel_l2 = keep.fit_rel_l2;
    st->stats.fit_ms = keep.fit_ms;
    st->stats.reconstruct_ms = keep.reconstruct_ms;

    /* Radiance grid over the media box: cubic voxels, `grid` along the longest side. */
    st->box = lu_scene_media_bounds(scene);
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float emax = fmaxf(lu_v3_maxc(ext), 1e-6f);
    int res = (int)st->p[P_GRID] > 0 ? (int)st->p[P_GRID] : st->density_res;
    float vox = emax / (float)res;
    lu_k_gr_params G;
    memset(&G, 0, sizeof G);
    G.cam = c->position;
    G.delta1 = (float)st->p[P_DELTA1] * st->density_voxel;
    G.lo = st->box.lo;
    G.delta2 = (float)st->p[P_DELTA2] * vox;
    G.voxel = lu_v3s(vox);
    G.g = scene->media[0].phase_g;
    G.nx = (int)fmaxf(1.0f, ceilf(ext.x / vox - 1e-3f));
    G.ny = (int)fmaxf(1.0f, ceilf(ext.y / vox - 1e-3f));
    G.nz = (int)fmaxf(1.0f, ceilf(ext.z / vox - 1e-3f));
    G.normalize = (int)st->p[P_NORMALIZE];
    float cell = emax / 32.0f;
    G.cell = lu_v3s(cell);
    G.cx = (int)fmaxf(1.0f, ceilf(ext.x / cell));
    G.cy = (int)fmaxf(1.0f, ceilf(ext.y / cell));
    G.cz = (int)fmaxf(1.0f, ceilf(ext.z / cell));
    G.rbf_floor = 1e-6f;
    G.mode = st->mode;
    G.map_res = st->mr.shadow_res;
    G.bviews_at = st->mr.bmap_views_at;
    G.bmaps_at = st->mr.bmap_maps_at;
    G.bview_count = st->mr.bmap_view_count;
    G.surf_normals_at = 8 * st->nm;
    G.surf_vis_at = G.surf_normals_at + c->width * c->height * st->nm * LU_MR_NORMAL_FLOATS;
    G.reflect = 0;
    for (int m = 0; m < st->nm; m++) {
        const lu_material *sm = &scene->media[m].surface;
        float *q = st->surf + 8 * m;
        q[0] = sm->albedo.x, q[1] = sm->albedo.y, q[2] = sm->albedo.z, q[3] = sm->shininess;
        q[4] = sm->specular.x, q[5] = sm->specular.y, q[6] = sm->specular.z, q[7] = 0.0f;
        G.reflect |= scene->media[m].has_boundary;
    }
    st->stats.grid[0] = G.nx, st->stats.grid[1] = G.ny, st->stats.grid[2] = G.nz;
    st->kctx = (struct lu_k_ctx){st->dens, st->km, st->nm, st->kl, st->nl, &st->mr, G, NULL, NULL, NULL, NULL, st->surf};

    lu_aabb mb = st->box;
    float diag = lu_aabb_valid(mb) ? lu_v3_len(lu_v3_sub(mb.hi, mb.lo)) : 1.0f;
    lu_gradient_frame *f = &st->frame;
    f->G = G;
    f->background = scene->background;
    f->step = fmaxf(diag, 1e-6f) / (float)st->p[P_STEPS];
    f->eps = st->eps;
    f->jitter = 0;
    f->t_cut = (float)st->p[P_T_CUT];
    f->width = c->width;
    f->height = c->height;
    f->medium_count = scene->medium_count;
    f->light_count = st->nl;
    f->mr = &st->mr;
    f->surf = st->surf;

    /* Samples: roots, then splitting levels (gradient only). */
    double t0 = lu_time_seconds();
    st->n = 0;
    if (st->mode != LU_K_GR_PERVOXEL) {
        r = root_samples(st, scene, err);
        if (r != LU_OK) return r;
        int roots = st->n;
        st->stats.root_samples = roots;
        int levels = st->mode == LU_K_GR_GRADIENT || st->mode == LU_K_GR_RBF ? (int)st->p[P_LEVELS] : 0;
        /* The finest grid stays at half the density resolution or coarser. */
        while (levels > 0 && (16 << (levels - 1)) > (st->density_res + 1) / 2) levels--;
        int first = 0, count = roots;
        double threshold = 0.0;
        for (int level = 0; level <= levels; level++) {
            bool more = level < levels;
            r = eval_samples(st, scene, first, count, more ? 1 : 0, err);
            if (r != LU_OK) return r;
            st->stats.level_samples[level] = count;
            if (!more) break;
            if (level == 0) threshold = st->p[P_EPSILON] * error_unit(st, roots);
            bool added;
            r = split_level(st, level, first, count, threshold, &added, err);
            if (r != LU_OK) return r;
            if (!added) break;
            first += count;
            count = st->n - first;
        }
        /* The final set: every sample not split, over all levels. */
        free(st->final);
        st->final = malloc((st->n ? (size_t)st->n : 1u) * LU_K_GR_SAMPLE_FLOATS * sizeof(float));
        if (!st->final) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", st->who);
        st->nfinal = 0;
        for (int j = 0; j < st->n; j++)
            if (st->active[j])
                memcpy(st->final + (size_t)st->nfinal++ * LU_K_GR_SAMPLE_FLOATS,
                       st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
        st->stats.samples = st->nfinal;
        r = build_cells(st, err);
        if (r != LU_OK) return r;
    } else {
        st->nfinal = 0;
        size_t nc = (size_t)G.cx * G.cy * G.cz + 1;
        if (nc > st->cells_cap) {
            free(st->cell_begin);
            st->cell_begin = calloc(nc, sizeof(int));
            st->cells_cap = st->cell_begin ? nc : 0;
            if (!st->cell_begin) return lu_fail(err, LU_ERR_NOMEM, "pervoxel: out of memory");
        } else {
            memset(st->cell_begin, 0, nc * sizeof(int));
        }
    }
    st->stats.ms_samples = 1e3 * (lu_time_seconds() - t0);
    f->samples = st->final;
    f->sample_count = st->nfinal;
    f->cell_begin = st->cell_begin;
    f->cell_items = st->cell_items;
    f->cell_item_count = st->cell_begin[G.cx * G.cy * G.cz];

    size_t nv = (size_t)G.nx * G.ny * G.nz;
    if (nv > st->field_cap) {
        free(st->field);
        st->field = malloc(nv * 3 * sizeof(float));
        st->field_cap = st->field ? nv : 0;
        if (!st->field) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for a %zu-voxel radiance grid", st->who, nv);
    }
    st->kctx.field = st->field;
    st->kctx.cell_begin = st->cell_begin;
    st->kctx.cell_items = st->cell_items;
    st->kctx.samples = st->final;
    if (st->backend == LU_BACKEND_GPU) {
        r = lu_gradient_gpu_render(st->gpu, scene, f, out, &st->stats.ms_field, &st->stats.ms_march, err);
    } else {
        t0 = lu_time_seconds();
        lu_parallel_for((int64_t)nv, 256, field_range, st, NULL);
        double t1 = lu_time_seconds();
        st->stats.ms_field = 1e3 * (t1 - t0);
        lu_parallel_for(c->height, 1, march_rows, st, NULL);
        st->stats.ms_march = 1e3 * (lu_time_seconds() - t1);
        if (getenv("LUCENT_GRADIENT_STATS")) st->stats.uncovered = uncovered_fraction(st);
    }
    if (r == LU_OK && getenv("LUCENT_GRADIENT_STATS"))
        fprintf(stderr,
                "%s: gaussians %d (fit rel-L2 %.4f, %.1f ms), roots %d (fill %d), final samples %d, levels %d/%d/%d/%d, "
                "split %d/%d/%d, grid %dx%dx%d, cell items %lld, uncovered %.4f, ms samples %.2f field %.2f march "
                "%.2f\n",
                st->who, st->stats.gaussians, st->stats.fit_rel_l2, st->stats.fit_ms, st->stats.root_samples,
                st->stats.fill_samples,
                st->stats.samples, st->stats.level_samples[0], st->stats.level_samples[1], st->stats.level_samples[2],
                st->stats.level_samples[3], st->stats.split[0], st->stats.split[1], st->stats.split[2], G.nx, G.ny,
                G.nz, st->stats.cell_items, st->stats.uncovered, st->stats.ms_samples, st->stats.ms_field,
                st->stats.ms_march);
    return r;
}

static lu_result gradient_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return gr_prepare_mode(s, p, P_COUNT, b, LU_K_GR_GRADIENT, out, err);
}
static lu_result rbf_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return gr_prepare_mode(s, p, P_COUNT, b, LU_K_GR_RBF, out, err);
}
static lu_result pervoxel_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return gr_prepare_mode(s, p, P_PERVOXEL_COUNT, b, LU_K_GR_PERVOXEL, out, err);
}

const lu_method lu_method_gradient = {
    .name = "gradient",
    .summary = "gradient-based interpolation of sparse source-radiance samples with dynamic sampling (Ren et al. "
               "2008; CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_gradient,
    .param_count = P_COUNT,
    .prepare = gradient_prepare,
    .render = gr_render,
    .destroy = gr_destroy,
};

const lu_method lu_method_rbf = {
    .name = "rbf",
    .summary = "baseline of gradient: RBF interpolation of the same samples without gradients (Ren et al. Fig. 3a)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_rbf,
    .param_count = P_COUNT,
    .prepare = rbf_prepare,
    .render = gr_render,
    .destroy = gr_destroy,
};

const lu_method lu_method_pervoxel = {
    .name = "pervoxel",
    .summary = "baseline of gradient: source radiance traced at every radiance-grid voxel, then the march (Ren et al. "
               "Table 2)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_pervoxel,
    .param_count = P_PERVOXEL_COUNT,
    .prepare = pervoxel_prepare,
    .render = gr_render,
    .destroy = gr_destroy,
};

bool lu_gradient_last_stats(const lu_renderer *r, lu_gradient_stats *out) {
    if (!r || (r->method != &lu_method_gradient && r->method != &lu_method_rbf && r->method != &lu_method_pervoxel))
        return false;
    *out = ((const gr_state *)r->state)->stats;
    return true;
}
