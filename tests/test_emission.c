/* Emission in participating media (include/lucent/scene.h, docs/volumes.md):
 *   - the blackbody table against an independent Gauss-Legendre quadrature of
 *     Planck's law times the CIE fit (Wyman, Sloan and Shirley 2013, its
 *     coefficients typed in here from the paper), the Planckian locus'
 *     chromaticities from the CIE 1931 tables at 2000, 3000 and 6504 K, and
 *     the white point (6504 K is nearly equal RGB);
 *   - a constant emissive slab (sigma_a Le convention), seen head-on without
 *     lights: L = Le sigma_a / sigma_t (1 - exp(-sigma_t d)) per channel,
 *     for reference, pathtrace (max_depth 1, noise bound from the pixels'
 *     spread), every march method on the CPU, and on the GPU (= CPU and =
 *     the closed form);
 *   - early termination drops emission behind an opaque-looking slab within
 *     the stated bound t_cut (sigma_a / sigma_t) Le;
 *   - reference = pathtrace (max_depth 1) on a heterogeneous temperature
 *     medium (hotter where denser) under a light, within the bound of pathtrace's own noise
 *     (estimated from two seeds);
 *   - temperature emission on the GPU = the CPU, every march method;
 *   - ddod and bssrdf refuse emissive media, naming the medium. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "lu_test.h"

/* ---- blackbody ------------------------------------------------------------------- */

static double g_lobe(double x, double mu, double s1, double s2) {
    double t = (x - mu) / (x < mu ? s1 : s2);
    return exp(-0.5 * t * t);
}

/* Planck times the fit, integrated by 16-point Gauss-Legendre on 47 panels of
 * 10 nm; returns XYZ / integral(y-bar) of the peak-normalised spectrum. */
static void bb_xyz(double T, double xyz[3]) {
    double gx[16], gw[16];
    lu_test_gauss_legendre(16, gx, gw);
    const double c = 299792458.0, h = 6.62606957e-34, k = 1.3806488e-23;
    double lpeak = 2.8977721e-3 / T;
    double bpeak = 2 * h * c * c / (pow(lpeak, 5) * (exp(h * c / (lpeak * k * T)) - 1));
    double X = 0, Y = 0, Z = 0, Yn = 0;
    for (int p = 0; p < 47; p++) {
        double a = 360.0 + 10.0 * p;
        for (int i = 0; i < 16; i++) {
            double nm = a + 5.0 * (gx[i] + 1.0), w = 5.0 * gw[i], l = nm * 1e-9;
            double b = 2 * h * c * c / (pow(l, 5) * (exp(h * c / (l * k * T)) - 1)) / bpeak;
            double xb = 1.056 * g_lobe(nm, 599.8, 37.9, 31.0) + 0.362 * g_lobe(nm, 442.0, 16.0, 26.7) -
                        0.065 * g_lobe(nm, 501.1, 20.4, 26.2);
            double yb = 0.821 * g_lobe(nm, 568.8, 46.9, 40.5) + 0.286 * g_lobe(nm, 530.9, 16.3, 31.1);
            double zb = 1.217 * g_lobe(nm, 437.0, 11.8, 36.0) + 0.681 * g_lobe(nm, 459.0, 26.0, 13.8);
            X += w * b * xb;
            Y += w * b * yb;
            Z += w * b * zb;
            Yn += w * yb;
        }
    }
    xyz[0] = X / Yn;
    xyz[1] = Y / Yn;
    xyz[2] = Z / Yn;
}

static void test_blackbody_table(void) {
    /* Between table nodes and at odd temperatures; relative to the largest
     * channel (the blue of a 900 K body is ~1e-6 of its red). */
    const double temps[] = {500.0, 900.0, 1234.5, 1850.0, 2700.0, 4321.0, 6504.0, 9876.0, 25000.0, 77777.0};
    for (size_t i = 0; i < sizeof temps / sizeof temps[0]; i++) {
        double xyz[3];
        bb_xyz(temps[i], xyz);
        double rgb[3] = {3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2],
                         -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2],
                         0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2]};
        lu_vec3 t = lu_blackbody_rgb((float)temps[i]), e = lu_blackbody_rgb_exact(temps[i]);
        double mx = fmax(rgb[0], fmax(rgb[1], rgb[2]));
        for (int ch = 0; ch < 3; ch++) {
            double want = fmax(rgb[ch], 0.0);
            CHECK_MSG(fabs(lu_v3_get(e, ch) - want) <= 1e-5 * mx, "T %g ch %d: exact %.8g, quadrature %.8g", temps[i],
                      ch, lu_v3_get(e, ch), want);
            CHECK_MSG(fabs(lu_v3_get(t, ch) - want) <= 2e-4 * mx, "T %g ch %d: table %.8g, quadrature %.8g", temps[i],
                      ch, lu_v3_get(t, ch), want);
        }
    }
    CHECK(lu_v3_maxc(lu_blackbody_rgb(100.0f)) == 0.0f);
    CHECK(lu_v3_maxc(lu_blackbody_rgb(-5.0f)) == 0.0f);
    CHECK(lu_v3_maxc(lu_blackbody_rgb(NAN)) == 0.0f);
}

