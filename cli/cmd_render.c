/* lucent render SCENE.json --method M [--set k=v ...] [--time T | --frame-range A-B] -o OUT */
#include <math.h>
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
           "  --time T            render the scene at time T seconds (default: the scene's \"time\");\n"
           "                      sequences show frame floor(T x fps), held at their ends\n"
           "  --frame-range A-B   render frames A to B (time F / fps for frame F) with one\n"
           "                      renderer, each to OUT with the frame number in place of its\n"
           "                      run of '#' (out_####.exr), or, without one, before the\n"
           "                      extension (out.exr -> out_0001.exr)\n"
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
           "Under mpirun or srun (a build with MPI) the ranks divide the image's rows,\n"
           "or with --frame-range the frames, and rank 0 alone writes the output; the\n"
           "images are the same, bit for bit (docs/distributed.md):\n"
           "  mpirun -n 4 lucent render SCENE.json ... -o OUT\n");
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

/* The output of frame f: its number in place of the run of '#' in out
 * (zero-padded to the run's width), or "_%04d" before the extension; false
 * when out has two runs of '#'. */
static bool frame_path(const char *out, int f, char *dst, size_t size) {
    const char *h = strchr(out, '#');
    if (h) {
        const char *e = h;
        while (*e == '#') e++;
        if (strchr(e, '#')) return false;
        snprintf(dst, size, "%.*s%0*d%s", (int)(h - out), out, (int)(e - h), f, e);
        return true;
    }
    const char *slash = strrchr(out, '/'), *dot = strrchr(out, '.');
    if (!dot || (slash && dot < slash)) dot = out + strlen(out);
    snprintf(dst, size, "%.*s_%04d%s", (int)(dot - out), out, f, dot);
    return true;
}

/* --frame-range: one renderer for every frame a rank renders, so the frame
 * stage rebuilds only what each time step touches. In a job the ranks take
 * the frames in turn (round k: frame A + k x ranks + rank); rank 0 writes
 * its own and then each other rank's frame of the round, in frame order,
 * so it holds two images at a time. */
static int render_frames(lu_renderer *r, lu_scene *scene, long frame_a, long frame_b, const char *out_path,
                         const lu_image_save_desc *save, const char *method, lu_backend backend, lu_image *img) {
    int ranks = lu_mpi_size(), me = lu_mpi_rank();
    lu_error err = {0};
    lu_image other = {0};
    lu_result res = LU_OK;
    for (long first = frame_a; first <= frame_b && res == LU_OK; first += ranks) {
        long f = first + me;
        double ms = 0.0;
        if (f <= frame_b) {
            res = lu_scene_set_time(scene, lu_scene_frame_time(scene, (int)f), &err);
            if (res == LU_OK) res = lu_renderer_render(r, scene, img, &err);
            ms = lu_cli_stats(r).frame_ms;
        }
        for (int k = 0; k < ranks && res == LU_OK; k++) {
            long fk = first + k;
            if (fk > frame_b) break;
            if (me != 0) {
                if (k == me) res = lu_mpi_send_image(img, ms, &err);
                continue;
            }
            double msk = ms;
            const lu_image *im = img;
            if (k != 0) {
                res = lu_mpi_recv_image(k, &other, &msk, &err);
                im = &other;
            }
            char fp[1100];
            frame_path(out_path, (int)fk, fp, sizeof fp);
            lu_cli_guard_output(fp);
            if (res == LU_OK) res = lu_image_save(im, fp, save, &err);
            char by[32] = "";
            if (ranks > 1) snprintf(by, sizeof by, " (rank %d)", k);
            if (res == LU_OK)
                fprintf(stderr, "lucent render: %s (frame %ld, time %g s) %dx%d with %s on %s: render %.1f ms%s\n", fp,
                        fk, lu_scene_frame_time(scene, (int)fk), im->width, im->height, method,
                        lu_backend_name(backend), msk, by);
        }
    }
    lu_image_destroy(&other);
    return res == LU_OK ? LU_EXIT_OK : lu_cli_error("render", &err);
}

