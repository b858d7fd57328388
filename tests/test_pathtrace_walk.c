/* The path tracer's subsurface random walk against numbers derived
 * independently of it:
 *   - boundary=diffuse (Lambertian entry and exit, no Fresnel, the walk ends
 *     at its first boundary hit): the albedo of an index-matched isotropic
 *     half-space under uniform light equals the bihemispherical albedo
 *     1 - 2 sqrt(1 - w) int_0^1 H(mu) mu dmu, with Chandrasekhar's H-function
 *     solved here by quadrature (Radiative Transfer, 1960, ch. V), for three
 *     single-scattering albedos at once (one per channel);
 *   - Dwivedi sampling (pathtrace.guide=dwivedi): v0 solves its transcendental
 *     equation, the direction density integrates to 1 and matches the
 *     sampler's histogram; the guided walk returns the same half-space
 *     albedo, keeps an albedo-1 dielectric sphere a white furnace, and its
 *     mean equals the unguided walk's on an absorbing dielectric sphere
 *     within 3 standard errors of the two together. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lu_test.h"
#include "methods/pathtrace/pathtrace_internal.h"


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

static void test_dwivedi_sampling(void) {
    const double albedo[4] = {0.3, 0.9, 0.99, 0.9999};
    for (int k = 0; k < 4; k++) {
        double a = albedo[k], v0 = lu_pt_dwivedi_v0(a);
        CHECK_NEAR(0.5 * a * v0 * log((v0 + 1) / (v0 - 1)), 1.0, 1e-9);
        /* Large v0: the diffusion limit v0 -> 1 / sqrt(3 (1 - a)). */
        if (a > 0.999) CHECK_REL(v0, 1.0 / sqrt(3.0 * (1.0 - a)), 0.01);
        float fv = (float)v0, lr = lu_pt_dwivedi_log(fv);
        /* The density per steradian integrates to 1 (midpoint rule in mu0). */
        double total = 0.0;
        const int nq = 200000;
        for (int i = 0; i < nq; i++) total += 2.0 * M_PI * lu_pt_dwivedi_pdf(fv, lr, (float)(-1.0 + (i + 0.5) * 2.0 / nq)) * (2.0 / nq);
        CHECK_NEAR(total, 1.0, 1e-4);
        /* 20-bin histogram of the sampler against the density's bin masses. */
        enum { NB = 20, NS = 200000 };
        int hist[NB] = {0};
        uint32_t x = 12345u + (uint32_t)k;
        for (int i = 0; i < NS; i++) {
            x = x * 1664525u + 1013904223u;
            float u = (float)(x >> 8) * (1.0f / 16777216.0f);
            float mu = lu_pt_dwivedi_sample(fv, lr, u);
            int b = (int)((mu + 1.0f) * 0.5f * NB);
            hist[b < 0 ? 0 : (b >= NB ? NB - 1 : b)]++;
        }
        for (int b = 0; b < NB; b++) {
            double lo = -1.0 + 2.0 * b / NB, hi = lo + 2.0 / NB;
            double mass = log((v0 - lo) / (v0 - hi)) / log((v0 + 1) / (v0 - 1)), want = mass * NS;
            CHECK_NEAR(hist[b], want, 5.0 * sqrt(want) + 1.0);
        }
    }
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
    for (int guide = 0; guide < 2; guide++) {
        lu_image img = {0};
        const char *settings = guide ? "pathtrace.spp=256 pathtrace.seed=4 pathtrace.boundary=diffuse pathtrace.guide=dwivedi"
                                     : "pathtrace.spp=256 pathtrace.seed=3 pathtrace.boundary=diffuse";
        if (!lu_test_render_json(json, "pathtrace", settings, &img)) return;
        for (int c = 0; c < 3; c++) {
            double want = halfspace_albedo(w[c]), got, se;
            channel_stats(&img, c, &got, &se);
            fprintf(stderr,
                    "  diffuse boundary%s, half-space albedo at w = %.2f: path tracer %.5f +- %.5f, H-function %.5f\n",
                    guide ? " (guided)" : "", w[c], got, se, want);
            CHECK_NEAR(got, want, 3.0 * se);
            CHECK(se < 0.01 * want); /* the check has power */
        }
        lu_image_destroy(&img);
    }
}

