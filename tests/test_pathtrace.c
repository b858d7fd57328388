/* The path tracer against numbers derived independently of it:
 *   - sampling kernels: HG inverse CDF against the closed-form CDF, Blinn-Phong
 *     pdf normalisation and E[f cos / pdf] against quadrature, Snell's law,
 *     reciprocity and total internal reflection, Fresnel reflection frequency,
 *     equiangular pdf against its closed-form integral;
 *   - the majorant grid bounds the trilinear field; ratio tracking's mean over
 *     many streams equals exp(-tau) from lu_march.h's exact optical depth
 *     (and a halved majorant is caught as biased); delta tracking's escape
 *     frequency equals the same transmittance;
 *   - depth 1 equals `reference` on bundled scenes within a bound derived
 *     from the measured per-pixel variance (and full depth does not);
 *   - an albedo-1 isotropic slab against the plane-parallel transfer integral
 *     equation solved here by Nystrom quadrature;
 *   - white furnaces (heterogeneous chromatic HG medium; dielectric sphere)
 *     return the environment, under both RGB strategies;
 *   - a Lambert plane under an environment map against quadrature;
 *   - lights behind a refracting boundary: refract (eta 1, manifold
 *     next-event estimation and light beams) = straight (eta 1, next-event
 *     estimation);
 *   - determinism across thread counts, seeds, progressive output;
 *   - the GLSL build of the kernels agrees with C (when the GPU backend is in). */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "lu_test.h"
#include "methods/methods.h"
#include "methods/pathtrace/pathtrace_internal.h"

/* Kernels under test with a test-local density context: one grid and its majorant. */
struct lu_k_ctx {
    const lu_grid *grid;
    const lu_pt_majorant *maj;
    float maj_scale; /* 1 = the true majorant; < 1 deliberately violates it */
};
static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) { return lu_grid_sample(c->grid, p); }
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    return c->maj_scale * lu_pt_majorant_at(c->maj, bx, by, bz);
}
#include "methods/common/lu_sampling.h"
#include "methods/pathtrace/lu_tracking.h"

/* ---- helpers ------------------------------------------------------------------- */


static bool load_bundled(const char *name, int w, int h, lu_scene *s) {
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", name);
    lu_error err = {0};
    CHECK_OK(lu_scene_load(path, s, &err), &err);
    if (err.code != LU_OK) return false;
    s->camera.width = w;
    s->camera.height = h;
    return true;
}

static bool render_scene(const lu_scene *s, const char *method, const char *settings, lu_image *img) {
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_test_settings(&kv, settings);
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_create(method, s, &kv, LU_BACKEND_CPU, &r, &err), &err);
    if (r) CHECK_OK(lu_renderer_render(r, s, img, &err), &err);
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
    return err.code == LU_OK;
}

/* Per-pixel mean and variance of M independent renders. */
typedef struct stack {
    int n, count; /* floats per image, images */
    double *sum, *sum2;
} stack;

static void stack_add(stack *s, const lu_image *img) {
    if (!s->sum) {
        s->n = img->width * img->height * 3;
        s->sum = calloc((size_t)s->n, sizeof(double));
        s->sum2 = calloc((size_t)s->n, sizeof(double));
    }
    for (int i = 0; i < s->n; i++) {
        s->sum[i] += img->rgb[i];
        s->sum2[i] += (double)img->rgb[i] * img->rgb[i];
    }
    s->count++;
}

/* ||mean - ref||^2, sum of per-pixel variances of the mean (unbiased sample
 * variance / M), ||ref||^2. */
static void stack_compare(const stack *s, const lu_image *ref, double *err2, double *var_mean, double *ref2) {
    *err2 = *var_mean = *ref2 = 0.0;
    int m = s->count;
    for (int i = 0; i < s->n; i++) {
        double mean = s->sum[i] / m;
        double var = (s->sum2[i] - m * mean * mean) / (m - 1);
        *var_mean += (var > 0 ? var : 0) / m;
        double d = mean - ref->rgb[i];
        *err2 += d * d;
        *ref2 += (double)ref->rgb[i] * ref->rgb[i];
    }
}

static void stack_free(stack *s) {
    free(s->sum);
    free(s->sum2);
}

static double image_mean(const lu_image *img, int c) {
    double acc = 0;
    int n = img->width * img->height;
    for (int i = 0; i < n; i++) acc += img->rgb[3 * i + c];
    return acc / n;
}

static double image_std(const lu_image *img, int c) {
    double m = image_mean(img, c), acc = 0;
    int n = img->width * img->height;
    for (int i = 0; i < n; i++) acc += (img->rgb[3 * i + c] - m) * (img->rgb[3 * i + c] - m);
    return sqrt(acc / (n - 1));
}

/* ---- sampling kernels ---------------------------------------------------------------- */

static void test_rng(void) {
    lu_k_rng r = lu_k_rng_make(1, 2, 3);
    double s = 0, s2 = 0;
    const int N = 200000;
    for (int i = 0; i < N; i++) {
        float u = lu_k_rng_float(&r);
        CHECK(u >= 0.0f && u < 1.0f);
        s += u;
        s2 += u * u;
    }
    CHECK_NEAR(s / N, 0.5, 5 * sqrt(1.0 / 12.0 / N));
    CHECK_NEAR(s2 / N - (s / N) * (s / N), 1.0 / 12.0, 2e-3);
    /* Neighbouring pixels and samples start apart. */
    lu_k_rng a = lu_k_rng_make(1, 2, 3), b = lu_k_rng_make(1, 3, 3), c = lu_k_rng_make(1, 2, 4),
             d = lu_k_rng_make(2, 2, 3);
    uint32_t xa = lu_k_rng_u32(&a), xb = lu_k_rng_u32(&b), xc = lu_k_rng_u32(&c), xd = lu_k_rng_u32(&d);
    CHECK(xa != xb && xa != xc && xa != xd && xb != xc);
}

/* Closed-form HG CDF in mu = cos(theta). */
static double hg_cdf(double mu, double g) {
    if (fabs(g) < 1e-3) return 0.5 * (mu + 1.0);
    return (1 - g * g) / (2 * g) * (1 / sqrt(1 + g * g - 2 * g * mu) - 1 / (1 + g));
}

