/* Scene loading: the JSON contract, strictness with JSON paths, transforms,
 * translucent objects as media, and every bundled scene. */
#include <lucent/lucent.h>

#include <dirent.h>
#include <math.h>
#include <sys/stat.h>
#include <stdio.h>
#include <string.h>

#include "lu_test.h"
#include "methods/bssrdf/bssrdf_profile.h"

#define CAMERA "\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"width\": 8, \"height\": 8}"

/* Loading must fail with `code` and a message containing every needle. */
static void expect_error(const char *json, lu_result code, const char *needle1, const char *needle2) {
    lu_scene s;
    lu_error err = {0};
    lu_result r = lu_scene_load_string(json, "bad.json", &s, &err);
    CHECK_MSG(r == code, "expected %s, got %s (%s) for %s", lu_result_name(code), lu_result_name(r), err.message, json);
    CHECK_MSG(strstr(err.message, "bad.json") != NULL, "message lacks the file: %s", err.message);
    if (needle1) CHECK_MSG(strstr(err.message, needle1) != NULL, "message lacks \"%s\": %s", needle1, err.message);
    if (needle2) CHECK_MSG(strstr(err.message, needle2) != NULL, "message lacks \"%s\": %s", needle2, err.message);
    if (r == LU_OK) lu_scene_destroy(&s);
}

static void test_strict_errors(void) {
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"intensity\": 1, \"colour\": 1}]}",
                 LU_ERR_SCENE, "$.lights[0].colour", "unknown key");
    expect_error("{" CAMERA ", \"extra\": 1}", LU_ERR_SCENE, "$.extra", NULL);
    expect_error("{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov\": 40}}", LU_ERR_SCENE,
                 "$.camera.fov", NULL);
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"area\"}]}", LU_ERR_SCENE, "$.lights[0].type", "area");
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": [0, 0], \"intensity\": 1}]}",
                 LU_ERR_SCENE, "$.lights[0].position", "3 numbers");
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": \"here\", \"intensity\": 1}]}",
                 LU_ERR_SCENE, "$.lights[0].position", NULL);
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"intensity\": 1e999}]}",
                 LU_ERR_NONFINITE, "$.lights[0].intensity", NULL);
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"intensity\": -1}]}",
                 LU_ERR_RANGE, "$.lights[0].intensity", NULL);
    expect_error("{" CAMERA ", \"lights\": [{\"type\": \"spot\", \"position\": [0,0,0], \"direction\": [0,-1,0],"
                 " \"intensity\": 1, \"inner_deg\": 30, \"outer_deg\": 20}]}",
                 LU_ERR_RANGE, "inner_deg", NULL);
    expect_error("{" CAMERA ", \"background\": [0,0,0], \"background\": [1,1,1]}", LU_ERR_SCENE, "$.background",
                 "duplicate");
    expect_error("{\"lights\": []}", LU_ERR_SCENE, "$.camera", "missing");
    expect_error("{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 5]}}", LU_ERR_SCENE, "$.camera", NULL);
    expect_error("{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"width\": 0}}", LU_ERR_RANGE,
                 "$.camera.width", NULL);
    expect_error("{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"width\": 10.5}}", LU_ERR_SCENE,
                 "$.camera.width", "integer");
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": 1}]}", LU_ERR_SCENE,
                 "$.media[0]", "boundary");
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"colour\": 2},"
                 " \"sigma_s\": 1}]}",
                 LU_ERR_SCENE, "colour", NULL);
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"procedural\": \"no_such_generator\"}, \"sigma_s\": 1}]}",
                 LU_ERR_SCENE, "no_such_generator", NULL);
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"file\": \"missing.nvdb\"}, \"sigma_s\": 1}]}", LU_ERR_IO,
                 "$.media[0].density", "missing.nvdb");
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"file\": \"missing.vdb\"}, \"sigma_s\": 1}]}", LU_ERR_IO,
                 "$.media[0].density", "missing.vdb");
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"file\": \"x.grid\"}, \"sigma_s\": 1}]}", LU_ERR_UNSUPPORTED,
                 "$.media[0].density.file", "neither a .nvdb nor a .vdb");
    expect_error("{" CAMERA ", \"objects\": [{\"mesh\": \"missing.ply\"}]}", LU_ERR_IO, "$.objects[0].mesh",
                 "missing.ply");
    expect_error("{" CAMERA ", \"objects\": [{\"mesh\": {\"procedural\": \"box\"}, \"material\": {\"type\": \"metal\"}}]}",
                 LU_ERR_SCENE, "$.objects[0].material.type", "metal");
    expect_error("{" CAMERA ", \"objects\": [{\"mesh\": {\"procedural\": \"box\"},"
                 " \"material\": {\"type\": \"translucent\", \"preset\": \"jelly\"}}]}",
                 LU_ERR_SCENE, "jelly", "marble");
    expect_error("{" CAMERA ", \"objects\": [{\"mesh\": {\"procedural\": \"box\"},"
                 " \"material\": {\"type\": \"diffuse\", \"preset\": \"marble\"}}]}",
                 LU_ERR_SCENE, "$.objects[0].material.preset", NULL);
    expect_error("{" CAMERA ", \"objects\": [{\"mesh\": {\"procedural\": \"box\"}, \"transform\": {\"scale\": 0}}]}",
                 LU_ERR_RANGE, "$.objects[0].transform.scale", NULL);
    /* Albedo + mean free path authoring. */
