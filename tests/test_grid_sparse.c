/* Sparse grids (lucent/grid.h, kernels/lu_grid_tree.h): a NanoVDB tree read
 * in place must give the numbers of its dense expansion, the second
 * algorithm here (the loader's own voxel-by-voxel fill and lu_grid_sample's
 * array path):
 *   - every bundled scene's grid media, written as .nvdb and loaded both
 *     ways, sample equal bit for bit at voxel centres, cell interiors, the
 *     support's edges and outside it, and voxel by voxel (lu_grid_at);
 *   - the majorant grid built from the tree's nodes bounds the field in
 *     every block, and is at least the dense per-block maximum;
 *   - edits are refused on sparse grids and work on a densified copy;
 *   - malformed trees (a negative or NaN leaf value, a box wider than
 *     LU_MAX_GRID_SIDE) are refused with the voxel named, and the storage
 *     key of a scene file is checked. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <dirent.h>
#include <stdint.h>
#include <string.h>

#include <sys/stat.h>

#include "kernels/lu_scene_layout.h"
#include "methods/common/majorant.h"

static uint64_t g_rng = 0x9e3779b97f4a7c15ull;
static float rnd(float lo, float hi) {
    g_rng = g_rng * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * (float)((g_rng >> 40) / 16777216.0);
}

static char g_tmp[256];

/* Sparse and dense loads of one grid written as .nvdb; false if it has no
 * active voxel (nothing to compare). */
static bool load_both(const lu_grid *src, lu_grid *sparse, lu_grid *dense) {
    lu_error err;
    char path[300];
    snprintf(path, sizeof path, "%s/g.nvdb", g_tmp);
    lu_result r = lu_grid_save_nvdb(src, path, &err);
    if (r != LU_OK) {
        CHECK_MSG(src->max_value == 0.0f, "save: %s", err.message);
        return false;
    }
    CHECK_OK(lu_grid_load_nvdb(path, NULL, sparse, &err), &err);
    CHECK_OK(lu_grid_load_nvdb_as(path, NULL, LU_GRID_STORAGE_DENSE, dense, &err), &err);
    return lu_grid_is_sparse(sparse) && dense->data;
}

/* Returns how many points differed. */
static long compare_sampling(const lu_grid *s, const lu_grid *d, const char *what) {
    CHECK(s->nx == d->nx && s->ny == d->ny && s->nz == d->nz);
    CHECK(memcmp(&s->index_to_world, &d->index_to_world, sizeof s->index_to_world) == 0);
    CHECK_MSG(s->min_value == d->min_value && s->max_value == d->max_value, "%s: range [%g, %g] vs [%g, %g]", what,
              (double)s->min_value, (double)s->max_value, (double)d->min_value, (double)d->max_value);
    long bad = 0, n = 0;
    double worst = 0.0;
    /* every voxel */
    for (int z = -1; z <= d->nz; z++)
        for (int y = -1; y <= d->ny; y++)
            for (int x = -1; x <= d->nx; x++, n++)
                if (lu_grid_at(s, x, y, z) != lu_grid_at(d, x, y, z)) bad++;
    /* random points over the support and a margin beyond it, plus points
     * on integer and half-integer lattices (cell corners and centres) */
    for (int i = 0; i < 40000; i++, n++) {
        lu_vec3 p = lu_v3(rnd(-2.0f, (float)d->nx + 1.0f), rnd(-2.0f, (float)d->ny + 1.0f),
                          rnd(-2.0f, (float)d->nz + 1.0f));
        if (i % 4 == 1) p = lu_v3(floorf(p.x), floorf(p.y), floorf(p.z));
        if (i % 4 == 2) p = lu_v3(floorf(p.x) + 0.5f, floorf(p.y) + 0.5f, floorf(p.z) + 0.5f);
        float a = lu_grid_sample(s, p), b = lu_grid_sample(d, p);
        if (a != b) {
            bad++;
            worst = fmax(worst, fabs((double)a - b));
        }
    }
    printf("  %-40s %5d x %4d x %4d: %ld points, %ld differ (max |diff| %.3g), tree %llu bytes vs dense %llu\n",
           what, d->nx, d->ny, d->nz, n, bad, worst, (unsigned long long)lu_grid_storage_bytes(s),
           (unsigned long long)lu_grid_storage_bytes(d));
    return bad;
}

