/* The multiple-scattering octaves on the GPU (docs/multiple-scattering.md):
 * both backends run the one kernel (methods/common/lu_ms.h in
 * lu_view_march.h and lu_gradient.h), so
 *   - with ms=octaves the GPU image equals the CPU image within rel-L2 1e-3
 *     (the cross-backend bound, test_cross_backend) for raymarch, afm and
 *     the gradient family's pervoxel mode (its other modes share the sample
 *     evaluation that holds the octaves);
 *   - N = 1 on the GPU equals ms=off on the GPU to float rounding;
 *   - the octaves do change the GPU image (the settings reach the shader).
 * Tiny images (32x18), cheap settings. */
#include "backends/gpu.h"
#include "lu_test.h"

#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#define W 32
#define H 18

static const struct {
    const char *key;
    double value;
} k_cheap[] = {
    {"raymarch.steps", 96}, {"raymarch.shadow_res", 256}, {"afm.steps", 96},          {"afm.map_res", 64},
    {"afm.shadow_res", 256}, {"pervoxel.steps", 96},      {"pervoxel.shadow_res", 256}, {"pervoxel.grid", 32},
};

/* n = 0: ms=off. */
static bool render(const lu_scene *s, const char *method, lu_backend b, int n, lu_image *img) {
    lu_kvlist set = {0};
    lu_error err = {0};
    size_t mlen = strlen(method);
    for (size_t i = 0; i < sizeof k_cheap / sizeof k_cheap[0]; i++)
        if (strncmp(k_cheap[i].key, method, mlen) == 0 && k_cheap[i].key[mlen] == '.')
            lu_kv_set_number(&set, k_cheap[i].key, &k_cheap[i].value, 1, &err);
    lu_test_ms_settings(&set, method, n, 0.5, 0.6, 0.6);
    lu_renderer *r = NULL;
    memset(img, 0, sizeof *img);
    lu_result rc = lu_renderer_create(method, s, &set, b, &r, &err);
    if (rc == LU_OK) rc = lu_renderer_render(r, s, img, &err);
    CHECK_OK(rc, &err);
    lu_renderer_destroy(r);
    lu_kv_free(&set);
    return rc == LU_OK;
}

static double rel_l2(const lu_image *a, const lu_image *b) {
    lu_metrics m = {0};
    lu_error err = {0};
    CHECK_OK(lu_image_compare(a, b, &m, &err), &err);
    return m.rel_l2;
}

static void test_gpu_equals_cpu(void) {
    const char *scenes[] = {"spot_shaft"};
    const char *methods[] = {"raymarch", "afm", "pervoxel"};
    for (int k = 0; k < 1; k++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/scenes/%s.json", LU_SOURCE_DIR, scenes[k]);
        lu_scene s;
        lu_error err = {0};
        lu_result r = lu_scene_load(path, &s, &err);
        CHECK_OK(r, &err);
        if (r != LU_OK) continue;
        s.camera.width = W;
        s.camera.height = H;
        for (int m = 0; m < 3; m++) {
            lu_image cpu, gpu, gpu_off, gpu_one;
            bool ok = render(&s, methods[m], LU_BACKEND_CPU, 4, &cpu) && render(&s, methods[m], LU_BACKEND_GPU, 4, &gpu);
            if (ok) {
                double e = rel_l2(&gpu, &cpu);
                fprintf(stderr, "  %s %s ms=octaves: GPU vs CPU rel-L2 %.2e\n", scenes[k], methods[m], e);
                CHECK_MSG(e <= 1e-3, "%s %s: GPU vs CPU rel-L2 %.3g", scenes[k], methods[m], e);
            }
            if (ok && m == 0 && render(&s, methods[m], LU_BACKEND_GPU, 0, &gpu_off) &&
                render(&s, methods[m], LU_BACKEND_GPU, 1, &gpu_one)) {
                double e1 = rel_l2(&gpu_one, &gpu_off), e4 = rel_l2(&gpu, &gpu_off);
                fprintf(stderr, "  %s %s GPU: N=1 vs off rel-L2 %.2e; N=4 vs off %.3f\n", scenes[k], methods[m], e1, e4);
                CHECK_MSG(e1 <= 1e-6, "%s GPU N=1 vs off: %.3g", scenes[k], e1);
                CHECK_MSG(e4 > 0.05, "%s GPU N=4 vs off: %.3g (the octaves did not reach the shader?)", scenes[k], e4);
                lu_image_destroy(&gpu_off);
                lu_image_destroy(&gpu_one);
            }
            lu_image_destroy(&cpu);
            lu_image_destroy(&gpu);
        }
        lu_scene_destroy(&s);
    }
}

int main(void) {
    if (!lu_gpu_compiled_in()) {
        SKIP_TEST(test_gpu_equals_cpu, "built without the GPU backend");
        TEST_EXIT_SKIPPED("built without the GPU backend");
    }
    RUN_TEST(test_gpu_equals_cpu);
    TEST_EXIT();
}
