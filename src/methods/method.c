/* The method registry, parameter resolution and the renderer wrapper that
 * times prepare and render. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "core/memory.h"
#include "methods/frame.h"
#include "methods/methods.h"

static const lu_method *const k_methods[] = {
    &lu_method_reference,
    &lu_method_bssrdf,
    &lu_method_pathtrace,
    &lu_method_raymarch,
    &lu_method_afm,
    &lu_method_gradient,
    &lu_method_rbf,
    &lu_method_pervoxel,
    &lu_method_ddod,
    &lu_method_froxel,
};

const lu_method *const *lu_methods(int *count) {
    *count = (int)(sizeof k_methods / sizeof k_methods[0]);
    return k_methods;
}

const lu_method *lu_method_find(const char *name) {
    int n;
    const lu_method *const *all = lu_methods(&n);
    for (int i = 0; i < n; i++)
        if (strcmp(all[i]->name, name) == 0) return all[i];
    return NULL;
}

static const lu_param_desc *find_param(const lu_method *m, const char *name, int *index) {
    for (int i = 0; i < m->param_count; i++)
        if (strcmp(m->params[i].name, name) == 0) {
            *index = i;
            return &m->params[i];
        }
    return NULL;
}

/* Index of `value` in a "a|b|c" list, or -1. */
static int choice_index(const char *choices, const char *value) {
    int idx = 0;
    size_t len = strlen(value);
    for (const char *p = choices; p && *p; idx++) {
        const char *bar = strchr(p, '|');
        size_t n = bar ? (size_t)(bar - p) : strlen(p);
        if (n == len && strncmp(p, value, n) == 0) return idx;
        p = bar ? bar + 1 : NULL;
    }
    return -1;
}

static lu_result unknown_param(const lu_method *m, const char *key, lu_error *err) {
    char names[512] = "";
    size_t used = 0;
    for (int i = 0; i < m->param_count && used + 1 < sizeof names; i++)
        used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", m->params[i].name);
    return lu_fail(err, LU_ERR_INVALID_ARG, "setting \"%s\": method %s has no such parameter (it has: %s)", key, m->name,
                   names[0] ? names : "none");
}

static const lu_preset *find_preset(const lu_method *m, const char *name) {
    for (int i = 0; i < m->preset_count; i++)
        if (strcmp(m->presets[i].name, name) == 0) return &m->presets[i];
    return NULL;
}

static lu_result unknown_preset(const lu_method *m, const lu_kv *kv, lu_error *err) {
    char names[256] = "";
    size_t used = 0;
    for (int i = 0; i < m->preset_count && used + 1 < sizeof names; i++)
        used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", m->presets[i].name);
    return lu_fail(err, LU_ERR_RANGE, "setting \"%s\": method %s has no preset \"%s\" (it has: %s)", kv->key, m->name,
                   kv->count == 0 ? kv->str : "(a number)", names[0] ? names : "none");
}

lu_result lu_settings_validate(const lu_kvlist *settings, lu_error *err) {
    for (int i = 0; settings && i < settings->count; i++) {
        const char *key = settings->items[i].key;
        const char *dot = strchr(key, '.');
        if (!dot) return lu_fail(err, LU_ERR_INVALID_ARG, "setting \"%s\" must be of the form method.parameter", key);
        char mname[LU_KV_KEY_MAX];
        snprintf(mname, sizeof mname, "%.*s", (int)(dot - key), key);
        const lu_method *m = lu_method_find(mname);
        if (!m) return lu_fail(err, LU_ERR_INVALID_ARG, "setting \"%s\": no method named \"%s\"", key, mname);
        int idx;
        if (strcmp(dot + 1, "preset") == 0) {
            const lu_kv *kv = &settings->items[i];
            if (kv->count != 0 || !find_preset(m, kv->str)) return unknown_preset(m, kv, err);
            continue;
        }
        if (!find_param(m, dot + 1, &idx)) return unknown_param(m, key, err);
    }
    return LU_OK;
}



