/* An environment light's SH projection (sh_env.h). */
#include "methods/common/sh_env.h"

#include <math.h>

#include "kernels/lu_optics.h"
#include "methods/common/lu_sh.h"

void lu_sh_env_grid(int width, int height, int cells_per_texel, int *nt, int *np) {
    int t = cells_per_texel * (height > 64 ? height : 64), p = 2 * t;
    if (cells_per_texel * width > p) p = cells_per_texel * width;
    *nt = t;
    *np = p;
}

void lu_sh_env_project(lu_sh_env_radiance_fn radiance, const void *user, int nt, int np, int bands,
                       lu_sh_env_angles angles, double *out) {
    int n = bands * bands;
    int single = angles == LU_SH_ENV_ANGLES_FLOAT;
    double pi = single ? (double)LU_PI : M_PI;
    float y[LU_SH_MAX_COEFFS];
    for (int k = 0; k < 3 * n; k++) out[k] = 0.0;
    for (int j = 0; j < nt; j++) {
        double th0 = single ? (double)(LU_PI * (float)j / (float)nt) : M_PI * j / nt;
        double th1 = single ? (double)(LU_PI * (float)(j + 1) / (float)nt) : M_PI * (j + 1) / nt;
        double dw = (cos(th0) - cos(th1)) * 2.0 * pi / np;   /* exact solid angle of the cell */
        for (int i = 0; i < np; i++) {
            lu_vec3 d = lu_k_env_dir((float)((i + 0.5) / np), (float)((j + 0.5) / nt));
            lu_vec3 L = radiance(user, d);
            lu_k_sh_eval(d, bands, y);
            for (int k = 0; k < n; k++) {
                out[3 * k] += L.x * y[k] * dw;
                out[3 * k + 1] += L.y * y[k] * dw;
                out[3 * k + 2] += L.z * y[k] * dw;
            }
        }
    }
}
