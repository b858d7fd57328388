/* Memory figures (lu_memory_get, lu_renderer_stats.memory).
 *
 * The tests' host allocator (lu_test_alloc.h) keeps its own record of every
 * live block and its size, so the library's process figures are checked
 * against an independent count: the same blocks, and bytes that differ by
 * exactly the one max_align_t header per block the host contract states.
 * A renderer's figures are checked against the process's: what its make and
 * frames add to the process is its figure, and its destroy gives back
 * exactly that, for every method, with two renderers at once and with two
 * rendering on two threads. Lower bounds come from storage the methods
 * document (froxel's cell grids, the GPU frame buffer, a primitive id per
 * triangle in Embree's tree). */
#include <lucent/lucent.h>

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/memory.h"
#include "lu_test.h"
#include "lu_test_alloc.h"

static lu_memory process(void) {
    lu_memory m;
    lu_memory_get(&m);
    return m;
}

/* The library's figures against the host allocator's own record. */
static void check_against_host(const char *where) {
    lu_memory m = process();
    long host_blocks = atomic_load(&g_live);
    long long host_bytes = atomic_load(&g_bytes);
    CHECK_MSG(m.blocks == (size_t)host_blocks, "%s: %zu blocks, the host allocator holds %ld", where, m.blocks,
              host_blocks);
    CHECK_MSG((long long)(m.bytes + m.blocks * sizeof(max_align_t)) == host_bytes,
              "%s: %zu bytes + %zu headers, the host allocator holds %lld bytes", where, m.bytes, m.blocks,
              host_bytes);
    CHECK_MSG(m.peak_bytes >= m.bytes, "%s: peak %zu below %zu", where, m.peak_bytes, m.bytes);
}

static bool load(const char *file, int w, int h, lu_scene *sc) {
    char path[1024];
    lu_error err = {0};
    snprintf(path, sizeof path, "%s/scenes/%s", LU_SOURCE_DIR, file);
    CHECK_OK(lu_scene_load(path, sc, &err), &err);
    if (err.code != LU_OK) return false;
    sc->camera.width = w;
    sc->camera.height = h;
    return true;
}

/* ---- blocks and accounts ---------------------------------------------------- */

static void test_blocks(void) {
    check_against_host("start");
    lu_memory m0 = process();
    /* a block far larger than anything alive: the peak must have seen it */
    size_t big = (size_t)8 << 20;
    char *p = lu_malloc(big);
    CHECK(p != NULL);
    CHECK(process().bytes == m0.bytes + big);
    CHECK(process().peak_bytes >= m0.bytes + big);
    check_against_host("one large block");
    p = lu_realloc(p, 100);
    CHECK(process().bytes == m0.bytes + 100);
    check_against_host("after shrinking it");
    float *z = lu_calloc(1000, sizeof *z);
    double sum = 0;
    for (int i = 0; z && i < 1000; i++) sum += z[i];
    CHECK(z != NULL && sum == 0.0);
    CHECK(process().bytes == m0.bytes + 100 + 1000 * sizeof *z);
    char *s = lu_strdup("seven!");
    CHECK(process().bytes == m0.bytes + 100 + 1000 * sizeof *z + 7);
    check_against_host("calloc and strdup");
    lu_free(s);
    lu_free(z);
    lu_free(p);
    lu_memory m1 = process();
    CHECK(m1.bytes == m0.bytes && m1.blocks == m0.blocks);
    CHECK(m1.peak_bytes >= m0.bytes + big);
    check_against_host("all freed");
}

typedef struct chunk_job {
    void **blocks;
    atomic_int helpers;   /* chunks run by a worker, not the caller */
} chunk_job;

static void alloc_chunk(void *ctx, int64_t begin, int64_t end, int thread_index) {
    chunk_job *j = ctx;
    for (int64_t i = begin; i < end; i++) j->blocks[i] = lu_malloc(1000 + (size_t)i);
    if (thread_index > 0) atomic_fetch_add(&j->helpers, 1);
    /* long enough that the pool's helpers join the job */
    struct timespec ts = {0, 2000000};
    nanosleep(&ts, NULL);
}