static void test_blackbody_locus(void) {
    /* Planckian locus from the CIE 1931 tables (Wyszecki and Stiles): the fit
     * of the matching functions moves chromaticity by ~1e-3. The test inverts
     * the library's RGB to XYZ (the inverse sRGB matrix, IEC 61966-2-1). */
    const struct {
        double T, x, y;
    } locus[] = {{2000.0, 0.5267, 0.4133}, {3000.0, 0.4369, 0.4041}, {6504.0, 0.3135, 0.3236}};
    for (int i = 0; i < 3; i++) {
        lu_vec3 c = lu_blackbody_rgb((float)locus[i].T);
        double X = 0.4124564 * c.x + 0.3575761 * c.y + 0.1804375 * c.z;
        double Y = 0.2126729 * c.x + 0.7151522 * c.y + 0.0721750 * c.z;
        double Z = 0.0193339 * c.x + 0.1191920 * c.y + 0.9503041 * c.z;
        double x = X / (X + Y + Z), y = Y / (X + Y + Z);
        fprintf(stderr, "  %5.0f K: xy (%.4f, %.4f), CIE (%.4f, %.4f)\n", locus[i].T, x, y, locus[i].x, locus[i].y);
        CHECK_NEAR(x, locus[i].x, 3e-3);
        CHECK_NEAR(y, locus[i].y, 3e-3);
    }
    /* White point: 6504 K lies 0.0054 in y from D65 (0.3127, 0.3290), a few
     * per cent of colour: equal RGB within 10 %. */
    lu_vec3 w = lu_blackbody_rgb(6504.0f);
    double mx = lu_v3_maxc(w), mn = fmin(w.x, fmin(w.y, w.z));
    fprintf(stderr, "  6504 K: rgb / max = (%.4f, %.4f, %.4f)\n", w.x / mx, w.y / mx, w.z / mx);
    CHECK_MSG(mn >= 0.9 * mx, "6504 K: rgb (%g, %g, %g) not near white", w.x, w.y, w.z);
    /* Redder when cooler. */
    lu_vec3 a = lu_blackbody_rgb(1500.0f), b = lu_blackbody_rgb(3000.0f);
    CHECK(a.z / a.x < b.z / b.x);
}

/* ---- rendering helpers ----------------------------------------------------------- */

static lu_result render(const char *json, const char *method, lu_backend b, const char *settings, lu_image *img,
                        lu_error *err) {
    lu_scene s;
    memset(img, 0, sizeof *img);
    lu_result r = lu_scene_load_string(json, "emission_test.json", &s, err);
    if (r != LU_OK) return r;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, settings);
    lu_renderer *rd = NULL;
    r = lu_renderer_create(method, &s, &kv, b, &rd, err);
    if (r == LU_OK) r = lu_renderer_render(rd, &s, img, err);
    lu_renderer_destroy(rd);
    lu_scene_destroy(&s);
    lu_kv_free(&kv);
    return r;
}

/* A slab of thickness 1 (constant density 1 in a wide box, eta 1: no
 * Fresnel), seen head-on from above, no lights, black background. */
static const char *k_slab =
    "{\"camera\": {\"position\": [0, 3, 0.0001], \"look_at\": [0, 0, 0], \"fov_y_deg\": 1,"
    " \"width\": 3, \"height\": 3},"
    " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [0.6, 0.3, 0.2], \"sigma_a\": [0.2, 1.0, 0.3],"
    "   \"emission\": {\"color\": [1, 0.5, 2], \"scale\": 3},"
    "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [40, 1, 40]}, \"eta\": 1.0}}]}";

static double slab_closed_form(int ch) {
    const double ss[3] = {0.6, 0.3, 0.2}, sa[3] = {0.2, 1.0, 0.3}, le[3] = {3.0, 1.5, 6.0};
    double st = ss[ch] + sa[ch];
    return le[ch] * sa[ch] / st * (1.0 - exp(-st * 1.0));
}

