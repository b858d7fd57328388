/* Allocation failure (docs/reliability.md, "Faults"): the host allocator
 * (lu_host) fails the N-th allocation of one job, swept over N. A job is one
 * method's renderer made for a loaded scene, two frames rendered (the second
 * after a camera move, so the frame stage's update path runs too) and the
 * renderer destroyed. For every N the job must
 *   - succeed, or fail with LU_ERR_NOMEM and a message;
 *   - leave no allocation of its own alive once destroyed (counted by the
 *     allocator itself, so it holds in every build, not only under
 *     LeakSanitizer);
 *   - leave the library working: when the failure hit a render, the same
 *     renderer renders again, and its image equals the job's unfailed image
 *     bit for bit.
 * Without an argument the sweep is sampled (the first allocations, then an
 * even spread); `test_alloc_fail --full` fails every N, as `make soak` runs
 * it. `--gpu` sweeps the GPU methods' host side instead (raymarch and
 * bssrdf on the GPU; the test test_alloc_fail_gpu). One thread, so the
 * allocation order is the same on every run. */
#include "lu_test.h"

#include <time.h>

#include "lu_test_alloc.h"

static void quiet_log(lu_log_level level, const char *message, void *user) {
    (void)level, (void)message, (void)user;
}

typedef struct job {
    const char *method, *settings;
    lu_scene *scene;
    lu_backend backend;   /* 0: the CPU */
} job;

typedef struct outcome {
    lu_result result;        /* the first failure, or LU_OK */
    char message[256];
    bool retried;            /* a render failed and the renderer rendered again */
    lu_image img;            /* the second frame: from the job, or from the retry */
} outcome;

static void move_camera(lu_scene *s, float a) {
    lu_vec3 d = lu_v3_sub(s->camera.position, s->camera.look_at);
    float ca = cosf(a), sa = sinf(a);
    s->camera.position = lu_v3_add(s->camera.look_at, lu_v3(ca * d.x + sa * d.z, d.y, -sa * d.x + ca * d.z));
}

/* Runs the job with the N-th allocation failing (0: none). */
static void run(const job *j, long fail_at, outcome *o) {
    memset(o, 0, sizeof *o);
    lu_scene *s = j->scene;
    lu_vec3 c0 = s->camera.position;
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_renderer *r = NULL;
    lu_image first = {0};
    atomic_store(&g_count, 0);
    atomic_store(&g_fail_at, fail_at);

    lu_result res = LU_OK;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", j->settings);
    for (char *tok = strtok(buf, " "); tok && res == LU_OK; tok = strtok(NULL, " "))
        res = lu_kv_parse_assignment(&kv, tok, &err);
    if (res == LU_OK) res = lu_renderer_create(j->method, s, &kv, j->backend ? j->backend : LU_BACKEND_CPU, &r, &err);
    if (res == LU_OK) res = lu_renderer_render(r, s, &first, &err);
    if (res == LU_OK) {
        move_camera(s, 0.1f);
        res = lu_renderer_render(r, s, &o->img, &err);
    }
    o->result = res;
    snprintf(o->message, sizeof o->message, "%.200s", res == LU_OK ? "" : err.message);
    atomic_store(&g_fail_at, 0);
    if (res != LU_OK && r) {
        /* The renderer must still work: render the two frames again. */
        o->retried = true;
        lu_error e2 = {0};
        lu_image_destroy(&first);
        lu_image_destroy(&o->img);
        s->camera.position = c0;
        lu_result r2 = lu_renderer_render(r, s, &first, &e2);
        move_camera(s, 0.1f);
        if (r2 == LU_OK) r2 = lu_renderer_render(r, s, &o->img, &e2);
        if (r2 != LU_OK) {
            o->retried = false;
            lu_image_destroy(&o->img);
            snprintf(o->message + strlen(o->message), sizeof o->message - strlen(o->message),
                     " / retry: %.100s", e2.message);
        }
    }
    s->camera.position = c0;
    lu_image_destroy(&first);
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
}

/* The job's unfailed image, kept outside the counted allocator. */
typedef struct plain_image {
    int width, height;
    float *rgb;
} plain_image;

static bool same(const lu_image *a, const plain_image *b) {
    return a->width == b->width && a->height == b->height && a->rgb && b->rgb &&
           memcmp(a->rgb, b->rgb, (size_t)a->width * a->height * 3 * sizeof(float)) == 0;
}

