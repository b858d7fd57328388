/* The density-edit API (grid.h "edits", lu_scene_medium_grid): an edit then
 * trilinear sampling gives the edited field in closed form (trilinear
 * interpolation reproduces a multilinear function exactly), the range and the
 * change stamps follow, and rejected edits leave the grid untouched. */
#include <lucent/lucent.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "lu_test.h"

enum { NX = 5, NY = 6, NZ = 7 };

static double linear(double x, double y, double z) { return 1.0 + x + 2.0 * y + 3.0 * z; }

static void fill_linear(float *v) {
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) v[(z * NY + y) * NX + x] = (float)linear(x, y, z);
}

static float add_five(void *ctx, int x, int y, int z, float value) {
    (void)ctx, (void)x, (void)y, (void)z;
    return value + 5.0f;
}

/* Replaces the box's values with 2 x y z: the edited field is then again
 * multilinear inside the box. */
static float set_xyz(void *ctx, int x, int y, int z, float value) {
    int *calls = ctx;
    (*calls)++;
    (void)value;
    return (float)(2 * x * y * z);
}

static float to_zero(void *ctx, int x, int y, int z, float value) {
    (void)ctx, (void)x, (void)y, (void)z, (void)value;
    return 0.0f;
}

/* Leaves every voxel alone except one, which becomes *(float *)ctx. */
static float poison_2_3_4(void *ctx, int x, int y, int z, float value) {
    return x == 2 && y == 3 && z == 4 ? *(const float *)ctx : value + 1.0f;
}

static void test_set_values(void) {
    lu_grid g;
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(&g, NX, NY, NZ, &err), &err);
    uint64_t gen0 = g.generation;
    CHECK(gen0 > 0 && g.prev_generation == 0);
    float v[NX * NY * NZ];
    fill_linear(v);
    CHECK_OK(lu_grid_set_values(&g, v, NX * NY * NZ, &err), &err);
    CHECK(g.generation > gen0 && g.prev_generation == gen0);
    CHECK(g.edit_lo[0] == 0 && g.edit_lo[1] == 0 && g.edit_lo[2] == 0);
    CHECK(g.edit_hi[0] == NX && g.edit_hi[1] == NY && g.edit_hi[2] == NZ);
    CHECK(g.min_value == 1.0f && g.max_value == (float)linear(NX - 1, NY - 1, NZ - 1));
    /* Interior points between voxel centres: trilinear = the linear function. */
    const float pts[][3] = {{0.25f, 0.5f, 0.75f}, {3.9f, 4.1f, 5.5f}, {1.5f, 2.5f, 3.5f}};
    for (int i = 0; i < 3; i++)
        CHECK_NEAR(lu_grid_sample(&g, lu_v3(pts[i][0], pts[i][1], pts[i][2])), linear(pts[i][0], pts[i][1], pts[i][2]),
                   1e-4);
    lu_grid_destroy(&g);
}