#define TMAT(body) "{" CAMERA ", \"objects\": [{\"mesh\": {\"procedural\": \"box\"}, \"material\": {\"type\": \"translucent\", " body "}}]}"
    expect_error(TMAT("\"subsurface_albedo\": [0.8, 0.5, 0.3]"), LU_ERR_SCENE, "$.objects[0].material.subsurface_albedo",
                 "mean_free_path_mm");
    expect_error(TMAT("\"mean_free_path_mm\": 1"), LU_ERR_SCENE, "$.objects[0].material.mean_free_path_mm",
                 "subsurface_albedo");
    expect_error(TMAT("\"subsurface_albedo\": 0.5, \"mean_free_path_mm\": 1, \"sigma_s\": 1"), LU_ERR_SCENE,
                 "$.objects[0].material.sigma_s", "not both");
    expect_error(TMAT("\"subsurface_albedo\": 0.5, \"mean_free_path_mm\": 1, \"preset\": \"marble\""), LU_ERR_SCENE,
                 "$.objects[0].material.preset", "not both");
    expect_error(TMAT("\"subsurface_albedo\": [0.5, 1.2, 0.5], \"mean_free_path_mm\": 1"), LU_ERR_RANGE,
                 "$.objects[0].material.subsurface_albedo", "element 1");
    expect_error(TMAT("\"subsurface_albedo\": [0.5, 0, 0.5], \"mean_free_path_mm\": 1"), LU_ERR_RANGE,
                 "$.objects[0].material.subsurface_albedo", "> 0");
    expect_error(TMAT("\"subsurface_albedo\": 0.5, \"mean_free_path_mm\": [1, 2, 0]"), LU_ERR_RANGE,
                 "$.objects[0].material.mean_free_path_mm", "element 2");
    expect_error(TMAT("\"subsurface_albedo\": 0.5, \"mean_free_path_mm\": [1, 2]"), LU_ERR_SCENE,
                 "$.objects[0].material.mean_free_path_mm", "3 numbers");
    expect_error(TMAT("\"subsurface_albedo\": \"pink\", \"mean_free_path_mm\": 1"), LU_ERR_SCENE,
                 "$.objects[0].material.subsurface_albedo", NULL);
#undef TMAT
    /* Syntax errors report line and column. */
    expect_error("{\n  \"camera\": {\n    \"position\": [0, 0, 5],,\n  }\n}", LU_ERR_FORMAT, "bad.json:3:", "syntax");
}

/* Emission keys under a medium: malformed input names the key, and a loaded
 * emission has the documented kind, defaults and grid. */
#define GRID_MEDIUM(EMISSION)                                                                                          \
    "{" CAMERA ", \"media\": [{\"density\": {\"procedural\": \"sphere\", \"resolution\": 8}, \"sigma_s\": 1" EMISSION "}]}"
