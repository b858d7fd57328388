/* The whole data path in one screen: scene -> prepare -> render -> image.
 *   build/examples/render_scene scenes/demo.json reference out.exr */
#include <lucent/lucent.h>

#include <stdio.h>

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s SCENE.json METHOD OUT.{png,exr,pfm}\n", argv[0]);
        return 2;
    }
    lu_error err = {0};
    lu_scene scene;
    lu_renderer *renderer = NULL;
    lu_image image = {0};
    int rc = 0;
    if (lu_scene_load(argv[1], &scene, &err) != LU_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    if (lu_renderer_create(argv[2], &scene, NULL, LU_BACKEND_CPU, &renderer, &err) != LU_OK ||
        lu_renderer_render(renderer, &scene, &image, &err) != LU_OK ||
        lu_image_save(&image, argv[3], NULL, &err) != LU_OK) {
        fprintf(stderr, "%s\n", err.message);
        rc = 1;
    } else {
        lu_renderer_stats st;
        lu_renderer_get_stats(renderer, &st, NULL);
        printf("%s: prepare %.1f ms, render %.1f ms\n", argv[3], st.prepare_ms, st.frame_ms);
    }
    lu_renderer_destroy(renderer);
    lu_image_destroy(&image);
    lu_scene_destroy(&scene);
    return rc;
}
