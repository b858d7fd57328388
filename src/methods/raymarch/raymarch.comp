/* raymarch.comp — the raymarch method on the GPU: one invocation per pixel
 * running methods/common/lu_view_march.h over the shared GPU scene
 * (kernels/lu_scene_gpu.glsl) and the frame buffers the CPU built (opaque
 * hits, bounded-media spans, light views, shadow maps, surface visibility).
 * One dispatch marches steps [u_seg_begin, u_seg_end) and keeps (L, tau) per
 * pixel in RmState; the last one (u_finish = 1) adds the ray's end and writes
 * the pixel (see lu_k_rm_segment for why the march is split). */
layout(local_size_x = 8, local_size_y = 8) in;

#include "kernels/lu_scene_gpu.glsl"
#include "methods/common/lu_lightview.h"

#include "methods/common/lu_view_march_gpu.glsl"

layout(std430, binding = LU_RM_BINDING_NEXT) writeonly buffer Out { float rm_out[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 1) buffer RmState { vec4 rm_state[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 2) readonly buffer RmSurfaceVis { float rm_surface_vis[]; };

uniform float u_step;
uniform float u_eps;
uniform int u_jitter;
uniform float u_t_cut;
uniform vec3 u_background;
uniform int u_seg_begin;
uniform int u_seg_end;
uniform int u_finish;

/* Surfaces are lit with the CPU's exact per-pixel visibility (raymarch.c). */
float lu_k_rm_surface_vis(LU_CTX_PARAM, int pixel, int l) { return rm_surface_vis[pixel * lu_scene_light_count() + l]; }
#define LU_K_RM_SURFACE_VIS(l, pixel, x, n) lu_k_rm_surface_vis(LU_CTX, pixel, l)

#include "methods/common/lu_view_march.h"

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
    P.t_cut = u_t_cut;
    P.ms = lu_rm_ms_uniform();
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
