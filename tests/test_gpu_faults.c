/* GPU faults (docs/reliability.md, "Faults"), through the injection hook
 * of backends/gpu.h, since llvmpipe neither fails to create a context nor
 * loses one:
 *   - a context that cannot be created: LU_ERR_BACKEND with a message, and
 *     once the fault is gone a renderer is made as before;
 *   - a context lost in the middle of a renderer's life: that frame fails
 *     with LU_ERR_BACKEND; a failed frame makes the renderer prepare again
 *     at its next frame, which takes a fresh device (the lost one is out of
 *     the table), so the next frame's image equals the one rendered before
 *     the loss, bit for bit; a new renderer also gets the fresh device;
 *   - --backend auto (LU_BACKEND_AUTO) falls back to the CPU when the GPU
 *     renderer cannot be made: run only where AUTO means the GPU (a
 *     hardware device), said so where it is skipped.
 * No GPU context at all: skipped (77). */
#include "lu_test.h"

static bool same(const lu_image *a, const lu_image *b) {
    return a->width == b->width && a->height == b->height && a->rgb && b->rgb &&
           memcmp(a->rgb, b->rgb, (size_t)a->width * a->height * 3 * sizeof(float)) == 0;
}

static void quiet_log(lu_log_level level, const char *message, void *user) {
    (void)level, (void)message, (void)user;
}

int main(void) {
    if (!lu_gpu_compiled_in()) TEST_EXIT_SKIPPED("built without the GPU backend");
    lu_host host = {.log = quiet_log};
    lu_error err = {0};
    CHECK_OK(lu_host_set(&host, &err), &err);
    lu_scene s;
    CHECK_OK(lu_scene_load(LU_SOURCE_DIR "/scenes/smoke_box.json", &s, &err), &err);
    if (err.code != LU_OK) TEST_EXIT();
    s.camera.width = 40;
    s.camera.height = 30;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "raymarch.steps=48");

    lu_renderer *r = NULL;
    lu_result res = lu_renderer_create("raymarch", &s, &kv, LU_BACKEND_GPU, &r, &err);
    if (res == LU_ERR_BACKEND) {
        lu_scene_destroy(&s);
        lu_kv_free(&kv);
        TEST_EXIT_SKIPPED("no GPU context");
    }
    CHECK_OK(res, &err);
    lu_image before = {0}, lost = {0}, again = {0}, fresh_img = {0};
    CHECK_OK(lu_renderer_render(r, &s, &before, &err), &err);

    /* Lost in the middle: the next GL check finds the device reset. */
    lu_gpu_fault_inject(LU_GPU_FAULT_LOSE, 1);
    s.camera.position.x += 0.05f; /* a change, so the frame does GPU work */
    res = lu_renderer_render(r, &s, &lost, &err);
    CHECK_MSG(res == LU_ERR_BACKEND, "render after a loss: result %d", (int)res);
    CHECK_MSG(strstr(err.message, "lost") != NULL, "message: %s", err.message);
    s.camera.position.x -= 0.05f;
    CHECK_OK(lu_renderer_render(r, &s, &again, &err), &err);
    CHECK_MSG(same(&before, &again), "the renderer's frame after the loss differs from the one before it");
    lu_renderer_stats st0 = {0};
    CHECK_OK(lu_renderer_get_stats(r, &st0, &err), &err);
    CHECK_MSG(st0.prepares == 2, "prepares after the loss: %llu", (unsigned long long)st0.prepares);
    lu_renderer_destroy(r);

    /* A new renderer gets a fresh device and the same image as before. */
    lu_renderer *fresh = NULL;
    CHECK_OK(lu_renderer_create("raymarch", &s, &kv, LU_BACKEND_GPU, &fresh, &err), &err);
    if (fresh) CHECK_OK(lu_renderer_render(fresh, &s, &fresh_img, &err), &err);
    CHECK_MSG(same(&before, &fresh_img), "a fresh device after the loss renders a different image");
    lu_renderer_destroy(fresh);

    /* Creation fails: a clear error, then recovery once the fault is gone.
     * No renderer holds the device now, so the next create makes one. */
    lu_gpu_fault_inject(LU_GPU_FAULT_CREATE, 0);
    lu_renderer *none = NULL;
    res = lu_renderer_create("raymarch", &s, &kv, LU_BACKEND_GPU, &none, &err);
    CHECK_MSG(res == LU_ERR_BACKEND && none == NULL, "create with no context: result %d", (int)res);
    CHECK_MSG(strstr(err.message, "context") != NULL, "message: %s", err.message);

    /* AUTO: the CPU renderer, and its image, when the GPU cannot be made. */
    if (lu_backend_auto(NULL) == LU_BACKEND_GPU) {
        lu_renderer *a = NULL, *cpu = NULL;
        lu_image ai = {0}, ci = {0};
        lu_renderer_desc d = {.method = "raymarch", .backend = LU_BACKEND_AUTO, .settings = &kv};
        CHECK_OK(lu_renderer_make(&d, &s, &a, &err), &err);
        lu_renderer_stats st = {0};
        if (a) CHECK_OK(lu_renderer_get_stats(a, &st, &err), &err);
        CHECK_MSG(st.backend == LU_BACKEND_CPU, "AUTO without a context: backend %s", lu_backend_name(st.backend));
        CHECK_OK(lu_renderer_create("raymarch", &s, &kv, LU_BACKEND_CPU, &cpu, &err), &err);
        if (a && cpu) {
            CHECK_OK(lu_renderer_render(a, &s, &ai, &err), &err);
            CHECK_OK(lu_renderer_render(cpu, &s, &ci, &err), &err);
            CHECK(same(&ai, &ci));
        }
        lu_image_destroy(&ai);
        lu_image_destroy(&ci);
        lu_renderer_destroy(a);
        lu_renderer_destroy(cpu);
    } else {
        fprintf(stderr, "  AUTO fallback part skipped: AUTO means the CPU here (no hardware GPU)\n");
    }
    lu_gpu_fault_inject(LU_GPU_FAULT_NONE, 0);
    lu_renderer *back = NULL;
    CHECK_OK(lu_renderer_create("raymarch", &s, &kv, LU_BACKEND_GPU, &back, &err), &err);
    lu_image back_img = {0};
    if (back) CHECK_OK(lu_renderer_render(back, &s, &back_img, &err), &err);
    CHECK_MSG(same(&before, &back_img), "after the creation fault clears, the image differs");
    lu_renderer_destroy(back);

    lu_image_destroy(&before);
    lu_image_destroy(&lost);
    lu_image_destroy(&again);
    lu_image_destroy(&fresh_img);
    lu_image_destroy(&back_img);
    lu_kv_free(&kv);
    lu_scene_destroy(&s);
    TEST_EXIT();
}
