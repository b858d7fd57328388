/* Internal: Embree accelerators methods build from a scene — all opaque
 * (diffuse) objects in one, and one per boundary mesh — shared by
 * reference, raymarch and ddod. */
#ifndef LU_METHODS_OPAQUE_ACCEL_H
#define LU_METHODS_OPAQUE_ACCEL_H

#include <lucent/lucent.h>

/* The scene's opaque objects in one accelerator: *out stays NULL when there
 * are none; (*object)[mesh_id] is the scene object index of each mesh id
 * (malloc'd, NULL when none). On failure nothing is left allocated. */
lu_result lu_opaque_accel_build(const lu_scene *scene, lu_accel **out, int **object, lu_error *err);

/* One mesh in its own committed accelerator. */
lu_result lu_mesh_accel_build(const lu_mesh *mesh, lu_accel **out, lu_error *err);

#endif
