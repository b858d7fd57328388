/* Scene JSON -> lu_scene (docs/architecture.md §7, docs/scene-format.md). Strict: an unknown key, a wrong type,
 * a duplicate key or an out-of-range number is an error naming the JSON path,
 * e.g. "scenes/smoke.json: $.lights[1].intensity: expected 3 numbers". The
 * file's values go through the scene builder (scene_builder.c), which checks
 * and assembles every scene, loaded or built. Over 800 lines: one parser per
 * key of docs/scene-format.md, sharing the JSON-path error helpers. */
#include <lucent/lucent.h>

#include <cjson/cJSON.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene/scene_time.h"
#include "volume/grid_internal.h"

#define LU_SCENE_MAX_BYTES (16u * 1024u * 1024u)
#define LU_SCENE_MAX_ITEMS 4096

typedef struct parse_ctx {
    const char *file;   /* for messages and relative paths */
    lu_error *err;
    lu_scene clock;     /* only time and fps: the scene's, for the grids that follow time */
    lu_grid_anim **anims;   /* 2 per medium of "media" (density, emission), handed to the scene at the end */
    int anim_count, anim_cap;
} parse_ctx;

/* JSON paths are built on the stack as the parser descends. */
typedef struct jpath {
    char s[256];
} jpath;

/* Over-long paths keep their start and end in "..." (messages stay readable). */
static void jp_mark_truncated(jpath *r) { memcpy(r->s + sizeof r->s - 4, "...", 4); }

static jpath jp_key(const jpath *p, const char *key) {
    jpath r;
    if (snprintf(r.s, sizeof r.s, "%s.%s", p->s, key) >= (int)sizeof r.s) jp_mark_truncated(&r);
    return r;
}

static jpath jp_index(const jpath *p, int i) {
    jpath r;
    if (snprintf(r.s, sizeof r.s, "%s[%d]", p->s, i) >= (int)sizeof r.s) jp_mark_truncated(&r);
    return r;
}

static lu_result scene_fail(parse_ctx *c, const jpath *p, lu_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

static lu_result scene_fail(parse_ctx *c, const jpath *p, lu_result code, const char *fmt, ...) {
    char reason[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    return lu_fail(c->err, code, "%s: %s: %s", c->file, p->s, reason);
}

/* Rejects keys outside `known` and duplicated keys (cJSON keeps both). */
static lu_result check_object(parse_ctx *c, const cJSON *obj, const jpath *p, const char *const *known) {
    if (!cJSON_IsObject(obj)) return scene_fail(c, p, LU_ERR_SCENE, "expected an object");
    for (const cJSON *it = obj->child; it; it = it->next) {
        bool ok = false;
        for (const char *const *k = known; *k && !ok; k++) ok = strcmp(*k, it->string) == 0;
        if (!ok) {
            char names[400] = "";
            size_t used = 0;
            for (const char *const *k = known; *k && used + 1 < sizeof names; k++)
                used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", used ? ", " : "", *k);
            jpath kp = jp_key(p, it->string);
            return scene_fail(c, &kp, LU_ERR_SCENE, "unknown key (allowed here: %s)", names);
        }
        for (const cJSON *jt = it->next; jt; jt = jt->next)
            if (strcmp(it->string, jt->string) == 0) {
                jpath kp = jp_key(p, it->string);
                return scene_fail(c, &kp, LU_ERR_SCENE, "duplicate key");
            }
    }
    return LU_OK;
}

static lu_result get_number(parse_ctx *c, const cJSON *obj, const jpath *p, const char *key, double def, double lo,
                            double hi, bool required, double *out) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    jpath kp = jp_key(p, key);
    if (!v) {
        if (required) return scene_fail(c, &kp, LU_ERR_SCENE, "missing required number");
        *out = def;
        return LU_OK;
    }
    if (!cJSON_IsNumber(v)) return scene_fail(c, &kp, LU_ERR_SCENE, "expected a number");
    if (!isfinite(v->valuedouble)) return scene_fail(c, &kp, LU_ERR_NONFINITE, "number is not finite");
    if (!(v->valuedouble >= lo && v->valuedouble <= hi))
        return scene_fail(c, &kp, LU_ERR_RANGE, "%g is outside [%g, %g]", v->valuedouble, lo, hi);
    *out = v->valuedouble;
    return LU_OK;
}

static lu_result get_float(parse_ctx *c, const cJSON *obj, const jpath *p, const char *key, double def, double lo,
                           double hi, bool required, float *out) {
    double d;
    lu_result r = get_number(c, obj, p, key, def, lo, hi, required, &d);
    if (r == LU_OK) *out = (float)d;
    return r;
}

static lu_result get_int(parse_ctx *c, const cJSON *obj, const jpath *p, const char *key, int def, int lo, int hi,
                         bool required, int *out) {
    double d;
    lu_result r = get_number(c, obj, p, key, def, lo, hi, required, &d);
    if (r != LU_OK) return r;
    if (d != (double)(int)d) {
        jpath kp = jp_key(p, key);
        return scene_fail(c, &kp, LU_ERR_SCENE, "expected an integer, got %g", d);
    }
    *out = (int)d;
    return LU_OK;
}

/* A vec3: [x, y, z]; `allow_scalar` also accepts one number for all three. */
static lu_result get_vec3(parse_ctx *c, const cJSON *obj, const jpath *p, const char *key, lu_vec3 def, double lo,
                          double hi, bool required, bool allow_scalar, lu_vec3 *out) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    jpath kp = jp_key(p, key);
    if (!v) {
        if (required) return scene_fail(c, &kp, LU_ERR_SCENE, "missing required [x, y, z]");
        *out = def;
        return LU_OK;
    }
    double d[3];
    if (allow_scalar && cJSON_IsNumber(v)) {
        d[0] = d[1] = d[2] = v->valuedouble;
    } else {
        if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 3)
            return scene_fail(c, &kp, LU_ERR_SCENE, allow_scalar ? "expected a number or 3 numbers" : "expected 3 numbers");
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(v, i);
            if (!cJSON_IsNumber(e)) return scene_fail(c, &kp, LU_ERR_SCENE, "element %d is not a number", i);
            d[i] = e->valuedouble;
        }
    }
    for (int i = 0; i < 3; i++) {
        if (!isfinite(d[i])) return scene_fail(c, &kp, LU_ERR_NONFINITE, "element %d is not finite", i);
        if (!(d[i] >= lo && d[i] <= hi))
            return scene_fail(c, &kp, LU_ERR_RANGE, "element %d = %g is outside [%g, %g]", i, d[i], lo, hi);
    }
    *out = lu_v3((float)d[0], (float)d[1], (float)d[2]);
    return LU_OK;
}

