/* The CLI is the one reader of lucent's environment variables: it turns them
 * into the library's lu_host (the library itself reads none). */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static bool env_on(const char *name) {
    const char *v = getenv(name);
    return v && *v && strcmp(v, "0") != 0;
}

bool lu_cli_threads_from_env;

int lu_cli_host_from_env(void) {
    lu_host host = {0};
    lu_error err = {0};
    /* A bad value the library would never see is still a mistake worth
     * stopping for. */
    const char *threads = getenv("LUCENT_THREADS");
    if (threads && *threads && lu_thread_count_parse(threads, "LUCENT_THREADS", &host.threads, &err) != LU_OK) {
        fprintf(stderr, "lucent: error: %s\n", err.message);
        return LU_EXIT_USAGE;
    }
    lu_cli_threads_from_env = threads && *threads;
    char cache[1024];
    if (lu_cache_dir_conventional(getenv("LUCENT_CACHE_DIR"), getenv("XDG_CACHE_HOME"), getenv("HOME"), cache,
                                  sizeof cache, NULL) == LU_OK)
        host.cache_dir = cache;   /* none of the three: no disk cache */
    host.quiet = env_on("LUCENT_QUIET");
    /* LUCENT_DDOD_DEBUG and LUCENT_GRADIENT_STATS are the older names of LUCENT_DEBUG. */
    host.debug = env_on("LUCENT_DEBUG") || env_on("LUCENT_DDOD_DEBUG") || env_on("LUCENT_GRADIENT_STATS");
    const char *gpu = getenv("LUCENT_GPU");
    if (gpu && *gpu) {
        if (strcmp(gpu, "hardware") == 0) host.gpu = LU_GPU_CHOICE_HARDWARE;
        else if (strcmp(gpu, "software") == 0) host.gpu = LU_GPU_CHOICE_SOFTWARE;
        else if (strcmp(gpu, "auto") != 0) {
            fprintf(stderr, "lucent: error: gpu: LUCENT_GPU=\"%.40s\" (expected auto, hardware or software)\n", gpu);
            return LU_EXIT_FAIL;
        }
    }
    const char *dev = getenv("LUCENT_GPU_DEVICE");
    if (dev && *dev) {
        char *end;
        long v = strtol(dev, &end, 10);
        if (*end || v < 0 || v > 15) {
            fprintf(stderr, "lucent: error: gpu: LUCENT_GPU_DEVICE=\"%.40s\" (expected 0 to 15)\n", dev);
            return LU_EXIT_FAIL;
        }
        host.gpu_device_only = true;
        host.gpu_device = (int)v;
    }
    /* The program .vdb input runs (lu_host.vdb_converter); unset: the
     * library's search beside this executable and in libexec/lucent. */
    const char *conv = getenv("LUCENT_VDB_CONVERTER");
    if (conv && *conv) host.vdb_converter = conv;
    if (lu_host_set(&host, &err) != LU_OK) {
        fprintf(stderr, "lucent: error: %s\n", err.message);
        return LU_EXIT_USAGE;
    }
    return LU_EXIT_OK;
}
