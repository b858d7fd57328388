/* Private helpers shared by accel.c and voxelize.c. */
#ifndef LU_GEOMETRY_INTERNAL_H
#define LU_GEOMETRY_INTERNAL_H

#include <lucent/geometry.h>

/* True once lu_accel_commit succeeded and no mesh was added since. */
bool lu_accel_is_committed(const lu_accel *a);

#endif
