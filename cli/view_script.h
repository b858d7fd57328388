/* Scripted interactions for `lucent view --script`: each frame of the script
 * sets the scene to the start state turned by LU_VIEW_SCRIPT_DEG degrees per
 * frame, so frame k's state is known in closed form (tests build it too). */
#ifndef LU_VIEW_SCRIPT_H
#define LU_VIEW_SCRIPT_H

#include <lucent/lucent.h>

#define LU_VIEW_SCRIPT_DEG 4.0

typedef enum lu_view_script {
    LU_VIEW_SCRIPT_NONE = 0,
    LU_VIEW_SCRIPT_ORBIT,   /* the camera orbits its look_at about its up axis */
    LU_VIEW_SCRIPT_LIGHT,   /* the first light orbits the camera's look_at about the camera's up axis */
    LU_VIEW_SCRIPT_PLAY,    /* the scene's time advances one frame (1 / fps) per frame; the viewer sets it
                             * (lu_scene_set_time may fail), lu_view_script_apply leaves the scene alone */
    LU_VIEW_SCRIPT_SOAK,    /* orbit and light together; the viewer also switches to the next method every
                             * LU_VIEW_SOAK_METHOD_EVERY frames and resizes its window every
                             * LU_VIEW_SOAK_RESIZE_EVERY (docs/reliability.md, "Soak") */
} lu_view_script;

#define LU_VIEW_SOAK_METHOD_EVERY 20
#define LU_VIEW_SOAK_RESIZE_EVERY 60

/* "orbit" / "light" / "play" / "soak"; false for anything else. */
bool lu_view_script_parse(const char *s, lu_view_script *out);
const char *lu_view_script_name(lu_view_script kind);
/* Whether the scene can run the script; false with the reason when the light
 * script finds no first light to turn (none, or an environment light), or
 * the play script nothing that follows time. */
bool lu_view_script_check(const lu_scene *scene, lu_view_script kind, char *why, size_t why_size);
/* Frame `frame` of the script: from the start state (camera0, and light0, the
 * first light as loaded; NULL when there is none), the camera (orbit) or
 * the first light (light) turned by frame * LU_VIEW_SCRIPT_DEG degrees, right
 * handed about the axis through camera0.look_at along camera0.up. A point or
 * spot light turns its position about that axis and a spot or directional
 * light its direction; nothing else in the scene changes. */
void lu_view_script_apply(lu_scene *scene, const lu_camera *camera0, const lu_light *light0, lu_view_script kind,
                          int frame);

#endif
