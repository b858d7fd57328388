/* lucent compare A B [-o diff.png] — metrics of A against reference B. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static void usage(void) {
    printf("usage: lucent compare A B [options]\n"
           "\n"
           "Prints error metrics of image A against the reference image B:\n"
           "rel_l2 = ||A-B||/||B|| (Ren et al.'s measure), rel_l1, rmse, psnr, max_abs,\n"
           "and mean_ratio = sum A / sum B (all channels, then R G B).\n"
           "\n"
           "options:\n"
           "  -o FILE            write a false-colour difference image (|A-B| luminance)\n"
           "  --scale S          full scale of the difference image (default: its 99th percentile)\n"
           "  --max-rel-l2 X     exit with status 3 if rel_l2 > X\n"
           "  --block K          compare the K x K block averages of A and B (a partial block at\n"
           "                     the right or bottom edge is dropped): removes most Monte Carlo\n"
           "                     noise, keeps structure coarser than K (default 1: per pixel)\n"
           "  --json             print the metrics as one JSON object\n");
}

/* Replaces *img by its k x k block averages. */
static lu_result block_average(lu_image *img, int k, lu_error *err) {
    lu_image avg;
    lu_result res = lu_image_block_average(img, k, &avg, err);
    lu_image_destroy(img);
    *img = avg;
    return res;
}

int lu_cmd_compare(int argc, char **argv) {
    const char *a_path = NULL, *b_path = NULL, *diff_path = NULL;
    float scale = 0.0f;
    double max_rel_l2 = -1.0;
    long block = 1;
    bool json = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        char *end = NULL;
        if (lu_cli_is_help(a)) {
            usage();
            return LU_EXIT_OK;
        } else if (strcmp(a, "-o") == 0 && has_next) {
            diff_path = argv[++i];
        } else if (strcmp(a, "--scale") == 0 && has_next) {
            scale = strtof(argv[++i], &end);
            if (*end || !(scale >= 0.0f)) return lu_cli_usage("compare", "--scale takes a number >= 0");
        } else if (strcmp(a, "--max-rel-l2") == 0 && has_next) {
            max_rel_l2 = strtod(argv[++i], &end);
            if (*end || !(max_rel_l2 >= 0.0)) return lu_cli_usage("compare", "--max-rel-l2 takes a number >= 0");
        } else if (strcmp(a, "--block") == 0 && has_next) {
            block = strtol(argv[++i], &end, 10);
            if (*end || block < 1 || block > 4096) return lu_cli_usage("compare", "--block takes an integer in [1, 4096]");
        } else if (strcmp(a, "--json") == 0) {
            json = true;
        } else if (a[0] == '-') {
            return lu_cli_usage("compare", "unknown or incomplete option \"%s\"", a);
        } else if (!a_path) {
            a_path = a;
        } else if (!b_path) {
            b_path = a;
        } else {
            return lu_cli_usage("compare", "unexpected argument \"%s\"", a);
        }
    }
    if (!a_path || !b_path) return lu_cli_usage("compare", "needs two images A and B");

    lu_error err = {0};
    lu_image a = {0}, b = {0}, diff = {0};
    lu_metrics m;
    int rc = LU_EXIT_OK;
    if (lu_image_load(a_path, &a, &err) != LU_OK || lu_image_load(b_path, &b, &err) != LU_OK ||
        (block > 1 && (block_average(&a, (int)block, &err) != LU_OK || block_average(&b, (int)block, &err) != LU_OK)) ||
        lu_image_compare(&a, &b, &m, &err) != LU_OK) {
        rc = lu_cli_error("compare", &err);
    } else {
        if (json)
            printf("{\"rel_l2\": %.6g, \"rel_l1\": %.6g, \"rmse\": %.6g, \"psnr\": %.6g, \"max_abs\": %.6g, "
                   "\"mean_ratio\": %.6g, \"mean_ratio_rgb\": [%.6g, %.6g, %.6g], \"block\": %ld}\n",
                   m.rel_l2, m.rel_l1, m.rmse, isinf(m.psnr) ? 999.0 : m.psnr, m.max_abs, m.mean_ratio,
                   m.mean_ratio_rgb[0], m.mean_ratio_rgb[1], m.mean_ratio_rgb[2], block);
        else
            printf("rel_l2   %.6g\nrel_l1   %.6g\nrmse     %.6g\npsnr     %.3f dB\nmax_abs  %.6g\n"
                   "mean_ratio %.6g  (R G B %.6g %.6g %.6g)\n",
                   m.rel_l2, m.rel_l1, m.rmse, m.psnr, m.max_abs, m.mean_ratio, m.mean_ratio_rgb[0],
                   m.mean_ratio_rgb[1], m.mean_ratio_rgb[2]);
        if (diff_path && (lu_image_diff_false_colour(&a, &b, scale, &diff, &err) != LU_OK ||
                          lu_image_save(&diff, diff_path, NULL, &err) != LU_OK))
            rc = lu_cli_error("compare", &err);
        if (rc == LU_EXIT_OK && max_rel_l2 >= 0.0 && m.rel_l2 > max_rel_l2) {
            fprintf(stderr, "lucent compare: rel_l2 %.6g exceeds --max-rel-l2 %.6g\n", m.rel_l2, max_rel_l2);
            rc = LU_EXIT_THRESHOLD;
        }
    }
    lu_image_destroy(&a);
    lu_image_destroy(&b);
    lu_image_destroy(&diff);
    return rc;
}
