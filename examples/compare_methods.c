/* Judge a fast method against the reference on one scene: the measure every
 * lucent method is held to (relative L2 error, Ren et al.).
 *   build/examples/compare_methods scenes/smoke_glow.json reference 96x72 */
#include <lucent/lucent.h>

#include <stdio.h>

static lu_result render(const char *method, const lu_scene *scene, lu_image *out, double *ms, lu_error *err) {
    lu_renderer *r = NULL;
    lu_result res = lu_renderer_create(method, scene, NULL, LU_BACKEND_CPU, &r, err);
    if (res == LU_OK) res = lu_renderer_render(r, scene, out, err);
    lu_renderer_stats st;
    if (res == LU_OK) res = lu_renderer_get_stats(r, &st, err);
    if (res == LU_OK) *ms = st.frame_ms;
    lu_renderer_destroy(r);
    return res;
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s SCENE.json METHOD WxH\n", argv[0]);
        return 2;
    }
    lu_error err = {0};
    lu_scene scene;
    if (lu_scene_load(argv[1], &scene, &err) != LU_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    if (sscanf(argv[3], "%dx%d", &scene.camera.width, &scene.camera.height) != 2) {
        fprintf(stderr, "bad size %s\n", argv[3]);
        lu_scene_destroy(&scene);
        return 2;
    }
    lu_image truth = {0}, fast = {0};
    double ms_ref = 0, ms_fast = 0;
    lu_metrics m;
    int rc = 0;
    if (render("reference", &scene, &truth, &ms_ref, &err) != LU_OK ||
        render(argv[2], &scene, &fast, &ms_fast, &err) != LU_OK || lu_image_compare(&fast, &truth, &m, &err) != LU_OK) {
        fprintf(stderr, "%s\n", err.message);
        rc = 1;
    } else {
        printf("%s: rel-L2 %.4f, PSNR %.2f dB, %.1f ms vs reference %.1f ms (%.1fx)\n", argv[2], m.rel_l2, m.psnr,
               ms_fast, ms_ref, ms_ref / ms_fast);
    }
    lu_image_destroy(&truth);
    lu_image_destroy(&fast);
    lu_scene_destroy(&scene);
    return rc;
}