static void test_hg_sampling(void) {
    const double gs[3] = {0.0, 0.6, -0.4};
    const int N = 200000, B = 20;
    for (int k = 0; k < 3; k++) {
        int hist[20] = {0};
        lu_k_rng r = lu_k_rng_make(7, (uint32_t)k, 0);
        lu_vec3 w = lu_v3_norm(lu_v3(0.3f, -0.5f, 0.8f));
        double mean_mu = 0;
        for (int i = 0; i < N; i++) {
            float u1 = lu_k_rng_float(&r), u2 = lu_k_rng_float(&r);
            lu_vec3 wi = lu_k_sample_hg(w, (float)gs[k], u1, u2);
            CHECK_NEAR(lu_v3_len(wi), 1.0, 1e-5);
            double mu = lu_v3_dot(w, wi);
            mean_mu += mu;
            int b = (int)((mu + 1.0) * 0.5 * B);
            hist[b < 0 ? 0 : (b >= B ? B - 1 : b)]++;
        }
        for (int b = 0; b < B; b++) {
            double p = hg_cdf(-1.0 + 2.0 * (b + 1) / B, gs[k]) - hg_cdf(-1.0 + 2.0 * b / B, gs[k]);
            CHECK_NEAR(hist[b], N * p, 5 * sqrt(N * p * (1 - p)) + 1);
        }
        CHECK_NEAR(mean_mu / N, gs[k], 5e-3); /* HG's mean cosine is g */
    }
}

static void test_blinn_phong_sampling(void) {
    lu_vec3 n = lu_v3(0, 0, 1);
    const struct {
        lu_vec3 albedo, spec;
        float shin, theta_o;
    } cases[3] = {{{0.6f, 0.5f, 0.4f}, {0.3f, 0.3f, 0.3f}, 40.0f, 0.5f},
                  {{0.2f, 0.2f, 0.2f}, {0.8f, 0.7f, 0.6f}, 200.0f, 1.1f},
                  {{0.9f, 0.9f, 0.9f}, {0, 0, 0}, 32.0f, 0.2f}};
    for (int k = 0; k < 3; k++) {
        lu_vec3 wo = lu_v3(sinf(cases[k].theta_o), 0, cosf(cases[k].theta_o));
        /* Quadrature over the hemisphere: the pdf integrates to 1 and the
         * BRDF x cos to the directional albedo. */
        double pint = 0, fint[3] = {0, 0, 0};
        const int NT = 2000, NP = 400;
        for (int i = 0; i < NT; i++) {
            double th = (i + 0.5) / NT * (M_PI / 2);
            for (int j = 0; j < NP; j++) {
                double ph = (j + 0.5) / NP * 2 * M_PI;
                lu_vec3 wi = lu_v3((float)(sin(th) * cos(ph)), (float)(sin(th) * sin(ph)), (float)cos(th));
                double dw = sin(th) * (M_PI / 2 / NT) * (2 * M_PI / NP);
                pint += lu_k_blinn_phong_pdf(cases[k].albedo, cases[k].spec, cases[k].shin, n, wo, wi) * dw;
                lu_vec3 f = lu_k_blinn_phong(cases[k].albedo, cases[k].spec, cases[k].shin, n, wo, wi);
                fint[0] += f.x * dw;
                fint[1] += f.y * dw;
                fint[2] += f.z * dw;
            }
        }
        /* Mass lost below the horizon (specular half vectors reflecting under it) is not sampled: pdf <= 1. */
        CHECK(pint <= 1.0 + 2e-3);
        CHECK(pint > 0.9);
        /* Monte Carlo estimate of the albedo with the sampler: E[f cos / pdf]. */
        lu_k_rng r = lu_k_rng_make(3, (uint32_t)k, 0);
        const int N = 400000;
        double s[3] = {0, 0, 0}, s2 = 0;
        for (int i = 0; i < N; i++) {
            float pdf, ul = lu_k_rng_float(&r), u1 = lu_k_rng_float(&r), u2 = lu_k_rng_float(&r);
            lu_vec3 wi =
                lu_k_sample_blinn_phong(cases[k].albedo, cases[k].spec, cases[k].shin, n, wo, ul, u1, u2, &pdf);
            if (!(pdf > 0.0f)) continue;
            lu_vec3 f = lu_k_blinn_phong(cases[k].albedo, cases[k].spec, cases[k].shin, n, wo, wi);
            s[0] += f.x / pdf;
            s[1] += f.y / pdf;
            s[2] += f.z / pdf;
            s2 += (double)(f.x / pdf) * (f.x / pdf);
            /* The pdf returned matches the pdf function evaluated at the sample. */
            if (i < 1000)
                CHECK_NEAR(pdf, lu_k_blinn_phong_pdf(cases[k].albedo, cases[k].spec, cases[k].shin, n, wo, wi),
                           1e-5 * (1 + pdf));
        }
        double sd = sqrt((s2 / N - (s[0] / N) * (s[0] / N)) / N);
        CHECK_NEAR(s[0] / N, fint[0], 5 * sd + 2e-3 * fint[0]);
        CHECK_NEAR(s[1] / N, fint[1], 5 * sd * fint[1] / fint[0] + 2e-3 * fint[1]);
        /* Sampling weights stay near the albedos: no weight above 1.5 (energy-normalised lobes). */
        fprintf(stderr, "  blinn-phong case %d: albedo MC %.5f quadrature %.5f, pdf mass %.5f\n", k, s[0] / N, fint[0],
                pint);
    }
}

static void test_dielectric(void) {
    const float eta = 1.5f;
    lu_k_rng r = lu_k_rng_make(11, 0, 0);
    for (int i = 0; i < 200; i++) {
        lu_vec3 n = lu_k_sample_sphere(lu_k_rng_float(&r), lu_k_rng_float(&r));
        lu_vec3 d = lu_k_sample_sphere(lu_k_rng_float(&r), lu_k_rng_float(&r));
        if (lu_v3_dot(d, n) > 0) d = lu_v3_neg(d);
        float ci = -lu_v3_dot(d, n);
        if (ci < 1e-3f) continue;
        lu_vec3 t;
        CHECK(lu_k_refract(d, n, eta, &t));
        float ct = -lu_v3_dot(t, n);
        /* Snell: sin_i = eta sin_t; t in the plane of d and n. */
        CHECK_NEAR(sqrtf(1 - ci * ci), eta * sqrtf(fmaxf(0, 1 - ct * ct)), 2e-4);
        CHECK_NEAR(lu_v3_dot(lu_v3_cross(d, n), t), 0.0, 1e-4);
        /* Reciprocity: going back out along -t returns -d. */
        lu_vec3 back;
        CHECK(lu_k_refract(lu_v3_neg(t), lu_v3_neg(n), 1.0f / eta, &back));
        CHECK_NEAR(lu_v3_dot(back, lu_v3_neg(d)), 1.0, 1e-4);
    }
    /* Total internal reflection beyond the critical angle asin(1/eta). */
    float crit = asinf(1.0f / eta);
    lu_vec3 n = lu_v3(0, 0, 1), t;
    lu_vec3 d_in = lu_v3(sinf(crit + 0.01f), 0, -cosf(crit + 0.01f));
    lu_vec3 d_ok = lu_v3(sinf(crit - 0.01f), 0, -cosf(crit - 0.01f));
    CHECK(!lu_k_refract(d_in, n, 1.0f / eta, &t));
    CHECK(lu_k_refract(d_ok, n, 1.0f / eta, &t));
    lu_k_dielectric_sample ds =
        lu_k_sample_dielectric(d_in, lu_v3_neg(n), eta, 0.999f); /* leaving: ng outward = -n here */
    CHECK(!ds.refracted);
    /* Reflection frequency equals F; refraction weight is 1 / eta_rel^2. */
    lu_vec3 d = lu_v3_norm(lu_v3(0.6f, 0, -0.8f));
    int refl = 0;
    const int N = 100000;
    for (int i = 0; i < N; i++) {
        lu_k_dielectric_sample s = lu_k_sample_dielectric(d, n, eta, lu_k_rng_float(&r));
        if (!s.refracted)
            refl++;
        else
            CHECK_NEAR(s.weight, 1.0 / (eta * eta), 1e-6);
    }
    double F = lu_k_fresnel_reflectance(0.8f, eta);
    CHECK_NEAR((double)refl / N, F, 5 * sqrt(F * (1 - F) / N));
}

