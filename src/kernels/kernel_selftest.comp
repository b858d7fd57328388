/* kernel_selftest.comp — runs the C/GLSL common-subset functions on the GPU
 * for tests/test_gpu.c, which evaluates the same lu_selftest.h as C.
 *   u_mode 0: for case i, out[i*3*OPS + 3*k + c] = lu_k_selftest_op(k, ...)[c]
 *   u_mode 1: out[i] = lu_grid_sample_tex(u_grid, in[3i .. 3i+2])
 *   u_mode 2: imageStore(u_image, (x, y), vec4(x, y, x*y, 1)) for every pixel */
layout(local_size_x = 64) in;

#include "lu_selftest.h"
#include "lu_grid_sample.glsl"

layout(std430, binding = 0) readonly buffer Inputs { float in_data[]; };
layout(std430, binding = 1) writeonly buffer Outputs { float out_data[]; };
layout(rgba32f, binding = 0) uniform writeonly image2D u_image;
uniform sampler3D u_grid;
uniform int u_mode;
uniform int u_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    if (u_mode == 0) {
        int base = i * LU_SELFTEST_IN;
        vec3 a = lu_v3(in_data[base + 0], in_data[base + 1], in_data[base + 2]);
        vec3 b = lu_v3(in_data[base + 3], in_data[base + 4], in_data[base + 5]);
        float s = in_data[base + 6], t = in_data[base + 7], u = in_data[base + 8], w = in_data[base + 9];
        for (int k = 0; k < LU_SELFTEST_OPS; k++) {
            vec3 r = lu_k_selftest_op(k, a, b, s, t, u, w);
            int o = (i * LU_SELFTEST_OPS + k) * 3;
            out_data[o + 0] = r.x;
            out_data[o + 1] = r.y;
            out_data[o + 2] = r.z;
        }
    } else if (u_mode == 1) {
        vec3 p = vec3(in_data[3 * i + 0], in_data[3 * i + 1], in_data[3 * i + 2]);
        out_data[i] = lu_grid_sample_tex(u_grid, p);
    } else {
        ivec2 size = imageSize(u_image);
        ivec2 xy = ivec2(i % size.x, i / size.x);
        imageStore(u_image, xy, vec4(float(xy.x), float(xy.y), float(xy.x * xy.y), 1.0));
    }
}
