/* Minimal test harness: checks report file:line and the values involved,
 * count failures, and the test program exits non-zero if any failed. */
#ifndef LU_TEST_H
#define LU_TEST_H

#include <lucent/lucent.h>
#include <dirent.h>

#include "backends/gpu.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/quadrature.h"

static int lu_test_failures = 0;
static int lu_test_checks = 0;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        lu_test_checks++;                                                            \
        if (!(cond)) {                                                               \
            lu_test_failures++;                                                      \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                            \
    } while (0)

#define CHECK_MSG(cond, ...)                                                  \
    do {                                                                      \
        lu_test_checks++;                                                     \
        if (!(cond)) {                                                        \
            lu_test_failures++;                                               \
            fprintf(stderr, "%s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                     \
            fprintf(stderr, "\n");                                            \
        }                                                                     \
    } while (0)

/* |a - b| <= tol */
#define CHECK_NEAR(a, b, tol)                                                                      \
    do {                                                                                           \
        double lu_a_ = (double)(a), lu_b_ = (double)(b), lu_t_ = (double)(tol);                    \
        lu_test_checks++;                                                                          \
        if (!(fabs(lu_a_ - lu_b_) <= lu_t_)) {                                                     \
            lu_test_failures++;                                                                    \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, |diff| = %.3g > %.3g\n", \
                    __FILE__, __LINE__, #a, lu_a_, #b, lu_b_, fabs(lu_a_ - lu_b_), lu_t_);         \
        }                                                                                          \
    } while (0)

/* |a - b| <= rel * |b| */
#define CHECK_REL(a, b, rel)                                                                          \
    do {                                                                                              \
        double lu_a_ = (double)(a), lu_b_ = (double)(b), lu_r_ = (double)(rel);                       \
        lu_test_checks++;                                                                             \
        if (!(fabs(lu_a_ - lu_b_) <= lu_r_ * fabs(lu_b_))) {                                          \
            lu_test_failures++;                                                                       \
            fprintf(stderr, "%s:%d: CHECK_REL failed: %s = %.9g, %s = %.9g, rel diff = %.3g > %.3g\n", \
                    __FILE__, __LINE__, #a, lu_a_, #b, lu_b_, fabs(lu_a_ - lu_b_) / fabs(lu_b_), lu_r_); \
        }                                                                                             \
    } while (0)

/* A call returning lu_result must succeed; prints the error message if not. */
#define CHECK_OK(call, errp)                                                                        \
    do {                                                                                            \
        lu_test_checks++;                                                                           \
        lu_result lu_r_ = (call);                                                                   \
        if (lu_r_ != LU_OK) {                                                                       \
            lu_test_failures++;                                                                     \
            fprintf(stderr, "%s:%d: %s failed: %s: %s\n", __FILE__, __LINE__, #call,                \
                    lu_result_name(lu_r_), (errp)->message);                                        \
        }                                                                                           \
    } while (0)

/* Gauss-Legendre nodes x and weights w on [-1, 1] (core/quadrature.c). */
static inline void lu_test_gauss_legendre(int n, double *x, double *w) { lu_gauss_legendre(n, x, w); }

/* rel-L2 of a against b by the library's metric (the one `lucent compare` prints). */
static inline double lu_test_rel_l2(const lu_image *a, const lu_image *b) {
    lu_metrics m = {0};
    lu_error err = {0};
    CHECK_OK(lu_image_compare(a, b, &m, &err), &err);
    return m.rel_l2;
}

/* Adds space-separated "method.key=value" settings to kv, each one checked. */
static inline void lu_test_settings(lu_kvlist *kv, const char *settings) {
    char buf[1024];
    lu_error err = {0};
    snprintf(buf, sizeof buf, "%s", settings ? settings : "");
    for (char *tok = strtok(buf, " "); tok; tok = strtok(NULL, " ")) CHECK_OK(lu_kv_parse_assignment(kv, tok, &err), &err);
}

/* The view march's multiple-scattering settings of `method` into kv:
 * ms=octaves with N octaves and scales a, b, c (n = 0: nothing, ms=off). */
static inline void lu_test_ms_settings(lu_kvlist *kv, const char *method, int n, double a, double b, double c) {
    if (n <= 0) return;
    char buf[512];
    snprintf(buf, sizeof buf, "%s.ms=octaves %s.ms_octaves=%d %s.ms_a=%.17g %s.ms_b=%.17g %s.ms_c=%.17g", method, method,
             n, method, a, method, b, method, c);
    lu_test_settings(kv, buf);
}

/* Renders a scene given as JSON text with `method` on the CPU ("method.key=value"
 * settings, space-separated); false (and a counted failure) if anything fails. */
static inline bool lu_test_render_json(const char *json, const char *method, const char *settings, lu_image *img) {
    lu_scene s;
    lu_error err = {0};
    lu_kvlist kv = {0};
    CHECK_OK(lu_scene_load_string(json, "test.json", &s, &err), &err);
    if (err.code != LU_OK) return false;
    lu_test_settings(&kv, settings);
    lu_renderer *r = NULL;
    lu_result res = lu_renderer_create(method, &s, &kv, LU_BACKEND_CPU, &r, &err);
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

/* Removes dir and the files in it (a test's scratch folder, e.g. a cache). */
static inline void lu_test_remove_dir(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[1024];
    while ((e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            remove(path);
        }
    closedir(d);
    rmdir(dir);
}

#define RUN_TEST(fn)                                   \
    do {                                               \
        int lu_before_ = lu_test_failures;             \
        fn();                                          \
        fprintf(stderr, "%-48s %s\n", #fn,             \
                lu_test_failures == lu_before_ ? "ok" : "FAILED"); \
    } while (0)

/* A test that cannot run in this build (a GPU test in a build without the GPU
 * backend) exits with this code, which CTest reports as skipped, not passed
 * (SKIP_RETURN_CODE in CMakeLists.txt). */
#define LU_TEST_SKIP_CODE 77
#define SKIP_TEST(fn, why) fprintf(stderr, "%-48s skipped: %s\n", #fn, why)
/* Ends main: failures fail; otherwise the program counts as skipped. */
#define TEST_EXIT_SKIPPED(why)                                                                  \
    do {                                                                                        \
        fprintf(stderr, "%d checks, %d failed; skipped: %s\n", lu_test_checks, lu_test_failures, why); \
        return lu_test_failures ? EXIT_FAILURE : LU_TEST_SKIP_CODE;                              \
    } while (0)

/* True (with a line saying so) when b is the GPU and this build has no GPU
 * backend: a test's GPU comparison is skipped there, not counted as passed. */
static inline bool lu_test_skip_gpu(lu_backend b) {
    if (b != LU_BACKEND_GPU || lu_gpu_compiled_in()) return false;
    fprintf(stderr, "  GPU part skipped: built without the GPU backend\n");
    return true;
}

#define TEST_EXIT()                                                                        \
    do {                                                                                   \
        fprintf(stderr, "%d checks, %d failed\n", lu_test_checks, lu_test_failures);       \
        return lu_test_failures ? EXIT_FAILURE : (lu_test_checks ? EXIT_SUCCESS : EXIT_FAILURE); \
    } while (0)

#endif
