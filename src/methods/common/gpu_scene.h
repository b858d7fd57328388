/* Internal: the shared GPU scene every GPU method reads (docs/architecture.md §5).
 *
 * One upload of an lu_scene for compute shaders:
 *   - each grid medium's density as a GL_R32F 3D texture (lu_grid_sample's
 *     convention) on texture unit LU_SCENE_UNIT_GRID0 + m; constant media
 *     have no texture (a flag in their record);
 *   - a std430 buffer of medium records (lu_k_medium: world->index affine,
 *     index support, world box, sigma_a/sigma_s, density scale, g, bounded,
 *     eta, DDA bound) at LU_SCENE_BINDING_MEDIA;
 *   - a std430 buffer of lights (lu_k_light, environment lights left out) at
 *     LU_SCENE_BINDING_LIGHTS;
 *   - a header buffer (camera as lu_k_camera + position, image size, counts)
 *     at LU_SCENE_BINDING_HEADER.
 * The numbers are #defines in kernels/lu_scene_layout.h (C and GLSL). A
 * method adds its own buffers at LU_SCENE_BINDING_FREE and above and its own
 * samplers at LU_SCENE_UNIT_FREE and above.
 *
 * Shader side: `#include "kernels/lu_scene_gpu.glsl"` first; it defines
 *   lu_k_density(LU_CTX_PARAM, int m, vec3 p_index)   (hook for lu_march.h etc.)
 *   lu_k_medium_count/lu_k_medium_get/lu_k_light_count/lu_k_light_get (LU_CTX_PARAM, ...)
 *     (the generic hooks of kernels looping over media and lights);
 *   lu_k_medium lu_scene_medium(int m);  lu_k_light lu_scene_light(int l);
 *   lu_k_camera lu_scene_camera();  vec3 lu_scene_camera_position();
 *   int lu_scene_width(), lu_scene_height(), lu_scene_medium_count(), lu_scene_light_count();
 * Pass 0 as LU_CTX on the GPU.
 *
 * C side:
 *   lu_gpu_scene *gs;
 *   lu_gpu_scene_create(ctx, scene, &gs, &err);    // uploads everything
 *   lu_gpu_scene_update(gs, scene, frame->rec, &err);  // each frame: uploads what changed
 *   lu_gpu_scene_bind(gs, &err);                   // before each dispatch (other code may rebind)
 *   lu_gpu_scene_destroy(gs);                      // before the context
 * CPU drivers of the same kernels build the same records with
 * lu_medium_to_kernel and lu_scene_kernel_lights, so both backends see
 * identical inputs. */
#ifndef LU_METHODS_GPU_SCENE_H
#define LU_METHODS_GPU_SCENE_H

#include <lucent/lucent.h>

#include "backends/gpu.h"
#include "kernels/lu_camera.h"
#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "kernels/lu_scene_layout.h"
#include "methods/frame.h"

typedef struct lu_gpu_scene lu_gpu_scene;

/* Fails with LU_ERR_LIMIT for more than LU_SCENE_MAX_MEDIA media, with the
 * backend's error when no GL call can be made. */
lu_result lu_gpu_scene_create(lu_gpu_context *ctx, const lu_scene *scene, lu_gpu_scene **out, lu_error *err);
/* Uploads the frame's records of `scene`: the header (camera) always; the
 * lights and the media buffer (medium records, majorants, emission grids)
 * only when they differ from what the GPU holds; and the values of every
 * grid whose generation changed (same media and grid sizes:
 * LU_ERR_INVALID_ARG if the medium count or a grid's size differs). */
lu_result lu_gpu_scene_update(lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec, lu_error *err);
/* The defines every program reading this scene is compiled with (prefix
 * to a method's own): "#define LU_SCENE_TREES 1" when a medium goes to the
 * GPU as a sparse tree, else "". A sparse grid whose dense box is at most
 * the dense limit (256 MiB; lu_gpu_scene_set_dense_limit, for tests) goes
 * as a texture of its dense expansion instead. */
const char *lu_gpu_scene_defines(const lu_scene *scene);
void lu_gpu_scene_set_dense_limit(uint64_t bytes);
/* How many times the media and the lights buffers were uploaded (tests). */
void lu_gpu_scene_uploads(const lu_gpu_scene *gs, int *media, int *lights);
/* Binds the three buffers and the grid textures at their fixed points. */
lu_result lu_gpu_scene_bind(lu_gpu_scene *gs, lu_error *err);
void lu_gpu_scene_destroy(lu_gpu_scene *gs);

/* ---- the same records for CPU drivers (no GL) ---- */

/* The kernel record of a medium (see kernels/lu_medium.h). */
lu_k_medium lu_medium_to_kernel(const lu_medium *m);
/* The scene's non-environment lights as kernel records, in scene order;
 * returns how many were written (out holds scene->light_count entries). */
int lu_scene_kernel_lights(const lu_scene *scene, lu_k_light *out);

#endif
