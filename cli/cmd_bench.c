/* lucent bench SCENE.json... --methods a,b — per-frame time after warm-up,
 * prepare time, peak memory, and error against the reference of the same
 * scene, all measured in one run (docs/architecture.md §8); parameter sweeps,
 * scripted motions (docs/bench.md) and the yardstick unit (cli/yardstick.c);
 * the pathtrace truth and its cache are cli/bench_truth.c, the plot
 * cli/bench_plot.c. Over 800 lines: one command whose motions, sweeps,
 * truths and rows share the row table and its output formats (in a job,
 * rows are gathered through cli/mpi.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_truth.h"
#include "cli.h"
#include "mpi_job.h"

static void usage(void) {
    printf("usage: lucent bench SCENE.json... --methods a,b,... [options]\n"
           "\n"
           "For each scene, motion, method, backend and combination of --sweep values: prepare\n"
           "once (timed), render --warmup frames, then --frames timed frames; reports the median\n"
           "frame time, prepare time, the method's peak resident memory, rel-L2 / PSNR against\n"
           "the reference image, and the frame time in sample-equivalents per pixel (below).\n"
           "\n"
           "options:\n"
           "  --methods LIST      comma-separated methods (default: the swept methods, else reference)\n"
           "  --backends LIST     cpu, gpu, auto or cpu,gpu (default: cpu; auto: a hardware GPU, else\n"
           "                      the CPU); methods skip backends they lack\n"
           "  --frames N          timed frames per row (default 5 still, 8 for a motion; reference: 1)\n"
           "  --warmup N          untimed frames first (default 1; the reference method: 0)\n"
           "  --size WxH          override the camera's image size\n"
           "  --set M.P=V         method parameter (repeatable); reference.* also shapes the truth\n"
           "  --sweep M.P=V1,V2   one row per value (repeatable; rows = the cross product of the\n"
           "                      sweeps of each method); overrides --set for that parameter\n"
           "  --motion LIST       still, orbit, light, medium (repeatable or comma list; default\n"
           "                      still). Timed frame k renders the scene k steps into the motion:\n"
           "                      orbit: the camera turns 4 deg per step about look_at and up;\n"
           "                      light: the first non-environment light turns 4 deg per step\n"
           "                      about the same axis; medium: a Gaussian blob of density added\n"
           "                      to the first grid medium moves one voxel along x per step;\n"
           "                      in a scene whose media follow time (sequences, an animated\n"
           "                      plume) the scene's time advances one frame (1/fps) instead.\n"
           "                      Warm-up frames render step 0; one renderer renders them all\n"
           "  --truth KIND        reference (default): single scattering, exact; pathtrace: every\n"
           "                      order of scattering, rendered with two seeds, doubling the samples\n"
           "                      until the noise of their mean is <= 2%% rel-L2 per pixel, or in 8x8\n"
           "                      block averages where per-pixel would take more than --truth-max-spp\n"
           "                      (the table's truth column says which); cached in the cache folder\n"
           "  --truth-max-spp N   most samples per pixel of the pathtrace truth (default %d)\n"
           "  --reference FILE    use this image as the truth instead of rendering it (one scene,\n"
           "                      still only); overrides --truth\n"
           "  --no-truth          render no truth: timings only, the error columns stay empty\n"
           "  --time T            put each scene at time T seconds first (media that follow time)\n"
           "  --stability         with a motion: render the truth at every timed state and\n"
           "                      report each row's flicker: the mean absolute difference of\n"
           "                      consecutive frames over the truth's own (1: no flicker of\n"
           "                      its own)\n"
           "  --tracking on|off|both  off: every frame rebuilds everything (what a frame costs\n"
           "                      without change tracking); both: each row twice, the second with\n"
           "                      params \"tracking=off\" (default on)\n"
           "  --no-yardstick      skip the yardstick (spp_eq stays 0): for a binary carried to a\n"
           "                      machine whose processor may lack this build's -march=native set\n"
           "  --save-images DIR   write each row's last frame as DIR/<method>-<backend>.exr (with\n"
           "                      the scene, motion and sweep index in the name when there are several)\n"
           "  --csv FILE          also write the table as CSV\n"
           "  --json FILE         also write the table as JSON\n"
           "  --plot FILE.png     draw rel-L2 against frame time (log-log, one point per row, one\n"
           "                      panel per scene and motion) with gnuplot\n"
           "\n"
           "Timings are wall-clock (monotonic) medians; compare methods as ratios within one\n"
           "run. The truth is the reference method at its settings on the CPU, rendered for the\n"
           "first and the last timed state of each motion; when reference is among --methods\n"
           "it reuses that render rather than rendering twice. Each run also times a fixed\n"
           "yardstick (trilinear samples over a 128^3 grid on all processors) and states each\n"
           "frame as frame time x yardstick throughput / pixels (spp_eq).\n"
           "\n"
           "Under mpirun or srun (a build with MPI) the ranks take whole scenes from a\n"
           "work queue (all of a scene's rows on one rank, spp_eq by that rank's own\n"
           "yardstick) and rank 0 prints and writes the merged table (docs/distributed.md).\n",
           LU_TRUTH_MAX_SPP_DEFAULT);
}

/* ---- motions ------------------------------------------------------------- */

typedef enum motion { MOTION_STILL = 0, MOTION_ORBIT, MOTION_LIGHT, MOTION_MEDIUM, MOTION_COUNT } motion;
static const char *const k_motion_names[MOTION_COUNT] = {"still", "orbit", "light", "medium"};

#define STEP_DEG 4.0f

/* A scene and the means to put it into any step of one motion. Steps are
 * computed from the saved step-0 values, so no error accumulates. */
typedef struct motion_state {
    motion kind;
    lu_scene *scene;
    lu_camera camera0;
    int light;            /* MOTION_LIGHT: index of the light that moves */
    lu_light light0;
    lu_grid *grid;        /* MOTION_MEDIUM */
    float *base;          /* the grid's values as loaded */
    float sigma, amplitude;
    int radius, cy, cz, cx0, step; /* blob: centre (blob_x(step), cy, cz) in voxels */
    bool blob_on;
    bool timed;           /* MOTION_MEDIUM in a scene that follows time: step k is time0 + k / fps */
    double time0;
} motion_state;

/* Rotates v by angle a (radians) about the unit axis k (Rodrigues). */
static lu_vec3 rotate_about(lu_vec3 v, lu_vec3 k, float a) {
    float c = cosf(a), s = sinf(a);
    lu_vec3 r = lu_v3_add(lu_v3_scale(v, c), lu_v3_scale(lu_v3_cross(k, v), s));
    return lu_v3_madd(r, k, lu_v3_dot(k, v) * (1.0f - c));
}

typedef struct blob_ctx {
    const motion_state *ms;
    int cx;
} blob_ctx;

/* The blob's x at step k: from nx/2 - frames/2 one voxel per step, turning
 * back at the grid's faces, so any number of frames stays inside. */
static int blob_x(const motion_state *ms, int k) {
    int n = ms->grid->nx;
    if (n < 2) return 0;
    int period = 2 * (n - 1), t = (ms->cx0 + k) % period;
    if (t < 0) t += period;
    return t < n ? t : period - t;
}

static float blob_value(const motion_state *ms, int cx, int x, int y, int z) {
    int dx = x - cx, dy = y - ms->cy, dz = z - ms->cz;
    if (abs(dx) > ms->radius || abs(dy) > ms->radius || abs(dz) > ms->radius) return 0.0f;
    float d2 = (float)(dx * dx + dy * dy + dz * dz);
    return ms->amplitude * expf(-0.5f * d2 / (ms->sigma * ms->sigma));
}

static float blob_edit(void *ctx, int x, int y, int z, float value) {
    const blob_ctx *b = ctx;
    const lu_grid *g = b->ms->grid;
    (void)value;
    return b->ms->base[((size_t)z * g->ny + y) * g->nx + x] + blob_value(b->ms, b->cx, x, y, z);
}

static void blob_box(const motion_state *ms, int cx, int lo[3], int hi[3]) {
    const int c[3] = {cx, ms->cy, ms->cz}, n[3] = {ms->grid->nx, ms->grid->ny, ms->grid->nz};
    for (int a = 0; a < 3; a++) {
        lo[a] = c[a] - ms->radius < 0 ? 0 : c[a] - ms->radius;
        hi[a] = c[a] + ms->radius + 1 > n[a] ? n[a] : c[a] + ms->radius + 1;
    }
}

/* Puts the scene into step k. The medium edit rewrites the union of the
 * blob's old and new boxes through the density-edit API, so renderers see a
 * local, non-uniform change with a new grid generation. */
