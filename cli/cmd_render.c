/* lucent render SCENE.json --method M [--set k=v ...] -o OUT */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "mpi_job.h"

static void usage(void) {
    printf("usage: lucent render SCENE.json [options] -o OUT.{png,exr,pfm}\n"
           "\n"
           "options:\n"
           "  --method M          rendering method (default: reference; see `lucent methods`)\n"
           "  --backend cpu|gpu|auto  where it runs (default: cpu); auto: a hardware GPU when\n"
           "                      there is one and the method has a GPU path, else the CPU\n"
           "                      (with a note); gpu forces the GPU backend, a software\n"
           "                      rasteriser (llvmpipe) included, and fails without one.\n"
           "                      LUCENT_GPU=auto|hardware|software picks the GPU device kind\n"
           "  --set M.P=V         set parameter P of method M (repeatable), e.g. --set reference.spp=4\n"
           "  --size WxH          override the camera's image size\n"
           "  --exposure E        PNG only: scale by 2^E before the sRGB curve (default 0)\n"
           "  --half              EXR only: store half floats\n"
           "  --progressive-every N  progressive methods (pathtrace): rewrite the output\n"
           "                      every N passes (samples per pixel) while rendering\n"
           "  --band-rows N       in a job of several ranks: rows per band of the work queue\n"
           "                      (default 16, whole tiles of bssrdf and ddod); fewer rows\n"
           "                      balance many ranks better on a long render\n"
           "  -o, --output FILE   output image; the format follows the extension\n"
           "\n"
           "Prints prepare and render times on stderr. The output folder is checked\n"
           "before the work starts. The file is written under a temporary name and\n"
           "renamed, so a failed or interrupted render (SIGINT: exit 130) leaves no\n"
           "partial file; with --progressive-every the last complete image stays.\n"
           "\n"
           "Under mpirun or srun (a build with MPI) the ranks divide the image's rows\n"
           "and rank 0 alone writes the output; the image is the same, bit for bit\n"
           "(docs/distributed.md): mpirun -n 4 lucent render SCENE.json ... -o OUT\n");
}

/* --progressive-every: each partial image replaces the output file
 * (atomically, so a viewer never sees half a file). */
typedef struct progressive_sink {
    const char *path;
    const lu_image_save_desc *save;
} progressive_sink;

static void save_partial(void *user, const lu_image *partial, int done, int total) {
    const progressive_sink *s = user;
    lu_error err = {0};
    if (lu_image_save(partial, s->path, s->save, &err) != LU_OK)
        fprintf(stderr, "lucent render: progressive write failed: %s\n", err.message);
    else if (lu_log_enabled(LU_LOG_INFO))
        fprintf(stderr, "lucent render: %s after %d of %d passes\n", s->path, done, total);
}

