/* The shared GPU scene (methods/common/gpu_scene.h): a scene with a rotated, scaled
 * fbm grid, a constant medium and three lights is uploaded; a test shader
 * reads it back through kernels/lu_scene_gpu.glsl and evaluates density
 * (lu_k_density) and exact optical depth (lu_march.h's lu_k_optical_depth)
 * on random rays. The CPU side evaluates the same quantities with
 * lu_grid_sample and the same kernel compiled as C. Fails (does not skip)
 * when no GL context can be made. */
#include "backends/gpu.h"
#include "lu_test.h"

#include <lucent/lucent.h>

#include <string.h>

#include "methods/common/gpu_scene.h"

/* CPU twin of the hook, over the scene's media. */
struct lu_k_ctx {
    const lu_scene *scene;
};
static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const lu_medium *med = &c->scene->media[m];
    return med->kind == LU_DENSITY_CONSTANT ? med->constant : lu_grid_sample(&med->grid, p);
}
#include "methods/common/lu_march.h"

static const char *k_scene =
    "{\"camera\": {\"position\": [0.5, 1, 7], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 37, \"height\": 23},"
    " \"lights\": [{\"type\": \"point\", \"position\": [1, 2, 3], \"intensity\": [5, 6, 7]},"
    "  {\"type\": \"spot\", \"position\": [0, 4, 0], \"direction\": [0, -1, 0], \"intensity\": [9, 9, 9],"
    "   \"inner_deg\": 10, \"outer_deg\": 25},"
    "  {\"type\": \"directional\", \"direction\": [0.3, 1, 0.2], \"irradiance\": [1, 2, 3]}],"
    " \"media\": ["
    "  {\"density\": {\"procedural\": \"fbm_cloud\", \"size\": [3, 2, 2.5], \"resolution\": 24, \"seed\": 7, \"radius\": 1.3, \"coverage\": 0.7, \"frequency\": 1.2},"
    "   \"transform\": {\"rotate_deg\": [20, 35, -10], \"translate\": [0.2, -0.1, 0.3]},"
    "   \"sigma_s\": [1, 2, 3], \"sigma_a\": [0.1, 0.2, 0.3], \"phase_g\": 0.4},"
    "  {\"density\": {\"constant\": 0.7}, \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 0.5}},"
    "   \"sigma_s\": [0.5, 0.5, 0.5], \"sigma_a\": [0.1, 0.1, 0.1]}]}";

/* For ray k: out[4k] = density at the ray origin (index space of medium 0),
 * out[4k+1] = optical depth over the grid's support, out[4k+2] = density of
 * medium 1 (constant), out[4k+3] = unused. */
static const char *k_shader =
    "layout(local_size_x = 64) in;\n"
    "#include \"../kernels/lu_scene_gpu.glsl\"\n"
    "#include \"methods/common/lu_march.h\"\n"
    "layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Rays { vec4 rays[]; };\n"
    "layout(std430, binding = LU_SCENE_BINDING_FREE + 1) writeonly buffer Out { vec4 result[]; };\n"
    "uniform int u_count;\n"
    "void main() {\n"
    "    int k = int(gl_GlobalInvocationID.x);\n"
    "    if (k >= u_count) return;\n"
    "    lu_k_medium m = lu_scene_medium(0);\n"
    "    vec3 o = lu_k_medium_point(m, rays[2 * k].xyz), d = lu_k_medium_vector(m, rays[2 * k + 1].xyz);\n"
    "    float ta, tb, tau = 0.0;\n"
    "    if (lu_k_box_clip(m.support_lo, m.support_hi, o, d, 0.0, 1e30, ta, tb))\n"
    "        tau = lu_k_optical_depth(0, 0, o, d, ta, tb, m.max_pieces);\n"
    "    result[k] = vec4(lu_k_density(0, 0, o), tau, lu_k_density(0, 1, o), 0.0);\n"
    "}\n";

static uint64_t g_rng = 0x2545f4914f6cdd1dull;
static float rnd(float lo, float hi) {
    g_rng = g_rng * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * (float)((g_rng >> 40) / 16777216.0);
}

