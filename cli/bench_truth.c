/* bench's multiple-scattering truth (`--truth pathtrace`): pathtrace rendered
 * until its own noise is small enough to judge the other methods by, and
 * cached so that a bench run pays for it once (docs/bench.md "The pathtrace
 * truth"). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cjson/cJSON.h>

#include "bench_truth.h"
#include "core/fnv.h"

/* Bumped whenever what a cached truth means changes without a lucent
 * version change (the rule, the file layout). */
#define TRUTH_FORMAT 2

/* ---- the key ------------------------------------------------------------- */


static void fnv_str(lu_fnv *f, const char *s) { lu_fnv_bytes(f, s, strlen(s) + 1); }
static void fnv_int(lu_fnv *f, int64_t v) { lu_fnv_bytes(f, &v, sizeof v); }

/* A file's bytes, streamed. */
static lu_result fnv_file(lu_fnv *f, const char *path, lu_error *err) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return lu_fail(err, LU_ERR_IO, "%s: %s", path, strerror(errno));
    static unsigned char buf[1 << 16];
    size_t n;
    uint64_t total = 0;
    while ((n = fread(buf, 1, sizeof buf, fp)) > 0) {
        lu_fnv_bytes(f, buf, n);
        total += n;
    }
    bool bad = ferror(fp);
    fclose(fp);
    if (bad) return lu_fail(err, LU_ERR_IO, "%s: read failed", path);
    fnv_int(f, (int64_t)total);
    return LU_OK;
}

/* Every string of the scene's JSON that names a regular file (relative to
 * the scene's folder or absolute) is a data file the truth depends on:
 * grids, meshes, environment maps, whatever key names them, so a new kind
 * of file needs nothing here. */
static lu_result fnv_json_files(lu_fnv *f, const cJSON *node, const char *scene_path, int depth, lu_error *err) {
    if (depth > 64) return LU_OK;
    if (cJSON_IsString(node) && node->valuestring && *node->valuestring && strlen(node->valuestring) < 1000) {
        char path[1100];
        lu_path_resolve(scene_path, node->valuestring, path, sizeof path);
        struct stat st;
        if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) {
            fnv_str(f, node->valuestring);
            return fnv_file(f, path, err);
        }
        return LU_OK;
    }
    lu_result r = LU_OK;
    for (const cJSON *c = node->child; c && r == LU_OK; c = c->next) r = fnv_json_files(f, c, scene_path, depth + 1, err);
    return r;
}

static void fnv_grid(lu_fnv *f, const lu_grid *g) {
    lu_fnv_bytes(f, &g->nx, 3 * sizeof(int));
    if (g->data) lu_fnv_bytes(f, g->data, (size_t)g->nx * g->ny * g->nz * sizeof(float));
    else if (g->tree) {
        lu_fnv_bytes(f, g->tree, (size_t)g->tree_bytes);
        lu_fnv_bytes(f, g->tree_lo, sizeof g->tree_lo);
    }
}

/* The key: the lucent version and this file's rule, the scene file's bytes,
 * the bytes of every data file it names, the media's values in this state
 * (which covers sequences, time and the medium motion's edits), the image
 * size, the motion state, and pathtrace's resolved parameters. */
static lu_result truth_key(const lu_scene *scene, const char *scene_path, const double *params, int nparams,
                           const char *state, int block_wanted, int max_spp, uint64_t *key, lu_error *err) {
    lu_fnv f = LU_FNV_INIT;
    fnv_str(&f, LU_VERSION_STRING);
    fnv_int(&f, TRUTH_FORMAT);
    lu_fnv_bytes(&f, &(double){LU_TRUTH_NOISE_TARGET}, sizeof(double));
    fnv_int(&f, LU_TRUTH_BLOCK);
    fnv_int(&f, max_spp);
    fnv_int(&f, block_wanted);
    char *text = NULL;
    size_t size = 0;
    lu_result r = lu_read_file(scene_path, (size_t)64 << 20, &text, &size, err);
    if (r != LU_OK) return r;
    lu_fnv_bytes(&f, text, size);
    cJSON *root = cJSON_ParseWithLength(text, size);
    lu_free(text);
    if (root) {
        r = fnv_json_files(&f, root, scene_path, 0, err);
        cJSON_Delete(root);
        if (r != LU_OK) return r;
    }
    for (int i = 0; i < scene->medium_count; i++) {
        const lu_medium *m = &scene->media[i];
        fnv_int(&f, m->kind);
        if (m->kind == LU_DENSITY_GRID) fnv_grid(&f, &m->grid);
        if (m->emission != LU_EMISSION_NONE) fnv_grid(&f, &m->emission_grid);
    }
    fnv_int(&f, scene->camera.width);
    fnv_int(&f, scene->camera.height);
    fnv_str(&f, state);
    fnv_int(&f, nparams);
    lu_fnv_bytes(&f, params, (size_t)nparams * sizeof *params);
    *key = f.h;
    return LU_OK;
}