/* The majorant of each block bounds the field there (checked at random
 * points of every non-empty block's region) and covers the dense maximum. */
static void compare_majorants(const lu_grid *s, const lu_grid *d, const char *what) {
    lu_error err;
    lu_majorant ms, md;
    CHECK_OK(lu_majorant_build(s, LU_SCENE_MAJORANT_BLOCK, &ms, &err), &err);
    CHECK_OK(lu_majorant_build(d, LU_SCENE_MAJORANT_BLOCK, &md, &err), &err);
    CHECK(ms.nx == md.nx && ms.ny == md.ny && ms.nz == md.nz);
    long below = 0, empty_sparse = 0, empty_dense = 0;
    size_t nb = (size_t)md.nx * md.ny * md.nz;
    for (size_t i = 0; i < nb && ms.dmax && md.dmax; i++) {
        if (ms.dmax[i] < md.dmax[i]) below++;
        empty_sparse += ms.dmax[i] == 0.0f;
        empty_dense += md.dmax[i] == 0.0f;
    }
    CHECK_MSG(below == 0, "%s: %ld blocks with a sparse majorant below the dense maximum", what, below);
    long exceed = 0;
    const float B = (float)LU_SCENE_MAJORANT_BLOCK;
    for (int i = 0; i < 20000 && ms.dmax; i++) {
        int bx = (int)rnd(0, (float)ms.nx - 0.01f), by = (int)rnd(0, (float)ms.ny - 0.01f),
            bz = (int)rnd(0, (float)ms.nz - 0.01f);
        lu_vec3 p = lu_v3(bx * B - 1.0f + rnd(0, B), by * B - 1.0f + rnd(0, B), bz * B - 1.0f + rnd(0, B));
        if (lu_grid_sample(s, p) > lu_majorant_at(&ms, bx, by, bz)) exceed++;
    }
    CHECK_MSG(exceed == 0, "%s: %ld points above their block's majorant", what, exceed);
    printf("  %-40s majorant blocks %zu: empty %ld (dense %ld)\n", what, nb, empty_sparse, empty_dense);
    lu_majorant_destroy(&ms);
    lu_majorant_destroy(&md);
}

static void test_bundled_scenes(void) {
    DIR *dir = opendir(LU_SOURCE_DIR "/scenes");
    CHECK(dir != NULL);
    if (!dir) return;
    int grids = 0;
    long bad = 0;
    for (struct dirent *e; (e = readdir(dir)) != NULL;) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".json") != 0) continue;
        char path[512];
        snprintf(path, sizeof path, "%s/scenes/%s", LU_SOURCE_DIR, e->d_name);
        lu_scene s;
        lu_error err;
        if (lu_scene_load(path, &s, &err) != LU_OK) {
            CHECK_MSG(0, "%s: %s", e->d_name, err.message);
            continue;
        }
        for (int m = 0; m < s.medium_count; m++) {
            const lu_medium *md = &s.media[m];
            if (md->kind != LU_DENSITY_GRID) continue;
            /* a sparse grid of a bundled scene is compared with its own dense expansion */
            lu_grid src = {0};
            if (lu_grid_is_sparse(&md->grid)) CHECK_OK(lu_grid_densify(&md->grid, &src, &err), &err);
            lu_grid sp = {0}, dn = {0};
            if (load_both(src.data ? &src : &md->grid, &sp, &dn)) {
                char what[300];
                snprintf(what, sizeof what, "%s medium %d", e->d_name, m);
                bad += compare_sampling(&sp, &dn, what);
                compare_majorants(&sp, &dn, what);
                grids++;
            }
            lu_grid_destroy(&src);
            lu_grid_destroy(&sp);
            lu_grid_destroy(&dn);
        }
        lu_scene_destroy(&s);
    }
    closedir(dir);
    CHECK_MSG(bad == 0, "%ld sparse samples differ from the dense path", bad);
    CHECK_MSG(grids >= 5, "only %d bundled grid media compared", grids);
}

/* Tiles (constant regions) and a grid whose box does not start at a leaf
 * boundary, sampled as above. */
