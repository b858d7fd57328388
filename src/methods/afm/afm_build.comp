/* afm_build.comp — builds the attenuation function maps on the GPU: one
 * invocation per texel (x, y) of view z, running lu_k_afm_build_texel
 * (methods/afm/lu_afm.h) over the shared GPU scene. The light-ray boundary
 * spans of bounded media and the cosines at their crossings come from the
 * CPU (Embree). */
layout(local_size_x = 8, local_size_y = 8) in;

#include "kernels/lu_scene_gpu.glsl"
#include "methods/common/lu_lightview.h"
#include "methods/common/lu_lightview_gpu.glsl"

layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer AfmViews { vec4 afm_views[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer AfmLspans { float afm_lspans[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) writeonly buffer AfmRecords { float afm_records[]; };

uniform int u_res;
uniform int u_coefs;
uniform int u_samples;
uniform int u_channels;
uniform int u_bounded;
uniform int u_view0;   /* first view of this dispatch (chunks keep dispatches short) */

float lu_k_afm_lspan(LU_CTX_PARAM, int texel, int m, int k) {
    /* unbounded: the whole ray, no crossing (2.0 = LU_K_AFM_NO_CROSSING) */
    if (u_bounded == 0) return k == 1 ? LU_K_FAR : (k == 0 ? 0.0 : 2.0);
    return afm_lspans[(texel * lu_scene_medium_count() + m) * 4 + k];
}
void lu_k_afm_store(LU_CTX_PARAM, int texel, int i, float v) {
    afm_records[texel * (6 + u_coefs * u_channels) + i] = v;
}

#define LU_K_AFM_MAP_ONLY 1
#include "lu_afm.h"

void main() {
    int x = int(gl_GlobalInvocationID.x), y = int(gl_GlobalInvocationID.y), v = u_view0 + int(gl_GlobalInvocationID.z);
    if (x >= u_res || y >= u_res) return;
    lu_k_afm_params P;
    P.res = u_res;
    P.coefs = u_coefs;
    P.samples = u_samples;
    P.channels = u_channels;
    lu_k_lightview vw = lu_k_lightview_unpack(afm_views[4 * v], afm_views[4 * v + 1], afm_views[4 * v + 2], afm_views[4 * v + 3]);
    lu_k_afm_build_texel(0, P, vw, (v * u_res + y) * u_res + x, x, y);
}
