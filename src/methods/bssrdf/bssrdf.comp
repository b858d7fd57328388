/* bssrdf.comp — the splat gather and deferred pass of the bssrdf method: one
 * work group per 16 x 16 tile, one invocation per pixel, summing the tile's
 * splats of the pixel's object in list order (the order the CPU loop uses),
 * then shading. The per-splat and per-pixel math is methods/bssrdf/lu_bssrdf.h.
 * A dispatch sums list entries [u_chunk_begin, u_chunk_begin + u_chunk_len)
 * of each tile onto the running sum in Scatter; the last (u_finish = 1)
 * shades: llvmpipe ends an invocation's loops after 65535 iterations in
 * total (tests/test_gpu.c), so long tile lists are summed in chunks. */
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = 0) readonly buffer Data { float data[]; };
layout(std430, binding = 1) readonly buffer Shadow { float shadow_depth[]; };
uniform int u_buf_off[6];
uniform int u_map_res;

float lu_k_bssrdf_fetch(int lu_ctx_, int b, int i) { return data[u_buf_off[b] + i]; }
float lu_k_shadow_depth(int lu_ctx_, int map, int i, int j) {
    return shadow_depth[(map * u_map_res + j) * u_map_res + i];
}

#include "lu_bssrdf.h"
#include "kernels/lu_camera.h"

layout(std430, binding = 2) readonly buffer Splats { lu_k_splat splats[]; };
layout(std430, binding = 3) readonly buffer GBuf { lu_k_gbuf gbuf[]; };
layout(std430, binding = 4) readonly buffer TileStart { int tile_start[]; };
layout(std430, binding = 5) readonly buffer TileList { int tile_list[]; };
layout(std430, binding = 6) writeonly buffer Out { float out_rgb[]; };
layout(std430, binding = 7) buffer Scatter { vec4 scatter_sum[]; };

uniform int u_width;
uniform int u_height;
uniform int u_tiles_x;
uniform vec3 u_cam_right;
uniform vec3 u_cam_up;
uniform vec3 u_cam_forward;
uniform int u_chunk_begin;
uniform int u_chunk_len;
uniform int u_finish;

void main() {
    int x = int(gl_GlobalInvocationID.x), y = int(gl_GlobalInvocationID.y);
    if (x >= u_width || y >= u_height) return;
    int tile = int(gl_WorkGroupID.y) * u_tiles_x + int(gl_WorkGroupID.x);
    lu_k_gbuf g = gbuf[y * u_width + x];
    int px = y * u_width + x;
    vec3 scatter = u_chunk_begin > 0 ? scatter_sum[px].xyz : vec3(0.0);
    if (g.object >= 0) {
        lu_k_bssrdf_mat m = lu_k_bssrdf_mat_load(0, g.object);
        if (m.translucent != 0) {
            int s0 = tile_start[tile] + u_chunk_begin;
            int s1 = min(tile_start[tile + 1], s0 + u_chunk_len);
            for (int k = s0; k < s1; k++) {
                lu_k_splat s = splats[tile_list[k]];
                if (s.object != g.object) continue;
                scatter = lu_v3_add(scatter, lu_k_bssrdf_splat_eval(0, m, s, g.position, g.normal));
            }
        }
    }
    if (u_finish == 0) {
        scatter_sum[px] = vec4(scatter, 0.0);
        return;
    }
    lu_k_camera cam;
    cam.right = u_cam_right;
    cam.up = u_cam_up;
    cam.forward = u_cam_forward;
    cam.inv_width = 1.0 / float(u_width);
    cam.inv_height = 1.0 / float(u_height);
    vec3 d = lu_k_camera_dir(cam, float(x) + 0.5, float(y) + 0.5);
    vec3 c = lu_k_bssrdf_shade(0, g, scatter, d);
    int o = 3 * (y * u_width + x);
    out_rgb[o] = c.x;
    out_rgb[o + 1] = c.y;
    out_rgb[o + 2] = c.z;
}