static void test_accounts(void) {
    lu_memory before = process();
    lu_mem_account *a = lu_mem_account_create();
    CHECK(a != NULL);
    if (!a) return;
    lu_memory am;
    lu_mem_account_read(a, &am);
    size_t own = am.bytes;   /* the account's own bookkeeping */
    CHECK(own > 0 && am.blocks == 1);
    CHECK(process().bytes == before.bytes + own);

    /* blocks made on the pool's workers are charged to the caller's account */
    enum { N = 64 };
    void *blocks[N] = {0};
    chunk_job j = {.blocks = blocks};
    atomic_init(&j.helpers, 0);
    lu_error err = {0};
    CHECK_OK(lu_set_thread_count(4, &err), &err);
    lu_mem_account *outer = lu_mem_account_use(a);
    lu_parallel_for(N, 1, alloc_chunk, &j, NULL);
    lu_mem_account_use(outer);
    CHECK_OK(lu_set_thread_count(0, &err), &err);
    size_t want = 0;
    for (int i = 0; i < N; i++) want += 1000 + (size_t)i;
    lu_mem_account_read(a, &am);
    CHECK_MSG(am.bytes == own + want, "account: %zu bytes, the chunks allocated %zu", am.bytes - own, want);
    CHECK(am.blocks == 1 + N);
    CHECK_MSG(atomic_load(&j.helpers) > 0, "no chunk ran on a worker thread (the case under test)");

    /* a realloc elsewhere keeps the block on the account it was charged to */
    blocks[0] = lu_realloc(blocks[0], 5000);
    lu_mem_account_read(a, &am);
    CHECK(am.bytes == own + want - 1000 + 5000);

    /* the owner lets go first: the account lives on until its last block is freed */
    lu_mem_account_release(a);
    for (int i = 0; i < N; i++) lu_free(blocks[i]);
    lu_memory after = process();
    CHECK(after.bytes == before.bytes && after.blocks == before.blocks);
    check_against_host("accounts");
}

/* ---- renderers ------------------------------------------------------------- */

static bool same_totals(lu_memory a, lu_memory b) {
    return a.bytes == b.bytes && a.blocks == b.blocks && a.accel_bytes == b.accel_bytes && a.gpu_bytes == b.gpu_bytes;
}

/* The renderer's figure equals what it added to the process (m0: before make). */
static void check_figure(const char *what, const lu_renderer *r, lu_memory m0, lu_renderer_stats *st) {
    lu_error err = {0};
    CHECK_OK(lu_renderer_get_stats(r, st, &err), &err);
    lu_memory m = process();
    CHECK_MSG(st->memory.bytes == m.bytes - m0.bytes, "%s: %zu bytes, the process gained %zu", what,
              st->memory.bytes, m.bytes - m0.bytes);
    CHECK_MSG(st->memory.blocks == m.blocks - m0.blocks, "%s: %zu blocks, the process gained %zu", what,
              st->memory.blocks, m.blocks - m0.blocks);
    CHECK_MSG(st->memory.accel_bytes == m.accel_bytes - m0.accel_bytes, "%s: Embree %zu, the process gained %zu", what,
              st->memory.accel_bytes, m.accel_bytes - m0.accel_bytes);
    CHECK_MSG(st->memory.gpu_bytes == m.gpu_bytes - m0.gpu_bytes, "%s: GPU %zu, the process gained %zu", what,
              st->memory.gpu_bytes, m.gpu_bytes - m0.gpu_bytes);
    CHECK_MSG(st->memory.peak_bytes >= st->memory.bytes, "%s: peak %zu below %zu", what, st->memory.peak_bytes,
              st->memory.bytes);
    CHECK_MSG(st->memory.bytes > 0, "%s: holds nothing", what);
}

