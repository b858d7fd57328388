/* lu_scene_gpu.glsl — the shared GPU scene (methods/common/gpu_scene.h uploads it):
 * camera, media records and density grids, lights, at the fixed bindings of
 * lu_scene_layout.h. Defines the backend hook
 *   float lu_k_density(LU_CTX_PARAM, int medium, vec3 p_index)
 * so kernels that march media (lu_march.h, ...) compile unchanged; include
 * this before them.
 *
 * Buffer contents (vec4 each; counts and sizes are small integers stored as
 * floats, exact):
 *   header (uints, lu_scene_layout.h), as vec4 of float bits:
 *   header[0] = camera position, w = image width
 *   header[1] = camera right (scaled, lu_k_camera), w = image height
 *   header[2] = camera up (scaled), w = medium count
 *   header[3] = camera forward, w = light count (environment lights excluded)
 *   media[LU_SCENE_MEDIUM_VEC4 m + i], lights[LU_SCENE_LIGHT_VEC4 l + i]: the
 *     records of lu_scene_layout.h's tables (LU_SCENE_MEDIUM_RECORD, ...)
 *   then, in media, the majorant grids (lu_scene_layout.h); in the header,
 *   the tree records and the sparse grids' trees (lu_grid_tree.h) */
#ifndef LU_SCENE_GPU_GLSL
#define LU_SCENE_GPU_GLSL

#include "lu_kernel.h"
#include "lu_scene_layout.h"
#include "lu_grid_sample.glsl"
#include "lu_camera.h"
#include "lu_optics.h"
#include "lu_medium.h"

layout(std430, binding = LU_SCENE_BINDING_HEADER) readonly buffer LuSceneHeader { uint lu_scene_words[]; };
layout(std430, binding = LU_SCENE_BINDING_MEDIA) readonly buffer LuSceneMedia { vec4 lu_scene_media[]; };
layout(std430, binding = LU_SCENE_BINDING_LIGHTS) readonly buffer LuSceneLights { vec4 lu_scene_lights[]; };
layout(binding = LU_SCENE_UNIT_GRID0) uniform sampler3D lu_scene_grid[LU_SCENE_MAX_MEDIA];
#ifdef LU_SCENE_TREES
#define pnanovdb_buf_data lu_scene_words
#include "lu_grid_tree.h"
#endif

vec4 lu_scene_header(int i) {
    return uintBitsToFloat(uvec4(lu_scene_words[4 * i], lu_scene_words[4 * i + 1], lu_scene_words[4 * i + 2],
                                 lu_scene_words[4 * i + 3]));
}

int lu_scene_width() { return int(lu_scene_header(0).w); }
int lu_scene_height() { return int(lu_scene_header(1).w); }
int lu_scene_medium_count() { return int(lu_scene_header(2).w); }
int lu_scene_light_count() { return int(lu_scene_header(3).w); }
vec3 lu_scene_camera_position() { return lu_scene_header(0).xyz; }

lu_k_camera lu_scene_camera() {
    lu_k_camera k;
    k.right = lu_scene_header(1).xyz;
    k.up = lu_scene_header(2).xyz;
    k.forward = lu_scene_header(3).xyz;
    k.inv_width = 1.0f / float(lu_scene_width());
    k.inv_height = 1.0f / float(lu_scene_height());
    return k;
}

#define LU_SCENE_GET_XYZ(i, f) k.f = lu_scene_REC[o + i].xyz;
#define LU_SCENE_GET_WF(i, f) k.f = lu_scene_REC[o + i].w;
#define LU_SCENE_GET_WI(i, f) k.f = int(lu_scene_REC[o + i].w);

lu_k_light lu_scene_light(int l) {
    int o = LU_SCENE_LIGHT_VEC4 * l;
    lu_k_light k;
#define lu_scene_REC lu_scene_lights
    LU_SCENE_LIGHT_RECORD(LU_SCENE_GET_XYZ, LU_SCENE_GET_WF, LU_SCENE_GET_WI)
#undef lu_scene_REC
    return k;
}

