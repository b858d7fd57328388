/* afm (attenuation function maps): the map's DCT reconstruction against
 * closed forms (constant, exponential, Fresnel step), the map against the
 * exact optical depth on a procedural cloud, images against `reference`
 * (two bundled scenes and an opaque blocker casting a volumetric shadow),
 * and the GPU image against the CPU image. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "methods/afm/afm.h"
#include "methods/common/gpu_scene.h"
#include "methods/frame.h"

/* Exact optical depth (lu_march.h) for the procedural check. */
struct lu_k_ctx {
    const lu_scene *scene;
};
static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const lu_medium *med = &c->scene->media[m];
    return med->kind == LU_DENSITY_CONSTANT ? med->constant : lu_grid_sample(&med->grid, p);
}
#include "methods/common/lu_march.h"

typedef struct built {
    lu_scene scene;
    lu_media_rays mr;
    lu_afm_map map;
    lu_k_medium km[8];
    lu_k_light kl[8];
    int nl;
    bool ok;
} built;

static void build(built *b, const char *json, int res, int coefs, int samples) {
    lu_error err = {0};
    memset(b, 0, sizeof *b);
    b->ok = false;
    lu_result r = lu_scene_load_string(json, LU_SOURCE_DIR "/scenes", &b->scene, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    r = lu_media_rays_init(&b->mr, &b->scene, 16, false, &err);
    CHECK_OK(r, &err);
    for (int m = 0; m < b->scene.medium_count; m++) b->km[m] = lu_medium_to_kernel(&b->scene.media[m]);
    b->nl = lu_scene_kernel_lights(&b->scene, b->kl);
    lu_afm_map_init(&b->map, &b->scene, res, coefs, samples);
    lu_frame first = {.scene = &b->scene, .changed = LU_CHANGE_ALL, .lights_changed = ~0ull};
    if (r == LU_OK) r = lu_afm_map_views(&b->map, &first, &b->mr, b->nl, &err);
    CHECK_OK(r, &err);
    if (r == LU_OK) r = lu_afm_map_build_cpu(&b->map, &b->scene, b->km, NULL, &err);
    CHECK_OK(r, &err);
    b->ok = r == LU_OK;
}

static void unbuild(built *b) {
    lu_afm_map_free(&b->map);
    lu_media_rays_free(&b->mr);
    lu_scene_destroy(&b->scene);
}

/* Light straight down (+y is towards the light) onto media stacked along y. */
#define DOWN_LIGHT "\"lights\": [{\"type\": \"directional\", \"direction\": [0, 1, 0], \"irradiance\": [1, 1, 1]}]"
#define CAMERA "\"camera\": {\"position\": [0, 0, 6], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 8, \"height\": 8}"

/* Root-mean-square error of the map along the vertical line through (0.013, ., 0.021)
 * against f(y), over y in (y0, y1); also the smallest and largest values seen. */
static double line_error(const built *b, double y0, double y1, double (*f)(double), double *lo, double *hi) {
    double sum = 0;
    int n = 400;
    *lo = 1e30;
    *hi = -1e30;
    for (int i = 0; i < n; i++) {
        double y = y1 - (y1 - y0) * (i + 0.5) / n;
        lu_vec3 T = lu_afm_map_transmittance(&b->map, 0, lu_v3(0.013f, (float)y, 0.021f));
        double e = T.x - f(y);
        sum += e * e;
        *lo = fmin(*lo, T.x);
        *hi = fmax(*hi, T.x);
    }
    return sqrt(sum / n);
}

static const double k_sigma = 1.7;  /* sigma_t of the slab: sigma_s 1.2 + sigma_a 0.5, density 1 */
static double slab_exact(double y) { return exp(-k_sigma * (1.0 - y)); }
static double one(double y) {
    (void)y;
    return 1.0;
}
static double k_ft;  /* Fresnel transmittance at normal incidence, eta 1.5 */
static double step_exact(double y) { return y > 0 ? k_ft : k_ft * k_ft * k_ft; }

static void test_dct_closed_forms(void) {
    char json[2048];
    /* Homogeneous slab y in [-1, 1] behind an index-matched boundary (eta 1: no Fresnel). */
    snprintf(json, sizeof json,
             "{" CAMERA ", " DOWN_LIGHT ", \"media\": [{\"density\": {\"constant\": 1},"
             " \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 2, 2]}, \"eta\": 1.0},"
             " \"sigma_s\": [1.2, 1.2, 1.2], \"sigma_a\": [0.5, 0.5, 0.5]}]}");
    double prev = 1e30, lo, hi;
    int ns[] = {2, 4, 8, 16, 32};
    double err16 = 0, err4 = 0;
    /* On s in [0, 1] (length 2) f' is -2 sigma f: the cosine series of f has
     * c_k ~ 2 (f'(1) (-1)^k - f'(0)) / (pi k)^2, so the rms error of N terms
     * is about sqrt(sum_{k >= N} c_k^2 / 2) with |c_k| <= 2 (|f'(0)| + |f'(1)|) / (pi k)^2. */
    double slope = 2 * k_sigma * (1 + exp(-2 * k_sigma));
    for (int i = 0; i < 5; i++) {
        built b;
        build(&b, json, 8, ns[i], 512);
        if (!b.ok) return;
        CHECK(b.map.channels == 1);
        double e = line_error(&b, -0.999, 0.999, slab_exact, &lo, &hi);
        fprintf(stderr, "  slab exp(-%.1f t): N = %2d rms error %.2e\n", k_sigma, ns[i], e);
        CHECK(e < prev);  /* more coefficients, less error */
        double tail = 0;
        for (int k = ns[i]; k < 100000; k++) tail += pow(2 * slope / (LU_PI * LU_PI * k * k), 2);
        CHECK(e < 1.1 * sqrt(tail / 2));
        CHECK(lo >= exp(-2 * k_sigma) - 1e-6 && hi <= 1.0 + 1e-6);
        prev = e;
        if (ns[i] == 4) err4 = e;
        if (ns[i] == 16) err16 = e;
        /* Beyond K_out the tail is the exact transmittance through the slab;
         * before K_in, 1. */
        lu_vec3 below = lu_afm_map_transmittance(&b.map, 0, lu_v3(0.01f, -1.5f, 0.0f));
        lu_vec3 above = lu_afm_map_transmittance(&b.map, 0, lu_v3(0.01f, 1.5f, 0.0f));
        CHECK_NEAR(below.x, exp(-2 * k_sigma), 1e-4);
        CHECK_NEAR(above.x, 1.0, 0.0);
        unbuild(&b);
    }
    /* The even extension has a slope kink at the ends: coefficients fall as
     * 1/k^2, so 4x the coefficients cut the error by well over 4x. */
    CHECK(err16 < err4 / 4);

    /* Constant: a medium that does not extinguish (sigma 0) reconstructs 1 exactly. */
    snprintf(json, sizeof json,
             "{" CAMERA ", " DOWN_LIGHT ", \"media\": [{\"density\": {\"constant\": 1},"
             " \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 2, 2]}, \"eta\": 1.0},"
             " \"sigma_s\": [0, 0, 0], \"sigma_a\": [0, 0, 0]}]}");
    {
        built b;
        build(&b, json, 8, 16, 64);
        if (!b.ok) return;
        double e = line_error(&b, -0.999, 0.999, one, &lo, &hi);
        CHECK(e < 1e-6);
        unbuild(&b);
    }

    /* Step: two clear boxes y in [0, 1] and [-1, 0], eta 1.5: the light
     * crosses one boundary above y = 0 (F_t) and three below (F_t^3). */
    k_ft = 1.0 - pow(0.5 / 2.5, 2);
    snprintf(json, sizeof json,
             "{" CAMERA ", " DOWN_LIGHT ", \"media\": ["
             "{\"density\": {\"constant\": 1}, \"transform\": {\"translate\": [0, 0.5, 0]},"
             " \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 1, 2]}, \"eta\": 1.5},"
             " \"sigma_s\": [0, 0, 0], \"sigma_a\": [0, 0, 0]},"
             "{\"density\": {\"constant\": 1}, \"transform\": {\"translate\": [0, -0.5, 0]},"
             " \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 1, 2]}, \"eta\": 1.5},"
             " \"sigma_s\": [0, 0, 0], \"sigma_a\": [0, 0, 0]}]}");
    prev = 1e30;
    for (int i = 1; i < 5; i++) {
        built b;
        build(&b, json, 8, ns[i], 512);
        if (!b.ok) return;
        double e = line_error(&b, -0.999, 0.999, step_exact, &lo, &hi);
        fprintf(stderr, "  Fresnel step %.4f -> %.4f: N = %2d rms error %.2e, range [%.4f, %.4f]\n", k_ft,
                k_ft * k_ft * k_ft, ns[i], e, lo, hi);
        CHECK(e < prev);
        /* Gibbs ringing stays inside [tail, 1] after the clamp. */
        CHECK(lo >= pow(k_ft, 4) - 1e-6 && hi <= 1.0 + 1e-6);
        /* L2 error of a truncated step series falls like 1/sqrt(N): jump * sqrt(1/(pi^2 N)) bounds it. */
        double jump = k_ft - k_ft * k_ft * k_ft;
        CHECK(e < jump * sqrt(1.0 / (LU_PI * LU_PI * ns[i])) * 1.5);
        prev = e;
        unbuild(&b);
    }
}

/* The map against the exact transmittance on a rotated fbm cloud with
 * coloured extinction, for a point, a spot and a directional light. */
static void test_map_vs_exact(void) {
    const char *json =
        "{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": [2.5, 2, 1.5], \"intensity\": [5, 5, 5]},"
        "  {\"type\": \"spot\", \"position\": [0, 4, 0.5], \"direction\": [0, -1, 0], \"intensity\": [9, 9, 9],"
        "   \"inner_deg\": 20, \"outer_deg\": 35},"
        "  {\"type\": \"directional\", \"direction\": [0.3, 1, 0.2], \"irradiance\": [1, 1, 1]}],"
        " \"media\": [{\"density\": {\"procedural\": \"fbm_cloud\", \"size\": [3, 2, 2.5], \"resolution\": 24, \"seed\": 7,"
        "   \"radius\": 1.3, \"coverage\": 0.7, \"frequency\": 1.2},"
        "   \"transform\": {\"rotate_deg\": [20, 35, -10], \"translate\": [0.2, -0.1, 0.3]},"
        "   \"sigma_s\": [1, 2, 3], \"sigma_a\": [0.1, 0.2, 0.3]}]}";
    built b;
    build(&b, json, 128, 32, 256);
    if (!b.ok) return;
    CHECK(b.map.channels == 3);
    CHECK(b.nl == 3);
    struct lu_k_ctx c = {&b.scene};
    const lu_medium *med = &b.scene.media[0];
    lu_vec3 st = lu_v3_add(med->sigma_a, med->sigma_s);
    uint32_t seed = 12345;
    for (int l = 0; l < b.nl; l++) {
        double sum = 0, worst = 0, mean_t = 0;
        int n = 0;
        for (int i = 0; i < 400; i++) {
            float r3[3];
            for (int k = 0; k < 3; k++) {
                seed = seed * 1664525u + 1013904223u;
                r3[k] = (float)(seed >> 8) / 16777216.0f;
            }
            lu_vec3 x = lu_v3(med->bounds.lo.x + r3[0] * (med->bounds.hi.x - med->bounds.lo.x),
                              med->bounds.lo.y + r3[1] * (med->bounds.hi.y - med->bounds.lo.y),
                              med->bounds.lo.z + r3[2] * (med->bounds.hi.z - med->bounds.lo.z));
            lu_k_light_sample ls = lu_k_light_arrive(b.kl[l], x);
            if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue; /* outside the spot's cone */
            float a, bb;
            float od = 0;
            if (lu_aabb_ray(med->bounds, x, ls.wl, 0.0f, ls.dist, &a, &bb)) {
                lu_vec3 oi = lu_affine_point(&med->world_to_index, x), di = lu_affine_vector(&med->world_to_index, ls.wl);
                od = lu_k_optical_depth(&c, 0, oi, di, a, bb, 100000);
            }
            lu_vec3 exact = lu_v3_exp(lu_v3_scale(st, -od));
            lu_vec3 T = lu_afm_map_transmittance(&b.map, l, x);
            double e = fmax(fabs(T.x - exact.x), fmax(fabs(T.y - exact.y), fabs(T.z - exact.z)));
            sum += e;
            worst = fmax(worst, e);
            mean_t += exact.z;
            n++;
        }
        fprintf(stderr, "  light %d: %d points, mean |map - exact| %.2e, max %.2e (mean exact T_blue %.3f)\n", l, n,
                sum / n, worst, mean_t / n);
        CHECK(n > 50);
        CHECK(sum / n < 5e-3);
        CHECK(worst < 0.05);
    }
    unbuild(&b);
}

static bool render(const lu_scene *s, const char *method, lu_backend backend, lu_image *img, const char *extra) {
    if (lu_test_skip_gpu(backend)) return false;
    lu_kvlist set = {0};
    lu_error err = {0};
    if (extra) lu_kv_parse_assignment(&set, extra, &err);
    lu_renderer *r = NULL;
    lu_result rc = lu_renderer_create(method, s, &set, backend, &r, &err);
    lu_kv_free(&set);
    CHECK_OK(rc, &err);
    if (rc != LU_OK) return false;
    memset(img, 0, sizeof *img);
    rc = lu_renderer_render(r, s, img, &err);
    CHECK_OK(rc, &err);
    lu_renderer_destroy(r);
    return rc == LU_OK;
}

/* A bundled scene at size x size pixels. */
static bool load_bundled(const char *name, int size, lu_scene *s) {
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", name);
    lu_error err = {0};
    lu_result r = lu_scene_load(path, s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return false;
    s->camera.width = s->camera.height = size;
    return true;
}

static void test_against_reference(void) {
    const char *scenes[] = {"smoke_box", "homogeneous_sphere"};
    for (int i = 0; i < 2; i++) {
        lu_scene s;
        if (!load_bundled(scenes[i], 64, &s)) continue;
        lu_image ref, afm;
        if (render(&s, "reference", LU_BACKEND_CPU, &ref, NULL) && render(&s, "afm", LU_BACKEND_CPU, &afm, NULL)) {
            double e = lu_test_rel_l2(&afm, &ref);
            fprintf(stderr, "  %s 64x64: afm vs reference rel-L2 %.4f\n", scenes[i], e);
            CHECK(e <= 0.02);
            lu_image_destroy(&afm);
        }
        lu_image_destroy(&ref);
        lu_scene_destroy(&s);
    }
}

/* A slab of fog lit from above with an opaque plate over the front half of
 * its left part: camera rays there cross shadowed fog, then lit fog seen
 * through it, so the left of the image is darker by a ratio the reference
 * finds (between 0 and 1, not trivially 0). */
static void test_blocker_shadow(void) {
    const char *json =
        "{\"camera\": {\"position\": [0, 0, 7], \"look_at\": [0, 0, 0], \"fov_y_deg\": 30, \"width\": 40, \"height\": 24},"
        " \"lights\": [{\"type\": \"directional\", \"direction\": [0, 1, 0], \"irradiance\": [3, 3, 3]}],"
        " \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"size\": [3, 1.2, 1.2], \"resolution\": 24, \"value\": 1},"
        "   \"sigma_s\": [0.8, 0.8, 0.8], \"sigma_a\": [0.1, 0.1, 0.1]}],"
        " \"objects\": [{\"mesh\": {\"procedural\": \"box\", \"size\": [2, 0.05, 1.5]}, \"transform\": {\"translate\": [-1.2, 1.2, 0.75]},"
        "   \"material\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}]}";
    lu_scene s;
    lu_error err = {0};
    lu_result r = lu_scene_load_string(json, LU_SOURCE_DIR "/scenes", &s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    lu_image ref, afm;
    if (render(&s, "reference", LU_BACKEND_CPU, &ref, NULL) && render(&s, "afm", LU_BACKEND_CPU, &afm, NULL)) {
        /* Mean radiance of the rows through the slab's middle, left (shadowed) and right (lit) of the plate's edge. */
        double sum[2][2] = {{0, 0}, {0, 0}};
        for (int y = 9; y < 15; y++)
            for (int x = 0; x < 40; x++) {
                int side = x < 12 ? 0 : (x >= 28 ? 1 : -1);
                if (side < 0) continue;
                sum[0][side] += lu_image_px(&ref, x, y)[0];
                sum[1][side] += lu_image_px(&afm, x, y)[0];
            }
        double ratio_ref = sum[0][0] / sum[0][1], ratio_afm = sum[1][0] / sum[1][1];
        fprintf(stderr, "  blocker: shadowed/lit radiance, reference %.4f, afm %.4f; image rel-L2 %.4f\n", ratio_ref,
                ratio_afm, lu_test_rel_l2(&afm, &ref));
        CHECK(ratio_ref > 0.1 && ratio_ref < 0.7);
        CHECK_NEAR(ratio_afm, ratio_ref, 0.02 * ratio_ref + 0.002);
        CHECK(lu_test_rel_l2(&afm, &ref) <= 0.02);
        lu_image_destroy(&afm);
    }
    lu_image_destroy(&ref);
    lu_scene_destroy(&s);
}

/* The GPU passes (afm_build.comp, afm_render.comp) against the CPU twin on
 * scenes covering opaque objects + spot light (smoke_box), a bounded medium
 * with Fresnel and boundary reflection under two point lights
 * (homogeneous_sphere), and coloured extinction (layered_cube, 3 channels). */
static void test_gpu_matches_cpu(void) {
    const char *scenes[] = {"smoke_box", "homogeneous_sphere", "layered_cube"};
    for (int i = 0; i < 3; i++) {
        lu_scene s;
        if (!load_bundled(scenes[i], 40, &s)) continue;
        lu_image cpu, gpu;
        if (render(&s, "afm", LU_BACKEND_CPU, &cpu, "afm.map_res=64") &&
            render(&s, "afm", LU_BACKEND_GPU, &gpu, "afm.map_res=64")) {
            double e = lu_test_rel_l2(&gpu, &cpu);
            fprintf(stderr, "  %s 40x40: GPU vs CPU rel-L2 %.2e\n", scenes[i], e);
            CHECK(e <= 1e-3);
            lu_image_destroy(&gpu);
        }
        lu_image_destroy(&cpu);
        lu_scene_destroy(&s);
    }
}

/* The GPU map build (afm_build.comp) against the CPU build of the same views. */
static void test_gpu_map_matches_cpu(const char *json_path) {
    if (lu_test_skip_gpu(LU_BACKEND_GPU)) return;
    lu_scene s;
    lu_error err = {0};
    lu_result r = lu_scene_load(json_path, &s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    lu_media_rays mr;
    lu_afm_map map;
    lu_k_medium km[8];
    lu_k_light kl[8];
    CHECK_OK(lu_media_rays_init(&mr, &s, 16, false, &err), &err);
    for (int m = 0; m < s.medium_count; m++) km[m] = lu_medium_to_kernel(&s.media[m]);
    int nl = lu_scene_kernel_lights(&s, kl);
    lu_afm_map_init(&map, &s, 32, 16, 64);
    lu_frame first = {.scene = &s, .changed = LU_CHANGE_ALL, .lights_changed = ~0ull};
    CHECK_OK(lu_afm_map_views(&map, &first, &mr, nl, &err), &err);
    CHECK_OK(lu_afm_map_build_cpu(&map, &s, km, NULL, &err), &err);
    size_t n = lu_afm_map_texels(&map) * (size_t)lu_afm_map_stride(&map);
    float *gpu_rec = calloc(n, sizeof(float));
    lu_afm_gpu *g = NULL;
    r = lu_afm_gpu_create(&s, &g, &err);
    CHECK_OK(r, &err);
    if (r == LU_OK) r = lu_afm_gpu_build_download(g, &s, &map, gpu_rec, &err);
    CHECK_OK(r, &err);
    if (r == LU_OK) {
        double worst = 0;
        size_t at = 0;
        for (size_t i = 0; i < n; i++) {
            double a = map.records[i], b = gpu_rec[i];
            double e = fabs(a - b) / (fabs(a) > 1 ? fabs(a) : 1);
            if (e > worst) worst = e, at = i;
        }
        fprintf(stderr, "  %s: %zu texels, GPU vs CPU map records: worst relative difference %.2e (float %zu of texel %zu)\n",
                json_path, lu_afm_map_texels(&map), worst, at % lu_afm_map_stride(&map), at / lu_afm_map_stride(&map));
        CHECK(worst < 1e-4);
    }
    lu_afm_gpu_destroy(g);
    free(gpu_rec);
    lu_afm_map_free(&map);
    lu_media_rays_free(&mr);
    lu_scene_destroy(&s);
}

static void test_gpu_maps(void) {
    test_gpu_map_matches_cpu(LU_SOURCE_DIR "/scenes/layered_cube.json");
    test_gpu_map_matches_cpu(LU_SOURCE_DIR "/scenes/smoke_glow.json");
}

int main(void) {
    RUN_TEST(test_dct_closed_forms);
    RUN_TEST(test_map_vs_exact);
    RUN_TEST(test_against_reference);
    RUN_TEST(test_blocker_shadow);
    RUN_TEST(test_gpu_maps);
    RUN_TEST(test_gpu_matches_cpu);
    TEST_EXIT();
}
