/* lucent view --script: the scripted camera and light orbits. */
#include "view_script.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

bool lu_view_script_parse(const char *s, lu_view_script *out) {
    if (strcmp(s, "orbit") == 0) *out = LU_VIEW_SCRIPT_ORBIT;
    else if (strcmp(s, "light") == 0) *out = LU_VIEW_SCRIPT_LIGHT;
    else if (strcmp(s, "play") == 0) *out = LU_VIEW_SCRIPT_PLAY;
    else if (strcmp(s, "soak") == 0) *out = LU_VIEW_SCRIPT_SOAK;
    else return false;
    return true;
}

const char *lu_view_script_name(lu_view_script kind) {
    return kind == LU_VIEW_SCRIPT_ORBIT ? "orbit" : kind == LU_VIEW_SCRIPT_LIGHT ? "light"
                                      : kind == LU_VIEW_SCRIPT_PLAY  ? "play"
                                      : kind == LU_VIEW_SCRIPT_SOAK  ? "soak"
                                                                     : "none";
}

bool lu_view_script_check(const lu_scene *scene, lu_view_script kind, char *why, size_t why_size) {
    if (kind == LU_VIEW_SCRIPT_PLAY && !lu_scene_animated(scene)) {
        snprintf(why, why_size, "nothing in the scene follows time (no sequence, no animated procedural)");
        return false;
    }
    if (kind != LU_VIEW_SCRIPT_LIGHT && kind != LU_VIEW_SCRIPT_SOAK) return true;
    if (scene->light_count == 0) {
        snprintf(why, why_size, "the scene has no light to orbit");
        return false;
    }
    if (scene->lights[0].type == LU_LIGHT_ENVIRONMENT) {
        snprintf(why, why_size,
                 "the scene's first light is an environment light (it has no position or direction to turn)");
        return false;
    }
    return true;
}

/* Rodrigues' rotation of v by angle a about the unit axis u. Computed in
 * double so frame k's state does not depend on float rounding of the angle. */
static lu_vec3 turn(lu_vec3 v, lu_vec3 u, double a) {
    double c = cos(a), s = sin(a), d = (double)u.x * v.x + (double)u.y * v.y + (double)u.z * v.z;
    double cx = (double)u.y * v.z - (double)u.z * v.y, cy = (double)u.z * v.x - (double)u.x * v.z,
           cz = (double)u.x * v.y - (double)u.y * v.x;
    return lu_v3((float)(v.x * c + cx * s + u.x * d * (1 - c)), (float)(v.y * c + cy * s + u.y * d * (1 - c)),
                 (float)(v.z * c + cz * s + u.z * d * (1 - c)));
}

static lu_vec3 turn_about(lu_vec3 p, lu_vec3 pivot, lu_vec3 u, double a) {
    return lu_v3_add(pivot, turn(lu_v3_sub(p, pivot), u, a));
}

void lu_view_script_apply(lu_scene *scene, const lu_camera *camera0, const lu_light *light0, lu_view_script kind,
                          int frame) {
    double a = frame * LU_VIEW_SCRIPT_DEG * 3.14159265358979323846 / 180.0;
    lu_vec3 u = lu_v3_norm(camera0->up), pivot = camera0->look_at;
    if (kind == LU_VIEW_SCRIPT_ORBIT || kind == LU_VIEW_SCRIPT_SOAK)
        scene->camera.position = turn_about(camera0->position, pivot, u, a);
    if ((kind == LU_VIEW_SCRIPT_LIGHT || kind == LU_VIEW_SCRIPT_SOAK) && light0 && scene->light_count > 0) {
        lu_light *l = &scene->lights[0];
        if (l->type == LU_LIGHT_POINT || l->type == LU_LIGHT_SPOT)
            l->position = turn_about(light0->position, pivot, u, a);
        if (l->type == LU_LIGHT_SPOT || l->type == LU_LIGHT_DIRECTIONAL) l->direction = turn(light0->direction, u, a);
    }
}
