/* lu_grid_sample.glsl — GLSL twin of lu_grid_sample (lucent/grid.h): trilinear
 * density at an index-space position, zero outside [0, n-1] (support [-1, n]).
 * The texture is made by lu_gpu_texture3d_create (GL_LINEAR, zero border),
 * so index coordinate i (a voxel centre) maps to texture coordinate (i + 0.5) / n. */
#ifndef LU_GRID_SAMPLE_GLSL
#define LU_GRID_SAMPLE_GLSL

float lu_grid_sample_tex(sampler3D grid, vec3 p_index) {
    return texture(grid, (p_index + 0.5) / vec3(textureSize(grid, 0))).r;
}

#endif