static lu_result get_string(parse_ctx *c, const cJSON *obj, const jpath *p, const char *key, bool required,
                            const char **out) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    jpath kp = jp_key(p, key);
    *out = NULL;
    if (!v) return required ? scene_fail(c, &kp, LU_ERR_SCENE, "missing required string") : LU_OK;
    if (!cJSON_IsString(v)) return scene_fail(c, &kp, LU_ERR_SCENE, "expected a string");
    *out = v->valuestring;
    return LU_OK;
}

#define TRY(x)                          \
    do {                                \
        lu_result try_r_ = (x);         \
        if (try_r_ != LU_OK) return try_r_; \
    } while (0)

/* Prefixes a loader's own message with the JSON path that named the file. */
static lu_result wrap_loader(parse_ctx *c, const jpath *p, lu_result r) {
    if (r == LU_OK) return r;
    char inner[sizeof c->err->message];
    snprintf(inner, sizeof inner, "%s", c->err->message);
    return lu_fail(c->err, r, "%s: %s: %s", c->file, p->s, inner);
}

/* Turns the parameters of a {"procedural": NAME, ...} object into settings. */
static lu_result params_from_object(parse_ctx *c, const cJSON *obj, const jpath *p, const char *skip_key,
                                    lu_kvlist *out) {
    for (const cJSON *it = obj->child; it; it = it->next) {
        if (strcmp(it->string, skip_key) == 0) continue;
        jpath kp = jp_key(p, it->string);
        double v[4];
        int n = 0;
        if (cJSON_IsNumber(it)) {
            v[n++] = it->valuedouble;
        } else if (cJSON_IsArray(it) && cJSON_GetArraySize(it) >= 1 && cJSON_GetArraySize(it) <= 4) {
            for (const cJSON *e = it->child; e; e = e->next) {
                if (!cJSON_IsNumber(e)) return scene_fail(c, &kp, LU_ERR_SCENE, "array elements must be numbers");
                v[n++] = e->valuedouble;
            }
        } else if (cJSON_IsString(it)) {
            lu_error kerr;
            if (lu_kv_set_string(out, it->string, it->valuestring, &kerr) != LU_OK)
                return scene_fail(c, &kp, kerr.code, "%s", kerr.message);
            continue;
        } else {
            return scene_fail(c, &kp, LU_ERR_SCENE, "expected a number, 1 to 4 numbers, or a string");
        }
        lu_error kerr;
        if (lu_kv_set_number(out, it->string, v, n, &kerr) != LU_OK)
            return scene_fail(c, &kp, kerr.code, "%s", kerr.message);
    }
    return LU_OK;
}

/* "transform": {"translate": [..], "rotate_deg": [..], "scale": s | [sx,sy,sz]} -> T * R * S */
static lu_result parse_transform(parse_ctx *c, const cJSON *parent, const jpath *p, lu_affine *out) {
    *out = lu_affine_identity();
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(parent, "transform");
    if (!t) return LU_OK;
    jpath tp = jp_key(p, "transform");
    static const char *const keys[] = {"translate", "rotate_deg", "scale", NULL};
    TRY(check_object(c, t, &tp, keys));
    lu_vec3 tr, rot, sc;
    TRY(get_vec3(c, t, &tp, "translate", lu_v3s(0), -1e6, 1e6, false, false, &tr));
    TRY(get_vec3(c, t, &tp, "rotate_deg", lu_v3s(0), -3600, 3600, false, false, &rot));
    TRY(get_vec3(c, t, &tp, "scale", lu_v3s(1), 1e-6, 1e6, false, true, &sc));
    lu_affine S = lu_affine_scale(sc), R = lu_affine_rotate_xyz_deg(rot), T = lu_affine_translate(tr);
    lu_affine RS = lu_affine_mul(&R, &S);
    *out = lu_affine_mul(&T, &RS);
    return LU_OK;
}

/* "mesh": "file.ply" | {"procedural": "sphere", ...} */
static lu_result parse_mesh_source(parse_ctx *c, const cJSON *parent, const jpath *p, const char *key, lu_mesh *out) {
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(parent, key);
    jpath mp = jp_key(p, key);
    if (!m) return scene_fail(c, &mp, LU_ERR_SCENE, "missing required mesh (a file name or {\"procedural\": ...})");
    if (cJSON_IsString(m)) {
        char path[1024];
        lu_path_resolve(c->file, m->valuestring, path, sizeof path);
        return wrap_loader(c, &mp, lu_mesh_load(path, out, c->err));
    }
    if (!cJSON_IsObject(m)) return scene_fail(c, &mp, LU_ERR_SCENE, "expected a file name or an object");
    const char *name;
    TRY(get_string(c, m, &mp, "procedural", true, &name));
    lu_kvlist params = {0};
    lu_result r = params_from_object(c, m, &mp, "procedural", &params);
    if (r == LU_OK) {
        char where[300];
        snprintf(where, sizeof where, "%s: %s", c->file, mp.s);
        r = lu_mesh_procedural(name, &params, out, where, c->err);
    }
    lu_kv_free(&params);
    return r;
}

/* Scattering coefficients per millimetre of a translucent material or coating:
 * a preset, overridden by explicit "sigma_s" / "sigma_a", or absorption from
 * the imaginary part of a complex index ("eta_imag", optional
 * "wavelengths_nm", default 700, 550, 425 as in Rohat 2011, Table 4.3). */
