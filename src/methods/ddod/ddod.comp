/* ddod.comp — the ddod method on the GPU, both passes of methods/ddod/lu_ddod.h
 * over the shared GPU scene (lights, media records) and the buffers the CPU
 * built (samples, SH, pixel records, tile lists, the traced table):
 *   LU_DDOD_PASS 1: one invocation per sample, its radiance factor f_i;
 *   LU_DDOD_PASS 2: one work group per 16 x 16 tile, one invocation per
 *   pixel, the tile's Gaussians in list order (the CPU's order). */
#if LU_DDOD_PASS == 1
layout(local_size_x = 64) in;
#else
layout(local_size_x = 16, local_size_y = 16) in;
#endif

#include "kernels/lu_scene_gpu.glsl"
#include "lu_ddod_layout.h"

layout(std430, binding = LU_SCENE_BINDING_FREE) readonly buffer Samples { float dd_samples[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 1) readonly buffer Coeffs { float dd_sh[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 2) buffer Radiance { float dd_radiance[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 3) readonly buffer Pixels { float dd_pixels[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 4) readonly buffer TileStart { int dd_tile_start[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 5) readonly buffer TileList { int dd_tile_list[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 6) readonly buffer Env { float dd_env[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 7) writeonly buffer Out { float dd_out[]; };
layout(std430, binding = LU_SCENE_BINDING_FREE + 8) readonly buffer Traced { float dd_traced[]; };

uniform int u_bands;
uniform int u_channels;
uniform int u_stride;
uniform int u_normalize;
uniform int u_tile;
uniform int u_tiles_x;
uniform int u_env;
uniform int u_traced;
uniform int u_count;

float lu_k_ddod_sample_f(LU_CTX_PARAM, int i, int k) { return dd_samples[i * LU_K_DDOD_SAMPLE_FLOATS + k]; }
float lu_k_ddod_coeff(LU_CTX_PARAM, int index) { return dd_sh[index]; }
vec3 lu_k_ddod_radiance(LU_CTX_PARAM, int i) { return vec3(dd_radiance[4 * i], dd_radiance[4 * i + 1], dd_radiance[4 * i + 2]); }
float lu_k_ddod_pixel_f(LU_CTX_PARAM, int pixel, int k) { return dd_pixels[pixel * LU_K_DDOD_PIXEL_FLOATS + k]; }
int lu_k_ddod_tile_start(LU_CTX_PARAM, int tile) { return dd_tile_start[tile]; }
int lu_k_ddod_tile_item(LU_CTX_PARAM, int k) { return dd_tile_list[k]; }
vec3 lu_k_ddod_env_coeff(LU_CTX_PARAM, int k) { return vec3(dd_env[3 * k], dd_env[3 * k + 1], dd_env[3 * k + 2]); }
vec3 lu_k_ddod_traced(LU_CTX_PARAM, int k) { return vec3(dd_traced[4 * k], dd_traced[4 * k + 1], dd_traced[4 * k + 2]); }

#include "lu_ddod.h"

void main() {
    lu_k_ddod_params P;
    P.bands = u_bands;
    P.channels = u_channels;
    P.stride = u_stride;
    P.normalize = u_normalize;
    P.tile = u_tile;
    P.tiles_x = u_tiles_x;
    P.env = u_env;
    P.traced = u_traced;
#if LU_DDOD_PASS == 1
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    vec3 f = lu_k_ddod_sample_radiance(0, P, i, lu_scene_camera_position());
    dd_radiance[4 * i] = f.x;
    dd_radiance[4 * i + 1] = f.y;
    dd_radiance[4 * i + 2] = f.z;
    dd_radiance[4 * i + 3] = 0.0;
#else
    int tile = int(gl_WorkGroupID.y) * u_tiles_x + int(gl_WorkGroupID.x);
    int x = int(gl_WorkGroupID.x) * u_tile + int(gl_LocalInvocationID.x);
    int y = int(gl_WorkGroupID.y) * u_tile + int(gl_LocalInvocationID.y);
    int w = lu_scene_width();
    if (x >= w || y >= lu_scene_height()) return;
    vec3 d = lu_k_camera_dir(lu_scene_camera(), float(x) + 0.5, float(y) + 0.5);
    vec3 L = lu_k_ddod_pixel(0, P, y * w + x, tile, lu_scene_camera_position(), d);
    int px = y * w + x;
    dd_out[3 * px] = L.x;
    dd_out[3 * px + 1] = L.y;
    dd_out[3 * px + 2] = L.z;
#endif
}
