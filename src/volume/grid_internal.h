/* Grid helpers for the library's own loaders. */
#ifndef LU_GRID_INTERNAL_H
#define LU_GRID_INTERNAL_H

#include <lucent/grid.h>

#include "kernels/lu_grid_tree.h"

/* What a sparse grid's tree_owner points to: a file mapping or words. */
typedef struct lu_grid_tree_owner {
    void *map;
    size_t map_bytes;
    uint32_t *words;
} lu_grid_tree_owner;
void lu_grid_tree_owner_free(lu_grid_tree_owner *o);

/* The kernel view of a sparse grid's tree (lu_grid_tree.h). */
lu_k_tree lu_grid_tree_view(const lu_grid *g);

/* Every node of a sparse grid's tree that holds values (grid_tree.c): a
 * leaf (dim 8, `leaf` its 512 values, voxel (x, y, z) of the leaf at
 * leaf[(x * 8 + y) * 8 + z]) or a non-zero tile (dim 8, 128 or 4096, value
 * `tile`, leaf NULL), with its origin in tree coordinates. Regions not
 * visited hold 0. */
typedef void (*lu_tree_visit_fn)(void *ctx, const int64_t origin[3], int dim, const float *leaf, float tile);
void lu_grid_tree_visit(const lu_grid *g, lu_tree_visit_fn fn, void *ctx);
/* The index box [lo, hi) of a node within the grid's box; false if empty. */
bool lu_grid_tree_clip(const lu_grid *g, const int64_t origin[3], int dim, int lo[3], int hi[3]);
/* A root tile key's upper-node origin; false for an invalid key. */
bool lu_nvdb_key_origin(uint64_t key, int64_t o[3]);

/* Gives a grid built without lu_grid_alloc (the voxeliser fills its own
 * buffer) a fresh generation, so it never shares a stamp with another grid. */
void lu_grid_stamp_new(lu_grid *g);

/* The nodes of lu_blackbody_rgb's table, LU_SCENE_BLACKBODY_N (kernels/lu_scene_layout.h)
 * RGB triples, uniform in log T over [100, 100000] K, for the GPU scene. */
void lu_blackbody_table(float *rgb);

/* Whether grid e lies in the index space of grid d: the same linear map,
 * and e's voxel 0 at the whole voxel k of d (a NanoVDB grid is loaded over
 * the box of its own active voxels, so two grids of one file, or two frames
 * of one sequence, share their index space up to such an offset). */
bool lu_grid_shared_index_space(const lu_grid *d, const lu_grid *e, int k[3]);
/* A new grid of nx x ny x nz voxels in e's index space shifted by k:
 * out(i) = e(i - k), 0 outside e; values of e outside the box are dropped.
 * out's map is index_to_world, its name e's. */
lu_result lu_grid_embed(const lu_grid *e, const int k[3], int nx, int ny, int nz, const lu_affine *index_to_world,
                        lu_grid *out, lu_error *err);

#endif