static void test_apply(void) {
    lu_grid g;
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(&g, NX, NY, NZ, &err), &err);
    float v[NX * NY * NZ];
    fill_linear(v);
    CHECK_OK(lu_grid_set_values(&g, v, NX * NY * NZ, &err), &err);

    /* +5 on the box [1,4) x [2,5) x [0,3): inside the box (between centres that
     * are all edited) the field is linear + 5; outside, untouched. */
    uint64_t gen1 = g.generation;
    const int lo[3] = {1, 2, 0}, hi[3] = {4, 5, 3};
    CHECK_OK(lu_grid_apply(&g, lo, hi, add_five, NULL, &err), &err);
    CHECK(g.generation > gen1 && g.prev_generation == gen1);
    CHECK(memcmp(g.edit_lo, lo, sizeof lo) == 0 && memcmp(g.edit_hi, hi, sizeof hi) == 0);
    CHECK_NEAR(lu_grid_sample(&g, lu_v3(2.3f, 3.6f, 1.2f)), linear(2.3, 3.6, 1.2) + 5.0, 1e-4);
    CHECK_NEAR(lu_grid_sample(&g, lu_v3(2.3f, 3.6f, 4.2f)), linear(2.3, 3.6, 4.2), 1e-4);
    /* Half-way between an edited centre (3,3,1) and an unedited one (4,3,1). */
    CHECK_NEAR(lu_grid_sample(&g, lu_v3(3.5f, 3.0f, 1.0f)), linear(3.5, 3, 1) + 2.5, 1e-4);
    /* The box did not hold the maximum: the range only grows if needed. */
    CHECK(g.max_value == (float)linear(NX - 1, NY - 1, NZ - 1) && g.min_value == 1.0f);

    /* 2xyz on the box [0,5) x [0,6) x [4,7): multilinear, reproduced exactly. */
    int calls = 0;
    const int lo2[3] = {0, 0, 4}, hi2[3] = {NX, NY, NZ};
    CHECK_OK(lu_grid_apply(&g, lo2, hi2, set_xyz, &calls, &err), &err);
    CHECK(calls == NX * NY * 3);
    CHECK_NEAR(lu_grid_sample(&g, lu_v3(1.7f, 2.2f, 5.4f)), 2.0 * 1.7 * 2.2 * 5.4, 1e-3);
    /* The box held the old maximum and lowered it: a rescan gives 2*4*5*6. */
    CHECK(g.max_value == 240.0f);
    CHECK(g.min_value == 0.0f);

    /* Zeroing the only voxels at the maximum lowers it to the next largest. */
    const int lo3[3] = {NX - 1, NY - 1, NZ - 1}, hi3[3] = {NX, NY, NZ};
    CHECK_OK(lu_grid_apply(&g, lo3, hi3, to_zero, NULL, &err), &err);
    CHECK(g.max_value == 2.0f * 4 * 5 * 5);
    lu_grid_destroy(&g);
}

