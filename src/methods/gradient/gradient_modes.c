/* The gradient family's three methods, modes of one driver (gradient.c)
 * that keep their own names and parameter sets:
 *   gradient  samples (Gaussian centres or stratified) + recursive splitting
 *             by the local shading error (Eq. 5), Eq. 4 interpolation;
 *   rbf       the same initial samples, RBF interpolation without gradients
 *             and without splitting (the paper's Fig. 3a, after Zhou et al.);
 *   pervoxel  source radiance traced at every voxel of the radiance grid
 *             (the paper's Table 2 "per-voxel"). */
#include <lucent/lucent.h>

#include "methods/gradient/gradient_cpu.h"
#include "methods/methods.h"

/* ---- parameters: pervoxel's are the first P_PERVOXEL_COUNT ---- */

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
    [P_T_CUT] = LU_VIEW_MARCH_T_CUT_PARAM,                                                                       \
    LU_VIEW_MARCH_MS_PARAMS(P_MS)

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

static lu_result gradient_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return lu_gr_prepare_mode(s, p, P_COUNT, k_params_gradient, b, LU_K_GR_GRADIENT, out, err);
}
static lu_result rbf_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return lu_gr_prepare_mode(s, p, P_COUNT, k_params_gradient, b, LU_K_GR_RBF, out, err);
}
static lu_result pervoxel_prepare(const lu_scene *s, const double *p, lu_backend b, void **out, lu_error *err) {
    return lu_gr_prepare_mode(s, p, P_PERVOXEL_COUNT, k_params_gradient, b, LU_K_GR_PERVOXEL, out, err);
}

const lu_method lu_method_gradient = {
    .name = "gradient",
    .summary = "gradient-based interpolation of sparse source-radiance samples with dynamic sampling (Ren et al. "
               "2008; CPU and GPU, one kernel)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_gradient,
    .param_count = P_COUNT,
    .prepare = gradient_prepare,
    .render = lu_gr_render,
    .destroy = lu_gr_destroy,
};

const lu_method lu_method_rbf = {
    .name = "rbf",
    .summary = "baseline of gradient: RBF interpolation of the same samples without gradients (Ren et al. Fig. 3a)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_rbf,
    .param_count = P_COUNT,
    .prepare = rbf_prepare,
    .render = lu_gr_render,
    .destroy = lu_gr_destroy,
};

const lu_method lu_method_pervoxel = {
    .name = "pervoxel",
    .summary = "baseline of gradient: source radiance traced at every radiance-grid voxel, then the march (Ren et al. "
               "Table 2)",
    .backends = LU_BACKEND_CPU | LU_BACKEND_GPU,
    .params = k_params_pervoxel,
    .param_count = P_PERVOXEL_COUNT,
    .prepare = pervoxel_prepare,
    .render = lu_gr_render,
    .destroy = lu_gr_destroy,
};

bool lu_gradient_last_stats(const lu_renderer *r, lu_gradient_stats *out) {
    if (!r || (r->method != &lu_method_gradient && r->method != &lu_method_rbf && r->method != &lu_method_pervoxel))
        return false;
    *out = ((const lu_gr_state *)r->state)->stats;
    return true;
}
