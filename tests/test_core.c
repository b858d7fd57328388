/* Core: settings parsing, affine maps, boxes, atomic files, parallel loop. */
#include <lucent/lucent.h>

#include <stdatomic.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <string.h>
#include <unistd.h>

#include "lu_test.h"

static void test_kv_parse(void) {
    lu_kvlist kv = {0};
    lu_error err = {0};
    CHECK_OK(lu_kv_parse_assignment(&kv, "afm.coeffs=16", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&kv, "pos=1,2.5,-3", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&kv, "bssrdf.profile=multipole", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&kv, "afm.coeffs=8", &err), &err); /* overrides */
    CHECK(kv.count == 3);
    const lu_kv *c = lu_kv_find(&kv, "afm.coeffs");
    CHECK(c && c->count == 1 && c->v[0] == 8.0);
    const lu_kv *p = lu_kv_find(&kv, "pos");
    CHECK(p && p->count == 3 && p->v[1] == 2.5 && p->v[2] == -3.0);
    const lu_kv *s = lu_kv_find(&kv, "bssrdf.profile");
    CHECK(s && s->count == 0 && strcmp(s->str, "multipole") == 0);
    CHECK(lu_kv_parse_assignment(&kv, "novalue", &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_kv_parse_assignment(&kv, "x=", &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_kv_parse_assignment(&kv, "x=nan", &err) == LU_ERR_NONFINITE);
    /* "1,2," is not a number list: kept as a string */
    CHECK_OK(lu_kv_parse_assignment(&kv, "y=1,2,", &err), &err);
    CHECK(lu_kv_find(&kv, "y")->count == 0);
    double v;
    CHECK(lu_kv_number(&kv, "afm.coeffs", 16, 1, 4, &v, "afm", &err) == LU_ERR_RANGE);
    CHECK(strstr(err.message, "afm.coeffs") != NULL);
    CHECK_OK(lu_kv_number(&kv, "missing", 3.5, 0, 10, &v, "afm", &err), &err);
    CHECK(v == 3.5);
    const char *known[] = {"afm.coeffs", "pos", NULL};
    CHECK(lu_kv_check_known(&kv, known, "$.x", &err) == LU_ERR_SCENE);
    CHECK(strstr(err.message, "bssrdf.profile") != NULL);
    lu_kv_free(&kv);
}

static void test_affine(void) {
    lu_affine t = lu_affine_translate(lu_v3(1, 2, 3));
    lu_affine r = lu_affine_rotate_xyz_deg(lu_v3(30, 45, 60));
    lu_affine s = lu_affine_scale(lu_v3(2, 3, 4));
    lu_affine rs = lu_affine_mul(&r, &s);
    lu_affine m = lu_affine_mul(&t, &rs);
    lu_affine inv;
    CHECK(lu_affine_invert(&m, &inv));
    lu_vec3 p = lu_v3(0.3f, -1.2f, 2.0f);
    lu_vec3 q = lu_affine_point(&inv, lu_affine_point(&m, p));
    CHECK_NEAR(q.x, p.x, 1e-5);
    CHECK_NEAR(q.y, p.y, 1e-5);
    CHECK_NEAR(q.z, p.z, 1e-5);
    /* Rotation about Z by 90 degrees takes X to Y. */
    lu_affine rz = lu_affine_rotate_xyz_deg(lu_v3(0, 0, 90));
    lu_vec3 y = lu_affine_vector(&rz, lu_v3(1, 0, 0));
    CHECK_NEAR(y.x, 0, 1e-6);
    CHECK_NEAR(y.y, 1, 1e-6);
    /* Normals stay perpendicular to transformed tangents under non-uniform scale. */
    lu_vec3 n = lu_v3_norm(lu_v3(1, 1, 0)), tan = lu_v3(1, -1, 0);
    lu_vec3 n2 = lu_affine_normal(&m, n), t2 = lu_affine_vector(&m, tan);
    CHECK_NEAR(lu_v3_dot(n2, t2), 0, 1e-4);
    lu_affine sing = lu_affine_scale(lu_v3(1, 0, 1));
    CHECK(!lu_affine_invert(&sing, &inv));
}

static void test_aabb_ray(void) {
    lu_aabb b = {{-1, -1, -1}, {1, 1, 1}};
    float t0, t1;
    CHECK(lu_aabb_ray(b, lu_v3(0, 0, -5), lu_v3(0, 0, 1), 0, 100, &t0, &t1));
    CHECK_NEAR(t0, 4, 1e-6);
    CHECK_NEAR(t1, 6, 1e-6);
    CHECK(!lu_aabb_ray(b, lu_v3(0, 2, -5), lu_v3(0, 0, 1), 0, 100, &t0, &t1));
    CHECK(lu_aabb_ray(b, lu_v3(0, 0, 0), lu_v3(1, 0, 0), 0, 0.5f, &t0, &t1));
    CHECK_NEAR(t1, 0.5, 1e-7);
}

static void test_atomic_file(void) {
    lu_error err = {0};
    const char *path = "test_core_atomic.txt";
    remove(path);
    lu_atomic_file f;
    CHECK_OK(lu_atomic_open(&f, path, &err), &err);
    fputs("partial", (FILE *)f.fp);
    CHECK(access(path, F_OK) != 0); /* nothing under the final name yet */
    lu_atomic_abort(&f);
    CHECK(access(path, F_OK) != 0);
    CHECK(access(f.temp_path, F_OK) != 0);
    CHECK_OK(lu_atomic_open(&f, path, &err), &err);
    fputs("hello", (FILE *)f.fp);
    CHECK_OK(lu_atomic_commit(&f, &err), &err);
    char *data;
    size_t size;
    CHECK_OK(lu_read_file(path, 100, &data, &size, &err), &err);
    CHECK(size == 5 && strcmp(data, "hello") == 0);
    lu_free(data);
    CHECK(lu_read_file(path, 3, &data, &size, &err) == LU_ERR_LIMIT);
    CHECK(lu_read_file("no/such/file", 100, &data, &size, &err) == LU_ERR_IO);
    CHECK(strstr(err.message, "no/such/file") != NULL);
    remove(path);
    CHECK(lu_atomic_open(&f, "no/such/dir/x.png", &err) == LU_ERR_IO);
}

static void test_paths(void) {
    char out[256];
    lu_path_resolve("scenes/a.json", "grid.nvdb", out, sizeof out);
    CHECK(strcmp(out, "scenes/grid.nvdb") == 0);
    lu_path_resolve("a.json", "grid.nvdb", out, sizeof out);
    CHECK(strcmp(out, "grid.nvdb") == 0);
    lu_path_resolve("scenes/a.json", "/abs/g.nvdb", out, sizeof out);
    CHECK(strcmp(out, "/abs/g.nvdb") == 0);
    CHECK(strcmp(lu_path_ext("x/y.PLY"), "ply") == 0);
    CHECK(strcmp(lu_path_ext("x.y/z"), "") == 0);
    CHECK(lu_path_has_suffix("dragon.ply.GZ", ".ply.gz"));
}

typedef struct sum_ctx {
    int64_t *out;
    atomic_int calls;
} sum_ctx;

static void square_range(void *ctx, int64_t b, int64_t e, int thread) {
    sum_ctx *c = ctx;
    for (int64_t i = b; i < e; i++) c->out[i] += i * i;
    atomic_fetch_add(&c->calls, 1);
}

static void test_parallel_for(void) {
    enum { N = 100003 };
    int64_t *out = calloc(N, sizeof *out);
    sum_ctx c = {.out = out};
    atomic_init(&c.calls, 0);
    lu_parallel_for(N, 97, square_range, &c, NULL);
    int bad = 0;
    for (int64_t i = 0; i < N; i++) bad += out[i] != i * i; /* each index exactly once */
    CHECK(bad == 0);
    CHECK(atomic_load(&c.calls) == (N + 96) / 97);
    free(out);
}

/* The cache folder: the conventional one's precedence (LUCENT_CACHE_DIR, an
 * absolute XDG_CACHE_HOME, HOME; none of them is an error), the host's
 * setting, and no disk cache without one. */
static void test_cache_dir(void) {
    char dir[1024], path[1100];
    lu_error err = {0};
    CHECK_OK(lu_cache_dir_conventional(NULL, NULL, "/h", dir, sizeof dir, &err), &err);
    CHECK_MSG(strcmp(dir, "/h/.cache/lucent") == 0, "%s", dir);
    CHECK_OK(lu_cache_dir_conventional("", "relative/ignored", "/h", dir, sizeof dir, &err), &err);
    CHECK_MSG(strcmp(dir, "/h/.cache/lucent") == 0, "%s", dir);
    CHECK_OK(lu_cache_dir_conventional(NULL, "/x", "/h", dir, sizeof dir, &err), &err);
    CHECK_MSG(strcmp(dir, "/x/lucent") == 0, "%s", dir);
    CHECK_OK(lu_cache_dir_conventional("/e", "/x", "/h", dir, sizeof dir, &err), &err);
    CHECK_MSG(strcmp(dir, "/e") == 0, "%s", dir);
    CHECK(lu_cache_dir_conventional(NULL, NULL, NULL, dir, sizeof dir, &err) == LU_ERR_IO);
    CHECK(strstr(err.message, "LUCENT_CACHE_DIR") != NULL);
    /* the library itself: no folder until the host names one */
    CHECK(!lu_cache_enabled());
    CHECK(lu_cache_path("f.bin", false, path, sizeof path, &err) == LU_ERR_UNSUPPORTED);
    CHECK_OK(lu_set_cache_dir("/s", &err), &err);
    CHECK(lu_cache_enabled());
    CHECK_OK(lu_cache_path("f.bin", false, path, sizeof path, &err), &err);
    CHECK_MSG(strcmp(path, "/s/f.bin") == 0, "%s", path);
    CHECK(lu_set_cache_dir("", &err) == LU_ERR_INVALID_ARG);
    CHECK_OK(lu_set_cache_dir(NULL, &err), &err);
    CHECK(lu_cache_dir(dir, sizeof dir, &err) == LU_ERR_UNSUPPORTED);
    /* create_dir makes the nested folder */
    char tmpl[] = "/tmp/lu_cache_XXXXXX";
    CHECK(mkdtemp(tmpl) != NULL);
    char nested[200];
    snprintf(nested, sizeof nested, "%s/a/b", tmpl);
    lu_host host = {.cache_dir = nested};
    CHECK_OK(lu_host_set(&host, &err), &err);
    nested[0] = '\0';   /* the library keeps its own copy */
    CHECK_OK(lu_cache_path("x", true, path, sizeof path, &err), &err);
    snprintf(nested, sizeof nested, "%s/a/b", tmpl);
    struct stat st;
    CHECK(stat(nested, &st) == 0 && S_ISDIR(st.st_mode));
    rmdir(nested);
    snprintf(nested, sizeof nested, "%s/a", tmpl);
    rmdir(nested);
    rmdir(tmpl);
    CHECK_OK(lu_host_set(NULL, &err), &err);
    CHECK(!lu_cache_enabled());
}

/* The host's hooks: every library allocation passes the allocator (counted
 * here against the frees), the log receives what the library reports, and
 * bad hosts are refused naming the field. */
typedef struct counting {
    long allocs, reallocs, frees;
    char last_log[256];
    int logs;
} counting;
static void *count_alloc(size_t n, void *u) { ((counting *)u)->allocs++; return malloc(n); }
static void *count_realloc(void *p, size_t n, void *u) { ((counting *)u)->reallocs++; return realloc(p, n); }
static void count_free(void *p, void *u) { ((counting *)u)->frees++; free(p); }
static void count_log(lu_log_level level, const char *msg, void *u) {
    counting *c = u;
    c->logs++;
    snprintf(c->last_log, sizeof c->last_log, "%d:%s", (int)level, msg);
}

static void test_host(void) {
    lu_error err = {0};
    CHECK(lu_version() == (uint32_t)LU_VERSION);
    CHECK(strcmp(lu_version_string(), LU_VERSION_STRING) == 0);
    char v[32];
    snprintf(v, sizeof v, "%d.%d.%d", LU_VERSION_MAJOR, LU_VERSION_MINOR, LU_VERSION_PATCH);
    CHECK_MSG(strcmp(v, LU_VERSION_STRING) == 0, "%s vs %s", v, LU_VERSION_STRING);

    lu_host half = {.alloc = count_alloc};
    CHECK(lu_host_set(&half, &err) == LU_ERR_INVALID_ARG && strstr(err.message, "together"));
    lu_host bad_threads = {.threads = LU_MAX_THREADS + 1};
    CHECK(lu_host_set(&bad_threads, &err) == LU_ERR_RANGE && strstr(err.message, "threads"));

    counting c = {0};
    lu_host host = {.alloc = count_alloc, .realloc = count_realloc, .free = count_free, .log = count_log,
                    .threads = 3, .user = &c};
    CHECK_OK(lu_host_set(&host, &err), &err);
    lu_host got;
    lu_host_get(&got);
    CHECK(got.threads == 3 && lu_thread_count() == 3 && got.alloc == count_alloc && got.user == &c);
    /* a settings list grows through realloc and frees through free */
    lu_kvlist kv = {0};
    for (int i = 0; i < 40; i++) {
        char text[64];
        snprintf(text, sizeof text, "m.k%d=%d", i, i);
        CHECK_OK(lu_kv_parse_assignment(&kv, text, &err), &err);
    }
    lu_kv_free(&kv);
    CHECK_MSG(c.allocs + c.reallocs >= 2 && c.frees >= 1, "allocs %ld reallocs %ld frees %ld", c.allocs, c.reallocs,
              c.frees);
    long before = c.allocs;
    lu_image im = {0};
    CHECK_OK(lu_image_create(&im, 4, 4, &err), &err);
    CHECK(c.allocs == before + 1);
    /* the allocator cannot change while its memory is alive */
    lu_host other = {.log = count_log, .user = &c};
    CHECK(lu_host_set(&other, &err) == LU_ERR_INVALID_ARG && strstr(err.message, "alive"));
    lu_image_destroy(&im);
    CHECK(c.allocs == c.frees);
    lu_log_msg(LU_LOG_WARNING, "careful: %d\n", 7);
    CHECK_MSG(strcmp(c.last_log, "1:careful: 7\n") == 0, "%s", c.last_log);
    int logs = c.logs;
    lu_log_msg(LU_LOG_DEBUG, "hidden\n");
    CHECK(c.logs == logs);   /* debug only with host.debug */
    CHECK_OK(lu_host_set(NULL, &err), &err);
    CHECK(lu_thread_count() >= 1);
    /* What lu_host_get answers, set again, changes nothing: the cache
     * folder it points to is the library's own copy. */
    lu_host with_cache = {.cache_dir = "/tmp/lucent-test-host-cache"};
    CHECK_OK(lu_host_set(&with_cache, &err), &err);
    lu_host again;
    lu_host_get(&again);
    CHECK_OK(lu_host_set(&again, &err), &err);
    lu_host_get(&again);
    CHECK_MSG(again.cache_dir && strcmp(again.cache_dir, "/tmp/lucent-test-host-cache") == 0, "cache_dir \"%s\"",
              again.cache_dir ? again.cache_dir : "(none)");
    CHECK_OK(lu_host_set(NULL, &err), &err);
}

int main(void) {
    RUN_TEST(test_cache_dir);
    RUN_TEST(test_host);
    RUN_TEST(test_kv_parse);
    RUN_TEST(test_affine);
    RUN_TEST(test_aabb_ray);
    RUN_TEST(test_atomic_file);
    RUN_TEST(test_paths);
    RUN_TEST(test_parallel_for);
    TEST_EXIT();
}