static void test_equiangular(void) {
    lu_vec3 x = lu_v3(0.3f, 0.7f, -0.2f), b = lu_v3(-1, 0, 0), u = lu_v3_norm(lu_v3(1, 0.1f, 0));
    float len = 2.5f;
    lu_k_equiangular e = lu_k_equiangular_make(x, b, u, len);
    /* The pdf integrates to one, and its normaliser is the exact line integral
     * of 1 / d^2: (theta_b - theta_a) / h. */
    double pint = 0, inv_d2 = 0;
    const int N = 200000;
    for (int i = 0; i < N; i++) {
        float s = (float)((i + 0.5) / N * len);
        pint += lu_k_equiangular_pdf(e, s) * len / N;
        lu_vec3 y = lu_v3_madd(b, u, s);
        inv_d2 += 1.0 / lu_v3_dot(lu_v3_sub(x, y), lu_v3_sub(x, y)) * len / N;
    }
    CHECK_NEAR(pint, 1.0, 1e-4);
    CHECK_REL(inv_d2, (e.th_b - e.th_a) / e.h, 1e-4);
    lu_k_rng r = lu_k_rng_make(5, 0, 0);
    for (int i = 0; i < 1000; i++) {
        float s = lu_k_equiangular_sample(e, lu_k_rng_float(&r));
        CHECK(s >= -1e-4f && s <= len + 1e-4f);
        float t = lu_k_trunc_exp_sample(1.7f, len, lu_k_rng_float(&r));
        CHECK(t >= 0 && t <= len);
    }
    double eint = 0;
    for (int i = 0; i < N; i++) eint += lu_k_trunc_exp_pdf(1.7f, len, (float)((i + 0.5) / N * len)) * len / N;
    CHECK_NEAR(eint, 1.0, 1e-4);
}

/* ---- tracking ---------------------------------------------------------------------------- */

static lu_grid random_grid(int n, unsigned seed) {
    lu_grid g = {0};
    lu_error err;
    CHECK_OK(lu_grid_alloc(&g, n, n, n, &err), &err);
    for (int i = 0; i < n * n * n; i++) {
        seed = seed * 1664525u + 1013904223u;
        float v = (float)(seed >> 8) / 16777216.0f;
        /* Half the grid empty, the rest in [0, 2]: blocks of very different majorants. */
        g.data[i] = (i % n) < n / 2 ? 0.0f : 2.0f * v * v;
    }
    lu_grid_update_range(&g);
    return g;
}

static void test_majorant_bounds(void) {
    lu_grid g = random_grid(13, 3);
    lu_pt_majorant m;
    lu_error err;
    CHECK_OK(lu_pt_majorant_build(&g, 4, &m, &err), &err);
    CHECK(m.nx == 4 && m.ny == 4 && m.nz == 4); /* ceil(14 / 4) */
    lu_k_rng r = lu_k_rng_make(1, 0, 0);
    int violations = 0, empty_blocks = 0;
    for (int i = 0; i < 200000; i++) {
        lu_vec3 p = lu_v3(-1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r));
        float q[3] = {(p.x + 1) / 4, (p.y + 1) / 4, (p.z + 1) / 4};
        float bound = lu_pt_majorant_at(&m, (int)floorf(q[0]), (int)floorf(q[1]), (int)floorf(q[2]));
        violations += lu_grid_sample(&g, p) > bound;
    }
    for (int i = 0; i < m.nx * m.ny * m.nz; i++) empty_blocks += m.dmax[i] == 0.0f;
    CHECK(violations == 0);
    /* The coarse grid is tighter than one global majorant: whole empty blocks. */
    CHECK(empty_blocks > 0);
    lu_pt_majorant_destroy(&m);
    CHECK(lu_pt_majorant_build(&g, 0, &m, &err) == LU_ERR_INVALID_ARG);
    lu_grid_destroy(&g);
}

