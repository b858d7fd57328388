/* Internal: grids that change with the scene's time (scene_time.c,
 * docs/volumes.md "Time and sequences"). A medium's density or emission grid
 * may be a numbered sequence of NanoVDB files or an animated procedural; its
 * lu_grid_anim produces the grid for a time, which lu_scene_set_time swaps
 * into the medium through the density-edit path (lu_grid_set_values), so the
 * frame stage and the GPU scene see a new grid generation and nothing else. */
#ifndef LU_SCENE_TIME_H
#define LU_SCENE_TIME_H

#include <lucent/lucent.h>

/* Frames per second when a scene gives none. */
#define LU_SCENE_DEFAULT_FPS 24.0
/* Most frames one sequence may list. */
#define LU_SEQUENCE_MAX_FRAMES 100000

/* A sequence "file": "smoke_####.nvdb", "frames": [first, last]. path is the
 * resolved pattern (one run of '#', the frame number zero-padded to the run's
 * width), label the JSON path for messages. Reads every frame once: each
 * must exist, load, and lie in the first frame's index space (same voxel
 * size and orientation, offset by whole voxels), and the grid covers the
 * union of their boxes. *g gets frame `frame` (clamped or looped into the
 * range) over that union box. */
lu_result lu_grid_anim_sequence(const char *path, const char *grid_name, int first, int last, bool loop, int frame,
                                lu_grid *g, lu_grid_anim **out, lu_error *err);
/* An animated procedural (lu_grid_procedural_animated): *g is made at `time`;
 * params are copied ("time" must not be among them). */
lu_result lu_grid_anim_procedural(const char *name, const lu_kvlist *params, const char *where, double time,
                                  lu_grid *g, lu_grid_anim **out, lu_error *err);
void lu_grid_anim_free(lu_grid_anim *a);
/* A sequence's frame range (false for a procedural). */
bool lu_grid_anim_range(const lu_grid_anim *a, int *first, int *last);
/* The file a sequence reads for frame number F (after clamping or looping). */
void lu_grid_anim_frame_path(const lu_grid_anim *a, int frame, char *out, size_t size);

#endif
