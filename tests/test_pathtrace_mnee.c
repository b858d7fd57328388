/* Delta lights behind a refracting boundary (manifold next-event estimation,
 * docs/pathtrace.md) against numbers derived independently of the path
 * tracer, on an isotropic half-space of index 1.5 (sigma_t = 1, single-
 * scattering albedos 0.3, 0.6, 0.9 in R, G, B) seen along its normal:
 *   - max_depth=1, directional lights at several angles: single scattering
 *     through a flat dielectric interface in closed form, the light refracted
 *     in with Fresnel transmittance and its beam widened by cos_i / cos_t, the
 *     view ray's Fresnel transmittance and radiance factor 1 / eta^2, the
 *     integral along the view ray exp(-sigma_t z (1 + 1 / mu_t));
 *   - max_depth=1, a point light on the view axis: the paraxial irradiance
 *     I T / (h + z / eta)^2 (the source at its apparent height) integrated
 *     along the axis by Gauss-Legendre quadrature;
 *   - all orders: by reciprocity the radiance seen along the normal under
 *     directional lights at the Gauss-Legendre nodes mu_k of [0, 1], each of
 *     irradiance 2 pi w_k, is the half-space's albedo for light along the
 *     normal, F_t(0) times the random walk's total (bssrdf's profile_mc.h,
 *     the walk of `lucent profile --mc`), within 3 standard errors of both
 *     estimators together. Before manifold next-event estimation the path
 *     tracer missed single scattering and light reflected inside between its
 *     first two scattering events, 10-20 % here. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kernels/lu_optics.h"
#include "lu_test.h"
#include "methods/bssrdf/profile_mc.h"

#define ETA 1.5
#define NL 8 /* Gauss-Legendre nodes of the light directions */

static const double k_sigma_s[3] = {0.3, 0.6, 0.9};

static void channel_stats(const lu_image *img, int c, double *mean, double *se) {
    int n = img->width * img->height;
    double m = 0, v = 0;
    for (int i = 0; i < n; i++) m += img->rgb[3 * i + c];
    m /= n;
    for (int i = 0; i < n; i++) v += (img->rgb[3 * i + c] - m) * (img->rgb[3 * i + c] - m);
    *mean = m;
    *se = sqrt(v / (n - 1) / n);
}

/* The half-space (a box 200 x 100 x 200 mean free paths, top at y = 50, at
 * least 50 diffusion lengths from the seen patch through its sides and
 * bottom) seen from 10 units above along its normal, field of view `fov`
 * degrees; `lights` is the JSON light list. */
static void scene_json(char *buf, size_t cap, double fov, const char *lights) {
    snprintf(buf, cap,
             "{\"camera\": {\"position\": [0, 60, 0.0001], \"look_at\": [0, 0, 0], \"fov_y_deg\": %g,"
             " \"width\": 16, \"height\": 16},"
             " \"lights\": [%s],"
             " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [0.3, 0.6, 0.9], \"sigma_a\": [0.7, 0.4, 0.1],"
             "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [200, 100, 200]}, \"eta\": %g}}]}",
             fov, lights, ETA);
}

/* Directional lights at the nodes mu_k of [0, 1] in the x-y plane, each of
 * irradiance 2 pi w_k. */
static void gl_lights(char *buf, size_t cap, double *mu, double *w) {
    double x[NL], wx[NL];
    lu_test_gauss_legendre(NL, x, wx);
    size_t at = 0;
    for (int k = 0; k < NL; k++) {
        mu[k] = 0.5 * (x[k] + 1.0);
        w[k] = 0.5 * wx[k];
        at += (size_t)snprintf(buf + at, cap - at,
                               "%s{\"type\": \"directional\", \"direction\": [%.9f, %.9f, 0], \"irradiance\": %.9f}",
                               k ? ", " : "", sqrt(1.0 - mu[k] * mu[k]), mu[k], 2.0 * M_PI * w[k]);
    }
}

static double fresnel_t(double cos_i) { return (double)lu_k_fresnel_transmittance((float)cos_i, (float)ETA); }

static void test_single_scattering_directional(void) {
    char lights[2048], json[4096];
    double mu[NL], w[NL];
    gl_lights(lights, sizeof lights, mu, w);
    scene_json(json, sizeof json, 4.0, lights);
    lu_image img = {0};
    if (!lu_test_render_json(json, "pathtrace", "pathtrace.spp=64 pathtrace.max_depth=1 pathtrace.seed=5 pathtrace.boundary=refract", &img)) return;
    double view = fresnel_t(1.0) / (ETA * ETA);
    for (int c = 0; c < 3; c++) {
        double want = 0.0;
        for (int k = 0; k < NL; k++) {
            double mt = sqrt(1.0 - (1.0 - mu[k] * mu[k]) / (ETA * ETA));
            want += view * k_sigma_s[c] / (4.0 * M_PI) * 2.0 * M_PI * w[k] * fresnel_t(mu[k]) * mu[k] / (mt + 1.0);
        }
        double got, se;
        channel_stats(&img, c, &got, &se);
        fprintf(stderr, "  single scattering, %d directional lights, channel %d: path tracer %.6f +- %.6f, closed form %.6f\n",
                NL, c, got, se, want);
        CHECK_NEAR(got, want, 3.0 * se);
        CHECK(se < 0.01 * want);
    }
    lu_image_destroy(&img);
}

