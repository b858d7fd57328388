/* Internal: light-space views of a scene's lights and CPU shadow maps.
 * The projection math is the kernel lu_lightview.h; this builds the views
 * (framing a region) and fills shadow maps with Embree. */
#ifndef LU_METHODS_LIGHTVIEW_H
#define LU_METHODS_LIGHTVIEW_H

#include <lucent/lucent.h>

#include "methods/common/lu_lightview.h"

/* One view (spot, directional) or six cube faces (point light). */
typedef struct lu_lightviews {
    int count;
    lu_k_lightview view[6];
} lu_lightviews;

/* Views of light l framing `region` (a world box: the media, or the whole
 * scene). Environment lights have none (count 0). */
void lu_lightviews_for_light(const lu_light *l, lu_aabb region, lu_lightviews *out);

/* Views of every non-environment light of `scene` (scene order) framing
 * `region`, cube faces' extents scaled by cube_widen (1: none): *views and
 * *packed (lu_lightview_pack) hold *count views, *table per kernel light
 * its first view and view count. Frees what the three pointers held. */
lu_result lu_lightviews_for_scene(const lu_scene *scene, lu_aabb region, float cube_widen, lu_k_lightview **views,
                                  float **packed, int **table, int *count, lu_error *err);

/* Index of the view that sees x (the cube face for point lights), or -1 if
 * x is outside every view. */
int lu_lightviews_select(const lu_lightviews *v, lu_vec3 x);

/* v as 16 floats (std430 vec4[4]): origin + ortho, axis_u + extent_u,
 * axis_v + extent_v, axis_w + depth_far; GLSL unpacks the same order. */
void lu_lightview_pack(const lu_k_lightview *v, float *p);

/* Shadow map of `opaque` (may be NULL: nothing casts) for view v: res x res
 * depths of the first hit along each texel's centre ray, or `far_value`
 * where nothing is hit. depth has res*res floats, row j = v index. */
lu_result lu_shadow_map_build(const lu_accel *opaque, const lu_k_lightview *v, int res, float far_value, float *depth,
                              lu_error *err);

#endif