static void test_ratio_tracking_unbiased(void) {
    lu_grid g = random_grid(12, 9);
    lu_pt_majorant m;
    lu_error err;
    CHECK_OK(lu_pt_majorant_build(&g, 3, &m, &err), &err);
    struct lu_k_ctx ctx = {&g, &m, 1.0f};
    struct lu_k_ctx bad = {&g, &m, 0.25f};
    lu_vec3 sigma_t = lu_v3(0.4f, 0.25f, 0.1f);
    lu_k_rng r = lu_k_rng_make(2, 0, 0);
    int biased_caught = 0, segments = 12;
    for (int k = 0; k < segments; k++) {
        lu_vec3 a = lu_v3(-1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r));
        lu_vec3 b = lu_v3(-1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r), -1 + 14 * lu_k_rng_float(&r));
        float len = lu_v3_len(lu_v3_sub(b, a));
        lu_vec3 d = lu_v3_scale(lu_v3_sub(b, a), 1.0f / len);
        float tau = lu_k_optical_depth(&ctx, 0, a, d, 0, len, 64);
        lu_vec3 exact = lu_v3_exp(lu_v3_scale(sigma_t, -tau));
        const int N = 6000;
        double s[3] = {0}, s2[3] = {0}, sb = 0, sb2 = 0;
        int escaped = 0;
        for (int i = 0; i < N; i++) {
            lu_k_rng ri = lu_k_rng_make(100 + (uint32_t)k, (uint32_t)i, 0);
            lu_vec3 t = lu_k_ratio_tracking(&ctx, 0, a, d, 0, len, 3.0f, sigma_t, 0.4f, &ri);
            for (int c = 0; c < 3; c++) {
                double v = lu_v3_get(t, c);
                s[c] += v;
                s2[c] += v * v;
            }
            lu_vec3 tb = lu_k_ratio_tracking(&bad, 0, a, d, 0, len, 3.0f, sigma_t, 0.4f, &ri);
            sb += tb.x;
            sb2 += (double)tb.x * tb.x;
            /* Delta tracking (grey medium, hero channel 0, no absorption):
             * the path escapes the segment with probability T. */
            lu_k_walk w = lu_k_walk_begin(a, d, 0, len, 3.0f);
            float tt = 0;
            lu_vec3 beta = lu_v3s(1), rr = lu_v3s(1);
            bool hit = false;
            for (;;) {
                tt = lu_k_walk_tentative(&ctx, 0, &w, tt, 0.4f, &ri);
                if (!(tt < len)) break;
                float dens = lu_grid_sample(&g, lu_v3_madd(a, d, tt));
                int ev = lu_k_hero_event(&beta, &rr, lu_v3s(0.0f), lu_v3s(0.4f * dens), 0.4f * w.dmax, 0,
                                         lu_k_rng_float(&ri));
                if (ev == LU_K_EVENT_SCATTER) {
                    hit = true;
                    break;
                }
            }
            escaped += !hit;
        }
        for (int c = 0; c < 3; c++) {
            double mean = s[c] / N, se = sqrt(fmax(s2[c] / N - mean * mean, 0) / N);
            CHECK_NEAR(mean, lu_v3_get(exact, c), 4.5 * se + 1e-5);
        }
        double p = exp(-0.4 * tau);
        CHECK_NEAR((double)escaped / N, p, 4.5 * sqrt(p * (1 - p) / N) + 1e-4);
        double mb = sb / N, seb = sqrt(fmax(sb2 / N - mb * mb, 0) / N);
        biased_caught += fabs(mb - exact.x) > 4.5 * seb + 1e-5;
    }
    /* The same comparison detects a majorant that is too small (most segments cross dense blocks). */
    CHECK_MSG(biased_caught >= segments / 2, "halved majorant flagged on %d of %d segments", biased_caught, segments);
    lu_pt_majorant_destroy(&m);
    lu_grid_destroy(&g);
}

/* ---- depth 1 against the reference ---------------------------------------------------------- */

/* Renders M seeds of pathtrace at depth `depth` and compares their mean with
 * ref. Returns the rel-L2 error and sets *bound: under the hypothesis that
 * the path tracer's mean is the reference, E||mean - ref||^2 = sum of the
 * per-pixel variances of the mean, which the M renders estimate; the ratio
 * concentrates around 1 (relative spread ~ sqrt(2 / pixels)), so 1.5 times
 * that sum is a 5-sigma-plus allowance. The reference's own quadrature
 * converged to < 0.1 % (test_reference); (2e-3 ||ref||)^2 covers it. */
static double depth_vs_reference(const lu_scene *scene, int spp, int M, int depth, const lu_image *ref, double *bound) {
    stack st = {0};
    for (int s = 0; s < M; s++) {
        char settings[256];
        snprintf(settings, sizeof settings,
                 "pathtrace.spp=%d pathtrace.seed=%d pathtrace.max_depth=%d pathtrace.jitter=0", spp, 17 + s, depth);
        lu_image img = {0};
        if (render_scene(scene, "pathtrace", settings, &img)) stack_add(&st, &img);
        lu_image_destroy(&img);
    }
    double err2, var, ref2;
    stack_compare(&st, ref, &err2, &var, &ref2);
    stack_free(&st);
    *bound = sqrt(1.5 * var + 4e-6 * ref2) / sqrt(ref2);
    return sqrt(err2 / ref2);
}

static void test_depth1_matches_reference(void) {
    const struct {
        const char *name;
        int w, h, spp;
    } scenes[] = {{"smoke_box", 24, 18, 96},
                  {"cube_torus", 20, 20, 48},
                  {"homogeneous_sphere", 20, 20, 48},
                  {"smoke_glow", 24, 18, 96}, {"spot_shaft", 24, 18, 96}};
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; i++) {
        lu_image ref = {0};
        lu_scene sc;
        if (!load_bundled(scenes[i].name, scenes[i].w, scenes[i].h, &sc)) continue;
        if (!render_scene(&sc, "reference", "", &ref)) {
            lu_scene_destroy(&sc);
            continue;
        }
        double bound, bound_full;
        double e1 = depth_vs_reference(&sc, scenes[i].spp, 6, 1, &ref, &bound);
        double ef = depth_vs_reference(&sc, scenes[i].spp / 2, 4, 3, &ref, &bound_full);
        lu_scene_destroy(&sc);
        fprintf(stderr, "  %-20s depth 1 rel-L2 %.4f (bound %.4f); depth 3 %.4f (bound %.4f)\n", scenes[i].name, e1,
                bound, ef, bound_full);
        CHECK_MSG(e1 <= bound, "%s: depth-1 rel-L2 %.4f > bound %.4f", scenes[i].name, e1, bound);
        /* The comparison can fail: two more orders of scattering land far
         * outside both their own noise bound and the depth-1 one. */
        CHECK_MSG(ef > bound_full && ef > 2 * bound, "%s: depth 3 vs reference %.4f, bounds %.4f / %.4f",
                  scenes[i].name, ef, bound_full, bound);
        lu_image_destroy(&ref);
    }
}

/* ---- the albedo-1 slab ----------------------------------------------------------------------- */

/* Exponential integrals E1 (series below 1, continued fraction above:
 * Abramowitz and Stegun 5.1.11 and 5.1.22) and E2 = exp(-x) - x E1. */
static double expint_e1(double x) {
    if (x <= 1.0) {
        double sum = 0, term = 1;
        for (int k = 1; k < 40; k++) {
            term *= -x / k;
            sum -= term / k;
        }
        return -0.57721566490153286 - log(x) + sum;
    }
    double f = 0; /* E1 = e^-x / (x + 1 / (1 + 1 / (x + 2 / (1 + 2 / (x + ...))))) */
    for (int k = 60; k >= 1; k--) f = k / (1.0 + k / (x + f));
    return exp(-x) / (x + f);
}
static double expint_e2(double x) { return x <= 0 ? 1.0 : exp(-x) - x * expint_e1(x); }

