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

#endif