static lu_result parse_scattering(parse_ctx *c, const cJSON *m, const jpath *mp, lu_vec3 *ss, lu_vec3 *sa, float *eta,
                                  float *g, char *preset_out, size_t preset_size) {
    const char *preset;
    TRY(get_string(c, m, mp, "preset", false, &preset));
    *ss = lu_v3s(1.0f);
    *sa = lu_v3s(0.01f);
    preset_out[0] = 0;
    bool has_imag = cJSON_HasObjectItem(m, "eta_imag");
    bool has_alb = cJSON_HasObjectItem(m, "subsurface_albedo"), has_mfp = cJSON_HasObjectItem(m, "mean_free_path_mm");
    if (has_alb || has_mfp) {
        /* Authored as artists give it: the half-space's total diffuse
         * reflectance and the reduced (volume) mean free path 1 / sigma_t',
         * inverted through the dipole total all 1D profiles share. */
        if (!has_alb || !has_mfp) {
            jpath kp = jp_key(mp, has_alb ? "subsurface_albedo" : "mean_free_path_mm");
            return scene_fail(c, &kp, LU_ERR_SCENE, "needs \"%s\" as well",
                              has_alb ? "mean_free_path_mm" : "subsurface_albedo");
        }
        static const char *const other[] = {"preset", "sigma_s", "sigma_a", "eta_imag", "wavelengths_nm"};
        for (int i = 0; i < 5; i++)
            if (cJSON_HasObjectItem(m, other[i])) {
                jpath kp = jp_key(mp, other[i]);
                return scene_fail(c, &kp, LU_ERR_SCENE,
                                  "give either \"subsurface_albedo\" with \"mean_free_path_mm\" or coefficients, not both");
            }
        lu_vec3 alb, mfp;
        TRY(get_vec3(c, m, mp, "subsurface_albedo", lu_v3s(0), 0, 1, true, true, &alb));
        TRY(get_vec3(c, m, mp, "mean_free_path_mm", lu_v3s(0), 0, 1e6, true, true, &mfp));
        for (int i = 0; i < 3; i++) {
            jpath ap = jp_key(mp, "subsurface_albedo"), fp = jp_key(mp, "mean_free_path_mm");
            if (!(lu_v3_get(alb, i) > 0.0f))
                return scene_fail(c, &ap, LU_ERR_RANGE, "element %d = %g must be > 0 (no light would scatter back)", i,
                                  lu_v3_get(alb, i));
            if (!(lu_v3_get(mfp, i) > 0.0f))
                return scene_fail(c, &fp, LU_ERR_RANGE, "element %d = %g must be > 0", i, lu_v3_get(mfp, i));
        }
        TRY(get_float(c, m, mp, "eta", *eta, 1.0, 4.0, false, eta));
        TRY(get_float(c, m, mp, "g", 0.0, -0.99, 0.99, false, g));
        float a3[3] = {alb.x, alb.y, alb.z}, l3[3] = {mfp.x, mfp.y, mfp.z};
        lu_vec3 sp;
        lu_material_from_albedo(a3, l3, *eta, &sp, sa);
        *ss = lu_v3_scale(sp, 1.0f / (1.0f - *g));   /* sigma_s with the phase function's g: (1 - g) sigma_s = sigma_s' */
        return LU_OK;
    }
    if (preset) {
        const lu_material_preset *mpre = lu_material_preset_find(preset);
        if (!mpre) {
            jpath pp = jp_key(mp, "preset");
            char names[400] = "";
            int n;
            const lu_material_preset *all = lu_material_presets(&n);
            size_t used = 0;
            for (int i = 0; i < n && used + 1 < sizeof names; i++)
                used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", all[i].name);
            return scene_fail(c, &pp, LU_ERR_SCENE, "unknown preset \"%s\" (known: %s)", preset, names);
        }
        snprintf(preset_out, preset_size, "%s", mpre->name);
        *ss = lu_v3(mpre->sigma_s_prime[0], mpre->sigma_s_prime[1], mpre->sigma_s_prime[2]);
        *sa = lu_v3(mpre->sigma_a[0], mpre->sigma_a[1], mpre->sigma_a[2]);
        *eta = mpre->eta;
    } else if (!cJSON_HasObjectItem(m, "sigma_s") || !(cJSON_HasObjectItem(m, "sigma_a") || has_imag)) {
        return scene_fail(c, mp, LU_ERR_SCENE,
                          "a translucent material needs \"preset\" or \"sigma_s\" with \"sigma_a\" or \"eta_imag\"");
    }
    if (has_imag && cJSON_HasObjectItem(m, "sigma_a"))
        return scene_fail(c, mp, LU_ERR_SCENE, "give either \"sigma_a\" or \"eta_imag\", not both");
    if (!has_imag && cJSON_HasObjectItem(m, "wavelengths_nm")) {
        jpath wp = jp_key(mp, "wavelengths_nm");
        return scene_fail(c, &wp, LU_ERR_SCENE, "only meaningful with \"eta_imag\"");
    }
    /* Explicit coefficients override the preset; both are per millimetre. */
    TRY(get_vec3(c, m, mp, "sigma_s", *ss, 0, 1e6, false, true, ss));
    TRY(get_vec3(c, m, mp, "sigma_a", *sa, 0, 1e6, false, true, sa));
    if (has_imag) {
        lu_vec3 k, lambda;
        TRY(get_vec3(c, m, mp, "eta_imag", lu_v3s(0), 0, 1, true, true, &k));
        TRY(get_vec3(c, m, mp, "wavelengths_nm", lu_v3(700, 550, 425), 100, 10000, false, false, &lambda));
        *sa = lu_v3(lu_sigma_a_from_ior_imag(k.x, lambda.x), lu_sigma_a_from_ior_imag(k.y, lambda.y),
                    lu_sigma_a_from_ior_imag(k.z, lambda.z));
    }
    TRY(get_float(c, m, mp, "eta", *eta, 1.0, 4.0, false, eta));
    TRY(get_float(c, m, mp, "g", 0.0, -0.99, 0.99, false, g));
    return LU_OK;
}