static void test_rejected(void) {
    lu_grid g;
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(&g, NX, NY, NZ, &err), &err);
    snprintf(g.name, sizeof g.name, "fog");
    float v[NX * NY * NZ];
    fill_linear(v);
    CHECK_OK(lu_grid_set_values(&g, v, NX * NY * NZ, &err), &err);
    uint64_t gen = g.generation;
    float before[NX * NY * NZ];
    memcpy(before, g.data, sizeof before);

    const int lo[3] = {0, 0, 0}, hi[3] = {NX, NY, NZ};
    float bad = NAN;
    CHECK(lu_grid_apply(&g, lo, hi, poison_2_3_4, &bad, &err) == LU_ERR_NONFINITE);
    CHECK_MSG(strstr(err.message, "(2, 3, 4)") && strstr(err.message, "fog"), "%s", err.message);
    bad = -0.5f;
    CHECK(lu_grid_apply(&g, lo, hi, poison_2_3_4, &bad, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "(2, 3, 4)") && strstr(err.message, "-0.5"), "%s", err.message);
    const int empty_hi[3] = {0, NY, NZ}, over_hi[3] = {NX + 1, NY, NZ}, neg_lo[3] = {-1, 0, 0};
    CHECK(lu_grid_apply(&g, lo, empty_hi, add_five, NULL, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_apply(&g, lo, over_hi, add_five, NULL, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_apply(&g, neg_lo, hi, add_five, NULL, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_apply(&g, lo, hi, NULL, NULL, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_grid_set_values(&g, v, NX * NY * NZ - 1, &err) == LU_ERR_INVALID_ARG);
    CHECK_MSG(strstr(err.message, "210 voxels") != NULL, "%s", err.message);
    float w[NX * NY * NZ];
    memcpy(w, v, sizeof w);
    w[NX * NY * NZ - 1] = -1.0f;
    CHECK(lu_grid_set_values(&g, w, NX * NY * NZ, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "(4, 5, 6)") != NULL, "%s", err.message);
    w[NX * NY * NZ - 1] = INFINITY;
    CHECK(lu_grid_set_values(&g, w, NX * NY * NZ, &err) == LU_ERR_NONFINITE);
    CHECK(lu_grid_set_values(&g, NULL, 0, &err) == LU_ERR_INVALID_ARG);
    /* Nothing of the above changed the grid or its stamp. */
    CHECK(memcmp(before, g.data, sizeof before) == 0);
    CHECK(g.generation == gen);
    lu_grid_destroy(&g);
}

/* A grid that replaces a destroyed one never repeats a stamp. */
static void test_stamps_unique(void) {
    lu_grid a, b;
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(&a, 2, 2, 2, &err), &err);
    CHECK_OK(lu_grid_alloc(&b, 2, 2, 2, &err), &err);
    CHECK(a.generation != b.generation);
    uint64_t old = a.generation;
    lu_grid_destroy(&a);
    CHECK_OK(lu_grid_alloc(&a, 2, 2, 2, &err), &err);
    CHECK(a.generation != old && a.generation > b.generation);
    lu_grid_destroy(&a);
    lu_grid_destroy(&b);
}

/* Scene media: a procedural grid and a voxelised one (the voxeliser builds
 * its grid itself) both carry stamps; constant media have no grid. */
static void test_scene_media(void) {
    char obj[64];
    snprintf(obj, sizeof obj, "test_grid_edit_%ld.obj", (long)getpid());
    FILE *f = fopen(obj, "w");
    CHECK(f != NULL);
    if (!f) return;
    /* A closed unit cube, outward-facing triangles. */
    fputs("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
          "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n",
          f);
    fclose(f);
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 8, "
             "\"height\": 8},"
             " \"lights\": [{\"type\": \"point\", \"position\": [2, 2, 2], \"intensity\": [1, 1, 1]}],"
             " \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"resolution\": 8}, \"sigma_s\": [1, 1, 1]},"
             "  {\"density\": {\"constant\": 0.5}, \"sigma_s\": [1, 1, 1],"
             "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [1, 1, 1]}}},"
             "  {\"density\": {\"voxelize\": \"%s\", \"resolution\": 8}, \"sigma_s\": [1, 1, 1]}]}",
             obj);
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(json, "edit.json", &s, &err), &err);
    remove(obj);
    if (err.code != LU_OK) return;
    lu_grid *g = NULL;
    CHECK_OK(lu_scene_medium_grid(&s, 0, &g, &err), &err);
    CHECK(g == &s.media[0].grid && g->generation > 0);
    CHECK(lu_scene_medium_grid(&s, 1, &g, &err) == LU_ERR_UNSUPPORTED && g == NULL);
    CHECK_MSG(strstr(err.message, "medium 1") && strstr(err.message, "constant"), "%s", err.message);
    CHECK(lu_scene_medium_grid(&s, 3, &g, &err) == LU_ERR_INVALID_ARG);
    CHECK(lu_scene_medium_grid(&s, -1, &g, &err) == LU_ERR_INVALID_ARG);
    CHECK_OK(lu_scene_medium_grid(&s, 2, &g, &err), &err);
    CHECK(g && g->generation > 0 && g->generation != s.media[0].grid.generation);
    /* An edit of a procedural grid edits its values: the uniform box is 1
     * everywhere, the edited voxel reads back what fn made of 1. */
    g = &s.media[0].grid;
    lu_aabb before = s.media[0].bounds;
    const int lo[3] = {2, 2, 2}, hi[3] = {3, 3, 3};
    CHECK_OK(lu_grid_apply(g, lo, hi, add_five, NULL, &err), &err);
    CHECK(lu_grid_sample(g, lu_v3(2, 2, 2)) == 6.0f && lu_grid_sample(g, lu_v3(3, 2, 2)) == 1.0f);
    CHECK(g->max_value == 6.0f);
    CHECK(memcmp(&before, &s.media[0].bounds, sizeof before) == 0);
    lu_scene_destroy(&s);
}

int main(void) {
    RUN_TEST(test_set_values);
    RUN_TEST(test_apply);
    RUN_TEST(test_rejected);
    RUN_TEST(test_stamps_unique);
    RUN_TEST(test_scene_media);
    TEST_EXIT();
}
