/* OpenVDB (.vdb) input: the files come from libopenvdb itself (tests/
 * vdb_gen.cpp, run here into a scratch folder), the expected values from the
 * formula the generator used, the expected world positions from OpenVDB's
 * own Transform::indexToWorld, and the .nvdb twin from Debian's
 * nanovdb_convert. The child-process containment is tested with stand-in
 * converters that crash, lie or flood, and with mutated files. */
#include <lucent/lucent.h>

#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "lu_test.h"

static char g_dir[256];

static void path_in(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", g_dir, name); }

static float density_value(int i, int j, int k) {
    int m = ((7 * i + 3 * j + 5 * k) % 11 + 11) % 11;
    return (float)(m + 1) / 8.0f;
}

/* The generator's density box. */
static const int k_lo[3] = {-5, 3, -9}, k_hi[3] = {10, 14, 2};

static bool read_all(const char *path, unsigned char **data, size_t *size) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return false;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    *data = malloc(n > 0 ? (size_t)n : 1);
    bool ok = *data && n >= 0 && fread(*data, 1, (size_t)n, fp) == (size_t)n;
    fclose(fp);
    *size = (size_t)n;
    return ok;
}

static bool write_all(const char *path, const void *data, size_t size) {
    FILE *fp = fopen(path, "wb");
    if (!fp) return false;
    bool ok = fwrite(data, 1, size, fp) == size;
    return fclose(fp) == 0 && ok;
}

/* Voxel by voxel, whatever the storage (a .nvdb or .vdb load is sparse). */
static bool same_grid(const lu_grid *a, const lu_grid *b) {
    if (a->nx != b->nx || a->ny != b->ny || a->nz != b->nz) return false;
    for (int z = 0; z < a->nz; z++)
        for (int y = 0; y < a->ny; y++)
            for (int x = 0; x < a->nx; x++)
                if (lu_grid_at(a, x, y, z) != lu_grid_at(b, x, y, z)) return false;
    return memcmp(&a->index_to_world, &b->index_to_world, sizeof a->index_to_world) == 0;
}

static lu_vec3 map_point(const lu_affine *m, double x, double y, double z) {
    return lu_v3((float)(m->m[0][0] * x + m->m[0][1] * y + m->m[0][2] * z + m->m[0][3]),
                 (float)(m->m[1][0] * x + m->m[1][1] * y + m->m[1][2] * z + m->m[1][3]),
                 (float)(m->m[2][0] * x + m->m[2][1] * y + m->m[2][2] * z + m->m[2][3]));
}

/* Expects failure `code` with the file's path and `needle` in the message. */
static void expect_fail(const char *path, const char *grid, lu_result code, const char *needle) {
    lu_grid g;
    lu_error err = {0};
    lu_result r = lu_grid_load_vdb(path, grid, &g, &err);
    CHECK_MSG(r == code, "%s grid %s: got %s (%s), expected %s", path, grid ? grid : "(first)", lu_result_name(r),
              err.message, lu_result_name(code));
    CHECK_MSG(strstr(err.message, path) != NULL, "message lacks the path: %s", err.message);
    CHECK_MSG(!needle || strstr(err.message, needle), "message lacks \"%s\": %s", needle, err.message);
    if (r == LU_OK) lu_grid_destroy(&g);
}

/* Every voxel of the density box is the generator's value, and the map
 * takes the box's corners where OpenVDB's transform puts them. */
