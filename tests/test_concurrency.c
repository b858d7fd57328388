/* Two renderers used at once from two threads (docs/architecture.md §5,
 * "Threads"): each thread loads its own scene, creates its renderer, and
 * renders three frames with a moving camera; every image must equal, bit
 * for bit, the one the same job renders when the jobs run one at a time.
 * Pairs: two CPU methods (they share the worker pool), two GPU methods (they
 * share the one GPU device, whose use is serialised), and a CPU with a GPU
 * method. Run under ThreadSanitizer by `make tsan`. */
#define _POSIX_C_SOURCE 200809L /* strtok_r */
#include "lu_test.h"

#include <pthread.h>

#define FRAMES 3

typedef struct job {
    const char *method, *scene, *settings;
    lu_backend backend;
    lu_image img[FRAMES];
    lu_result result;
    char message[256];
} job;

/* No CHECK in here: the harness's counters are not atomic. */
static void *run(void *arg) {
    job *j = arg;
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", j->scene);
    lu_error err = {0};
    lu_scene s;
    lu_kvlist kv = {0};
    lu_renderer *r = NULL;
    j->result = lu_scene_load(path, &s, &err);
    if (j->result != LU_OK) goto done;
    s.camera.width = 40;
    s.camera.height = 30;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", j->settings);
    char *save = NULL;
    for (char *tok = strtok_r(buf, " ", &save); tok && j->result == LU_OK; tok = strtok_r(NULL, " ", &save))
        j->result = lu_kv_parse_assignment(&kv, tok, &err);
    if (j->result == LU_OK) j->result = lu_renderer_create(j->method, &s, &kv, j->backend, &r, &err);
    lu_vec3 c0 = s.camera.position;
    for (int f = 0; f < FRAMES && j->result == LU_OK; f++) {
        /* a small orbit about the up axis through look_at */
        float a = 0.05f * (float)f, ca = cosf(a), sa = sinf(a);
        lu_vec3 d = lu_v3_sub(c0, s.camera.look_at);
        s.camera.position = lu_v3_add(s.camera.look_at, lu_v3(ca * d.x + sa * d.z, d.y, -sa * d.x + ca * d.z));
        j->result = lu_renderer_render(r, &s, &j->img[f], &err);
    }
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
    lu_scene_destroy(&s);
done:
    snprintf(j->message, sizeof j->message, "%.200s", j->result == LU_OK ? "" : err.message);
    return NULL;
}

static void free_job(job *j) {
    for (int f = 0; f < FRAMES; f++) lu_image_destroy(&j->img[f]);
}

static bool same(const lu_image *a, const lu_image *b) {
    return a->width == b->width && a->height == b->height &&
           memcmp(a->rgb, b->rgb, (size_t)a->width * a->height * 3 * sizeof(float)) == 0;
}

static double sum(const lu_image *a) {
    double s = 0.0;
    for (size_t i = 0; i < (size_t)a->width * a->height * 3; i++) s += a->rgb[i];
    return s;
}

/* Returns false (and says so) when the pair needs a GPU this build lacks. */
static bool pair(job a, job b) {
    job one[2] = {a, b}, two[2] = {a, b};
    run(&one[0]);
    run(&one[1]);
    for (int k = 0; k < 2; k++) {
        if (one[k].result == LU_ERR_BACKEND && one[k].backend == LU_BACKEND_GPU) {
            fprintf(stderr, "  %s on the GPU: skipped (%s)\n", one[k].method, one[k].message);
            free_job(&one[0]);
            free_job(&one[1]);
            return false;
        }
        CHECK_MSG(one[k].result == LU_OK, "%s alone: %s", one[k].method, one[k].message);
    }
    pthread_t t[2];
    for (int k = 0; k < 2; k++) CHECK(pthread_create(&t[k], NULL, run, &two[k]) == 0);
    for (int k = 0; k < 2; k++) pthread_join(t[k], NULL);
    for (int k = 0; k < 2; k++) {
        CHECK_MSG(two[k].result == LU_OK, "%s at once: %s", two[k].method, two[k].message);
        if (one[k].result != LU_OK || two[k].result != LU_OK) continue;
        for (int f = 0; f < FRAMES; f++) {
            /* a black image would make the comparison void */
            CHECK_MSG(sum(&one[k].img[f]) > 0.0, "%s frame %d is black", one[k].method, f);
            CHECK_MSG(same(&one[k].img[f], &two[k].img[f]), "%s (%s) frame %d differs when rendered at once",
                      one[k].method, lu_backend_name(one[k].backend), f);
        }
        fprintf(stderr, "  %-9s %-4s %-12s %d frames alone = at once\n", one[k].method,
                lu_backend_name(one[k].backend), one[k].scene, FRAMES);
    }
    for (int k = 0; k < 2; k++) {
        free_job(&one[k]);
        free_job(&two[k]);
    }
    return true;
}

static void test_two_cpu_methods(void) {
    pair((job){.method = "reference", .scene = "spot_shaft", .settings = "", .backend = LU_BACKEND_CPU},
         (job){.method = "afm", .scene = "smoke_glow", .settings = "afm.steps=64 afm.map_res=64",
               .backend = LU_BACKEND_CPU});
}

static void test_two_gpu_methods(void) {
    pair((job){.method = "raymarch", .scene = "smoke_box", .settings = "raymarch.steps=64", .backend = LU_BACKEND_GPU},
         (job){.method = "gradient", .scene = "spot_shaft", .settings = "gradient.steps=64",
               .backend = LU_BACKEND_GPU});
}

static void test_cpu_and_gpu(void) {
    pair((job){.method = "afm", .scene = "bunny_fog", .settings = "afm.steps=64 afm.map_res=64",
               .backend = LU_BACKEND_GPU},
         (job){.method = "raymarch", .scene = "dusty_room", .settings = "raymarch.steps=64", .backend = LU_BACKEND_CPU});
}

int main(void) {
    RUN_TEST(test_two_cpu_methods);
    RUN_TEST(test_two_gpu_methods);
    RUN_TEST(test_cpu_and_gpu);
    TEST_EXIT();
}
