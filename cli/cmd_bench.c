/* lucent bench SCENE.json --methods a,b — per-frame time after warm-up,
 * prepare time, peak memory, and error against the reference of the same
 * scene, all measured in one run (DESIGN.md §7). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"

static void usage(void) {
    printf("usage: lucent bench SCENE.json --methods a,b,... [options]\n"
           "\n"
           "For each method (and backend): prepare once (timed), render --warmup frames,\n"
           "then --frames timed frames; reports the median frame time, prepare time, the\n"
           "method's peak resident memory, and rel-L2 / PSNR against the reference image.\n"
           "\n"
           "options:\n"
           "  --methods LIST      comma-separated methods (default: reference)\n"
           "  --backends LIST     cpu, gpu or cpu,gpu (default: cpu); methods skip backends they lack\n"
           "  --frames N          timed frames per method (default 5; the reference method: 1)\n"
           "  --warmup N          untimed frames first (default 1; the reference method: 0)\n"
           "  --size WxH          override the camera's image size\n"
           "  --set M.P=V         method parameter (repeatable); reference.* also shapes the truth\n"
           "  --reference FILE    use this image as the truth instead of rendering it\n"
           "  --save-images DIR   write each method's last frame as DIR/<method>-<backend>.exr\n"
           "  --csv FILE          also write the table as CSV\n"
           "  --json FILE         also write the table as JSON\n"
           "\n"
           "Timings are wall-clock (monotonic) medians; compare methods as ratios within one\n"
           "run. The truth is the reference method at its settings on the CPU; when reference\n"
           "is among --methods its first frame is reused rather than rendered twice.\n");
}

typedef struct row {
    const char *method;
    lu_backend backend;
    double prepare_ms, median_ms, min_ms, max_ms;
    double peak_mb;
    int frames;
    lu_metrics err;
    bool has_err;
} row;

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static int split_list(char *s, char **items, int max) {
    int n = 0;
    for (char *tok = strtok(s, ","); tok && n < max; tok = strtok(NULL, ",")) items[n++] = tok;
    return n;
}

/* Renders one method/backend; keeps the last frame in *img. */
static lu_result bench_one(const lu_scene *scene, const char *method, lu_backend backend, const lu_kvlist *settings,
                           int warmup, int frames, row *out, lu_image *img, lu_error *err) {
    memset(out, 0, sizeof *out);
    out->method = method;
    out->backend = backend;
    lu_peak_rss_reset();
    size_t rss0 = lu_peak_rss_bytes();
    lu_renderer *r;
    lu_result res = lu_renderer_create(method, scene, settings, backend, &r, err);
    if (res != LU_OK) return res;
    out->prepare_ms = r->prepare_ms;
    double *ms = calloc((size_t)frames, sizeof *ms);
    if (!ms) {
        lu_renderer_destroy(r);
        return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    }
    for (int i = 0; i < warmup + frames && res == LU_OK; i++) {
        res = lu_renderer_render(r, scene, img, err);
        if (i >= warmup) ms[i - warmup] = r->last_render_ms;
    }
    if (res == LU_OK) {
        qsort(ms, (size_t)frames, sizeof *ms, cmp_double);
        out->frames = frames;
        out->min_ms = ms[0];
        out->max_ms = ms[frames - 1];
        out->median_ms = frames % 2 ? ms[frames / 2] : 0.5 * (ms[frames / 2 - 1] + ms[frames / 2]);
        size_t rss1 = lu_peak_rss_bytes();
        out->peak_mb = (double)(rss1 > rss0 ? rss1 : rss0) / (1024.0 * 1024.0);
    }
    free(ms);
    lu_renderer_destroy(r);
    return res;
}

static void print_table(FILE *f, const row *rows, int n, double ref_ms) {
    fprintf(f, "%-12s %-4s %12s %12s %10s %10s %10s %9s\n", "method", "dev", "prepare_ms", "frame_ms", "x_vs_ref",
            "peak_MB", "rel_l2", "psnr_dB");
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f, "%-12s %-4s %12.2f %12.2f %10.2f %10.1f ", r->method, lu_backend_name(r->backend), r->prepare_ms,
                r->median_ms, ref_ms > 0 ? ref_ms / r->median_ms : 0.0, r->peak_mb);
        if (r->has_err) fprintf(f, "%10.5f %9.2f\n", r->err.rel_l2, isinf(r->err.psnr) ? 999.0 : r->err.psnr);
        else fprintf(f, "%10s %9s\n", "-", "-");
    }
}

