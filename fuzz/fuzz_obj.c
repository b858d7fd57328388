/* libFuzzer target: the Wavefront OBJ loader. The loader reads files, so the
 * input goes to a private temporary file first. */
#define _POSIX_C_SOURCE 200809L /* mkstemp, fdopen */

#include <lucent/mesh.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    char path[] = "/tmp/lu_fuzz_obj_XXXXXX";
    int fd = mkstemp(path);
    if (fd < 0) return 0;
    FILE *fp = fdopen(fd, "wb");
    if (!fp) {
        close(fd);
        unlink(path);
        return 0;
    }
    size_t written = fwrite(data, 1, size, fp);
    fclose(fp);
    if (written == size) {
        lu_mesh mesh;
        lu_error err;
        if (lu_mesh_load_obj(path, &mesh, &err) == LU_OK) {
            /* Touch the result so a bad index or count shows up under ASan. */
            volatile double sink = lu_mesh_area(&mesh) + lu_mesh_volume(&mesh);
            (void)sink;
            lu_mesh_destroy(&mesh);
        }
    }
    unlink(path);
    return 0;
}