static lu_result motion_set(motion_state *ms, int k, lu_error *err) {
    lu_scene *s = ms->scene;
    float a = (float)k * STEP_DEG * (float)M_PI / 180.0f;
    lu_vec3 axis = lu_v3_norm(ms->camera0.up), pivot = ms->camera0.look_at;
    switch (ms->kind) {
    case MOTION_STILL: return LU_OK;
    case MOTION_ORBIT:
        s->camera.position = lu_v3_add(pivot, rotate_about(lu_v3_sub(ms->camera0.position, pivot), axis, a));
        return LU_OK;
    case MOTION_LIGHT: {
        lu_light *l = &s->lights[ms->light];
        if (l->type != LU_LIGHT_DIRECTIONAL)
            l->position = lu_v3_add(pivot, rotate_about(lu_v3_sub(ms->light0.position, pivot), axis, a));
        if (l->type != LU_LIGHT_POINT) l->direction = lu_v3_norm(rotate_about(ms->light0.direction, axis, a));
        return LU_OK;
    }
    case MOTION_MEDIUM: {
        if (ms->timed) return lu_scene_set_time(s, ms->time0 + lu_scene_frame_time(s, k), err);
        int cx = blob_x(ms, k), lo[3], hi[3];
        blob_box(ms, cx, lo, hi);
        if (ms->blob_on) {
            int olo[3], ohi[3];
            blob_box(ms, blob_x(ms, ms->step), olo, ohi);
            for (int i = 0; i < 3; i++) {
                lo[i] = olo[i] < lo[i] ? olo[i] : lo[i];
                hi[i] = ohi[i] > hi[i] ? ohi[i] : hi[i];
            }
        }
        blob_ctx b = {ms, cx};
        lu_result r = lu_grid_apply(ms->grid, lo, hi, blob_edit, &b, err);
        if (r == LU_OK) {
            ms->step = k;
            ms->blob_on = true;
        }
        return r;
    }
    default: return LU_OK;
    }
}

/* Prepares a motion on the scene; *available false (with a note) when the
 * scene has nothing the motion can move. Leaves the scene at step 0. */
static lu_result motion_begin(motion_state *ms, motion kind, lu_scene *scene, int frames, bool *available,
                              lu_error *err) {
    memset(ms, 0, sizeof *ms);
    ms->kind = kind;
    ms->scene = scene;
    ms->camera0 = scene->camera;
    *available = true;
    if (kind == MOTION_LIGHT) {
        ms->light = -1;
        for (int i = 0; i < scene->light_count && ms->light < 0; i++)
            if (scene->lights[i].type != LU_LIGHT_ENVIRONMENT) ms->light = i;
        if (ms->light < 0) *available = false;
        else ms->light0 = scene->lights[ms->light];
    } else if (kind == MOTION_MEDIUM && lu_scene_animated(scene)) {
        /* The scene's own change of density, one frame per step. */
        ms->timed = true;
        ms->time0 = scene->time;
    } else if (kind == MOTION_MEDIUM) {
        for (int i = 0; i < scene->medium_count && !ms->grid; i++)
            if (lu_scene_medium_grid(scene, i, &ms->grid, NULL) != LU_OK) ms->grid = NULL;
        if (!ms->grid) {
            *available = false;
            return LU_OK;
        }
        const lu_grid *g = ms->grid;
        if (lu_grid_is_sparse(g))
            return lu_fail(err, LU_ERR_UNSUPPORTED,
                           "bench: --motion medium edits the density, and grid \"%s\" is sparse (read-only); give "
                           "the scene's file density \"storage\": \"dense\"",
                           g->name);
        size_t n = (size_t)g->nx * g->ny * g->nz;
        ms->base = malloc(n * sizeof *ms->base);
        if (!ms->base) return lu_fail(err, LU_ERR_NOMEM, "bench: out of memory copying the grid");
        memcpy(ms->base, g->data, n * sizeof *ms->base);
        int longest = g->nx > g->ny ? (g->nx > g->nz ? g->nx : g->nz) : (g->ny > g->nz ? g->ny : g->nz);
        /* A blob a sixteenth of the grid wide, as dense as the densest voxel,
         * passing through the grid's centre at the middle of the sequence. */
        ms->sigma = fmaxf(1.5f, (float)longest / 16.0f);
        ms->radius = (int)ceilf(3.0f * ms->sigma);
        ms->amplitude = g->max_value > 0.0f ? g->max_value : 1.0f;
        ms->cy = g->ny / 2;
        ms->cz = g->nz / 2;
        ms->cx0 = g->nx / 2 - frames / 2;
    }
    return *available ? motion_set(ms, 0, err) : LU_OK;
}

/* Back to the scene as loaded. */
static lu_result motion_end(motion_state *ms, lu_error *err) {
    lu_result r = LU_OK;
    ms->scene->camera = ms->camera0;
    if (ms->kind == MOTION_LIGHT && ms->light >= 0) ms->scene->lights[ms->light] = ms->light0;
    if (ms->kind == MOTION_MEDIUM && ms->timed) r = lu_scene_set_time(ms->scene, ms->time0, err);
    if (ms->kind == MOTION_MEDIUM && ms->grid && ms->blob_on)
        r = lu_grid_set_values(ms->grid, ms->base, (size_t)ms->grid->nx * ms->grid->ny * ms->grid->nz, err);
    free(ms->base);
    ms->base = NULL;
    return r;
}

/* ---- sweeps -------------------------------------------------------------- */

#define MAX_SWEEPS 16
#define MAX_SWEEP_VALUES 64
#define MAX_METHODS 32
#define MAX_SCENES 64
#define MAX_ROWS 4096

typedef struct sweep {
    char key[LU_KV_KEY_MAX];   /* method.param */
    char method[LU_KV_KEY_MAX];
    char *text;                /* owns the value strings */
    char *values[MAX_SWEEP_VALUES];
    int count;
} sweep;

/* Parses "method.param=v1,v2,..." and checks every value against the
 * method's parameter table, so a typo fails before anything renders. */
static int parse_sweep(const char *arg, sweep *sw, const sweep *prev, int nprev) {
    memset(sw, 0, sizeof *sw);
    const char *eq = strchr(arg, '=');
    const char *dot = strchr(arg, '.');
    if (!eq || !dot || dot > eq || dot == arg || dot + 1 == eq || eq[1] == '\0')
        return lu_cli_usage("bench", "--sweep \"%s\": expected method.param=v1,v2,...", arg);
    if ((size_t)(eq - arg) >= sizeof sw->key) return lu_cli_usage("bench", "--sweep \"%s\": name too long", arg);
    snprintf(sw->key, sizeof sw->key, "%.*s", (int)(eq - arg), arg);
    snprintf(sw->method, sizeof sw->method, "%.*s", (int)(dot - arg), arg);
    for (int i = 0; i < nprev; i++)
        if (strcmp(prev[i].key, sw->key) == 0) return lu_cli_usage("bench", "--sweep %s given twice", sw->key);
    const lu_method *m = lu_method_find(sw->method);
    if (!m) return lu_cli_usage("bench", "--sweep %s: no method named \"%s\"", sw->key, sw->method);
    sw->text = strdup(eq + 1);
    if (!sw->text) return lu_cli_usage("bench", "out of memory");
    for (char *p = sw->text;;) {
        char *comma = strchr(p, ',');
        if (comma) *comma = '\0';
        if (*p == '\0') return lu_cli_usage("bench", "--sweep \"%s\": empty value in the list", arg);
        if (strlen(p) >= LU_KV_STR_MAX)
            return lu_cli_usage("bench", "--sweep %s: a value longer than %d characters", sw->key, LU_KV_STR_MAX - 1);
        if (sw->count == MAX_SWEEP_VALUES)
            return lu_cli_usage("bench", "--sweep %s: more than %d values", sw->key, MAX_SWEEP_VALUES);
        sw->values[sw->count++] = p;
        if (!comma) break;
        p = comma + 1;
    }
    for (int i = 0; i < sw->count; i++) {
        char assign[LU_KV_KEY_MAX + LU_KV_STR_MAX + 2];
        snprintf(assign, sizeof assign, "%s=%s", sw->key, sw->values[i]);
        lu_kvlist kv = {0};
        lu_error err = {0};
        double vals[LU_MAX_PARAMS];
        lu_result r = lu_kv_parse_assignment(&kv, assign, &err);
        if (r == LU_OK) r = lu_settings_validate(&kv, &err);
        if (r == LU_OK) r = lu_method_resolve_params(m, &kv, vals, &err);
        lu_kv_free(&kv);
        if (r != LU_OK) return lu_cli_usage("bench", "--sweep %s: %s", sw->key, err.message);
    }
    return LU_EXIT_OK;
}