static bool write_csv(const char *path, const row *rows, int n, double ref_ms, const char *scene, lu_error *err) {
    lu_atomic_file af;
    if (lu_atomic_open(&af, path, err) != LU_OK) return false;
    FILE *f = af.fp;
    fprintf(f, "scene,method,backend,prepare_ms,frame_ms_median,frame_ms_min,frame_ms_max,frames,speedup_vs_reference,"
               "peak_mb,rel_l2,rel_l1,rmse,psnr\n");
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f, "%s,%s,%s,%.3f,%.3f,%.3f,%.3f,%d,%.4f,%.1f,", scene, r->method, lu_backend_name(r->backend),
                r->prepare_ms, r->median_ms, r->min_ms, r->max_ms, r->frames, ref_ms > 0 ? ref_ms / r->median_ms : 0.0,
                r->peak_mb);
        if (r->has_err)
            fprintf(f, "%.6g,%.6g,%.6g,%.4f\n", r->err.rel_l2, r->err.rel_l1, r->err.rmse,
                    isinf(r->err.psnr) ? 999.0 : r->err.psnr);
        else fprintf(f, ",,,\n");
    }
    return lu_atomic_commit(&af, err) == LU_OK;
}

static bool write_json(const char *path, const row *rows, int n, double ref_ms, const char *scene, int w, int h,
                       lu_error *err) {
    lu_atomic_file af;
    if (lu_atomic_open(&af, path, err) != LU_OK) return false;
    FILE *f = af.fp;
    fprintf(f, "{\"scene\": \"%s\", \"width\": %d, \"height\": %d, \"threads\": %d, \"rows\": [\n", scene, w, h,
            lu_thread_count());
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f,
                "  {\"method\": \"%s\", \"backend\": \"%s\", \"prepare_ms\": %.3f, \"frame_ms\": %.3f, \"frames\": %d, "
                "\"speedup_vs_reference\": %.4f, \"peak_mb\": %.1f",
                r->method, lu_backend_name(r->backend), r->prepare_ms, r->median_ms, r->frames,
                ref_ms > 0 ? ref_ms / r->median_ms : 0.0, r->peak_mb);
        if (r->has_err)
            fprintf(f, ", \"rel_l2\": %.6g, \"rel_l1\": %.6g, \"psnr\": %.4f", r->err.rel_l2, r->err.rel_l1,
                    isinf(r->err.psnr) ? 999.0 : r->err.psnr);
        fprintf(f, "}%s\n", i + 1 < n ? "," : "");
    }
    fprintf(f, "]}\n");
    return lu_atomic_commit(&af, err) == LU_OK;
}

#define MAX_ROWS 64