static void test_single_scattering_point(void) {
    /* Point light 4 units above the surface on the view axis (the camera,
     * above it, looks past it). On the axis the light arrives at normal
     * incidence; over the 0.25 degrees the pixels see, the view rays stay
     * within 0.05 units of the axis, 0.7 degrees off it as the light sees
     * them, a change in irradiance below 1e-3. */
    const double h = 4.0, intensity = 100.0;
    char lights[256], json[4096];
    snprintf(lights, sizeof lights, "{\"type\": \"point\", \"position\": [0, %g, 0], \"intensity\": %g}", 50.0 + h,
             intensity);
    scene_json(json, sizeof json, 0.25, lights);
    lu_image img = {0};
    if (!lu_test_render_json(json, "pathtrace", "pathtrace.spp=64 pathtrace.max_depth=1 pathtrace.seed=6 pathtrace.boundary=refract", &img)) return;
    /* L = T(0)^2 / eta^2 sigma_s / (4 pi) int_0^inf I / (h + z / eta)^2 exp(-2 z) dz; z = -ln(1 - u) / 2 maps the
     * exponential onto [0, 1). */
    enum { NQ = 64 };
    double x[NQ], wq[NQ];
    lu_test_gauss_legendre(NQ, x, wq);
    double integral = 0.0;
    for (int i = 0; i < NQ; i++) {
        double u = 0.5 * (x[i] + 1.0), z = -log(1.0 - u) / 2.0;
        integral += 0.5 * wq[i] * intensity / ((h + z / ETA) * (h + z / ETA)) / 2.0;
    }
    for (int c = 0; c < 3; c++) {
        double want = fresnel_t(1.0) * fresnel_t(1.0) / (ETA * ETA) * k_sigma_s[c] / (4.0 * M_PI) * integral;
        double got, se;
        channel_stats(&img, c, &got, &se);
        fprintf(stderr, "  single scattering, point light on the axis, channel %d: path tracer %.6f +- %.6f, quadrature %.6f\n",
                c, got, se, want);
        CHECK_NEAR(got, want, 3.0 * se + 1e-3 * want);
        CHECK(se < 0.01 * want);
    }
    lu_image_destroy(&img);
}

static void test_halfspace_albedo_against_walk(void) {
    char lights[2048], json[4096];
    double mu[NL], w[NL];
    gl_lights(lights, sizeof lights, mu, w);
    scene_json(json, sizeof json, 4.0, lights);
    lu_image img = {0};
    if (!lu_test_render_json(json, "pathtrace", "pathtrace.spp=48 pathtrace.seed=7 pathtrace.boundary=refract", &img)) return;
    for (int c = 0; c < 3; c++) {
        lu_bssrdf_mc_result mc;
        lu_error err = {0};
        CHECK_OK(lu_bssrdf_mc_slab(k_sigma_s[c], 1.0 - k_sigma_s[c], ETA, INFINITY, 400000, 17 + (unsigned)c, 1, 1.0,
                                   &mc, &err),
                 &err);
        if (err.code != LU_OK) break;
        double want = fresnel_t(1.0) * mc.r_total, want_se = fresnel_t(1.0) * mc.r_stderr;
        double single = fresnel_t(1.0) * (mc.r_total - mc.r_multiple_total);
        lu_bssrdf_mc_destroy(&mc);
        double got, se;
        channel_stats(&img, c, &got, &se);
        double sigma = sqrt(se * se + want_se * want_se);
        fprintf(stderr,
                "  half-space albedo, all orders, channel %d: path tracer %.5f +- %.5f, walk x F_t(0) %.5f +- %.5f "
                "(of it single scattering %.5f)\n",
                c, got, se, want, want_se, single);
        CHECK_NEAR(got, want, 3.0 * sigma);
        CHECK(sigma < 0.02 * want); /* the check has power: the paths once missed are 10-20 % */
    }
    lu_image_destroy(&img);
}

int main(void) {
    RUN_TEST(test_single_scattering_directional);
    RUN_TEST(test_single_scattering_point);
    RUN_TEST(test_halfspace_albedo_against_walk);
    TEST_EXIT();
}
