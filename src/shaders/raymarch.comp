/* raymarch.comp — the raymarch method on the GPU: one invocation per pixel
 * running kernels/lu_raymarch.h over the shared GPU scene
 * (kernels/lu_scene_gpu.glsl) and the frame buffers the CPU built (opaque
 * hits, bounded-media spans, light views, shadow maps). One dispatch marches
 * steps [u_seg_begin, u_seg_end) and keeps (L, tau) per pixel in RmState; the
 * last one (u_finish = 1) adds the ray's end and writes the pixel (see
 * lu_k_rm_segment for why the march is split). */
layout(local_size_x = 8, local_size_y = 8) in;

#include "../kernels/lu_scene_gpu.glsl"
#include "../kernels/lu_lightview.h"

layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Hits { float rm_hits[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer Spans { float rm_spans[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) readonly buffer Views { vec4 rm_views[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 3) readonly buffer ViewTable { int rm_view_table[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 4) readonly buffer Shadow { float rm_shadow[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 5) writeonly buffer Out { float rm_out[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 6) buffer RmState { vec4 rm_state[]; };

uniform int u_map_res;
uniform float u_step;
uniform float u_eps;
uniform int u_jitter;
uniform vec3 u_background;
uniform int u_seg_begin;
uniform int u_seg_end;
uniform int u_finish;

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
float lu_k_rm_span(LU_CTX_PARAM, int pixel, int m, int end) {
    return rm_spans[(pixel * lu_scene_medium_count() + m) * 2 + end];
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
    vec3 o = lu_scene_camera_position();
    vec3 L = vec3(0.0), tau = vec3(0.0);
    if (u_seg_begin > 0) {
        L = rm_state[2 * px].xyz;
        tau = rm_state[2 * px + 1].xyz;
    }
    lu_k_rm_segment(0, P, px, o, d, lu_k_rm_jitter(P.jitter, px), u_seg_begin, u_seg_end, L, tau);
    if (u_finish == 0) {
        rm_state[2 * px] = vec4(L, 0.0);
        rm_state[2 * px + 1] = vec4(tau, 0.0);
        return;
    }
    L = lu_k_rm_finish(0, P, px, o, d, L, tau);
    rm_out[3 * px] = L.x;
    rm_out[3 * px + 1] = L.y;
    rm_out[3 * px + 2] = L.z;
}
