/* lu_scene_layout.h — where the shared GPU scene lives (C and GLSL): binding
 * points of its storage buffers, texture units of its density grids, and the
 * record sizes. Included by methods/common/gpu_scene.h (C) and
 * kernels/lu_scene_gpu.glsl, so the numbers exist once. Methods put their
 * own buffers at LU_SCENE_BINDING_FREE and above, their own samplers at
 * LU_SCENE_UNIT_FREE and above. */
#ifndef LU_SCENE_LAYOUT_H
#define LU_SCENE_LAYOUT_H

#define LU_SCENE_BINDING_HEADER 0   /* std430 vec4[4]: camera + counts */
#define LU_SCENE_BINDING_MEDIA 1    /* std430 vec4[LU_SCENE_MEDIUM_VEC4 * media] */
#define LU_SCENE_BINDING_LIGHTS 2   /* std430 vec4[LU_SCENE_LIGHT_VEC4 * lights] */
#define LU_SCENE_BINDING_FREE 3     /* first binding a method may use */

#define LU_SCENE_MAX_MEDIA 8        /* grid media: sampler units LU_SCENE_UNIT_GRID0 + m */
#define LU_SCENE_UNIT_GRID0 0
#define LU_SCENE_UNIT_FREE 8        /* first texture unit a method may use */

#define LU_SCENE_HEADER_VEC4 4
/* The header buffer is read as uints (camera floats by their bits). After
 * the camera's LU_SCENE_HEADER_VEC4 vec4 it holds one tree record of
 * LU_SCENE_TREE_WORDS uints per medium from word LU_SCENE_TREE_TABLE (root
 * node byte offset, tree coordinate of index 0 as three ints, the index box
 * nx, ny, nz, and 1 for a sparse grid, else 0), then, from byte
 * LU_SCENE_TREES_BYTE, the sparse grids' NanoVDB buffers, each 32-byte
 * aligned, which kernels/lu_grid_tree.h reads in place. A buffer address is
 * a 32-bit byte offset, and the whole buffer must fit the device's largest
 * storage buffer (lu_gpu_info.max_ssbo_size). */
#define LU_SCENE_TREE_TABLE 16
#define LU_SCENE_TREE_WORDS 8
#define LU_SCENE_TREES_BYTE ((LU_SCENE_TREE_TABLE + LU_SCENE_TREE_WORDS * LU_SCENE_MAX_MEDIA) * 4)
#define LU_SCENE_MEDIUM_VEC4 10
#define LU_SCENE_LIGHT_VEC4 3

/* The records, declared once: each table lists a kernel struct's fields
 * (lu_k_medium, lu_k_light) with the vec4 they occupy in the record. The C
 * packer (methods/common/gpu_scene.c) and the GLSL unpacker
 * (lu_scene_gpu.glsl) expand the same table with their own XYZ (a vec3 in
 * .xyz), WF (a float in .w) and WI (an int in .w, stored as an exact float)
 * macros, so the two cannot drift apart. */
#define LU_SCENE_MEDIUM_RECORD(XYZ, WF, WI)                                                                           \
    XYZ(0, w2i_x) WF(0, w2i_t.x)                                                                                       \
    XYZ(1, w2i_y) WF(1, w2i_t.y)                                                                                       \
    XYZ(2, w2i_z) WF(2, w2i_t.z)                                                                                       \
    XYZ(3, support_lo) WI(3, max_pieces)                                                                               \
    XYZ(4, support_hi) WF(4, density_scale)                                                                            \
    XYZ(5, sigma_a) WF(5, g)                                                                                           \
    XYZ(6, sigma_s) WI(6, constant)                                                                                    \
    XYZ(7, bounds_lo) WI(7, bounded)                                                                                   \
    XYZ(8, bounds_hi) WF(8, eta)                                                                                       \
    XYZ(9, le) WI(9, emission)
#define LU_SCENE_LIGHT_RECORD(XYZ, WF, WI)                                                                            \
    XYZ(0, position) WI(0, type)                                                                                       \
    XYZ(1, direction) WF(1, cos_inner)                                                                                 \
    XYZ(2, intensity) WF(2, cos_outer)
/* The vec4 that lu_k_density reads: density scale in .w, and the one that
 * says a medium is constant. */
#define LU_SCENE_MEDIUM_DENSITY_VEC4 4
#define LU_SCENE_MEDIUM_CONSTANT_VEC4 6

/* The media buffer continues, after LU_SCENE_MAX_MEDIA medium records, with
 * each grid medium's majorant grid (methods/common/majorant.h, blocks of
 * LU_SCENE_MAJORANT_BLOCK^3 voxels) for empty-space skipping: one header
 * vec4 per medium at LU_SCENE_MAJORANT_HEADER + m (block counts x, y, z as
 * floats; w: offset of its first value), then the values, four per vec4,
 * from LU_SCENE_MAJORANT_DATA. */
#define LU_SCENE_MAJORANT_BLOCK 8
#define LU_SCENE_MAJORANT_HEADER (LU_SCENE_MAX_MEDIA * LU_SCENE_MEDIUM_VEC4)
/* Then two vec4 per medium for grid and temperature emission
 * (include/lucent/scene.h) at LU_SCENE_EMISSION_HEADER + 2 m: (nx, ny, nz,
 * offset of its first value) and (temperature_scale, temperature_offset,
 * offset of the blackbody table, 0). The emission values (x fastest) and the
 * table (LU_SCENE_BLACKBODY_N linear sRGB triples, the nodes of
 * lu_blackbody_rgb) follow the majorant values in the same data region;
 * every offset counts floats from LU_SCENE_MAJORANT_DATA. */
#define LU_SCENE_EMISSION_HEADER (LU_SCENE_MAJORANT_HEADER + LU_SCENE_MAX_MEDIA)
#define LU_SCENE_BLACKBODY_N 2048
#define LU_SCENE_MAJORANT_DATA (LU_SCENE_EMISSION_HEADER + 2 * LU_SCENE_MAX_MEDIA)

#endif
