/* Cross-backend agreement: every method that runs on the GPU renders every
 * bundled scene (scenes/ *.json, found at run time, so new scenes and new GPU
 * methods are covered without editing this file) on both backends, and the
 * GPU image equals the CPU image within rel-L2 1e-3 (docs/architecture.md §5; both
 * backends run the same kernel source, so the only differences are float
 * rounding and the order of operations in the shader compiler).
 *
 * The tolerance is the stated bound for llvmpipe; the measured
 * values (printed) are 1e-7..1e-5. Images are rendered small with cheap
 * settings so the test takes seconds. A scene the method cannot render on
 * the CPU (an LU_ERR_UNSUPPORTED answer) is reported and skipped; every other
 * error fails. No GPU context fails the test (CI has llvmpipe). */
#include "backends/gpu.h"
#include "lu_test.h"

#include <lucent/lucent.h>

#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#define W 40
#define H 30

/* Settings that keep each method's frame cheap; methods not listed run with
 * their defaults. */
static const struct {
    const char *key;
    double value;
} k_cheap[] = {
    {"raymarch.steps", 96},   {"raymarch.shadow_res", 256}, {"bssrdf.splats", 600},
    {"bssrdf.map_res", 256},  {"bssrdf.env_max", 2000}, {"afm.steps", 96},
    {"afm.map_res", 64},      {"afm.shadow_res", 256},
    {"gradient.steps", 96},   {"gradient.shadow_res", 256}, {"gradient.grid", 32}, {"gradient.gaussians", 64},
    {"rbf.steps", 96},        {"rbf.shadow_res", 256},      {"rbf.grid", 32},      {"rbf.gaussians", 64},
    {"pervoxel.steps", 96},   {"pervoxel.shadow_res", 256}, {"pervoxel.grid", 32},
    {"ddod.res", 16},         {"ddod.dirs", 16},          {"ddod.samples", 1000},
    {"ddod.bands", 3},        {"ddod.fit", 2},            {"ddod.cache", 0},
    {"froxel.nx", 20},        {"froxel.ny", 15},          {"froxel.nz", 32},   {"froxel.shadow_res", 256},
};

static int compare_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Sorted scene file names (caller frees). */
static int list_scenes(char ***out) {
    DIR *d = opendir(LU_SOURCE_DIR "/scenes");
    CHECK_MSG(d != NULL, "cannot open %s/scenes", LU_SOURCE_DIR);
    if (!d) return 0;
    char **names = NULL;
    int n = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".json") != 0) continue;
        names = realloc(names, (size_t)(n + 1) * sizeof *names);
        names[n++] = strdup(e->d_name);
    }
    closedir(d);
    qsort(names, (size_t)n, sizeof *names, compare_names);
    *out = names;
    return n;
}

static double sum_squares(const lu_image *im) {
    double s = 0.0;
    for (size_t i = 0; i < (size_t)im->width * im->height * 3; i++) s += (double)im->rgb[i] * im->rgb[i];
    return s;
}

/* Renders with the cheap settings; returns the lu_result. */
static lu_result render(const char *method, const lu_scene *s, lu_backend b, lu_image *img, lu_error *err) {
    lu_kvlist set = {0};
    size_t mlen = strlen(method);
    for (size_t i = 0; i < sizeof k_cheap / sizeof k_cheap[0]; i++)
        if (strncmp(k_cheap[i].key, method, mlen) == 0 && k_cheap[i].key[mlen] == '.')
            lu_kv_set_number(&set, k_cheap[i].key, &k_cheap[i].value, 1, err);
    lu_renderer *r = NULL;
    memset(img, 0, sizeof *img);
    lu_result rc = lu_renderer_create(method, s, &set, b, &r, err);
    if (rc == LU_OK) rc = lu_renderer_render(r, s, img, err);
    lu_renderer_destroy(r);
    lu_kv_free(&set);
    return rc;
}

