/* What the file-reading fuzz targets share: the loaders read from a path, so
 * each input goes to a private temporary file with the loader's extension
 * (gzip-wrapped PLY is recognised by content, not by name).
 * Build (instrumenting the library too, so coverage guides the search):
 *   cmake -S . -B build-fuzz -DLUCENT_FUZZ=ON -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
 *         -DCMAKE_C_FLAGS=-fsanitize=fuzzer-no-link,address,undefined
 *   cmake --build build-fuzz --target fuzz_pfm fuzz_png fuzz_exr fuzz_obj fuzz_ply */
#ifndef LU_FUZZ_FILE_H
#define LU_FUZZ_FILE_H

#define _POSIX_C_SOURCE 200809L /* mkstemps, fdopen */
#define _DEFAULT_SOURCE         /* mkstemps */

#include <lucent/image.h>
#include <lucent/mesh.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Writes the input to /tmp/lu_fuzz_XXXXXX.<ext>; returns 1 with its name in
 * path (unlink it after), 0 when it could not be written whole. */
static inline int lu_fuzz_temp_file(const uint8_t *data, size_t size, const char *ext, char path[64]) {
    snprintf(path, 64, "/tmp/lu_fuzz_XXXXXX.%s", ext);
    int fd = mkstemps(path, (int)strlen(ext) + 1);
    if (fd < 0) return 0;
    FILE *fp = fdopen(fd, "wb");
    if (!fp) {
        close(fd);
        unlink(path);
        return 0;
    }
    size_t written = fwrite(data, 1, size, fp);
    if (fclose(fp) != 0 || written != size) {
        unlink(path);
        return 0;
    }
    return 1;
}

static inline int lu_fuzz_image_load(const uint8_t *data, size_t size, const char *ext) {
    char path[64];
    if (!lu_fuzz_temp_file(data, size, ext, path)) return 0;
    lu_image img;
    lu_error err;
    if (lu_image_load(path, &img, &err) == LU_OK) lu_image_destroy(&img);
    unlink(path);
    return 0;
}

typedef lu_result (*lu_fuzz_mesh_loader)(const char *path, lu_mesh *out, lu_error *err);

static inline int lu_fuzz_mesh_load(const uint8_t *data, size_t size, const char *ext, lu_fuzz_mesh_loader load) {
    char path[64];
    if (!lu_fuzz_temp_file(data, size, ext, path)) return 0;
    lu_mesh mesh;
    lu_error err;
    if (load(path, &mesh, &err) == LU_OK) {
        /* Touch the result so a bad index or count shows up under ASan. */
        volatile double sink = lu_mesh_area(&mesh) + lu_mesh_volume(&mesh);
        (void)sink;
        lu_mesh_destroy(&mesh);
    }
    unlink(path);
    return 0;
}

#endif
