/* libFuzzer target for the NanoVDB reader (container, tree walk, dense
 * expansion) through the in-memory entry point. The lowest input bit picks
 * selection by name or the first Float grid, so both paths are explored. */
#include <lucent/grid.h>

#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    lu_grid g;
    lu_error err;
    const char *name = size && (data[size - 1] & 1u) ? "density" : NULL;
    /* Both storages: the sparse walk and the dense fill read the tree differently. */
    lu_grid_storage storage = size && (data[size - 1] & 2u) ? LU_GRID_STORAGE_DENSE : LU_GRID_STORAGE_SPARSE;
    if (lu_grid_load_nvdb_memory_as(data, size, "fuzz.nvdb", name, storage, &g, &err) == LU_OK) {
        /* Sampling the result must be safe too. */
        volatile float sink = lu_grid_sample(&g, lu_v3(0.5f * g.nx, 0.5f * g.ny, 0.5f * g.nz));
        (void)sink;
        lu_grid_destroy(&g);
    }
    return 0;
}