static void check_slab(const lu_image *img, const char *what, double tol) {
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++)
            for (int ch = 0; ch < 3; ch++) {
                double v = lu_image_px(img, i, j)[ch], want = slab_closed_form(ch);
                CHECK_MSG(fabs(v - want) <= tol * want, "%s: pixel (%d, %d) ch %d = %.6g, closed form %.6g", what, i, j,
                          ch, v, want);
            }
}

static void test_slab_reference(void) {
    lu_image img;
    lu_error err = {0};
    CHECK_OK(render(k_slab, "reference", LU_BACKEND_CPU, "", &img, &err), &err);
    if (err.code != LU_OK) return;
    check_slab(&img, "reference", 1e-3);
    lu_image_destroy(&img);
}

static void test_slab_pathtrace(void) {
    /* 9 pixels see the same slab: their spread estimates the noise of each,
     * and the mean of 9 has a ninth of that variance. */
    lu_image img;
    lu_error err = {0};
    CHECK_OK(render(k_slab, "pathtrace", LU_BACKEND_CPU, "pathtrace.max_depth=1 pathtrace.spp=4096", &img, &err), &err);
    if (err.code != LU_OK) return;
    for (int ch = 0; ch < 3; ch++) {
        double s = 0, s2 = 0;
        for (int p = 0; p < 9; p++) {
            double v = img.rgb[3 * p + ch];
            s += v;
            s2 += v * v;
        }
        double mean = s / 9, var = (s2 - 9 * mean * mean) / 8, se = sqrt(fmax(var, 0.0) / 9);
        double want = slab_closed_form(ch);
        fprintf(stderr, "  pathtrace slab ch %d: %.5f +- %.5f, closed form %.5f\n", ch, mean, se, want);
        CHECK_MSG(fabs(mean - want) <= 4.0 * se + 1e-4 * want, "pathtrace ch %d: %.6g vs %.6g (se %.3g)", ch, mean,
                  want, se);
        CHECK_MSG(se < 0.02 * want, "pathtrace ch %d: noise %.3g too large to test anything", ch, se);
    }
    lu_image_destroy(&img);
}

static const char *k_march[] = {"raymarch", "afm", "gradient", "rbf", "pervoxel"};

static void test_slab_march_methods(void) {
    for (size_t k = 0; k < sizeof k_march / sizeof k_march[0]; k++) {
        lu_image cpu, gpu;
        lu_error err = {0};
        lu_result r = render(k_slab, k_march[k], LU_BACKEND_CPU, "", &cpu, &err);
        CHECK_MSG(r == LU_OK, "%s (cpu): %s", k_march[k], err.message);
        if (r != LU_OK) continue;
        /* Constant extinction: the step's analytic weight makes the march
         * exact up to float rounding. */
        check_slab(&cpu, k_march[k], 1e-4);
        if (lu_test_skip_gpu(LU_BACKEND_GPU)) {
            lu_image_destroy(&cpu);
            continue;
        }
        r = render(k_slab, k_march[k], LU_BACKEND_GPU, "", &gpu, &err);
        CHECK_MSG(r == LU_OK, "%s (gpu): %s", k_march[k], err.message);
        if (r == LU_OK) {
            char what[64];
            snprintf(what, sizeof what, "%s gpu", k_march[k]);
            check_slab(&gpu, what, 1e-4);
            lu_metrics m = {0};
            CHECK_OK(lu_image_compare(&gpu, &cpu, &m, &err), &err);
            fprintf(stderr, "  %-9s slab: GPU vs CPU rel-L2 %.2e\n", k_march[k], m.rel_l2);
            CHECK_MSG(m.rel_l2 <= 1e-5, "%s: GPU vs CPU rel-L2 %.3g", k_march[k], m.rel_l2);
            lu_image_destroy(&gpu);
        }
        lu_image_destroy(&cpu);
    }
}

/* Early termination with emission: an absorbing slab (optical depth 7,
 * transmittance 9.1e-4) in front of an emissive one. With t_cut = 1e-3 the
 * march stops inside the front slab and drops exactly the back slab's
 * T_front * Le sigma_a / sigma_t (1 - exp(-sigma_t d)); the bound the march
 * states is t_cut * (sigma_a / sigma_t) Le. With t_cut = 0 nothing is dropped.
 * The march's steps (union box diagonal / steps) do not end on the slabs'
 * faces: a step across a face takes its midpoint's density, so each face
 * moves the optical depth by at most sigma h / 2, the march's own error. */