static lu_scene g_scene, g_sparse;

static void test_records(void) {
    const lu_scene *s = &g_scene;
    /* Environment lights are dropped; order and fields follow lu_light_to_kernel. */
    lu_k_light kl[3];
    CHECK(lu_scene_kernel_lights(s, kl) == 3);
    CHECK(kl[1].type == LU_K_LIGHT_SPOT);
    CHECK_NEAR(kl[1].cos_outer, cosf(25.0f * LU_PI / 180.0f), 1e-6);
    /* The kernel affine maps world points like lu_affine_point. */
    lu_k_medium m = lu_medium_to_kernel(&s->media[0]);
    lu_vec3 p = lu_v3(0.3f, -0.7f, 1.1f);
    lu_vec3 a = lu_k_medium_point(m, p), b = lu_affine_point(&s->media[0].world_to_index, p);
    CHECK_NEAR(a.x, b.x, 1e-5);
    CHECK_NEAR(a.y, b.y, 1e-5);
    CHECK_NEAR(a.z, b.z, 1e-5);
    CHECK(m.constant == 0 && m.max_pieces == s->media[0].grid.nx + s->media[0].grid.ny + s->media[0].grid.nz + 8);
    lu_k_medium c = lu_medium_to_kernel(&s->media[1]);
    CHECK(c.constant == 1 && c.bounded == 1 && c.density_scale == 0.7f);
}