/* Appends s to dst (capacity size, *used bytes so far), cutting it short
 * rather than overflowing. */
static void append(char *dst, size_t size, size_t *used, const char *s) {
    size_t n = strlen(s);
    if (*used + n >= size) n = size - 1 - *used;
    memcpy(dst + *used, s, n);
    *used += n;
    dst[*used] = '\0';
}

/* Settings for combination `combo` of method m's sweeps (the first sweep
 * varies slowest), on top of the --set list; label gets "k=v k=v". */
static lu_result combo_settings(const lu_kvlist *base, const sweep *sw, int nsw, const char *method, int combo,
                                lu_kvlist *out, char *label, size_t label_size, lu_error *err) {
    memset(out, 0, sizeof *out);
    label[0] = '\0';
    lu_result r = LU_OK;
    for (int i = 0; i < base->count && r == LU_OK; i++) {
        const lu_kv *kv = &base->items[i];
        r = kv->count ? lu_kv_set_number(out, kv->key, kv->v, kv->count, err) : lu_kv_set_string(out, kv->key, kv->str, err);
    }
    int radix = 1, pick[MAX_SWEEPS];
    for (int i = nsw - 1; i >= 0; i--) {
        if (strcmp(sw[i].method, method) != 0) continue;
        pick[i] = (combo / radix) % sw[i].count;
        radix *= sw[i].count;
    }
    size_t used = 0;
    for (int i = 0; i < nsw && r == LU_OK; i++) {
        if (strcmp(sw[i].method, method) != 0) continue;
        char assign[LU_KV_KEY_MAX + LU_KV_STR_MAX + 2];
        size_t alen = 0;
        append(assign, sizeof assign, &alen, sw[i].key);
        append(assign, sizeof assign, &alen, "=");
        append(assign, sizeof assign, &alen, sw[i].values[pick[i]]);
        r = lu_kv_parse_assignment(out, assign, err);
        if (used) append(label, label_size, &used, " ");
        append(label, label_size, &used, assign);
    }
    return r;
}

static int combo_count(const sweep *sw, int nsw, const char *method) {
    int n = 1;
    for (int i = 0; i < nsw; i++)
        if (strcmp(sw[i].method, method) == 0) n *= sw[i].count;
    return n;
}

/* ---- rows ---------------------------------------------------------------- */

typedef struct row {
    const char *scene;      /* the SCENE argument */
    int width, height;
    const char *method;
    lu_backend backend;
    motion motion;
    char params[512];       /* the sweep values of this row, "" without sweeps */
    double prepare_ms, median_ms, min_ms, max_ms;
    double ref_ms;          /* the truth's render time for this row's first state */
    double peak_mb;
    double held_mb, gpu_mb; /* what the renderer held after its frames (lu_renderer_stats.memory) */
    int frames;
    lu_metrics err;         /* the last frame against the truth of its state */
    bool has_err;
    double rel_l2_first, rel_l2_last, last_vs_first;
    double spp_equiv, load_avg;
    double update_ms;       /* median time of the scene change before each timed frame (not in frame_ms) */
    double flicker;         /* --stability: mean |frame k - frame k-1| over the truth's; < 0: not measured */
    double gsps;            /* the yardstick spp_equiv used: in a job, its rank's */
    char truth[48];         /* what rel_l2 is measured against: "reference", "pathtrace(1.6%)", "file" */
    double truth_noise;     /* the first state's pathtrace truth: its noise and spp (0: another truth) */
    int truth_spp;
    /* A row travels to rank 0 as bytes (cli/mpi.c); these name what its
     * pointers point to, to point them again there. */
    int scene_index, seq;
    char method_name[64];
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

static double load_avg_1min(void) {
    double l[3];
    return getloadavg(l, 3) >= 1 ? l[0] : -1.0;
}

static lu_result image_copy(const lu_image *src, lu_image *dst, lu_error *err) {
    if (dst->width != src->width || dst->height != src->height) {
        lu_image_destroy(dst);
        lu_result r = lu_image_create(dst, src->width, src->height, err);
        if (r != LU_OK) return r;
    }
    memcpy(dst->rgb, src->rgb, (size_t)src->width * src->height * 3 * sizeof *src->rgb);
    return LU_OK;
}

/* Mean absolute difference of two images of one size, over pixels and channels. */
static double mean_abs_diff(const lu_image *a, const lu_image *b) {
    size_t n = (size_t)a->width * a->height * 3;
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += fabs((double)a->rgb[i] - b->rgb[i]);
    return n ? s / (double)n : 0.0;
}

/* Renders one row: prepare once at step 0, warm-up frames at step 0, timed
 * frame k at step k (1..frames; still: always step 0). Keeps the first and
 * the last timed frame. Leaves the scene at step 0 of the motion. */
static lu_result bench_one(motion_state *ms, const char *method, lu_backend backend, const lu_kvlist *settings,
                           int warmup, int frames, bool untracked, row *out, lu_image *first, lu_image *last,
                           double *step_diff, lu_error *err) {
    out->method = method;
    out->backend = backend;
    lu_peak_rss_reset();
    size_t rss0 = lu_peak_rss_bytes();
    lu_renderer *r;
    lu_result res = lu_renderer_create(method, ms->scene, settings, backend, &r, err);
    if (res != LU_OK) return res;
    out->prepare_ms = lu_cli_stats(r).prepare_ms;
    double *ms_list = calloc((size_t)frames, sizeof *ms_list);
    if (!ms_list) {
        lu_renderer_destroy(r);
        return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    }
    /* untracked: every frame rebuilds everything, what frames cost without
     * the frame stage's change tracking. */
    for (int i = 0; i < warmup && res == LU_OK; i++) {
        if (untracked) lu_renderer_invalidate(r, LU_CHANGE_ALL);
        res = lu_renderer_render(r, ms->scene, last, err);
    }
    lu_image prev = {0};
    *step_diff = 0.0;
    double *up_list = calloc((size_t)frames, sizeof *up_list);
    if (!up_list) res = lu_fail(err, LU_ERR_NOMEM, "out of memory");
    for (int k = 1; k <= frames && res == LU_OK; k++) {
        double u0 = lu_time_seconds();
        res = motion_set(ms, ms->kind == MOTION_STILL ? 0 : k, err);
        up_list[k - 1] = 1e3 * (lu_time_seconds() - u0);
        if (untracked) lu_renderer_invalidate(r, LU_CHANGE_ALL);
        if (res == LU_OK) res = lu_renderer_render(r, ms->scene, last, err);
        if (res == LU_OK) ms_list[k - 1] = lu_cli_stats(r).frame_ms;
        if (res == LU_OK && k == 1) res = image_copy(last, first, err);
        /* the frame-to-frame change, outside the timed render */
        if (res == LU_OK && k > 1) *step_diff += mean_abs_diff(last, &prev);
        if (res == LU_OK && k < frames) res = image_copy(last, &prev, err);
    }
    lu_image_destroy(&prev);
    if (res == LU_OK) res = motion_set(ms, 0, err);
    if (res == LU_OK) {
        qsort(ms_list, (size_t)frames, sizeof *ms_list, cmp_double);
        out->frames = frames;
        out->min_ms = ms_list[0];
        out->max_ms = ms_list[frames - 1];
        out->median_ms = frames % 2 ? ms_list[frames / 2] : 0.5 * (ms_list[frames / 2 - 1] + ms_list[frames / 2]);
        qsort(up_list, (size_t)frames, sizeof *up_list, cmp_double);
        out->update_ms = frames % 2 ? up_list[frames / 2] : 0.5 * (up_list[frames / 2 - 1] + up_list[frames / 2]);
        size_t rss1 = lu_peak_rss_bytes();
        out->peak_mb = (double)(rss1 > rss0 ? rss1 : rss0) / (1024.0 * 1024.0);
        lu_memory held = lu_cli_stats(r).memory;
        out->held_mb = (double)(held.bytes + held.accel_bytes) / (1024.0 * 1024.0);
        out->gpu_mb = (double)held.gpu_bytes / (1024.0 * 1024.0);
    }
    free(ms_list);
    free(up_list);
    lu_renderer_destroy(r);
    return res;
}

/* The truth at step k: the reference at its settings on the CPU, a fresh
 * renderer for that state. Leaves the scene at step 0. */
static lu_result render_truth(motion_state *ms, int k, const lu_kvlist *settings, lu_image *img, double *ms_out,
                              lu_error *err) {
    lu_result r = motion_set(ms, k, err);
    lu_renderer *rd = NULL;
    if (r == LU_OK) r = lu_renderer_create("reference", ms->scene, settings, LU_BACKEND_CPU, &rd, err);
    if (r == LU_OK) r = lu_renderer_render(rd, ms->scene, img, err);
    if (r == LU_OK) *ms_out = lu_cli_stats(rd).frame_ms;
    lu_renderer_destroy(rd);
    lu_result r2 = motion_set(ms, 0, err);
    return r != LU_OK ? r : r2;
}

/* a against the truth t, per pixel (block 1) or as block x block averages. */
static lu_result compare_truth(const lu_image *a, const lu_image *t, int block, lu_metrics *m, lu_error *err) {
    if (block <= 1) return lu_image_compare(a, t, m, err);
    lu_image ba = {0}, bt = {0};
    lu_result r = lu_image_block_average(a, block, &ba, err);
    if (r == LU_OK) r = lu_image_block_average(t, block, &bt, err);
    if (r == LU_OK) r = lu_image_compare(&ba, &bt, m, err);
    lu_image_destroy(&ba);
    lu_image_destroy(&bt);
    return r;
}

static double psnr_out(double p) { return isinf(p) ? 999.0 : p; }

/* Column names say which truth the errors are measured against: the plain
 * names are those against reference (or the --reference image), sfx
 * "_vs_pathtrace" (the text table: "_pt") marks the multiple-scattering truth. */
static void colname(char *out, size_t n, const char *base, const char *sfx) { snprintf(out, n, "%s%s", base, sfx); }

static void print_table(FILE *f, const row *rows, int n, const char *sfx) {
    char x[64], rl[64], ps[64], rf[64];
    colname(x, sizeof x, *sfx ? "x_vs" : "x_vs_ref", sfx);
    colname(rl, sizeof rl, "rel_l2", sfx);
    colname(ps, sizeof ps, "psnr_dB", sfx);
    colname(rf, sizeof rf, "rel_l2_first", sfx);
    int wx = *sfx ? (int)strlen(x) : 10, wr = *sfx ? (int)strlen(rl) : 10, wp = *sfx ? (int)strlen(ps) : 9,
        wf = *sfx ? (int)strlen(rf) : 12;
    fprintf(f, "%-12s %-4s %12s %12s %*s %10s %9s %*s %*s %-7s %*s %10s %-20s %s\n", "method", "dev", "prepare_ms",
            "frame_ms", wx, x, "peak_MB", "held_MB", wr, rl, wp, ps, "motion", wf, rf, "spp_eq", "truth", "scene params");
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f, "%-12s %-4s %12.2f %12.2f %*.2f %10.1f %9.1f ", r->method, lu_backend_name(r->backend),
                r->prepare_ms, r->median_ms, wx, r->ref_ms > 0 ? r->ref_ms / r->median_ms : 0.0, r->peak_mb,
                r->held_mb + r->gpu_mb);
        if (r->has_err) fprintf(f, "%*.5f %*.2f ", wr, r->err.rel_l2, wp, psnr_out(r->err.psnr));
        else fprintf(f, "%*s %*s ", wr, "-", wp, "-");
        fprintf(f, "%-7s ", k_motion_names[r->motion]);
        if (r->has_err) fprintf(f, "%*.5f ", wf, r->rel_l2_first);
        else fprintf(f, "%*s ", wf, "-");
        fprintf(f, "%10.1f %-20s %s%s%s", r->spp_equiv, r->truth[0] ? r->truth : "-", r->scene, r->params[0] ? " " : "",
                r->params);
        if (r->flicker >= 0.0) fprintf(f, "  flicker %.3f", r->flicker);
        fputc('\n', f);
    }
}

