/* lu_grid_tree.h — density of a sparse grid: a NanoVDB float tree read in
 * place through PNanoVDB.h, in C (the CPU samplers, src/volume/grid.c) and
 * in GLSL (lu_scene_gpu.glsl, the tree in a storage buffer), from this one
 * source (docs/architecture.md §5, docs/volumes.md "Sparse grids").
 *
 * Index space is lucent/grid.h's: voxel (x, y, z) is tree voxel
 * lo + (x, y, z); every voxel outside [0, n-1] reads 0 (even where the tree
 * holds an inactive value there), so the field equals the dense expansion
 * of the same tree. lu_tree_sample is lu_grid_sample's arithmetic, operation
 * for operation, so the two agree bit for bit on the CPU.
 *
 * C: PNanoVDB runs with its buffer bounds check (a read past the buffer
 * gives 0), the same setting the loader validates the tree with.
 * GLSL: the includer declares the storage buffer as `pnanovdb_buf_data`
 * (a uint array, possibly through a #define) before including this. */
#ifndef LU_GRID_TREE_H
#define LU_GRID_TREE_H

#include "lu_kernel.h"

#ifdef LU_GLSL
#define PNANOVDB_GLSL
#include "nanovdb/PNanoVDB.h"
#else
#define PNANOVDB_C
#ifndef PNANOVDB_BUF_BOUNDS_CHECK
#define PNANOVDB_BUF_BOUNDS_CHECK
#endif
#include <nanovdb/PNanoVDB.h>
#endif

struct lu_k_tree {
    pnanovdb_buf_t buf;
    pnanovdb_root_handle_t root;
    int lo_x, lo_y, lo_z;      /* tree coordinate of index 0 */
    int nx, ny, nz;            /* the index box */
};
LU_TYPEDEF(lu_k_tree)

/* The GPU reads trees of at most this many root tiles (each 4096^3 voxels;
 * a box up to 4096 a side meets at most 8), checked without a loop: Mesa's
 * llvmpipe ends every loop of an invocation after 65535 iterations in
 * total (docs/architecture.md §5), and PNanoVDB's root search is a loop run
 * at every sample that misses the cached nodes. */
#define LU_TREE_GPU_ROOT_TILES 8

#ifdef LU_GLSL
#define LU_TREE_ROOT_TRY(i)                                                                                            \
    if (i < count && pnanovdb_address_is_null(found.address)) {                                                      \
        pnanovdb_root_tile_handle_t tile = pnanovdb_root_get_tile(PNANOVDB_GRID_TYPE_FLOAT, t.root, i);               \
        if (pnanovdb_uint64_is_equal(key, pnanovdb_root_tile_get_key(t.buf, tile))) found = tile;                     \
    }
/* pnanovdb_root_get_value_address_and_cache with the search unrolled. */
pnanovdb_address_t lu_tree_root_address(lu_k_tree t, inout pnanovdb_readaccessor_t acc, pnanovdb_coord_t ijk) {
    const pnanovdb_grid_type_t gt = PNANOVDB_GRID_TYPE_FLOAT;
    uint count = pnanovdb_root_get_tile_count(t.buf, t.root);
    pnanovdb_uint64_t key = pnanovdb_coord_to_key(ijk);
    pnanovdb_root_tile_handle_t found;
    found.address = pnanovdb_address_null();
    LU_TREE_ROOT_TRY(0u) LU_TREE_ROOT_TRY(1u) LU_TREE_ROOT_TRY(2u) LU_TREE_ROOT_TRY(3u)
    LU_TREE_ROOT_TRY(4u) LU_TREE_ROOT_TRY(5u) LU_TREE_ROOT_TRY(6u) LU_TREE_ROOT_TRY(7u)
    if (pnanovdb_address_is_null(found.address))
        return pnanovdb_address_offset(t.root.address, PNANOVDB_GRID_TYPE_GET(gt, root_off_background));
    if (pnanovdb_int64_is_zero(pnanovdb_root_tile_get_child(t.buf, found)))
        return pnanovdb_address_offset(found.address, PNANOVDB_GRID_TYPE_GET(gt, root_tile_off_value));
    pnanovdb_upper_handle_t child = pnanovdb_root_get_child(gt, t.buf, t.root, found);
    acc.upper = child;
    acc.key = ijk;
    return pnanovdb_upper_get_value_address_and_cache(gt, t.buf, child, ijk, acc);
}
#endif