static void test_emission_keys(void) {
    expect_error(GRID_MEDIUM(", \"emission\": {\"colour\": 1}"), LU_ERR_SCENE, "$.media[0].emission.colour",
                 "unknown key");
    expect_error(GRID_MEDIUM(", \"emission\": 3"), LU_ERR_SCENE, "$.media[0].emission", "object");
    expect_error(GRID_MEDIUM(", \"emission\": {\"scale\": -1}"), LU_ERR_RANGE, "$.media[0].emission.scale", NULL);
    expect_error(GRID_MEDIUM(", \"emission\": {\"color\": [1, 2]}"), LU_ERR_SCENE, "$.media[0].emission.color",
                 NULL);
    expect_error(GRID_MEDIUM(", \"emission\": {\"temperature_scale\": 2}"), LU_ERR_SCENE, "$.media[0].emission",
                 "need a \"temperature\"");
    expect_error(GRID_MEDIUM(", \"emission\": {\"grid\": {\"procedural\": \"sphere\", \"resolution\": 8},"
                             " \"temperature\": {\"procedural\": \"sphere\", \"resolution\": 8}}"),
                 LU_ERR_SCENE, "$.media[0].emission", "not both");
    expect_error(GRID_MEDIUM(", \"emission\": {\"temperature\": {\"constant\": 1500}}"), LU_ERR_SCENE,
                 "$.media[0].emission.temperature", "\"file\", \"raw\"");
    expect_error(GRID_MEDIUM(", \"emission\": {\"temperature\": [1]}"), LU_ERR_SCENE,
                 "$.media[0].emission.temperature", "object");
    /* Another index space: other voxels, or an offset of a fraction of a voxel (0.1 of 0.25). */
    expect_error(GRID_MEDIUM(", \"emission\": {\"temperature\": {\"procedural\": \"sphere\", \"resolution\": 9}}"),
                 LU_ERR_SCENE, "$.media[0].emission.temperature", "share one index space");
    expect_error(GRID_MEDIUM(", \"emission\": {\"grid\": {\"procedural\": \"sphere\", \"resolution\": 8,"
                             " \"center\": [0.1, 0, 0]}}"),
                 LU_ERR_SCENE, "$.media[0].emission.grid", "share one index space");
    expect_error(GRID_MEDIUM(", \"emission\": {\"temperature\": {\"file\": \"missing_t.nvdb\"}}"), LU_ERR_IO,
                 "$.media[0].emission.temperature", "missing_t.nvdb");
    expect_error("{" CAMERA ", \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": 1,"
                 " \"boundary\": {\"mesh\": {\"procedural\": \"box\"}},"
                 " \"emission\": {\"grid\": {\"procedural\": \"sphere\", \"resolution\": 8}}}]}",
                 LU_ERR_SCENE, "$.media[0].emission.grid", "constant density");

    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(GRID_MEDIUM(", \"emission\": {\"temperature\": {\"procedural\": \"sphere\","
                                              " \"resolution\": 8, \"value\": 2}, \"temperature_scale\": 1000,"
                                              " \"temperature_offset\": 0.5, \"color\": [1, 0.5, 0.25]}"),
                                  "ok.json", &s, &err),
             &err);
    if (err.code != LU_OK) return;
    const lu_medium *m = &s.media[0];
    CHECK(m->emission == LU_EMISSION_BLACKBODY);
    CHECK(m->le_scale == 1.0f && m->temp_scale == 1000.0f && m->temp_offset == 0.5f && m->le_color.y == 0.5f);
    /* At the sphere's centre the temperature grid holds 2: T' = (2 - 0.5) * 1000. */
    lu_vec3 c = lu_v3(3.5f, 3.5f, 3.5f);
    float t = lu_grid_sample(&m->emission_grid, c);
    CHECK_NEAR(t, 2.0, 1e-6);
    lu_vec3 le = lu_medium_emission(m, c), bb = lu_blackbody_rgb(1500.0f);
    CHECK_REL(le.x, bb.x, 1e-6);
    CHECK_REL(le.y, 0.5 * bb.y, 1e-6);
    CHECK_REL(le.z, 0.25 * bb.z, 1e-6);
    lu_scene_destroy(&s);
    /* Offset by whole voxels (0.5 = 2 voxels of 0.25 along x): re-embedded
     * over the density's voxels, e'(i) = e(i - 2), 0 where e has none. */
    CHECK_OK(lu_scene_load_string(GRID_MEDIUM(", \"emission\": {\"grid\": {\"procedural\": \"sphere\", \"resolution\": 8,"
                                              " \"center\": [0.5, 0, 0]}}"),
                                  "ok.json", &s, &err),
             &err);
    if (err.code != LU_OK) return;
    {
        lu_grid e = {0};
        lu_kvlist kv = {0};
        const double res = 8, center[3] = {0.5, 0, 0};
        CHECK_OK(lu_kv_set_number(&kv, "resolution", &res, 1, &err), &err);
        CHECK_OK(lu_kv_set_number(&kv, "center", center, 3, &err), &err);
        CHECK_OK(lu_grid_procedural("sphere", &kv, &e, "test", &err), &err);
        const lu_grid *g = &s.media[0].emission_grid;
        CHECK(g->nx == 8 && g->ny == 8 && g->nz == 8);
        int mismatches = 0;
        for (int z = 0; z < 8; z++)
            for (int y = 0; y < 8; y++)
                for (int x = 0; x < 8; x++) mismatches += lu_grid_at(g, x, y, z) != lu_grid_at(&e, x - 2, y, z);
        CHECK_MSG(mismatches == 0, "%d voxels differ from the shifted grid", mismatches);
        /* the shift is visible: the density sphere is centred at voxel 3.5, this one at 5.5 */
        CHECK(lu_grid_at(g, 6, 3, 3) > lu_grid_at(g, 1, 3, 3));
        lu_grid_destroy(&e);
        lu_kv_free(&kv);
    }
    lu_scene_destroy(&s);
    CHECK_OK(lu_scene_load_string(GRID_MEDIUM(", \"emission\": {}"), "ok.json", &s, &err), &err);
    if (err.code != LU_OK) return;
    CHECK(s.media[0].emission == LU_EMISSION_CONSTANT);
    CHECK(lu_medium_emission(&s.media[0], lu_v3s(0.0f)).x == 1.0f);
    lu_scene_destroy(&s);
}