int lu_cmd_render(int argc, char **argv) {
    const char *scene_path = NULL, *out_path = NULL, *method = "reference";
    lu_backend backend = LU_BACKEND_CPU;
    lu_kvlist settings = {0};
    lu_image_save_desc save = {0};
    int width = 0, height = 0, progressive_every = 0, band_rows = 0;
    lu_error err = {0};
    int rc = LU_EXIT_OK;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        if (lu_cli_is_help(a)) {
            usage();
            lu_kv_free(&settings);
            return LU_EXIT_OK;
        } else if (strcmp(a, "--method") == 0 && has_next) {
            method = argv[++i];
        } else if (strcmp(a, "--backend") == 0 && has_next) {
            if (!lu_cli_parse_backend(argv[++i], &backend))
                rc = lu_cli_usage("render", "--backend takes cpu, gpu or auto");
        } else if (strcmp(a, "--set") == 0 && has_next) {
            if (lu_kv_parse_assignment(&settings, argv[++i], &err) != LU_OK) rc = lu_cli_error("render", &err);
        } else if (strcmp(a, "--size") == 0 && has_next) {
            if (!lu_cli_parse_size(argv[++i], &width, &height)) rc = lu_cli_usage("render", "--size takes WxH");
        } else if (strcmp(a, "--exposure") == 0 && has_next) {
            char *end;
            save.exposure = strtof(argv[++i], &end);
            if (*end) rc = lu_cli_usage("render", "--exposure takes a number");
        } else if (strcmp(a, "--progressive-every") == 0 && has_next) {
            char *end;
            long n = strtol(argv[++i], &end, 10);
            if (*end || n < 1 || n > 1000000000L)
                rc = lu_cli_usage("render", "--progressive-every takes a positive integer");
            else
                progressive_every = (int)n;
        } else if (strcmp(a, "--band-rows") == 0 && has_next) {
            char *end;
            long n = strtol(argv[++i], &end, 10);
            if (*end || n < 1 || n > LU_MAX_IMAGE_DIM)
                rc = lu_cli_usage("render", "--band-rows takes a positive integer up to %d", LU_MAX_IMAGE_DIM);
            else
                band_rows = (int)n;
        } else if (strcmp(a, "--half") == 0) {
            save.exr_half = true;
        } else if ((strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) && has_next) {
            out_path = argv[++i];
        } else if (a[0] == '-') {
            rc = lu_cli_usage("render", "unknown or incomplete option \"%s\"", a);
        } else if (!scene_path) {
            scene_path = a;
        } else {
            rc = lu_cli_usage("render", "unexpected argument \"%s\"", a);
        }
        if (rc != LU_EXIT_OK) break;
    }
    if (rc == LU_EXIT_OK && !scene_path) rc = lu_cli_usage("render", "missing SCENE.json");
    if (rc == LU_EXIT_OK && !out_path) rc = lu_cli_usage("render", "missing -o OUT");
    if (rc == LU_EXIT_OK && lu_image_format_from_path(out_path) == LU_IMAGE_AUTO)
        rc = lu_cli_usage("render", "cannot tell the image format of \"%s\" (use .png, .exr or .pfm)", out_path);
    /* Only the writer's file system needs the output folder. */
    if (rc == LU_EXIT_OK && lu_mpi_rank() == 0) rc = lu_cli_check_output("render", out_path);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&settings);
        return rc;
    }

    lu_scene scene;
    rc = lu_cli_load_scene("render", scene_path, width, height, &scene);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&settings);
        return rc;
    }
    bool writer = lu_mpi_rank() == 0;   /* in a job, rank 0 alone writes the output */
    if (writer) lu_cli_guard_output(out_path);
    lu_renderer *r = NULL;
    lu_image img = {0};
    progressive_sink sink = {out_path, &save};
    bool backend_auto = backend == LU_BACKEND_AUTO;
    backend = lu_cli_resolve_backend("render", backend, lu_method_find(method));
    lu_result cr = lu_renderer_create(method, &scene, &settings, backend, &r, &err);
    if (cr == LU_ERR_BACKEND && backend_auto && backend == LU_BACKEND_GPU) {
        /* the hardware device answered the probe but this method's context failed */
        fprintf(stderr, "lucent render: note: --backend auto: the GPU failed (%s); rendering on the CPU\n",
                err.message);
        backend = LU_BACKEND_CPU;
        cr = lu_renderer_create(method, &scene, &settings, backend, &r, &err);
    }
    bool created = cr == LU_OK;
    if (created && progressive_every > 0 && lu_mpi_size() > 1) {
        /* Each rank runs every pass of its own rows: no rank holds a
         * partial image of the whole frame. */
        if (writer) fprintf(stderr, "lucent render: --progressive-every is ignored in a job of several ranks\n");
    } else if (created && progressive_every > 0 && !lu_renderer_set_progressive(r, save_partial, &sink, progressive_every)) {
        fprintf(stderr, "lucent render: %s renders in one pass; --progressive-every ignored\n", method);
    }
    double t_job = lu_time_seconds();
    if (!created || lu_mpi_render(r, &scene, &img, band_rows, method, &err) != LU_OK ||
        (writer && lu_image_save(&img, out_path, &save, &err) != LU_OK)) {
        rc = lu_cli_error("render", &err);
    } else if (writer) {
        /* In a job: the wall time until the whole image was on rank 0. */
        double render_ms = lu_mpi_size() > 1 ? 1e3 * (lu_time_seconds() - t_job) : lu_cli_stats(r).frame_ms;
        fprintf(stderr, "lucent render: %s %dx%d with %s on %s: prepare %.1f ms, render %.1f ms", out_path, img.width,
                img.height, method, lu_backend_name(backend), lu_cli_stats(r).prepare_ms, render_ms);
        if (lu_mpi_size() > 1)
            fprintf(stderr, " (%d ranks, %d thread%s each)", lu_mpi_size(), lu_thread_count(),
                    lu_thread_count() == 1 ? "" : "s");
        fputc('\n', stderr);
    }
    lu_renderer_destroy(r);
    lu_image_destroy(&img);
    lu_scene_destroy(&scene);
    lu_kv_free(&settings);
    return rc;
}