static void test_cut_with_emission(void) {
    const char *json =
        "{\"camera\": {\"position\": [0, 3, 0.0001], \"look_at\": [0, 0, 0], \"fov_y_deg\": 1,"
        " \"width\": 3, \"height\": 3},"
        " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": 0, \"sigma_a\": 7,"
        "   \"transform\": {\"translate\": [0, 1, 0]},"
        "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [40, 1, 40]}, \"eta\": 1.0}},"
        "  {\"density\": {\"constant\": 1}, \"sigma_s\": 0.5, \"sigma_a\": 1.5, \"emission\": {\"scale\": 200},"
        "   \"transform\": {\"translate\": [0, -1, 0]},"
        "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [40, 1, 40]}, \"eta\": 1.0}}]}";
    const double le_src = 200.0 * 1.5 / 2.0, back = le_src * (1.0 - exp(-2.0)), front_t = exp(-7.0);
    lu_image full, cut;
    lu_error err = {0};
    CHECK_OK(render(json, "raymarch", LU_BACKEND_CPU, "raymarch.t_cut=0 raymarch.steps=16384", &full, &err), &err);
    if (err.code != LU_OK) return;
    CHECK_OK(render(json, "raymarch", LU_BACKEND_CPU, "raymarch.t_cut=0.001 raymarch.steps=16384", &cut, &err), &err);
    if (err.code != LU_OK) return;
    double f = lu_image_px(&full, 1, 1)[0], c = lu_image_px(&cut, 1, 1)[0], dropped = f - c;
    fprintf(stderr, "  cut: full %.6g (closed form %.6g), cut %.6g, dropped %.6g, bound %.6g\n", f, front_t * back, c,
            dropped, 1e-3 * le_src);
    double h = sqrt(40.0 * 40.0 * 2 + 3.0 * 3.0) / 16384.0;
    CHECK_REL(f, front_t * back, expm1((7.0 + 2.0) * h));
    CHECK_NEAR(c, 0.0, 1e-9);
    CHECK_MSG(dropped <= 1e-3 * le_src, "dropped %.6g > bound %.6g", dropped, 1e-3 * le_src);
    lu_image_destroy(&full);
    lu_image_destroy(&cut);
}

/* A heterogeneous medium with temperature: Gaussian blobs of density and of
 * temperature (other seed, same box and resolution: one index space), and a
 * directional light, so single scattering and emission both count. */
#define K_HOT(EMISSION)                                                                                          \
    "{\"camera\": {\"position\": [0, 0.3, 3.2], \"look_at\": [0, 0, 0], \"fov_y_deg\": 12,"                       \
    " \"width\": 8, \"height\": 8},"                                                                                \
    " \"lights\": [{\"type\": \"directional\", \"direction\": [0.3, 1, 0.4], \"irradiance\": 1.5}],"               \
    " \"media\": [{\"density\": {\"procedural\": \"gaussians\", \"resolution\": 16, \"count\": 6, \"seed\": 3},"  \
    "   \"sigma_s\": 2.0, \"sigma_a\": [1.0, 1.2, 1.5], \"phase_g\": 0.3" EMISSION "}]}"
static const char *k_hot =
    K_HOT(", \"emission\": {\"scale\": 4, \"temperature\": {\"procedural\": \"gaussians\", \"resolution\": 16,"
          " \"count\": 6, \"seed\": 3}, \"temperature_scale\": 2500, \"temperature_offset\": 0.1}");
static const char *k_cold = K_HOT("");

