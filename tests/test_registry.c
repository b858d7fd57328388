/* The method registry: parameter resolution with presets. A preset replaces
 * the defaults, an explicit setting overrides the preset, and an unknown
 * preset is an error naming the ones there are. */
#include <lucent/lucent.h>

#include <string.h>

#include "lu_test.h"

static int param_index(const lu_method *m, const char *name) {
    for (int i = 0; i < m->param_count; i++)
        if (strcmp(m->params[i].name, name) == 0) return i;
    return -1;
}

static void test_presets(void) {
    const lu_method *m = lu_method_find("afm");
    CHECK(m && m->preset_count >= 1);
    if (!m) return;
    int steps = param_index(m, "steps"), res = param_index(m, "map_res"), coefs = param_index(m, "coefs");
    CHECK(steps >= 0 && res >= 0 && coefs >= 0);
    double v[LU_MAX_PARAMS];
    lu_error err = {0};
    lu_kvlist kv = {0};
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == m->params[steps].def && v[res] == m->params[res].def);

    lu_test_settings(&kv, "afm.preset=paper");
    CHECK_OK(lu_settings_validate(&kv, &err), &err);
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == 500 && v[res] == 1024 && v[coefs] == 16);
    lu_kv_free(&kv);

    /* explicit settings win, before or after the preset */
    lu_test_settings(&kv, "afm.steps=64 afm.preset=paper");
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == 64 && v[res] == 1024);
    lu_kv_free(&kv);

    lu_test_settings(&kv, "afm.preset=fastest");
    CHECK(lu_settings_validate(&kv, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "fastest") && strstr(err.message, "paper"), "%s", err.message);
    CHECK(lu_method_resolve_params(m, &kv, v, &err) == LU_ERR_RANGE);
    lu_kv_free(&kv);

    /* a method without presets refuses any */
    lu_test_settings(&kv, "reference.preset=paper");
    CHECK(lu_settings_validate(&kv, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "none") != NULL, "%s", err.message);
    lu_kv_free(&kv);
}

static void count_partial(void *user, const lu_image *partial, int done, int total) {
    (*(int *)user)++;
}

/* The renderer descriptor: zero means the defaults, resolved in one place;
 * "set" texts override settings; the stats count what happened. */
static void test_renderer_desc_and_stats(void) {
    lu_error err = {0};
    lu_renderer_desc zero = {0}, d;
    CHECK_OK(lu_renderer_desc_resolve(&zero, &d, &err), &err);
    CHECK(d.method && strcmp(d.method, LU_DEFAULT_METHOD) == 0);
    /* reference has no GPU path, so AUTO is the CPU wherever this runs */
    CHECK(d.backend == LU_BACKEND_CPU);
    CHECK(d.settings == NULL && d.set == NULL && d.progressive.fn == NULL);
    lu_renderer_desc bad = {.method = "nope"};
    CHECK(lu_renderer_desc_resolve(&bad, &d, &err) == LU_ERR_INVALID_ARG && strstr(err.message, "\"nope\""));
    lu_renderer_desc gpu_ref = {.method = "reference", .backend = LU_BACKEND_GPU};
    CHECK(lu_renderer_desc_resolve(&gpu_ref, &d, &err) == LU_ERR_UNSUPPORTED);
    lu_renderer_desc odd = {.backend = (lu_backend)7};
    CHECK(lu_renderer_desc_resolve(&odd, &d, &err) == LU_ERR_INVALID_ARG);

    lu_scene scene;
    CHECK_OK(lu_scene_load(LU_SOURCE_DIR "/scenes/demo.json", &scene, &err), &err);
    scene.camera.width = 16;
    scene.camera.height = 12;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, "raymarch.steps=8 raymarch.shadow_res=32");
    const char *const set[] = {"raymarch.steps=6", NULL};
    lu_renderer_desc rd = {.method = "raymarch", .backend = LU_BACKEND_CPU, .settings = &kv, .set = set};
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_make(&rd, &scene, &r, &err), &err);
    const lu_method *m = NULL;
    double v[LU_MAX_PARAMS];
    int n = 0;
    if (r) {
        CHECK_OK(lu_renderer_get_method(r, &m, &err), &err);
        CHECK_OK(lu_renderer_get_params(r, v, LU_MAX_PARAMS, &n, &err), &err);
    }
    CHECK(m == lu_method_find("raymarch") && m && n == m->param_count);
    if (m && n == m->param_count) {
        CHECK(v[param_index(m, "steps")] == 6);          /* set over settings */
        CHECK(v[param_index(m, "shadow_res")] == 32);  /* settings kept */
    }
    lu_renderer_stats st = {0};
    if (r) CHECK_OK(lu_renderer_get_stats(r, &st, &err), &err);
    CHECK(st.method && strcmp(st.method, "raymarch") == 0 && st.backend == LU_BACKEND_CPU);
    CHECK(st.prepares == 1 && st.frames == 0 && st.prepare_ms >= 0.0);
    lu_image img = {0};
    for (int f = 0; f < 3 && r; f++) {
        if (f == 2) scene.camera.position.x += 0.1f;
        CHECK_OK(lu_renderer_render(r, &scene, &img, &err), &err);
        CHECK_OK(lu_renderer_get_stats(r, &st, &err), &err);
        CHECK(st.frames == (uint64_t)f + 1 && st.prepares == 1);
        unsigned want = f == 0 ? LU_CHANGE_ALL : f == 1 ? 0u : LU_CHANGE_CAMERA;
        CHECK_MSG(st.changed == want, "frame %d: changed %#x, expected %#x", f, st.changed, want);
        CHECK(st.render_ms >= 0.0 && st.frame_update_ms >= 0.0 &&
              st.render_ms + st.frame_update_ms <= st.frame_ms + 1e-9);
        CHECK(st.products == lu_renderer_products(r, NULL, NULL, 0) && st.products > 0);
    }
    CHECK(r && lu_renderer_rebuilds(r, "media_rays.camera") == 2);   /* frame 0 and the camera move */
    CHECK(lu_renderer_get_stats(NULL, &st, &err) == LU_ERR_INVALID_ARG);
    /* a bad "set" text is an error naming it */
    lu_renderer *r2 = NULL;
    const char *const typo[] = {"raymarch.stpes=5", NULL};
    lu_renderer_desc td = {.method = "raymarch", .backend = LU_BACKEND_CPU, .set = typo};
    CHECK(lu_renderer_make(&td, &scene, &r2, &err) == LU_ERR_INVALID_ARG && r2 == NULL);
    CHECK_MSG(strstr(err.message, "stpes") != NULL, "%s", err.message);
    /* progressive output through the descriptor: after passes 1 and 2 of 3 */
    int calls = 0;
    const char *const spp[] = {"pathtrace.spp=3", NULL};
    lu_renderer_desc pd = {.method = "pathtrace", .backend = LU_BACKEND_CPU, .set = spp,
                           .progressive = {.fn = count_partial, .user = &calls, .every = 1}};
    scene.camera.width = 8;
    scene.camera.height = 6;
    lu_image pimg = {0};
    CHECK_OK(lu_renderer_make(&pd, &scene, &r2, &err), &err);
    if (r2) CHECK_OK(lu_renderer_render(r2, &scene, &pimg, &err), &err);
    CHECK_MSG(calls == 2, "%d progressive calls", calls);
    lu_renderer_destroy(r2);
    lu_image_destroy(&pimg);
    lu_image_destroy(&img);
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
    lu_scene_destroy(&scene);
}

int main(void) {
    RUN_TEST(test_renderer_desc_and_stats);
    RUN_TEST(test_presets);
    TEST_EXIT();
}