static bool write_csv(const char *path, const row *rows, int n, const char *sfx, lu_error *err) {
    lu_atomic_file af;
    if (lu_atomic_open(&af, path, err) != LU_OK) return false;
    FILE *f = af.fp;
    const char *t = *sfx ? sfx : "_vs_reference";
    fprintf(f, "scene,method,backend,prepare_ms,frame_ms_median,frame_ms_min,frame_ms_max,frames,speedup%s,"
               "peak_mb,rel_l2%s,rel_l1%s,rmse%s,psnr%s,motion,params,rel_l2_first%s,rel_l2_last%s,rel_l2_last_vs_first,"
               "spp_equiv,yardstick_gsps,load_avg,width,height,threads,flicker,update_ms,truth,held_mb,gpu_mb\n",
            t, sfx, sfx, sfx, sfx, sfx, sfx);
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f, "%s,%s,%s,%.3f,%.3f,%.3f,%.3f,%d,%.4f,%.1f,", r->scene, r->method, lu_backend_name(r->backend),
                r->prepare_ms, r->median_ms, r->min_ms, r->max_ms, r->frames,
                r->ref_ms > 0 ? r->ref_ms / r->median_ms : 0.0, r->peak_mb);
        if (r->has_err)
            fprintf(f, "%.6g,%.6g,%.6g,%.4f,", r->err.rel_l2, r->err.rel_l1, r->err.rmse, psnr_out(r->err.psnr));
        else fprintf(f, ",,,,");
        /* Sweep labels separate assignments with spaces, so no field holds a comma. */
        fprintf(f, "%s,%s,", k_motion_names[r->motion], r->params);
        if (r->has_err) fprintf(f, "%.6g,%.6g,", r->rel_l2_first, r->rel_l2_last);
        else fprintf(f, ",,");
        fprintf(f, "%.6g,%.2f,%.4f,%.2f,%d,%d,%d,", r->last_vs_first, r->spp_equiv, r->gsps, r->load_avg, r->width,
                r->height, lu_thread_count());
        if (r->flicker >= 0.0) fprintf(f, "%.6g", r->flicker);
        fprintf(f, ",%.3f,%s,%.3f,%.3f\n", r->update_ms, r->truth, r->held_mb, r->gpu_mb);
    }
    return lu_atomic_commit(&af, err) == LU_OK;
}

static void json_string(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"' || *s == '\\') fputc('\\', f);
        if ((unsigned char)*s < 0x20) fprintf(f, "\\u%04x", (unsigned char)*s);
        else fputc(*s, f);
    }
    fputc('"', f);
}

static bool write_json(const char *path, const row *rows, int n, double gsps, double gsps_end, int ys_threads,
                       const char *scene0, const char *truth, const char *sfx, lu_error *err) {
    lu_atomic_file af;
    if (lu_atomic_open(&af, path, err) != LU_OK) return false;
    FILE *f = af.fp;
    fprintf(f, "{\"scene\": ");
    json_string(f, scene0);
    fprintf(f, ", \"truth\": \"%s\"", truth);
    fprintf(f, ", \"width\": %d, \"height\": %d, \"threads\": %d, \"yardstick_gsps\": %.4f, \"yardstick_gsps_end\": %.4f, "
               "\"yardstick_threads\": %d, \"load_avg\": %.2f, \"rows\": [\n",
            n ? rows[0].width : 0, n ? rows[0].height : 0, lu_thread_count(), gsps, gsps_end, ys_threads,
            load_avg_1min());
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        fprintf(f, "  {\"scene\": ");
        json_string(f, r->scene);
        fprintf(f,
                ", \"width\": %d, \"height\": %d, \"method\": \"%s\", \"backend\": \"%s\", \"motion\": \"%s\", "
                "\"params\": ",
                r->width, r->height, r->method, lu_backend_name(r->backend), k_motion_names[r->motion]);
        json_string(f, r->params);
        fprintf(f, ", \"truth\": ");
        json_string(f, r->truth);
        fprintf(f,
                ", \"prepare_ms\": %.3f, \"frame_ms\": %.3f, \"frames\": %d, \"speedup%s\": %.4f, "
                "\"peak_mb\": %.1f, \"held_mb\": %.3f, \"gpu_mb\": %.3f",
                r->prepare_ms, r->median_ms, r->frames, *sfx ? sfx : "_vs_reference",
                r->ref_ms > 0 ? r->ref_ms / r->median_ms : 0.0, r->peak_mb, r->held_mb, r->gpu_mb);
        if (r->has_err)
            fprintf(f, ", \"rel_l2%s\": %.6g, \"rel_l1%s\": %.6g, \"psnr%s\": %.4f, \"rel_l2_first%s\": %.6g, "
                       "\"rel_l2_last%s\": %.6g",
                    sfx, r->err.rel_l2, sfx, r->err.rel_l1, sfx, psnr_out(r->err.psnr), sfx, r->rel_l2_first, sfx,
                    r->rel_l2_last);
        if (r->flicker >= 0.0) fprintf(f, ", \"flicker\": %.6g", r->flicker);
        fprintf(f, ", \"update_ms\": %.3f", r->update_ms);
        fprintf(f, ", \"rel_l2_last_vs_first\": %.6g, \"spp_equiv\": %.2f, \"yardstick_gsps\": %.4f, \"load_avg\": %.2f}%s\n",
                r->last_vs_first, r->spp_equiv, r->gsps, r->load_avg, i + 1 < n ? "," : "");
    }
    fprintf(f, "]}\n");
    return lu_atomic_commit(&af, err) == LU_OK;
}

