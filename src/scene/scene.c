/* Scene lifetime, bounds and camera rays. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "kernels/lu_camera.h"
#include "scene/scene_time.h"

void lu_scene_destroy(lu_scene *s) {
    for (int i = 0; i < s->light_count; i++) lu_image_destroy(&s->lights[i].env);
    for (int i = 0; i < s->medium_count; i++) {
        lu_grid_destroy(&s->media[i].grid);
        lu_grid_destroy(&s->media[i].emission_grid);
        lu_mesh_destroy(&s->media[i].boundary);
        lu_grid_anim_free(s->media[i].density_anim);
        lu_grid_anim_free(s->media[i].emission_anim);
    }
    for (int i = 0; i < s->object_count; i++) lu_mesh_destroy(&s->objects[i].mesh);
    lu_free(s->lights);
    lu_free(s->media);
    lu_free(s->objects);
    memset(s, 0, sizeof *s);
}

lu_result lu_scene_medium_grid(lu_scene *s, int medium, lu_grid **grid, lu_error *err) {
    if (grid) *grid = NULL;
    if (!s || !grid) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_scene_medium_grid: no scene or no output");
    if (medium < 0 || medium >= s->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: no medium %d (the scene has %d)", s->path, medium,
                       s->medium_count);
    if (s->media[medium].kind != LU_DENSITY_GRID)
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: medium %d has constant density: there is no grid to edit", s->path,
                       medium);
    *grid = &s->media[medium].grid;
    return LU_OK;
}

lu_aabb lu_scene_media_bounds(const lu_scene *s) {
    lu_aabb b = lu_aabb_empty();
    for (int i = 0; i < s->medium_count; i++) {
        if (!lu_aabb_valid(s->media[i].bounds)) continue;
        lu_aabb_grow(&b, s->media[i].bounds.lo);
        lu_aabb_grow(&b, s->media[i].bounds.hi);
    }
    return b;
}

lu_aabb lu_scene_bounds(const lu_scene *s) {
    lu_aabb b = lu_scene_media_bounds(s);
    for (int i = 0; i < s->object_count; i++) {
        lu_aabb ob = lu_mesh_bounds(&s->objects[i].mesh);
        if (!lu_aabb_valid(ob)) continue;
        lu_aabb_grow(&b, ob.lo);
        lu_aabb_grow(&b, ob.hi);
    }
    return b;
}

void lu_camera_ray(const lu_camera *cam, float px, float py, lu_vec3 *o, lu_vec3 *d) {
    lu_k_camera k = lu_k_camera_make(cam->position, cam->look_at, cam->up, cam->fov_y_deg, cam->width, cam->height);
    *o = cam->position;
    *d = lu_k_camera_dir(k, px, py);
}