/* Voxel (x, y, z), 0 outside the index box; acc caches the path to the
 * last leaf, so neighbouring reads skip the root. The cascade is PNanoVDB's
 * pnanovdb_readaccessor_get_value_address; only the GPU's root stage is
 * lu_tree_root_address. */
LU_FN float lu_tree_at(lu_k_tree t, PNANOVDB_INOUT(pnanovdb_readaccessor_t) acc, int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= t.nx || y >= t.ny || z >= t.nz) return 0.0f;
    const pnanovdb_grid_type_t gt = PNANOVDB_GRID_TYPE_FLOAT;
    pnanovdb_coord_t ijk;
    ijk.x = t.lo_x + x;
    ijk.y = t.lo_y + y;
    ijk.z = t.lo_z + z;
#ifdef LU_GLSL
    pnanovdb_address_t a;
    int dirty = pnanovdb_readaccessor_computedirty(acc, ijk);
    if (pnanovdb_readaccessor_iscached0(acc, dirty))
        a = pnanovdb_leaf_get_value_address_and_cache(gt, t.buf, acc.leaf, ijk, acc);
    else if (pnanovdb_readaccessor_iscached1(acc, dirty))
        a = pnanovdb_lower_get_value_address_and_cache(gt, t.buf, acc.lower, ijk, acc);
    else if (pnanovdb_readaccessor_iscached2(acc, dirty))
        a = pnanovdb_upper_get_value_address_and_cache(gt, t.buf, acc.upper, ijk, acc);
    else
        a = lu_tree_root_address(t, acc, ijk);
#else
    pnanovdb_address_t a = pnanovdb_readaccessor_get_value_address(gt, t.buf, acc, PNANOVDB_REF(ijk));
#endif
    return pnanovdb_read_float(t.buf, a);
}

LU_FN float lu_tree_voxel(lu_k_tree t, int x, int y, int z) {
    pnanovdb_readaccessor_t acc;
    pnanovdb_readaccessor_init(PNANOVDB_REF(acc), t.root);
    return lu_tree_at(t, PNANOVDB_REF(acc), x, y, z);
}

/* Trilinear at an index-space position, zero outside (lu_grid_sample). */
LU_FN float lu_tree_sample(lu_k_tree t, vec3 p) {
    if (!(p.x >= -1.0f && p.y >= -1.0f && p.z >= -1.0f && p.x <= lu_float(t.nx) && p.y <= lu_float(t.ny) &&
          p.z <= lu_float(t.nz)))
        return 0.0f;
    int x = lu_int(p.x + 1.0f) - 1, y = lu_int(p.y + 1.0f) - 1, z = lu_int(p.z + 1.0f) - 1;
    float tx = p.x - lu_float(x), ty = p.y - lu_float(y), tz = p.z - lu_float(z);
    pnanovdb_readaccessor_t acc;
    pnanovdb_readaccessor_init(PNANOVDB_REF(acc), t.root);
    float c000 = lu_tree_at(t, PNANOVDB_REF(acc), x, y, z), c100 = lu_tree_at(t, PNANOVDB_REF(acc), x + 1, y, z);
    float c010 = lu_tree_at(t, PNANOVDB_REF(acc), x, y + 1, z), c110 = lu_tree_at(t, PNANOVDB_REF(acc), x + 1, y + 1, z);
    float c001 = lu_tree_at(t, PNANOVDB_REF(acc), x, y, z + 1), c101 = lu_tree_at(t, PNANOVDB_REF(acc), x + 1, y, z + 1);
    float c011 = lu_tree_at(t, PNANOVDB_REF(acc), x, y + 1, z + 1);
    float c111 = lu_tree_at(t, PNANOVDB_REF(acc), x + 1, y + 1, z + 1);
    float c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
    float c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
    float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
}

#endif