/* Sweeps one job; returns the number of failure points tried. */
static long sweep(const job *j, bool full) {
    clock_t t0 = clock();
    outcome o;
    run(j, 0, &o); /* warm-up: process-wide tables built once (e.g. a bssrdf profile) stay alive */
    CHECK_MSG(o.result == LU_OK, "%s: %s", j->method, o.message);
    lu_image_destroy(&o.img);
    long live0 = atomic_load(&g_live);
    run(j, 0, &o);
    long total = atomic_load(&g_count);
    size_t n = (size_t)o.img.width * o.img.height * 3;
    plain_image base = {o.img.width, o.img.height, malloc(n * sizeof(float))};
    if (o.img.rgb && base.rgb) memcpy(base.rgb, o.img.rgb, n * sizeof(float));
    lu_result base_result = o.result;
    lu_image_destroy(&o.img);
    CHECK_MSG(atomic_load(&g_live) == live0, "%s: %ld blocks alive after an unfailed job, %ld before",
              j->method, atomic_load(&g_live), live0);
    if (atomic_load(&g_live) != live0) print_leaks(j->method, live0);
    if (base_result != LU_OK || !base.rgb) {
        free(base.rgb);
        return 0;
    }

    /* The sampled sweep: the first 16 allocations (where creation and the
     * first buffers are), then 16 points spread evenly over the rest. */
    long tried = 0, nomem = 0, retried = 0;
    for (long k = 1; k <= total; k++) {
        if (!full && k > 16 && (k - 16) % ((total - 16) / 16 + 1) != 0) continue;
        long failed0 = atomic_load(&g_failed);
        run(j, k, &o);
        bool hit = atomic_load(&g_failed) > failed0;
        tried++;
        if (o.result != LU_OK) nomem++;
        CHECK_MSG(o.result == LU_OK || o.result == LU_ERR_NOMEM, "%s, allocation %ld/%ld: result %d (%s)",
                  j->method, k, total, (int)o.result, o.message);
        CHECK_MSG(o.result == LU_OK || o.message[0], "%s, allocation %ld: failed without a message", j->method, k);
        /* A refused allocation the job then reported as success would be an
         * unchecked NULL that happened not to be used: only a fallback path
         * may do that, and its image must still be right. */
        CHECK_MSG(!hit || o.result != LU_OK || same(&o.img, &base),
                  "%s, allocation %ld: a refused allocation, success reported, and a different image", j->method, k);
        if (o.retried) {
            retried++;
            CHECK_MSG(same(&o.img, &base), "%s, allocation %ld: the renderer's image after the failure differs",
                      j->method, k);
        }
        lu_image_destroy(&o.img);
        CHECK_MSG(atomic_load(&g_live) == live0, "%s, allocation %ld/%ld: %ld blocks leaked", j->method, k, total,
                  atomic_load(&g_live) - live0);
        if (atomic_load(&g_live) != live0) {
            print_leaks(j->method, live0);
            live0 = atomic_load(&g_live); /* one report per leak */
        }
        if (lu_test_failures > 20) break;
    }
    fprintf(stderr,
            "  %-10s %6ld allocations, %4ld failure points: %4ld LU_ERR_NOMEM, %4ld re-rendered after a failed frame"
            " (%.1f s)\n",
            j->method, total, tried, nomem, retried, (double)(clock() - t0) / CLOCKS_PER_SEC);
    free(base.rgb);
    return tried;
}

/* The scene loader under the same sweep: each load either succeeds or
 * fails with LU_ERR_NOMEM and a message, and leaves nothing alive. cJSON,
 * libpng, zlib and OpenEXR allocate on their own, outside the sweep. */
static long sweep_load(const char *name, bool full) {
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", name);
    lu_error err = {0};
    lu_scene s;
    atomic_store(&g_fail_at, 0);
    CHECK_MSG(lu_scene_load(path, &s, &err) == LU_OK, "%s: %s", path, err.message); /* warm-up */
    lu_scene_destroy(&s);
    long live0 = atomic_load(&g_live);
    atomic_store(&g_count, 0);
    if (lu_scene_load(path, &s, &err) != LU_OK) return 0;
    lu_scene_destroy(&s);
    long total = atomic_load(&g_count), tried = 0, nomem = 0;
    for (long k = 1; k <= total; k++) {
        if (!full && k > 16 && (k - 16) % ((total - 16) / 16 + 1) != 0) continue;
        atomic_store(&g_count, 0);
        atomic_store(&g_fail_at, k);
        lu_error e = {0};
        lu_result r = lu_scene_load(path, &s, &e);
        atomic_store(&g_fail_at, 0);
        tried++;
        if (r == LU_OK) lu_scene_destroy(&s);
        else nomem++;
        CHECK_MSG(r == LU_OK || r == LU_ERR_NOMEM, "load %s, allocation %ld/%ld: result %d (%s)", name, k, total,
                  (int)r, e.message);
        CHECK_MSG(r == LU_OK || e.message[0], "load %s, allocation %ld: failed without a message", name, k);
        CHECK_MSG(atomic_load(&g_live) == live0, "load %s, allocation %ld/%ld: %ld blocks leaked", name, k, total,
                  atomic_load(&g_live) - live0);
        if (atomic_load(&g_live) != live0) {
            print_leaks(name, live0);
            live0 = atomic_load(&g_live);
        }
        if (lu_test_failures > 20) break;
    }
    fprintf(stderr, "  load %-14s %5ld allocations, %4ld failure points: %4ld LU_ERR_NOMEM\n", name, total, tried, nomem);
    return tried;
}

