/* The meaning of LU_BACKEND_AUTO, decided in one place for the library and
 * every command: a hardware GPU when there is one, otherwise the CPU. */
#include <lucent/lucent.h>

#include <pthread.h>

#include "backends/gpu.h"

const char *lu_backend_name(lu_backend b) {
    return b == LU_BACKEND_GPU ? "gpu" : b == LU_BACKEND_CPU ? "cpu" : "auto";
}

static pthread_once_t g_auto_once = PTHREAD_ONCE_INIT;
static lu_backend g_auto = LU_BACKEND_CPU;
static char g_auto_why[400];

static void decide_auto(void) {
    g_auto = lu_gpu_hardware_probe(g_auto_why, sizeof g_auto_why) ? LU_BACKEND_GPU : LU_BACKEND_CPU;
}

lu_backend lu_backend_auto(const char **why) {
    pthread_once(&g_auto_once, decide_auto);
    if (why) *why = g_auto_why;
    return g_auto;
}

lu_backend lu_backend_resolve(lu_backend b, const lu_method *m) {
    if (b != LU_BACKEND_AUTO) return b;
    if (!m || !(m->backends & LU_BACKEND_GPU)) return LU_BACKEND_CPU;
    return lu_backend_auto(NULL);
}
