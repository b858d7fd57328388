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
#define LU_SCENE_MEDIUM_VEC4 9
#define LU_SCENE_LIGHT_VEC4 3

#endif