lu_k_medium lu_scene_medium(int m) {
    int o = LU_SCENE_MEDIUM_VEC4 * m;
    lu_k_medium k;
#define lu_scene_REC lu_scene_media
    LU_SCENE_MEDIUM_RECORD(LU_SCENE_GET_XYZ, LU_SCENE_GET_WF, LU_SCENE_GET_WI)
#undef lu_scene_REC
    return k;
}

/* The generic scene hooks of kernels that loop over media and lights. */
int lu_k_medium_count(LU_CTX_PARAM) { return lu_scene_medium_count(); }
lu_k_medium lu_k_medium_get(LU_CTX_PARAM, int m) { return lu_scene_medium(m); }
int lu_k_light_count(LU_CTX_PARAM) { return lu_scene_light_count(); }
lu_k_light lu_k_light_get(LU_CTX_PARAM, int l) { return lu_scene_light(l); }

/* Trilinear density at an index-space position: lu_grid_sample's convention
 * (zero outside [0, n-1]) from a sparse grid's tree (lu_grid_tree.h) or
 * through a dense grid's zero-border GL_LINEAR texture. The
 * sampler index is a literal in each branch, so no dynamically uniform
 * indexing rule applies. */
float lu_k_density(LU_CTX_PARAM, int medium, vec3 p_index) {
    vec4 s = lu_scene_media[LU_SCENE_MEDIUM_VEC4 * medium + LU_SCENE_MEDIUM_DENSITY_VEC4];
    if (lu_scene_media[LU_SCENE_MEDIUM_VEC4 * medium + LU_SCENE_MEDIUM_CONSTANT_VEC4].w != 0.0f) return s.w;
#ifdef LU_SCENE_TREES
    int tw = LU_SCENE_TREE_TABLE + LU_SCENE_TREE_WORDS * medium;
    if (lu_scene_words[tw + 7] != 0u) {
        lu_k_tree t;
        t.buf.unused = 0u;
        t.root.address.byte_offset = lu_scene_words[tw];
        t.lo_x = int(lu_scene_words[tw + 1]);
        t.lo_y = int(lu_scene_words[tw + 2]);
        t.lo_z = int(lu_scene_words[tw + 3]);
        t.nx = int(lu_scene_words[tw + 4]);
        t.ny = int(lu_scene_words[tw + 5]);
        t.nz = int(lu_scene_words[tw + 6]);
        return lu_tree_sample(t, p_index) * s.w;
    }
#endif
    float v = 0.0f;
    switch (medium) {
    case 0: v = lu_grid_sample_tex(lu_scene_grid[0], p_index); break;
    case 1: v = lu_grid_sample_tex(lu_scene_grid[1], p_index); break;
    case 2: v = lu_grid_sample_tex(lu_scene_grid[2], p_index); break;
    case 3: v = lu_grid_sample_tex(lu_scene_grid[3], p_index); break;
    case 4: v = lu_grid_sample_tex(lu_scene_grid[4], p_index); break;
    case 5: v = lu_grid_sample_tex(lu_scene_grid[5], p_index); break;
    case 6: v = lu_grid_sample_tex(lu_scene_grid[6], p_index); break;
    default: v = lu_grid_sample_tex(lu_scene_grid[7], p_index); break;
    }
    return v * s.w;
}

/* Value k of the data region (lu_scene_layout.h). */
float lu_scene_data(int k) { return lu_scene_media[LU_SCENE_MAJORANT_DATA + k / 4][k % 4]; }

/* Voxel (x, y, z) of an emission grid at offset o, 0 outside (lu_grid_at). */
float lu_scene_emission_at(int o, int nx, int ny, int nz, int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0.0f;
    return lu_scene_data(o + (z * ny + y) * nx + x);
}

