/* libFuzzer target: the Wavefront OBJ loader. */
#include "fuzz_file.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    return lu_fuzz_mesh_load(data, size, "obj", lu_mesh_load_obj);
}