/* A temperature grid from its own .nvdb file, named: its active voxels
 * extend one voxel further than the density's on every side, so it is
 * loaded over a box offset by -1 voxel and re-embedded; a file of other
 * voxels is refused. */
static void test_emission_nvdb(void) {
    char dir[512], dpath[600], tpath[600], bpath[600], json[2400];
    snprintf(dir, sizeof dir, "%s/emission_nvdb_test", LU_BINARY_DIR);
    lu_test_remove_dir(dir);
    CHECK(mkdir(dir, 0755) == 0);
    snprintf(dpath, sizeof dpath, "%s/density.nvdb", dir);
    snprintf(tpath, sizeof tpath, "%s/temperature.nvdb", dir);
    snprintf(bpath, sizeof bpath, "%s/coarse.nvdb", dir);
    lu_error err = {0};
    lu_grid d = {0}, t = {0}, b = {0};
    CHECK_OK(lu_grid_alloc(&d, 8, 8, 8, &err), &err);
    CHECK_OK(lu_grid_alloc(&t, 10, 10, 10, &err), &err);
    CHECK_OK(lu_grid_alloc(&b, 8, 8, 8, &err), &err);
    if (err.code != LU_OK) return;
    for (int i = 0; i < 512; i++) d.data[i] = 1.0f, b.data[i] = 1.0f;
    for (int z = 0; z < 10; z++)
        for (int y = 0; y < 10; y++)
            for (int x = 0; x < 10; x++) t.data[(z * 10 + y) * 10 + x] = 1000.0f + 100.0f * x + 10.0f * y + z;
    d.index_to_world = lu_affine_scale(lu_v3s(0.1f));
    lu_affine sh = lu_affine_translate(lu_v3s(-0.1f)), sc = lu_affine_scale(lu_v3s(0.1f));
    t.index_to_world = lu_affine_mul(&sh, &sc);
    b.index_to_world = lu_affine_scale(lu_v3s(0.2f));
    snprintf(t.name, sizeof t.name, "temperature");
    CHECK_OK(lu_grid_save_nvdb(&d, dpath, &err), &err);
    CHECK_OK(lu_grid_save_nvdb(&t, tpath, &err), &err);
    CHECK_OK(lu_grid_save_nvdb(&b, bpath, &err), &err);
    snprintf(json, sizeof json,
             "{" CAMERA ", \"media\": [{\"density\": {\"file\": \"%s\"}, \"sigma_s\": 1,"
             " \"emission\": {\"temperature\": {\"file\": \"%s\", \"grid\": \"temperature\"}}}]}",
             dpath, tpath);
    lu_scene s;
    CHECK_OK(lu_scene_load_string(json, "ok.json", &s, &err), &err);
    if (err.code == LU_OK) {
        const lu_grid *g = &s.media[0].emission_grid;
        CHECK(g->nx == 8 && g->ny == 8 && g->nz == 8);
        /* density voxel (x, y, z) is temperature voxel (x + 1, y + 1, z + 1) */
        CHECK(lu_grid_at(g, 0, 0, 0) == 1111.0f);
        CHECK(lu_grid_at(g, 7, 2, 5) == 1000.0f + 800.0f + 30.0f + 6.0f);
        lu_scene_destroy(&s);
    }
    snprintf(json, sizeof json,
             "{" CAMERA ", \"media\": [{\"density\": {\"file\": \"%s\"}, \"sigma_s\": 1,"
             " \"emission\": {\"temperature\": {\"file\": \"%s\", \"grid\": \"no_such_grid\"}}}]}",
             dpath, tpath);
    expect_error(json, LU_ERR_INVALID_ARG, "$.media[0].emission.temperature", "no_such_grid");
    snprintf(json, sizeof json,
             "{" CAMERA ", \"media\": [{\"density\": {\"file\": \"%s\"}, \"sigma_s\": 1,"
             " \"emission\": {\"grid\": {\"file\": \"%s\"}}}]}",
             dpath, bpath);
    expect_error(json, LU_ERR_SCENE, "$.media[0].emission.grid", "share one index space");
    lu_grid_destroy(&d);
    lu_grid_destroy(&t);
    lu_grid_destroy(&b);
    lu_test_remove_dir(dir);
}

