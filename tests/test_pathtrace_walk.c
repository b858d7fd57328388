/* The path tracer's subsurface random walk against numbers derived
 * independently of it:
 *   - boundary=diffuse (Lambertian entry and exit, no Fresnel, the walk ends
 *     at its first boundary hit): the albedo of an index-matched isotropic
 *     half-space under uniform light equals the bihemispherical albedo
 *     1 - 2 sqrt(1 - w) int_0^1 H(mu) mu dmu, with Chandrasekhar's H-function
 *     solved here by quadrature (Radiative Transfer, 1960, ch. V), for three
 *     single-scattering albedos at once (one per channel). */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lu_test.h"

static bool render_json(const char *json, const char *settings, lu_image *img) {
    lu_scene s;
    lu_error err = {0};
    lu_kvlist kv = {0};
    CHECK_OK(lu_scene_load_string(json, "test.json", &s, &err), &err);
    if (err.code != LU_OK) return false;
    lu_test_settings(&kv, settings);
    lu_renderer *r = NULL;
    lu_result res = lu_renderer_create("pathtrace", &s, &kv, LU_BACKEND_CPU, &r, &err);
    if (res == LU_OK) res = lu_renderer_render(r, &s, img, &err);
    if (res != LU_OK) {
        fprintf(stderr, "render failed: %s\n", err.message);
        lu_test_failures++;
    }
    lu_renderer_destroy(r);
    lu_scene_destroy(&s);
    lu_kv_free(&kv);
    return res == LU_OK;
}

static void channel_stats(const lu_image *img, int c, double *mean, double *se) {
    int n = img->width * img->height;
    double m = 0, v = 0;
    for (int i = 0; i < n; i++) m += img->rgb[3 * i + c];
    m /= n;
    for (int i = 0; i < n; i++) v += (img->rgb[3 * i + c] - m) * (img->rgb[3 * i + c] - m);
    *mean = m;
    *se = sqrt(v / (n - 1) / n);
}

/* ---- Chandrasekhar's H-function for isotropic scattering -------------------------------- */

#define HN 96

/* H at the Gauss-Legendre nodes mu[] on [0, 1] (weights wq[]), by iterating
 * 1 / H(mu) = sqrt(1 - w) + (w / 2) int_0^1 mu' H(mu') / (mu + mu') dmu'
 * (Chandrasekhar 1960, eq. V.(40)), which converges for every w <= 1. */
static void h_function(double w, const double *mu, const double *wq, double *h) {
    for (int i = 0; i < HN; i++) h[i] = 1.0;
    double s = sqrt(1.0 - w);
    for (int it = 0; it < 20000; it++) {
        double change = 0.0;
        for (int i = 0; i < HN; i++) {
            double acc = 0.0;
            for (int j = 0; j < HN; j++) acc += wq[j] * mu[j] * h[j] / (mu[i] + mu[j]);
            double hn = 1.0 / (s + 0.5 * w * acc);
            change = fmax(change, fabs(hn - h[i]));
            h[i] = hn;
        }
        if (change < 1e-13) break;
    }
}

/* Bihemispherical albedo of the index-matched half-space: the entry direction
 * is cosine-distributed (2 mu dmu) and the plane albedo at mu is
 * 1 - sqrt(1 - w) H(mu). */
static double halfspace_albedo(double w) {
    double x[HN], wx[HN], mu[HN], wq[HN], h[HN];
    lu_test_gauss_legendre(HN, x, wx);
    for (int i = 0; i < HN; i++) {
        mu[i] = 0.5 * (x[i] + 1.0);
        wq[i] = 0.5 * wx[i];
    }
    h_function(w, mu, wq, h);
    /* The zeroth moment has a closed form: int H = (2 / w) (1 - sqrt(1 - w)). */
    double h0 = 0.0, h1 = 0.0;
    for (int i = 0; i < HN; i++) {
        h0 += wq[i] * h[i];
        h1 += wq[i] * h[i] * mu[i];
    }
    CHECK_NEAR(h0, 2.0 / w * (1.0 - sqrt(1.0 - w)), 1e-9);
    return 1.0 - 2.0 * sqrt(1.0 - w) * h1;
}

static void test_diffuse_boundary_halfspace(void) {
    /* A conservative medium has albedo 1 (and the quadrature knows it). */
    CHECK_NEAR(halfspace_albedo(1.0), 1.0, 1e-9);
    /* sigma_t = 1 per unit in every channel; the box is 200 x 100 x 200 mean
     * free paths, at least 17 diffusion lengths (1 / sigma_tr) from the seen
     * patch in every direction for w <= 0.99, so light through its sides and
     * bottom is below e^-17 of the signal. The camera sees a small patch at
     * the top's centre; the eta given is ignored by a diffuse boundary. */
    const double w[3] = {0.5, 0.9, 0.99};
    const char *json =
        "{\"camera\": {\"position\": [0, 60, 0.0001], \"look_at\": [0, 0, 0], \"fov_y_deg\": 4,"
        " \"width\": 16, \"height\": 16},"
        " \"lights\": [{\"type\": \"environment\", \"radiance\": 1}],"
        " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [0.5, 0.9, 0.99], \"sigma_a\": [0.5, 0.1, 0.01],"
        "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [200, 100, 200]}, \"eta\": 1.4}}]}";
    lu_image img = {0};
    if (!render_json(json, "pathtrace.spp=256 pathtrace.seed=3 pathtrace.boundary=diffuse", &img)) return;
    for (int c = 0; c < 3; c++) {
        double want = halfspace_albedo(w[c]), got, se;
        channel_stats(&img, c, &got, &se);
        fprintf(stderr, "  diffuse boundary, half-space albedo at w = %.2f: path tracer %.5f +- %.5f, H-function %.5f\n",
                w[c], got, se, want);
        CHECK_NEAR(got, want, 3.0 * se);
        CHECK(se < 0.01 * want); /* the check has power */
    }
    lu_image_destroy(&img);
}

int main(void) {
    RUN_TEST(test_diffuse_boundary_halfspace);
    TEST_EXIT();
}