/* ---- the cache file ------------------------------------------------------ */

static const char k_magic[8] = {'L', 'U', 'T', 'R', 'U', 'T', 'H', '\n'};

typedef struct truth_header {
    char magic[8];
    uint32_t format, block;
    uint64_t key;
    int32_t width, height, spp, pad;
    double noise, ms;
    uint64_t checksum;      /* FNV-1a of the pixels */
} truth_header;

static uint64_t pixels_checksum(const lu_image *img) {
    lu_fnv f = LU_FNV_INIT;
    lu_fnv_bytes(&f, img->rgb, (size_t)img->width * img->height * 3 * sizeof(float));
    return f.h;
}

/* Reads a cached truth; *why gets the reason when it is not usable. */
static bool cache_load(const char *path, uint64_t key, int w, int h, lu_image *out, lu_truth_info *info,
                       char *why, size_t why_size) {
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        snprintf(why, why_size, "%s", strerror(errno));
        return false;
    }
    truth_header hd;
    struct stat st;
    bool ok = false;
    uint64_t want = sizeof hd + (uint64_t)w * h * 3 * sizeof(float);
    lu_error e = {0};
    if (fstat(fileno(fp), &st) != 0 || fread(&hd, sizeof hd, 1, fp) != 1) snprintf(why, why_size, "truncated header");
    else if (memcmp(hd.magic, k_magic, sizeof k_magic) != 0) snprintf(why, why_size, "not a truth cache file");
    else if (hd.format != TRUTH_FORMAT) snprintf(why, why_size, "format %u, this build reads %d", hd.format, TRUTH_FORMAT);
    else if (hd.key != key) snprintf(why, why_size, "made for other inputs (key mismatch)");
    else if (hd.width != w || hd.height != h || (hd.block != 1 && hd.block != LU_TRUTH_BLOCK) || hd.spp < 1 ||
             !isfinite(hd.noise) || hd.noise < 0)
        snprintf(why, why_size, "inconsistent header");
    else if ((uint64_t)st.st_size != want)
        snprintf(why, why_size, "%s: %llu bytes, expected %llu", (uint64_t)st.st_size < want ? "truncated" : "trailing bytes",
                 (unsigned long long)st.st_size, (unsigned long long)want);
    else if (lu_image_create(out, w, h, &e) != LU_OK) snprintf(why, why_size, "%.100s", e.message);
    else if (fread(out->rgb, sizeof(float), (size_t)w * h * 3, fp) != (size_t)w * h * 3)
        snprintf(why, why_size, "read failed");
    else if (pixels_checksum(out) != hd.checksum) snprintf(why, why_size, "checksum mismatch (corrupt)");
    else ok = true;
    fclose(fp);
    if (!ok) {
        lu_image_destroy(out);
        return false;
    }
    info->block = (int)hd.block;
    info->spp = hd.spp;
    info->noise = hd.noise;
    info->ms = 0.0;
    info->from_cache = true;
    return true;
}

static lu_result cache_save(const char *path, uint64_t key, const lu_image *img, const lu_truth_info *info,
                            lu_error *err) {
    truth_header hd;
    memset(&hd, 0, sizeof hd);
    memcpy(hd.magic, k_magic, sizeof k_magic);
    hd.format = TRUTH_FORMAT;
    hd.block = (uint32_t)info->block;
    hd.key = key;
    hd.width = img->width;
    hd.height = img->height;
    hd.spp = info->spp;
    hd.noise = info->noise;
    hd.ms = info->ms;
    hd.checksum = pixels_checksum(img);
    lu_atomic_file af;
    lu_result r = lu_atomic_open(&af, path, err);
    if (r != LU_OK) return r;
    size_t n = (size_t)img->width * img->height * 3;
    if (fwrite(&hd, sizeof hd, 1, af.fp) != 1 || fwrite(img->rgb, sizeof(float), n, af.fp) != n) {
        lu_atomic_abort(&af);
        return lu_fail(err, LU_ERR_IO, "%s: write failed: %s", path, strerror(errno));
    }
    return lu_atomic_commit(&af, err);
}

