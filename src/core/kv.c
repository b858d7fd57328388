/* Named settings: method parameters and procedural generator parameters. */
#include <lucent/core.h>

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void lu_kv_free(lu_kvlist *list) {
    lu_free(list->items);
    list->items = NULL;
    list->count = list->capacity = 0;
}

static lu_kv *kv_slot(lu_kvlist *list, const char *key, lu_error *err) {
    if (strlen(key) == 0 || strlen(key) >= LU_KV_KEY_MAX) {
        lu_fail(err, LU_ERR_INVALID_ARG, "setting name \"%.80s\" is empty or longer than %d characters", key,
                LU_KV_KEY_MAX - 1);
        return NULL;
    }
    for (int i = 0; i < list->count; i++)
        if (strcmp(list->items[i].key, key) == 0) return &list->items[i];
    if (list->count == list->capacity) {
        int cap = list->capacity ? list->capacity * 2 : 8;
        lu_kv *items = lu_realloc(list->items, (size_t)cap * sizeof *items);
        if (!items) {
            lu_fail(err, LU_ERR_NOMEM, "out of memory growing settings");
            return NULL;
        }
        list->items = items;
        list->capacity = cap;
    }
    lu_kv *kv = &list->items[list->count++];
    memset(kv, 0, sizeof *kv);
    snprintf(kv->key, sizeof kv->key, "%s", key);
    return kv;
}

lu_result lu_kv_set_number(lu_kvlist *list, const char *key, const double *v, int count, lu_error *err) {
    if (count < 1 || count > 4) return lu_fail(err, LU_ERR_INVALID_ARG, "%s: expected 1 to 4 numbers, got %d", key, count);
    for (int i = 0; i < count; i++)
        if (!isfinite(v[i])) return lu_fail(err, LU_ERR_NONFINITE, "%s: value is not a finite number", key);
    lu_kv *kv = kv_slot(list, key, err);
    if (!kv) return err ? err->code : LU_ERR_INVALID_ARG;
    kv->count = count;
    for (int i = 0; i < count; i++) kv->v[i] = v[i];
    kv->str[0] = '\0';
    return LU_OK;
}

lu_result lu_kv_set_string(lu_kvlist *list, const char *key, const char *value, lu_error *err) {
    if (strlen(value) >= LU_KV_STR_MAX)
        return lu_fail(err, LU_ERR_LIMIT, "%s: string value longer than %d characters", key, LU_KV_STR_MAX - 1);
    lu_kv *kv = kv_slot(list, key, err);
    if (!kv) return err ? err->code : LU_ERR_INVALID_ARG;
    kv->count = 0;
    snprintf(kv->str, sizeof kv->str, "%s", value);
    return LU_OK;
}

/* Parses a full-string double; false if anything but a number is present. */
static bool parse_double(const char *s, size_t len, double *out) {
    char buf[128];
    if (len == 0 || len >= sizeof buf) return false;
    memcpy(buf, s, len);
    buf[len] = '\0';
    char *end = NULL;
    errno = 0;
    double v = strtod(buf, &end);
    while (end && isspace((unsigned char)*end)) end++;
    if (!end || *end != '\0' || end == buf || errno == ERANGE) return false;
    *out = v;
    return true;
}

lu_result lu_kv_parse_assignment(lu_kvlist *list, const char *text, lu_error *err) {
    const char *eq = strchr(text, '=');
    if (!eq || eq == text) return lu_fail(err, LU_ERR_INVALID_ARG, "setting \"%s\" is not of the form key=value", text);
    char key[LU_KV_KEY_MAX];
    size_t klen = (size_t)(eq - text);
    if (klen >= sizeof key) return lu_fail(err, LU_ERR_INVALID_ARG, "setting name in \"%s\" is too long", text);
    memcpy(key, text, klen);
    key[klen] = '\0';
    const char *val = eq + 1;
    double v[4];
    int n = 0;
    const char *p = val;
    bool numeric = *p != '\0';
    while (numeric && *p) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        if (n == 4 || !parse_double(p, len, &v[n])) numeric = false;
        else n++;
        p = comma ? comma + 1 : p + len;
        if (comma && *p == '\0') numeric = false;
    }
    if (numeric && n > 0) return lu_kv_set_number(list, key, v, n, err);
    if (*val == '\0') return lu_fail(err, LU_ERR_INVALID_ARG, "setting \"%s\" has an empty value", key);
    return lu_kv_set_string(list, key, val, err);
}

const lu_kv *lu_kv_find(const lu_kvlist *list, const char *key) {
    if (!list) return NULL;
    for (int i = 0; i < list->count; i++)
        if (strcmp(list->items[i].key, key) == 0) return &list->items[i];
    return NULL;
}

lu_result lu_kv_number(const lu_kvlist *list, const char *key, double def, double lo, double hi, double *out,
                       const char *where, lu_error *err) {
    const lu_kv *kv = lu_kv_find(list, key);
    if (!kv) {
        *out = def;
        return LU_OK;
    }
    if (kv->count != 1)
        return lu_fail(err, LU_ERR_SCENE, "%s: \"%s\" must be a single number", where, key);
    if (!(kv->v[0] >= lo && kv->v[0] <= hi))
        return lu_fail(err, LU_ERR_RANGE, "%s: \"%s\" = %g is outside [%g, %g]", where, key, kv->v[0], lo, hi);
    *out = kv->v[0];
    return LU_OK;
}

lu_result lu_kv_vec3(const lu_kvlist *list, const char *key, const double def[3], double out[3], const char *where,
                     lu_error *err) {
    const lu_kv *kv = lu_kv_find(list, key);
    if (!kv) {
        for (int i = 0; i < 3; i++) out[i] = def[i];
        return LU_OK;
    }
    if (kv->count == 1) {
        for (int i = 0; i < 3; i++) out[i] = kv->v[0];
        return LU_OK;
    }
    if (kv->count != 3) return lu_fail(err, LU_ERR_SCENE, "%s: \"%s\" must be a number or 3 numbers", where, key);
    for (int i = 0; i < 3; i++) out[i] = kv->v[i];
    return LU_OK;
}

lu_result lu_kv_check_known(const lu_kvlist *list, const char *const *known, const char *where, lu_error *err) {
    if (!list) return LU_OK;
    for (int i = 0; i < list->count; i++) {
        bool found = false;
        for (const char *const *k = known; *k; k++)
            if (strcmp(*k, list->items[i].key) == 0) found = true;
        if (!found) {
            char names[512] = "";
            size_t used = 0;
            for (const char *const *k = known; *k && used + 1 < sizeof names; k++)
                used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", used ? ", " : "", *k);
            return lu_fail(err, LU_ERR_SCENE, "%s: unknown parameter \"%s\" (known: %s)", where, list->items[i].key,
                           names[0] ? names : "none");
        }
    }
    return LU_OK;
}