static lu_result set_value(const lu_method *m, const lu_kv *kv, const char *pname, double *values, lu_error *err) {
    int idx;
    const lu_param_desc *pd = find_param(m, pname, &idx);
    if (!pd) return unknown_param(m, kv->key, err);
    double v;
    if (pd->type == LU_PARAM_CHOICE) {
        int c = kv->count == 0 ? choice_index(pd->choices, kv->str) : -1;
        if (c < 0) return lu_fail(err, LU_ERR_RANGE, "setting \"%s\": expected one of %s", kv->key, pd->choices);
        v = c;
    } else if (pd->type == LU_PARAM_BOOL && kv->count == 0) {
        if (strcmp(kv->str, "true") == 0 || strcmp(kv->str, "on") == 0) v = 1;
        else if (strcmp(kv->str, "false") == 0 || strcmp(kv->str, "off") == 0) v = 0;
        else return lu_fail(err, LU_ERR_RANGE, "setting \"%s\": expected true/false or 1/0", kv->key);
    } else {
        if (kv->count != 1) return lu_fail(err, LU_ERR_RANGE, "setting \"%s\": expected a single number", kv->key);
        v = kv->v[0];
        if (pd->type != LU_PARAM_FLOAT && v != (double)(long long)v)
            return lu_fail(err, LU_ERR_RANGE, "setting \"%s\": expected an integer, got %g", kv->key, v);
        if (!(v >= pd->lo && v <= pd->hi))
            return lu_fail(err, LU_ERR_RANGE, "setting \"%s\" = %g is outside [%g, %g]", kv->key, v, pd->lo, pd->hi);
    }
    values[idx] = v;
    return LU_OK;
}

lu_result lu_method_resolve_params(const lu_method *m, const lu_kvlist *settings, double *values, lu_error *err) {
    for (int i = 0; i < m->param_count; i++) values[i] = m->params[i].def;
    size_t prefix = strlen(m->name);
    /* the preset first, so explicit settings override it */
    for (int i = 0; settings && i < settings->count; i++) {
        const lu_kv *kv = &settings->items[i];
        if (strncmp(kv->key, m->name, prefix) != 0 || kv->key[prefix] != '.' || strcmp(kv->key + prefix + 1, "preset"))
            continue;
        const lu_preset *ps = kv->count == 0 ? find_preset(m, kv->str) : NULL;
        if (!ps) return unknown_preset(m, kv, err);
        lu_kvlist pv = {0};
        lu_result r = LU_OK;
        char text[512];
        snprintf(text, sizeof text, "%s", ps->values);
        for (char *tok = strtok(text, " "); tok && r == LU_OK; tok = strtok(NULL, " ")) {
            char full[LU_KV_KEY_MAX + 256];
            snprintf(full, sizeof full, "%s.%s", m->name, tok);
            r = lu_kv_parse_assignment(&pv, full, err);
        }
        for (int j = 0; j < pv.count && r == LU_OK; j++) r = set_value(m, &pv.items[j], pv.items[j].key + prefix + 1, values, err);
        lu_kv_free(&pv);
        if (r != LU_OK) return r;
    }
    for (int i = 0; settings && i < settings->count; i++) {
        const lu_kv *kv = &settings->items[i];
        if (strncmp(kv->key, m->name, prefix) != 0 || kv->key[prefix] != '.') continue;
        if (strcmp(kv->key + prefix + 1, "preset") == 0) continue;
        lu_result r = set_value(m, kv, kv->key + prefix + 1, values, err);
        if (r != LU_OK) return r;
    }
    return LU_OK;
}

/* Runs the method's prepare into r->state and times it (state NULL on failure). */
/* GPU renderers share one device, used by one thread at a time (backends/gpu.h). */
static void gpu_enter(const lu_renderer *r) {
    if (r->backend != LU_BACKEND_GPU) return;
    lu_gpu_serial_enter();
    lu_gpu_caller_use(r->caller);
}
static void gpu_leave(const lu_renderer *r) {
    if (r->backend != LU_BACKEND_GPU) return;
    lu_gpu_caller_use(NULL);
    lu_gpu_serial_leave();
}

static lu_result prepare_state(lu_renderer *r, const lu_scene *scene, lu_error *err) {
    r->state = NULL;
    double t0 = lu_time_seconds();
    lu_result e = r->method->prepare(scene, r->params, r->backend, &r->state, err);
    r->stats.prepare_ms = 1e3 * (lu_time_seconds() - t0);
    r->stats.prepares++;
    if (e != LU_OK) r->state = NULL;
    return e;
}

static lu_result no_method(const char *method, lu_error *err) {
    int n;
    const lu_method *const *all = lu_methods(&n);
    char names[256] = "";
    size_t used = 0;
    for (int i = 0; i < n && used + 1 < sizeof names; i++)
        used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", all[i]->name);
    return lu_fail(err, LU_ERR_INVALID_ARG, "no method named \"%s\" (available: %s)", method, names);
}

