/* The host's hooks (lu_host): its settings, the log, and the version query
 * (the allocator's hooks are memory.c's). Set once, before other calls, so
 * the hot paths read the hooks without a lock. */
#include <lucent/core.h>

#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/core_internal.h"
#include "core/memory.h"

static lu_host g_host;
static char g_vdb_converter[1024];   /* the host's vdb_converter, copied ("" = search) */

uint32_t lu_version(void) { return (uint32_t)LU_VERSION; }
const char *lu_version_string(void) { return LU_VERSION_STRING; }

/* ---- the log ----------------------------------------------------------- */

bool lu_log_enabled(lu_log_level level) {
    if (level == LU_LOG_DEBUG) return g_host.debug;
    if (level == LU_LOG_PROGRESS || level == LU_LOG_INFO) return !g_host.quiet;
    return true;
}

void lu_log_msg(lu_log_level level, const char *fmt, ...) {
    if (!lu_log_enabled(level)) return;
    char text[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (g_host.log) {
        g_host.log(level, text, g_host.user);
    } else {
        fputs(text, stderr);
        if (level == LU_LOG_PROGRESS) fflush(stderr);
    }
}

/* ---- lu_host_set ----------------------------------------------------------- */

lu_result lu_host_set(const lu_host *host, lu_error *err) {
    static const lu_host k_default;
    const lu_host *h = host ? host : &k_default;
    lu_result r = lu_mem_allocator_check(h, err);
    if (r != LU_OK) return r;
    if (h->threads < 0 || h->threads > LU_MAX_THREADS)
        return lu_fail(err, LU_ERR_RANGE, "host: threads = %d outside [0, %d] (0 = automatic)", h->threads,
                       LU_MAX_THREADS);
    if (h->gpu != LU_GPU_CHOICE_AUTO && h->gpu != LU_GPU_CHOICE_HARDWARE && h->gpu != LU_GPU_CHOICE_SOFTWARE)
        return lu_fail(err, LU_ERR_INVALID_ARG, "host: gpu = %d is not an lu_gpu_choice", (int)h->gpu);
    if (h->gpu_device_only && (h->gpu_device < 0 || h->gpu_device >= 16))
        return lu_fail(err, LU_ERR_RANGE, "host: gpu_device = %d outside [0, 15]", h->gpu_device);
    if (h->vdb_converter && (!*h->vdb_converter || strlen(h->vdb_converter) >= sizeof g_vdb_converter))
        return lu_fail(err, LU_ERR_INVALID_ARG, "host: vdb_converter must be a path of 1 to %zu bytes",
                       sizeof g_vdb_converter - 1);
    r = lu_set_thread_count(h->threads, err);
    if (r == LU_OK) r = lu_set_cache_dir(h->cache_dir, err);
    if (r != LU_OK) return r;
    lu_mem_set_allocator(h);
    g_host = *h;
    g_host.cache_dir = NULL;   /* the library's copy lives in the cache module */
    snprintf(g_vdb_converter, sizeof g_vdb_converter, "%s", h->vdb_converter ? h->vdb_converter : "");
    g_host.vdb_converter = NULL;
    return LU_OK;
}

void lu_host_get(lu_host *out) {
    *out = g_host;
    out->threads = lu_thread_count();
    out->cache_dir = lu_cache_dir_copy();
    out->vdb_converter = g_vdb_converter[0] ? g_vdb_converter : NULL;
}
