/* libFuzzer target: lu_image_load on arbitrary .exr bytes. */
#include "fuzz_file.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return lu_fuzz_image_load(data, size, "exr"); }
