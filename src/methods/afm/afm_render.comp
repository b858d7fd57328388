/* afm_render.comp — the afm view march on the GPU: one invocation per
 * pixel of rows [u_row0, u_row0 + rows of this dispatch), running
 * lu_k_afm_radiance (methods/afm/lu_afm.h over lu_view_march.h's march) with the
 * maps afm_build.comp wrote and the CPU's camera/shadow buffers. */
layout(local_size_x = 8, local_size_y = 8) in;

#include "kernels/lu_scene_gpu.glsl"
#include "methods/common/lu_lightview.h"
#include "methods/common/lu_view_march_gpu.glsl"

layout(std430, binding = LU_RM_BINDING_NEXT) readonly buffer CamNormals { float afm_cam_normals[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 1) readonly buffer AfmViews { vec4 afm_views[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 2) readonly buffer AfmTable { int afm_table[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 3) readonly buffer AfmRecords { float afm_records[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 4) readonly buffer AfmSurfaces { float afm_surfaces[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 5) writeonly buffer Out { float afm_out[]; };
layout(std430, binding = LU_RM_BINDING_NEXT + 6) readonly buffer SurfaceVis { float afm_surface_vis[]; };

uniform float u_step;
uniform float u_eps;
uniform int u_jitter;
uniform float u_t_cut;
uniform vec3 u_background;
uniform int u_res;
uniform int u_coefs;
uniform int u_samples;
uniform int u_channels;
uniform int u_row0;

int lu_k_afm_param(LU_CTX_PARAM, int i) { return i == 0 ? u_res : (i == 1 ? u_coefs : (i == 2 ? u_samples : u_channels)); }
float lu_k_afm_fetch(LU_CTX_PARAM, int base, int i) { return afm_records[base + i]; }
int lu_k_afm_view_first(LU_CTX_PARAM, int l) { return afm_table[2 * l]; }
int lu_k_afm_view_count(LU_CTX_PARAM, int l) { return afm_table[2 * l + 1]; }
lu_k_lightview lu_k_afm_view(LU_CTX_PARAM, int v) {
    return lu_k_lightview_unpack(afm_views[4 * v], afm_views[4 * v + 1], afm_views[4 * v + 2], afm_views[4 * v + 3]);
}
float lu_k_afm_cam_normal(LU_CTX_PARAM, int pixel, int m, int k) {
    return afm_cam_normals[(pixel * lu_scene_medium_count() + m) * 6 + k];
}
float lu_k_afm_surface_vis(LU_CTX_PARAM, int pixel, int l) { return afm_surface_vis[pixel * lu_scene_light_count() + l]; }
float lu_k_afm_surface(LU_CTX_PARAM, int m, int k) { return afm_surfaces[m * 8 + k]; }
/* Build-only hooks, unused by the render path. */
float lu_k_afm_lspan(LU_CTX_PARAM, int texel, int m, int k) { return 0.0; }
void lu_k_afm_store(LU_CTX_PARAM, int texel, int i, float v) {}

#include "lu_afm.h"

void main() {
    int x = int(gl_GlobalInvocationID.x), y = u_row0 + int(gl_GlobalInvocationID.y);
    int w = lu_scene_width();
    if (x >= w || y >= lu_scene_height()) return;
    lu_k_rm_params R;
    R.background = u_background;
    R.step = u_step;
    R.eps = u_eps;
    R.jitter = u_jitter;
    R.map_res = u_map_res;
    R.t_cut = u_t_cut;
    R.ms = lu_rm_ms_uniform();
    int px = y * w + x;
    vec3 d = lu_k_camera_dir(lu_scene_camera(), float(x) + 0.5, float(y) + 0.5);
    vec3 L = lu_k_afm_radiance(0, lu_k_afm_params_get(0), R, px, lu_scene_camera_position(), d, lu_k_rm_jitter(R.jitter, px));
    afm_out[3 * px] = L.x;
    afm_out[3 * px + 1] = L.y;
    afm_out[3 * px + 2] = L.z;
}
