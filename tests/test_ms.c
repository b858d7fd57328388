/* Multiple-scattering octaves of the view march (methods/common/lu_ms.h,
 * lu_view_march.h; docs/multiple-scattering.md) against numbers derived
 * without the kernel's code:
 *   - a homogeneous slab lit from the side, whose octave sum is known in
 *     closed form: every point of the camera ray sees the same distance w to
 *     the light, so octave i adds
 *       b^i albedo p(0, c^i g) E exp(-a^i sigma_t w) (1 - exp(-sigma_t D));
 *   - N = 1 is single scattering bit for bit, through the whole method
 *     (settings parsed, CPU renders of raymarch, afm and pervoxel);
 *   - with a = c = 1 every octave is b^i times single scattering, so in a
 *     scene of medium alone (black background, no surfaces) the image is
 *     (1 - b^N) / (1 - b) times the ms=off image, pixel by pixel, for
 *     raymarch and afm (whose map transmittance then enters unchanged) and
 *     the gradient family's per-voxel mode (the octaves in its radiance grid);
 *   - bad settings are refused with the setting's name.
 * GPU = CPU with the octaves on is test_ms_gpu. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "methods/common/lu_lightview.h"

struct lu_k_ctx {
    lu_k_medium km;
    lu_k_light kl;
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) { return c->km.density_scale; }
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) { return c->km.density_scale; }
#include "lu_test_march.h"

#include "methods/common/lu_view_march.h"

/* Slab |x| <= w, |y| <= 1, 0 <= z <= D seen along -z, lit along +x. */
static void test_slab_closed_form(void) {
    const float sig_t = 1.0f, albedo = 0.9f, w = 0.6f, D = 3.0f, E = 4.0f * (float)LU_PI, g = 0.6f;
    struct lu_k_ctx c;
    lu_test_march_slab(&c, sig_t, albedo, w, D, E);
    c.km.g = g;
    lu_k_rm_params P;
    memset(&P, 0, sizeof P);
    P.step = 0.01f;
    P.map_res = 1;
    lu_vec3 o = lu_v3(0, 0, D + 1.0f), d = lu_v3(0, 0, -1);
    const struct {
        int n;
        float a, b, c;
    } cases[] = {{1, 0.5f, 0.5f, 0.5f}, {2, 0.5f, 0.5f, 0.5f}, {4, 0.5f, 0.6f, 0.7f}, {6, 0.3f, 0.8f, 0.2f}, {3, 1.0f, 0.7f, 1.0f}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        P.ms = lu_k_ms_make(cases[k].n, cases[k].a, cases[k].b, cases[k].c);
        double exact = 0.0;
        for (int i = 0; i < cases[k].n; i++) {
            double gi = g * pow(cases[k].c, i);
            /* HG at cos 0: (1 - g^2) / (4 pi (1 + g^2)^1.5) */
            double p = (1.0 - gi * gi) / (4.0 * LU_PI * pow(1.0 + gi * gi, 1.5));
            exact += pow(cases[k].b, i) * albedo * p * E * exp(-pow(cases[k].a, i) * sig_t * w) * (1.0 - exp(-sig_t * D));
        }
        double got = lu_k_rm_radiance(&c, P, 0, o, d, 0.5f).x;
        fprintf(stderr, "  N=%d a=%g b=%g c=%g: march %.7g, closed form %.7g\n", cases[k].n, cases[k].a, cases[k].b,
                cases[k].c, got, exact);
        CHECK_MSG(fabs(got - exact) <= 2e-5 * exact, "N=%d: march %.8g, closed form %.8g", cases[k].n, got, exact);
    }
}

/* ---- through the methods ---- */

#define W 24
#define H 18

/* A box of medium alone (no surfaces, black background): two lights, one
 * with a shadowing path through the box, colour-dependent extinction. */
static const char *k_box_scene =
    "{\"camera\": {\"position\": [0.3, 0.4, 4.5], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 24, \"height\": 18},"
    " \"background\": [0, 0, 0],"
    " \"lights\": [{\"type\": \"point\", \"position\": [2.0, 1.5, 1.0], \"intensity\": [20, 20, 20]},"
    "              {\"type\": \"directional\", \"direction\": [-0.3, -1, -0.2], \"irradiance\": [1.5, 1.2, 1.0]}],"
    " \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"size\": [2, 1.6, 1.4], \"resolution\": 16, \"value\": 1},"
    "              \"sigma_s\": [1.8, 1.5, 1.2], \"sigma_a\": [0.1, 0.15, 0.2], \"phase_g\": 0.4}]}";

/* Renders `method` of scene s with ms settings (n = 0: ms=off). */
static bool render_ms(const lu_scene *s, const char *method, int n, double a, double b, double c, lu_image *img) {
    lu_kvlist set = {0};
    lu_error err = {0};
    lu_test_ms_settings(&set, method, n, a, b, c);
    lu_renderer *r = NULL;
    memset(img, 0, sizeof *img);
    lu_result rc = lu_renderer_create(method, s, &set, LU_BACKEND_CPU, &r, &err);
    if (rc == LU_OK) rc = lu_renderer_render(r, s, img, &err);
    CHECK_OK(rc, &err);
    lu_renderer_destroy(r);
    lu_kv_free(&set);
    return rc == LU_OK;
}

