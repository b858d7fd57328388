/* libFuzzer target for .vdb input: the input goes to a temporary .vdb file
 * that lu_grid_load_vdb hands to the converter child (lucent-vdb-convert,
 * found beside this program), so what is exercised is the library's side of
 * the process boundary (spawn, exit status and signal decoding, reading the
 * converted image back through the NanoVDB reader) and the claim that no
 * input reaches this process as a crash. OpenVDB itself runs in the child,
 * uninstrumented: coverage does not guide mutations inside it, and each
 * input costs a process start (tens of executions a second, not
 * thousands). The lowest bit of the last byte picks selection by name or
 * the first float grid. */
#include "fuzz_file.h" /* first: it sets the feature macros */

#include <lucent/grid.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    char path[64];
    if (!lu_fuzz_temp_file(data, size, "vdb", path)) return 0;
    lu_grid g;
    lu_error err;
    const char *name = size && (data[size - 1] & 1u) ? "density" : NULL;
    if (lu_grid_load_vdb(path, name, &g, &err) == LU_OK) {
        volatile float sink = lu_grid_sample(&g, lu_v3(0.5f * g.nx, 0.5f * g.ny, 0.5f * g.nz));
        (void)sink;
        lu_grid_destroy(&g);
    } else if (!strstr(err.message, path)) {
        /* Every failure names the file it is about. */
        __builtin_trap();
    }
    unlink(path);
    return 0;
}
