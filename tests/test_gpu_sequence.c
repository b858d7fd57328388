/* Density changes reach the GPU: a GPU renderer kept across a change of the
 * scene's time (the animated smoke plume, lu_scene_set_time) re-uploads the
 * grid, so its image equals a fresh GPU renderer's image at the new time bit
 * for bit, and the CPU image of that time within the cross-backend bound
 * (rel-L2 1e-3, tests/test_cross_backend.c); the image before the change
 * differs, so the comparison can fail. No GPU context: skipped (77). */
#include "backends/gpu.h"
#include "lu_test.h"

#include <lucent/lucent.h>

#include <string.h>

static const char *k_scene =
    "{\"camera\": {\"position\": [0, 1.1, 4.2], \"look_at\": [0, 1, 0], \"width\": 40, \"height\": 32},"
    " \"lights\": [{\"type\": \"point\", \"position\": [1.5, 3, 1.5], \"intensity\": [40, 40, 40]}],"
    " \"media\": [{\"density\": {\"procedural\": \"smoke_plume\", \"center\": [0, 1, 0], \"size\": [2, 2, 2],"
    "  \"resolution\": 32, \"seed\": 4, \"rise\": 0.6}, \"sigma_s\": 8, \"sigma_a\": 1}]}";

static const char *k_methods[] = {"raymarch", "afm", "gradient"};

int main(void) {
    if (!lu_gpu_compiled_in()) TEST_EXIT_SKIPPED("built without the GPU backend");
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(k_scene, "gpu_sequence.json", &s, &err), &err);
    if (err.code != LU_OK) TEST_EXIT();
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "raymarch.steps=96 afm.steps=96 afm.map_res=64 gradient.steps=96 gradient.grid=32");
    for (size_t mi = 0; mi < sizeof k_methods / sizeof k_methods[0]; mi++) {
        const char *m = k_methods[mi];
        CHECK_OK(lu_scene_set_time(&s, 0.0, &err), &err);
        lu_renderer *kept = NULL, *fresh = NULL, *cpu = NULL;
        lu_result r = lu_renderer_create(m, &s, &kv, LU_BACKEND_GPU, &kept, &err);
        if (r == LU_ERR_BACKEND) {
            lu_scene_destroy(&s);
            lu_kv_free(&kv);
            TEST_EXIT_SKIPPED("no GPU context");
        }
        CHECK_OK(r, &err);
        lu_image before = {0}, after = {0}, want = {0}, on_cpu = {0};
        CHECK_OK(lu_renderer_render(kept, &s, &before, &err), &err);
        CHECK_OK(lu_scene_set_time(&s, 0.5, &err), &err);
        CHECK_OK(lu_renderer_render(kept, &s, &after, &err), &err);
        CHECK_OK(lu_renderer_create(m, &s, &kv, LU_BACKEND_GPU, &fresh, &err), &err);
        CHECK_OK(lu_renderer_render(fresh, &s, &want, &err), &err);
        CHECK_OK(lu_renderer_create(m, &s, &kv, LU_BACKEND_CPU, &cpu, &err), &err);
        CHECK_OK(lu_renderer_render(cpu, &s, &on_cpu, &err), &err);
        if (before.rgb && after.rgb && want.rgb && on_cpu.rgb) {
            double moved = lu_test_rel_l2(&before, &want), kept_vs_fresh = lu_test_rel_l2(&after, &want),
                   gpu_vs_cpu = lu_test_rel_l2(&after, &on_cpu);
            fprintf(stderr, "  %-9s time 0 -> 0.5: image moved by rel-L2 %.3g; kept vs fresh GPU %.3g; GPU vs CPU %.3g\n",
                    m, moved, kept_vs_fresh, gpu_vs_cpu);
            CHECK_MSG(moved > 1e-2, "%s: the time change did not change the image (%g)", m, moved);
            CHECK_MSG(kept_vs_fresh == 0.0, "%s: the kept GPU renderer missed the density change (rel-L2 %g)", m,
                      kept_vs_fresh);
            CHECK_MSG(gpu_vs_cpu < 1e-3, "%s: GPU and CPU differ after the time change (rel-L2 %g)", m, gpu_vs_cpu);
        }
        lu_image_destroy(&before);
        lu_image_destroy(&after);
        lu_image_destroy(&want);
        lu_image_destroy(&on_cpu);
        lu_renderer_destroy(kept);
        lu_renderer_destroy(fresh);
        lu_renderer_destroy(cpu);
    }
    lu_scene_destroy(&s);
    lu_kv_free(&kv);
    TEST_EXIT();
}