static void test_vdb_values_and_map(void) {
    char path[300], map_txt[300];
    path_in(path, sizeof path, "fog.vdb");
    path_in(map_txt, sizeof map_txt, "fog_map.txt");
    lu_grid g;
    lu_error err = {0};
    lu_result r = lu_grid_load_vdb(path, "density", &g, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    CHECK(g.nx == k_hi[0] - k_lo[0] + 1 && g.ny == k_hi[1] - k_lo[1] + 1 && g.nz == k_hi[2] - k_lo[2] + 1);
    int wrong = 0;
    for (int k = k_lo[2]; k <= k_hi[2]; k++)
        for (int j = k_lo[1]; j <= k_hi[1]; j++)
            for (int i = k_lo[0]; i <= k_hi[0]; i++)
                wrong += lu_grid_at(&g, i - k_lo[0], j - k_lo[1], k - k_lo[2]) != density_value(i, j, k);
    CHECK_MSG(wrong == 0, "%d voxels differ from the generator's values", wrong);
    CHECK(strcmp(g.name, "density") == 0);
    FILE *fp = fopen(map_txt, "r");
    CHECK(fp != NULL);
    int corners = 0;
    int i, j, k;
    double x, y, z;
    while (fp && fscanf(fp, "%d %d %d %lf %lf %lf", &i, &j, &k, &x, &y, &z) == 6) {
        lu_vec3 w = map_point(&g.index_to_world, i - k_lo[0], j - k_lo[1], k - k_lo[2]);
        CHECK_NEAR(w.x, x, 2e-6);
        CHECK_NEAR(w.y, y, 2e-6);
        CHECK_NEAR(w.z, z, 2e-6);
        corners++;
    }
    if (fp) fclose(fp);
    CHECK(corners == 8);
    lu_grid_destroy(&g);
}

/* No name: the first float grid in file order ("temperature", after a vec3s
 * grid and before "density"); ZIP, no compression and half floats read to
 * the same grid (k/8 for k <= 11 is exact in 16 bits). */
static void test_vdb_select_and_codecs(void) {
    char path[300];
    path_in(path, sizeof path, "fog.vdb");
    lu_grid g, h;
    lu_error err = {0};
    const char *names[] = {NULL, "", "temperature"};
    for (int n = 0; n < 3; n++) {
        lu_result r = lu_grid_load_vdb(path, names[n], &g, &err);
        CHECK_OK(r, &err);
        if (r != LU_OK) return;
        CHECK(strcmp(g.name, "temperature") == 0);
        CHECK(g.nx == 4 && g.ny == 1 && g.nz == 1);
        for (int i = 0; i < 4 && g.nx == 4; i++) CHECK(lu_grid_at(&g, i, 0, 0) == 300.0f + 100.0f * (float)i);
        lu_grid_destroy(&g);
    }
    lu_result r = lu_grid_load_vdb(path, "density", &g, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    const char *others[] = {"fog_zip.vdb", "fog_none.vdb", "fog_half.vdb"};
    for (int n = 0; n < 3; n++) {
        char other[300];
        path_in(other, sizeof other, others[n]);
        r = lu_grid_load_vdb(other, NULL, &h, &err);
        CHECK_OK(r, &err);
        if (r != LU_OK) continue;
        CHECK_MSG(same_grid(&g, &h), "%s differs from fog.vdb's density", others[n]);
        lu_grid_destroy(&h);
    }
    lu_grid_destroy(&g);
}

static void test_vdb_refusals(void) {
    char fog[300], vec[300], none[300], missing[300];
    path_in(fog, sizeof fog, "fog.vdb");
    path_in(vec, sizeof vec, "vec_only.vdb");
    path_in(none, sizeof none, "no_grids.vdb");
    path_in(missing, sizeof missing, "missing.vdb");
    expect_fail(fog, "velocity", LU_ERR_UNSUPPORTED, "vec3s");
    expect_fail(fog, "twice", LU_ERR_UNSUPPORTED, "double");
    expect_fail(fog, "nope", LU_ERR_INVALID_ARG, "\"density\" (float)");
    expect_fail(fog, "empty", LU_ERR_UNSUPPORTED, "no active voxels");
    expect_fail(fog, "sdf", LU_ERR_UNSUPPORTED, "level set");
    expect_fail(fog, "frustum", LU_ERR_UNSUPPORTED, "non-linear");
    expect_fail(vec, NULL, LU_ERR_UNSUPPORTED, "no float grid");
    expect_fail(none, NULL, LU_ERR_UNSUPPORTED, "no grids");
    expect_fail(missing, NULL, LU_ERR_IO, NULL);
    expect_fail(g_dir, NULL, LU_ERR_IO, NULL);
}

/* Truncations, garbage and byte flips: every one is an error naming the
 * file (or, for a flip OpenVDB does not notice, a grid), and this process
 * survives whatever the converter does with them. */
static void test_vdb_malformed(void) {
    char src[300], bad[300];
    path_in(src, sizeof src, "fog_zip.vdb");
    path_in(bad, sizeof bad, "bad.vdb");
    unsigned char *data = NULL;
    size_t size = 0;
    if (!read_all(src, &data, &size) || size < 1000) {
        CHECK_MSG(false, "cannot read %s (or it is too small)", src);
        free(data);
        return;
    }
    const size_t cuts[] = {0, 1, 7, 8, 12, 40, 100, 200, 400, size / 4, size / 2, size - 100, size - 1};
    for (size_t c = 0; c < sizeof cuts / sizeof cuts[0]; c++) {
        CHECK(write_all(bad, data, cuts[c]));
        lu_grid g;
        lu_error err = {0};
        lu_result r = lu_grid_load_vdb(bad, NULL, &g, &err);
        CHECK_MSG(r != LU_OK, "truncated to %zu of %zu bytes, yet loaded", cuts[c], size);
        CHECK_MSG(r == LU_OK || strstr(err.message, bad), "cut %zu: %s", cuts[c], err.message);
        if (r == LU_OK) lu_grid_destroy(&g);
    }
    /* Garbage, and a real header followed by garbage. */
    unsigned char junk[4096];
    uint32_t s = 12345u;
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (unsigned char)((s = s * 1664525u + 1013904223u) >> 24);
    CHECK(write_all(bad, junk, sizeof junk));
    expect_fail(bad, NULL, LU_ERR_FORMAT, "OpenVDB");
    memcpy(junk, data, 64);
    CHECK(write_all(bad, junk, sizeof junk));
    lu_grid g;
    lu_error err = {0};
    lu_result r = lu_grid_load_vdb(bad, NULL, &g, &err);
    CHECK_MSG(r != LU_OK && strstr(err.message, bad), "header + garbage: %s %s", lu_result_name(r), err.message);
    /* Byte flips all over the file. */
    int loaded = 0, failed = 0, crashed = 0;
    for (int t = 0; t < 24; t++) {
        unsigned char *m = malloc(size);
        memcpy(m, data, size);
        for (int f = 0; f < 3; f++) {
            s = s * 1664525u + 1013904223u;
            m[(s >> 8) % size] ^= (unsigned char)(1u << (t % 8));
        }
        CHECK(write_all(bad, m, size));
        free(m);
        err.message[0] = '\0';
        r = lu_grid_load_vdb(bad, NULL, &g, &err);
        if (r == LU_OK) {
            loaded++;
            lu_grid_destroy(&g);
        } else {
            failed++;
            crashed += strstr(err.message, "crashed") != NULL;
            CHECK_MSG(strstr(err.message, bad) != NULL, "flip %d: %s", t, err.message);
        }
    }
    fprintf(stderr, "  24 mutated files: %d loaded, %d refused (%d of those crashed the converter)\n", loaded, failed,
            crashed);
    remove(bad);
    free(data);
}

/* Stand-in converters, set through lu_host.vdb_converter: what the library
 * makes of a converter that crashes, exits with an unknown status, writes
 * nothing, writes garbage, or floods its standard error. */
static void set_converter(const char *path) {
    lu_host h;
    lu_host_get(&h);
    h.threads = 0;
    h.vdb_converter = path;
    lu_error err = {0};
    CHECK_OK(lu_host_set(&h, &err), &err);
}

static void test_vdb_containment(void) {
    char fog[300], script[300];
    path_in(fog, sizeof fog, "fog_zip.vdb");
    path_in(script, sizeof script, "fake_convert.sh");
    struct {
        const char *body;
        lu_result code;
        const char *needle;
    } cases[] = {
        {"kill -SEGV $$", LU_ERR_FORMAT, "signal 11"},
        {"echo 'about to fall over' >&2; kill -ABRT $$", LU_ERR_FORMAT, "about to fall over"},
        {"exit 42", LU_ERR_IO, "status 42"},
        {"exit 0", LU_ERR_FORMAT, "wrote no grid"},
        {"head -c 3000 /dev/zero; exit 0", LU_ERR_FORMAT, NULL},
        {"head -c 1000000 /dev/zero | tr '\\0' x >&2; exit 3", LU_ERR_FORMAT, "xxxx"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        char text[512];
        snprintf(text, sizeof text, "#!/bin/sh\n%s\n", cases[c].body);
        CHECK(write_all(script, text, strlen(text)));
        CHECK(chmod(script, 0755) == 0);
        set_converter(script);
        expect_fail(fog, NULL, cases[c].code, cases[c].needle);
    }
    char nowhere[300];
    path_in(nowhere, sizeof nowhere, "no_such_converter");
    set_converter(nowhere);
    expect_fail(fog, NULL, LU_ERR_IO, "no_such_converter");
    /* The converter is looked up only for files that exist. */
    char missing[300];
    path_in(missing, sizeof missing, "missing.vdb");
    lu_grid g;
    lu_error err = {0};
    CHECK(lu_grid_load_vdb(missing, NULL, &g, &err) == LU_ERR_IO && strstr(err.message, "missing.vdb"));
    /* An empty path is a mistake, not "search". */
    lu_host h;
    lu_host_get(&h);
    h.threads = 0;
    h.vdb_converter = "";
    CHECK(lu_host_set(&h, &err) == LU_ERR_INVALID_ARG && strstr(err.message, "vdb_converter"));
    set_converter(NULL);
    char found[1024];
    CHECK_OK(lu_grid_vdb_converter(found, sizeof found, &err), &err);
    CHECK(strstr(found, "lucent-vdb-convert") != NULL);
    remove(script);
}

typedef struct {
    const char *path;
    lu_grid g;
    lu_result r;
} load_job;

static void *load_thread(void *p) {
    load_job *j = p;
    lu_error err = {0};
    j->r = lu_grid_load_vdb(j->path, "density", &j->g, &err);
    return NULL;
}

/* Several threads converting at once each get their own whole grid. */
static void test_vdb_threads(void) {
    char path[300];
    path_in(path, sizeof path, "fog.vdb");
    load_job jobs[4];
    pthread_t t[4];
    for (int i = 0; i < 4; i++) {
        jobs[i].path = path;
        CHECK(pthread_create(&t[i], NULL, load_thread, &jobs[i]) == 0);
    }
    for (int i = 0; i < 4; i++) pthread_join(t[i], NULL);
    for (int i = 0; i < 4; i++) CHECK(jobs[i].r == LU_OK);
    for (int i = 1; i < 4; i++)
        if (jobs[0].r == LU_OK && jobs[i].r == LU_OK) CHECK(same_grid(&jobs[0].g, &jobs[i].g));
    for (int i = 0; i < 4; i++)
        if (jobs[i].r == LU_OK) lu_grid_destroy(&jobs[i].g);
}

/* A scene reading twin.vdb renders bit for bit what the scene reading its
 * .nvdb twin renders: the twin from nanovdb_convert (another program's
 * OpenVDB -> NanoVDB path) and the converter's own output written out. */
static void render_scene(const char *file, const char *method, lu_image *img) {
    char json[1200];
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0.1, 0.3, 3], \"look_at\": [0.05, 0.0, 0.05], \"fov_y_deg\": 35,"
             " \"width\": 32, \"height\": 28},"
             " \"lights\": [{\"type\": \"point\", \"position\": [2, 2, 2], \"intensity\": [30, 30, 30]}],"
             " \"media\": [{\"density\": {\"file\": \"%s\", \"grid\": \"density\"},"
             " \"transform\": {\"rotate_deg\": [0, 20, 0]},"
             " \"sigma_s\": [3, 2.5, 2], \"sigma_a\": [0.3, 0.4, 0.5], \"phase_g\": 0.3}]}",
             file);
    memset(img, 0, sizeof *img);
    lu_test_render_json(json, method, "reference.spp=4 pathtrace.spp=4", img);
}

static void test_vdb_twin_render(void) {
    char vdb[300], nvdb_tool[300], nvdb_ours[300], cmd[3000];
    path_in(vdb, sizeof vdb, "twin.vdb");
    path_in(nvdb_tool, sizeof nvdb_tool, "twin_tool.nvdb");
    path_in(nvdb_ours, sizeof nvdb_ours, "twin_ours.nvdb");
    lu_error err = {0};
    char conv[512];
    CHECK_OK(lu_grid_vdb_converter(conv, sizeof conv, &err), &err);
    snprintf(cmd, sizeof cmd, "'%s' --grid density '%s' > '%s'", conv, vdb, nvdb_ours);
    CHECK(system(cmd) == 0);
    const char *twins[2] = {nvdb_ours, NULL};
    snprintf(cmd, sizeof cmd, "command -v nanovdb_convert >/dev/null 2>&1 && nanovdb_convert -f '%s' '%s' >/dev/null",
             vdb, nvdb_tool);
    if (system(cmd) == 0) twins[1] = nvdb_tool;
    else fprintf(stderr, "  note: nanovdb_convert not installed; the twin is the converter's own output only\n");
    lu_grid a, b;
    CHECK_OK(lu_grid_load_vdb(vdb, "density", &a, &err), &err);
    const char *methods[] = {"reference", "pathtrace"};
    for (int m = 0; m < 2; m++) {
        lu_image iv;
        render_scene(vdb, methods[m], &iv);
        double sum = 0;
        for (int i = 0; iv.rgb && i < 3 * iv.width * iv.height; i++) sum += iv.rgb[i];
        CHECK_MSG(sum > 0.5, "%s: the blob renders black (sum %g)", methods[m], sum);
        for (int t = 0; t < 2; t++) {
            if (!twins[t]) continue;
            if (m == 0) {
                lu_result r = lu_grid_load_nvdb(twins[t], "density", &b, &err);
                CHECK_OK(r, &err);
                if (r == LU_OK) {
                    CHECK_MSG(same_grid(&a, &b), "%s: grid differs from the .vdb's", twins[t]);
                    lu_grid_destroy(&b);
                }
            }
            lu_image in;
            render_scene(twins[t], methods[m], &in);
            bool same = iv.rgb && in.rgb && iv.width == in.width && iv.height == in.height &&
                        memcmp(iv.rgb, in.rgb, sizeof(float) * 3 * (size_t)iv.width * iv.height) == 0;
            CHECK_MSG(same, "%s: the .vdb scene and %s differ", methods[m], twins[t]);
            lu_image_destroy(&in);
        }
        lu_image_destroy(&iv);
    }
    lu_grid_destroy(&a);
    remove(nvdb_tool);
    remove(nvdb_ours);
}

/* The scene loader reads .vdb by extension, with "grid" selecting. */
static void test_vdb_scene(void) {
    char json[800], fog[300];
    path_in(fog, sizeof fog, "fog.vdb");
    lu_scene s;
    lu_error err = {0};
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0]},"
             " \"media\": [{\"density\": {\"file\": \"%s\", \"grid\": \"velocity\"}, \"sigma_s\": 1}]}",
             fog);
    CHECK(lu_scene_load_string(json, "t.json", &s, &err) == LU_ERR_UNSUPPORTED);
    CHECK_MSG(strstr(err.message, "$.media[0].density") && strstr(err.message, fog) && strstr(err.message, "vec3s"),
              "%s", err.message);
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0]},"
             " \"media\": [{\"density\": {\"file\": \"%s\", \"grid\": \"density\"}, \"sigma_s\": 1}]}",
             fog);
    lu_result r = lu_scene_load_string(json, "t.json", &s, &err);
    CHECK_OK(r, &err);
    if (r == LU_OK) lu_scene_destroy(&s);
}

