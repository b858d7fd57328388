/* lu_march_blocks.h — empty-space skipping over a coarse majorant grid
 * (kernel: C and GLSL), for the view march (lu_view_march.h) and its shadow
 * rays.
 *
 * Each grid medium has a majorant grid of blocks of LU_SCENE_MAJORANT_BLOCK^3
 * voxels (methods/common/majorant.h): block k along an axis covers index
 * coordinates [k B - 1, (k + 1) B - 1], block space q = (p_index + 1) / B, and
 * its value bounds the trilinear density over the block. A block of value 0
 * has density exactly 0 at every point there (all eight corners of every
 * trilinear cell it touches are 0), so skipping it leaves every integral as
 * it was: march samples there are 0, and so are the optical-depth pieces.
 *
 * The backend defines, before including this file (beside lu_k_density):
 *   float lu_k_majorant(LU_CTX_PARAM, int medium, int bx, int by, int bz);
 *     (0 outside the block grid; a constant medium: its density)
 * the same hook the path tracer's tracking reads (lu_tracking.h). */
#ifndef LU_MARCH_BLOCKS_H
#define LU_MARCH_BLOCKS_H

#include "kernels/lu_kernel.h"
#include "kernels/lu_scene_layout.h"
#include "lu_march.h"

/* How close (in block units) to a block face a point may sit and still be
 * judged by that block alone: float rounding of the sample position is far
 * below it, so a point judged empty is in the empty region for certain. */
LU_CONST float LU_K_BLOCK_MARGIN = 1.0f / 64.0f;

/* The majorant of the block of medium m holding the point at t on the
 * index-space ray o + t d, and in t_exit the ray parameter where the ray
 * comes within LU_K_BLOCK_MARGIN of that block's exit face. -1 (unknown)
 * when the point itself is that close to a face: the caller then treats the
 * point as possibly dense. */
LU_FN float lu_k_block_at(LU_CTX_PARAM, int m, vec3 o, vec3 d, float t, LU_OUT(float) t_exit) {
    float inv = 1.0f / lu_float(LU_SCENE_MAJORANT_BLOCK);
    vec3 q = lu_v3_scale(lu_v3_add(lu_v3_madd(o, d, t), lu_v3s(1.0f)), inv);
    vec3 c = lu_v3(lu_floor(q.x), lu_floor(q.y), lu_floor(q.z));
    vec3 f = lu_v3_sub(q, c);
    LU_DEREF(t_exit) = t;
    if (lu_min(f.x, lu_min(f.y, f.z)) < LU_K_BLOCK_MARGIN || lu_max(f.x, lu_max(f.y, f.z)) > 1.0f - LU_K_BLOCK_MARGIN)
        return -1.0f;
    float dt = LU_K_FAR_MARCH;
    for (int a = 0; a < 3; a++) {
        float da = lu_v3_get(d, a) * inv, fa = lu_v3_get(f, a);
        if (da > 0.0f) dt = lu_min(dt, (1.0f - LU_K_BLOCK_MARGIN - fa) / da);
        if (da < 0.0f) dt = lu_min(dt, (fa - LU_K_BLOCK_MARGIN) / -da);
    }
    LU_DEREF(t_exit) = t + dt;
    return lu_k_majorant(LU_CTX, m, lu_int(c.x), lu_int(c.y), lu_int(c.z));
}

/* lu_k_optical_depth (exact, lu_march.h) over [t0, t1] of the index-space ray
 * o + t d, walking the blocks with the same DDA on the grid B times coarser
 * and leaving out the blocks whose majorant is 0: each run of consecutive
 * blocks with density is integrated by one cell walk, so a ray that meets no
 * empty block takes exactly lu_k_optical_depth's walk (restarting the cell
 * walk at every block would cost more than the look-ups). Elsewhere equal to
 * it up to float rounding: block faces are cell faces, so the Simpson pieces
 * are the same. max_pieces bounds each cell walk and the block walk. */
LU_FN float lu_k_optical_depth_blocks(LU_CTX_PARAM, int medium, vec3 o, vec3 d, float t0, float t1, int max_pieces) {
    if (!(t1 > t0)) return 0.0f;
    float inv = 1.0f / lu_float(LU_SCENE_MAJORANT_BLOCK);
    vec3 oq = lu_v3_scale(lu_v3_add(o, lu_v3s(1.0f)), inv);
    vec3 dq = lu_v3_scale(d, inv);
    lu_k_dda s = lu_k_dda_begin(oq, dq, t0, t1);
    float ta = t0;
    bool in_run = false;   /* inside a run of dense blocks, which began at `run` */
    float run = t0;
    float tau = 0.0f;
    for (int i = 0; i < max_pieces && ta < t1; i++) {
        float tb = lu_k_dda_step(LU_REF(s));
        vec3 q = lu_v3_madd(oq, dq, 0.5f * (ta + tb));
        bool dense =
            lu_k_majorant(LU_CTX, medium, lu_int(lu_floor(q.x)), lu_int(lu_floor(q.y)), lu_int(lu_floor(q.z))) > 0.0f;
        if (dense && !in_run) run = ta;
        if (!dense && in_run) tau += lu_k_optical_depth(LU_CTX, medium, o, d, run, ta, max_pieces);
        in_run = dense;
        ta = tb;
    }
    if (in_run) tau += lu_k_optical_depth(LU_CTX, medium, o, d, run, t1, max_pieces);
    return tau;
}

#endif