int lu_cmd_bench(int argc, char **argv) {
    const char *scene_path = NULL, *csv = NULL, *json = NULL, *ref_path = NULL, *img_dir = NULL;
    char methods_buf[512] = "reference", backends_buf[64] = "cpu";
    int frames = 5, warmup = 1, width = 0, height = 0;
    lu_kvlist settings = {0};
    lu_error err = {0};
    int rc = LU_EXIT_OK;
    for (int i = 1; i < argc && rc == LU_EXIT_OK; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        char *end = NULL;
        if (lu_cli_is_help(a)) {
            usage();
            lu_kv_free(&settings);
            return LU_EXIT_OK;
        } else if (strcmp(a, "--methods") == 0 && has_next) {
            snprintf(methods_buf, sizeof methods_buf, "%s", argv[++i]);
        } else if (strcmp(a, "--backends") == 0 && has_next) {
            snprintf(backends_buf, sizeof backends_buf, "%s", argv[++i]);
        } else if (strcmp(a, "--frames") == 0 && has_next) {
            frames = (int)strtol(argv[++i], &end, 10);
            if (*end || frames < 1 || frames > 10000) rc = lu_cli_usage("bench", "--frames takes 1..10000");
        } else if (strcmp(a, "--warmup") == 0 && has_next) {
            warmup = (int)strtol(argv[++i], &end, 10);
            if (*end || warmup < 0 || warmup > 10000) rc = lu_cli_usage("bench", "--warmup takes 0..10000");
        } else if (strcmp(a, "--size") == 0 && has_next) {
            if (!lu_cli_parse_size(argv[++i], &width, &height)) rc = lu_cli_usage("bench", "--size takes WxH");
        } else if (strcmp(a, "--set") == 0 && has_next) {
            if (lu_kv_parse_assignment(&settings, argv[++i], &err) != LU_OK) rc = lu_cli_error("bench", &err);
        } else if (strcmp(a, "--reference") == 0 && has_next) {
            ref_path = argv[++i];
        } else if (strcmp(a, "--save-images") == 0 && has_next) {
            img_dir = argv[++i];
        } else if (strcmp(a, "--csv") == 0 && has_next) {
            csv = argv[++i];
        } else if (strcmp(a, "--json") == 0 && has_next) {
            json = argv[++i];
        } else if (a[0] == '-') {
            rc = lu_cli_usage("bench", "unknown or incomplete option \"%s\"", a);
        } else if (!scene_path) {
            scene_path = a;
        } else {
            rc = lu_cli_usage("bench", "unexpected argument \"%s\"", a);
        }
    }
    if (rc == LU_EXIT_OK && !scene_path) rc = lu_cli_usage("bench", "missing SCENE.json");
    char *methods[MAX_ROWS], *backend_names[2];
    int nm = split_list(methods_buf, methods, MAX_ROWS);
    int nb = split_list(backends_buf, backend_names, 2);
    lu_backend backends[2];
    for (int i = 0; i < nm && rc == LU_EXIT_OK; i++)
        if (!lu_method_find(methods[i])) rc = lu_cli_usage("bench", "no method named \"%s\"", methods[i]);
    for (int i = 0; i < nb && rc == LU_EXIT_OK; i++)
        if (!lu_cli_parse_backend(backend_names[i], &backends[i])) rc = lu_cli_usage("bench", "--backends takes cpu,gpu,auto");
        else backends[i] = lu_cli_resolve_backend("bench", backends[i], NULL);
    if (rc == LU_EXIT_OK && lu_settings_validate(&settings, &err) != LU_OK) rc = lu_cli_error("bench", &err);
    if (rc == LU_EXIT_OK && img_dir) mkdir(img_dir, 0755);
    lu_scene scene;
    if (rc == LU_EXIT_OK) rc = lu_cli_load_scene("bench", scene_path, width, height, &scene);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&settings);
        return rc;
    }

    /* The truth: a given image, or the reference rendered once at its settings. */
    lu_image truth = {0};
    row rows[MAX_ROWS], ref_row;
    int nrows = 0;
    double ref_ms = 0.0;
    lu_result res = LU_OK;
    if (ref_path) {
        res = lu_image_load(ref_path, &truth, &err);
        if (res == LU_OK && (truth.width != scene.camera.width || truth.height != scene.camera.height))
            res = lu_fail(&err, LU_ERR_INVALID_ARG, "%s is %dx%d but the scene renders %dx%d", ref_path, truth.width,
                          truth.height, scene.camera.width, scene.camera.height);
    } else {
        fprintf(stderr, "lucent bench: rendering the reference (the truth) ...\n");
        res = bench_one(&scene, "reference", LU_BACKEND_CPU, &settings, 0, 1, &ref_row, &truth, &err);
        ref_ms = ref_row.median_ms;
    }
    bool ref_row_used = false;
    for (int i = 0; i < nm && res == LU_OK; i++) {
        for (int b = 0; b < nb && res == LU_OK && nrows < MAX_ROWS; b++) {
            const lu_method *m = lu_method_find(methods[i]);
            if (!(m->backends & backends[b])) {
                fprintf(stderr, "lucent bench: %s has no %s backend, skipped\n", m->name, lu_backend_name(backends[b]));
                continue;
            }
            bool is_ref = strcmp(m->name, "reference") == 0;
            lu_image img = {0};
            row *r = &rows[nrows];
            if (is_ref && backends[b] == LU_BACKEND_CPU && !ref_path && !ref_row_used) {
                ref_row_used = true; /* already rendered as the truth */
                *r = ref_row;
                r->has_err = lu_image_compare(&truth, &truth, &r->err, &err) == LU_OK;
                nrows++;
                continue;
            }
            fprintf(stderr, "lucent bench: %s on %s ...\n", m->name, lu_backend_name(backends[b]));
            res = bench_one(&scene, m->name, backends[b], &settings, is_ref ? 0 : warmup, is_ref ? 1 : frames, r, &img,
                            &err);
            if (res == LU_OK) r->has_err = lu_image_compare(&img, &truth, &r->err, &err) == LU_OK;
            if (res == LU_OK && img_dir) {
                char path[1024];
                snprintf(path, sizeof path, "%s/%s-%s.exr", img_dir, m->name, lu_backend_name(backends[b]));
                res = lu_image_save(&img, path, NULL, &err);
            }
            if (res == LU_OK) nrows++;
            lu_image_destroy(&img);
        }
    }
    if (res == LU_OK && img_dir) {
        char path[1024];
        snprintf(path, sizeof path, "%s/truth.exr", img_dir);
        res = lu_image_save(&truth, path, NULL, &err);
    }
    if (res != LU_OK) {
        rc = lu_cli_error("bench", &err);
    } else {
        printf("scene %s, %dx%d, %d threads\n", scene_path, scene.camera.width, scene.camera.height, lu_thread_count());
        print_table(stdout, rows, nrows, ref_ms);
        if (csv && !write_csv(csv, rows, nrows, ref_ms, scene_path, &err)) rc = lu_cli_error("bench", &err);
        if (json && !write_json(json, rows, nrows, ref_ms, scene_path, scene.camera.width, scene.camera.height, &err))
            rc = lu_cli_error("bench", &err);
    }
    lu_image_destroy(&truth);
    lu_scene_destroy(&scene);
    lu_kv_free(&settings);
    return rc;
}