static void test_every_scene_every_gpu_method(void) {
    char **scenes = NULL;
    int ns = list_scenes(&scenes);
    CHECK_MSG(ns >= 10, "found %d bundled scenes", ns);
    int nm;
    const lu_method *const *methods = lu_methods(&nm);
    int pairs = 0, black = 0;
    for (int k = 0; k < nm; k++) {
        if (!(methods[k]->backends & LU_BACKEND_GPU)) continue;
        const char *method = methods[k]->name;
        for (int i = 0; i < ns; i++) {
            char path[1024];
            snprintf(path, sizeof path, "%s/scenes/%s", LU_SOURCE_DIR, scenes[i]);
            lu_scene s;
            lu_error err = {0};
            lu_result lr = lu_scene_load(path, &s, &err);
            CHECK_OK(lr, &err);
            if (lr != LU_OK) continue;
            s.camera.width = W;
            s.camera.height = H;
            lu_image cpu, gpu;
            lu_result rc = render(method, &s, LU_BACKEND_CPU, &cpu, &err);
            if (rc == LU_ERR_UNSUPPORTED) {
                fprintf(stderr, "  %-9s %-26s skipped: %s\n", method, scenes[i], err.message);
            } else {
                CHECK_MSG(rc == LU_OK, "%s on %s (cpu): %s", method, scenes[i], err.message);
                lu_result rg = rc == LU_OK ? render(method, &s, LU_BACKEND_GPU, &gpu, &err) : rc;
                CHECK_MSG(rc != LU_OK || rg == LU_OK, "%s on %s (gpu): %s", method, scenes[i], err.message);
                if (rc == LU_OK && rg == LU_OK) {
                    double ref = sum_squares(&cpu);
                    lu_metrics m = {0};
                    if (ref > 0.0) {
                        CHECK_OK(lu_image_compare(&gpu, &cpu, &m, &err), &err);
                        CHECK_MSG(m.rel_l2 <= 1e-3, "%s on %s: GPU vs CPU rel-L2 %.3g > 1e-3", method, scenes[i],
                                  m.rel_l2);
                        pairs++;
                        fprintf(stderr, "  %-9s %-26s GPU vs CPU rel-L2 %.2e\n", method, scenes[i], m.rel_l2);
                    } else {
                        /* Nothing the method draws: the GPU must draw nothing either, but two
                         * black images are not counted as agreement. */
                        CHECK_MSG(sum_squares(&gpu) == 0.0, "%s on %s: CPU image black, GPU not", method,
                                  scenes[i]);
                        black++;
                        fprintf(stderr, "  %-9s %-26s not compared: the CPU image is black\n", method, scenes[i]);
                    }
                    lu_image_destroy(&gpu);
                }
                if (rc == LU_OK) lu_image_destroy(&cpu);
            }
            lu_scene_destroy(&s);
        }
    }
    fprintf(stderr, "  %d scene/method pairs compared, %d with a black CPU image not counted\n", pairs, black);
    CHECK_MSG(pairs >= ns, "only %d scene/method pairs compared", pairs);
    for (int i = 0; i < ns; i++) free(scenes[i]);
    free(scenes);
}

/* Renders `method` on both backends with two numeric settings and checks
 * the GPU image against the CPU's. */
