/* lu_froxel_grid.h — the froxel grid's records (kernel: C and GLSL),
 * declared once for the kernel (lu_froxel.h), the CPU driver and the GPU
 * driver's uniforms. */
#ifndef LU_FROXEL_GRID_H
#define LU_FROXEL_GRID_H

#include "kernels/lu_camera.h"

/* Floats per lit cell (S, lit: 1 or 0 where culled, sigma_t, pad) and per integrated node
 * (L, pad, tau, pad): the CPU arrays are the GPU's float buffers. */
#define LU_K_FX_CELL_FLOATS 8
#define LU_K_FX_MAX_NZ 1024

/* One frame's grid: its camera and slice distribution. */
struct lu_k_fx_grid {
    lu_k_camera cam;
    vec3 origin;       /* camera position */
    float t_lo;        /* the slices start here (nearest point of the media's boxes) */
    float n0;          /* slices are uniform in log(t - t_lo + n0) */
    float log_r;       /* log((t_hi - t_lo + n0) / n0) */
    float u;           /* sample position in a slice, in [0, 1) */
    int nx, ny, nz;
    int width, height; /* image size: columns span it */
};
LU_TYPEDEF(lu_k_fx_grid)

#endif