/* Base name of a scene path without ".json", for image names. */
static void scene_stem(const char *path, char *out, size_t n) {
    const char *s = strrchr(path, '/');
    s = s ? s + 1 : path;
    snprintf(out, n, "%s", s);
    char *dot = strrchr(out, '.');
    if (dot && strcmp(dot, ".json") == 0) *dot = '\0';
}

static int cmp_rows(const void *a, const void *b) {
    const row *x = a, *y = b;
    if (x->scene_index != y->scene_index) return x->scene_index < y->scene_index ? -1 : 1;
    return (x->seq > y->seq) - (x->seq < y->seq);
}

typedef struct bench_opts bench_opts;
static lu_result gather_rows(const bench_opts *o, row **rows, int *nrows, lu_error *err);

/* ---- the command --------------------------------------------------------- */

struct bench_opts {
    const char *scenes[MAX_SCENES];
    int nscenes;
    char *methods[MAX_METHODS];
    int nmethods;
    lu_backend backends[2];
    int nbackends;
    bool motions[MOTION_COUNT];
    int frames, warmup, width, height;   /* frames 0: the default per motion */
    lu_kvlist settings;
    sweep sweeps[MAX_SWEEPS];
    int nsweeps;
    const char *csv, *json, *ref_path, *img_dir, *plot;
    bool truth_pathtrace;      /* --truth pathtrace (without --reference) */
    int truth_max_spp;
    bool no_truth, no_yardstick, stability, time_given;
    double time;
    unsigned tracking;         /* bit 0: rows with change tracking, bit 1: rows without */
};

static int parse_motions(const char *arg, bool *motions) {
    char buf[256];
    snprintf(buf, sizeof buf, "%s", arg);
    char *items[16];
    int n = split_list(buf, items, 16);
    if (n == 0) return lu_cli_usage("bench", "--motion takes still, orbit, light or medium");
    for (int i = 0; i < n; i++) {
        int k = 0;
        while (k < MOTION_COUNT && strcmp(items[i], k_motion_names[k]) != 0) k++;
        if (k == MOTION_COUNT)
            return lu_cli_usage("bench", "--motion: unknown motion \"%s\" (still, orbit, light, medium)", items[i]);
        motions[k] = true;
    }
    return LU_EXIT_OK;
}

static int parse_args(int argc, char **argv, bench_opts *o, char *methods_buf, size_t mb_size, char *backends_buf,
                      size_t bb_size) {
    lu_error err = {0};
    bool methods_given = false, motion_given = false;
    int rc = LU_EXIT_OK;
    for (int i = 1; i < argc && rc == LU_EXIT_OK; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        char *end = NULL;
        if (lu_cli_is_help(a)) {
            usage();
            return -1;
        } else if (strcmp(a, "--methods") == 0 && has_next) {
            snprintf(methods_buf, mb_size, "%s", argv[++i]);
            methods_given = true;
        } else if (strcmp(a, "--backends") == 0 && has_next) {
            snprintf(backends_buf, bb_size, "%s", argv[++i]);
        } else if (strcmp(a, "--frames") == 0 && has_next) {
            o->frames = (int)strtol(argv[++i], &end, 10);
            if (*end || o->frames < 1 || o->frames > 10000) rc = lu_cli_usage("bench", "--frames takes 1..10000");
        } else if (strcmp(a, "--warmup") == 0 && has_next) {
            o->warmup = (int)strtol(argv[++i], &end, 10);
            if (*end || o->warmup < 0 || o->warmup > 10000) rc = lu_cli_usage("bench", "--warmup takes 0..10000");
        } else if (strcmp(a, "--size") == 0 && has_next) {
            if (!lu_cli_parse_size(argv[++i], &o->width, &o->height)) rc = lu_cli_usage("bench", "--size takes WxH");
        } else if (strcmp(a, "--set") == 0 && has_next) {
            if (lu_kv_parse_assignment(&o->settings, argv[++i], &err) != LU_OK) rc = lu_cli_error("bench", &err);
        } else if (strcmp(a, "--sweep") == 0 && has_next) {
            if (o->nsweeps == MAX_SWEEPS) rc = lu_cli_usage("bench", "at most %d --sweep options", MAX_SWEEPS);
            else {
                rc = parse_sweep(argv[++i], &o->sweeps[o->nsweeps], o->sweeps, o->nsweeps);
                o->nsweeps++; /* counted even on failure, so its text is freed */
            }
        } else if (strcmp(a, "--motion") == 0 && has_next) {
            rc = parse_motions(argv[++i], o->motions);
            motion_given = true;
        } else if (strcmp(a, "--reference") == 0 && has_next) {
            o->ref_path = argv[++i];
        } else if (strcmp(a, "--truth") == 0 && has_next) {
            const char *v = argv[++i];
            if (strcmp(v, "pathtrace") == 0) o->truth_pathtrace = true;
            else if (strcmp(v, "reference") == 0) o->truth_pathtrace = false;
            else rc = lu_cli_usage("bench", "--truth \"%s\": expected reference or pathtrace", v);
        } else if (strcmp(a, "--truth-max-spp") == 0 && has_next) {
            o->truth_max_spp = (int)strtol(argv[++i], &end, 10);
            if (*end || o->truth_max_spp < 2 || o->truth_max_spp > (1 << 20))
                rc = lu_cli_usage("bench", "--truth-max-spp takes 2..1048576");
        } else if (strcmp(a, "--plot") == 0 && has_next) {
            o->plot = argv[++i];
        } else if (strcmp(a, "--no-truth") == 0) {
            o->no_truth = true;
        } else if (strcmp(a, "--time") == 0 && has_next) {
            o->time = strtod(argv[++i], &end);
            o->time_given = true;
            if (*end || end == argv[i] || !isfinite(o->time) || fabs(o->time) > 1e6)
                rc = lu_cli_usage("bench", "--time takes seconds in [-1e6, 1e6] (\"%s\")", argv[i]);
        } else if (strcmp(a, "--stability") == 0) {
            o->stability = true;
        } else if (strcmp(a, "--no-yardstick") == 0) {
            o->no_yardstick = true;
        } else if (strcmp(a, "--tracking") == 0 && has_next) {
            const char *v = argv[++i];
            o->tracking = strcmp(v, "on") == 0 ? 1u : strcmp(v, "off") == 0 ? 2u : strcmp(v, "both") == 0 ? 3u : 0u;
            if (!o->tracking) return lu_cli_usage("bench", "--tracking \"%s\": expected on, off or both", v);
        } else if (strcmp(a, "--save-images") == 0 && has_next) {
            o->img_dir = argv[++i];
        } else if (strcmp(a, "--csv") == 0 && has_next) {
            o->csv = argv[++i];
        } else if (strcmp(a, "--json") == 0 && has_next) {
            o->json = argv[++i];
        } else if (a[0] == '-') {
            rc = lu_cli_usage("bench", "unknown or incomplete option \"%s\"", a);
        } else if (o->nscenes == MAX_SCENES) {
            rc = lu_cli_usage("bench", "at most %d scenes", MAX_SCENES);
        } else {
            o->scenes[o->nscenes++] = a;
        }
    }
    if (rc != LU_EXIT_OK) return rc;
    if (o->nscenes == 0) return lu_cli_usage("bench", "missing SCENE.json");
    if (!motion_given) o->motions[MOTION_STILL] = true;
    if (!methods_given && o->nsweeps > 0) {
        /* The swept methods, in the order first named. */
        methods_buf[0] = '\0';
        for (int i = 0; i < o->nsweeps; i++) {
            bool seen = false;
            for (int j = 0; j < i; j++) seen = seen || strcmp(o->sweeps[j].method, o->sweeps[i].method) == 0;
            if (seen) continue;
            size_t len = strlen(methods_buf);
            snprintf(methods_buf + len, mb_size - len, "%s%s", len ? "," : "", o->sweeps[i].method);
        }
    }
    o->nmethods = split_list(methods_buf, o->methods, MAX_METHODS);
    char *bnames[3];
    o->nbackends = split_list(backends_buf, bnames, 3);
    if (o->nmethods == 0) return lu_cli_usage("bench", "--methods is empty");
    for (int i = 0; i < o->nmethods; i++)
        if (!lu_method_find(o->methods[i])) return lu_cli_usage("bench", "no method named \"%s\"", o->methods[i]);
    if (o->nbackends == 0 || o->nbackends > 2) return lu_cli_usage("bench", "--backends takes cpu,gpu,auto");
    for (int i = 0; i < o->nbackends; i++) {
        if (!lu_cli_parse_backend(bnames[i], &o->backends[i]))
            return lu_cli_usage("bench", "--backends takes cpu,gpu,auto");
        o->backends[i] = lu_cli_resolve_backend("bench", o->backends[i], NULL);
    }
    for (int i = 0; i < o->nsweeps; i++) {
        bool listed = false;
        for (int j = 0; j < o->nmethods; j++) listed = listed || strcmp(o->methods[j], o->sweeps[i].method) == 0;
        if (!listed)
            return lu_cli_usage("bench", "--sweep %s: method %s is not among --methods", o->sweeps[i].key,
                                o->sweeps[i].method);
    }
    long rows = 0;
    for (int j = 0; j < o->nmethods; j++) rows += combo_count(o->sweeps, o->nsweeps, o->methods[j]);
    int nmot = 0;
    for (int k = 0; k < MOTION_COUNT; k++) nmot += o->motions[k];
    rows *= (long)o->nscenes * o->nbackends * nmot;
    if (rows > MAX_ROWS) return lu_cli_usage("bench", "%ld rows requested; at most %d", rows, MAX_ROWS);
    if (o->ref_path && o->no_truth) return lu_cli_usage("bench", "--reference and --no-truth exclude each other");
    if (o->truth_pathtrace && o->no_truth) return lu_cli_usage("bench", "--truth and --no-truth exclude each other");
    /* --reference overrides --truth: the image is the truth. */
    if (o->ref_path) o->truth_pathtrace = false;
    if (o->truth_pathtrace && o->stability)
        return lu_cli_usage("bench", "--stability: the pathtrace truth's own noise would count as change; use "
                                     "--truth reference");
    if (o->plot && o->no_truth) return lu_cli_usage("bench", "--plot draws errors: not with --no-truth");
    if (o->plot && !lu_path_has_suffix(o->plot, ".png")) return lu_cli_usage("bench", "--plot %s: expected a .png name", o->plot);
    if (o->stability && (o->no_truth || o->ref_path))
        return lu_cli_usage("bench", "--stability measures against the truth: not with --no-truth or --reference");
    if (o->stability && nmot == o->motions[MOTION_STILL])
        return lu_cli_usage("bench", "--stability needs a motion (orbit, light or medium)");
    if (o->stability && o->frames == 1) return lu_cli_usage("bench", "--stability needs --frames of 2 or more");
    if (o->ref_path && (o->nscenes > 1 || nmot > 1 || !o->motions[MOTION_STILL]))
        return lu_cli_usage("bench", "--reference takes one SCENE and --motion still only");
    for (int i = 0; i < o->nscenes; i++) {
        struct stat st;
        if (stat(o->scenes[i], &st) != 0 || !S_ISREG(st.st_mode)) {
            lu_error e;
            lu_fail(&e, LU_ERR_IO, "%s: no such scene file", o->scenes[i]);
            return lu_cli_error("bench", &e);
        }
    }
    if (lu_settings_validate(&o->settings, &err) != LU_OK) return lu_cli_error("bench", &err);
    return LU_EXIT_OK;
}

