/* Grid helpers for the library's own loaders. */
#ifndef LU_GRID_INTERNAL_H
#define LU_GRID_INTERNAL_H

#include <lucent/grid.h>

/* Gives a grid built without lu_grid_alloc (the voxeliser fills its own
 * buffer) a fresh generation, so it never shares a stamp with another grid. */
void lu_grid_stamp_new(lu_grid *g);

#endif