/* lu_blackbody_rgb (src/volume/emission.c) from the table at offset o. */
vec3 lu_scene_blackbody(float kelvin, int o) {
    if (!(kelvin > 100.0f)) return vec3(0.0f);
    float u = log(kelvin / 100.0f) / log(1000.0f) * float(LU_SCENE_BLACKBODY_N - 1);
    int i = LU_SCENE_BLACKBODY_N - 2;
    float f = 1.0f;
    if (u < float(LU_SCENE_BLACKBODY_N - 1)) {
        i = int(u);
        f = u - float(i);
    }
    vec3 r;
    for (int ch = 0; ch < 3; ch++) {
        float a = lu_scene_data(o + 3 * i + ch), b = lu_scene_data(o + 3 * i + 3 + ch);
        r[ch] = a > 0.0f && b > 0.0f ? exp(log(a) + f * (log(b) - log(a))) : a + f * (b - a);
    }
    return r;
}

/* Le of medium m at index-space p (before sigma_a and density): the
 * record's le, times the trilinear emission grid (lu_grid_sample's
 * arithmetic) or the blackbody colour of the mapped temperature. */
vec3 lu_k_emission(LU_CTX_PARAM, int m, vec3 p) {
    lu_k_medium md = lu_scene_medium(m);
    if (md.emission <= 1) return md.emission == 1 ? md.le : vec3(0.0f);
    vec4 h = lu_scene_media[LU_SCENE_EMISSION_HEADER + 2 * m];
    vec4 h2 = lu_scene_media[LU_SCENE_EMISSION_HEADER + 2 * m + 1];
    int nx = int(h.x), ny = int(h.y), nz = int(h.z), o = int(h.w);
    if (!(p.x >= -1.0f && p.y >= -1.0f && p.z >= -1.0f && p.x <= float(nx) && p.y <= float(ny) && p.z <= float(nz)))
        return vec3(0.0f);
    int x = int(p.x + 1.0f) - 1, y = int(p.y + 1.0f) - 1, z = int(p.z + 1.0f) - 1;
    float tx = p.x - float(x), ty = p.y - float(y), tz = p.z - float(z);
    float c000 = lu_scene_emission_at(o, nx, ny, nz, x, y, z), c100 = lu_scene_emission_at(o, nx, ny, nz, x + 1, y, z);
    float c010 = lu_scene_emission_at(o, nx, ny, nz, x, y + 1, z), c110 = lu_scene_emission_at(o, nx, ny, nz, x + 1, y + 1, z);
    float c001 = lu_scene_emission_at(o, nx, ny, nz, x, y, z + 1), c101 = lu_scene_emission_at(o, nx, ny, nz, x + 1, y, z + 1);
    float c011 = lu_scene_emission_at(o, nx, ny, nz, x, y + 1, z + 1);
    float c111 = lu_scene_emission_at(o, nx, ny, nz, x + 1, y + 1, z + 1);
    float c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
    float c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
    float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    float v = c0 + tz * (c1 - c0);
    if (md.emission == 2) return md.le * v;
    return md.le * lu_scene_blackbody((v - h2.y) * h2.x, int(h2.z));
}

/* Majorant of block (bx, by, bz) of medium m (lu_scene_layout.h; 0 outside
 * its block grid; a constant medium: its density), the hook of
 * methods/common/lu_march_blocks.h and the tracking kernels. */
float lu_k_majorant(LU_CTX_PARAM, int m, int bx, int by, int bz) {
    vec4 s = lu_scene_media[LU_SCENE_MEDIUM_VEC4 * m + LU_SCENE_MEDIUM_DENSITY_VEC4];
    if (lu_scene_media[LU_SCENE_MEDIUM_VEC4 * m + LU_SCENE_MEDIUM_CONSTANT_VEC4].w != 0.0f) return s.w;
    vec4 h = lu_scene_media[LU_SCENE_MAJORANT_HEADER + m];
    int nx = int(h.x), ny = int(h.y), nz = int(h.z);
    if (bx < 0 || by < 0 || bz < 0 || bx >= nx || by >= ny || bz >= nz) return 0.0f;
    int k = int(h.w) + (bz * ny + by) * nx + bx;
    return lu_scene_media[LU_SCENE_MAJORANT_DATA + k / 4][k % 4];
}

#endif