static lu_result parse_material(parse_ctx *c, const cJSON *parent, const jpath *p, const char *key,
                                lu_material *out) {
    lu_material_defaults(out);
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(parent, key);
    if (!m) return LU_OK;
    jpath mp = jp_key(p, key);
    static const char *const keys[] = {"type",     "albedo",         "specular", "shininess", "preset",
                                       "sigma_s",  "sigma_a",        "eta_imag", "wavelengths_nm", "eta",
                                       "g",        "mm_per_unit",    "coatings", "subsurface_albedo",
                                       "mean_free_path_mm", NULL};
    TRY(check_object(c, m, &mp, keys));
    const char *type;
    TRY(get_string(c, m, &mp, "type", false, &type));
    if (!type || strcmp(type, "diffuse") == 0) {
        static const char *const diffuse_keys[] = {"type", "albedo", "specular", "shininess", NULL};
        TRY(check_object(c, m, &mp, diffuse_keys));
        TRY(get_vec3(c, m, &mp, "albedo", out->albedo, 0, 1, false, true, &out->albedo));
        TRY(get_vec3(c, m, &mp, "specular", out->specular, 0, 1, false, true, &out->specular));
        TRY(get_float(c, m, &mp, "shininess", out->shininess, 1, 1e5, false, &out->shininess));
        return LU_OK;
    }
    if (strcmp(type, "translucent") != 0) {
        jpath tp = jp_key(&mp, "type");
        return scene_fail(c, &tp, LU_ERR_SCENE, "unknown material type \"%s\" (diffuse, translucent)", type);
    }
    static const char *const tkeys[] = {"type", "preset", "sigma_s", "sigma_a", "eta_imag", "wavelengths_nm", "eta",
                                        "g", "mm_per_unit", "specular", "shininess", "coatings", "subsurface_albedo",
                                        "mean_free_path_mm", NULL};
    TRY(check_object(c, m, &mp, tkeys));
    out->type = LU_MATERIAL_TRANSLUCENT;
    out->albedo = lu_v3s(0.0f);
    lu_vec3 ss, sa;
    TRY(parse_scattering(c, m, &mp, &ss, &sa, &out->eta, &out->g, out->preset, sizeof out->preset));
    TRY(get_float(c, m, &mp, "mm_per_unit", 1.0, 1e-6, 1e6, false, &out->mm_per_unit));
    TRY(get_vec3(c, m, &mp, "specular", lu_v3s(1.0f), 0, 1, false, true, &out->specular));
    TRY(get_float(c, m, &mp, "shininess", 64.0, 1, 1e5, false, &out->shininess));
    const cJSON *coats = cJSON_GetObjectItemCaseSensitive(m, "coatings");
    if (coats) {
        jpath cp = jp_key(&mp, "coatings");
        if (!cJSON_IsArray(coats)) return scene_fail(c, &cp, LU_ERR_SCENE, "expected an array");
        if (cJSON_GetArraySize(coats) > LU_MAX_COATINGS)
            return scene_fail(c, &cp, LU_ERR_LIMIT, "%d coatings exceed the limit of %d", cJSON_GetArraySize(coats),
                              LU_MAX_COATINGS);
        int i = 0;
        for (const cJSON *it = coats->child; it; it = it->next, i++) {
            jpath ip = jp_index(&cp, i);
            if (!cJSON_IsObject(it)) return scene_fail(c, &ip, LU_ERR_SCENE, "expected an object");
            static const char *const ckeys[] = {"preset", "sigma_s", "sigma_a", "eta_imag", "wavelengths_nm", "eta",
                                                "g", "thickness_mm", "subsurface_albedo", "mean_free_path_mm", NULL};
            TRY(check_object(c, it, &ip, ckeys));
            lu_coating *co = &out->coatings[i];
            lu_vec3 css, csa;
            char name[32];
            co->eta = 1.3f;
            TRY(parse_scattering(c, it, &ip, &css, &csa, &co->eta, &co->g, name, sizeof name));
            float mm;
            TRY(get_float(c, it, &ip, "thickness_mm", 0.0, 1e-9, 1e9, true, &mm));
            co->sigma_s = lu_v3_scale(css, out->mm_per_unit);
            co->sigma_a = lu_v3_scale(csa, out->mm_per_unit);
            co->thickness = mm / out->mm_per_unit;
            out->coating_count = i + 1;
        }
    }
    out->sigma_s = lu_v3_scale(ss, out->mm_per_unit);
    out->sigma_a = lu_v3_scale(sa, out->mm_per_unit);
    return LU_OK;
}

static lu_result parse_camera(parse_ctx *c, const cJSON *root, lu_scene_builder *b) {
    jpath p = {"$.camera"};
    lu_camera camera, *cam = &camera;
    const cJSON *o = cJSON_GetObjectItemCaseSensitive(root, "camera");
    if (!o) return scene_fail(c, &p, LU_ERR_SCENE, "missing required object");
    static const char *const keys[] = {"position", "look_at", "up", "fov_y_deg", "width", "height", NULL};
    TRY(check_object(c, o, &p, keys));
    TRY(get_vec3(c, o, &p, "position", lu_v3s(0), -1e6, 1e6, true, false, &cam->position));
    TRY(get_vec3(c, o, &p, "look_at", lu_v3s(0), -1e6, 1e6, true, false, &cam->look_at));
    TRY(get_vec3(c, o, &p, "up", lu_v3(0, 1, 0), -1e6, 1e6, false, false, &cam->up));
    TRY(get_float(c, o, &p, "fov_y_deg", 45.0, 0.01, 179.0, false, &cam->fov_y_deg));
    TRY(get_int(c, o, &p, "width", 512, 1, LU_MAX_IMAGE_DIM, false, &cam->width));
    TRY(get_int(c, o, &p, "height", 512, 1, LU_MAX_IMAGE_DIM, false, &cam->height));
    return wrap_loader(c, &p, lu_scene_builder_set_camera(b, cam, c->err));
}

/* Fills *l (the builder checks and adds it). */
static lu_result parse_light(parse_ctx *c, const cJSON *o, const jpath *p, lu_light *l) {
    memset(l, 0, sizeof *l);
    const char *type;
    if (!cJSON_IsObject(o)) return scene_fail(c, p, LU_ERR_SCENE, "expected an object");
    TRY(get_string(c, o, p, "type", true, &type));
    if (strcmp(type, "point") == 0) {
        static const char *const keys[] = {"type", "position", "intensity", NULL};
        TRY(check_object(c, o, p, keys));
        l->type = LU_LIGHT_POINT;
        TRY(get_vec3(c, o, p, "position", lu_v3s(0), -1e6, 1e6, true, false, &l->position));
        TRY(get_vec3(c, o, p, "intensity", lu_v3s(0), 0, 1e9, true, true, &l->intensity));
    } else if (strcmp(type, "spot") == 0) {
        static const char *const keys[] = {"type", "position", "direction", "intensity", "inner_deg", "outer_deg", NULL};
        TRY(check_object(c, o, p, keys));
        l->type = LU_LIGHT_SPOT;
        TRY(get_vec3(c, o, p, "position", lu_v3s(0), -1e6, 1e6, true, false, &l->position));
        TRY(get_vec3(c, o, p, "direction", lu_v3s(0), -1e6, 1e6, true, false, &l->direction));
        TRY(get_vec3(c, o, p, "intensity", lu_v3s(0), 0, 1e9, true, true, &l->intensity));
        TRY(get_float(c, o, p, "inner_deg", 20.0, 0.0, 89.9, false, &l->inner_deg));
        TRY(get_float(c, o, p, "outer_deg", 25.0, 0.01, 89.9, false, &l->outer_deg));
    } else if (strcmp(type, "directional") == 0) {
        static const char *const keys[] = {"type", "direction", "irradiance", NULL};
        TRY(check_object(c, o, p, keys));
        l->type = LU_LIGHT_DIRECTIONAL;
        TRY(get_vec3(c, o, p, "direction", lu_v3s(0), -1e6, 1e6, true, false, &l->direction));
        TRY(get_vec3(c, o, p, "irradiance", lu_v3s(0), 0, 1e9, true, true, &l->intensity));
    } else if (strcmp(type, "environment") == 0) {
        static const char *const keys[] = {"type", "file", "radiance", "scale", NULL};
        TRY(check_object(c, o, p, keys));
        l->type = LU_LIGHT_ENVIRONMENT;
        const char *file;
        TRY(get_string(c, o, p, "file", false, &file));
        TRY(get_float(c, o, p, "scale", 1.0, 0.0, 1e9, false, &l->env_scale));
        if (file && cJSON_HasObjectItem(o, "radiance"))
            return scene_fail(c, p, LU_ERR_SCENE, "give either \"file\" or \"radiance\", not both");
        if (file) {
            char path[1024];
            lu_path_resolve(c->file, file, path, sizeof path);
            jpath fp = jp_key(p, "file");
            TRY(wrap_loader(c, &fp, lu_image_load(path, &l->env, c->err)));
        } else {
            /* A constant environment is a 1x1 map. */
            lu_vec3 rad;
            TRY(get_vec3(c, o, p, "radiance", lu_v3s(0), 0, 1e9, true, true, &rad));
            TRY(wrap_loader(c, p, lu_image_create(&l->env, 1, 1, c->err)));
            l->env.rgb[0] = rad.x;
            l->env.rgb[1] = rad.y;
            l->env.rgb[2] = rad.z;
        }
        return LU_OK;
    } else {
        jpath tp = jp_key(p, "type");
        return scene_fail(c, &tp, LU_ERR_SCENE, "unknown light type \"%s\" (point, spot, directional, environment)",
                          type);
    }
    return LU_OK;
}

