/* lu_ddod_layout.h — record layouts of the ddod method (C and GLSL): what
 * the precomputation writes per sample and the CPU per pixel, read by
 * methods/ddod/lu_ddod.h on both backends. No functions, no hooks. */
#ifndef LU_DDOD_LAYOUT_H
#define LU_DDOD_LAYOUT_H

#include "kernels/lu_kernel.h"

/* Floats per sample record. */
#define LU_K_DDOD_SAMPLE_FLOATS 8
#define LU_K_DDOD_SAMPLE_X 0        /* centre b_i (world), 3 floats */
#define LU_K_DDOD_SAMPLE_S 3        /* Gaussian standard deviation s_i */
#define LU_K_DDOD_SAMPLE_DENSITY 4  /* D(b_i) */
#define LU_K_DDOD_SAMPLE_AMP 5      /* amplitude A_i */
#define LU_K_DDOD_SAMPLE_MEDIUM 6   /* medium index */
/* Floats per pixel record (built on the CPU for both backends). */
#define LU_K_DDOD_PIXEL_FLOATS 8
#define LU_K_DDOD_PIXEL_T0 0        /* camera ray enters the medium (t) */
#define LU_K_DDOD_PIXEL_T1 1        /* leaves it or meets an opaque surface; t1 <= t0: no medium */
#define LU_K_DDOD_PIXEL_SURFACE 4   /* rgb: boundary reflection + transmitted background / opaque surface */
/* Gaussians are cut off at this many standard deviations (exp(-4.5) = 1.1 %). */
#define LU_K_DDOD_CUTOFF 3.0f
#define LU_K_DDOD_MAX_CHANNELS 3
/* Bits of lu_k_ddod_params.traced. */
#define LU_K_DDOD_TRACED_VIEW 1     /* psi towards the camera */
#define LU_K_DDOD_TRACED_LIGHTS 2   /* psi^F towards each point / spot / directional light */


/* Per-frame constants of both passes. */
struct lu_k_ddod_params {
    int bands;        /* SH bands per function (bands^2 coefficients) */
    int channels;     /* 1: grey sigma_t (psi shared by r, g, b), 3: per channel */
    int stride;       /* coefficients per sample: 2 sets (view, light) x channels x bands^2 */
    int normalize;    /* 1: Shepard-normalised line integrals (see above) */
    int tile;         /* tile side in pixels */
    int tiles_x;
    int env;          /* 1: environment SH in lu_k_ddod_env_coeff */
    int traced;       /* LU_K_DDOD_TRACED_* bits: which psi come from the CPU's traced table
                         (lu_k_ddod_traced) instead of the SH sets (the paper) */
};
LU_TYPEDEF(lu_k_ddod_params)

#endif