/* ---- rendering ----------------------------------------------------------- */

/* ||A - B|| / (2 ||(A + B) / 2||) over all channels: for two independent
 * estimates of one image with equal variance sigma^2 per value,
 * E||A - B||^2 = 2 n sigma^2, and their mean has variance sigma^2 / 2, so
 * its error norm is about ||A - B|| / 2. */
static double mean_noise(const lu_image *a, const lu_image *b) {
    size_t n = (size_t)a->width * a->height * 3;
    double d2 = 0.0, m2 = 0.0;
    for (size_t i = 0; i < n; i++) {
        double d = (double)a->rgb[i] - b->rgb[i], m = 0.5 * ((double)a->rgb[i] + b->rgb[i]);
        d2 += d * d;
        m2 += m * m;
    }
    return m2 > 0.0 ? 0.5 * sqrt(d2 / m2) : (d2 > 0.0 ? INFINITY : 0.0);
}

static lu_result block_noise(const lu_image *a, const lu_image *b, double *out, lu_error *err) {
    lu_image ba = {0}, bb = {0};
    lu_result r = lu_image_block_average(a, LU_TRUTH_BLOCK, &ba, err);
    if (r == LU_OK) r = lu_image_block_average(b, LU_TRUTH_BLOCK, &bb, err);
    if (r == LU_OK) *out = mean_noise(&ba, &bb);
    lu_image_destroy(&ba);
    lu_image_destroy(&bb);
    return r;
}

/* Renders spp samples with seed into img and adds them, weighted, to acc
 * (which holds acc_spp samples so far). */
static lu_result render_add(const lu_scene *scene, const lu_kvlist *base, int seed, int spp, lu_image *acc,
                            int acc_spp, double *ms, lu_error *err) {
    lu_kvlist kv = {0};
    lu_result r = LU_OK;
    for (int i = 0; i < base->count && r == LU_OK; i++) {
        const lu_kv *e = &base->items[i];
        r = e->count ? lu_kv_set_number(&kv, e->key, e->v, e->count, err) : lu_kv_set_string(&kv, e->key, e->str, err);
    }
    if (r == LU_OK) r = lu_kv_set_number(&kv, "pathtrace.spp", &(double){spp}, 1, err);
    if (r == LU_OK) r = lu_kv_set_number(&kv, "pathtrace.seed", &(double){seed}, 1, err);
    lu_renderer *rd = NULL;
    lu_image img = {0};
    if (r == LU_OK) r = lu_renderer_create("pathtrace", scene, &kv, LU_BACKEND_CPU, &rd, err);
    if (r == LU_OK) r = lu_renderer_render(rd, scene, &img, err);
    if (r == LU_OK) {
        lu_renderer_stats st = {0};
        lu_renderer_get_stats(rd, &st, NULL);
        *ms += st.frame_ms;
    }
    if (r == LU_OK && acc_spp == 0) {
        *acc = img;
        img = (lu_image){0};
    } else if (r == LU_OK) {
        size_t n = (size_t)img.width * img.height * 3;
        double wa = (double)acc_spp / (acc_spp + spp), wb = 1.0 - wa;
        for (size_t i = 0; i < n; i++) acc->rgb[i] = (float)(wa * acc->rgb[i] + wb * img.rgb[i]);
    }
    lu_image_destroy(&img);
    lu_renderer_destroy(rd);
    lu_kv_free(&kv);
    return r;
}

/* Seeds of half h (0 or 1), pass i: disjoint for the two halves and all
 * passes, and away from the seed itself, so that a pathtrace row at the same
 * settings is judged by samples it does not share with the truth. */
static int seed_of(int base, int i, int h) {
    return (int)(((long long)base + (1LL << 30) + 2LL * i + h) % 2147483647LL);
}