typedef struct case_ {
    const char *scene, *method, *settings;
} case_;

static const case_ k_cases[] = {
    {"demo.json", "reference", "reference.spp=1 reference.tolerance=0.05"},
    {"demo.json", "raymarch", "raymarch.steps=32"},
    {"demo.json", "afm", "afm.steps=32 afm.map_res=32"},
    {"demo.json", "gradient", "gradient.steps=32"},
    {"demo.json", "rbf", ""},
    {"demo.json", "pervoxel", "pervoxel.grid=16"},
    {"demo.json", "froxel", "froxel.nx=24 froxel.ny=14 froxel.nz=16 froxel.shadow_res=32"},
    {"demo.json", "pathtrace", "pathtrace.spp=1 pathtrace.max_depth=2"},
    {"bssrdf_spheres.json", "bssrdf", "bssrdf.splats=256 bssrdf.map_res=48 bssrdf.table_size=64 bssrdf.prefilter=2"},
    {"cube_torus.json", "ddod", "ddod.res=12 ddod.dirs=16 ddod.samples=300 ddod.fit=2"},
};

/* make, two frames (the second after a camera move, so products are
 * rebuilt and old ones freed), destroy: the figure tracks the process at
 * each step and destroy returns it to where it was. */
static void run_case(const case_ *c, lu_backend backend) {
    lu_scene sc;
    if (!load(c->scene, 48, 27, &sc)) return;
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_test_settings(&kv, c->settings);
    lu_image img = {0};
    CHECK_OK(lu_image_create(&img, 48, 27, &err), &err);
    char what[128];
    snprintf(what, sizeof what, "%s on %s (%s)", c->method, lu_backend_name(backend), c->scene);
    lu_memory m0 = process();
    lu_renderer *r = NULL;
    lu_renderer_stats st;
    CHECK_OK(lu_renderer_create(c->method, &sc, &kv, backend, &r, &err), &err);
    if (r) {
        check_figure(what, r, m0, &st);
        CHECK_OK(lu_renderer_render(r, &sc, &img, &err), &err);
        check_figure(what, r, m0, &st);
        sc.camera.position = lu_v3_add(sc.camera.position, lu_v3(0.05f, 0.0f, 0.0f));
        CHECK_OK(lu_renderer_render(r, &sc, &img, &err), &err);
        check_figure(what, r, m0, &st);
        if (strcmp(c->method, "froxel") == 0) {
            /* two lighting grids (reprojection keeps the last) and the integral,
             * where the cells are lit: in CPU memory or on the GPU, not both */
            size_t cells = (size_t)24 * 14 * 16;
            size_t least = 3 * cells * 8 * sizeof(float);
            bool gpu = backend == LU_BACKEND_GPU;
            size_t there = gpu ? st.memory.gpu_bytes : st.memory.bytes;
            CHECK_MSG(there >= least, "froxel holds %zu bytes on the %s, its grids alone are %zu", there,
                      lu_backend_name(backend), least);
            if (gpu)
                CHECK_MSG(st.memory.bytes < least, "froxel on the GPU holds %zu bytes in CPU memory (grids: %zu)",
                          st.memory.bytes, least);
        }
        if (backend == LU_BACKEND_GPU) {
            size_t frame = (size_t)48 * 27 * 3 * sizeof(float);
            CHECK_MSG(st.memory.gpu_bytes >= frame, "%s: %zu GPU bytes, its frame buffer alone is %zu", what,
                      st.memory.gpu_bytes, frame);
        }
        lu_renderer_destroy(r);
    }
    lu_memory m1 = process();
    CHECK_MSG(same_totals(m1, m0), "%s: destroy left %lld bytes, %lld blocks, %lld Embree, %lld GPU", what,
              (long long)(m1.bytes - m0.bytes), (long long)(m1.blocks - m0.blocks),
              (long long)(m1.accel_bytes - m0.accel_bytes), (long long)(m1.gpu_bytes - m0.gpu_bytes));
    lu_image_destroy(&img);
    lu_kv_free(&kv);
    lu_scene_destroy(&sc);
    check_against_host(what);
}