/* The pathtrace truth at step k (cli/bench_truth.c). The state's words
 * enter the cache key; the media's values in that state enter it there.
 * Leaves the scene at step 0. */
static lu_result pathtrace_truth(const bench_opts *o, motion_state *ms, const char *path, int k, int block,
                                 lu_image *img, lu_truth_info *ti, lu_error *err) {
    lu_result r = motion_set(ms, k, err);
    char state[96];
    snprintf(state, sizeof state, "%s %d time %.17g", k_motion_names[ms->kind], k, ms->scene->time);
    if (r == LU_OK)
        r = lu_bench_pathtrace_truth(ms->scene, path, &o->settings, state, block,
                                     o->truth_max_spp ? o->truth_max_spp : LU_TRUTH_MAX_SPP_DEFAULT, img, ti, err);
    lu_result r2 = motion_set(ms, 0, err);
    return r != LU_OK ? r : r2;
}

/* One scene: every motion, method, backend and sweep combination. Appends
 * to rows. */
static lu_result bench_scene(const bench_opts *o, const char *path, lu_scene *scene, double gsps, row *rows,
                             int *nrows, lu_error *err) {
    char stem[256];
    scene_stem(path, stem, sizeof stem);
    const int pixels = scene->camera.width * scene->camera.height;
    lu_result res = LU_OK;
    for (int mk = 0; mk < MOTION_COUNT && res == LU_OK; mk++) {
        if (!o->motions[mk]) continue;
        motion mo = (motion)mk;
        int frames = o->frames ? o->frames : (mo == MOTION_STILL ? 5 : 8);
        motion_state ms;
        bool available;
        res = motion_begin(&ms, mo, scene, frames, &available, err);
        if (res == LU_OK && !available) {
            fprintf(stderr, "lucent bench: %s has no %s to move; --motion %s skipped\n", path,
                    mo == MOTION_LIGHT ? "point, spot or directional light" : "grid medium", k_motion_names[mo]);
            motion_end(&ms, err);
            continue;
        }
        /* Truths for the first and last timed state (still: one state). */
        lu_image truth_first = {0}, truth_last = {0};
        double truth_first_ms = 0.0, truth_last_ms = 0.0;
        int first_step = mo == MOTION_STILL ? 0 : 1, last_step = mo == MOTION_STILL ? 0 : frames;
        lu_truth_info ti_first = {0}, ti_last = {0};
        char truth_label[48] = "";
        int block = 1;      /* the truth is compared in block x block averages */
        if (res == LU_OK && o->ref_path) {
            snprintf(truth_label, sizeof truth_label, "file");
            res = lu_image_load(o->ref_path, &truth_first, err);
            if (res == LU_OK && (truth_first.width != scene->camera.width || truth_first.height != scene->camera.height))
                res = lu_fail(err, LU_ERR_INVALID_ARG, "%s is %dx%d but the scene renders %dx%d", o->ref_path,
                              truth_first.width, truth_first.height, scene->camera.width, scene->camera.height);
        } else if (res == LU_OK && o->truth_pathtrace) {
            fprintf(stderr, "lucent bench: %s: the pathtrace truth, %s ...\n", path, k_motion_names[mo]);
            res = pathtrace_truth(o, &ms, path, first_step, 0, &truth_first, &ti_first, err);
            truth_first_ms = ti_first.ms;
            block = ti_first.block;
            /* the last state is judged in the first one's comparison */
            if (res == LU_OK && last_step != first_step)
                res = pathtrace_truth(o, &ms, path, last_step, block, &truth_last, &ti_last, err);
            snprintf(truth_label, sizeof truth_label, "%s", last_step != first_step ? ti_last.label : ti_first.label);
        } else if (res == LU_OK && !o->no_truth) {
            snprintf(truth_label, sizeof truth_label, "reference");
            fprintf(stderr, "lucent bench: %s: rendering the reference (the truth), %s ...\n", path,
                    k_motion_names[mo]);
            res = render_truth(&ms, first_step, &o->settings, &truth_first, &truth_first_ms, err);
        }
        /* --stability: the truth of every timed state, for the truth's own frame-to-frame change */
        double truth_step_diff = 0.0;
        if (res == LU_OK && o->stability && last_step != first_step) {
            lu_image prev = {0}, cur = {0};
            double t_ms;
            res = image_copy(&truth_first, &prev, err);
            for (int k = first_step + 1; k < last_step && res == LU_OK; k++) {
                fprintf(stderr, "lucent bench: %s: the truth of state %d of %d (--stability) ...\n", path, k, last_step);
                res = render_truth(&ms, k, &o->settings, &cur, &t_ms, err);
                if (res == LU_OK) truth_step_diff += mean_abs_diff(&cur, &prev);
                if (res == LU_OK) res = image_copy(&cur, &prev, err);
            }
            if (res == LU_OK) res = render_truth(&ms, last_step, &o->settings, &truth_last, &truth_last_ms, err);
            if (res == LU_OK) truth_step_diff += mean_abs_diff(&truth_last, &prev);
            lu_image_destroy(&prev);
            lu_image_destroy(&cur);
        } else if (res == LU_OK && last_step != first_step && !o->no_truth && !o->truth_pathtrace) {
            res = render_truth(&ms, last_step, &o->settings, &truth_last, &truth_last_ms, err);
        }
        const lu_image *tlast = last_step != first_step ? &truth_last : &truth_first;
        if (res == LU_OK && o->img_dir && !o->no_truth) {
            char p[1400];
            if (mo == MOTION_STILL) {
                snprintf(p, sizeof p, "%s/%s%struth.exr", o->img_dir, o->nscenes > 1 ? stem : "",
                         o->nscenes > 1 ? "-" : "");
                res = lu_image_save(&truth_first, p, NULL, err);
            } else {
                snprintf(p, sizeof p, "%s/%s%struth-%s-first.exr", o->img_dir, o->nscenes > 1 ? stem : "",
                         o->nscenes > 1 ? "-" : "", k_motion_names[mo]);
                res = lu_image_save(&truth_first, p, NULL, err);
                snprintf(p, sizeof p, "%s/%s%struth-%s-last.exr", o->img_dir, o->nscenes > 1 ? stem : "",
                         o->nscenes > 1 ? "-" : "", k_motion_names[mo]);
                if (res == LU_OK) res = lu_image_save(tlast, p, NULL, err);
            }
        }
        bool truth_row_used = false;
        for (int mi = 0; mi < o->nmethods && res == LU_OK; mi++) {
            const lu_method *m = lu_method_find(o->methods[mi]);
            int ncombo = combo_count(o->sweeps, o->nsweeps, m->name);
            bool is_ref = strcmp(m->name, "reference") == 0;
            for (int b = 0; b < o->nbackends && res == LU_OK; b++) {
                if (!(m->backends & o->backends[b])) {
                    fprintf(stderr, "lucent bench: %s has no %s backend, skipped\n", m->name,
                            lu_backend_name(o->backends[b]));
                    continue;
                }
                for (int ct = 0; ct < 2 * ncombo && res == LU_OK; ct++) {
                    int c = ct / 2;
                    bool untracked = ct % 2 == 1;
                    if (!(o->tracking & (1u << (ct % 2)))) continue;
                    if (*nrows >= MAX_ROWS) {
                        res = lu_fail(err, LU_ERR_LIMIT, "more than %d rows", MAX_ROWS);
                        break;
                    }
                    row *r = &rows[*nrows];
                    memset(r, 0, sizeof *r);
                    r->flicker = -1.0;
                    r->scene = path;
                    r->width = scene->camera.width;
                    r->height = scene->camera.height;
                    r->motion = mo;
                    r->ref_ms = truth_first_ms;
                    snprintf(r->truth, sizeof r->truth, "%s", truth_label);
                    r->truth_noise = ti_first.noise;
                    r->truth_spp = ti_first.spp;
                    lu_kvlist settings;
                    res = combo_settings(&o->settings, o->sweeps, o->nsweeps, m->name, c, &settings, r->params,
                                         sizeof r->params, err);
                    if (untracked) {
                        size_t n = strlen(r->params);
                        snprintf(r->params + n, sizeof r->params - n, "%stracking=off", n ? " " : "");
                    }
                    lu_image first = {0}, last = {0};
                    bool reuse = is_ref && o->backends[b] == LU_BACKEND_CPU && !o->ref_path && !o->no_truth &&
                                 !o->truth_pathtrace && !r->params[0] && !truth_row_used;
                    if (res == LU_OK && reuse) {
                        /* The truth of the first state is this row's one frame. */
                        truth_row_used = true;
                        r->method = m->name;
                        r->backend = LU_BACKEND_CPU;
                        r->frames = 1;
                        r->median_ms = r->min_ms = r->max_ms = truth_first_ms;
                        res = image_copy(&truth_first, &first, err);
                        if (res == LU_OK) res = image_copy(&truth_first, &last, err);
                    } else if (res == LU_OK) {
                        fprintf(stderr, "lucent bench: %s: %s on %s, %s%s%s ...\n", path, m->name,
                                lu_backend_name(o->backends[b]), k_motion_names[mo], r->params[0] ? ", " : "",
                                r->params);
                        double step_diff = 0.0;
                        res = bench_one(&ms, m->name, o->backends[b], &settings, is_ref ? 0 : o->warmup,
                                        is_ref ? 1 : frames, untracked, r, &first, &last, &step_diff, err);
                        if (res == LU_OK && truth_step_diff > 0.0 && r->frames == frames && frames > 1)
                            r->flicker = step_diff / truth_step_diff;
                    }
                    lu_kv_free(&settings);
                    /* The reference renders one frame: its last state is the first. */
                    const lu_image *tl = r->frames == frames ? tlast : &truth_first;
                    lu_metrics mf, ml, d;
                    if (res == LU_OK && !o->no_truth) {
                        res = compare_truth(&first, &truth_first, block, &mf, err);
                        if (res == LU_OK) res = compare_truth(&last, tl, block, &ml, err);
                        if (res == LU_OK) {
                            r->err = ml;
                            r->has_err = true;
                            r->rel_l2_first = mf.rel_l2;
                            r->rel_l2_last = ml.rel_l2;
                        }
                    }
                    if (res == LU_OK) res = lu_image_compare(&last, &first, &d, err);
                    if (res == LU_OK) r->last_vs_first = d.rel_l2;
                    if (res == LU_OK) {
                        r->spp_equiv = r->median_ms * 1e-3 * gsps * 1e9 / (double)pixels;
                        r->gsps = gsps;
                        r->load_avg = load_avg_1min();
                    }
                    if (res == LU_OK && o->img_dir) {
                        char p[1400], tail[64] = "";
                        if (ncombo > 1) snprintf(tail, sizeof tail, "-p%d", c);
                        if (untracked) strcat(tail, "-untracked");
                        snprintf(p, sizeof p, "%s/%s%s%s-%s%s%s%s.exr", o->img_dir, o->nscenes > 1 ? stem : "",
                                 o->nscenes > 1 ? "-" : "", m->name, lu_backend_name(o->backends[b]),
                                 mo == MOTION_STILL ? "" : "-", mo == MOTION_STILL ? "" : k_motion_names[mo], tail);
                        res = lu_image_save(&last, p, NULL, err);
                    }
                    lu_image_destroy(&first);
                    lu_image_destroy(&last);
                    if (res == LU_OK) (*nrows)++;
                }
            }
        }
        lu_image_destroy(&truth_first);
        lu_image_destroy(&truth_last);
        lu_result r2 = motion_end(&ms, err);
        if (res == LU_OK) res = r2;
    }
    return res;
}