static lu_result add_light(parse_ctx *c, const cJSON *o, const jpath *p, lu_scene_builder *b) {
    lu_light l;
    lu_result r = parse_light(c, o, p, &l);
    if (r != LU_OK) {
        lu_image_destroy(&l.env);
        return r;
    }
    return wrap_loader(c, p, lu_scene_builder_add_light(b, &l, c->err));
}

/* "density": {"constant": v} | {"file": "x.nvdb" or "x.vdb", "grid": "density"} |
 *            {"raw": "x.raw", "dims": [nx,ny,nz], "voxel_size": h, "origin": [x,y,z]} |
 *            {"procedural": NAME, ...params} */
static lu_result parse_grid_source(parse_ctx *c, const cJSON *d, const jpath *pp, bool density, lu_grid *grid,
                                   lu_grid_anim **anim);

static lu_result parse_density(parse_ctx *c, const cJSON *parent, const jpath *p, lu_medium *m) {
    const cJSON *d = cJSON_GetObjectItemCaseSensitive(parent, "density");
    jpath dp = jp_key(p, "density");
    if (!d) return scene_fail(c, &dp, LU_ERR_SCENE, "missing required object");
    if (!cJSON_IsObject(d)) return scene_fail(c, &dp, LU_ERR_SCENE, "expected an object");
    if (cJSON_HasObjectItem(d, "constant")) {
        static const char *const keys[] = {"constant", NULL};
        TRY(check_object(c, d, &dp, keys));
        m->kind = LU_DENSITY_CONSTANT;
        return get_float(c, d, &dp, "constant", 1.0, 0.0, 1e6, true, &m->constant);
    }
    m->kind = LU_DENSITY_GRID;
    return parse_grid_source(c, d, &dp, true, &m->grid, &m->density_anim);
}

/* "frames": [first, last], "extend": "hold" | "loop" of a sequence. */
static lu_result parse_frames(parse_ctx *c, const cJSON *d, const jpath *dp, int *first, int *last, bool *loop) {
    const cJSON *f = cJSON_GetObjectItemCaseSensitive(d, "frames");
    jpath fp = jp_key(dp, "frames");
    if (!cJSON_IsArray(f) || cJSON_GetArraySize(f) != 2)
        return scene_fail(c, &fp, LU_ERR_SCENE, "expected [first, last] (two whole frame numbers)");
    int v[2];
    for (int i = 0; i < 2; i++) {
        const cJSON *e = cJSON_GetArrayItem(f, i);
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || e->valuedouble != floor(e->valuedouble))
            return scene_fail(c, &fp, LU_ERR_SCENE, "element %d is not a whole number", i);
        if (!(e->valuedouble >= 0 && e->valuedouble <= 1e9))
            return scene_fail(c, &fp, LU_ERR_RANGE, "element %d = %g is outside [0, 1e9]", i, e->valuedouble);
        v[i] = (int)e->valuedouble;
    }
    if (v[1] < v[0]) return scene_fail(c, &fp, LU_ERR_RANGE, "the last frame %d comes before the first %d", v[1], v[0]);
    if ((long long)v[1] - v[0] + 1 > LU_SEQUENCE_MAX_FRAMES)
        return scene_fail(c, &fp, LU_ERR_LIMIT, "%d frames exceed the limit of %d", v[1] - v[0] + 1, LU_SEQUENCE_MAX_FRAMES);
    const char *extend;
    TRY(get_string(c, d, dp, "extend", false, &extend));
    if (extend && strcmp(extend, "hold") != 0 && strcmp(extend, "loop") != 0) {
        jpath ep = jp_key(dp, "extend");
        return scene_fail(c, &ep, LU_ERR_SCENE, "unknown \"%s\" (hold, loop)", extend);
    }
    *first = v[0];
    *last = v[1];
    *loop = extend && strcmp(extend, "loop") == 0;
    return LU_OK;
}

/* A grid from one of "file", "raw", "voxelize", "procedural" in object d (at
 * path *pp); *anim is set when the grid follows time (a sequence, an animated
 * procedural). */