/* The one place a descriptor's defaults are decided. */
lu_result lu_renderer_desc_resolve(const lu_renderer_desc *desc, lu_renderer_desc *out, lu_error *err) {
    static const lu_renderer_desc k_zero;
    lu_renderer_desc d = desc ? *desc : k_zero;
    if (!d.method) d.method = LU_DEFAULT_METHOD;
    const lu_method *m = lu_method_find(d.method);
    if (!m) return no_method(d.method, err);
    d.method = m->name;
    if (d.backend != LU_BACKEND_AUTO && d.backend != LU_BACKEND_CPU && d.backend != LU_BACKEND_GPU)
        return lu_fail(err, LU_ERR_INVALID_ARG, "renderer: backend %d is not an lu_backend", (int)d.backend);
    d.backend = lu_backend_resolve(d.backend, m);
    if (!(m->backends & d.backend))
        return lu_fail(err, LU_ERR_UNSUPPORTED, "method %s does not run on the %s backend", m->name,
                       lu_backend_name(d.backend));
    if (d.progressive.every <= 0) d.progressive.fn = NULL;
    *out = d;
    return LU_OK;
}

lu_result lu_renderer_make(const lu_renderer_desc *desc, const lu_scene *scene, lu_renderer **out, lu_error *err) {
    *out = NULL;
    lu_renderer_desc d;
    lu_result r = lu_renderer_desc_resolve(desc, &d, err);
    if (r != LU_OK) return r;
    /* settings, then the "set" texts over them */
    lu_kvlist merged = {0};
    for (int i = 0; d.settings && i < d.settings->count && r == LU_OK; i++) {
        const lu_kv *kv = &d.settings->items[i];
        r = kv->count ? lu_kv_set_number(&merged, kv->key, kv->v, kv->count, err)
                      : lu_kv_set_string(&merged, kv->key, kv->str, err);
    }
    for (int i = 0; d.set && d.set[i] && r == LU_OK; i++) r = lu_kv_parse_assignment(&merged, d.set[i], err);
    if (r == LU_OK) r = lu_settings_validate(&merged, err);
    if (r != LU_OK) {
        lu_kv_free(&merged);
        return r;
    }
    const lu_method *m = lu_method_find(d.method);
    /* Everything the renderer allocates from here on, itself included, is
     * charged to its account (lu_renderer_stats.memory). */
    lu_mem_account *account = lu_mem_account_create();
    lu_mem_account *outer = lu_mem_account_use(account);
    lu_renderer *rd = account ? lu_calloc(1, sizeof *rd) : NULL;
    if (!rd) {
        lu_mem_account_use(outer);
        lu_mem_account_release(account);
        lu_kv_free(&merged);
        return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    }
    rd->account = account;
    rd->method = m;
    rd->backend = d.backend;
    rd->progressive = d.progressive;
    rd->stats.method = m->name;
    rd->stats.backend = d.backend;
    r = lu_method_resolve_params(m, &merged, rd->params, err);
    lu_kv_free(&merged);
    if (r == LU_OK && d.gl_caller_context && d.backend == LU_BACKEND_GPU)
        r = lu_gpu_caller_context_create(&rd->caller, err);
    if (r == LU_OK) r = lu_frame_stage_create(&rd->stage, err);
    gpu_enter(rd);
    if (r == LU_OK) r = prepare_state(rd, scene, err);
    /* The scene prepare saw: a first frame with other geometry prepares again. */
    if (r == LU_OK) r = lu_frame_stage_end(rd->stage, scene, true, err);
    if (r != LU_OK && rd->state) m->destroy(rd->state);
    gpu_leave(rd);
    if (r != LU_OK) {
        lu_frame_stage_destroy(rd->stage);
        lu_gpu_context_destroy(rd->caller);
        lu_free(rd);
        lu_mem_account_use(outer);
        lu_mem_account_release(account);
        /* AUTO promised a working renderer, not a GPU: a device that cannot
         * be made (or was lost while preparing) leaves the CPU. */
        bool from_auto = !desc || desc->backend == LU_BACKEND_AUTO;
        if (r == LU_ERR_BACKEND && from_auto && d.backend == LU_BACKEND_GPU && (m->backends & LU_BACKEND_CPU)) {
            lu_log_msg(LU_LOG_WARNING, "lucent: %s on the GPU failed (%s); using the CPU\n", m->name, err ? err->message : "");
            lu_renderer_desc cpu = d;
            cpu.backend = LU_BACKEND_CPU;
            return lu_renderer_make(&cpu, scene, out, err);
        }
        return r;
    }
    lu_mem_account_use(outer);
    *out = rd;
    return LU_OK;
}

