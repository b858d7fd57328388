/* lu_raymarch_gpu.glsl — the GPU hooks of lu_view_march.h (GLSL only): the
 * per-frame buffers the CPU builds (methods/common/media_ray.h) at bindings
 * LU_SCENE_BINDING_FREE + 0..4 (camera hits, media spans, packed light
 * views, view table, shadow maps) and the shadow map resolution u_map_res.
 * Shared by raymarch.comp and afm_render.comp; include after
 * lu_scene_gpu.glsl and lu_lightview.h. */
layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Hits { float rm_hits[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer Spans { float rm_spans[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) readonly buffer Views { vec4 rm_views[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 3) readonly buffer ViewTable { int rm_view_table[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 4) readonly buffer Shadow { float rm_shadow[]; };
#include "lu_lightview_gpu.glsl"
#include "lu_ms.h"

#define LU_RM_BINDING_NEXT (LU_SCENE_BINDING_FREE + 5)

uniform int u_map_res;
/* lu_k_rm_params.ms: octaves, a, b, c (lu_ms.h) */
uniform vec4 u_ms;

lu_k_ms lu_rm_ms_uniform() { return lu_k_ms_make(int(u_ms.x), u_ms.y, u_ms.z, u_ms.w); }

float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j) { return rm_shadow[(map * u_map_res + j) * u_map_res + i]; }
int lu_k_rm_view_first(LU_CTX_PARAM, int l) { return rm_view_table[2 * l]; }
int lu_k_rm_view_count(LU_CTX_PARAM, int l) { return rm_view_table[2 * l + 1]; }
lu_k_lightview lu_k_rm_view(LU_CTX_PARAM, int v) {
    return lu_k_lightview_unpack(rm_views[4 * v], rm_views[4 * v + 1], rm_views[4 * v + 2], rm_views[4 * v + 3]);
}
float lu_k_rm_hit_fetch(LU_CTX_PARAM, int pixel, int k) { return rm_hits[pixel * 16 + k]; }
float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int end) {
    return rm_spans[(pixel * lu_scene_medium_count() + m) * 2 + end];
}
