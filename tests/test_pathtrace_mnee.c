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
 *     along the axis by Gauss-Legendre quadrature; and beside it: along the
 *     view line, the refraction point by bisection on Snell's law and the
 *     irradiance from the ray tube's spreading by finite differences (not the
 *     renderer's closed form), integrated the same way;
 *   - all orders: by reciprocity the radiance seen along the normal under
 *     directional lights at the Gauss-Legendre nodes mu_k of [0, 1], each of
 *     irradiance 2 pi w_k, is the half-space's albedo for light along the
 *     normal, F_t(0) times the random walk's total (bssrdf's profile_mc.h,
 *     the walk of `lucent profile --mc`), within 3 standard errors of both
 *     estimators together (8 nodes integrate the single-scattering part of
 *     the integrand to 1e-7 of 16 nodes). Before manifold next-event
 *     estimation the path tracer missed single scattering and light
 *     reflected inside between its first two scattering events: 33-79 % of
 *     this albedo, and black at max_depth=1. */
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

/* ---- a point light at oblique incidence: the ray tube by finite differences ---------------- */

typedef struct v3d {
    double x, y, z;
} v3d;

static v3d vd(double x, double y, double z) { return (v3d){x, y, z}; }
static v3d vadd(v3d a, v3d b) { return vd(a.x + b.x, a.y + b.y, a.z + b.z); }
static v3d vsc(v3d a, double s) { return vd(a.x * s, a.y * s, a.z * s); }
static double vdot(v3d a, v3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3d vcross(v3d a, v3d b) { return vd(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
static v3d vnorm(v3d a) { return vsc(a, 1.0 / sqrt(vdot(a, a))); }

/* Snell's law at the plane y = 0 (normal +y) for a ray travelling along unit d (d.y < 0). */
static v3d refract_down(v3d d) {
    double ci = -d.y, r = 1.0 / ETA, ct = sqrt(1.0 - r * r * (1.0 - ci * ci));
    return vnorm(vadd(vsc(d, r), vsc(vd(0, 1, 0), r * ci - ct)));
}

/* Where the ray from the light at lp along d, refracted at y = 0, meets the
 * plane through x with normal t. */
static v3d tube_point(v3d lp, v3d d, v3d x, v3d t) {
    v3d p = vadd(lp, vsc(d, lp.y / -d.y));
    v3d tr = refract_down(d);
    return vadd(p, vsc(tr, vdot(vadd(x, vsc(p, -1)), t) / vdot(tr, t)));
}

static void test_single_scattering_point_oblique(void) {
    /* Point light 2 units above the surface; the camera looks straight down
     * 1.5 units beside it, 0.25 degrees wide (the view rays stay within 0.05
     * units of the line, a change in irradiance below 1e-3 of it). Along
     * the view line at depth z the light's refraction point is found by
     * bisection on Snell's law, and the irradiance facing the refracted ray
     * from the spreading of the ray tube: the emission direction nudged two
     * ways, the refracted rays intersected with the plane across the ray at
     * x, intensity x solid angle / area. */
    const double h = 2.0, X = 1.5, intensity = 20.0;
    char lights[256], json[4096];
    snprintf(lights, sizeof lights, "{\"type\": \"point\", \"position\": [0, %g, 0], \"intensity\": %g}", 50.0 + h,
             intensity);
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [%g, 60, 0.0001], \"look_at\": [%g, 0, 0], \"fov_y_deg\": 0.25,"
             " \"width\": 16, \"height\": 16},"
             " \"lights\": [%s],"
             " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [0.3, 0.6, 0.9], \"sigma_a\": [0.7, 0.4, 0.1],"
             "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [200, 100, 200]}, \"eta\": %g}}]}",
             X, X, lights, ETA);
    lu_image img = {0};
    if (!lu_test_render_json(json, "pathtrace", "pathtrace.spp=64 pathtrace.max_depth=1 pathtrace.seed=8 pathtrace.boundary=refract", &img))
        return;
    /* In the surface's frame (top at y = 0): light at (0, h, 0), x = (X, -z, 0). */
    enum { NQ = 48 };
    double xq[NQ], wq[NQ];
    lu_test_gauss_legendre(NQ, xq, wq);
    double integral = 0.0; /* int_0^inf E(z) F_t(cos_i) exp(-(d2 + z)) dz, sigma_t = 1 */
    v3d lp = vd(0, h, 0);
    for (int i = 0; i < NQ; i++) {
        double u = 0.5 * (xq[i] + 1.0), z = -log(1.0 - u) / 2.0, jac = 0.5 * wq[i] / (2.0 * (1.0 - u));
        v3d x = vd(X, -z, 0);
        double lo = 0.0, hi = X; /* the refraction point (r, 0, 0): sin_i - eta sin_t rises in r */
        for (int it = 0; it < 100; it++) {
            double r = 0.5 * (lo + hi);
            double f = r / sqrt(r * r + h * h) - ETA * (X - r) / sqrt((X - r) * (X - r) + z * z);
            if (f > 0) hi = r;
            else lo = r;
        }
        v3d s = vd(0.5 * (lo + hi), 0, 0);
        v3d d = vnorm(vadd(s, vsc(lp, -1))), t = refract_down(d);
        v3d e1 = vnorm(vcross(d, vd(0, 0, 1))), e2 = vcross(d, e1);
        const double eps = 1e-6;
        v3d p0 = tube_point(lp, d, x, t);
        v3d a = vadd(tube_point(lp, vnorm(vadd(d, vsc(e1, eps))), x, t), vsc(p0, -1));
        v3d b = vadd(tube_point(lp, vnorm(vadd(d, vsc(e2, eps))), x, t), vsc(p0, -1));
        double area = sqrt(vdot(vcross(a, b), vcross(a, b)));
        double e_perp = intensity * eps * eps / area;
        double d2 = sqrt(vdot(vadd(x, vsc(s, -1)), vadd(x, vsc(s, -1))));
        integral += jac * exp(-2.0 * z) * e_perp * fresnel_t(-d.y) * exp(-(d2 - z));
    }
    for (int c = 0; c < 3; c++) {
        double want = fresnel_t(1.0) / (ETA * ETA) * k_sigma_s[c] / (4.0 * M_PI) * integral;
        double got, se;
        channel_stats(&img, c, &got, &se);
        fprintf(stderr,
                "  single scattering, point light at oblique incidence, channel %d: path tracer %.6f +- %.6f, ray-tube "
                "quadrature %.6f\n",
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
        CHECK(sigma < 0.02 * want); /* the check has power: the paths once missed are a third or more */
    }
    lu_image_destroy(&img);
}

int main(void) {
    RUN_TEST(test_single_scattering_directional);
    RUN_TEST(test_single_scattering_point);
    RUN_TEST(test_single_scattering_point_oblique);
    RUN_TEST(test_halfspace_albedo_against_walk);
    TEST_EXIT();
}