static void test_transform_and_translucent(void) {
    const char *json = "{" CAMERA ", \"objects\": ["
                       " {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 2, 2]},"
                       "  \"transform\": {\"translate\": [1, 2, 3], \"rotate_deg\": [0, 90, 0], \"scale\": [1, 2, 3]}},"
                       " {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1},"
                       "  \"material\": {\"type\": \"translucent\", \"preset\": \"marble\", \"mm_per_unit\": 10}}]}";
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(json, "t.json", &s, &err), &err);
    if (err.code != LU_OK) return;
    /* Scale (1,2,3), then 90 degrees about Y (x -> -z, z -> x), then translate. */
    lu_aabb b = lu_mesh_bounds(&s.objects[0].mesh);
    CHECK_NEAR(b.lo.x, 1 - 3, 1e-5);
    CHECK_NEAR(b.hi.x, 1 + 3, 1e-5);
    CHECK_NEAR(b.lo.y, 2 - 2, 1e-5);
    CHECK_NEAR(b.hi.z, 3 + 1, 1e-5);
    /* The translucent sphere is also a bounded homogeneous medium in scene units:
     * marble sigma_s' = 2.19 / mm, 10 mm per unit -> 21.9 per unit. */
    CHECK(s.medium_count == 1);
    CHECK(s.media[0].from_object == 1);
    CHECK(s.media[0].has_boundary && s.media[0].kind == LU_DENSITY_CONSTANT);
    CHECK_REL(s.media[0].sigma_s.x, 21.9, 1e-5);
    CHECK_REL(s.media[0].sigma_a.z, 0.071, 1e-5);
    CHECK_REL(s.media[0].eta, 1.3, 1e-6);
    CHECK(s.media[0].boundary.triangle_count == s.objects[1].mesh.triangle_count);
    CHECK(s.objects[1].material.type == LU_MATERIAL_TRANSLUCENT);
    lu_scene_destroy(&s);
}

static void test_grid_transform(void) {
    /* The scene transform composes after the grid's own index-to-world map:
     * the support box of a 16^3 uniform box of size 2 spans [-1 - h/2, 1 + h/2]
     * with h = 2/16; translated by 5 in x it moves with it. */
    const char *json = "{" CAMERA ", \"media\": [{\"density\": {\"procedural\": \"uniform_box\", \"resolution\": 16,"
                       " \"size\": [2, 2, 2]}, \"sigma_s\": 1, \"transform\": {\"translate\": [5, 0, 0]}}]}";
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(json, "t.json", &s, &err), &err);
    if (err.code != LU_OK) return;
    double h = 2.0 / 16.0;
    CHECK_NEAR(s.media[0].bounds.lo.x, 5 - 1 - h / 2, 1e-5);
    CHECK_NEAR(s.media[0].bounds.hi.x, 5 + 1 + h / 2, 1e-5);
    lu_vec3 c = lu_affine_point(&s.media[0].index_to_world, lu_v3(0, 0, 0));
    CHECK_NEAR(c.x, 5 - 1 + h / 2, 1e-5); /* voxel 0's centre */
    lu_scene_destroy(&s);
}