int lu_cmd_render(int argc, char **argv) {
    const char *scene_path = NULL, *out_path = NULL, *method = "reference";
    lu_backend backend = LU_BACKEND_CPU;
    lu_kvlist settings = {0};
    lu_image_save_desc save = {0};
    int width = 0, height = 0, progressive_every = 0, band_rows = 0;
    bool time_given = false, range_given = false;
    double time = 0.0;
    long frame_a = 0, frame_b = 0;
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
        } else if (strcmp(a, "--time") == 0 && has_next) {
            char *end;
            time = strtod(argv[++i], &end);
            time_given = true;
            if (*end || end == argv[i] || !isfinite(time) || fabs(time) > 1e6)
                rc = lu_cli_usage("render", "--time takes seconds in [-1e6, 1e6] (\"%s\")", argv[i]);
        } else if (strcmp(a, "--frame-range") == 0 && has_next) {
            char *end, *end2;
            const char *v = argv[++i];
            frame_a = strtol(v, &end, 10);
            frame_b = *end == '-' ? strtol(end + 1, &end2, 10) : -1;
            range_given = true;
            if (end == v || *end != '-' || *end2 || end2 == end + 1 || frame_a < 0 || frame_b < frame_a ||
                frame_b > 1000000000L || frame_b - frame_a >= 100000)
                rc = lu_cli_usage("render", "--frame-range takes A-B, whole frame numbers 0 <= A <= B, at most 100000 "
                                            "frames (\"%s\")", v);
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
    if (rc == LU_EXIT_OK && time_given && range_given)
        rc = lu_cli_usage("render", "give --time or --frame-range, not both");
    if (rc == LU_EXIT_OK && range_given && progressive_every > 0)
        rc = lu_cli_usage("render", "--progressive-every writes one image; it does not go with --frame-range");
    if (rc == LU_EXIT_OK && lu_image_format_from_path(out_path) == LU_IMAGE_AUTO)
        rc = lu_cli_usage("render", "cannot tell the image format of \"%s\" (use .png, .exr or .pfm)", out_path);
    /* Only the writer, rank 0 in a job, checks: only its file system needs
     * the output folder. */
    bool writer = lu_mpi_rank() == 0;
    if (rc == LU_EXIT_OK && range_given && writer) {
        /* every frame's output before any work */
        for (long f = frame_a; f <= frame_b && rc == LU_EXIT_OK; f++) {
            char fp[1100];
            if (!frame_path(out_path, (int)f, fp, sizeof fp))
                rc = lu_cli_usage("render", "-o \"%s\": more than one run of '#'", out_path);
            else
                rc = lu_cli_check_output("render", fp);
        }
    } else if (rc == LU_EXIT_OK && writer) {
        rc = lu_cli_check_output("render", out_path);
    }
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
    if ((time_given || range_given) && !lu_scene_animated(&scene))
        fprintf(stderr, "lucent render: note: nothing in %s follows time; %s changes nothing\n", scene_path,
                time_given ? "--time" : "--frame-range");
    if (time_given && lu_scene_set_time(&scene, time, &err) != LU_OK) {
        rc = lu_cli_error("render", &err);
        lu_scene_destroy(&scene);
        lu_kv_free(&settings);
        return rc;
    }
    if (range_given && lu_scene_set_time(&scene, lu_scene_frame_time(&scene, (int)frame_a), &err) != LU_OK) {
        rc = lu_cli_error("render", &err);
        lu_scene_destroy(&scene);
        lu_kv_free(&settings);
        return rc;
    }
    if (!range_given && writer) lu_cli_guard_output(out_path);
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
    if (!created && range_given) {
        rc = lu_cli_error("render", &err);
    } else if (range_given) {
        rc = render_frames(r, &scene, frame_a, frame_b, out_path, &save, method, backend, &img);
    } else {
        double t_job = lu_time_seconds();
        if (!created || lu_mpi_render(r, &scene, &img, band_rows, method, &err) != LU_OK ||
            (writer && lu_image_save(&img, out_path, &save, &err) != LU_OK)) {
            rc = lu_cli_error("render", &err);
        } else if (writer) {
            /* In a job: the wall time until the whole image was on rank 0. */
            double render_ms = lu_mpi_size() > 1 ? 1e3 * (lu_time_seconds() - t_job) : lu_cli_stats(r).frame_ms;
            fprintf(stderr, "lucent render: %s %dx%d with %s on %s: prepare %.1f ms, render %.1f ms", out_path,
                    img.width, img.height, method, lu_backend_name(backend), lu_cli_stats(r).prepare_ms, render_ms);
            if (lu_mpi_size() > 1)
                fprintf(stderr, " (%d ranks, %d thread%s each)", lu_mpi_size(), lu_thread_count(),
                        lu_thread_count() == 1 ? "" : "s");
            fputc('\n', stderr);
        }
    }
    lu_renderer_destroy(r);
    lu_image_destroy(&img);
    lu_scene_destroy(&scene);
    lu_kv_free(&settings);
    return rc;
}