static void check_backends_agree(const lu_scene *s, const char *method, const char *k1, double v1, const char *k2,
                                 double v2, const char *label) {
    lu_error err = {0};
    lu_kvlist set = {0};
    lu_kv_set_number(&set, k1, &v1, 1, &err);
    if (k2) lu_kv_set_number(&set, k2, &v2, 1, &err);
    lu_image img[2];
    for (int b = 0; b < 2; b++) {
        lu_renderer *r = NULL;
        memset(&img[b], 0, sizeof img[b]);
        CHECK_OK(lu_renderer_create(method, s, &set, b ? LU_BACKEND_GPU : LU_BACKEND_CPU, &r, &err), &err);
        if (r) CHECK_OK(lu_renderer_render(r, s, &img[b], &err), &err);
        lu_renderer_destroy(r);
    }
    if (img[0].rgb && img[1].rgb) {
        lu_metrics m = {0};
        CHECK_OK(lu_image_compare(&img[1], &img[0], &m, &err), &err);
        fprintf(stderr, "  %s: GPU vs CPU rel-L2 %.2e\n", label, m.rel_l2);
        CHECK_MSG(m.rel_l2 <= 1e-3, "%s: rel-L2 %.3g", label, m.rel_l2);
    }
    lu_image_destroy(&img[0]);
    lu_image_destroy(&img[1]);
    lu_kv_free(&set);
}

/* Work beyond one shader invocation's loop budget on llvmpipe (65535 loop
 * iterations, tests/test_gpu.c) must still equal the CPU, which it does only
 * because the drivers split the work (see also test_raymarch's 2048 steps). */
static void test_long_loops(void) {
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/marble_dragon.json", LU_SOURCE_DIR);
    lu_scene s;
    lu_error err = {0};
    lu_result lr = lu_scene_load(path, &s, &err);
    CHECK_OK(lr, &err);
    if (lr == LU_OK) {
        s.camera.width = 16;   /* one 16 x 16 tile holds every splat */
        s.camera.height = 12;
        check_backends_agree(&s, "bssrdf", "bssrdf.splats", 100000, NULL, 0, "bssrdf, 1e5 splats in one tile");
        lu_scene_destroy(&s);
    }
    /* raymarch with cheap steps (constant media, no DDA) but shadow-map taps
     * for four lights: many steps per dispatch, each with every loop the
     * kernel has. */
    static const char *k_json =
        "{\"camera\": {\"position\": [0, 0.5, 4], \"look_at\": [0, 0, 0], \"width\": 16, \"height\": 12},"
        " \"lights\": [{\"type\": \"point\", \"position\": [2, 2, 1], \"intensity\": [9, 9, 9]},"
        "  {\"type\": \"point\", \"position\": [-2, 2, 1], \"intensity\": [9, 5, 5]},"
        "  {\"type\": \"point\", \"position\": [0, 3, -2], \"intensity\": [5, 9, 5]},"
        "  {\"type\": \"spot\", \"position\": [0, 3, 0], \"direction\": [0, -1, 0], \"intensity\": [20, 20, 20],"
        "   \"inner_deg\": 20, \"outer_deg\": 30}],"
        " \"media\": [{\"density\": {\"constant\": 0.5}, \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [3, 3, 3]}},"
        "  \"sigma_s\": [0.5, 0.5, 0.5], \"sigma_a\": [0.1, 0.1, 0.1]},"
        "  {\"density\": {\"constant\": 0.2}, \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1.4}},"
        "   \"sigma_s\": [0.3, 0.3, 0.3], \"sigma_a\": [0.1, 0.1, 0.1]}],"
        " \"objects\": [{\"mesh\": {\"procedural\": \"sphere\", \"radius\": 0.4},"
        "  \"material\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}]}";
    lr = lu_scene_load_string(k_json, "loops.json", &s, &err);
    CHECK_OK(lr, &err);
    if (lr != LU_OK) return;
    check_backends_agree(&s, "raymarch", "raymarch.steps", 16384, "raymarch.shadow_res", 64,
                         "raymarch, 16384 steps, 4 lights, 2 media, shadow maps");
    lu_scene_destroy(&s);
}

int main(void) {
    if (!lu_gpu_compiled_in()) {
        SKIP_TEST(test_every_scene_every_gpu_method, "built without the GPU backend");
        SKIP_TEST(test_long_loops, "built without the GPU backend");
        TEST_EXIT_SKIPPED("built without the GPU backend");
    }
    RUN_TEST(test_every_scene_every_gpu_method);
    RUN_TEST(test_long_loops);
    TEST_EXIT();
}