static lu_scene *load(const char *name, int w, int h) {
    static lu_scene scenes[4];
    static int n;
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", name);
    lu_error err = {0};
    lu_scene *s = &scenes[n];
    if (lu_scene_load(path, s, &err) != LU_OK) {
        fprintf(stderr, "%s: %s\n", path, err.message);
        exit(1);
    }
    n++;
    s->camera.width = w;
    s->camera.height = h;
    return s;
}

int main(int argc, char **argv) {
    bool full = false, gpu = false;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--full") == 0) full = true;
        else if (strcmp(argv[i], "--gpu") == 0) gpu = true;
        else {
            fprintf(stderr, "usage: test_alloc_fail [--full] [--gpu]\n");
            return 2;
        }
    }
    lu_host host = k_test_alloc_host;
    host.log = quiet_log;
    host.threads = 1;
    lu_error err = {0};
    CHECK(lu_host_set(&host, &err) == LU_OK);

    lu_scene *demo = load("demo", 24, 18);
    lu_scene *spheres = load("bssrdf_spheres", 24, 16);
    lu_scene *sparse = load("sparse_cloud", 24, 16);
    long points = 0;
    if (gpu) {
        /* The GPU methods' host side: context, programs, the shared scene
         * upload and each driver's buffers, and the CPU products they
         * upload. The driver's own memory is outside the sweep. */
        if (!lu_gpu_compiled_in()) TEST_EXIT_SKIPPED("built without the GPU backend");
        lu_renderer *probe = NULL;
        lu_result pr = lu_renderer_create("raymarch", demo, NULL, LU_BACKEND_GPU, &probe, &err);
        lu_renderer_destroy(probe);
        if (pr == LU_ERR_BACKEND) TEST_EXIT_SKIPPED("no GPU context");
        demo->camera.width = 12;
        demo->camera.height = 9;
        const job gpu_jobs[] = {
            {"raymarch", "raymarch.steps=32", demo, LU_BACKEND_GPU},
            {"bssrdf", "bssrdf.splats=64", spheres, LU_BACKEND_GPU},
            {"ddod", "ddod.res=16 ddod.dirs=16 ddod.samples=500", spheres, LU_BACKEND_GPU},
        };
        for (size_t i = 0; i < sizeof gpu_jobs / sizeof gpu_jobs[0]; i++) points += sweep(&gpu_jobs[i], full);
    } else {
        const job jobs[] = {
            {"reference", "", demo, 0},
            {"raymarch", "", demo, 0},
            {"raymarch", "", sparse, 0},   /* a NanoVDB tree sampled in place */
            {"afm", "afm.map_res=32", demo, 0},
            {"gradient", "", demo, 0},
            {"pervoxel", "", demo, 0},
            {"rbf", "", demo, 0},
            {"ddod", "ddod.res=16 ddod.dirs=16 ddod.samples=500", spheres, 0},
            {"pathtrace", "pathtrace.spp=1", demo, 0},
            {"pathtrace", "pathtrace.spp=1", spheres, 0},   /* refracting boundaries: the manifold next-event path */
            {"bssrdf", "bssrdf.splats=256", spheres, 0},
        };
        const char *loads[] = {"demo", "bssrdf_spheres", "sparse_cloud", "bunny_marble", "smoke_box"};
        for (size_t i = 0; i < sizeof loads / sizeof loads[0]; i++) points += sweep_load(loads[i], full);
        for (size_t i = 0; i < sizeof jobs / sizeof jobs[0]; i++) points += sweep(&jobs[i], full);
    }
    CHECK(points > 0);
    lu_scene_destroy(demo);
    lu_scene_destroy(spheres);
    lu_scene_destroy(sparse);
    TEST_EXIT();
}