static void test_bundled_scenes_load(void) {
    DIR *dir = opendir(LU_SOURCE_DIR "/scenes");
    CHECK(dir != NULL);
    if (!dir) return;
    int n = 0;
    for (struct dirent *e; (e = readdir(dir));) {
        if (!strstr(e->d_name, ".json")) continue;
        char path[1024];
        snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s", e->d_name);
        lu_scene s;
        lu_error err = {0};
        CHECK_OK(lu_scene_load(path, &s, &err), &err);
        if (err.code == LU_OK) {
            CHECK_MSG(s.light_count > 0, "%s has no lights", e->d_name);
            CHECK_MSG(s.medium_count > 0, "%s has no media", e->d_name);
            for (int m = 0; m < s.medium_count; m++)
                CHECK_MSG(lu_aabb_valid(s.media[m].bounds), "%s medium %d has empty bounds", e->d_name, m);
            lu_scene_destroy(&s);
        }
        n++;
    }
    closedir(dir);
    CHECK(n >= 9);
}

/* The ablation's half-space stand-in (docs/bssrdf.md, "Where the error comes
 * from") is one only if the marble below every visible point is at least
 * 5 diffusion lengths 1/sigma_tr deep in its most translucent channel (light
 * left at the bottom: e^-5 of the lateral flux), and at least r_max of it lies
 * around every visible point. sigma_tr from the preset's published
 * coefficients; r_max from the dipole table the renderer builds; the visible
 * region from the camera's frustum corners on the top face. */
static void test_ablation_halfspace_is_deep_and_wide(void) {
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load(LU_SOURCE_DIR "/scenes/ablate_halfspace.json", &s, &err), &err);
    if (err.code != LU_OK) return;
    CHECK(s.object_count == 1 && s.objects[0].material.type == LU_MATERIAL_TRANSLUCENT);
    const lu_material *m = &s.objects[0].material;
    const lu_material_preset *p = lu_material_preset_find(m->preset);
    CHECK(p != NULL);
    if (!p) return;
    double str_min = INFINITY; /* the most translucent channel, per mm */
    for (int c = 0; c < 3; c++) {
        double sa = p->sigma_a[c], st = sa + p->sigma_s_prime[c];
        str_min = fmin(str_min, sqrt(3 * sa * st));
    }
    lu_aabb box = lu_aabb_empty();
    for (uint32_t v = 0; v < s.objects[0].mesh.vertex_count; v++) lu_aabb_grow(&box, s.objects[0].mesh.positions[v]);
    const double mm = m->mm_per_unit;
    CHECK_MSG((box.hi.y - box.lo.y) * mm >= 5 / str_min, "depth %.1f mm < 5/sigma_tr = %.1f mm",
              (box.hi.y - box.lo.y) * mm, 5 / str_min);

    lu_bssrdf_layer layer = {lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]),
                             lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]), m->eta, 0.0f};
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    lu_bssrdf_profile prof;
    CHECK_OK(lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err), &err);
    const double r_max = prof.r_max / mm; /* scene units */
    lu_bssrdf_profile_destroy(&prof);
    CHECK((box.hi.x - box.lo.x) >= 4 * r_max && (box.hi.z - box.lo.z) >= 4 * r_max);

    /* Frustum corners onto the top face y = box.hi.y (the view is a convex
     * quadrilateral there, so its corners bound it). */
    const lu_camera *cam = &s.camera;
    lu_vec3 fwd = lu_v3_norm(lu_v3_sub(cam->look_at, cam->position));
    lu_vec3 right = lu_v3_norm(lu_v3_cross(fwd, cam->up));
    lu_vec3 up = lu_v3_cross(right, fwd);
    double th = tan(cam->fov_y_deg * LU_PI / 360.0), tw = th * cam->width / cam->height;
    for (int k = 0; k < 4; k++) {
        lu_vec3 d = lu_v3_add(fwd, lu_v3_add(lu_v3_scale(right, (float)((k & 1) ? tw : -tw)),
                                             lu_v3_scale(up, (float)((k & 2) ? th : -th))));
        CHECK(d.y < 0);
        double t = (box.hi.y - cam->position.y) / d.y;
        double x = cam->position.x + t * d.x, z = cam->position.z + t * d.z;
        double margin = fmin(fmin(x - box.lo.x, box.hi.x - x), fmin(z - box.lo.z, box.hi.z - z));
        CHECK_MSG(margin >= r_max, "view corner %d is %.3f from the side, r_max %.3f", k, margin, r_max);
    }
    lu_scene_destroy(&s);
}