static bool load_scene(const char *name, lu_scene *s) {
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/%s.json", LU_SOURCE_DIR, name);
    lu_error err = {0};
    lu_result r = lu_scene_load(path, s, &err);
    CHECK_OK(r, &err);
    s->camera.width = W;
    s->camera.height = H;
    return r == LU_OK;
}

static void test_one_octave_is_single_scattering(void) {
    const char *scenes[] = {"smoke_box", "spot_shaft"};
    const char *methods[] = {"raymarch", "afm", "pervoxel"};
    for (int k = 0; k < 2; k++) {
        lu_scene s;
        if (!load_scene(scenes[k], &s)) continue;
        for (int m = 0; m < 3; m++) {
            lu_image off, one;
            /* a, b, c far from 1: with N = 1 none of them may matter. */
            if (render_ms(&s, methods[m], 0, 0, 0, 0, &off) && render_ms(&s, methods[m], 1, 0.2, 0.3, 0.1, &one)) {
                size_t n = (size_t)W * H * 3, diff = 0;
                double sum = 0.0;
                for (size_t i = 0; i < n; i++) {
                    diff += off.rgb[i] != one.rgb[i];
                    sum += off.rgb[i];
                }
                fprintf(stderr, "  %s %s: %zu of %zu values differ (image sum %.4g)\n", scenes[k], methods[m], diff, n, sum);
                CHECK_MSG(diff == 0 && sum > 0.0, "%s %s: N=1 differs from ms=off in %zu values", scenes[k], methods[m],
                          diff);
            }
            lu_image_destroy(&off);
            lu_image_destroy(&one);
        }
        lu_scene_destroy(&s);
    }
}

static void test_geometric_series(void) {
    lu_scene s;
    lu_error err = {0};
    lu_result r = lu_scene_load_string(k_box_scene, LU_SOURCE_DIR, &s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    const char *methods[] = {"raymarch", "afm", "pervoxel"};
    const struct {
        int n;
        double b;
    } cases[] = {{2, 0.5}, {5, 0.7}};
    for (int m = 0; m < 3; m++) {
        lu_image off;
        if (!render_ms(&s, methods[m], 0, 0, 0, 0, &off)) continue;
        for (int k = 0; k < 2; k++) {
            lu_image oct;
            if (!render_ms(&s, methods[m], cases[k].n, 1.0, cases[k].b, 1.0, &oct)) continue;
            double factor = (1.0 - pow(cases[k].b, cases[k].n)) / (1.0 - cases[k].b), worst = 0.0;
            int lit = 0;
            for (size_t i = 0; i < (size_t)W * H * 3; i++) {
                if (!(off.rgb[i] > 1e-6f)) continue;
                lit++;
                worst = fmax(worst, fabs(oct.rgb[i] / (factor * off.rgb[i]) - 1.0));
            }
            fprintf(stderr, "  %s N=%d b=%g: factor %.6f, worst pixel ratio error %.2e over %d values\n", methods[m],
                    cases[k].n, cases[k].b, factor, worst, lit);
            CHECK_MSG(lit > W * H && worst <= 1e-5, "%s N=%d: worst %.3g (%d values)", methods[m], cases[k].n, worst, lit);
            lu_image_destroy(&oct);
        }
        lu_image_destroy(&off);
    }
    lu_scene_destroy(&s);
}

static void test_bad_settings(void) {
    lu_scene s;
    if (!load_scene("spot_shaft", &s)) return;
    const struct {
        const char *key;
        double v;
        const char *str;
    } bad[] = {{"raymarch.ms_octaves", 0, NULL}, {"afm.ms_a", 1.5, NULL}, {"raymarch.ms_b", -0.1, NULL},
               {"gradient.ms_c", 2, NULL},      {"raymarch.ms", 0, "diffusion"}};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        lu_kvlist set = {0};
        lu_error err = {0};
        if (bad[k].str)
            lu_kv_set_string(&set, bad[k].key, bad[k].str, &err);
        else
            lu_kv_set_number(&set, bad[k].key, &bad[k].v, 1, &err);
        char method[32];
        snprintf(method, sizeof method, "%.*s", (int)(strchr(bad[k].key, '.') - bad[k].key), bad[k].key);
        lu_renderer *r = NULL;
        lu_result rc = lu_renderer_create(method, &s, &set, LU_BACKEND_CPU, &r, &err);
        const char *name = strchr(bad[k].key, '.') + 1;
        fprintf(stderr, "  %s: %s\n", bad[k].key, err.message);
        CHECK_MSG(rc != LU_OK && strstr(err.message, name) != NULL, "%s accepted or unnamed: %s", bad[k].key,
                  err.message);
        lu_renderer_destroy(r);
        lu_kv_free(&set);
    }
    lu_scene_destroy(&s);
}

int main(void) {
    RUN_TEST(test_slab_closed_form);
    RUN_TEST(test_one_octave_is_single_scattering);
    RUN_TEST(test_geometric_series);
    RUN_TEST(test_bad_settings);
    TEST_EXIT();
}