static lu_result render_truth(const lu_scene *scene, const lu_kvlist *settings, int spp0, int base_seed,
                              int block_wanted, int max_spp, lu_image *out, lu_truth_info *info, lu_error *err) {
    const int w = scene->camera.width, h = scene->camera.height;
    /* A noise estimate from a few blocks is itself too noisy to trust. */
    const bool can_block = (w / LU_TRUTH_BLOCK) * (h / LU_TRUTH_BLOCK) >= LU_TRUTH_MIN_BLOCKS;
    if (block_wanted == LU_TRUTH_BLOCK && !can_block) block_wanted = 1;
    lu_image a = {0}, b = {0};
    int half = 0;   /* samples per pixel in each of a and b */
    double ms = 0.0, n_pix = INFINITY, n_blk = INFINITY;
    lu_result r = LU_OK;
    int block = 0;
    for (int pass = 0; r == LU_OK && !block; pass++) {
        int add = half ? half : spp0;
        r = render_add(scene, settings, seed_of(base_seed, pass, 0), add, &a, half, &ms, err);
        if (r == LU_OK) r = render_add(scene, settings, seed_of(base_seed, pass, 1), add, &b, half, &ms, err);
        if (r != LU_OK) break;
        half += add;
        /* A target counts as met when this pass's estimate meets it and the
         * previous one, halved in variance, did too: one estimate can dip
         * far below the noise where rare bright paths dominate it. */
        const double prev_ok = LU_TRUTH_NOISE_TARGET * sqrt(2.0);
        bool pix_prev = n_pix <= prev_ok, blk_prev = n_blk <= prev_ok;
        n_pix = mean_noise(&a, &b);
        if (can_block) r = block_noise(&a, &b, &n_blk, err);
        if (r != LU_OK) break;
        bool pix_ok = pix_prev && n_pix <= LU_TRUTH_NOISE_TARGET, blk_ok = blk_prev && n_blk <= LU_TRUTH_NOISE_TARGET;
        int total = 2 * half;
        /* what per-pixel would take: noise falls as 1 / sqrt(spp) */
        double need = (double)total * (n_pix / LU_TRUTH_NOISE_TARGET) * (n_pix / LU_TRUTH_NOISE_TARGET);
        fprintf(stderr, "lucent bench: pathtrace truth, %d spp: noise %.2f%% per pixel%s", total, 100.0 * n_pix,
                can_block ? "" : "\n");
        if (can_block) fprintf(stderr, ", %.2f%% in %dx%d blocks\n", 100.0 * n_blk, LU_TRUTH_BLOCK, LU_TRUTH_BLOCK);
        if (block_wanted != LU_TRUTH_BLOCK && pix_ok) block = 1;
        else if (block_wanted != 1 && can_block && blk_ok && (block_wanted == LU_TRUTH_BLOCK || need > max_spp))
            block = LU_TRUTH_BLOCK;
        else if (2 * total > max_spp) {
            block = block_wanted ? block_wanted : can_block ? LU_TRUTH_BLOCK : 1;
            fprintf(stderr, "lucent bench: warning: the pathtrace truth stops at %d spp (--truth-max-spp) before "
                            "meeting the %.0f%% target: noise %.2f%% %s\n",
                    total, 100.0 * LU_TRUTH_NOISE_TARGET, 100.0 * (block == 1 ? n_pix : n_blk),
                    block == 1 ? "per pixel" : "in blocks");
        }
    }
    if (r == LU_OK) {
        size_t n = (size_t)w * h * 3;
        for (size_t i = 0; i < n; i++) a.rgb[i] = 0.5f * (a.rgb[i] + b.rgb[i]);
        *out = a;
        a = (lu_image){0};
        info->block = block;
        info->spp = 2 * half;
        info->noise = block == 1 ? n_pix : n_blk;
        info->ms = ms;
        info->from_cache = false;
    }
    lu_image_destroy(&a);
    lu_image_destroy(&b);
    return r;
}

static void make_label(lu_truth_info *info) {
    if (info->block > 1)
        snprintf(info->label, sizeof info->label, "pathtrace/%dx%d(%.1f%%)", info->block, info->block,
                 100.0 * info->noise);
    else snprintf(info->label, sizeof info->label, "pathtrace(%.1f%%)", 100.0 * info->noise);
}