/* A scene built in code equals the same scene loaded from JSON, field for
 * field and image for image, and the builder refuses what the loader would. */
static const char k_built_json[] =
    "{\"camera\": {\"position\": [0, 1, 5], \"look_at\": [0, 0.5, 0], \"fov_y_deg\": 40, \"width\": 24, \"height\": 16},"
    " \"background\": [0.1, 0.1, 0.2],"
    " \"lights\": [{\"type\": \"point\", \"position\": [1, 3, 2], \"intensity\": [40, 30, 20]},"
    "            {\"type\": \"directional\", \"direction\": [0, 2, 0], \"irradiance\": [0.5, 0.5, 0.5]}],"
    " \"media\": [{\"density\": {\"procedural\": \"fbm_cloud\", \"resolution\": 16, \"seed\": 3},"
    "            \"sigma_s\": [3, 3, 3], \"sigma_a\": [0.2, 0.2, 0.2], \"phase_g\": 0.3,"
    "            \"transform\": {\"translate\": [0, 0.5, 0]}}],"
    " \"objects\": [{\"mesh\": {\"procedural\": \"sphere\", \"radius\": 0.3}, \"transform\": {\"translate\": [0.8, 0.3, 0]},"
    "              \"material\": {\"type\": \"diffuse\", \"albedo\": [0.7, 0.2, 0.1]}}]}";