lu_result lu_renderer_create(const char *method, const lu_scene *scene, const lu_kvlist *settings, lu_backend backend,
                             lu_renderer **out, lu_error *err) {
    *out = NULL;
    if (!method) return lu_fail(err, LU_ERR_INVALID_ARG, "renderer: no method named (NULL)");
    lu_renderer_desc d = {.method = method, .backend = backend, .settings = settings};
    return lu_renderer_make(&d, scene, out, err);
}

typedef struct rows_request {
    lu_rows_fn next;
    void *user;
} rows_request;

static lu_result render_frame(lu_renderer *r, const lu_scene *scene, const rows_request *rows, lu_image *out,
                              lu_error *err);
static lu_result render_charged(lu_renderer *r, const lu_scene *scene, const rows_request *rows, lu_image *out,
                                lu_error *err);

lu_result lu_renderer_render(lu_renderer *r, const lu_scene *scene, lu_image *out, lu_error *err) {
    gpu_enter(r);
    lu_result e = render_frame(r, scene, NULL, out, err);
    gpu_leave(r);
    return e;
}

lu_result lu_renderer_render_texture(lu_renderer *r, const lu_scene *scene, unsigned texture, lu_error *err) {
    if (r->backend == LU_BACKEND_GPU && !r->caller)
        return lu_fail(err, LU_ERR_UNSUPPORTED,
                       "%s: this GPU renderer works in lucent's own context, whose textures the caller's context "
                       "cannot use; make it with gl_caller_context to render into a texture",
                       r->method->name);
    lu_image *img = &r->texture_image;
    if (img->width != scene->camera.width || img->height != scene->camera.height) {
        /* the renderer's own frame: charged to it, unlike a caller's image */
        lu_mem_account *outer = lu_mem_account_use(r->account);
        lu_image_destroy(img);
        memset(img, 0, sizeof *img);
        lu_result e = lu_image_create(img, scene->camera.width, scene->camera.height, err);
        lu_mem_account_use(outer);
        if (e != LU_OK) return e;
    }
    gpu_enter(r);
    lu_gpu_output_target(texture);
    lu_result e = render_frame(r, scene, NULL, img, err);
    bool written = lu_gpu_output_written();
    r->stats.texture_direct = e == LU_OK && written;
    lu_gpu_output_target(0);
    gpu_leave(r);
    /* A method whose frame ends on the CPU (every CPU renderer) uploads it. */
    if (e == LU_OK && !written)
        e = lu_gpu_texture_put_rgb(texture, img->rgb, img->width, img->height, err);
    return e;
}

lu_result lu_renderer_render_rows(lu_renderer *r, const lu_scene *scene, lu_rows_fn next, void *user, lu_image *out,
                                  lu_error *err) {
    if (!next) return lu_fail(err, LU_ERR_INVALID_ARG, "render rows: no source of rows (NULL)");
    /* The GPU drivers dispatch whole images. */
    if (r->backend != LU_BACKEND_CPU)
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: rendering bands of rows needs the CPU backend (this renderer is on %s)",
                       r->method->name, lu_backend_name(r->backend));
    rows_request q = {next, user};
    return render_frame(r, scene, &q, out, err);
}

static lu_result render_frame(lu_renderer *r, const lu_scene *scene, const rows_request *rows, lu_image *out,
                              lu_error *err) {
    const lu_camera *c = &scene->camera;
    if (out->width == 0) {
        lu_result e = lu_image_create(out, c->width, c->height, err);
        if (e != LU_OK) return e;
    } else if (out->width != c->width || out->height != c->height) {
        return lu_fail(err, LU_ERR_INVALID_ARG, "output image is %dx%d but the camera is %dx%d", out->width,
                       out->height, c->width, c->height);
    }
    /* out is the caller's, so the account is used only from here */
    lu_mem_account *outer = lu_mem_account_use(r->account);
    lu_result e = render_charged(r, scene, rows, out, err);
    lu_mem_account_use(outer);
    return e;
}

