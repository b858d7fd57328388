/* libFuzzer target: the Stanford PLY loader (ascii, binary, or gzip-wrapped,
 * which gzread sees through). */
#include "fuzz_file.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    return lu_fuzz_mesh_load(data, size, "ply", lu_mesh_load_ply);
}