static void test_tiles_and_offsets(void) {
    lu_error err;
    lu_grid g;
    CHECK_OK(lu_grid_alloc(&g, 260, 96, 130, &err), &err);
    for (int z = 0; z < g.nz; z++)
        for (int y = 0; y < g.ny; y++)
            for (int x = 0; x < g.nx; x++) {
                float v = 0.0f;
                if (x >= 3 && x < 250 && y >= 5 && z >= 9 && z < 126) v = 0.75f;             /* tiles inside */
                if ((x * 7 + y * 3 + z) % 11 == 0 && x > 1 && x < 40) v = 0.1f + 0.01f * (float)(x % 13); /* leaves */
                g.data[((size_t)z * g.ny + y) * g.nx + x] = v;
            }
    g.index_to_world = lu_affine_identity();
    g.index_to_world.m[0][3] = 5.0f;   /* world offset; index offset comes from the box */
    lu_grid_update_range(&g);
    lu_grid s, d;
    if (load_both(&g, &s, &d)) {
        CHECK(compare_sampling(&s, &d, "tiles + leaves, offset box") == 0);
        compare_majorants(&s, &d, "tiles + leaves, offset box");
        /* the tree is smaller than the dense box here */
        CHECK(lu_grid_storage_bytes(&s) < lu_grid_storage_bytes(&d));
    }
    lu_grid_destroy(&s);
    lu_grid_destroy(&d);
    lu_grid_destroy(&g);
}

static void test_edits(void) {
    lu_error err;
    lu_grid g, s, d, e;
    CHECK_OK(lu_grid_alloc(&g, 9, 10, 11, &err), &err);
    for (size_t i = 0; i < 990; i++) g.data[i] = (float)(i % 7) * 0.25f;
    lu_grid_update_range(&g);
    if (!load_both(&g, &s, &d)) return;
    float vals[990] = {0};
    CHECK(lu_grid_set_values(&s, vals, 990, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "sparse") != NULL);
    const int lo[3] = {0, 0, 0}, hi[3] = {2, 2, 2};
    CHECK(lu_grid_apply(&s, lo, hi, NULL, NULL, &err) == LU_ERR_UNSUPPORTED);
    CHECK_OK(lu_grid_densify(&s, &e, &err), &err);
    CHECK(e.data && memcmp(e.data, d.data, sizeof(float) * (size_t)d.nx * d.ny * d.nz) == 0);
    uint64_t gen = e.generation;
    CHECK_OK(lu_grid_set_values(&e, vals, (size_t)e.nx * e.ny * e.nz, &err), &err);
    CHECK(e.generation != gen && e.max_value == 0.0f);
    lu_grid_destroy(&e);
    lu_grid_destroy(&s);
    lu_grid_destroy(&d);
    lu_grid_destroy(&g);
}

/* Overwrites the last float equal to `old` in the file with `v`: a leaf's
 * value table comes after the statistics (which the header checksum may
 * cover) of its node and of the root. */
static bool patch_value(const char *path, float old, float v) {
    FILE *f = fopen(path, "r+b");
    if (!f) return false;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    unsigned char *buf = malloc((size_t)n);
    fseek(f, 0, SEEK_SET);
    bool ok = fread(buf, 1, (size_t)n, f) == (size_t)n;
    long at = -1;
    for (long i = 0; ok && i + 4 <= n; i += 4)
        if (memcmp(buf + i, &old, 4) == 0) at = i;
    if (at >= 0) {
        fseek(f, at, SEEK_SET);
        ok = fwrite(&v, 4, 1, f) == 1;
    }
    free(buf);
    fclose(f);
    return ok && at >= 0;
}