/* A numbered sequence of .vdb frames loads as its frames do. */
static void test_vdb_sequence(void) {
    char src[300], f1[300], f2[300], json[1000];
    path_in(src, sizeof src, "twin.vdb");
    path_in(f1, sizeof f1, "seq_0001.vdb");
    path_in(f2, sizeof f2, "seq_0002.vdb");
    unsigned char *data = NULL;
    size_t size = 0;
    CHECK(read_all(src, &data, &size) && write_all(f1, data, size) && write_all(f2, data, size));
    free(data);
    lu_grid g;
    lu_error err = {0};
    lu_result r = lu_grid_load_vdb(src, "density", &g, &err);
    CHECK_OK(r, &err);
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 0, 3], \"look_at\": [0, 0, 0]},"
             " \"media\": [{\"density\": {\"file\": \"%s/seq_####.vdb\", \"frames\": [1, 2]}, \"sigma_s\": 1}]}",
             g_dir);
    lu_scene s;
    lu_result rs = lu_scene_load_string(json, "t.json", &s, &err);
    CHECK_OK(rs, &err);
    if (rs == LU_OK && r == LU_OK) {
        CHECK(s.medium_count == 1 && same_grid(&s.media[0].grid, &g));
        lu_scene_destroy(&s);
    }
    remove(f2);
    rs = lu_scene_load_string(json, "t.json", &s, &err);
    CHECK_MSG(rs == LU_ERR_IO && strstr(err.message, "frame 2") && strstr(err.message, "seq_0002.vdb"), "%s: %s",
              lu_result_name(rs), err.message);
    if (rs == LU_OK) lu_scene_destroy(&s);
    if (r == LU_OK) lu_grid_destroy(&g);
    remove(f1);
}

int main(void) {
#if !LU_HAVE_VDB
    TEST_EXIT_SKIPPED("built without libopenvdb-dev: no converter, no .vdb input");
#else
    snprintf(g_dir, sizeof g_dir, "%s/test_vdb_tmp_%ld", LU_BINARY_DIR, (long)getpid());
    char cmd[600];
    snprintf(cmd, sizeof cmd, "mkdir -p '%s' && '%s/lu_vdb_gen' '%s'", g_dir, LU_BINARY_DIR, g_dir);
    if (system(cmd) != 0) {
        fprintf(stderr, "cannot write the test files with %s/lu_vdb_gen\n", LU_BINARY_DIR);
        return EXIT_FAILURE;
    }
    RUN_TEST(test_vdb_values_and_map);
    RUN_TEST(test_vdb_select_and_codecs);
    RUN_TEST(test_vdb_refusals);
    RUN_TEST(test_vdb_malformed);
    RUN_TEST(test_vdb_containment);
    RUN_TEST(test_vdb_threads);
    RUN_TEST(test_vdb_twin_render);
    RUN_TEST(test_vdb_scene);
    RUN_TEST(test_vdb_sequence);
    lu_test_remove_dir(g_dir);
    TEST_EXIT();
#endif
}