static void gpu_matches_cpu(const lu_scene *s, const char *defines) {
    lu_error err;
    lu_gpu_context *ctx = NULL;
    /* No skip: a machine that cannot make a context fails this test. */
    CHECK_OK(lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err), &err);
    if (!ctx) return;
    lu_gpu_scene *gs = NULL;
    CHECK_OK(lu_gpu_scene_create(ctx, s, &gs, &err), &err);
    lu_gpu_source overlay = {"shaders/test_gpu_scene.comp", k_shader};
    lu_gpu_program *prog = NULL;
    CHECK_OK(lu_gpu_program_create_ex(ctx, "shaders/test_gpu_scene.comp", defines, &overlay, 1, &prog, &err), &err);
    enum { N = 512 };
    static float rays[N * 8], out[N * 4];
    lu_aabb wb = s->media[0].bounds;
    for (int k = 0; k < N; k++) {
        /* Origins inside and around the medium's world box, random directions. */
        lu_vec3 o = lu_v3(rnd(wb.lo.x - 0.3f, wb.hi.x + 0.3f), rnd(wb.lo.y - 0.3f, wb.hi.y + 0.3f),
                          rnd(wb.lo.z - 0.3f, wb.hi.z + 0.3f));
        lu_vec3 d = lu_v3_norm(lu_v3(rnd(-1, 1), rnd(-1, 1), rnd(-1, 1)));
        if (k == 0) d = lu_v3(1, 0, 0); /* axis-parallel */
        memcpy(&rays[8 * k], &o, 12);
        memcpy(&rays[8 * k + 4], &d, 12);
    }
    lu_gpu_buffer *bin = NULL, *bout = NULL;
    CHECK_OK(lu_gpu_buffer_create(ctx, sizeof rays, rays, &bin, &err), &err);
    CHECK_OK(lu_gpu_buffer_create(ctx, sizeof out, NULL, &bout, &err), &err);
    if (gs && prog && bin && bout) {
        CHECK_OK(lu_gpu_scene_bind(gs, &err), &err);
        CHECK_OK(lu_gpu_buffer_bind(bin, LU_SCENE_BINDING_FREE, &err), &err);
        CHECK_OK(lu_gpu_buffer_bind(bout, LU_SCENE_BINDING_FREE + 1, &err), &err);
        lu_gpu_uniform_int(prog, "u_count", N);
        CHECK_OK(lu_gpu_dispatch(prog, (N + 63) / 64, 1, 1, &err), &err);
        CHECK_OK(lu_gpu_buffer_download(bout, 0, out, sizeof out, &err), &err);
        struct lu_k_ctx kc = {s};
        lu_k_medium m = lu_medium_to_kernel(&s->media[0]);
        double max_dd = 0, max_dt = 0, tau_sum = 0;
        int nonzero = 0;
        for (int k = 0; k < N; k++) {
            lu_vec3 o, d;
            memcpy(&o, &rays[8 * k], 12);
            memcpy(&d, &rays[8 * k + 4], 12);
            lu_vec3 oi = lu_k_medium_point(m, o), di = lu_k_medium_vector(m, d);
            float dens = lu_grid_sample(&s->media[0].grid, oi);
            float ta, tb, tau = 0.0f;
            if (lu_k_box_clip(m.support_lo, m.support_hi, oi, di, 0.0f, 1e30f, &ta, &tb))
                tau = lu_k_optical_depth(&kc, 0, oi, di, ta, tb, m.max_pieces);
            nonzero += tau > 0.0f;
            tau_sum += tau;
            max_dd = fmax(max_dd, fabs(out[4 * k] - dens));
            max_dt = fmax(max_dt, fabs(out[4 * k + 1] - tau) / fmax(1e-3, tau));
            CHECK(out[4 * k + 2] == 0.7f);
        }
        /* Texture filtering in float vs C trilinear: agreement to ~1e-5 of
         * the density range (values in [0, 1]); optical depth sums hundreds
         * of such samples, so relative 1e-4 leaves a margin of ~10x. */
        CHECK_MSG(max_dd <= 2e-5 * fmax(1.0, s->media[0].grid.max_value), "density max |diff| %.3g", max_dd);
        CHECK_MSG(max_dt <= 1e-4, "optical depth max rel diff %.3g", max_dt);
        /* enough rays meet cloud for the comparison to mean something */
        CHECK_MSG(nonzero > N / 8 && tau_sum > 0.0, "only %d rays crossed the medium", nonzero);
        printf("  density max |diff| %.3g, optical depth max rel diff %.3g over %d rays (%d through the grid)\n",
               max_dd, max_dt, N, nonzero);
    }
    /* Each update uploads only what differs from what the GPU holds: a
     * camera move nothing but the header, a light its buffer, a medium's
     * coefficients or an edited grid (new majorants) the media buffer. A
     * grid of another size is refused. */
    if (gs) {
        lu_scene s2 = *s;
        lu_frame_records rec = {0};
        int m0, l0, m1, l1;
        CHECK_OK(lu_frame_records_update(&rec, &s2, &err), &err);
        CHECK_OK(lu_gpu_scene_update(gs, &s2, &rec, &err), &err);
        lu_gpu_scene_uploads(gs, &m0, &l0);
        CHECK_MSG(m0 >= 1 && l0 >= 1, "first update: media %d, lights %d uploads", m0, l0);
        s2.camera.position = lu_v3_add(s2.camera.position, lu_v3(0.1f, 0.0f, 0.0f));
        CHECK_OK(lu_frame_records_update(&rec, &s2, &err), &err);
        CHECK_OK(lu_gpu_scene_update(gs, &s2, &rec, &err), &err);
        lu_gpu_scene_uploads(gs, &m1, &l1);
        CHECK_MSG(m1 == m0 && l1 == l0, "camera move: media %d -> %d, lights %d -> %d uploads", m0, m1, l0, l1);
        lu_light lights[8];
        if (s2.light_count > 0 && s2.light_count <= 8) {
            memcpy(lights, s2.lights, (size_t)s2.light_count * sizeof *lights);
            s2.lights = lights;
            lights[0].intensity = lu_v3_scale(lights[0].intensity, 2.0f);
            CHECK_OK(lu_frame_records_update(&rec, &s2, &err), &err);
            CHECK_OK(lu_gpu_scene_update(gs, &s2, &rec, &err), &err);
            lu_gpu_scene_uploads(gs, &m1, &l1);
            CHECK_MSG(m1 == m0 && l1 == l0 + 1, "light change: media %d -> %d, lights %d -> %d", m0, m1, l0, l1);
        }
        lu_medium media[LU_SCENE_MAX_MEDIA];
        memcpy(media, s2.media, (size_t)s2.medium_count * sizeof *media);
        s2.media = media;
        media[0].sigma_s = lu_v3_scale(media[0].sigma_s, 0.5f);
        CHECK_OK(lu_frame_records_update(&rec, &s2, &err), &err);
        CHECK_OK(lu_gpu_scene_update(gs, &s2, &rec, &err), &err);
        lu_gpu_scene_uploads(gs, &m1, &l1);
        CHECK_MSG(m1 == m0 + 1, "medium change: media %d -> %d uploads", m0, m1);
        s2.medium_count = 1;
        CHECK(lu_gpu_scene_update(gs, &s2, &rec, &err) == LU_ERR_INVALID_ARG);
        lu_frame_records_free(&rec);
    }
    lu_gpu_buffer_destroy(bin);
    lu_gpu_buffer_destroy(bout);
    lu_gpu_program_destroy(prog);
    lu_gpu_scene_destroy(gs);
    lu_gpu_context_destroy(ctx);
}

