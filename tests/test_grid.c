/* Density grids: trilinear sampling, raw and NanoVDB files, procedural
 * generators. Expected numbers come from closed forms (multilinear
 * reproduction, sphere/Gaussian/torus volumes), an independent GL_LINEAR
 * emulation, NanoVDB's own C++ writer and its nanovdb_print tool, and the
 * documented byte layout of the .nvdb container. */
#include <lucent/lucent.h>

#include <float.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "lu_test.h"
#include "volume/lu_noise.h"
#include "volume/nvdb_write.h"

#define TMP_PREFIX "test_grid_tmp_"

static char *tmp_path(char *buf, size_t n, const char *name) {
    snprintf(buf, n, "%s%ld_%s", TMP_PREFIX, (long)getpid(), name);
    return buf;
}

static bool read_all(const char *path, unsigned char **data, size_t *size) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return false;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    *data = malloc((size_t)n + 1);
    *size = (size_t)n;
    bool ok = *data && fread(*data, 1, (size_t)n, fp) == (size_t)n;
    fclose(fp);
    return ok;
}

static bool write_all(const char *path, const void *data, size_t size) {
    FILE *fp = fopen(path, "wb");
    if (!fp) return false;
    bool ok = fwrite(data, 1, size, fp) == size;
    return fclose(fp) == 0 && ok;
}

static uint32_t get32(const unsigned char *b) {
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}
static uint64_t get64(const unsigned char *b) { return (uint64_t)get32(b) | ((uint64_t)get32(b + 4) << 32); }
static void put16(unsigned char *b, uint16_t v) {
    b[0] = (unsigned char)v;
    b[1] = (unsigned char)(v >> 8);
}
static void put32(unsigned char *b, uint32_t v) {
    for (int i = 0; i < 4; i++) b[i] = (unsigned char)(v >> (8 * i));
}
static void put64(unsigned char *b, uint64_t v) {
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(v >> (8 * i));
}

/* Byte layout of a single-grid .nvdb segment (nanovdb/util/IO.h):
 * header 16, metadata 176, name, then the grid; in the grid the tree header
 * follows the 672-byte grid header. */
static size_t grid_data_offset(const unsigned char *file) { return 16 + 176 + get32(file + 16 + 136); }
static uint32_t tree_u32(const unsigned char *file, size_t field) {
    return get32(file + grid_data_offset(file) + 672 + field);
}
#define TREE_NODE_COUNT_LEAF 32
#define TREE_TILE_COUNT_LEAF 44  /* active tiles in lower nodes (8^3 each) */
#define TREE_TILE_COUNT_LOWER 48 /* active tiles in upper nodes (128^3 each) */

/* The tests of this file read the dense expansion (g.data); sparse storage,
 * the default, is held to it in test_grid_sparse.c. */
static lu_result load_nvdb_dense(const char *path, const char *name, lu_grid *g, lu_error *err) {
    return lu_grid_load_nvdb_as(path, name, LU_GRID_STORAGE_DENSE, g, err);
}
static lu_result load_nvdb_memory_dense(const void *data, size_t size, const char *label, const char *name, lu_grid *g,
                                        lu_error *err) {
    return lu_grid_load_nvdb_memory_as(data, size, label, name, LU_GRID_STORAGE_DENSE, g, err);
}

static bool same_grid_values(const lu_grid *a, const lu_grid *b) {
    if (a->nx != b->nx || a->ny != b->ny || a->nz != b->nz) return false;
    return memcmp(a->data, b->data, (size_t)a->nx * a->ny * a->nz * sizeof(float)) == 0;
}

static bool has_tool(const char *name) {
    char cmd[256];
    snprintf(cmd, sizeof cmd, "command -v %s >/dev/null 2>&1", name);
    return system(cmd) == 0;
}

/* Runs `nanovdb_print -l` and returns its output (caller frees) or NULL. */
static char *nanovdb_print(const char *path) {
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "nanovdb_print -l '%s' 2>&1", path);
    FILE *p = popen(cmd, "r");
    if (!p) return NULL;
    size_t cap = 1 << 16, len = 0;
    char *out = malloc(cap);
    size_t got;
    while (out && (got = fread(out + len, 1, cap - 1 - len, p)) > 0) len += got;
    int rc = pclose(p);
    if (!out) return NULL;
    out[len] = '\0';
    if (rc != 0) {
        fprintf(stderr, "nanovdb_print failed (%d): %s\n", rc, out);
        free(out);
        return NULL;
    }
    return out;
}

/* The data row of `nanovdb_print -l` for the grid: the "A->B->C" columns are
 * node counts (upper->lower->leaf) then active tiles (upper->lower->leaf
 * levels, i.e. root, upper and lower node tiles). */
static bool print_counts(const char *out, const char *name, long nodes[3], long tiles[3], long *voxels) {
    const char *line = out;
    while ((line = strstr(line, "\n1  ")) != NULL) {
        line++;
        const char *end = strchr(line, '\n');
        size_t n = end ? (size_t)(end - line) : strlen(line);
        char row[1024];
        if (n >= sizeof row) n = sizeof row - 1;
        memcpy(row, line, n);
        row[n] = '\0';
        char *tok, *save = NULL;
        int idx = 0, arrows = 0;
        bool named = false, after_scale = false;
        for (tok = strtok_r(row, " ", &save); tok; tok = strtok_r(NULL, " ", &save), idx++) {
            if (idx == 1) named = strcmp(tok, name) == 0;
            if (after_scale) *voxels = atol(tok); /* "# Voxels" follows the "(sx,sy,sz)" scale */
            after_scale = tok[0] == '(' && *voxels == 0;
            if (strstr(tok, "->") && strchr(tok, '(') == NULL) {
                long *dst = arrows == 0 ? nodes : tiles;
                if (arrows < 2 && sscanf(tok, "%ld->%ld->%ld", &dst[0], &dst[1], &dst[2]) == 3) arrows++;
            }
        }
        if (named && arrows == 2) return true;
    }
    return false;
}

/* ---- alloc, sampling -------------------------------------------------------- */

