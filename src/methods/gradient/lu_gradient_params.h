/* lu_gradient_params.h — the gradient kernel's parameter record (kernel: C
 * and GLSL; no hooks, so drivers can include it on its own). */
#ifndef LU_GRADIENT_PARAMS_H
#define LU_GRADIENT_PARAMS_H

#include "kernels/lu_kernel.h"
#include "methods/common/lu_ms.h"

LU_CONST int LU_K_GR_GRADIENT = 0;
LU_CONST int LU_K_GR_RBF = 1;
LU_CONST int LU_K_GR_PERVOXEL = 2;

struct lu_k_gr_params {
    vec3 cam;          /* camera position */
    float delta1;      /* volume tracing interval; 0: exact optical depth */
    vec3 lo;           /* radiance grid: world position of the box's low corner */
    float delta2;      /* central-difference offset */
    vec3 voxel;        /* radiance grid voxel size (voxel centres at lo + (i + 0.5) voxel) */
    float g;           /* phase g of the media (one value for all) */
    vec3 cell;         /* cell-list cell size (cells start at lo) */
    float rbf_floor;   /* rbf: smallest weight counted (cut of the Gaussian tail) */
    int nx, ny, nz;    /* radiance grid size */
    int normalize;     /* 1: interpolate J / N (lu_gradient.h) */
    int cx, cy, cz;    /* cell-list size */
    int mode;          /* LU_K_GR_* */
    int map_res;       /* shadow map resolution */
    int bviews_at;     /* boundary-map buffer: where the views start (lu_k_gr_bmap_at) */
    int bmaps_at;      /* ... where the maps start */
    int bview_count;   /* 0: no bounded medium, shadow rays clip media to their boxes */
    int surf_normals_at; /* lu_k_gr_surf: where the per-pixel boundary normals start (after 8 floats per medium) */
    int reflect;       /* 1: add the boundary reflection where camera rays enter bounded media */
    int surf_vis_at;   /* lu_k_gr_surf (GPU): where the per-pixel, per-light surface visibility starts */
    int pad1;
    lu_k_ms ms;        /* multiple-scattering octaves of the source radiance J (lu_ms.h; octaves 1: off) */
};
LU_TYPEDEF(lu_k_gr_params)

/* Floats per stored sample (layout in lu_gradient.h). */
#define LU_K_GR_SAMPLE_FLOATS 24

#endif