static void test_builder(void) {
    lu_error err = {0};
    lu_scene loaded, built;
    CHECK_OK(lu_scene_load_string(k_built_json, "built.json", &loaded, &err), &err);

    lu_scene_builder *b = NULL;
    CHECK_OK(lu_scene_builder_create(&b, &err), &err);
    if (!b) return;
    lu_camera cam = {.position = lu_v3(0, 1, 5), .look_at = lu_v3(0, 0.5f, 0), .fov_y_deg = 40, .width = 24,
                     .height = 16};
    CHECK_OK(lu_scene_builder_set_camera(b, &cam, &err), &err);
    lu_scene_builder_set_background(b, lu_v3(0.1f, 0.1f, 0.2f));
    lu_light pl = {.type = LU_LIGHT_POINT, .position = lu_v3(1, 3, 2), .intensity = lu_v3(40, 30, 20)};
    lu_light dl = {.type = LU_LIGHT_DIRECTIONAL, .direction = lu_v3(0, 2, 0), .intensity = lu_v3s(0.5f)};
    CHECK_OK(lu_scene_builder_add_light(b, &pl, &err), &err);
    CHECK_OK(lu_scene_builder_add_light(b, &dl, &err), &err);
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "resolution=16 seed=3");
    lu_grid grid = {0};
    CHECK_OK(lu_grid_procedural("fbm_cloud", &kv, &grid, "test", &err), &err);
    lu_kv_free(&kv);
    lu_affine up = lu_affine_translate(lu_v3(0, 0.5f, 0));
    lu_medium_desc md = {.grid = &grid, .sigma_s = lu_v3s(3), .sigma_a = lu_v3s(0.2f), .phase_g = 0.3f,
                         .transform = &up};
    CHECK_OK(lu_scene_builder_add_medium(b, &md, &err), &err);
    CHECK(grid.data == NULL);   /* moved in */
    lu_test_settings(&kv, "radius=0.3");
    lu_mesh sphere = {0};
    CHECK_OK(lu_mesh_procedural("sphere", &kv, &sphere, "test", &err), &err);
    lu_kv_free(&kv);
    lu_material mat;
    lu_material_defaults(&mat);
    mat.albedo = lu_v3(0.7f, 0.2f, 0.1f);
    lu_affine at = lu_affine_translate(lu_v3(0.8f, 0.3f, 0));
    CHECK_OK(lu_scene_builder_add_object(b, &sphere, &at, &mat, &err), &err);
    CHECK_OK(lu_scene_builder_finish(b, &built, &err), &err);

    CHECK(built.light_count == 2 && built.medium_count == 1 && built.object_count == 1);
    if (built.light_count == 2 && loaded.light_count == 2)
        CHECK(memcmp(&built.lights[1].direction, &loaded.lights[1].direction, sizeof(lu_vec3)) == 0);
    if (built.medium_count == 1 && loaded.medium_count == 1) {
        const lu_medium *x = &built.media[0], *y = &loaded.media[0];
        CHECK(memcmp(&x->index_to_world, &y->index_to_world, sizeof x->index_to_world) == 0);
        CHECK(memcmp(&x->bounds, &y->bounds, sizeof x->bounds) == 0);
        CHECK(x->phase_g == y->phase_g && x->from_object == -1 && x->grid.generation != 0);
    }
    if (built.object_count == 1 && loaded.object_count == 1)
        CHECK(memcmp(built.objects[0].mesh.positions, loaded.objects[0].mesh.positions,
                     loaded.objects[0].mesh.vertex_count * sizeof(lu_vec3)) == 0 &&
              memcmp(&built.objects[0].material, &loaded.objects[0].material, sizeof mat) == 0);
    lu_image a = {0}, c = {0};
    lu_renderer *r = NULL;
    const char *const set[] = {"raymarch.steps=32", NULL};
    lu_renderer_desc d = {.method = "raymarch", .backend = LU_BACKEND_CPU, .set = set};
    CHECK_OK(lu_renderer_make(&d, &loaded, &r, &err), &err);
    if (r) CHECK_OK(lu_renderer_render(r, &loaded, &a, &err), &err);
    lu_renderer_destroy(r);
    r = NULL;
    CHECK_OK(lu_renderer_make(&d, &built, &r, &err), &err);
    if (r) CHECK_OK(lu_renderer_render(r, &built, &c, &err), &err);
    lu_renderer_destroy(r);
    CHECK(a.rgb && c.rgb && memcmp(a.rgb, c.rgb, sizeof(float) * 3 * 24 * 16) == 0);
    lu_image_destroy(&a);
    lu_image_destroy(&c);

    /* refusals: nothing is added, what was to be taken is freed */
    CHECK_OK(lu_scene_builder_create(&b, &err), &err);
    lu_camera bad = {.position = lu_v3(1, 1, 1), .look_at = lu_v3(1, 1, 1)};
    CHECK(lu_scene_builder_set_camera(b, &bad, &err) == LU_ERR_SCENE && strstr(err.message, "coincide"));
    lu_light spot = {.type = LU_LIGHT_SPOT, .direction = lu_v3(0, -1, 0), .inner_deg = 30, .outer_deg = 20};
    CHECK(lu_scene_builder_add_light(b, &spot, &err) == LU_ERR_RANGE && strstr(err.message, "inner_deg"));
    lu_light nodir = {.type = LU_LIGHT_DIRECTIONAL};
    CHECK(lu_scene_builder_add_light(b, &nodir, &err) == LU_ERR_SCENE && strstr(err.message, "non-zero"));
    lu_medium_desc unbounded = {.kind = LU_DENSITY_CONSTANT, .constant = 1, .sigma_s = lu_v3s(1)};
    CHECK(lu_scene_builder_add_medium(b, &unbounded, &err) == LU_ERR_SCENE && strstr(err.message, "boundary"));
    lu_scene none;
    CHECK(lu_scene_builder_finish(b, &none, &err) == LU_ERR_SCENE && strstr(err.message, "no camera"));
    CHECK(none.light_count == 0 && none.lights == NULL);
    lu_scene_destroy(&built);
    lu_scene_destroy(&loaded);
}

int main(void) {
    RUN_TEST(test_builder);
    RUN_TEST(test_strict_errors);
    RUN_TEST(test_emission_keys);
    RUN_TEST(test_emission_nvdb);
    RUN_TEST(test_transform_and_translucent);
    RUN_TEST(test_grid_transform);
    RUN_TEST(test_bundled_scenes_load);
    RUN_TEST(test_ablation_halfspace_is_deep_and_wide);
    TEST_EXIT();
}