static void test_renderers_cpu(void) {
    for (size_t i = 0; i < sizeof k_cases / sizeof k_cases[0]; i++) run_case(&k_cases[i], LU_BACKEND_CPU);
}

/* Embree's share: the bssrdf spheres are meshes in a tree that holds at
 * least a primitive id (4 bytes) per triangle. */
static void test_accel(void) {
    lu_scene sc;
    if (!load("bssrdf_spheres.json", 48, 27, &sc)) return;
    size_t triangles = 0;
    for (int i = 0; i < sc.object_count; i++) triangles += sc.objects[i].mesh.triangle_count;
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_test_settings(&kv, k_cases[8].settings);
    lu_renderer *r = NULL;
    lu_renderer_stats st = {0};
    CHECK_OK(lu_renderer_create("bssrdf", &sc, &kv, LU_BACKEND_CPU, &r, &err), &err);
    if (r) CHECK_OK(lu_renderer_get_stats(r, &st, &err), &err);
    CHECK(triangles > 0);
    CHECK_MSG(st.memory.accel_bytes >= 4 * triangles, "Embree holds %zu bytes for %zu triangles",
              st.memory.accel_bytes, triangles);
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
    lu_scene_destroy(&sc);
}

/* Two renderers alive at once: each figure is its own, their sum is what
 * both added, and destroying one gives back exactly its figure. */
static void test_two_renderers(void) {
    lu_scene sc;
    if (!load("demo.json", 48, 27, &sc)) return;
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "raymarch.steps=32 afm.steps=32 afm.map_res=32");
    lu_image img = {0};
    CHECK_OK(lu_image_create(&img, 48, 27, &err), &err);
    lu_memory m0 = process();
    lu_renderer *a = NULL, *b = NULL;
    CHECK_OK(lu_renderer_create("raymarch", &sc, &kv, LU_BACKEND_CPU, &a, &err), &err);
    CHECK_OK(lu_renderer_create("afm", &sc, &kv, LU_BACKEND_CPU, &b, &err), &err);
    if (a && b) {
        CHECK_OK(lu_renderer_render(a, &sc, &img, &err), &err);
        CHECK_OK(lu_renderer_render(b, &sc, &img, &err), &err);
        lu_renderer_stats sa, sb;
        CHECK_OK(lu_renderer_get_stats(a, &sa, &err), &err);
        CHECK_OK(lu_renderer_get_stats(b, &sb, &err), &err);
        lu_memory m = process();
        CHECK(sa.memory.bytes + sb.memory.bytes == m.bytes - m0.bytes);
        CHECK(sa.memory.blocks + sb.memory.blocks == m.blocks - m0.blocks);
        CHECK(sa.memory.accel_bytes + sb.memory.accel_bytes == m.accel_bytes - m0.accel_bytes);
        lu_renderer_destroy(a);
        a = NULL;
        CHECK(process().bytes == m.bytes - sa.memory.bytes);
        CHECK(process().blocks == m.blocks - sa.memory.blocks);
    }
    lu_renderer_destroy(a);
    lu_renderer_destroy(b);
    CHECK(same_totals(process(), m0));
    lu_image_destroy(&img);
    lu_kv_free(&kv);
    lu_scene_destroy(&sc);
}

typedef struct thread_job {
    const lu_scene *scene;
    const char *method;
    const lu_kvlist *kv;
    lu_renderer *r;
    lu_image img;
    lu_result result;
} thread_job;

static void *render_thread(void *arg) {
    thread_job *t = arg;
    lu_error err = {0};
    t->result = lu_renderer_create(t->method, t->scene, t->kv, LU_BACKEND_CPU, &t->r, &err);
    for (int f = 0; f < 2 && t->result == LU_OK; f++) t->result = lu_renderer_render(t->r, t->scene, &t->img, &err);
    return NULL;
}

