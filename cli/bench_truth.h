/* Pieces of `lucent bench` in their own files: the multiple-scattering
 * truth and its cache (cli/bench_truth.c), the error-time plot
 * (cli/bench_plot.c). docs/bench.md describes both. */
#ifndef LU_BENCH_TRUTH_H
#define LU_BENCH_TRUTH_H

#include <lucent/lucent.h>

/* The noise rule of the pathtrace truth (docs/bench.md "The pathtrace truth"). */
#define LU_TRUTH_NOISE_TARGET 0.02   /* rel-L2 of the truth's own noise */
#define LU_TRUTH_BLOCK 8             /* side of the block averages when per-pixel would cost too much */
#define LU_TRUTH_MIN_BLOCKS 64       /* fewer blocks than this: per pixel only */
#define LU_TRUTH_MAX_SPP_DEFAULT 4096 /* both seeds together */

typedef struct lu_truth_info {
    int block;          /* 1: compared per pixel; LU_TRUTH_BLOCK: compared as block averages */
    int spp;            /* samples per pixel of the truth, both seeds together */
    double noise;       /* estimated rel-L2 of the truth's noise, in the comparison it is used in */
    double ms;          /* render time, summed over its passes; 0 when read from the cache */
    bool from_cache;
    char label[48];     /* "pathtrace(1.6%)", "pathtrace/8x8(1.6%)": no spaces, one word of the table */
} lu_truth_info;

/* The pathtrace truth of the scene in its current state. Renders two
 * estimates with disjoint seeds, doubling both until the noise of their mean,
 * ||A - B|| / (2 ||(A + B) / 2||), is at most LU_TRUTH_NOISE_TARGET per pixel
 * (and was at most sqrt(2) times that one pass before);
 * where that would take more than max_spp it settles for the same noise in
 * LU_TRUTH_BLOCK-sized block averages, and at max_spp it stops with a warning.
 * block_wanted: 0 the rule above, 1 or LU_TRUTH_BLOCK that comparison only
 * (a later state of one motion uses the first state's). The image is the
 * mean at full resolution. Read from and written to the cache folder when
 * there is one, keyed by everything it depends on (state: the motion state
 * in words, e.g. "orbit 8/8"). */
lu_result lu_bench_pathtrace_truth(lu_scene *scene, const char *scene_path, const lu_kvlist *settings,
                                   const char *state, int block_wanted, int max_spp, lu_image *out,
                                   lu_truth_info *info, lu_error *err);

/* One point of the error-time plot. */
typedef struct lu_plot_point {
    const char *panel;    /* scene and motion: one panel each */
    char label[160];      /* method, backend and sweep values */
    const char *method;   /* the colour */
    bool gpu;             /* the point shape */
    double ms;            /* frame time, median */
    double rel_l2;        /* < 0: no error measured; 0: the truth itself */
} lu_plot_point;

/* Whether gnuplot is on PATH (the plot needs it). */
bool lu_bench_have_gnuplot(void);
/* Draws the points to a PNG at path (written to <path>.tmp.<pid>, then
 * renamed). truth: the y axis' name of the truth. note: one line under the
 * title (size, threads, yardstick). */
lu_result lu_bench_plot(const char *path, const lu_plot_point *pts, int n, const char *truth, const char *note,
                        lu_error *err);

#endif
