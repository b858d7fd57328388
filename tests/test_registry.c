/* The method registry: parameter resolution with presets. A preset replaces
 * the defaults, an explicit setting overrides the preset, and an unknown
 * preset is an error naming the ones there are. */
#include <lucent/lucent.h>

#include <string.h>

#include "lu_test.h"

static int param_index(const lu_method *m, const char *name) {
    for (int i = 0; i < m->param_count; i++)
        if (strcmp(m->params[i].name, name) == 0) return i;
    return -1;
}

static void test_presets(void) {
    const lu_method *m = lu_method_find("afm");
    CHECK(m && m->preset_count >= 1);
    if (!m) return;
    int steps = param_index(m, "steps"), res = param_index(m, "map_res"), coefs = param_index(m, "coefs");
    CHECK(steps >= 0 && res >= 0 && coefs >= 0);
    double v[LU_MAX_PARAMS];
    lu_error err = {0};
    lu_kvlist kv = {0};
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == m->params[steps].def && v[res] == m->params[res].def);

    lu_test_settings(&kv, "afm.preset=paper");
    CHECK_OK(lu_settings_validate(&kv, &err), &err);
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == 500 && v[res] == 1024 && v[coefs] == 16);
    lu_kv_free(&kv);

    /* explicit settings win, before or after the preset */
    lu_test_settings(&kv, "afm.steps=64 afm.preset=paper");
    CHECK_OK(lu_method_resolve_params(m, &kv, v, &err), &err);
    CHECK(v[steps] == 64 && v[res] == 1024);
    lu_kv_free(&kv);

    lu_test_settings(&kv, "afm.preset=fastest");
    CHECK(lu_settings_validate(&kv, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "fastest") && strstr(err.message, "paper"), "%s", err.message);
    CHECK(lu_method_resolve_params(m, &kv, v, &err) == LU_ERR_RANGE);
    lu_kv_free(&kv);

    /* a method without presets refuses any */
    lu_test_settings(&kv, "reference.preset=paper");
    CHECK(lu_settings_validate(&kv, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "none") != NULL, "%s", err.message);
    lu_kv_free(&kv);
}

int main(void) {
    RUN_TEST(test_presets);
    TEST_EXIT();
}