static void test_reference_equals_pathtrace(void) {
    lu_image ref, ref64, a, b;
    lu_error err = {0};
    /* pathtrace averages each pixel's area, so the reference does too (R2
     * supersampling): 256 samples, whose own error is bounded by its
     * distance from 64 samples (the blackbody makes Le vary within a pixel). */
    CHECK_OK(render(k_hot, "reference", LU_BACKEND_CPU, "reference.spp=256", &ref, &err), &err);
    if (err.code != LU_OK) return;
    CHECK_OK(render(k_hot, "reference", LU_BACKEND_CPU, "reference.spp=64", &ref64, &err), &err);
    if (err.code != LU_OK) return;
    double rel_ref = lu_test_rel_l2(&ref64, &ref);
    CHECK_OK(render(k_hot, "pathtrace", LU_BACKEND_CPU, "pathtrace.max_depth=1 pathtrace.spp=4096 pathtrace.seed=1",
                    &a, &err),
             &err);
    CHECK_OK(render(k_hot, "pathtrace", LU_BACKEND_CPU, "pathtrace.max_depth=1 pathtrace.spp=4096 pathtrace.seed=2",
                    &b, &err),
             &err);
    if (err.code != LU_OK) return;
    /* E[((a - b) / 2)^2] is the variance of the two seeds' mean, per value:
     * the mean's rel-L2 against an unbiased truth is that noise. */
    double num = 0, noise = 0, den = 0, le = 0;
    size_t n = (size_t)ref.width * ref.height * 3;
    for (size_t i = 0; i < n; i++) {
        double m = 0.5 * (a.rgb[i] + b.rgb[i]), dv = 0.5 * (a.rgb[i] - b.rgb[i]);
        num += (m - ref.rgb[i]) * (m - ref.rgb[i]);
        noise += dv * dv;
        den += (double)ref.rgb[i] * ref.rgb[i];
    }
    /* Emission must matter here: the same scene without it differs a lot. */
    lu_image c;
    CHECK_OK(render(k_cold, "reference", LU_BACKEND_CPU, "reference.spp=256", &c, &err), &err);
    if (err.code == LU_OK) {
        for (size_t i = 0; i < n; i++) le += (double)(ref.rgb[i] - c.rgb[i]) * (ref.rgb[i] - c.rgb[i]);
        lu_image_destroy(&c);
    }
    double rel = sqrt(num / den), rel_noise = sqrt(noise / den), rel_le = sqrt(le / den);
    fprintf(stderr,
            "  reference vs pathtrace (max_depth 1): rel-L2 %.4f, pathtrace noise %.4f, reference's %.4f, emission "
            "share %.3f\n",
            rel, rel_noise, rel_ref, rel_le);
    CHECK_MSG(rel_le > 0.2, "emission adds only %.3g of the image", rel_le);
    CHECK_MSG(rel <= 2.5 * rel_noise + rel_ref, "rel-L2 %.4g > 2.5 x noise %.4g + reference's %.4g", rel, rel_noise,
              rel_ref);
    CHECK_MSG(rel_noise < 0.05, "pathtrace noise %.3g too large to test anything", rel_noise);
    lu_image_destroy(&ref);
    lu_image_destroy(&ref64);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

static void test_refusals(void) {
    const char *methods[] = {"ddod", "bssrdf"};
    for (int k = 0; k < 2; k++) {
        lu_image img;
        lu_error err = {0};
        lu_result r = render(k_slab, methods[k], LU_BACKEND_CPU, "", &img, &err);
        CHECK_MSG(r == LU_ERR_UNSUPPORTED, "%s: %d (%s)", methods[k], (int)r, err.message);
        CHECK_MSG(strstr(err.message, "medium 0") && strstr(err.message, "emissive"), "%s: \"%s\"", methods[k],
                  err.message);
        if (r == LU_OK) lu_image_destroy(&img);
    }
}

/* Temperature emission on the GPU: the grid and the blackbody table from the
 * scene buffer, GPU = CPU for every march method. */
static void test_temperature_gpu(void) {
    if (lu_test_skip_gpu(LU_BACKEND_GPU)) return;
    for (size_t k = 0; k < sizeof k_march / sizeof k_march[0]; k++) {
        lu_image cpu, gpu;
        lu_error err = {0};
        CHECK_OK(render(k_hot, k_march[k], LU_BACKEND_CPU, "", &cpu, &err), &err);
        if (err.code != LU_OK) continue;
        CHECK_OK(render(k_hot, k_march[k], LU_BACKEND_GPU, "", &gpu, &err), &err);
        if (err.code == LU_OK) {
            lu_metrics m = {0};
            CHECK_OK(lu_image_compare(&gpu, &cpu, &m, &err), &err);
            fprintf(stderr, "  %-9s temperature: GPU vs CPU rel-L2 %.2e\n", k_march[k], m.rel_l2);
            /* the suite's GPU = CPU bound (tests/test_cross_backend.c) */
            CHECK_MSG(m.rel_l2 <= 1e-3, "%s: GPU vs CPU rel-L2 %.3g", k_march[k], m.rel_l2);
            lu_image_destroy(&gpu);
        }
        lu_image_destroy(&cpu);
    }
}

int main(void) {
    RUN_TEST(test_blackbody_table);
    RUN_TEST(test_blackbody_locus);
    RUN_TEST(test_slab_reference);
    RUN_TEST(test_slab_pathtrace);
    RUN_TEST(test_slab_march_methods);
    RUN_TEST(test_cut_with_emission);
    RUN_TEST(test_reference_equals_pathtrace);
    RUN_TEST(test_refusals);
    RUN_TEST(test_temperature_gpu);
    TEST_EXIT();
}
