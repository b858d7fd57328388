/* libFuzzer target for the scene parser (JSON syntax, the strict contract,
 * procedural generators it calls). Seed it with the bundled scenes:
 *   build-fuzz/fuzz_scene -rss_limit_mb=4096 -timeout=20 corpus/ ../scenes/
 * File references resolve against the current directory. */
#include <lucent/scene.h>

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    lu_scene scene;
    lu_error err;
    if (lu_scene_load_string(text, "fuzz.json", &scene, &err) == LU_OK) lu_scene_destroy(&scene);
    free(text);
    return 0;
}