static bool g_no_cache_noted;

static lu_result truth_cached(lu_scene *scene, const char *scene_path, const lu_kvlist *settings,
                              const char *state, int block_wanted, int max_spp, lu_image *out, lu_truth_info *info,
                              lu_error *err);

lu_result lu_bench_pathtrace_truth(lu_scene *scene, const char *scene_path, const lu_kvlist *settings,
                                   const char *state, int block_wanted, int max_spp, lu_image *out,
                                   lu_truth_info *info, lu_error *err) {
    /* The truth samples pixel centres, as reference (spp 1) and the other
     * methods do: pathtrace's default box filter differs from a centre
     * sample by more than the multiple scattering at a small image size
     * (docs/bench.md). An explicit pathtrace.jitter wins. */
    lu_kvlist kv = {0};
    lu_result r = LU_OK;
    for (int i = 0; i < settings->count && r == LU_OK; i++) {
        const lu_kv *e = &settings->items[i];
        r = e->count ? lu_kv_set_number(&kv, e->key, e->v, e->count, err) : lu_kv_set_string(&kv, e->key, e->str, err);
    }
    if (r == LU_OK && !lu_kv_find(&kv, "pathtrace.jitter")) r = lu_kv_set_number(&kv, "pathtrace.jitter", &(double){0}, 1, err);
    if (r == LU_OK) r = truth_cached(scene, scene_path, &kv, state, block_wanted, max_spp, out, info, err);
    lu_kv_free(&kv);
    return r;
}

static lu_result truth_cached(lu_scene *scene, const char *scene_path, const lu_kvlist *settings,
                              const char *state, int block_wanted, int max_spp, lu_image *out, lu_truth_info *info,
                              lu_error *err) {
    memset(info, 0, sizeof *info);
    const lu_method *m = lu_method_find("pathtrace");
    if (!m) return lu_fail(err, LU_ERR_UNSUPPORTED, "this build has no pathtrace method");
    double params[LU_MAX_PARAMS];
    lu_result r = lu_method_resolve_params(m, settings, params, err);
    if (r != LU_OK) return r;
    int spp0 = 16, seed = 1;
    for (int i = 0; i < m->param_count; i++) {
        if (strcmp(m->params[i].name, "spp") == 0) spp0 = (int)params[i];
        if (strcmp(m->params[i].name, "seed") == 0) seed = (int)params[i];
    }
    if (spp0 > max_spp / 2) spp0 = max_spp / 2 > 0 ? max_spp / 2 : 1;
    uint64_t key = 0;
    char path[1200] = "", name[64] = "";
    bool cached = lu_cache_enabled();
    if (cached) {
        r = truth_key(scene, scene_path, params, m->param_count, state, block_wanted, max_spp, &key, err);
        snprintf(name, sizeof name, "truth-pathtrace-%016llx.bin", (unsigned long long)key);
        if (r == LU_OK) r = lu_cache_path(name, false, path, sizeof path, err);
        if (r != LU_OK) return r;
        struct stat st;
        char why[160];
        if (stat(path, &st) == 0) {
            if (cache_load(path, key, scene->camera.width, scene->camera.height, out, info, why, sizeof why)) {
                make_label(info);
                fprintf(stderr, "lucent bench: truth from cache %s (%s, %d spp)\n", path, info->label, info->spp);
                return LU_OK;
            }
            fprintf(stderr, "lucent bench: truth cache %s: %s; rendering it again\n", path, why);
        }
    } else if (!g_no_cache_noted) {
        g_no_cache_noted = true;
        fprintf(stderr, "lucent bench: no cache folder (LUCENT_CACHE_DIR, XDG_CACHE_HOME or HOME): the pathtrace "
                        "truth is rendered every run\n");
    }
    r = render_truth(scene, settings, spp0, seed, block_wanted, max_spp, out, info, err);
    if (r != LU_OK) return r;
    make_label(info);
    if (cached) {
        r = lu_cache_path(name, true, path, sizeof path, err);
        if (r == LU_OK) r = cache_save(path, key, out, info, err);
        if (r != LU_OK) {
            lu_image_destroy(out);
            return r;
        }
        fprintf(stderr, "lucent bench: truth written to cache %s (%s, %d spp)\n", path, info->label, info->spp);
    }
    return LU_OK;
}