static lu_result parse_grid_source(parse_ctx *c, const cJSON *d, const jpath *pp, bool density, lu_grid *grid,
                                   lu_grid_anim **anim) {
    jpath dp = *pp;
    *anim = NULL;
    if (cJSON_HasObjectItem(d, "file")) {
        static const char *const keys[] = {"file", "grid", "storage", "frames", "extend", NULL};
        TRY(check_object(c, d, &dp, keys));
        const char *file, *gname, *storage_name = NULL;
        TRY(get_string(c, d, &dp, "file", true, &file));
        TRY(get_string(c, d, &dp, "grid", false, &gname));
        TRY(get_string(c, d, &dp, "storage", false, &storage_name));
        /* Emission and temperature grids are re-embedded over the density's
         * voxels (embed_grid), which is dense work: they load dense. */
        lu_grid_storage storage = density ? LU_GRID_STORAGE_SPARSE : LU_GRID_STORAGE_DENSE;
        if (storage_name && strcmp(storage_name, "dense") == 0) {
            storage = LU_GRID_STORAGE_DENSE;
        } else if (storage_name && (strcmp(storage_name, "sparse") != 0 || !density)) {
            jpath sp = jp_key(&dp, "storage");
            return scene_fail(c, &sp, LU_ERR_SCENE, "%s", density ? "expected \"sparse\" or \"dense\""
                                                                  : "an emission or temperature grid is always dense");
        }
        char path[1024];
        lu_path_resolve(c->file, file, path, sizeof path);
        bool vdb = lu_path_has_suffix(path, ".vdb");
        if (!vdb && !lu_path_has_suffix(path, ".nvdb")) {
            jpath fp = jp_key(&dp, "file");
            return scene_fail(c, &fp, LU_ERR_UNSUPPORTED,
                              "\"%s\" is neither a .nvdb nor a .vdb file (raw grids use \"raw\")", file);
        }
        if (storage_name && cJSON_HasObjectItem(d, "frames")) {
            jpath sp = jp_key(&dp, "storage");
            return scene_fail(c, &sp, LU_ERR_SCENE, "a sequence is always dense (its frames are edited in)");
        }
        if (cJSON_HasObjectItem(d, "frames")) {
            int first = 0, last = 0;
            bool loop = false;
            TRY(parse_frames(c, d, &dp, &first, &last, &loop));
            return wrap_loader(c, &dp, lu_grid_anim_sequence(path, gname, first, last, loop,
                                                             lu_scene_frame_at(&c->clock, c->clock.time), grid, anim,
                                                             c->err));
        }
        if (cJSON_HasObjectItem(d, "extend")) {
            jpath ep = jp_key(&dp, "extend");
            return scene_fail(c, &ep, LU_ERR_SCENE, "only meaningful with \"frames\"");
        }
        if (vdb) {
            lu_result r = lu_grid_load_vdb(path, gname, grid, c->err);
            if (r == LU_OK && storage == LU_GRID_STORAGE_DENSE && lu_grid_is_sparse(grid)) {
                lu_grid d2;
                r = lu_grid_densify(grid, &d2, c->err);
                lu_grid_destroy(grid);
                if (r == LU_OK) *grid = d2;
            }
            return wrap_loader(c, &dp, r);
        }
        return wrap_loader(c, &dp, lu_grid_load_nvdb_as(path, gname, storage, grid, c->err));
    }
    if (cJSON_HasObjectItem(d, "raw")) {
        static const char *const keys[] = {"raw", "dims", "voxel_size", "origin", NULL};
        TRY(check_object(c, d, &dp, keys));
        const char *file;
        TRY(get_string(c, d, &dp, "raw", true, &file));
        lu_vec3 dims, origin;
        float h;
        TRY(get_vec3(c, d, &dp, "dims", lu_v3s(0), 1, 65536, true, false, &dims));
        TRY(get_float(c, d, &dp, "voxel_size", 1.0, 1e-9, 1e9, false, &h));
        TRY(get_vec3(c, d, &dp, "origin", lu_v3s(0), -1e6, 1e6, false, false, &origin));
        if (dims.x != floorf(dims.x) || dims.y != floorf(dims.y) || dims.z != floorf(dims.z)) {
            jpath kp = jp_key(&dp, "dims");
            return scene_fail(c, &kp, LU_ERR_SCENE, "dims must be integers");
        }
        char path[1024];
        lu_path_resolve(c->file, file, path, sizeof path);
        TRY(wrap_loader(c, &dp, lu_grid_load_raw(path, (int)dims.x, (int)dims.y, (int)dims.z, grid, c->err)));
        lu_affine s = lu_affine_scale(lu_v3s(h)), t = lu_affine_translate(origin);
        grid->index_to_world = lu_affine_mul(&t, &s);
        return LU_OK;
    }
    if (cJSON_HasObjectItem(d, "voxelize")) {
        /* A fog volume from a closed mesh: density = value * inside fraction. */
        static const char *const keys[] = {"voxelize", "resolution", "value", "supersample", NULL};
        TRY(check_object(c, d, &dp, keys));
        int res, ss;
        float value;
        TRY(get_int(c, d, &dp, "resolution", 64, 4, 1024, false, &res));
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
        if (res > 16) res = 16; /* the fuzzer is after the parser, not the voxelizer */
#endif
        TRY(get_int(c, d, &dp, "supersample", 2, 1, 8, false, &ss));
        TRY(get_float(c, d, &dp, "value", 1.0, 0.0, 1e6, false, &value));
        lu_mesh mesh = {0};
        TRY(parse_mesh_source(c, d, &dp, "voxelize", &mesh));
        lu_accel *acc = NULL;
        lu_result r = lu_accel_create(&acc, c->err);
        uint32_t id;
        if (r == LU_OK) r = lu_accel_add_mesh(acc, &mesh, &id, c->err);
        if (r == LU_OK) r = lu_accel_commit(acc, c->err);
        if (r == LU_OK) {
            lu_aabb b = lu_mesh_bounds(&mesh);
            lu_vec3 pad = lu_v3s(lu_v3_maxc(lu_v3_sub(b.hi, b.lo)) / (float)res);
            b.lo = lu_v3_sub(b.lo, pad);
            b.hi = lu_v3_add(b.hi, pad);
            r = lu_voxelize(acc, b, res, ss, grid, c->err);
        }
        if (acc) lu_accel_destroy(acc);
        lu_mesh_destroy(&mesh);
        if (r != LU_OK) return wrap_loader(c, &dp, r);
        for (size_t i = 0; i < (size_t)grid->nx * grid->ny * grid->nz; i++) grid->data[i] *= value;
        lu_grid_update_range(grid);
        return LU_OK;
    }
    if (cJSON_HasObjectItem(d, "procedural")) {
        const char *name;
        TRY(get_string(c, d, &dp, "procedural", true, &name));
        lu_kvlist params = {0};
        lu_result r = params_from_object(c, d, &dp, "procedural", &params);
        if (r == LU_OK && lu_kv_find(&params, "time")) {
            jpath tp = jp_key(&dp, "time");
            r = scene_fail(c, &tp, LU_ERR_SCENE, "the time is the scene's (its key \"time\", or --time)");
        }
        if (r == LU_OK) {
            char where[300];
            snprintf(where, sizeof where, "%s: %s", c->file, dp.s);
            r = lu_grid_procedural_animated(name, &params)
                    ? lu_grid_anim_procedural(name, &params, where, c->clock.time, grid, anim, c->err)
                    : lu_grid_procedural(name, &params, grid, where, c->err);
        }
        lu_kv_free(&params);
        return r;
    }
    return scene_fail(c, &dp, LU_ERR_SCENE, "expected one of %s\"file\", \"raw\", \"voxelize\", \"procedural\"",
                      density ? "\"constant\", " : "");
}

/* e re-embedded over d's voxels (offset k, lu_grid_embed). Values of e
 * outside d's box are dropped: the density is 0 there, and emission is
 * weighted by density. */
static lu_result embed_grid(parse_ctx *c, const jpath *p, const lu_grid *d, lu_grid *e, const int k[3]) {
    if (k[0] == 0 && k[1] == 0 && k[2] == 0 && e->nx == d->nx && e->ny == d->ny && e->nz == d->nz) return LU_OK;
    lu_grid g = {0};
    lu_result r = lu_grid_embed(e, k, d->nx, d->ny, d->nz, &d->index_to_world, &g, c->err);
    if (r != LU_OK) return scene_fail(c, p, r, "%s", c->err->message);
    lu_grid_destroy(e);
    *e = g;
    return LU_OK;
}

/* "emission": {"color": c, "scale": s} (constant Le) | {..., "grid": SOURCE} |
 *             {..., "temperature": SOURCE, "temperature_scale": k, "temperature_offset": t0}
 * SOURCE as a grid density (parse_grid_source), in the density's index space. */