/* Two application threads, each making and rendering its own renderer
 * while the other does (both using the one worker pool). */
static void test_threads(void) {
    lu_scene sc;
    if (!load("demo.json", 48, 27, &sc)) return;
    lu_error err = {0};
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "raymarch.steps=32 reference.spp=1 reference.tolerance=0.05");
    thread_job t[2] = {{.scene = &sc, .method = "raymarch", .kv = &kv}, {.scene = &sc, .method = "reference", .kv = &kv}};
    for (int i = 0; i < 2; i++) CHECK_OK(lu_image_create(&t[i].img, 48, 27, &err), &err);
    lu_memory m0 = process();
    pthread_t tid[2];
    for (int i = 0; i < 2; i++) CHECK(pthread_create(&tid[i], NULL, render_thread, &t[i]) == 0);
    for (int i = 0; i < 2; i++) pthread_join(tid[i], NULL);
    CHECK(t[0].result == LU_OK && t[1].result == LU_OK);
    if (t[0].r && t[1].r) {
        lu_renderer_stats s0, s1;
        CHECK_OK(lu_renderer_get_stats(t[0].r, &s0, &err), &err);
        CHECK_OK(lu_renderer_get_stats(t[1].r, &s1, &err), &err);
        lu_memory m = process();
        CHECK_MSG(s0.memory.bytes + s1.memory.bytes == m.bytes - m0.bytes, "%zu + %zu bytes, the process gained %zu",
                  s0.memory.bytes, s1.memory.bytes, m.bytes - m0.bytes);
        CHECK(s0.memory.blocks + s1.memory.blocks == m.blocks - m0.blocks);
    }
    for (int i = 0; i < 2; i++) lu_renderer_destroy(t[i].r);
    lu_memory m1 = process();
    CHECK_MSG(same_totals(m1, m0), "destroy left %lld bytes, %lld blocks, %lld Embree",
              (long long)(m1.bytes - m0.bytes), (long long)(m1.blocks - m0.blocks),
              (long long)(m1.accel_bytes - m0.accel_bytes));
    for (int i = 0; i < 2; i++) lu_image_destroy(&t[i].img);
    lu_kv_free(&kv);
    lu_scene_destroy(&sc);
}

static void test_renderers_gpu(void) {
    if (lu_test_skip_gpu(LU_BACKEND_GPU)) return;
    /* The device every GPU renderer shares is the process's: held here
     * across the cases so that it is not made inside one of them. */
    lu_gpu_context *ctx = NULL;
    lu_error err = {0};
    if (lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err) != LU_OK) {
        fprintf(stderr, "  GPU part skipped: no GPU context (%s)\n", err.message);
        return;
    }
    static const int gpu_cases[] = {1, 2, 3, 6, 8};   /* raymarch, afm, gradient, froxel, bssrdf */
    for (size_t i = 0; i < sizeof gpu_cases / sizeof gpu_cases[0]; i++) run_case(&k_cases[gpu_cases[i]], LU_BACKEND_GPU);
    lu_gpu_info info;
    lu_gpu_info_get(ctx, &info);
    fprintf(stderr, "  %zu methods on the GPU (%s)\n", sizeof gpu_cases / sizeof gpu_cases[0], info.renderer);
    lu_gpu_context_destroy(ctx);
}

int main(void) {
    lu_error err = {0};
    /* before any other call: every block the library makes is seen by the
     * tests' allocator */
    CHECK_OK(lu_host_set(&k_test_alloc_host, &err), &err);
    RUN_TEST(test_blocks);
    RUN_TEST(test_accounts);
    RUN_TEST(test_renderers_cpu);
    RUN_TEST(test_accel);
    RUN_TEST(test_two_renderers);
    RUN_TEST(test_threads);
    RUN_TEST(test_renderers_gpu);
    check_against_host("end");
    TEST_EXIT();
}