/* Plane-parallel slab of optical thickness tau0, single-scattering albedo w,
 * isotropic scattering, lit by a collimated beam of irradiance E at cosine mu0:
 * the source function J solves (Chandrasekhar 1960, Radiative Transfer, §11;
 * the Schwarzschild-Milne equation with E1 kernel)
 *   J(t) = w/(4 pi) E exp(-t/mu0) + w/2 int_0^tau0 E1(|t - t'|) J(t') dt',
 * solved by Nystrom on n cells (piecewise constant J, exact cell integrals of
 * E1 via E2) and source iteration. Emergent radiance along the normal:
 * transmitted int J exp(-(tau0 - t)) dt, reflected int J exp(-t) dt. */
static void slab_solve(double tau0, double w, double mu0, double E, int n, double *lr, double *lt) {
    double h = tau0 / n;
    double *k = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * n), *j = malloc(sizeof(double) * n),
           *jn = malloc(sizeof(double) * n);
    k[0] = 2 * (1 - expint_e2(0.5 * h));
    for (int d = 1; d < n; d++) k[d] = expint_e2((d - 0.5) * h) - expint_e2((d + 0.5) * h);
    for (int i = 0; i < n; i++) {
        double a = i * h; /* cell average of the beam term */
        b[i] = w / (4 * M_PI) * E * mu0 * (exp(-a / mu0) - exp(-(a + h) / mu0)) / h;
        j[i] = b[i];
    }
    for (int it = 0; it < 2000; it++) {
        double change = 0;
        for (int i = 0; i < n; i++) {
            double acc = 0;
            for (int q = 0; q < n; q++) acc += k[abs(i - q)] * j[q];
            jn[i] = b[i] + 0.5 * w * acc;
            change = fmax(change, fabs(jn[i] - j[i]));
        }
        memcpy(j, jn, sizeof(double) * n);
        if (change < 1e-14) break;
    }
    *lr = *lt = 0;
    for (int i = 0; i < n; i++) {
        double a = i * h, c = a + h;
        *lr += j[i] * (exp(-a) - exp(-c));
        *lt += j[i] * (exp(-(tau0 - c)) - exp(-(tau0 - a)));
    }
    free(k);
    free(b);
    free(j);
    free(jn);
}

static void slab_exact(double tau0, double mu0, double *lr, double *lt) {
    double r1, t1, r2, t2;
    slab_solve(tau0, 1.0, mu0, 1.0, 300, &r1, &t1);
    slab_solve(tau0, 1.0, mu0, 1.0, 600, &r2, &t2);
    /* Richardson: the midpoint collocation error is O(h^2). */
    *lr = (4 * r2 - r1) / 3;
    *lt = (4 * t2 - t1) / 3;
    CHECK_NEAR(r2, *lr, 2e-4 * *lr); /* and the discretisation is converged */
}

static void test_slab_integral_equation(void) {
    /* Sanity of the exponential integrals: the two branches meet at x = 1. */
    CHECK_NEAR(expint_e1(1.0), 0.219383934395520, 1e-12);
    CHECK_NEAR(expint_e1(1.0000001), 0.219383934395520 - 1e-7 * exp(-1.0), 1e-10);
    /* A slab of unit thickness, albedo 1, chromatic extinction (optical
     * thickness 1, 0.6, 0.3 per channel: hero sampling meets null collisions
     * in the thinner channels), light at mu0 = 0.6, E = 1. */
    const double tau[3] = {1.0, 0.6, 0.3}, mu0 = 0.6;
    double lr[3], lt[3];
    for (int c = 0; c < 3; c++) slab_exact(tau[c], mu0, &lr[c], &lt[c]);
    const char *fmt =
        "{\"camera\": {\"position\": [0, %g, 0], \"look_at\": [0, 0, 0], \"up\": [0, 0, 1], \"fov_y_deg\": 1,"
        " \"width\": 4, \"height\": 4},"
        " \"lights\": [{\"type\": \"directional\", \"direction\": [0.8, 0.6, 0], \"irradiance\": 1}],"
        " \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"size\": [44, 2, 44], \"resolution\": [8, 4, "
        "8]},"
        "   \"sigma_s\": [1.0, 0.6, 0.3], \"sigma_a\": 0,"
        "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [36, 1, 36]}, \"eta\": 1.0}}]}";
    for (int side = 0; side < 2; side++) {
        for (int mode = 0; mode < 2; mode++) {
            char json[2048];
            snprintf(json, sizeof json, fmt, side == 0 ? 3.0 : -3.0);
            lu_image img = {0};
            const char *settings = mode == 0 ? "pathtrace.spp=3000 pathtrace.seed=5"
                                             : "pathtrace.spp=3000 pathtrace.seed=6 pathtrace.spectral=tracking";
            if (!lu_test_render_json(json, "pathtrace", settings, &img)) continue;
            for (int c = 0; c < 3; c++) {
                double want = side == 0 ? lr[c] : lt[c];
                double got = image_mean(&img, c), se = image_std(&img, c) / sqrt(16.0);
                fprintf(stderr, "  slab %s tau0 %.1f (%s): path tracer %.6f +- %.6f, integral equation %.6f\n",
                        side == 0 ? "reflected" : "transmitted", tau[c], mode == 0 ? "hero" : "tracking", got, se,
                        want);
                CHECK_NEAR(got, want, 4.5 * se + 2e-3 * want);
            }
            lu_image_destroy(&img);
        }
    }
}

/* ---- furnaces ------------------------------------------------------------------------------ */

static void furnace_check(const char *json, const char *settings, const double L[3]) {
    lu_image img = {0};
    if (!lu_test_render_json(json, "pathtrace", settings, &img)) return;
    int n = img.width * img.height;
    for (int c = 0; c < 3; c++) {
        double m = image_mean(&img, c), se = image_std(&img, c) / sqrt((double)n);
        fprintf(stderr, "  furnace [%s] channel %d: %.5f +- %.5f (environment %.3f)\n", settings, c, m, se, L[c]);
        CHECK_NEAR(m, L[c], 4.5 * se + 1e-6);
        CHECK(se < 0.02 * L[c]); /* the check has power */
    }
    lu_image_destroy(&img);
}

