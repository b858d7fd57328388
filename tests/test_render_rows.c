/* lu_renderer_render_rows (the split a distributed job uses, docs/distributed.md):
 * every CPU method renders bands of rows, handed out in any order and of any
 * size, to the very bits lu_renderer_render gives those rows; a renderer that
 * rendered a whole frame before renders its bands from the kept products to
 * the same bits; the GPU backend refuses. */
#include "lu_test.h"

typedef struct bands {
    const int (*rows)[2];
    int count, next;
} bands;

static bool next_band(void *user, int *y0, int *y1) {
    bands *b = user;
    if (b->next == b->count) return false;
    *y0 = b->rows[b->next][0];
    *y1 = b->rows[b->next][1];
    b->next++;
    return true;
}

/* 37 rows: bands out of order, sizes 1 to 16, one crossing a 16-pixel tile
 * edge, one empty and one hanging past the image (clipped). Rows 3 and 4 are
 * in no band. */
static const int k_bands[][2] = {{30, 40}, {0, 3}, {21, 30}, {5, 21}, {12, 12}, {-4, 0}};

static bool rows_equal(const lu_image *a, const lu_image *b, int y0, int y1, int *bad_row) {
    for (int y = y0; y < y1; y++)
        if (memcmp(a->rgb + (size_t)y * a->width * 3, b->rgb + (size_t)y * b->width * 3,
                   (size_t)a->width * 3 * sizeof(float)) != 0) {
            *bad_row = y;
            return false;
        }
    return true;
}

static void check_bands(const char *what, const lu_image *whole, const lu_image *part) {
    int bad = -1;
    for (size_t i = 0; i < sizeof k_bands / sizeof k_bands[0]; i++) {
        int y0 = k_bands[i][0] < 0 ? 0 : k_bands[i][0], y1 = k_bands[i][1] > whole->height ? whole->height : k_bands[i][1];
        CHECK_MSG(rows_equal(whole, part, y0, y1, &bad), "%s: row %d differs from the whole image's", what, bad);
    }
}

static void run(const char *scene_file, const char *method, const char *settings) {
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/%s", LU_SOURCE_DIR, scene_file);
    lu_scene sc;
    lu_error err = {0};
    CHECK_OK(lu_scene_load(path, &sc, &err), &err);
    if (err.code != LU_OK) return;
    sc.camera.width = 41;
    sc.camera.height = 37;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, settings);
    lu_renderer *a = NULL, *b = NULL;
    lu_image whole = {0}, part = {0}, again = {0};
    CHECK_OK(lu_renderer_create(method, &sc, &kv, LU_BACKEND_CPU, &a, &err), &err);
    CHECK_OK(lu_renderer_create(method, &sc, &kv, LU_BACKEND_CPU, &b, &err), &err);
    if (a && b) {
        CHECK_OK(lu_renderer_render(a, &sc, &whole, &err), &err);
        bands q = {k_bands, (int)(sizeof k_bands / sizeof k_bands[0]), 0};
        CHECK_OK(lu_renderer_render_rows(b, &sc, next_band, &q, &part, &err), &err);
        CHECK(q.next == q.count);
        lu_renderer_stats st;
        lu_renderer_get_stats(b, &st, NULL);
        CHECK_MSG(st.rows_ms > 0.0 && st.rows_ms <= st.render_ms, "%s: rows_ms %g of render_ms %g", method,
                  st.rows_ms, st.render_ms);
        char what[128];
        snprintf(what, sizeof what, "%s on %s, fresh renderer", method, scene_file);
        if (whole.rgb && part.rgb) check_bands(what, &whole, &part);
        /* The renderer that rendered the whole frame, from its kept products. */
        bands q2 = {k_bands, (int)(sizeof k_bands / sizeof k_bands[0]), 0};
        CHECK_OK(lu_renderer_render_rows(a, &sc, next_band, &q2, &again, &err), &err);
        snprintf(what, sizeof what, "%s on %s, second frame", method, scene_file);
        if (whole.rgb && again.rgb) check_bands(what, &whole, &again);
    }
    lu_image_destroy(&whole);
    lu_image_destroy(&part);
    lu_image_destroy(&again);
    lu_renderer_destroy(a);
    lu_renderer_destroy(b);
    lu_kv_free(&kv);
    lu_scene_destroy(&sc);
}

static void test_every_cpu_method(void) {
    run("demo.json", "reference", "reference.spp=1");
    run("layered_cube.json", "pathtrace", "pathtrace.spp=3");
    run("demo.json", "raymarch", NULL);
    run("layered_cube.json", "afm", "afm.map_res=64");
    run("demo.json", "gradient", NULL);
    run("demo.json", "rbf", NULL);
    run("demo.json", "pervoxel", NULL);
    run("cube_torus.json", "ddod", "ddod.res=12 ddod.dirs=16 ddod.samples=300 ddod.fit=2");
    run("bssrdf_spheres.json", "bssrdf",
        "bssrdf.splats=256 bssrdf.map_res=48 bssrdf.table_size=64 bssrdf.prefilter=2");
}

static bool no_rows(void *user, int *y0, int *y1) {
    (void)user;
    (void)y0;
    (void)y1;
    return false;
}

static void test_gpu_refused(void) {
    if (lu_test_skip_gpu(LU_BACKEND_GPU)) return;
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/demo.json", LU_SOURCE_DIR);
    lu_scene sc;
    lu_error err = {0};
    CHECK_OK(lu_scene_load(path, &sc, &err), &err);
    lu_renderer *r = NULL;
    lu_image img = {0};
    if (lu_renderer_create("raymarch", &sc, NULL, LU_BACKEND_GPU, &r, &err) == LU_OK) {
        CHECK(lu_renderer_render_rows(r, &sc, no_rows, NULL, &img, &err) == LU_ERR_UNSUPPORTED);
        CHECK_MSG(strstr(err.message, "CPU backend") != NULL, "%s", err.message);
    } else {
        fprintf(stderr, "  skipped: no GPU renderer (%s)\n", err.message);
    }
    lu_renderer_destroy(r);
    lu_image_destroy(&img);
    lu_scene_destroy(&sc);
}

int main(void) {
    char cache[] = "/tmp/lucent-test-rows-XXXXXX";
    CHECK(mkdtemp(cache) != NULL);
    lu_set_cache_dir(cache, NULL);
    RUN_TEST(test_every_cpu_method);
    RUN_TEST(test_gpu_refused);
    lu_test_remove_dir(cache);
    TEST_EXIT();
}