/* Every rank's rows on rank 0, in scene order (a job of one too, where it
 * changes nothing); the other ranks keep none. */
static lu_result gather_rows(const bench_opts *o, row **rows, int *nrows, lu_error *err) {
    for (int i = 0; i < *nrows; i++) {
        row *r = &(*rows)[i];
        r->seq = i;
        snprintf(r->method_name, sizeof r->method_name, "%s", r->method);
    }
    void *all;
    size_t bytes;
    lu_result res = lu_mpi_gather(*rows, (size_t)*nrows * sizeof(row), &all, &bytes, err);
    if (res != LU_OK) return res;
    *nrows = (int)(bytes / sizeof(row));
    if (lu_mpi_rank() != 0) return LU_OK;
    if (*nrows > MAX_ROWS) {
        free(all);
        return lu_fail(err, LU_ERR_LIMIT, "more than %d rows", MAX_ROWS);
    }
    memcpy(*rows, all, bytes);
    free(all);
    for (int i = 0; i < *nrows; i++) {
        row *r = &(*rows)[i];
        r->scene = o->scenes[r->scene_index];
        r->method = lu_method_find(r->method_name)->name;
    }
    qsort(*rows, (size_t)*nrows, sizeof(row), cmp_rows);
    return LU_OK;
}

/* The error-time plot of the rows (cli/bench_plot.c): one panel per scene
 * and motion, and with the pathtrace truth its own point at its render time
 * and estimated noise when it was rendered in this run. */
