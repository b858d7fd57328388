/* raymarch.comp — the raymarch method on the GPU: one invocation per pixel
 * running kernels/lu_raymarch.h over the shared GPU scene
 * (kernels/lu_scene_gpu.glsl) and the frame buffers the CPU built (opaque
 * hits, bounded-media spans, light views, shadow maps). */
layout(local_size_x = 8, local_size_y = 8) in;

#include "../kernels/lu_scene_gpu.glsl"
#include "../kernels/lu_lightview.h"

#include "../kernels/lu_raymarch_gpu.glsl"

layout(std430, binding = LU_RM_BINDING_NEXT) writeonly buffer Out { float rm_out[]; };

uniform float u_step;
uniform float u_eps;
uniform int u_jitter;
uniform vec3 u_background;

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