static void test_gpu_matches_cpu(void) { gpu_matches_cpu(&g_scene, lu_gpu_scene_defines(&g_scene)); }

/* The same grid as a sparse tree read in place on both sides (lu_grid_tree.h
 * in GLSL from the header buffer, in C from the mapped file): the same
 * bounds. */
static void test_gpu_sparse_matches_cpu(void) {
    CHECK(lu_grid_is_sparse(&g_sparse.media[0].grid));
    /* small enough for a texture: the tree path is forced */
    CHECK(strcmp(lu_gpu_scene_defines(&g_sparse), "") == 0);
    lu_gpu_scene_set_dense_limit(0);
    CHECK(strstr(lu_gpu_scene_defines(&g_sparse), "LU_SCENE_TREES") != NULL);
    gpu_matches_cpu(&g_sparse, lu_gpu_scene_defines(&g_sparse));
    lu_gpu_scene_set_dense_limit(256ull << 20);
}

int main(void) {
    lu_error err;
    CHECK_OK(lu_scene_load_string(k_scene, "gpu_scene_test.json", &g_scene, &err), &err);
    CHECK(g_scene.medium_count == 2);
    if (g_scene.medium_count == 2) {
        RUN_TEST(test_records);
        if (!lu_gpu_compiled_in()) {
            SKIP_TEST(test_gpu_matches_cpu, "built without the GPU backend");
            lu_scene_destroy(&g_scene);
            TEST_EXIT_SKIPPED("built without the GPU backend");
        }
        RUN_TEST(test_gpu_matches_cpu);
        /* medium 0 written as .nvdb and loaded sparse, in the same place */
        char path[512], json[4096];
        snprintf(path, sizeof path, "%s/test_gpu_scene_sparse.nvdb", LU_BINARY_DIR);
        lu_grid g = g_scene.media[0].grid;
        g.index_to_world = g_scene.media[0].index_to_world;
        CHECK_OK(lu_grid_save_nvdb(&g, path, &err), &err);
        const char *at = strstr(k_scene, "{\"procedural\": \"fbm_cloud\""), *end = at ? strchr(at, '}') : NULL;
        if (at && end) {
            snprintf(json, sizeof json, "%.*s{\"file\": \"%s\"}%s", (int)(at - k_scene), k_scene, path, end + 1);
            const char *tr = strstr(json, "\"transform\"");
            if (tr) memmove((char *)tr, strstr(tr, "}") + 2, strlen(strstr(tr, "}") + 2) + 1);
            CHECK_OK(lu_scene_load_string(json, "gpu_scene_sparse.json", &g_sparse, &err), &err);
            if (g_sparse.medium_count == 2) RUN_TEST(test_gpu_sparse_matches_cpu);
            lu_scene_destroy(&g_sparse);
        }
        remove(path);
    }
    lu_scene_destroy(&g_scene);
    TEST_EXIT();
}