static lu_result parse_emission(parse_ctx *c, const cJSON *o, const jpath *p, lu_medium *m) {
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(o, "emission");
    if (!e) return LU_OK;
    jpath ep = jp_key(p, "emission");
    static const char *const keys[] = {"color", "scale", "grid", "temperature", "temperature_scale",
                                       "temperature_offset", NULL};
    TRY(check_object(c, e, &ep, keys));
    TRY(get_vec3(c, e, &ep, "color", lu_v3s(1), 0, 1e6, false, true, &m->le_color));
    TRY(get_float(c, e, &ep, "scale", 1.0, 0.0, 1e9, false, &m->le_scale));
    const cJSON *g = cJSON_GetObjectItemCaseSensitive(e, "grid");
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(e, "temperature");
    if (g && t) return scene_fail(c, &ep, LU_ERR_SCENE, "give \"grid\" or \"temperature\", not both");
    bool blackbody = t != NULL;
    if (!blackbody && (cJSON_HasObjectItem(e, "temperature_scale") || cJSON_HasObjectItem(e, "temperature_offset")))
        return scene_fail(c, &ep, LU_ERR_SCENE, "\"temperature_scale\" and \"temperature_offset\" need a \"temperature\" grid");
    TRY(get_float(c, e, &ep, "temperature_scale", 1.0, 0.0, 1e9, false, &m->temp_scale));
    TRY(get_float(c, e, &ep, "temperature_offset", 0.0, -1e9, 1e9, false, &m->temp_offset));
    if (!g && !t) {
        m->emission = LU_EMISSION_CONSTANT;
        return LU_OK;
    }
    jpath gp = jp_key(&ep, blackbody ? "temperature" : "grid");
    if (m->kind != LU_DENSITY_GRID)
        return scene_fail(c, &gp, LU_ERR_SCENE,
                          "a constant density has no index space for an emission grid (use a grid density, or a "
                          "constant emission)");
    if (!cJSON_IsObject(blackbody ? t : g)) return scene_fail(c, &gp, LU_ERR_SCENE, "expected an object");
    m->emission = blackbody ? LU_EMISSION_BLACKBODY : LU_EMISSION_GRID;
    TRY(parse_grid_source(c, blackbody ? t : g, &gp, false, &m->emission_grid, &m->emission_anim));
    int k[3];
    if (!lu_grid_shared_index_space(&m->grid, &m->emission_grid, k)) {
        const lu_affine *a = &m->grid.index_to_world, *b = &m->emission_grid.index_to_world;
        return scene_fail(c, &gp, LU_ERR_SCENE,
                          "this grid is %dx%dx%d with voxel (%g, %g, %g) at (%g, %g, %g), the density grid %dx%dx%d with "
                          "voxel (%g, %g, %g) at (%g, %g, %g): the two must share one index space (the same voxels, "
                          "offset by whole voxels at most)",
                          m->emission_grid.nx, m->emission_grid.ny, m->emission_grid.nz, (double)b->m[0][0],
                          (double)b->m[1][1], (double)b->m[2][2], (double)b->m[0][3], (double)b->m[1][3],
                          (double)b->m[2][3], m->grid.nx, m->grid.ny, m->grid.nz, (double)a->m[0][0],
                          (double)a->m[1][1], (double)a->m[2][2], (double)a->m[0][3], (double)a->m[1][3],
                          (double)a->m[2][3]);
    }
    return embed_grid(c, &gp, &m->grid, &m->emission_grid, k);
}

static lu_result parse_medium(parse_ctx *c, const cJSON *o, const jpath *p, lu_medium *m, lu_affine *xf,
                              bool *surface_given) {
    static const char *const keys[] = {"density", "sigma_s", "sigma_a", "phase_g", "transform", "boundary", "emission",
                                       NULL};
    TRY(check_object(c, o, p, keys));
    TRY(parse_density(c, o, p, m));
    TRY(get_vec3(c, o, p, "sigma_s", lu_v3s(1), 0, 1e6, true, true, &m->sigma_s));
    TRY(get_vec3(c, o, p, "sigma_a", lu_v3s(0), 0, 1e6, false, true, &m->sigma_a));
    TRY(get_float(c, o, p, "phase_g", 0.0, -0.99, 0.99, false, &m->phase_g));
    TRY(parse_emission(c, o, p, m));
    TRY(parse_transform(c, o, p, xf));
    const cJSON *bd = cJSON_GetObjectItemCaseSensitive(o, "boundary");
    if (bd) {
        jpath bp = jp_key(p, "boundary");
        static const char *const bkeys[] = {"mesh", "eta", "surface", NULL};
        TRY(check_object(c, bd, &bp, bkeys));
        TRY(parse_mesh_source(c, bd, &bp, "mesh", &m->boundary));
        m->has_boundary = true;
        TRY(get_float(c, bd, &bp, "eta", 1.5, 1.0, 4.0, false, &m->eta));
        TRY(parse_material(c, bd, &bp, "surface", &m->surface));
        *surface_given = cJSON_HasObjectItem(bd, "surface");
    }
    return LU_OK;
}

static lu_result add_medium(parse_ctx *c, const cJSON *o, const jpath *p, lu_scene_builder *b) {
    lu_medium m;
    memset(&m, 0, sizeof m);
    lu_affine xf;
    bool surface_given = false;
    lu_result r = parse_medium(c, o, p, &m, &xf, &surface_given);
    if (r == LU_OK && c->anim_count + 2 > c->anim_cap) {
        int cap = c->anim_cap ? 2 * c->anim_cap : 8;
        lu_grid_anim **a = lu_realloc(c->anims, (size_t)cap * sizeof *a);
        if (!a) r = scene_fail(c, p, LU_ERR_NOMEM, "out of memory");
        else c->anims = a, c->anim_cap = cap;
    }
    if (r != LU_OK) {
        lu_grid_destroy(&m.grid);
        lu_grid_destroy(&m.emission_grid);
        lu_mesh_destroy(&m.boundary);
        lu_grid_anim_free(m.density_anim);
        lu_grid_anim_free(m.emission_anim);
        return r;
    }
    /* A zero colour or scale is no emission (zero means "default" in the desc). */
    if (m.le_scale == 0.0f || (m.le_color.x == 0.0f && m.le_color.y == 0.0f && m.le_color.z == 0.0f)) {
        m.emission = LU_EMISSION_NONE;
        lu_grid_destroy(&m.emission_grid);
        lu_grid_anim_free(m.emission_anim);
        m.emission_anim = NULL;
    }
    /* The scene takes them after lu_scene_builder_finish (parse_root), medium i of "media" being media[i]. */
    c->anims[c->anim_count++] = m.density_anim;
    c->anims[c->anim_count++] = m.emission_anim;
    lu_medium_desc d = {.kind = m.kind, .grid = &m.grid, .constant = m.constant, .sigma_s = m.sigma_s,
                        .sigma_a = m.sigma_a, .phase_g = m.phase_g, .transform = &xf,
                        .boundary = m.has_boundary ? &m.boundary : NULL, .eta = m.eta,
                        .surface = surface_given ? &m.surface : NULL, .emission = m.emission,
                        .emission_grid = &m.emission_grid, .le_color = m.le_color, .le_scale = m.le_scale,
                        .temp_scale = m.temp_scale, .temp_offset = m.temp_offset};
    r = lu_scene_builder_add_medium(b, &d, c->err);
    lu_grid_destroy(&m.grid);   /* empty unless the builder refused the kind */
    lu_grid_destroy(&m.emission_grid);
    return wrap_loader(c, p, r);
}

