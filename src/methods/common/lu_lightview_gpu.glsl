/* lu_lightview_gpu.glsl — a light view packed by lu_lightview_pack
 * (methods/common/lightview.h: 4 vec4 = origin + ortho, axis_u + extent_u,
 * axis_v + extent_v, axis_w + depth_far) read back in GLSL. Include after
 * lu_lightview.h. */
#ifndef LU_LIGHTVIEW_GPU_GLSL
#define LU_LIGHTVIEW_GPU_GLSL
lu_k_lightview lu_k_lightview_unpack(vec4 a, vec4 b, vec4 c, vec4 d) {
    lu_k_lightview w;
    w.origin = a.xyz;
    w.ortho = int(a.w);
    w.axis_u = b.xyz;
    w.extent_u = b.w;
    w.axis_v = c.xyz;
    w.extent_v = c.w;
    w.axis_w = d.xyz;
    w.depth_far = d.w;
    return w;
}
#endif