static const char *k_sphere =
    "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0], \"fov_y_deg\": 36, \"width\": 12, \"height\": 12},"
    " \"lights\": [{\"type\": \"environment\", \"radiance\": [0.5, 1.0, 2.0]}],"
    " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [%g, %g, %g], \"sigma_a\": [%g, %g, %g], \"phase_g\": %g,"
    "   \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1, \"subdivisions\": 3}, \"eta\": 1.5}}]}";

static void test_guided_unbiased(void) {
    char json[1024];
    /* Albedo 1 inside a dielectric: the guided walk must return the
     * environment, isotropic and forward-scattering (a smaller guided share). */
    const double L[3] = {0.5, 1.0, 2.0};
    for (int k = 0; k < 2; k++) {
        double g = k ? 0.3 : 0.0;
        snprintf(json, sizeof json, k_sphere, 6.0, 10.0, 16.0, 0.0, 0.0, 0.0, g);
        lu_image img = {0};
        if (lu_test_render_json(json, "pathtrace", "pathtrace.spp=192 pathtrace.boundary=refract pathtrace.guide=dwivedi", &img)) {
            for (int c = 0; c < 3; c++) {
                double m, se;
                channel_stats(&img, c, &m, &se);
                fprintf(stderr, "  guided furnace g = %.1f channel %d: %.5f +- %.5f (environment %.3f)\n", g, c, m, se,
                        L[c]);
                CHECK_NEAR(m, L[c], 3.0 * se + 1e-6);
                CHECK(se < 0.02 * L[c]);
            }
        }
        lu_image_destroy(&img);
    }
    /* Absorbing and chromatic, both boundaries: guided against unguided. */
    snprintf(json, sizeof json, k_sphere, 6.0, 10.0, 16.0, 0.3, 0.1, 0.02, 0.0);
    for (int bd = 0; bd < 2; bd++) {
        lu_image a = {0}, b = {0};
        char sa[256], sb[256];
        const char *boundary = bd ? "diffuse" : "refract";
        snprintf(sa, sizeof sa, "pathtrace.spp=384 pathtrace.seed=11 pathtrace.boundary=%s", boundary);
        snprintf(sb, sizeof sb, "pathtrace.spp=384 pathtrace.seed=12 pathtrace.boundary=%s pathtrace.guide=dwivedi",
                 boundary);
        if (lu_test_render_json(json, "pathtrace", sa, &a) && lu_test_render_json(json, "pathtrace", sb, &b)) {
            /* The per-pixel difference of two independent images has mean 0
             * under "same expectation" and its spread is the two estimators'
             * noise alone (the image's own structure cancels). */
            int n = a.width * a.height;
            for (int c = 0; c < 3; c++) {
                double md = 0, vd = 0, ma = 0;
                for (int i = 0; i < n; i++) {
                    md += b.rgb[3 * i + c] - a.rgb[3 * i + c];
                    ma += a.rgb[3 * i + c];
                }
                md /= n;
                ma /= n;
                for (int i = 0; i < n; i++) {
                    double e = b.rgb[3 * i + c] - a.rgb[3 * i + c] - md;
                    vd += e * e;
                }
                double se = sqrt(vd / (n - 1) / n);
                fprintf(stderr, "  absorbing sphere (%s) channel %d: unguided mean %.5f, guided - unguided %+.5f +- %.5f\n",
                        boundary, c, ma, md, se);
                CHECK_NEAR(md, 0.0, 3.0 * se);
                CHECK(se < 0.01 * ma);
            }
        }
        lu_image_destroy(&a);
        lu_image_destroy(&b);
    }
}

int main(void) {
    RUN_TEST(test_dwivedi_sampling);
    RUN_TEST(test_diffuse_boundary_halfspace);
    RUN_TEST(test_guided_unbiased);
    TEST_EXIT();
}