static void test_white_furnace(void) {
    const double L[3] = {0.5, 1.0, 2.0};
    const char *cloud = "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0], \"fov_y_deg\": 36, \"width\": "
                        "12, \"height\": 12},"
                        " \"lights\": [{\"type\": \"environment\", \"radiance\": [0.5, 1.0, 2.0]}],"
                        " \"media\": [{\"density\": {\"procedural\": \"fbm_cloud\", \"size\": [2, 2, 2], "
                        "\"resolution\": 20, \"seed\": 3},"
                        "   \"sigma_s\": [3, 8, 14], \"sigma_a\": 0, \"phase_g\": 0.5}]}";
    furnace_check(cloud, "pathtrace.spp=48 pathtrace.majorant_block=4", L);
    furnace_check(cloud, "pathtrace.spp=48 pathtrace.spectral=tracking", L);
    const char *sphere =
        "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0], \"fov_y_deg\": 36, \"width\": 12, \"height\": "
        "12},"
        " \"lights\": [{\"type\": \"environment\", \"radiance\": [0.5, 1.0, 2.0]}],"
        " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [2, 4, 7], \"sigma_a\": 0, \"phase_g\": -0.3,"
        "   \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1, \"subdivisions\": 3}, \"eta\": "
        "1.5}}]}";
    furnace_check(sphere, "pathtrace.spp=96 pathtrace.boundary=refract", L);
}

/* ---- an environment map over a Lambert plane ---------------------------------------------------- */

static void test_env_lambert_plane(void) {
    /* A map with a small bright sun and a sky gradient, written as PFM. */
    lu_image env = {0};
    lu_error err;
    CHECK_OK(lu_image_create(&env, 64, 32, &err), &err);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            float *p = lu_image_px(&env, x, y);
            float sky = 0.2f + 0.5f * (1.0f - (float)y / 32.0f);
            bool sun = (x == 40 || x == 41) && (y == 9);
            p[0] = sky * 0.6f + (sun ? 400.0f : 0.0f);
            p[1] = sky * 0.8f + (sun ? 380.0f : 0.0f);
            p[2] = sky + (sun ? 300.0f : 0.0f);
        }
    char path[512];
    snprintf(path, sizeof path, LU_BINARY_DIR "/test_pathtrace_env.pfm");
    CHECK_OK(lu_image_save(&env, path, NULL, &err), &err);
    /* L_out = albedo / pi * int_{upper hemisphere} L(w) cos(theta) dw, by a
     * fine midpoint rule over the sphere with the map's own bilinear lookup. */
    double ref[3] = {0, 0, 0};
    const int NT = 1024, NP = 2048;
    for (int i = 0; i < NT / 2; i++) {
        double th = (i + 0.5) / NT * M_PI;
        for (int j = 0; j < NP; j++) {
            double ph = (j + 0.5) / NP * 2 * M_PI;
            lu_vec3 w = lu_v3((float)(sin(th) * cos(ph)), (float)cos(th), (float)(sin(th) * sin(ph)));
            lu_vec3 le = lu_env_lookup(&env, 1.0f, w);
            double dw = sin(th) * (M_PI / NT) * (2 * M_PI / NP) * cos(th);
            ref[0] += le.x * dw;
            ref[1] += le.y * dw;
            ref[2] += le.z * dw;
        }
    }
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 2, 0.0001], \"look_at\": [0, 0, 0], \"fov_y_deg\": 2,"
             " \"width\": 4, \"height\": 4},"
             " \"lights\": [{\"type\": \"environment\", \"file\": \"%s\"}],"
             " \"objects\": [{\"mesh\": {\"procedural\": \"plane\", \"size\": [1000, 1000]},"
             "   \"material\": {\"albedo\": [0.5, 0.5, 0.5]}}]}",
             path);
    lu_image img = {0};
    if (lu_test_render_json(json, "pathtrace", "pathtrace.spp=1500", &img)) {
        for (int c = 0; c < 3; c++) {
            double want = 0.5 / M_PI * ref[c], got = image_mean(&img, c), se = image_std(&img, c) / 4.0;
            fprintf(stderr, "  env plane channel %d: %.5f +- %.5f, quadrature %.5f\n", c, got, se, want);
            CHECK_NEAR(got, want, 4.5 * se + 1e-3 * want);
            CHECK(se < 0.01 * want);
        }
    }
    lu_image_destroy(&img);
    lu_image_destroy(&env);
    remove(path);
}

/* ---- lights behind a refracting boundary -------------------------------------------------------- */

static void test_refract_identity(void) {
    /* With eta = 1 a refracting boundary changes nothing physically, but the
     * path tracer must reach the lights through it by manifold next-event
     * estimation (the boundary is specular to a straight shadow ray) and, for
     * longer specular chains, light beams; a straight boundary uses plain
     * next-event estimation. So refract(all depths) = straight(all depths):
     * two independent estimators of the same image, single scattering
     * included. Point, spot and directional lights. */
    const char *json =
        "{\"camera\": {\"position\": [0, 0.5, 3.2], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 10, "
        "\"height\": 10},"
        " \"lights\": [{\"type\": \"point\", \"position\": [2, 1.5, 1], \"intensity\": [20, 20, 20]},"
        "   {\"type\": \"directional\", \"direction\": [-1, 0.5, -0.3], \"irradiance\": [1, 1.5, 2]},"
        "   {\"type\": \"spot\", \"position\": [0, 3, 0.3], \"direction\": [0, -1, 0], \"intensity\": [30, 30, 30],"
        "    \"inner_deg\": 20, \"outer_deg\": 30}],"
        " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [1.5, 2, 3], \"sigma_a\": [0.2, 0.1, 0.05],"
        "   \"phase_g\": 0.3, \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1, \"subdivisions\": "
        "3},"
        "   \"eta\": 1.0}}]}";
    stack refr = {0}, straight = {0};
    for (int s = 0; s < 4; s++) {
        char settings[256];
        /* Half the seeds without light subpaths: both must be unbiased. */
        snprintf(settings, sizeof settings,
                 "pathtrace.spp=256 pathtrace.boundary=refract pathtrace.jitter=0 pathtrace.seed=%d "
                 "pathtrace.light_paths=%d",
                 s + 1, s % 2);
        lu_image img = {0};
        if (lu_test_render_json(json, "pathtrace", settings, &img)) stack_add(&refr, &img);
        lu_image_destroy(&img);
        if (s >= 2) continue;
        snprintf(settings, sizeof settings,
                 "pathtrace.spp=512 pathtrace.boundary=straight pathtrace.jitter=0 "
                 "pathtrace.seed=%d",
                 50 + s);
        if (lu_test_render_json(json, "pathtrace", settings, &img)) stack_add(&straight, &img);
        lu_image_destroy(&img);
    }
    if (refr.count < 4 || straight.count < 2) return;
    /* Error of mean(refract) against mean(straight); under the identity its
     * expected square is the sum of the two means' variances. A sample
     * variance from a few seeds scatters, so the bound is 3x that sum. */
    double err2 = 0, var = 0, ref2 = 0, m_got = 0, m_ref = 0;
    const stack *st[2] = {&refr, &straight};
    for (int i = 0; i < refr.n; i++) {
        double mean[2];
        for (int k = 0; k < 2; k++) {
            int m = st[k]->count;
            mean[k] = st[k]->sum[i] / m;
            var += fmax((st[k]->sum2[i] - m * mean[k] * mean[k]) / (m - 1), 0) / m;
        }
        double d = mean[0] - mean[1];
        err2 += d * d;
        ref2 += mean[1] * mean[1];
        if (i % 3 == 1) {
            m_got += mean[0];
            m_ref += mean[1];
        }
    }
    double rel = sqrt(err2 / ref2), bound = sqrt(3.0 * var / ref2);
    fprintf(stderr, "  refract(eta 1) vs straight: rel-L2 %.4f (bound %.4f); green mean %.5f vs %.5f\n", rel, bound,
            m_got / (refr.n / 3), m_ref / (refr.n / 3));
    CHECK(rel <= bound);
    /* Power: single scattering is about 35 % of the image here, so leaving
     * it out, a missing light or a 25 % flux error lands outside. */
    CHECK(bound < 0.2);
    CHECK_NEAR(m_got, m_ref, 0.04 * m_ref);
    stack_free(&refr);
    stack_free(&straight);
}