static void test_malformed(void) {
    lu_error err;
    char path[300];
    snprintf(path, sizeof path, "%s/bad.nvdb", g_tmp);
    lu_grid g, s;
    const float marker = 0.123456789f;
    CHECK_OK(lu_grid_alloc(&g, 12, 12, 12, &err), &err);
    for (size_t i = 0; i < 12 * 12 * 12; i++) g.data[i] = 0.5f;
    g.data[(5 * 12 + 6) * 12 + 7] = marker;   /* voxel (7, 6, 5) */
    lu_grid_update_range(&g);
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    CHECK(patch_value(path, marker, -2.0f));
    CHECK(lu_grid_load_nvdb(path, NULL, &s, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "(7,6,5)") && strstr(err.message, "negative"), "%s", err.message);
    CHECK(!lu_grid_has_values(&s));
    CHECK(patch_value(path, -2.0f, NAN));
    CHECK(lu_grid_load_nvdb(path, NULL, &s, &err) == LU_ERR_NONFINITE);
    CHECK_MSG(strstr(err.message, "(7,6,5)") != NULL, "%s", err.message);
    lu_grid_destroy(&g);

    /* Two voxels LU_MAX_GRID_SIDE + 8 apart: the box is too wide to index. */
    CHECK_OK(lu_grid_alloc(&g, LU_MAX_GRID_SIDE + 8, 1, 1, &err), &err);
    g.data[0] = 1.0f;
    g.data[LU_MAX_GRID_SIDE + 7] = 1.0f;
    lu_grid_update_range(&g);
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    CHECK(lu_grid_load_nvdb(path, NULL, &s, &err) == LU_ERR_LIMIT);
    CHECK_MSG(strstr(err.message, "LU_MAX_GRID_SIDE") != NULL, "%s", err.message);
    /* ... and as a dense grid it would be a long line, which fits */
    CHECK_OK(lu_grid_load_nvdb_as(path, NULL, LU_GRID_STORAGE_DENSE, &s, &err), &err);
    lu_grid_destroy(&s);
    lu_grid_destroy(&g);

    /* Truncations of a valid file at every 97th byte fail cleanly, never crash. */
    CHECK_OK(lu_grid_alloc(&g, 20, 20, 20, &err), &err);
    for (size_t i = 0; i < 8000; i++) g.data[i] = (float)(i % 5) * 0.2f;
    lu_grid_update_range(&g);
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    size_t n = 0;
    char *file = NULL;
    CHECK_OK(lu_read_file(path, 1u << 26, &file, &n, &err), &err);
    int refused = 0, tried = 0;
    for (size_t cut = 0; file && cut < n; cut += 97, tried++) {
        if (lu_grid_load_nvdb_memory(file, cut, "cut", NULL, &s, &err) != LU_OK) refused++;
        lu_grid_destroy(&s);
    }
    CHECK_MSG(refused == tried, "%d of %d truncated files loaded", tried - refused, tried);
    lu_free(file);
    lu_grid_destroy(&g);
}

static void test_scene_storage_key(void) {
    lu_error err;
    char path[300], json[1200];
    snprintf(path, sizeof path, "%s/cloud.nvdb", g_tmp);
    lu_grid g;
    lu_kvlist kv = {0};
    CHECK_OK(lu_grid_procedural("fbm_cloud", &kv, &g, "test", &err), &err);
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    lu_grid_destroy(&g);
    const char *storage[] = {"", ", \"storage\": \"sparse\"", ", \"storage\": \"dense\"", ", \"storage\": \"tiled\""};
    for (int k = 0; k < 4; k++) {
        snprintf(json, sizeof json,
                 "{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 8, "
                 "\"height\": 8}, \"lights\": [{\"type\": \"point\", \"position\": [1, 2, 3], \"intensity\": [1, 1, 1]}],"
                 " \"media\": [{\"density\": {\"file\": \"%s\"%s}, \"sigma_s\": [1, 1, 1], \"sigma_a\": [0, 0, 0]}]}",
                 path, storage[k]);
        lu_scene s;
        lu_result r = lu_scene_load_string(json, "storage.json", &s, &err);
        if (k == 3) {
            CHECK(r == LU_ERR_SCENE && strstr(err.message, "storage"));
            continue;
        }
        CHECK_OK(r, &err);
        if (r == LU_OK) {
            CHECK(lu_grid_is_sparse(&s.media[0].grid) == (k != 2));
            lu_scene_destroy(&s);
        }
    }
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "%s/test_grid_sparse.tmp", LU_BINARY_DIR);
    lu_test_remove_dir(g_tmp);
    CHECK(mkdir(g_tmp, 0755) == 0);
    RUN_TEST(test_tiles_and_offsets);
    RUN_TEST(test_edits);
    RUN_TEST(test_malformed);
    RUN_TEST(test_scene_storage_key);
    RUN_TEST(test_bundled_scenes);
    lu_test_remove_dir(g_tmp);
    TEST_EXIT();
}
