/* Accelerators over a scene's opaque objects and boundary meshes (see opaque_accel.h). */
#include "methods/common/opaque_accel.h"

#include <stdlib.h>

lu_result lu_opaque_accel_build(const lu_scene *scene, lu_accel **out, int **object, lu_error *err) {
    *out = NULL;
    *object = NULL;
    int count = 0;
    for (int i = 0; i < scene->object_count; i++) count += scene->objects[i].material.type == LU_MATERIAL_DIFFUSE;
    if (count == 0) return LU_OK;
    int *map = lu_calloc((size_t)count, sizeof *map);
    if (!map) return lu_fail(err, LU_ERR_NOMEM, "out of memory for the opaque objects");
    lu_accel *a = NULL;
    lu_result r = lu_accel_create(&a, err);
    for (int i = 0; i < scene->object_count && r == LU_OK; i++) {
        if (scene->objects[i].material.type != LU_MATERIAL_DIFFUSE) continue;
        uint32_t id;
        r = lu_accel_add_mesh(a, &scene->objects[i].mesh, &id, err);
        if (r == LU_OK) map[id] = i;
    }
    if (r == LU_OK) r = lu_accel_commit(a, err);
    if (r != LU_OK) {
        if (a) lu_accel_destroy(a);
        lu_free(map);
        return r;
    }
    *out = a;
    *object = map;
    return LU_OK;
}

lu_result lu_mesh_accel_build(const lu_mesh *mesh, lu_accel **out, lu_error *err) {
    *out = NULL;
    lu_accel *a = NULL;
    uint32_t id;
    lu_result r = lu_accel_create(&a, err);
    if (r == LU_OK) r = lu_accel_add_mesh(a, mesh, &id, err);
    if (r == LU_OK) r = lu_accel_commit(a, err);
    if (r != LU_OK) {
        if (a) lu_accel_destroy(a);
        return r;
    }
    *out = a;
    return LU_OK;
}
