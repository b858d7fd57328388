/* The yardstick: a fixed measure of this machine's speed, so that bench can
 * state frame times in units that do not depend on the machine or its load
 * (docs/bench.md). It measures the machine, not lucent: keep it exactly as
 * it is, and never optimise it, or every number stated in its unit changes
 * meaning. Built with its own flags (-O3 -march=native -fopenmp, see
 * CMakeLists.txt), whatever the rest of the build uses.
 *
 * Definition: a 128^3 float grid; 640 x 360 rays, 100 trilinear samples
 * along each, every sample a plain scalar trilinear interpolation of 8
 * voxels; rays split over all processors by OpenMP. Throughput = samples /
 * wall time, in G samples/s. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>

#include "cli.h"

enum { YS_N = 128, YS_W = 640, YS_H = 360, YS_SAMPLES = 100 };

static float trilinear(const float *g, float x, float y, float z) {
    int ix = (int)x, iy = (int)y, iz = (int)z;
    if (ix > YS_N - 2) ix = YS_N - 2;
    if (iy > YS_N - 2) iy = YS_N - 2;
    if (iz > YS_N - 2) iz = YS_N - 2;
    float fx = x - (float)ix, fy = y - (float)iy, fz = z - (float)iz;
    const float *c = g + ((size_t)iz * YS_N + (size_t)iy) * YS_N + (size_t)ix;
    const size_t sy = YS_N, sz = (size_t)YS_N * YS_N;
    float c00 = c[0] + fx * (c[1] - c[0]);
    float c10 = c[sy] + fx * (c[sy + 1] - c[sy]);
    float c01 = c[sz] + fx * (c[sz + 1] - c[sz]);
    float c11 = c[sz + sy] + fx * (c[sz + sy + 1] - c[sz + sy]);
    float c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
    return c0 + fz * (c1 - c0);
}

/* One pass over every ray; returns the wall seconds. Each ray runs from a
 * point on the grid's front face (z = 0) to a point on the back face
 * (z = N-1) pulled half-way towards the centre, like a perspective camera
 * looking through the volume, so neighbouring rays share cache lines the way
 * a renderer's do. */
static double one_pass(const float *grid, float *out) {
    double t0 = omp_get_wtime();
    const float last = (float)(YS_N - 1), mid = 0.5f * last;
#pragma omp parallel for schedule(dynamic, 4) num_threads(omp_get_num_procs())
    for (int py = 0; py < YS_H; py++) {
        for (int px = 0; px < YS_W; px++) {
            float x0 = last * ((float)px + 0.5f) / (float)YS_W, y0 = last * ((float)py + 0.5f) / (float)YS_H;
            float x1 = mid + 0.5f * (x0 - mid), y1 = mid + 0.5f * (y0 - mid);
            float sum = 0.0f;
            for (int i = 0; i < YS_SAMPLES; i++) {
                float t = ((float)i + 0.5f) / (float)YS_SAMPLES;
                sum += trilinear(grid, x0 + t * (x1 - x0), y0 + t * (y1 - y0), t * last);
            }
            out[py * YS_W + px] = sum;
        }
    }
    return omp_get_wtime() - t0;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double lu_yardstick_gsps(int repetitions, int *threads) {
    if (threads) *threads = omp_get_num_procs();
    if (repetitions < 1 || repetitions > 64) repetitions = 5;
    float *grid = malloc(sizeof(float) * YS_N * YS_N * YS_N);
    float *out = malloc(sizeof(float) * YS_W * YS_H);
    if (!grid || !out) {
        free(grid);
        free(out);
        return 0.0;
    }
    /* A smooth, non-constant field; the values do not affect the timing. */
    for (int z = 0; z < YS_N; z++)
        for (int y = 0; y < YS_N; y++)
            for (int x = 0; x < YS_N; x++)
                grid[((size_t)z * YS_N + y) * YS_N + x] = 0.5f + 0.5f * sinf(0.1f * (float)x + 0.07f * (float)y - 0.05f * (float)z);
    double secs[64];
    one_pass(grid, out); /* first touch of the grid and the threads */
    for (int r = 0; r < repetitions; r++) secs[r] = one_pass(grid, out);
    qsort(secs, (size_t)repetitions, sizeof secs[0], cmp_double);
    double median = repetitions % 2 ? secs[repetitions / 2] : 0.5 * (secs[repetitions / 2 - 1] + secs[repetitions / 2]);
    /* Keeps the sums alive, so no compiler can drop the loop. */
    volatile float sink = out[(YS_H / 2) * YS_W + YS_W / 2];
    (void)sink;
    free(grid);
    free(out);
    return (double)YS_W * YS_H * YS_SAMPLES / median * 1e-9;
}