static lu_result add_object(parse_ctx *c, const cJSON *o, const jpath *p, lu_scene_builder *b) {
    static const char *const keys[] = {"mesh", "transform", "material", NULL};
    TRY(check_object(c, o, p, keys));
    lu_mesh mesh = {0};
    lu_affine xf;
    lu_material mat;
    lu_result r = parse_mesh_source(c, o, p, "mesh", &mesh);
    if (r == LU_OK) r = parse_transform(c, o, p, &xf);
    if (r == LU_OK) r = parse_material(c, o, p, "material", &mat);
    if (r != LU_OK) {
        lu_mesh_destroy(&mesh);
        return r;
    }
    return wrap_loader(c, p, lu_scene_builder_add_object(b, &mesh, &xf, &mat, c->err));
}

/* Parses each element of a JSON list and adds it to the builder with fn. */
static lu_result parse_list(parse_ctx *c, const cJSON *root, const char *key, lu_scene_builder *b,
                            lu_result (*fn)(parse_ctx *, const cJSON *, const jpath *, lu_scene_builder *)) {
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(root, key);
    if (!list) return LU_OK;
    jpath lp = {"$"};
    lp = jp_key(&lp, key);
    if (!cJSON_IsArray(list)) return scene_fail(c, &lp, LU_ERR_SCENE, "expected an array");
    int n = cJSON_GetArraySize(list);
    if (n > LU_SCENE_MAX_ITEMS)
        return scene_fail(c, &lp, LU_ERR_LIMIT, "%d entries exceed the limit of %d", n, LU_SCENE_MAX_ITEMS);
    int i = 0;
    for (const cJSON *it = list->child; it; it = it->next, i++) {
        jpath ip = jp_index(&lp, i);
        TRY(fn(c, it, &ip, b));
    }
    return LU_OK;
}

static lu_result parse_root(parse_ctx *c, const cJSON *root, lu_scene *s) {
    jpath rp = {"$"};
    static const char *const keys[] = {"name", "description", "reproduces", "camera", "background",
                                       "lights", "media", "objects", "time", "fps", NULL};
    TRY(check_object(c, root, &rp, keys));
    const char *str;
    TRY(get_string(c, root, &rp, "name", false, &str));
    TRY(get_string(c, root, &rp, "description", false, &str));
    TRY(get_string(c, root, &rp, "reproduces", false, &str));
    TRY(get_number(c, root, &rp, "time", 0.0, -1e6, 1e6, false, &c->clock.time));
    TRY(get_number(c, root, &rp, "fps", LU_SCENE_DEFAULT_FPS, 1e-3, 1e6, false, &c->clock.fps));
    lu_scene_builder *b;
    TRY(lu_scene_builder_create(&b, c->err));
    lu_vec3 background;
    lu_result r = parse_camera(c, root, b);
    if (r == LU_OK) r = get_vec3(c, root, &rp, "background", lu_v3s(0), 0, 1e9, false, true, &background);
    if (r == LU_OK) lu_scene_builder_set_background(b, background);
    if (r == LU_OK) r = parse_list(c, root, "lights", b, add_light);
    if (r == LU_OK) r = parse_list(c, root, "media", b, add_medium);
    if (r == LU_OK) r = parse_list(c, root, "objects", b, add_object);
    if (r != LU_OK) {
        lu_scene_builder_destroy(b);
        return r;
    }
    TRY(wrap_loader(c, &rp, lu_scene_builder_finish(b, s, c->err)));
    for (int i = 0; i < c->anim_count / 2 && i < s->medium_count; i++) {
        s->media[i].density_anim = c->anims[2 * i];
        s->media[i].emission_anim = c->anims[2 * i + 1];
        c->anims[2 * i] = c->anims[2 * i + 1] = NULL;
    }
    s->time = c->clock.time;
    s->fps = c->clock.fps;
    return LU_OK;
}

/* Byte offset -> "line L, column C" for cJSON's syntax errors. */
static void line_col(const char *text, size_t offset, int *line, int *col) {
    *line = 1;
    *col = 1;
    for (size_t i = 0; i < offset && text[i]; i++) {
        if (text[i] == '\n') {
            (*line)++;
            *col = 1;
        } else {
            (*col)++;
        }
    }
}

lu_result lu_scene_load_string(const char *json, const char *base_path, lu_scene *scene, lu_error *err) {
    memset(scene, 0, sizeof *scene);
    const char *file = base_path && *base_path ? base_path : "<scene>";
    parse_ctx c = {.file = file, .err = err};
    size_t len = strlen(json);
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(json, len + 1, &end, true); /* length includes the NUL it requires */
    if (!root) {
        size_t off = end && end >= json ? (size_t)(end - json) : 0;
        int line, col;
        line_col(json, off, &line, &col);
        return lu_fail(err, LU_ERR_FORMAT, "%s:%d:%d: JSON syntax error near byte %zu", file, line, col, off);
    }
    lu_error local;
    if (!err) c.err = &local;
    lu_result r = parse_root(&c, root, scene);
    cJSON_Delete(root);
    for (int i = 0; i < c.anim_count; i++) lu_grid_anim_free(c.anims[i]);   /* those the scene did not take */
    lu_free(c.anims);
    if (r != LU_OK) lu_scene_destroy(scene);
    else snprintf(scene->path, sizeof scene->path, "%s", base_path ? base_path : "");
    return r;
}

lu_result lu_scene_load(const char *path, lu_scene *scene, lu_error *err) {
    memset(scene, 0, sizeof *scene);
    char *text;
    size_t size;
    lu_result r = lu_read_file(path, LU_SCENE_MAX_BYTES, &text, &size, err);
    if (r != LU_OK) return r;
    if (strlen(text) != size) {
        lu_free(text);
        return lu_fail(err, LU_ERR_FORMAT, "%s: offset %zu: NUL byte in a JSON file", path, strlen(text));
    }
    r = lu_scene_load_string(text, path, scene, err);
    lu_free(text);
    return r;
}
