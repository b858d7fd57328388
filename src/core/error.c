/* Result names and the one formatting path for error messages. */
#include <lucent/core.h>

#include <stdarg.h>
#include <stdio.h>

static const char *const k_names[LU_ERR_COUNT] = {
    [LU_OK] = "LU_OK",
    [LU_ERR_INVALID_ARG] = "LU_ERR_INVALID_ARG",
    [LU_ERR_IO] = "LU_ERR_IO",
    [LU_ERR_FORMAT] = "LU_ERR_FORMAT",
    [LU_ERR_NONFINITE] = "LU_ERR_NONFINITE",
    [LU_ERR_RANGE] = "LU_ERR_RANGE",
    [LU_ERR_LIMIT] = "LU_ERR_LIMIT",
    [LU_ERR_NOMEM] = "LU_ERR_NOMEM",
    [LU_ERR_UNSUPPORTED] = "LU_ERR_UNSUPPORTED",
    [LU_ERR_SCENE] = "LU_ERR_SCENE",
    [LU_ERR_BACKEND] = "LU_ERR_BACKEND",
};

const char *lu_result_name(lu_result r) {
    if ((int)r < 0 || r >= LU_ERR_COUNT) return "LU_ERR_UNKNOWN";
    return k_names[r];
}

lu_result lu_fail(lu_error *err, lu_result code, const char *fmt, ...) {
    if (err) {
        err->code = code;
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}
