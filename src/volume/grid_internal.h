/* Grid helpers for the library's own loaders. */
#ifndef LU_GRID_INTERNAL_H
#define LU_GRID_INTERNAL_H

#include <lucent/grid.h>

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