/* ---- determinism and progressive output -------------------------------------------------------- */

typedef struct progress_log {
    int calls, last_done;
    lu_image copy;
} progress_log;

static void on_pass(void *user, const lu_image *partial, int done, int total) {
    progress_log *p = user;
    p->calls++;
    p->last_done = done;
    CHECK(done < total && total == 7);
    lu_error err;
    lu_image_destroy(&p->copy);
    CHECK_OK(lu_image_create(&p->copy, partial->width, partial->height, &err), &err);
    memcpy(p->copy.rgb, partial->rgb, sizeof(float) * 3 * partial->width * partial->height);
}

static void test_determinism_and_progressive(void) {
    lu_image a = {0}, b = {0}, c = {0};
    lu_scene s;
    if (!load_bundled("smoke_box", 16, 12, &s)) return;
    lu_set_thread_count(1, NULL);
    render_scene(&s, "pathtrace", "pathtrace.spp=7", &a);
    lu_set_thread_count(3, NULL);
    render_scene(&s, "pathtrace", "pathtrace.spp=7", &b);
    render_scene(&s, "pathtrace", "pathtrace.spp=7 pathtrace.seed=2", &c);
    lu_set_thread_count(0, NULL);
    size_t bytes = sizeof(float) * 3 * 16 * 12;
    CHECK(a.rgb && b.rgb && memcmp(a.rgb, b.rgb, bytes) == 0);
    CHECK(c.rgb && memcmp(a.rgb, c.rgb, bytes) != 0);

    /* Progressive: a callback every 3 passes (after 3 and 6 of 7), the same final image. */
    lu_error err = {0};
    lu_kvlist kv = {0};
    CHECK_OK(lu_kv_parse_assignment(&kv, "pathtrace.spp=7", &err), &err);
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_create("pathtrace", &s, &kv, LU_BACKEND_CPU, &r, &err), &err);
    progress_log log = {0};
    lu_image p = {0};
    if (r) {
        CHECK(lu_renderer_set_progressive(r, on_pass, &log, 3));
        CHECK_OK(lu_renderer_render(r, &s, &p, &err), &err);
    }
    CHECK(log.calls == 2 && log.last_done == 6);
    CHECK(p.rgb && memcmp(a.rgb, p.rgb, bytes) == 0);
    CHECK(log.copy.rgb && memcmp(log.copy.rgb, p.rgb, bytes) != 0);
    /* A one-shot method declines progressive output. */
    lu_renderer *ref = NULL;
    CHECK_OK(lu_renderer_create("reference", &s, NULL, LU_BACKEND_CPU, &ref, &err), &err);
    if (ref) CHECK(!lu_renderer_set_progressive(ref, on_pass, &log, 3));
    lu_renderer_destroy(ref);
    lu_renderer_destroy(r);
    lu_image_destroy(&log.copy);
    lu_image_destroy(&p);
    lu_kv_free(&kv);
    lu_scene_destroy(&s);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
    lu_image_destroy(&c);
}

static void test_bad_parameters(void) {
    const char *json = "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0], \"width\": 2, \"height\": 2}}";
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(json, "t.json", &s, &err), &err);
    const char *bad[] = {"pathtrace.boundary=bent", "pathtrace.spp=0", "pathtrace.max_depth=1.5", "pathtrace.nope=1",
                         "pathtrace.spectral=rainbow"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        lu_kvlist kv = {0};
        CHECK_OK(lu_kv_parse_assignment(&kv, bad[i], &err), &err);
        lu_renderer *r = NULL;
        CHECK_MSG(lu_renderer_create("pathtrace", &s, &kv, LU_BACKEND_CPU, &r, &err) != LU_OK, "%s accepted", bad[i]);
        CHECK(r == NULL);
        lu_kv_free(&kv);
    }
    /* An empty scene renders black (the background is zero). */
    lu_image img = {0};
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_create("pathtrace", &s, NULL, LU_BACKEND_CPU, &r, &err), &err);
    if (r) CHECK_OK(lu_renderer_render(r, &s, &img, &err), &err);
    CHECK(img.rgb && img.rgb[0] == 0.0f);
    lu_renderer_destroy(r);
    lu_image_destroy(&img);
    lu_scene_destroy(&s);
}

/* ---- GLSL twin of the kernels ---------------------------------------------------------------- */