static void test_alloc(void) {
    lu_grid g;
    lu_error err = {0};
    CHECK(lu_grid_alloc(&g, 0, 4, 4, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_alloc(&g, 513, 512, 512, &err) == LU_ERR_LIMIT);
    CHECK(strstr(err.message, "513") != NULL);
    CHECK(lu_grid_alloc(&g, 2147483647, 2147483647, 2147483647, &err) == LU_ERR_LIMIT);
    CHECK(lu_grid_alloc(&g, 1, 2147483647, 1, &err) == LU_ERR_LIMIT);
    CHECK_OK(lu_grid_alloc(&g, 3, 4, 5, &err), &err);
    bool zero = true;
    for (int i = 0; i < 60; i++) zero = zero && g.data[i] == 0.0f;
    CHECK(zero);
    lu_vec3 p = lu_affine_point(&g.index_to_world, lu_v3(1, 2, 3));
    CHECK(p.x == 1 && p.y == 2 && p.z == 3);
    g.data[7] = 3.0f;
    g.data[11] = -1.0f;
    lu_grid_update_range(&g);
    CHECK(g.min_value == -1.0f && g.max_value == 3.0f);
    lu_aabb s = lu_grid_index_support(&g);
    CHECK(s.lo.x == -1 && s.lo.y == -1 && s.lo.z == -1 && s.hi.x == 3 && s.hi.y == 4 && s.hi.z == 5);
    lu_grid_destroy(&g);
    CHECK(g.data == NULL);
}

/* A multilinear function a + b x + c y + d z + e xy + f yz + g xz + k xyz is
 * reproduced exactly by trilinear interpolation of its samples. */
static double multilinear(double x, double y, double z) {
    return 1.0 + 0.5 * x + 0.25 * y + 2.0 * z + 0.125 * x * y - 0.375 * y * z + 0.0625 * x * z + 0.03125 * x * y * z;
}

/* Independent model of a GL_LINEAR 3D texture with a zero border colour:
 * normalised coordinate s = (p + 0.5) / n, i0 = floor(s n - 0.5),
 * alpha = frac(s n - 0.5), texels outside [0, n) read the border (0). */
static double gl_linear(const lu_grid *g, double px, double py, double pz) {
    double s[3] = {(px + 0.5) / g->nx, (py + 0.5) / g->ny, (pz + 0.5) / g->nz};
    int n[3] = {g->nx, g->ny, g->nz}, i0[3];
    double a[3];
    for (int k = 0; k < 3; k++) {
        double u = s[k] * n[k] - 0.5;
        i0[k] = (int)floor(u);
        a[k] = u - floor(u);
    }
    double sum = 0.0;
    for (int c = 0; c < 8; c++) {
        int d[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
        double w = 1.0;
        int idx[3];
        bool inside = true;
        for (int k = 0; k < 3; k++) {
            w *= d[k] ? a[k] : 1.0 - a[k];
            idx[k] = i0[k] + d[k];
            inside = inside && idx[k] >= 0 && idx[k] < n[k];
        }
        if (inside) sum += w * g->data[((size_t)idx[2] * g->ny + idx[1]) * g->nx + idx[0]];
    }
    return sum;
}

static void test_sample(void) {
    lu_grid g;
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(&g, 4, 3, 5, &err), &err);
    for (int z = 0; z < 5; z++)
        for (int y = 0; y < 3; y++)
            for (int x = 0; x < 4; x++) g.data[(z * 3 + y) * 4 + x] = (float)multilinear(x, y, z);
    /* Exact at voxel centres. */
    bool exact = true;
    for (int z = 0; z < 5; z++)
        for (int y = 0; y < 3; y++)
            for (int x = 0; x < 4; x++)
                exact = exact && lu_grid_sample(&g, lu_v3((float)x, (float)y, (float)z)) == lu_grid_at(&g, x, y, z);
    CHECK(exact);
    /* Interior points: equals the multilinear function. */
    const float pts[][3] = {{0.5f, 0.5f, 0.5f}, {1.25f, 1.75f, 3.5f}, {2.9f, 0.1f, 0.3f}, {3.0f, 2.0f, 3.999f}};
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++)
        CHECK_NEAR(lu_grid_sample(&g, lu_v3(pts[i][0], pts[i][1], pts[i][2])),
                   multilinear(pts[i][0], pts[i][1], pts[i][2]), 2e-6);
    /* A hand-computed case on a 2x2x2 block: corners 1..8, point (0.25, 0.5, 0.75):
     * x-lerps: 1.25, 3.25, 5.25, 7.25; y: 2.25, 6.25; z: 2.25 + 0.75*4 = 5.25. */
    lu_grid h;
    CHECK_OK(lu_grid_alloc(&h, 2, 2, 2, &err), &err);
    for (int i = 0; i < 8; i++) h.data[i] = (float)(i + 1);
    CHECK_NEAR(lu_grid_sample(&h, lu_v3(0.25f, 0.5f, 0.75f)), 5.25, 1e-6);
    /* Zero border: half-way between the first centre and index -1 halves it;
     * at exactly -1 and n (the support) the field is exactly 0. */
    CHECK_NEAR(lu_grid_sample(&h, lu_v3(-0.5f, 0.0f, 0.0f)), 0.5, 1e-7);
    CHECK_NEAR(lu_grid_sample(&h, lu_v3(1.0f, 1.0f, 1.5f)), 4.0, 1e-7);
    CHECK(lu_grid_sample(&g, lu_v3(-1.0f, 1.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(4.0f, 1.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(1.0f, 3.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(1.0f, 1.0f, 5.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(1.0f, -1.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(1.0f, 1.0f, -1.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(-1.0001f, 1.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(-0.999f, 1.0f, 2.0f)) > 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(NAN, 1.0f, 2.0f)) == 0.0f);
    CHECK(lu_grid_sample(&g, lu_v3(1e30f, 1.0f, 2.0f)) == 0.0f);
    /* Agrees with the GL_LINEAR + zero border model everywhere, border band included. */
    uint32_t s = 12345u;
    double worst = 0.0;
    for (int i = 0; i < 20000; i++) {
        float p[3];
        int n[3] = {4, 3, 5};
        for (int k = 0; k < 3; k++) {
            s = s * 1664525u + 1013904223u;
            p[k] = -1.5f + (n[k] + 2.0f) * (float)(s >> 8) / 16777216.0f;
        }
        double d = fabs(lu_grid_sample(&g, lu_v3(p[0], p[1], p[2])) - gl_linear(&g, p[0], p[1], p[2]));
        if (d > worst) worst = d;
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    lu_grid_destroy(&g);
    lu_grid_destroy(&h);
}

/* ---- raw ---------------------------------------------------------------------- */

static void test_raw(void) {
    char path[256];
    tmp_path(path, sizeof path, "a.raw");
    lu_error err = {0};
    /* Known little-endian bytes: 1.0f = 00 00 80 3f, 0.5f = 00 00 00 3f. */
    unsigned char bytes[2 * 2 * 1 * 4] = {0, 0, 0x80, 0x3f, 0, 0, 0, 0x3f, 0, 0, 0, 0, 0, 0, 0x80, 0x40};
    CHECK(write_all(path, bytes, sizeof bytes));
    lu_grid g;
    CHECK_OK(lu_grid_load_raw(path, 2, 2, 1, &g, &err), &err);
    CHECK(g.data && g.data[0] == 1.0f && g.data[1] == 0.5f && g.data[2] == 0.0f && g.data[3] == 4.0f);
    CHECK(lu_grid_at(&g, 1, 1, 0) == 4.0f);
    CHECK(g.max_value == 4.0f);
    char out[256];
    tmp_path(out, sizeof out, "b.raw");
    CHECK_OK(lu_grid_save_raw(&g, out, &err), &err);
    unsigned char *back = NULL;
    size_t n = 0;
    CHECK(read_all(out, &back, &n) && n == sizeof bytes && memcmp(back, bytes, n) == 0);
    free(back);
    lu_grid_destroy(&g);

    /* Size mismatch: names the file and both sizes. */
    lu_result r = lu_grid_load_raw(path, 2, 2, 2, &g, &err);
    CHECK(r == LU_ERR_FORMAT);
    CHECK(strstr(err.message, path) && strstr(err.message, "32 bytes") && strstr(err.message, "16 bytes"));
    CHECK(g.data == NULL);
    CHECK(lu_grid_load_raw(path, 600, 600, 600, &g, &err) == LU_ERR_LIMIT);
    CHECK(lu_grid_load_raw(path, 0, 2, 2, &g, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_load_raw("does/not/exist.raw", 1, 1, 1, &g, &err) == LU_ERR_IO);
    /* NaN at voxel 2 (byte offset 8), negative at voxel 3 (byte offset 12). */
    unsigned char bad[16];
    memcpy(bad, bytes, 16);
    bad[8] = 0, bad[9] = 0, bad[10] = 0xc0, bad[11] = 0x7f;
    CHECK(write_all(path, bad, 16));
    CHECK(lu_grid_load_raw(path, 2, 2, 1, &g, &err) == LU_ERR_NONFINITE);
    CHECK(strstr(err.message, path) && strstr(err.message, "byte offset 8"));
    memcpy(bad, bytes, 16);
    bad[15] = 0xc0;
    CHECK(write_all(path, bad, 16));
    CHECK(lu_grid_load_raw(path, 2, 2, 1, &g, &err) == LU_ERR_RANGE);
    CHECK(strstr(err.message, "byte offset 12"));
    remove(path);
    remove(out);
}

/* ---- NanoVDB ------------------------------------------------------------------ */

static lu_grid make_dusty(int nx, int ny, int nz) {
    lu_kvlist kv = {0};
    lu_error err = {0};
    double res[3] = {nx, ny, nz}, size[3] = {1.5, 1.25, 1.0};
    lu_kv_set_number(&kv, "resolution", res, 3, &err);
    lu_kv_set_number(&kv, "size", size, 3, &err);
    lu_grid g;
    CHECK_OK(lu_grid_procedural("dusty_room", &kv, &g, "test", &err), &err);
    lu_kv_free(&kv);
    return g;
}

static void test_nvdb_roundtrip(void) {
    char path[256];
    tmp_path(path, sizeof path, "round.nvdb");
    lu_error err = {0};
    /* Every voxel of dusty_room is > 0, so the active box is the whole grid. */
    lu_grid g = make_dusty(24, 20, 16);
    CHECK(g.min_value > 0.0f);
    /* A full affine map: rotation, anisotropic scale, translation. */
    lu_affine r = lu_affine_rotate_xyz_deg(lu_v3(10, 20, 30));
    lu_affine s = lu_affine_scale(lu_v3(0.5f, 0.25f, 0.125f));
    lu_affine rs = lu_affine_mul(&r, &s);
    lu_affine t = lu_affine_translate(lu_v3(1.5f, -2.0f, 3.25f));
    g.index_to_world = lu_affine_mul(&t, &rs);
    snprintf(g.name, sizeof g.name, "dust");
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    lu_grid h;
    CHECK_OK(load_nvdb_dense(path, NULL, &h, &err), &err);
    CHECK(h.nx == 24 && h.ny == 20 && h.nz == 16);
    CHECK(same_grid_values(&g, &h));
    CHECK(strcmp(h.name, "dust") == 0);
    bool map_same = true;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++) map_same = map_same && h.index_to_world.m[i][j] == g.index_to_world.m[i][j];
    CHECK(map_same);
    CHECK(h.min_value == g.min_value && h.max_value == g.max_value);
    lu_grid_destroy(&h);
    /* By name, and from memory. */
    CHECK_OK(load_nvdb_dense(path, "dust", &h, &err), &err);
    CHECK(same_grid_values(&g, &h));
    lu_grid_destroy(&h);
    unsigned char *file = NULL;
    size_t n = 0;
    CHECK(read_all(path, &file, &n));
    CHECK_OK(load_nvdb_memory_dense(file, n, "mem.nvdb", "", &h, &err), &err);
    CHECK(same_grid_values(&g, &h));
    lu_grid_destroy(&h);
    /* The container metadata matches the documented layout: grid type 1
     * (Float) at 32, class 2 (fog volume) at 36, voxel count at 24. */
    CHECK(get32(file + 16 + 32) == 1 && get32(file + 16 + 36) == 2);
    CHECK(get64(file + 16 + 24) == 24u * 20u * 16u);
    free(file);

    /* Independent C++ reader: NanoVDB's own nanovdb_print. */
    if (has_tool("nanovdb_print")) {
        char *out = nanovdb_print(path);
        CHECK(out != NULL);
        if (out) {
            long nodes[3] = {0}, tiles[3] = {0}, voxels = 0;
            CHECK_MSG(print_counts(out, "dust", nodes, tiles, &voxels), "%s", out);
            CHECK(voxels == 24 * 20 * 16);
            CHECK(strstr(out, "float") && strstr(out, "24 x 20 x 16"));
            CHECK(strstr(out, "(0,0,0) -> (23,19,15)"));
            free(out);
        }
    } else {
        fprintf(stderr, "note: nanovdb_print not installed, skipping the C++ reader cross-check\n");
    }
    lu_grid_destroy(&g);
    remove(path);
}

/* The loader crops to the active box and shifts the map, so the field in
 * world space is unchanged. */
static void test_nvdb_crop(void) {
    char path[256];
    tmp_path(path, sizeof path, "sphere.nvdb");
    lu_error err = {0};
    lu_kvlist kv = {0};
    double res = 40;
    lu_kv_set_number(&kv, "resolution", &res, 1, &err);
    lu_grid g, h;
    CHECK_OK(lu_grid_procedural("sphere", &kv, &g, "test", &err), &err);
    lu_kv_free(&kv);
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    CHECK_OK(load_nvdb_dense(path, NULL, &h, &err), &err);
    /* Active box from the data itself. */
    int lo[3] = {g.nx, g.ny, g.nz}, hi[3] = {-1, -1, -1};
    for (int z = 0; z < g.nz; z++)
        for (int y = 0; y < g.ny; y++)
            for (int x = 0; x < g.nx; x++)
                if (lu_grid_at(&g, x, y, z) != 0.0f) {
                    int c[3] = {x, y, z};
                    for (int k = 0; k < 3; k++) {
                        if (c[k] < lo[k]) lo[k] = c[k];
                        if (c[k] > hi[k]) hi[k] = c[k];
                    }
                }
    CHECK(lo[0] > 0 && h.nx == hi[0] - lo[0] + 1 && h.ny == hi[1] - lo[1] + 1 && h.nz == hi[2] - lo[2] + 1);
    bool same = true;
    for (int z = 0; z < h.nz; z++)
        for (int y = 0; y < h.ny; y++)
            for (int x = 0; x < h.nx; x++)
                same = same && lu_grid_at(&h, x, y, z) == lu_grid_at(&g, x + lo[0], y + lo[1], z + lo[2]);
    CHECK(same);
    lu_vec3 a = lu_affine_point(&h.index_to_world, lu_v3(0, 0, 0));
    lu_vec3 b = lu_affine_point(&g.index_to_world, lu_v3((float)lo[0], (float)lo[1], (float)lo[2]));
    CHECK_NEAR(a.x, b.x, 1e-6);
    CHECK_NEAR(a.y, b.y, 1e-6);
    CHECK_NEAR(a.z, b.z, 1e-6);
    lu_grid_destroy(&g);
    lu_grid_destroy(&h);
    remove(path);
}

/* Constant all-active 8^3 leaves become lower-node tiles and a constant
 * 128^3 lower node an upper-node tile; the reader must expand both. */
static void test_nvdb_tiles(void) {
    char path[256];
    tmp_path(path, sizeof path, "tiles.nvdb");
    lu_error err = {0};
    lu_grid g, h;
    CHECK_OK(lu_grid_alloc(&g, 40, 32, 24, &err), &err);
    for (int z = 0; z < g.nz; z++)
        for (int y = 0; y < g.ny; y++)
            for (int x = 0; x < g.nx; x++) {
                float v;
                if (x >= 8 && x < 32 && y >= 8 && y < 24) v = 2.5f; /* 3 x 2 x 3 whole leaves */
                else if (x < 4) v = 0.0f;
                else v = 0.01f * (float)(x + 3 * y + 7 * z);
                g.data[((size_t)z * g.ny + y) * g.nx + x] = v;
            }
    snprintf(g.name, sizeof g.name, "tiled");
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    unsigned char *file = NULL;
    size_t n = 0;
    CHECK(read_all(path, &file, &n));
    uint32_t leaf_tiles = tree_u32(file, TREE_TILE_COUNT_LEAF);
    CHECK_MSG(leaf_tiles == 18, "lower-node tiles: %u", leaf_tiles);
    free(file);
    if (has_tool("nanovdb_print")) {
        char *out = nanovdb_print(path);
        long nodes[3] = {0}, tiles[3] = {0}, voxels = 0;
        CHECK(out && print_counts(out, "tiled", nodes, tiles, &voxels));
        CHECK(tiles[2] == 18);
        free(out);
    }
    CHECK_OK(load_nvdb_dense(path, NULL, &h, &err), &err);
    /* x < 4 is inactive, so the loaded box starts at x = 4. */
    CHECK(h.nx == 36 && h.ny == 32 && h.nz == 24);
    bool same = true;
    for (int z = 0; z < h.nz; z++)
        for (int y = 0; y < h.ny; y++)
            for (int x = 0; x < h.nx; x++) same = same && lu_grid_at(&h, x, y, z) == lu_grid_at(&g, x + 4, y, z);
    CHECK(same);
    CHECK_NEAR(h.index_to_world.m[0][3], 4.0, 0.0);
    lu_grid_destroy(&h);
    lu_grid_destroy(&g);

    /* 128^3 of one value: a single upper-node tile, no leaves at all. */
    CHECK_OK(lu_grid_alloc(&g, 128, 128, 128, &err), &err);
    for (size_t i = 0; i < (size_t)128 * 128 * 128; i++) g.data[i] = 0.75f;
    CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
    CHECK(read_all(path, &file, &n));
    CHECK(tree_u32(file, TREE_TILE_COUNT_LOWER) == 1);
    CHECK(tree_u32(file, TREE_NODE_COUNT_LEAF) == 0);
    free(file);
    CHECK_OK(load_nvdb_dense(path, NULL, &h, &err), &err);
    CHECK(same_grid_values(&g, &h));
    lu_grid_destroy(&h);
    lu_grid_destroy(&g);
    remove(path);
}

static void test_nvdb_zip(void) {
    char plain[256], zip[256], handmade[256];
    tmp_path(plain, sizeof plain, "plain.nvdb");
    tmp_path(zip, sizeof zip, "zip.nvdb");
    tmp_path(handmade, sizeof handmade, "hand.nvdb");
    lu_error err = {0};
    lu_grid g = make_dusty(20, 12, 10), a, b;
    CHECK_OK(lu_grid_save_nvdb(&g, plain, &err), &err);
    CHECK_OK(lu_nvdb_save_dense(&g, zip, LU_NVDB_CODEC_ZIP, &err), &err);
    CHECK_OK(load_nvdb_dense(zip, NULL, &a, &err), &err);
    CHECK(same_grid_values(&g, &a));
    lu_grid_destroy(&a);
    if (has_tool("nanovdb_print")) {
        char *out = nanovdb_print(zip);
        CHECK(out && strstr(out, "ZIP"));
        free(out);
    }
    /* ZIP built here with zlib from the uncompressed file's grid: codec 1 in
     * the header, file size = 8 + compressed size, u64 compressed size. */
    unsigned char *file = NULL;
    size_t n = 0;
    CHECK(read_all(plain, &file, &n));
    size_t off = grid_data_offset(file), raw = n - off;
    uLongf csize = compressBound(raw);
    unsigned char *out = malloc(off + 8 + csize);
    CHECK(out && compress(out + off + 8, &csize, file + off, raw) == Z_OK);
    memcpy(out, file, off);
    put16(out + 14, 1);
    put64(out + 16 + 8, 8 + (uint64_t)csize);
    put64(out + off, (uint64_t)csize);
    CHECK(write_all(handmade, out, off + 8 + csize));
    CHECK_OK(load_nvdb_dense(handmade, NULL, &b, &err), &err);
    CHECK(same_grid_values(&g, &b));
    lu_grid_destroy(&b);
    /* Corrupt stream, and a size claim beyond what deflate can expand to. */
    out[off + 8 + csize / 2] ^= 0xff;
    out[off + 8 + csize / 2 + 1] ^= 0x5a;
    CHECK(write_all(handmade, out, off + 8 + csize));
    CHECK(load_nvdb_dense(handmade, NULL, &b, &err) == LU_ERR_FORMAT);
    CHECK(strstr(err.message, handmade) != NULL);
    put64(out + 16, (uint64_t)csize * 2000u);
    CHECK(write_all(handmade, out, off + 8 + csize));
    CHECK(load_nvdb_dense(handmade, NULL, &b, &err) == LU_ERR_FORMAT);
    CHECK(strstr(err.message, "more than zlib can produce") != NULL);
    free(out);
    free(file);
    lu_grid_destroy(&g);
    remove(plain);
    remove(zip);
    remove(handmade);
}

static lu_result gen_sphere_for_convert(lu_grid *g, lu_error *err) {
    lu_kvlist kv = {0};
    double res = 36, c[3] = {0.25, -0.5, 1.0};
    lu_kv_set_number(&kv, "resolution", &res, 1, err);
    lu_kv_set_number(&kv, "center", c, 3, err);
    lu_result r = lu_grid_procedural("sphere", &kv, g, "test", err);
    lu_kv_free(&kv);
    return r;
}

/* Files written by another writer: nanovdb_convert takes our grid through
 * OpenVDB and back with its OpenToNanoVDB builder, uncompressed, ZIP and
 * BLOSC (which must be refused cleanly). */
static void test_nvdb_converted(void) {
    if (!has_tool("nanovdb_convert")) {
        fprintf(stderr, "note: nanovdb_convert not installed, skipping the OpenVDB round trip\n");
        return;
    }
    char src[256], vdb[256], out[3][256];
    tmp_path(src, sizeof src, "conv_src.nvdb");
    tmp_path(vdb, sizeof vdb, "conv.vdb");
    tmp_path(out[0], sizeof out[0], "conv_none.nvdb");
    tmp_path(out[1], sizeof out[1], "conv_zip.nvdb");
    tmp_path(out[2], sizeof out[2], "conv_blosc.nvdb");
    lu_error err = {0};
    lu_grid g, h;
    CHECK_OK(gen_sphere_for_convert(&g, &err), &err);
    CHECK_OK(lu_grid_save_nvdb(&g, src, &err), &err);
    lu_grid ref;
    CHECK_OK(load_nvdb_dense(src, NULL, &ref, &err), &err);
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "nanovdb_convert -f '%s' '%s' >/dev/null 2>&1 && nanovdb_convert -f '%s' '%s' >/dev/null 2>&1 && "
             "nanovdb_convert -f -z '%s' '%s' >/dev/null 2>&1 && nanovdb_convert -f -b '%s' '%s' >/dev/null 2>&1",
             src, vdb, vdb, out[0], vdb, out[1], vdb, out[2]);
    CHECK(system(cmd) == 0);
    for (int i = 0; i < 2; i++) {
        CHECK_OK(load_nvdb_dense(out[i], "sphere", &h, &err), &err);
        CHECK(same_grid_values(&ref, &h));
        bool map_same = true;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++)
                map_same = map_same && fabsf(h.index_to_world.m[r][c] - ref.index_to_world.m[r][c]) < 1e-6f;
        CHECK(map_same);
        lu_grid_destroy(&h);
    }
    CHECK(load_nvdb_dense(out[2], NULL, &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "BLOSC") && strstr(err.message, out[2]));
    lu_grid_destroy(&ref);
    lu_grid_destroy(&g);
    remove(src);
    remove(vdb);
    for (int i = 0; i < 3; i++) remove(out[i]);
}

static lu_result load_bytes(const unsigned char *data, size_t n, const char *path, lu_grid *g, lu_error *err) {
    if (!write_all(path, data, n)) return LU_ERR_IO;
    return load_nvdb_dense(path, NULL, g, err);
}

static bool msg_has_offset(const lu_error *err, const char *path, unsigned long long off) {
    char want[64];
    snprintf(want, sizeof want, "byte offset %llu", off);
    return strstr(err->message, path) && strstr(err->message, want);
}

static void test_nvdb_malformed(void) {
    char good[256], bad[256];
    tmp_path(good, sizeof good, "good.nvdb");
    tmp_path(bad, sizeof bad, "bad.nvdb");
    lu_error err = {0};
    lu_grid g = make_dusty(12, 10, 8), h;
    CHECK_OK(lu_grid_save_nvdb(&g, good, &err), &err);
    unsigned char *file = NULL;
    size_t n = 0;
    CHECK(read_all(good, &file, &n));
    unsigned char *copy = malloc(n);
    size_t data = grid_data_offset(file);

    /* Truncations: inside the header, the metadata, the name, the grid. */
    CHECK(load_bytes(file, 10, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, 0), "%s", err.message);
    CHECK(load_bytes(file, 100, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, 16), "%s", err.message);
    CHECK(load_bytes(file, 16 + 176 + 1, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, 16 + 176), "%s", err.message);
    CHECK(load_bytes(file, n - 1, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, data), "%s", err.message);
    CHECK(strstr(err.message, "truncated") != NULL);
    CHECK(load_bytes(file, 0, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(h.data == NULL);

    /* Bad magic, at offset 0. */
    memcpy(copy, file, n);
    copy[0] = 'X';
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(msg_has_offset(&err, bad, 0) && strstr(err.message, "magic"));
    /* Garbage. */
    uint32_t s = 99;
    for (size_t i = 0; i < n; i++) copy[i] = (unsigned char)((s = s * 1103515245u + 12345u) >> 24);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(msg_has_offset(&err, bad, 0));
    /* A second segment that is garbage after a valid one. */
    unsigned char *two = malloc(n + 40);
    memcpy(two, file, n);
    memset(two + n, 0x41, 40);
    CHECK(load_bytes(two, n + 40, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(msg_has_offset(&err, bad, n));
    free(two);
    /* BLOSC codec: refused with a clear message. */
    memcpy(copy, file, n);
    put16(copy + 14, 2);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "BLOSC") && strstr(err.message, bad));
    /* Unknown codec, other major version, zero grids. */
    memcpy(copy, file, n);
    put16(copy + 14, 7);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(msg_has_offset(&err, bad, 14));
    memcpy(copy, file, n);
    put32(copy + 8, (31u << 21) | (2u << 10));
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "31.2.0") != NULL);
    memcpy(copy, file, n);
    put16(copy + 12, 0);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    /* Grid size fields that disagree or are absurd. */
    memcpy(copy, file, n);
    put64(copy + 16, get64(copy + 16) + 8);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    memcpy(copy, file, n);
    put64(copy + 16 + 8, UINT64_MAX - 4);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(strstr(err.message, "truncated") != NULL);
    memcpy(copy, file, n);
    put32(copy + 16 + 136, 0xFFFFFFFFu);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK(msg_has_offset(&err, bad, 16 + 136));
    /* Header checksum: a changed world bbox (grid byte 560) is detected. */
    memcpy(copy, file, n);
    copy[data + 560 + 3] ^= 0x10;
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, data + 8) && strstr(err.message, "checksum"), "%s", err.message);
    /* A child pointer in a lower node sent outside the grid: named by the
     * file offset of the pointer. Tree at grid byte 672; lower nodes at
     * tree + node_offset_lower; child mask at +544, table at +1088. */
    memcpy(copy, file, n);
    size_t tree = data + 672, lower = tree + get64(copy + tree + 8);
    uint32_t first = 0;
    while (first < 4096 && !((get32(copy + lower + 544 + 4 * (first / 32)) >> (first % 32)) & 1u)) first++;
    CHECK(first < 4096);
    size_t slot = lower + 1088 + 8 * (size_t)first;
    put64(copy + slot, 0x7000000000000000ull);
    CHECK(load_bytes(copy, n, bad, &h, &err) == LU_ERR_FORMAT);
    CHECK_MSG(msg_has_offset(&err, bad, slot) && strstr(err.message, "child pointer"), "%s", err.message);
    /* Nonexistent file. */
    CHECK(load_nvdb_dense("does/not/exist.nvdb", NULL, &h, &err) == LU_ERR_IO);

    /* Random byte flips: always a clean result, never a crash (ASan). */
    int ok = 0, failed = 0;
    for (int trial = 0; trial < 200; trial++) {
        memcpy(copy, file, n);
        int flips = 1 + trial % 4;
        for (int f = 0; f < flips; f++) {
            s = s * 1103515245u + 12345u;
            size_t at = (size_t)(s >> 4) % n;
            s = s * 1103515245u + 12345u;
            copy[at] ^= (unsigned char)(1u << ((s >> 20) & 7u));
        }
        lu_result r = load_nvdb_memory_dense(copy, n, "flip", NULL, &h, &err);
        if (r == LU_OK) {
            ok++;
            bool valid = true;
            for (size_t i = 0; i < (size_t)h.nx * h.ny * h.nz; i++) valid = valid && isfinite(h.data[i]) && h.data[i] >= 0;
            CHECK(valid);
            lu_grid_destroy(&h);
        } else {
            failed++;
            CHECK(r > LU_OK && r < LU_ERR_COUNT && strstr(err.message, "flip"));
        }
        /* The sparse load checks the same values in the tree: the same answer,
         * and every voxel it reads valid. */
        lu_grid t;
        lu_result rs = lu_grid_load_nvdb_memory(copy, n, "flip", NULL, &t, &err);
        CHECK_MSG(rs == r || (r == LU_ERR_LIMIT && rs == LU_OK), "dense %s, sparse %s", lu_result_name(r),
                  lu_result_name(rs));
        if (rs == LU_OK) {
            /* A flip may widen the box far beyond the file's grid: every
             * voxel of a small box, else a lattice of 2^18 through it. */
            bool valid = true;
            int step[3] = {1, 1, 1}, n3[3] = {t.nx, t.ny, t.nz};
            for (int a = 0; a < 3; a++)
                while (n3[a] / step[a] > 64) step[a] *= 2;
            for (int z = 0; z < t.nz; z += step[2])
                for (int y = 0; y < t.ny; y += step[1])
                    for (int x = 0; x < t.nx && valid; x += step[0]) {
                        float v = lu_grid_at(&t, x, y, z);
                        valid = isfinite(v) && v >= 0.0f;
                    }
            CHECK(valid);
            lu_grid_destroy(&t);
        }
    }
    CHECK(ok + failed == 200 && failed > 0);
    free(copy);
    free(file);
    lu_grid_destroy(&g);
    remove(good);
    remove(bad);
}

static void test_nvdb_types(void) {
    char path[256];
    tmp_path(path, sizeof path, "types.nvdb");
    lu_error err = {0};
    lu_grid h;
    const int32_t ijk[3][3] = {{-5, -3, -20}, {2, 4, 1}, {0, 0, 0}};
    const float vals[3] = {1.5f, 2.5f, 0.25f};
    lu_nvdb_sparse grids[2] = {
        {.name = "velocity", .type = LU_NVDB_VEC3F, .count = 3, .ijk = ijk, .values = vals, .voxel_size = 0.5},
        {.name = "density", .type = LU_NVDB_FLOAT, .count = 3, .ijk = ijk, .values = vals, .voxel_size = 0.5},
    };
    /* Two grids in one file: the first Float grid is picked; names select. */
    CHECK_OK(lu_nvdb_save_sparse(path, grids, 2, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK_OK(load_nvdb_dense(path, NULL, &h, &err), &err);
    CHECK(strcmp(h.name, "density") == 0);
    /* Active box [-5,2] x [-3,4] x [-20,1]; the map puts index 0 at -5*0.5 etc. */
    CHECK(h.nx == 8 && h.ny == 8 && h.nz == 22);
    CHECK(lu_grid_at(&h, 0, 0, 0) == 1.5f && lu_grid_at(&h, 7, 7, 21) == 2.5f && lu_grid_at(&h, 5, 3, 20) == 0.25f);
    double sum = 0;
    for (size_t i = 0; i < (size_t)h.nx * h.ny * h.nz; i++) sum += h.data[i];
    CHECK_NEAR(sum, 4.25, 0.0);
    CHECK(h.index_to_world.m[0][0] == 0.5f && h.index_to_world.m[0][3] == -2.5f &&
          h.index_to_world.m[1][3] == -1.5f && h.index_to_world.m[2][3] == -10.0f);
    lu_grid_destroy(&h);
    CHECK(load_nvdb_dense(path, "velocity", &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "Vec3f") && strstr(err.message, path));
    CHECK(load_nvdb_dense(path, "nope", &h, &err) == LU_ERR_INVALID_ARG);
    CHECK(strstr(err.message, "velocity") && strstr(err.message, "density"));
    /* Only non-float grids. */
    grids[1].type = LU_NVDB_DOUBLE;
    CHECK_OK(lu_nvdb_save_sparse(path, grids, 2, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "Double") != NULL);
    CHECK(load_nvdb_dense(path, "density", &h, &err) == LU_ERR_UNSUPPORTED);
    /* Float grids the density convention cannot take. */
    grids[1].type = LU_NVDB_FLOAT;
    grids[1].background = 0.5f;
    CHECK_OK(lu_nvdb_save_sparse(path, grids + 1, 1, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_UNSUPPORTED);
    CHECK(strstr(err.message, "background") != NULL);
    grids[1].background = 0.0f;
    const float negative[3] = {1.0f, -2.0f, 1.0f}, nan3[3] = {1.0f, NAN, 1.0f};
    grids[1].values = negative;
    CHECK_OK(lu_nvdb_save_sparse(path, grids + 1, 1, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_RANGE);
    CHECK(strstr(err.message, "(2,4,1)") != NULL);
    grids[1].values = nan3;
    CHECK_OK(lu_nvdb_save_sparse(path, grids + 1, 1, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_NONFINITE);
    /* Past LU_MAX_GRID_VOXELS: 601^3 dense voxels from two active ones. */
    const int32_t far[2][3] = {{0, 0, 0}, {600, 600, 600}};
    grids[1].ijk = far;
    grids[1].values = vals;
    grids[1].count = 2;
    CHECK_OK(lu_nvdb_save_sparse(path, grids + 1, 1, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_LIMIT);
    CHECK(strstr(err.message, path) != NULL);
    /* No active voxels at all. */
    grids[1].count = 0;
    CHECK_OK(lu_nvdb_save_sparse(path, grids + 1, 1, LU_NVDB_CODEC_NONE, &err), &err);
    CHECK(load_nvdb_dense(path, NULL, &h, &err) == LU_ERR_UNSUPPORTED);
    /* The writer refuses what the reader would refuse. */
    lu_grid g;
    CHECK_OK(lu_grid_alloc(&g, 2, 2, 2, &err), &err);
    g.data[3] = -1.0f;
    CHECK(lu_grid_save_nvdb(&g, path, &err) == LU_ERR_RANGE);
    g.data[3] = INFINITY;
    CHECK(lu_grid_save_nvdb(&g, path, &err) == LU_ERR_NONFINITE);
    g.data[3] = 1.0f;
    g.index_to_world.m[1][1] = 0.0f;
    CHECK(lu_grid_save_nvdb(&g, path, &err) == LU_ERR_INVALID_ARG);
    g.index_to_world.m[1][1] = 1.0f;
    CHECK(lu_grid_save_nvdb(&g, "no/such/dir/x.nvdb", &err) == LU_ERR_IO);
    lu_grid_destroy(&g);
    remove(path);
}

/* ---- procedural ----------------------------------------------------------------- */

static lu_result gen(const char *name, lu_grid *g, lu_error *err, const char *assignments) {
    lu_kvlist kv = {0};
    char buf[512];
    snprintf(buf, sizeof buf, "%s", assignments ? assignments : "");
    lu_result r = LU_OK;
    for (char *save = NULL, *tok = strtok_r(buf, " ", &save); tok && r == LU_OK; tok = strtok_r(NULL, " ", &save))
        r = lu_kv_parse_assignment(&kv, tok, err);
    if (r == LU_OK) r = lu_grid_procedural(name, &kv, g, "$.media[0].density", err);
    lu_kv_free(&kv);
    return r;
}

static double grid_sum(const lu_grid *g) {
    double s = 0;
    for (size_t i = 0; i < (size_t)g->nx * g->ny * g->nz; i++) s += g->data[i];
    return s;
}

static void test_proc_box(void) {
    lu_error err = {0};
    lu_grid g;
    CHECK_OK(gen("uniform_box", &g, &err, "value=2.5 resolution=8,4,2 size=4,2,1 center=1,2,3"), &err);
    CHECK(g.nx == 8 && g.ny == 4 && g.nz == 2);
    CHECK(g.min_value == 2.5f && g.max_value == 2.5f);
    /* h = 0.5 on every axis; voxel 0 centre = lo + h/2. */
    lu_vec3 c0 = lu_affine_point(&g.index_to_world, lu_v3(0, 0, 0));
    lu_vec3 c1 = lu_affine_point(&g.index_to_world, lu_v3(7, 3, 1));
    CHECK(c0.x == -0.75f && c0.y == 1.25f && c0.z == 2.75f);
    CHECK(c1.x == 2.75f && c1.y == 2.75f && c1.z == 3.25f);
    CHECK(strcmp(g.name, "uniform_box") == 0);
    lu_grid_destroy(&g);
    /* One number: longest side, others in proportion; default 64. */
    CHECK_OK(gen("uniform_box", &g, &err, "size=2,1,0.5 resolution=64"), &err);
    CHECK(g.nx == 64 && g.ny == 32 && g.nz == 16);
    lu_grid_destroy(&g);
    CHECK_OK(gen("uniform_box", &g, &err, NULL), &err);
    CHECK(g.nx == 64 && g.ny == 64 && g.nz == 64 && g.min_value == 1.0f);
    lu_grid_destroy(&g);
}

static void test_proc_sphere(void) {
    lu_error err = {0};
    lu_grid g;
    /* Each voxel holds value * clamp(0.5 - (d - r)/h): the continuous
     * integral of that ramp profile is V + pi r h^2 / 3 (relative excess
     * h^2/(4 r^2)). What remains is the lattice (midpoint) sampling error of
     * a surface smoothed over one voxel, of the same order h^2/r^2; the
     * tolerance is that first-order term h^2/(4 r^2) itself. */
    const int res[2] = {32, 64};
    for (int k = 0; k < 2; k++) {
        char a[128];
        snprintf(a, sizeof a, "radius=0.8 value=1.5 resolution=%d", res[k]);
        CHECK_OK(gen("sphere", &g, &err, a), &err);
        double h = 2.0 / res[k], r = 0.8;
        double v = grid_sum(&g) * h * h * h / 1.5;
        double exact = 4.0 / 3.0 * M_PI * r * r * r, ramp = M_PI * r * h * h / 3.0;
        CHECK_REL(v, exact + ramp, h * h / (4 * r * r));
        CHECK(g.max_value == 1.5f && g.min_value == 0.0f);
        /* Centre full, corners empty. */
        CHECK(lu_grid_at(&g, g.nx / 2, g.ny / 2, g.nz / 2) == 1.5f && lu_grid_at(&g, 0, 0, 0) == 0.0f);
        lu_grid_destroy(&g);
    }
}

static void test_proc_gaussians(void) {
    lu_error err = {0};
    lu_grid g;
    /* Three Gaussians of sigma 0.08, centres >= 0.3 from the walls (3.75
     * sigma, < 1e-3 of the mass outside); at h = sigma/2.56 the lattice sum
     * of a Gaussian equals its integral to ~exp(-2 pi^2 sigma^2/h^2).
     * Total = 3 * A * (2 pi)^(3/2) sigma^3. */
    CHECK_OK(gen("gaussians", &g, &err, "count=3 sigma=0.08 amplitude=2 seed=7"), &err);
    double h = 2.0 / 64, s = 0.08;
    CHECK_REL(grid_sum(&g) * h * h * h, 3 * 2.0 * pow(2 * M_PI, 1.5) * s * s * s, 1e-3);
    lu_grid a;
    CHECK_OK(gen("gaussians", &a, &err, "count=3 sigma=0.08 amplitude=2 seed=7"), &err);
    CHECK(same_grid_values(&g, &a));
    lu_grid_destroy(&a);
    CHECK_OK(gen("gaussians", &a, &err, "count=3 sigma=0.08 amplitude=2 seed=8"), &err);
    CHECK(!same_grid_values(&g, &a));
    lu_grid_destroy(&a);
    lu_grid_destroy(&g);
    CHECK(gen("gaussians", &g, &err, "sigma=0.3,0.1") == LU_ERR_RANGE);
    CHECK(gen("gaussians", &g, &err, "sigma=0.1,0.2,0.3") == LU_ERR_SCENE);
    CHECK(gen("gaussians", &g, &err, "count=2.5") == LU_ERR_RANGE);
}

static void test_proc_layered(void) {
    lu_error err = {0};
    lu_grid g;
    /* 4 layers along y on 64 rows: 16 rows each, exactly low/high/low/high. */
    CHECK_OK(gen("layered_cube", &g, &err, "layers=4 low=0.2 high=1 axis=1 resolution=64"), &err);
    bool ok = true;
    for (int y = 0; y < 64; y++) {
        float want = (y / 16) % 2 == 0 ? 0.2f : 1.0f;
        for (int z = 0; z < 64; z += 9)
            for (int x = 0; x < 64; x += 7) ok = ok && fabsf(lu_grid_at(&g, x, y, z) - want) < 1e-6f;
    }
    CHECK(ok);
    lu_grid_destroy(&g);
    /* 3 layers on 10 voxels along x: boundaries cut voxels 3 and 6; the box
     * filter keeps the integral exact: mean = (2 low + high) / 3. */
    CHECK_OK(gen("layered_cube", &g, &err, "layers=3 low=0.5 high=2 axis=0 resolution=10,2,2"), &err);
    CHECK_NEAR(grid_sum(&g) / 40.0, (2 * 0.5 + 2.0) / 3.0, 1e-6);
    CHECK_NEAR(lu_grid_at(&g, 3, 0, 0), (2.0 / 3.0) * 2.0 + (1.0 / 3.0) * 0.5, 1e-6);
    CHECK_NEAR(lu_grid_at(&g, 0, 1, 1), 0.5, 1e-6);
    lu_grid_destroy(&g);
    CHECK(gen("layered_cube", &g, &err, "axis=3") == LU_ERR_RANGE);
}

static void test_proc_torus(void) {
    lu_error err = {0};
    lu_grid g;
    /* Missing density = torus volume 2 pi^2 R r^2 plus the ramp term
     * pi^2 R h^2 / 6 (Pappus on the ramped disc pi r^2 + pi h^2 / 12).
     * Tolerance h^2/r^2: the lattice error of a one-voxel-smoothed surface
     * is of that order relative to the enclosed volume. */
    CHECK_OK(gen("torus_in_cube", &g, &err, "value=1 major_radius=0.5 minor_radius=0.18 resolution=64"), &err);
    double h = 2.0 / 64, R = 0.5, r = 0.18;
    double missing = (64.0 * 64 * 64 - grid_sum(&g)) * h * h * h;
    CHECK_REL(missing, 2 * M_PI * M_PI * R * r * r + M_PI * M_PI * R * h * h / 6, h * h / (r * r));
    /* Centre of the hole and the cube corners are full; the tube core empty.
     * Voxel 47 along x has its centre at x = 0.484, 0.016 from the core. */
    CHECK(lu_grid_at(&g, 32, 32, 32) == 1.0f && lu_grid_at(&g, 0, 0, 0) == 1.0f);
    CHECK(lu_grid_at(&g, 47, 31, 32) == 0.0f && lu_grid_at(&g, 32, 32, 47) == 0.0f);
    lu_grid_destroy(&g);
}

static void test_proc_dusty(void) {
    lu_error err = {0};
    lu_grid g;
    /* Without noise: exactly bottom + (top - bottom) (j + 0.5) / ny per row. */
    CHECK_OK(gen("dusty_room", &g, &err, "noise=0"), &err);
    bool exact = true;
    for (int y = 0; y < 64; y++)
        exact = exact && fabs(lu_grid_at(&g, 5, y, 9) - (0.6 + (0.3 - 0.6) * (y + 0.5) / 64)) < 1e-6;
    CHECK(exact);
    lu_grid_destroy(&g);
    /* With the default noise 0.15 x fBm (std ~0.2, about (2 x 3)^2 = 36
     * independent features per row plane at frequency 3 over 2 units) a
     * row mean strays by ~0.15 * 0.2 / 6 = 0.005: rows within 0.03 (6 sigma),
     * and the least-squares line over the 64 rows is 0.6 -> 0.3. */
    CHECK_OK(gen("dusty_room", &g, &err, NULL), &err);
    double sx = 0, sy = 0, sxx = 0, sxy = 0, worst = 0;
    for (int y = 0; y < 64; y++) {
        double m = 0;
        for (int z = 0; z < 64; z++)
            for (int x = 0; x < 64; x++) m += lu_grid_at(&g, x, y, z);
        m /= 64 * 64;
        double t = (y + 0.5) / 64, want = 0.6 - 0.3 * t;
        if (fabs(m - want) > worst) worst = fabs(m - want);
        sx += t, sy += m, sxx += t * t, sxy += t * m;
    }
    double slope = (64 * sxy - sx * sy) / (64 * sxx - sx * sx), icpt = (sy - slope * sx) / 64;
    CHECK_NEAR(worst, 0.0, 0.03);
    CHECK_NEAR(icpt, 0.6, 0.01);
    CHECK_NEAR(icpt + slope, 0.3, 0.01);
    CHECK(g.min_value >= 0.0f && g.max_value > 0.6f);
    lu_grid_destroy(&g);
}

static void test_proc_cloud_plume(void) {
    lu_error err = {0};
    lu_grid g;
    CHECK_OK(gen("fbm_cloud", &g, &err, "radius=0.7 resolution=48"), &err);
    /* Zero beyond the radius (voxel centres farther than 0.7), some cloud inside, <= 1. */
    bool outside_zero = true;
    double inside = 0;
    for (int z = 0; z < 48; z++)
        for (int y = 0; y < 48; y++)
            for (int x = 0; x < 48; x++) {
                lu_vec3 p = lu_affine_point(&g.index_to_world, lu_v3((float)x, (float)y, (float)z));
                float v = lu_grid_at(&g, x, y, z);
                if (lu_v3_len(p) >= 0.7f) outside_zero = outside_zero && v == 0.0f;
                else inside += v > 0.0f;
            }
    CHECK(outside_zero);
    CHECK(inside > 1000 && g.max_value <= 1.0f && g.max_value > 0.3f);
    lu_grid_destroy(&g);

    CHECK_OK(gen("smoke_plume", &g, &err, "resolution=48"), &err);
    /* Mass centred on the vertical axis; densest near the source (lower
     * half), thinner as the column widens; the top and the source rows
     * fade to nothing. */
    double m = 0, mx = 0, mz = 0, peak_low = 0, peak_high = 0, floor_row = 0;
    for (int z = 0; z < 48; z++)
        for (int y = 0; y < 48; y++)
            for (int x = 0; x < 48; x++) {
                double v = lu_grid_at(&g, x, y, z);
                m += v, mx += v * (x - 23.5), mz += v * (z - 23.5);
                if (y < 24) peak_low = fmax(peak_low, v);
                else peak_high = fmax(peak_high, v);
                if (y == 0 || y == 47) floor_row = fmax(floor_row, v);
            }
    CHECK_MSG(m > 0 && fabs(mx / m) < 48 * 0.1 && fabs(mz / m) < 48 * 0.1, "%g %g %g", m, mx / m, mz / m);
    CHECK_MSG(peak_low > 1.5 * peak_high && floor_row < 0.2 * peak_low, "%g %g %g", peak_low, peak_high, floor_row);
    CHECK(lu_grid_at(&g, 0, 0, 0) < 1e-3f && g.min_value >= 0.0f);
    lu_grid_destroy(&g);
}

static void test_proc_determinism(void) {
    const char *names[] = {"fbm_cloud", "gaussians", "dusty_room", "smoke_plume"};
    lu_error err = {0};
    for (int i = 0; i < 4; i++) {
        lu_grid a, b, c;
        lu_set_thread_count(1, NULL);
        CHECK_OK(gen(names[i], &a, &err, "seed=3 resolution=32"), &err);
        lu_set_thread_count(3, NULL);
        CHECK_OK(gen(names[i], &b, &err, "seed=3 resolution=32"), &err);
        CHECK_OK(gen(names[i], &c, &err, "seed=4 resolution=32"), &err);
        CHECK_MSG(same_grid_values(&a, &b), "%s not deterministic", names[i]);
        CHECK_MSG(!same_grid_values(&a, &c), "%s ignores its seed", names[i]);
        lu_grid_destroy(&a);
        lu_grid_destroy(&b);
        lu_grid_destroy(&c);
    }
    lu_set_thread_count(0, NULL);
}

static void test_proc_errors(void) {
    lu_error err = {0};
    lu_grid g;
    CHECK(gen("cloudy", &g, &err, NULL) == LU_ERR_SCENE);
    CHECK(strstr(err.message, "$.media[0].density") && strstr(err.message, "cloudy") &&
          strstr(err.message, "smoke_plume"));
    CHECK(g.data == NULL);
    CHECK(gen("sphere", &g, &err, "radius=0.5 radiuss=1") == LU_ERR_SCENE);
    CHECK(strstr(err.message, "$.media[0].density") && strstr(err.message, "radiuss"));
    CHECK(gen("sphere", &g, &err, "radius=-1") == LU_ERR_RANGE);
    CHECK(strstr(err.message, "radius") != NULL);
    CHECK(gen("sphere", &g, &err, "radius=big") == LU_ERR_SCENE);
    CHECK(gen("uniform_box", &g, &err, "resolution=2.5") == LU_ERR_RANGE);
    CHECK(gen("uniform_box", &g, &err, "resolution=8,8") == LU_ERR_SCENE);
    CHECK(gen("uniform_box", &g, &err, "resolution=0") == LU_ERR_RANGE);
    CHECK(gen("uniform_box", &g, &err, "resolution=4096") == LU_ERR_LIMIT);
    CHECK(strstr(err.message, "$.media[0].density") != NULL);
    CHECK(gen("uniform_box", &g, &err, "size=1,0,1") == LU_ERR_RANGE);
    CHECK(gen("fbm_cloud", &g, &err, "octaves=40") == LU_ERR_RANGE);
    CHECK(gen("dusty_room", &g, &err, "seed=-1") == LU_ERR_RANGE);
    CHECK(lu_grid_procedural(NULL, NULL, &g, NULL, &err) == LU_ERR_SCENE);
    CHECK_OK(lu_grid_procedural("sphere", NULL, &g, NULL, &err), &err);
    lu_grid_destroy(&g);
}

static void test_noise(void) {
    /* Gradient noise is exactly 0 on the lattice. */
    bool zero = true;
    for (int i = -3; i <= 3; i++) zero = zero && lu_noise3(i, 2 * i, -i + 7, 5u) == 0.0f;
    CHECK(zero);
    double lo = 1, hi = -1, sum = 0, sum2 = 0, jump = 0;
    int n = 0;
    for (int i = 0; i < 40; i++)
        for (int j = 0; j < 40; j++)
            for (int k = 0; k < 40; k++) {
                double x = i * 0.173, y = j * 0.119, z = k * 0.231;
                float v = lu_noise3(x, y, z, 11u);
                lo = fmin(lo, v), hi = fmax(hi, v), sum += v, sum2 += (double)v * v, n++;
                /* Continuity: the gradient is bounded (|grad| <= ~3), so a
                 * 1e-4 step moves the value by well under 1e-3. */
                jump = fmax(jump, fabs(lu_noise3(x + 1e-4, y, z, 11u) - v));
            }
    CHECK(lo >= -1 && hi <= 1 && lo < -0.4 && hi > 0.4);
    CHECK_NEAR(sum / n, 0.0, 0.02);
    CHECK(sqrt(sum2 / n) > 0.15);
    CHECK(jump < 1e-3);
    CHECK(lu_noise3(0.3, 0.4, 0.5, 1u) == lu_noise3(0.3, 0.4, 0.5, 1u));
    CHECK(lu_noise3(0.3, 0.4, 0.5, 1u) != lu_noise3(0.3, 0.4, 0.5, 2u));
    float f = lu_fbm3(0.3, 0.4, 0.5, 5, 0.5, 1u);
    CHECK(f >= -1 && f <= 1 && f != 0.0f);
    /* Not periodic over 256 like a permutation-table Perlin noise. */
    CHECK(lu_noise3(0.3, 0.4, 0.5, 1u) != lu_noise3(256.3, 0.4, 0.5, 1u));
}

int main(void) {
    RUN_TEST(test_alloc);
    RUN_TEST(test_sample);
    RUN_TEST(test_raw);
    RUN_TEST(test_nvdb_roundtrip);
    RUN_TEST(test_nvdb_crop);
    RUN_TEST(test_nvdb_tiles);
    RUN_TEST(test_nvdb_zip);
    RUN_TEST(test_nvdb_converted);
    RUN_TEST(test_nvdb_malformed);
    RUN_TEST(test_nvdb_types);
    RUN_TEST(test_proc_box);
    RUN_TEST(test_proc_sphere);
    RUN_TEST(test_proc_gaussians);
    RUN_TEST(test_proc_layered);
    RUN_TEST(test_proc_torus);
    RUN_TEST(test_proc_dusty);
    RUN_TEST(test_proc_cloud_plume);
    RUN_TEST(test_proc_determinism);
    RUN_TEST(test_proc_errors);
    RUN_TEST(test_noise);
    TEST_EXIT();
}
