/* Shared body of the image fuzz targets: the loaders read from a path, so the
 * input goes to a per-process temporary file with the right extension.
 * Build (instrumenting the library too, so coverage guides the search):
 *   cmake -S . -B build-fuzz -DLUCENT_FUZZ=ON -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
 *         -DCMAKE_C_FLAGS=-fsanitize=fuzzer-no-link,address,undefined
 *   cmake --build build-fuzz --target fuzz_pfm fuzz_png fuzz_exr */
#ifndef LU_FUZZ_IMAGE_LOAD_H
#define LU_FUZZ_IMAGE_LOAD_H

#include <lucent/image.h>

#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

static int lu_fuzz_image_load(const uint8_t *data, size_t size, const char *ext) {
    char path[64];
    snprintf(path, sizeof path, "/tmp/lu_fuzz_%ld.%s", (long)getpid(), ext);
    FILE *fp = fopen(path, "wb");
    if (!fp) return 0;
    size_t written = fwrite(data, 1, size, fp);
    fclose(fp);
    if (written == size) {
        lu_image img;
        lu_error err;
        if (lu_image_load(path, &img, &err) == LU_OK) lu_image_destroy(&img);
    }
    remove(path);
    return 0;
}

#endif