static lu_result plot_rows(const bench_opts *o, const row *rows, int n, double gsps, lu_error *err) {
    lu_plot_point *pts = calloc((size_t)2 * n + 1, sizeof *pts);
    char (*panels)[320] = calloc((size_t)n + 1, sizeof *panels);
    if (!pts || !panels) {
        free(pts);
        free(panels);
        return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    }
    int np = 0;
    for (int i = 0; i < n; i++) {
        const row *r = &rows[i];
        snprintf(panels[i], sizeof panels[i], "%s, %s, %dx%d, truth %s", r->scene, k_motion_names[r->motion], r->width,
                 r->height, r->truth);
        bool new_panel = i == 0 || strcmp(panels[i], panels[i - 1]) != 0;
        if (new_panel && o->truth_pathtrace && r->ref_ms > 0.0) {
            lu_plot_point *p = &pts[np++];
            p->panel = panels[i];
            p->method = "truth";
            snprintf(p->label, sizeof p->label, "pathtrace truth, %d spp (noise est.)", r->truth_spp);
            p->ms = r->ref_ms;
            p->rel_l2 = r->truth_noise;
        }
        lu_plot_point *p = &pts[np++];
        p->panel = panels[i];
        p->method = r->method;
        p->gpu = r->backend == LU_BACKEND_GPU;
        /* "afm steps=32 jitter=1": the sweep values without their method's name */
        size_t used = (size_t)snprintf(p->label, sizeof p->label, "%s%s", r->method, p->gpu ? "/gpu" : "");
        size_t mlen = strlen(r->method);
        for (const char *q = r->params; *q && used + 2 < sizeof p->label;) {
            const char *sp = strchr(q, ' ');
            size_t len = sp ? (size_t)(sp - q) : strlen(q);
            if (len > mlen && strncmp(q, r->method, mlen) == 0 && q[mlen] == '.') q += mlen + 1, len -= mlen + 1;
            used += (size_t)snprintf(p->label + used, sizeof p->label - used, " %.*s", (int)len, q);
            if (used >= sizeof p->label) break;
            q += len;
            while (*q == ' ') q++;
        }
        p->ms = r->median_ms;
        p->rel_l2 = r->has_err ? r->err.rel_l2 : -1.0;
    }
    char note[200], truth[64];
    if (gsps > 0.0) snprintf(note, sizeof note, "%d threads, yardstick %.4f G samples/s", lu_thread_count(), gsps);
    else snprintf(note, sizeof note, "%d threads, no yardstick", lu_thread_count());
    snprintf(truth, sizeof truth, "%s", o->ref_path ? "the --reference image" : o->truth_pathtrace ? "pathtrace" : "reference");
    lu_result res = lu_bench_plot(o->plot, pts, np, truth, note, err);
    if (res == LU_OK) fprintf(stderr, "lucent bench: plot written to %s\n", o->plot);
    free(pts);
    free(panels);
    return res;
}

int lu_cmd_bench(int argc, char **argv) {
    bench_opts o;
    memset(&o, 0, sizeof o);
    o.warmup = 1;
    o.tracking = 1u;
    char methods_buf[1024] = "reference", backends_buf[64] = "cpu";
    int rc = parse_args(argc, argv, &o, methods_buf, sizeof methods_buf, backends_buf, sizeof backends_buf);
    row *rows = NULL;
    lu_error err = {0};
    if (rc == LU_EXIT_OK) {
        rows = calloc(MAX_ROWS, sizeof *rows);
        if (!rows) rc = lu_cli_error("bench", &(lu_error){LU_ERR_NOMEM, "out of memory"});
    }
    /* The images are each rank's, and only rank 0 writes. */
    if (rc == LU_EXIT_OK && lu_mpi_size() > 1 && o.img_dir)
        rc = lu_cli_usage("bench", "--save-images: in a job of several ranks only rank 0 writes; run without it");
    /* Every output is checked before the first frame: a sweep can run for
     * hours. Only rank 0 writes the tables: only its file system needs
     * their folders. */
    bool writer = lu_mpi_rank() == 0;
    if (rc == LU_EXIT_OK && o.csv && writer) rc = lu_cli_check_output("bench", o.csv);
    if (rc == LU_EXIT_OK && o.json && writer) rc = lu_cli_check_output("bench", o.json);
    if (rc == LU_EXIT_OK && o.plot && writer) rc = lu_cli_check_output("bench", o.plot);
    if (rc == LU_EXIT_OK && o.plot && writer && !lu_bench_have_gnuplot())
        rc = lu_cli_error("bench", &(lu_error){LU_ERR_UNSUPPORTED, "--plot needs gnuplot, which is not on PATH "
                                                                   "(scripts/setup.sh installs gnuplot-nox)"});
    if (rc == LU_EXIT_OK && o.img_dir) {
        char probe[1100];
        snprintf(probe, sizeof probe, "%s/truth.exr", o.img_dir);
        mkdir(o.img_dir, 0755);
        rc = lu_cli_check_output("bench", probe);
    }
    int nrows = 0, ys_threads = 0;
    double gsps = 0.0, load0 = 0.0;
    if (rc == LU_EXIT_OK) {
        load0 = load_avg_1min();
        gsps = o.no_yardstick ? 0.0 : lu_yardstick_gsps(5, &ys_threads);
        if (gsps <= 0.0 && !o.no_yardstick) rc = lu_cli_error("bench", &(lu_error){LU_ERR_NOMEM, "out of memory for the yardstick"});
    }
    /* In a job, whole scenes go to the ranks from a work queue: all of a
     * scene's rows (its truth, methods, sweeps) are timed on one rank, so
     * they stay ratios within one run. */
    if (rc == LU_EXIT_OK && lu_mpi_queue_open(o.nscenes, &err) != LU_OK) rc = lu_cli_error("bench", &err);
    for (int s; rc == LU_EXIT_OK && (s = lu_mpi_queue_next()) >= 0;) {
        lu_scene scene;
        if (lu_mpi_size() > 1)
            fprintf(stderr, "lucent bench: rank %d of %d: %s\n", lu_mpi_rank(), lu_mpi_size(), o.scenes[s]);
        rc = lu_cli_load_scene("bench", o.scenes[s], o.width, o.height, &scene);
        if (rc != LU_EXIT_OK) break;
        if (o.time_given && lu_scene_set_time(&scene, o.time, &err) != LU_OK) {
            rc = lu_cli_error("bench", &err);
            lu_scene_destroy(&scene);
            break;
        }
        int first = nrows;
        if (bench_scene(&o, o.scenes[s], &scene, gsps, rows, &nrows, &err) != LU_OK) rc = lu_cli_error("bench", &err);
        for (int i = first; i < nrows; i++) rows[i].scene_index = s;
        lu_scene_destroy(&scene);
    }
    lu_mpi_queue_close();
    if (rc == LU_EXIT_OK && gather_rows(&o, &rows, &nrows, &err) != LU_OK) rc = lu_cli_error("bench", &err);
    if (rc == LU_EXIT_OK && lu_mpi_rank() == 0) {
        /* Timed again at the end: the two differ when the machine's load
         * changed during the run, and then so does the meaning of spp_eq. */
        double gsps_end = o.no_yardstick ? 0.0 : lu_yardstick_gsps(5, &ys_threads);
        double l[3] = {0, 0, 0};
        getloadavg(l, 3);
        if (o.nscenes == 1)
            printf("scene %s, %dx%d, %d threads\n", o.scenes[0], nrows ? rows[0].width : 0, nrows ? rows[0].height : 0,
                   lu_thread_count());
        else printf("%d scenes, %d threads\n", o.nscenes, lu_thread_count());
        printf("yardstick %.4f G samples/s (%.4f at the end, %d threads); load average %.2f at the start, "
               "%.2f %.2f %.2f at the end\n",
               gsps, gsps_end, ys_threads, load0, l[0], l[1], l[2]);
        const char *sfx = o.truth_pathtrace ? "_vs_pathtrace" : "";
        print_table(stdout, rows, nrows, o.truth_pathtrace ? "_pt" : "");
        if (o.csv && !write_csv(o.csv, rows, nrows, sfx, &err)) rc = lu_cli_error("bench", &err);
        if (o.json && !write_json(o.json, rows, nrows, gsps, gsps_end, ys_threads, o.scenes[0],
                                  o.ref_path ? "file" : o.truth_pathtrace ? "pathtrace" : "reference", sfx, &err))
            rc = lu_cli_error("bench", &err);
        if (rc == LU_EXIT_OK && o.plot && plot_rows(&o, rows, nrows, gsps, &err) != LU_OK) rc = lu_cli_error("bench", &err);
    }
    free(rows);
    for (int i = 0; i < o.nsweeps; i++) free(o.sweeps[i].text);
    lu_kv_free(&o.settings);
    return rc < 0 ? LU_EXIT_OK : rc;
}
