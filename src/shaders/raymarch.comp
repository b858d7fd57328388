/* raymarch.comp — the raymarch method on the GPU: one invocation per pixel
 * running kernels/lu_raymarch.h over the shared GPU scene
 * (kernels/lu_scene_gpu.glsl) and the frame buffers the CPU built (opaque
 * hits, bounded-media spans, light views, shadow maps). */
layout(local_size_x = 8, local_size_y = 8) in;

#include "../kernels/lu_scene_gpu.glsl"
#include "../kernels/lu_lightview.h"

layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Hits { float rm_hits[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer Spans { float rm_spans[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) readonly buffer Views { vec4 rm_views[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 3) readonly buffer ViewTable { int rm_view_table[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 4) readonly buffer Shadow { float rm_shadow[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 5) readonly buffer BMaps { float rm_bmaps[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 6) writeonly buffer Out { float rm_out[]; };

uniform int u_map_res;
uniform float u_step;
uniform float u_eps;
uniform int u_jitter;
uniform vec3 u_background;

float lu_k_shadow_depth(LU_CTX_PARAM, int map, int i, int j) { return rm_shadow[(map * u_map_res + j) * u_map_res + i]; }
int lu_k_rm_view_first(LU_CTX_PARAM, int l) { return rm_view_table[2 * l]; }
int lu_k_rm_view_count(LU_CTX_PARAM, int l) { return rm_view_table[2 * l + 1]; }
lu_k_lightview lu_k_rm_view(LU_CTX_PARAM, int v) {
    lu_k_lightview w;
    w.origin = rm_views[4 * v].xyz;
    w.ortho = int(rm_views[4 * v].w);
    w.axis_u = rm_views[4 * v + 1].xyz;
    w.extent_u = rm_views[4 * v + 1].w;
    w.axis_v = rm_views[4 * v + 2].xyz;
    w.extent_v = rm_views[4 * v + 2].w;
    w.axis_w = rm_views[4 * v + 3].xyz;
    w.depth_far = rm_views[4 * v + 3].w;
    return w;
}
float lu_k_rm_hit_fetch(LU_CTX_PARAM, int pixel, int k) { return rm_hits[pixel * 16 + k]; }
float lu_k_rm_bmap(LU_CTX_PARAM, int map, int i, int j, int k) {
    return rm_bmaps[((map * u_map_res + j) * u_map_res + i) * 4 + k]; // 4: LU_K_RM_BMAP_FLOATS (defined after these hooks)
}
float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int k) {
    return rm_spans[(pixel * lu_scene_medium_count() + m) * 16 + k]; // 16: LU_K_RM_SPAN_FLOATS
}

#include "../kernels/lu_raymarch.h"

void main() {
    int x = int(gl_GlobalInvocationID.x), y = int(gl_GlobalInvocationID.y);
    int w = lu_scene_width();
    if (x >= w || y >= lu_scene_height()) return;
    lu_k_rm_params P;
    P.background = u_background;
    P.step = u_step;
    P.eps = u_eps;
    P.jitter = u_jitter;
    P.map_res = u_map_res;
    P.pad = 0;
    int px = y * w + x;
    vec3 d = lu_k_camera_dir(lu_scene_camera(), float(x) + 0.5, float(y) + 0.5);
    vec3 L = lu_k_rm_radiance(0, P, px, lu_scene_camera_position(), d, lu_k_rm_jitter(P.jitter, px));
    rm_out[3 * px] = L.x;
    rm_out[3 * px + 1] = L.y;
    rm_out[3 * px + 2] = L.z;
}