static void test_kernels_glsl(void) {
    if (!lu_gpu_compiled_in()) {
        fprintf(stderr, "  built without the GPU backend: GLSL check skipped\n");
        return;
    }
    lu_error err;
    lu_gpu_context *ctx = NULL;
    CHECK_OK(lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err), &err);
    if (!ctx) return;
    /* The density hooks: a smooth analytic field under a constant majorant of 1. */
    static const lu_gpu_source ov[] = {
        {"tests/pt_kernels.comp",
         "layout(local_size_x = 64) in;\n"
         "float lu_k_density(int ctx, int m, vec3 p) { return 0.5 + 0.45 * sin(p.x) * cos(0.7 * p.y + p.z); }\n"
         "float lu_k_majorant(int ctx, int m, int bx, int by, int bz) { return 1.0; }\n"
         "#include \"methods/pathtrace/lu_tracking.h\"\n"
         "layout(std430, binding = 0) buffer Out { float o[]; };\n"
         "uniform int u_count;\n"
         "void main() {\n"
         "  int i = int(gl_GlobalInvocationID.x);\n"
         "  if (i >= u_count) return;\n"
         "  lu_k_rng r = lu_k_rng_make(7u, uint(i), 3u);\n"
         "  o[8 * i + 0] = float(lu_k_rng_u32(r) >> 8u);\n"
         "  float u1 = lu_k_rng_float(r), u2 = lu_k_rng_float(r);\n"
         "  vec3 w = lu_k_sample_hg(lu_v3_norm(lu_v3(0.3, -0.5, 0.8)), 0.6, u1, u2);\n"
         "  o[8 * i + 1] = w.x; o[8 * i + 2] = w.z;\n"
         "  lu_k_dielectric_sample ds = lu_k_sample_dielectric(lu_v3_norm(lu_v3(u1 - 0.5, u2 - 0.5, -1.0)),\n"
         "                                                      lu_v3(0.0, 0.0, 1.0), 1.3, lu_k_rng_float(r));\n"
         "  o[8 * i + 3] = ds.wi.x + (ds.refracted ? 10.0 : 0.0);\n"
         "  lu_k_equiangular e = lu_k_equiangular_make(lu_v3(u1, u2, 0.3), lu_v3(-1.0, 0.0, 0.0), lu_v3(1.0, 0.0, "
         "0.0), 2.0);\n"
         "  float s = lu_k_equiangular_sample(e, u1);\n"
         "  o[8 * i + 4] = s; o[8 * i + 5] = lu_k_equiangular_pdf(e, s);\n"
         "  float pdf;\n"
         "  vec3 wi = lu_k_sample_blinn_phong(lu_v3s(0.5), lu_v3s(0.3), 40.0, lu_v3(0.0, 0.0, 1.0),\n"
         "                                    lu_v3_norm(lu_v3(0.3, 0.1, 1.0)), u1, u2, lu_k_rng_float(r), pdf);\n"
         "  o[8 * i + 6] = pdf;\n"
         "  vec3 t = lu_k_ratio_tracking(0, 0, lu_v3(0.1 * float(i), 0.0, 0.0), lu_v3(0.0, 0.6, 0.8), 0.0, 3.0, 2.0,\n"
         "                               lu_v3(0.9, 0.5, 0.2), 0.9, r);\n"
         "  o[8 * i + 7] = t.y;\n"
         "}\n"},
    };
    const int N = 256;
    lu_gpu_program *p = NULL;
    lu_gpu_buffer *buf = NULL;
    float *gpu = calloc((size_t)N * 8, sizeof(float));
    CHECK_OK(lu_gpu_program_create_ex(ctx, "tests/pt_kernels.comp", NULL, ov, 1, &p, &err), &err);
    if (p) {
        CHECK_OK(lu_gpu_buffer_create(ctx, sizeof(float) * 8 * N, NULL, &buf, &err), &err);
        lu_gpu_uniform_int(p, "u_count", N);
        CHECK_OK(lu_gpu_buffer_bind(buf, 0, &err), &err);
        CHECK_OK(lu_gpu_dispatch(p, (N + 63) / 64, 1, 1, &err), &err);
        CHECK_OK(lu_gpu_buffer_download(buf, 0, gpu, sizeof(float) * 8 * N, &err), &err);
    }
    /* The C side of the same expressions. */
    int mismatches = 0, tracking_diff = 0;
    for (int i = 0; i < N && p; i++) {
        float c[8];
        lu_k_rng r = lu_k_rng_make(7u, (uint32_t)i, 3u);
        c[0] = (float)(lu_k_rng_u32(&r) >> 8u);
        float u1 = lu_k_rng_float(&r), u2 = lu_k_rng_float(&r);
        lu_vec3 w = lu_k_sample_hg(lu_v3_norm(lu_v3(0.3f, -0.5f, 0.8f)), 0.6f, u1, u2);
        c[1] = w.x;
        c[2] = w.z;
        lu_k_dielectric_sample ds = lu_k_sample_dielectric(lu_v3_norm(lu_v3(u1 - 0.5f, u2 - 0.5f, -1.0f)),
                                                           lu_v3(0, 0, 1), 1.3f, lu_k_rng_float(&r));
        c[3] = ds.wi.x + (ds.refracted ? 10.0f : 0.0f);
        lu_k_equiangular e = lu_k_equiangular_make(lu_v3(u1, u2, 0.3f), lu_v3(-1, 0, 0), lu_v3(1, 0, 0), 2.0f);
        c[4] = lu_k_equiangular_sample(e, u1);
        c[5] = lu_k_equiangular_pdf(e, c[4]);
        float pdf;
        lu_k_sample_blinn_phong(lu_v3s(0.5f), lu_v3s(0.3f), 40.0f, lu_v3(0, 0, 1), lu_v3_norm(lu_v3(0.3f, 0.1f, 1.0f)),
                                u1, u2, lu_k_rng_float(&r), &pdf);
        c[6] = pdf;
        /* Ratio tracking draws a data-dependent number of random numbers:
         * compare its mean below rather than each value. */
        for (int k = 0; k < 7; k++)
            if (fabsf(c[k] - gpu[8 * i + k]) > 2e-4f * (1.0f + fabsf(c[k]))) mismatches++;
        tracking_diff += gpu[8 * i + 7] < 0.0f || gpu[8 * i + 7] > 1.0f;
    }
    CHECK_MSG(mismatches == 0, "%d C/GLSL mismatches", mismatches);
    CHECK(tracking_diff == 0);
    lu_gpu_buffer_destroy(buf);
    lu_gpu_program_destroy(p);
    lu_gpu_context_destroy(ctx);
    free(gpu);
}

/* RUN_TEST plus the wall time, so the suite's cost stays visible. */
#define TIMED(fn)                                                                                                      \
    do {                                                                                                               \
        double t0_ = lu_time_seconds();                                                                                \
        RUN_TEST(fn);                                                                                                  \
        fprintf(stderr, "  (%s: %.2f s)\n", #fn, lu_time_seconds() - t0_);                                             \
    } while (0)

int main(void) {
    TIMED(test_rng);
    TIMED(test_hg_sampling);
    TIMED(test_blinn_phong_sampling);
    TIMED(test_dielectric);
    TIMED(test_equiangular);
    TIMED(test_majorant_bounds);
    TIMED(test_ratio_tracking_unbiased);
    TIMED(test_depth1_matches_reference);
    TIMED(test_slab_integral_equation);
    TIMED(test_white_furnace);
    TIMED(test_env_lambert_plane);
    TIMED(test_refract_identity);
    TIMED(test_determinism_and_progressive);
    TIMED(test_bad_parameters);
    TIMED(test_kernels_glsl);
    TEST_EXIT();
}