static lu_result render_charged(lu_renderer *r, const lu_scene *scene, const rows_request *rows, lu_image *out,
                                lu_error *err) {
    double t0 = lu_time_seconds();
    lu_frame frame;
    lu_result b = lu_frame_stage_begin(r->stage, scene, &frame, err);
    r->stats.frame_update_ms = 1e3 * (lu_time_seconds() - t0);
    if (b != LU_OK) return b;
    if ((frame.changed & (LU_CHANGE_GEOMETRY | r->method->prepare_deps)) || !r->state) {
        /* Objects are baked to world space and the methods' accelerations,
         * profiles and boundary tables are built at prepare: new geometry is
         * a new scene for them, so prepare again. */
        r->method->destroy(r->state);
        lu_result e = prepare_state(r, scene, err);
        if (e != LU_OK) {
            r->frames = 0;
            r->stats.frame_ms = 1e3 * (lu_time_seconds() - t0);
            return e;
        }
        lu_frame_rebuilt(&frame, "renderer.prepare");
        r->frames = 0;
    }
    if (r->frames == 0) {   /* nothing has been rendered from this state yet */
        frame.changed = LU_CHANGE_ALL;
        frame.lights_changed = ~0ull;
    }
    r->stats.changed = frame.changed;
    double rows_seconds = 0.0;
    frame.rows = rows ? rows->next : NULL;
    frame.rows_user = rows ? rows->user : NULL;
    frame.rows_seconds = &rows_seconds;
    double t1 = lu_time_seconds();
    lu_result e = r->progressive.fn && r->method->render_progressive && !rows
                      ? r->method->render_progressive(r->state, &frame, out, &r->progressive, err)
                      : r->method->render(r->state, &frame, out, err);
    double t2 = lu_time_seconds();
    lu_result s = lu_frame_stage_end(r->stage, scene, e == LU_OK, err);
    r->frames = e == LU_OK ? r->frames + 1 : 0;
    if (e == LU_OK) r->stats.frames++;
    r->stats.render_ms = 1e3 * (t2 - t1);
    r->stats.rows_ms = 1e3 * rows_seconds;
    r->stats.frame_update_ms += 1e3 * (lu_time_seconds() - t2);
    r->stats.frame_ms = 1e3 * (lu_time_seconds() - t0);
    return e != LU_OK ? e : s;
}

lu_result lu_renderer_get_stats(const lu_renderer *r, lu_renderer_stats *out, lu_error *err) {
    if (!r || !out) return lu_fail(err, LU_ERR_INVALID_ARG, "renderer stats: NULL %s", r ? "out" : "renderer");
    *out = r->stats;
    out->products = lu_frame_stage_stats(r->stage)->count;
    lu_mem_account_read(r->account, &out->memory);
    return LU_OK;
}

lu_result lu_renderer_get_method(const lu_renderer *r, const lu_method **method, lu_error *err) {
    if (!r || !method) return lu_fail(err, LU_ERR_INVALID_ARG, "renderer method: NULL %s", r ? "out" : "renderer");
    *method = r->method;
    return LU_OK;
}

lu_result lu_renderer_get_params(const lu_renderer *r, double *values, int cap, int *count, lu_error *err) {
    if (!r || !count) return lu_fail(err, LU_ERR_INVALID_ARG, "renderer params: NULL %s", r ? "count" : "renderer");
    *count = r->method->param_count;
    for (int i = 0; values && i < r->method->param_count && i < cap; i++) values[i] = r->params[i];
    return LU_OK;
}

bool lu_renderer_set_progressive(lu_renderer *r, lu_progressive_fn fn, void *user, int every) {
    r->progressive.fn = every > 0 ? fn : NULL;
    r->progressive.user = user;
    r->progressive.every = every;
    return r->method->render_progressive != NULL;
}

void lu_renderer_destroy(lu_renderer *r) {
    if (!r) return;
    lu_mem_account *account = r->account;
    lu_mem_account *outer = lu_mem_account_use(account);
    gpu_enter(r);
    r->method->destroy(r->state);
    gpu_leave(r);
    lu_frame_stage_destroy(r->stage);
    lu_gpu_context_destroy(r->caller);
    lu_image_destroy(&r->texture_image);
    lu_free(r);
    lu_mem_account_use(outer);
    lu_mem_account_release(account);
}

void lu_renderer_invalidate(lu_renderer *r, unsigned what) { lu_frame_stage_invalidate(r->stage, what); }

uint64_t lu_renderer_rebuilds(const lu_renderer *r, const char *product) {
    const lu_frame_stats *st = lu_frame_stage_stats(r->stage);
    for (int i = 0; i < st->count; i++)
        if (strcmp(st->product[i].name, product) == 0) return st->product[i].rebuilds;
    return 0;
}

int lu_renderer_products(const lu_renderer *r, const char **names, uint64_t *counts, int max) {
    const lu_frame_stats *st = lu_frame_stage_stats(r->stage);
    for (int i = 0; i < st->count && i < max; i++) {
        if (names) names[i] = st->product[i].name;
        if (counts) counts[i] = st->product[i].rebuilds;
    }
    return st->count;
}
