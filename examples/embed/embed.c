/* Embedding lucent: a program outside the lucent tree that finds the
 * installed package (CMake: find_package(lucent); or pkg-config lucent),
 * installs its own host hooks, renders a scene into CPU memory and saves it.
 *
 *   embed SCENE.json OUT.png [METHOD [WxH [method.param=value ...]]]
 *
 * GPU methods render into lucent's own headless context here and hand the
 * image back in CPU memory; embed_window.c renders into a texture of the
 * program's own window instead. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>

/* The host's hooks: the library's allocations and messages pass here. */
typedef struct app {
    size_t allocations;
    int messages;
} app;

static void *app_alloc(size_t size, void *user) {
    ((app *)user)->allocations++;
    return malloc(size);
}
static void *app_realloc(void *ptr, size_t size, void *user) { return realloc(ptr, size); }
static void app_free(void *ptr, void *user) { free(ptr); }
static void app_log(lu_log_level level, const char *message, void *user) {
    ((app *)user)->messages++;
    fprintf(stderr, "[lucent %s] %s", level == LU_LOG_ERROR ? "error" : level == LU_LOG_WARNING ? "warning" : "info",
            message);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s SCENE.json OUT.png [METHOD [WxH [method.param=value ...]]]\n", argv[0]);
        return 2;
    }
    /* A shared liblucent of another major version is not this API. */
    if ((lu_version() >> 16) != LU_VERSION_MAJOR || ((lu_version() >> 8) & 0xff) != LU_VERSION_MINOR) {
        fprintf(stderr, "built against lucent %s, running with %s\n", LU_VERSION_STRING, lu_version_string());
        return 1;
    }
    app a = {0};
    lu_host host = {.alloc = app_alloc, .realloc = app_realloc, .free = app_free, .log = app_log,
                    .quiet = true, .user = &a};
    lu_error err = {0};
    lu_scene scene = {0};
    lu_image image = {0};
    lu_renderer *r = NULL;
    int rc = 1;
    if (lu_host_set(&host, &err) != LU_OK || lu_scene_load(argv[1], &scene, &err) != LU_OK) goto done;
    int w = 0, h = 0;
    if (argc > 4 && (sscanf(argv[4], "%dx%d", &w, &h) != 2 || w < 1 || h < 1)) {
        fprintf(stderr, "size \"%s\": expected WxH\n", argv[4]);
        goto done;
    }
    if (w > 0) {
        scene.camera.width = w;
        scene.camera.height = h;
    }
    /* Zero is the default of every field: the method's default parameters,
     * the backend AUTO (a hardware GPU, else the CPU). */
    lu_renderer_desc desc = {.method = argc > 3 ? argv[3] : NULL, .set = argc > 5 ? (const char *const *)argv + 5 : NULL};
    if (lu_renderer_make(&desc, &scene, &r, &err) != LU_OK || lu_renderer_render(r, &scene, &image, &err) != LU_OK ||
        lu_image_save(&image, argv[2], NULL, &err) != LU_OK)
        goto done;
    lu_renderer_stats st;
    if (lu_renderer_get_stats(r, &st, &err) != LU_OK) goto done;
    printf("%s: %dx%d, %s on %s (lucent %s): prepare %.1f ms, frame update %.2f ms, render %.1f ms; "
           "%zu allocations through the host\n",
           argv[2], image.width, image.height, st.method, lu_backend_name(st.backend), lu_version_string(),
           st.prepare_ms, st.frame_update_ms, st.render_ms, a.allocations);
    rc = 0;
done:
    if (rc != 0) fprintf(stderr, "embed: %s\n", err.message);
    lu_renderer_destroy(r);
    lu_image_destroy(&image);
    lu_scene_destroy(&scene);
    return rc;
}
