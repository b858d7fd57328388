/* Every kernel header must compile as GLSL 4.50 too (that is what makes it a
 * kernel): one compute shader includes them all, on llvmpipe here and in CI. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <string.h>

#include "backends/gpu.h"
#include "lu_test.h"

static void test_all_kernels_compile_as_glsl(void) {
    /* Hooks the kernels expect from a backend, as trivial GLSL definitions. */
    char src[16384];
    size_t n = (size_t)snprintf(src, sizeof src,
                                "layout(local_size_x = 1) in;\n"
                                "layout(std430, binding = 0) buffer Out { float v[]; } o;\n"
                                "layout(std430, binding = 1) readonly buffer Tree { uint pnanovdb_buf_data[]; };\n"
                                "#include \"kernels/lu_kernel.h\"\n"
                                "float lu_k_density(LU_CTX_PARAM, int m, vec3 p) { return p.x; }\n"
                                "float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j) { return 1.0; }\n"
                                "float lu_k_bssrdf_fetch(LU_CTX_PARAM, int b, int i) { return float(b + i); }\n"
                                "float lu_k_majorant(LU_CTX_PARAM, int m, int bx, int by, int bz) { return 1.0; }\n"
                                "#include \"kernels/lu_medium.h\"\n"
                                "#include \"kernels/lu_optics.h\"\n"
                                "#include \"methods/common/lu_lightview.h\"\n"
                                "int lu_k_medium_count(LU_CTX_PARAM) { return 1; }\n"
                                "lu_k_medium lu_k_medium_get(LU_CTX_PARAM, int m) { lu_k_medium k; k.constant = 1; return k; }\n"
                                "vec3 lu_k_emission(LU_CTX_PARAM, int m, vec3 p) { return p; }\n"
                                "int lu_k_light_count(LU_CTX_PARAM) { return 1; }\n"
                                "lu_k_light lu_k_light_get(LU_CTX_PARAM, int l) { lu_k_light k; k.type = 0; return k; }\n"
                                "int lu_k_rm_view_first(LU_CTX_PARAM, int l) { return 0; }\n"
                                "int lu_k_rm_view_count(LU_CTX_PARAM, int l) { return 0; }\n"
                                "lu_k_lightview lu_k_rm_view(LU_CTX_PARAM, int v) { lu_k_lightview w; w.ortho = 1; return w; }\n"
                                "float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int end) { return float(end); }\n"
                                "float lu_k_rm_hit_fetch(LU_CTX_PARAM, int pixel, int k) { return -1.0; }\n"
                                "#include \"methods/gradient/lu_gradient_params.h\"\n"
                                "lu_k_gr_params lu_k_gr_get(LU_CTX_PARAM) { lu_k_gr_params p; p.nx = 1; return p; }\n"
                                "vec3 lu_k_gr_field(LU_CTX_PARAM, int i) { return vec3(float(i)); }\n"
                                "int lu_k_gr_cell_begin(LU_CTX_PARAM, int c) { return 0; }\n"
                                "int lu_k_gr_cell_end(LU_CTX_PARAM, int c) { return 0; }\n"
                                "int lu_k_gr_cell_item(LU_CTX_PARAM, int k) { return k; }\n"
                                "float lu_k_gr_sample_fetch(LU_CTX_PARAM, int j, int k) { return float(j + k); }\n"
                                "float lu_k_gr_bmap_at(LU_CTX_PARAM, int k) { return float(k); }\n"
                                "float lu_k_gr_surf(LU_CTX_PARAM, int k) { return float(k); }\n"
                                "float lu_k_ddod_sample_f(LU_CTX_PARAM, int i, int k) { return 1.0; }\n"
                                "float lu_k_ddod_coeff(LU_CTX_PARAM, int i) { return 0.5; }\n"
                                "vec3 lu_k_ddod_radiance(LU_CTX_PARAM, int i) { return vec3(1.0); }\n"
                                "float lu_k_ddod_pixel_f(LU_CTX_PARAM, int pixel, int k) { return 0.0; }\n"
                                "int lu_k_ddod_tile_start(LU_CTX_PARAM, int tile) { return 0; }\n"
                                "int lu_k_ddod_tile_item(LU_CTX_PARAM, int k) { return 0; }\n"
                                "vec3 lu_k_ddod_env_coeff(LU_CTX_PARAM, int k) { return vec3(0.0); }\n"
                                "vec3 lu_k_ddod_traced(LU_CTX_PARAM, int k) { return vec3(0.0); }\n"
                                "float lu_k_afm_lspan(LU_CTX_PARAM, int texel, int m, int k) { return float(k); }\n"
                                "void lu_k_afm_store(LU_CTX_PARAM, int texel, int i, float v) { o.v[i] = v; }\n"
                                "float lu_k_afm_fetch(LU_CTX_PARAM, int texel, int i) { return float(i); }\n"
                                "int lu_k_afm_view_first(LU_CTX_PARAM, int l) { return 0; }\n"
                                "int lu_k_afm_view_count(LU_CTX_PARAM, int l) { return 0; }\n"
                                "lu_k_lightview lu_k_afm_view(LU_CTX_PARAM, int v) { lu_k_lightview w; w.ortho = 1; return w; }\n"
                                "float lu_k_afm_cam_normal(LU_CTX_PARAM, int pixel, int m, int k) { return 0.0; }\n"
                                "float lu_k_afm_surface(LU_CTX_PARAM, int m, int k) { return 1.0; }\n"
                                "int lu_k_afm_param(LU_CTX_PARAM, int i) { return 4; }\n"
                                "float lu_k_afm_surface_vis(LU_CTX_PARAM, int pixel, int l) { return 1.0; }\n"
                                "float lu_k_fx_span(LU_CTX_PARAM, int column, int m, int end) { return float(end); }\n"
                                "vec3 lu_k_fx_hist(LU_CTX_PARAM, int cell, int part) { return vec3(0.0); }\n"
                                "float lu_k_fx_hist_valid(LU_CTX_PARAM, int cell) { return 0.0; }\n"
                                "float lu_k_fx_reach(LU_CTX_PARAM, int column) { return 1.0; }\n"
                                "vec3 lu_k_fx_lit(LU_CTX_PARAM, int cell, int part) { return vec3(0.0); }\n"
                                "vec3 lu_k_fx_int(LU_CTX_PARAM, int node, int part) { return vec3(0.0); }\n"
                                "void lu_k_fx_int_store(LU_CTX_PARAM, int node, vec3 L, vec3 tau) { o.v[node] = L.x + tau.x; }\n");
    /* Every embedded kernel header (lu_*.h in src/kernels and the method rooms). */
    int count = 0;
    for (int i = 0; i < lu_gpu_embedded_source_count; i++) {
        const char *name = lu_gpu_embedded_sources[i].name, *base = strrchr(name, '/');
        base = base ? base + 1 : name;
        size_t len = strlen(base);
        if (strncmp(base, "lu_", 3) != 0 || len < 3 || strcmp(base + len - 2, ".h") != 0) continue;
        n += (size_t)snprintf(src + n, sizeof src - n, "#include \"%s\"\n", name);
        count++;
    }
    snprintf(src + n, sizeof src - n, "void main() { o.v[0] = lu_smoothstep(0.0, 1.0, 0.5); }\n");
    fprintf(stderr, "  %d kernel headers\n", count);
    CHECK(count >= 8);

    lu_error err = {0};
    lu_gpu_context *ctx = NULL;
    CHECK_OK(lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err), &err);
    if (!ctx) return;
    lu_gpu_source overlay = {"shaders/all_kernels.comp", src};
    lu_gpu_program *prog = NULL;
    CHECK_OK(lu_gpu_program_create_ex(ctx, "shaders/all_kernels.comp", NULL, &overlay, 1, &prog, &err), &err);
    lu_gpu_program_destroy(prog);
    lu_gpu_context_destroy(ctx);
}

int main(void) {
    if (!lu_gpu_compiled_in()) {
        SKIP_TEST(test_all_kernels_compile_as_glsl, "built without the GPU backend");
        TEST_EXIT_SKIPPED("built without the GPU backend");
    }
    RUN_TEST(test_all_kernels_compile_as_glsl);
    TEST_EXIT();
}
