/* Headless OpenGL 4.5 core context through EGL: enumerate EGL devices
 * (EGL_EXT_device_enumeration + EGL_EXT_platform_device), prefer hardware
 * ones, fall back to Mesa's surfaceless platform; GL entry points via libepoxy.
 * lu_gpu_hardware_probe answers, for LU_BACKEND_AUTO, whether a hardware
 * device is there, from the same candidate list. */
#ifdef LU_HAVE_GPU
#include "backends/gpu/gpu_internal.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef EGL_RENDERER_EXT
#define EGL_RENDERER_EXT 0x335F   /* EGL_EXT_device_query_name */
#endif

#define LU_GPU_MAX_DEVICES 16

static const char *egl_error_name(EGLint e) {
    switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "unknown EGL error";
    }
}

static bool has_ext(const char *list, const char *name) {
    if (!list) return false;
    size_t n = strlen(name);
    for (const char *p = list; (p = strstr(p, name)) != NULL; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

static bool renderer_is_software(const char *r) {
    return strstr(r, "llvmpipe") || strstr(r, "softpipe") || strstr(r, "swrast") || strstr(r, "SwiftShader") ||
           strstr(r, "Software Rasterizer");
}

/* ---- EGL displays are process-wide singletons per (platform, device),
 * shared by every context on them. They are initialised once and never
 * terminated: eglTerminate would pull a display from under other contexts and
 * unload the driver (the next create pays its load again, tens of ms for
 * llvmpipe), and Mesa 22.3's swrast_dri.so leaks 128 bytes per load/unload
 * cycle (LeakSanitizer, "<unknown module>"). eglInitialize on an initialised
 * display is a no-op, so no bookkeeping is needed. */

static bool display_init(EGLDisplay dpy, char *why, size_t why_size) {
    EGLint major = 0, minor = 0;
    if (eglInitialize(dpy, &major, &minor)) return true;
    snprintf(why, why_size, "eglInitialize failed (%s)", egl_error_name(eglGetError()));
    return false;
}

/* ---- candidates ------------------------------------------------------------ */

typedef struct candidate {
    EGLenum platform;
    void *native;
    bool software_device;
    char desc[200];
} candidate;

static void describe_device(EGLDeviceEXT dev, int index, bool *software, char *out, size_t out_size) {
    const char *ext = eglQueryDeviceStringEXT(dev, EGL_EXTENSIONS);
    if (!ext) eglGetError();
    *software = has_ext(ext, "EGL_MESA_device_software");
    int n = snprintf(out, out_size, "EGL device %d (%s", index,
                     *software ? "software: EGL_MESA_device_software" : "hardware");
    if (has_ext(ext, "EGL_EXT_device_drm")) {
        const char *file = eglQueryDeviceStringEXT(dev, EGL_DRM_DEVICE_FILE_EXT);
        if (file && n >= 0 && (size_t)n < out_size) n += snprintf(out + n, out_size - (size_t)n, ", %s", file);
        else eglGetError();
    }
    if (has_ext(ext, "EGL_EXT_device_query_name")) {
        const char *vendor = eglQueryDeviceStringEXT(dev, EGL_VENDOR);
        const char *renderer = eglQueryDeviceStringEXT(dev, EGL_RENDERER_EXT);
        if (vendor && renderer && n >= 0 && (size_t)n < out_size)
            n += snprintf(out + n, out_size - (size_t)n, ", %s %s", vendor, renderer);
        else eglGetError();
    }
    if (n >= 0 && (size_t)n < out_size) snprintf(out + n, out_size - (size_t)n, ")");
}

/* The GL version a display does offer, for the error when 4.5 core is not. */
static void probe_version(EGLDisplay dpy, EGLConfig cfg, char *out, size_t out_size) {
    static const EGLint core32[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 2,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                    EGL_NONE};
    static const EGLint any[] = {EGL_NONE};
    const EGLint *tries[2] = {core32, any};
    snprintf(out, out_size, "no OpenGL context of any version");
    for (int i = 0; i < 2; i++) {
        EGLContext c = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, tries[i]);
        if (c == EGL_NO_CONTEXT) {
            eglGetError();
            continue;
        }
        if (eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
            const char *v = (const char *)glGetString(GL_VERSION);
            snprintf(out, out_size, "the display offers OpenGL \"%s\"%s", v ? v : "?",
                     i == 0 ? " (core profile)" : "");
            eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        }
        eglDestroyContext(dpy, c);
        return;
    }
}

static void copy_gl_string(GLenum name, char *out, size_t out_size) {
    const char *s = (const char *)glGetString(name);
    snprintf(out, out_size, "%s", s ? s : "");
}

void lu_gpu_query_info(lu_gpu_info *info) {
    copy_gl_string(GL_VENDOR, info->vendor, sizeof info->vendor);
    copy_gl_string(GL_RENDERER, info->renderer, sizeof info->renderer);
    copy_gl_string(GL_VERSION, info->version, sizeof info->version);
    copy_gl_string(GL_SHADING_LANGUAGE_VERSION, info->glsl_version, sizeof info->glsl_version);
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &info->max_3d_texture_size);
    GLint64 ssbo = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &ssbo);
    info->max_ssbo_size = ssbo;
    glGetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &info->max_ssbo_bindings);
    for (GLuint i = 0; i < 3; i++) {
        glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, i, &info->max_work_group_count[i]);
        glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_SIZE, i, &info->max_work_group_size[i]);
    }
    glGetIntegerv(GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS, &info->max_work_group_invocations);
    glGetIntegerv(GL_MAX_COMPUTE_SHARED_MEMORY_SIZE, &info->max_shared_memory);
    glGetIntegerv(GL_MAX_IMAGE_UNITS, &info->max_image_units);
    glGetIntegerv(GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS, &info->max_texture_units);
    while (glGetError() != GL_NO_ERROR) {
    }
}

/* Tries one candidate; on success ctx->display/context are set and current. */
static bool try_candidate(const candidate *cand, lu_gpu_device_pref pref, lu_gpu_context *ctx, char *why,
                          size_t why_size) {
    EGLDisplay dpy = eglGetPlatformDisplayEXT(cand->platform, cand->native, NULL);
    if (dpy == EGL_NO_DISPLAY) {
        snprintf(why, why_size, "no EGL display (eglGetPlatformDisplayEXT: %s)", egl_error_name(eglGetError()));
        return false;
    }
    if (!display_init(dpy, why, why_size)) return false;
    const char *dext = eglQueryString(dpy, EGL_EXTENSIONS);
    const char *egl_version = eglQueryString(dpy, EGL_VERSION);
    bool egl15 = egl_version && (egl_version[0] > '1' || (egl_version[0] == '1' && egl_version[2] >= '5'));
    EGLContext c = EGL_NO_CONTEXT;
    if (!egl15 && !has_ext(dext, "EGL_KHR_create_context")) {
        snprintf(why, why_size, "EGL %s without EGL_KHR_create_context", egl_version ? egl_version : "?");
        goto fail;
    }
    if (!has_ext(dext, "EGL_KHR_surfaceless_context")) {
        snprintf(why, why_size, "display lacks EGL_KHR_surfaceless_context");
        goto fail;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        snprintf(why, why_size, "eglBindAPI(EGL_OPENGL_API) failed (%s): no desktop OpenGL",
                 egl_error_name(eglGetError()));
        goto fail;
    }
    EGLConfig cfg = EGL_NO_CONFIG_KHR;
    if (!has_ext(dext, "EGL_KHR_no_config_context")) {
        /* surface type 0: no surface will ever be made, any config will do */
        static const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
        EGLint n = 0;
        if (!eglChooseConfig(dpy, want, &cfg, 1, &n) || n < 1) {
            snprintf(why, why_size, "no EGL config with EGL_OPENGL_BIT (%s)", egl_error_name(eglGetError()));
            goto fail;
        }
    }
    static const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                     EGL_NONE};
    c = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, attribs);
    if (c == EGL_NO_CONTEXT) {
        const char *e = egl_error_name(eglGetError());
        char avail[160];
        probe_version(dpy, cfg, avail, sizeof avail);
        snprintf(why, why_size, "no OpenGL 4.5 core context (eglCreateContext: %s); %s", e, avail);
        goto fail;
    }
    if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
        snprintf(why, why_size, "eglMakeCurrent without a surface failed (%s)", egl_error_name(eglGetError()));
        goto fail;
    }
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    const char *renderer = (const char *)glGetString(GL_RENDERER);
    if (!renderer) renderer = "";
    if (major * 10 + minor < 45) {
        snprintf(why, why_size, "context reports OpenGL %d.%d, need 4.5", (int)major, (int)minor);
        goto fail_current;
    }
    bool software = cand->software_device || renderer_is_software(renderer);
    if (pref == LU_GPU_HARDWARE && software) {
        snprintf(why, why_size, "renderer \"%s\" is a software rasteriser (hardware requested)", renderer);
        goto fail_current;
    }
    if (pref == LU_GPU_SOFTWARE && !software) {
        snprintf(why, why_size, "renderer \"%s\" is hardware (software requested)", renderer);
        goto fail_current;
    }
    ctx->display = dpy;
    ctx->context = c;
    ctx->info.is_software = software;
    return true;

fail_current:
    eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
fail:
    if (c != EGL_NO_CONTEXT) eglDestroyContext(dpy, c);
    return false;
}

static void append(char *out, size_t out_size, const char *fmt, const char *a, const char *b) {
    size_t len = strlen(out);
    if (len + 1 < out_size) snprintf(out + len, out_size - len, fmt, a, b);
}

/* The host's GPU choice (the CLI's LUCENT_GPU) narrows an automatic choice
 * (methods create AUTO contexts), so a user can insist on the hardware device
 * or on llvmpipe. */
static lu_result env_preference(lu_gpu_device_pref *pref, lu_error *err) {
    lu_host host;
    lu_host_get(&host);
    if (*pref != LU_GPU_AUTO) return LU_OK;
    if (host.gpu == LU_GPU_CHOICE_HARDWARE) *pref = LU_GPU_HARDWARE;
    else if (host.gpu == LU_GPU_CHOICE_SOFTWARE) *pref = LU_GPU_SOFTWARE;
    return LU_OK;
}

/* EGL's client extensions, after checking that a GL library can be loaded:
 * libepoxy exits the process if it cannot dlopen one when the first GL
 * function is resolved, so this is an error instead. */
static lu_result egl_client(const char **client, lu_error *err) {
    void *gl = dlopen("libOpenGL.so.0", RTLD_LAZY | RTLD_LOCAL);
    if (!gl) gl = dlopen("libGL.so.1", RTLD_LAZY | RTLD_LOCAL);
    if (!gl) return lu_fail(err, LU_ERR_BACKEND, "gpu: neither libOpenGL.so.0 nor libGL.so.1 can be loaded");
    dlclose(gl);
    *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!*client) {
        eglGetError();
        return lu_fail(err, LU_ERR_BACKEND,
                       "gpu: no EGL display: EGL has no client extensions (EGL_EXT_client_extensions), "
                       "so no platform display can be made");
    }
    if (!has_ext(*client, "EGL_EXT_platform_base"))
        return lu_fail(err, LU_ERR_BACKEND,
                       "gpu: no EGL display: EGL lacks EGL_EXT_platform_base (no EGL driver installed, "
                       "e.g. libegl-mesa0?)");
    return LU_OK;
}

/* The candidates a context of preference pref tries, in order: hardware EGL
 * devices, software ones, then Mesa's surfaceless platform. LUCENT_GPU_DEVICE=N
 * keeps only EGL device N (as `lucent info --gpu` lists them), for machines
 * with several GPUs. *enumerated: EGL listed its devices. */
typedef struct candidate_list {
    candidate c[LU_GPU_MAX_DEVICES + 1];
    int count;
    bool enumerated;
    char device_list[sizeof ((lu_gpu_info *)0)->device_list];
} candidate_list;

static lu_result list_candidates(const char *client, lu_gpu_device_pref pref, candidate_list *out, lu_error *err) {
    out->count = 0;
    out->enumerated = false;
    out->device_list[0] = '\0';
    int only = -1;
    lu_host host;
    lu_host_get(&host);
    if (host.gpu_device_only) {
        if (host.gpu_device < 0 || host.gpu_device >= LU_GPU_MAX_DEVICES)
            return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: device %d (expected 0 to %d)", host.gpu_device,
                           LU_GPU_MAX_DEVICES - 1);
        only = host.gpu_device;
    }
    bool can_enumerate = has_ext(client, "EGL_EXT_device_enumeration") || has_ext(client, "EGL_EXT_device_base");
    if (can_enumerate && has_ext(client, "EGL_EXT_platform_device")) {
        EGLDeviceEXT devs[LU_GPU_MAX_DEVICES];
        EGLint ndev = 0;
        if (!eglQueryDevicesEXT(LU_GPU_MAX_DEVICES, devs, &ndev)) {
            eglGetError();
            ndev = 0;
        }
        out->enumerated = true;
        candidate hw[LU_GPU_MAX_DEVICES], sw[LU_GPU_MAX_DEVICES];
        int nhw = 0, nsw = 0;
        for (int i = 0; i < ndev; i++) {
            candidate c = {EGL_PLATFORM_DEVICE_EXT, devs[i], false, ""};
            describe_device(devs[i], i, &c.software_device, c.desc, sizeof c.desc);
            append(out->device_list, sizeof out->device_list, "%s%s", out->device_list[0] ? "; " : "", c.desc);
            if (only >= 0 && i != only) continue;
            if (c.software_device) sw[nsw++] = c;
            else hw[nhw++] = c;
        }
        if (only >= ndev)
            return lu_fail(err, LU_ERR_BACKEND, "gpu: LUCENT_GPU_DEVICE=%d but there are %d EGL devices (%.300s)",
                           only, (int)ndev, ndev ? out->device_list : "none");
        if (pref != LU_GPU_SOFTWARE)
            for (int i = 0; i < nhw; i++) out->c[out->count++] = hw[i];
        if (pref != LU_GPU_HARDWARE)
            for (int i = 0; i < nsw; i++) out->c[out->count++] = sw[i];
        if (ndev == 0) snprintf(out->device_list, sizeof out->device_list, "(no EGL devices)");
    } else {
        snprintf(out->device_list, sizeof out->device_list,
                 "(EGL_EXT_device_enumeration/EGL_EXT_platform_device not available)");
    }
    if (only >= 0 && !can_enumerate)
        return lu_fail(err, LU_ERR_BACKEND, "gpu: LUCENT_GPU_DEVICE is set but EGL cannot enumerate devices");
    if (only < 0 && has_ext(client, "EGL_MESA_platform_surfaceless")) {
        candidate c = {EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, false, "EGL_PLATFORM_SURFACELESS_MESA"};
        out->c[out->count++] = c;
    }
    return LU_OK;
}

/* One device per preference serves every renderer of the process: the first
 * create makes its context, later ones share it (GL objects of one renderer
 * never meet another's, so sharing names is safe), the last destroy frees it.
 * g_devices_mu guards the table; g_serial serialises every use (below). */
static lu_gpu_context *g_devices[3];
static pthread_mutex_t g_devices_mu = PTHREAD_MUTEX_INITIALIZER;

static lu_result context_create(lu_gpu_context **out, lu_gpu_device_pref pref, lu_error *err);

static atomic_int g_fault;        /* lu_gpu_fault */
static atomic_int g_fault_after;  /* LOSE: GL checks left before the loss */
static _Thread_local lu_gpu_context *t_bound; /* the device this thread's GL calls go to */

void lu_gpu_fault_inject(lu_gpu_fault fault, int after) {
    atomic_store(&g_fault_after, after > 0 ? after : 1);
    atomic_store(&g_fault, (int)fault);
}

/* Marks the device this thread uses lost and takes it out of the table, so
 * the next create makes a fresh one; whoever holds the lost one keeps the
 * reference until they destroy it, and every call on it fails. */
static void mark_bound_lost(void) {
    lu_gpu_context *ctx = t_bound;
    if (!ctx) return;
    pthread_mutex_lock(&g_devices_mu);
    ctx->lost = true;
    if (g_devices[ctx->slot] == ctx) g_devices[ctx->slot] = NULL;
    pthread_mutex_unlock(&g_devices_mu);
}

lu_result lu_gpu_context_create(lu_gpu_context **out, lu_gpu_device_pref pref, lu_error *err) {
    *out = NULL;
    if (pref != LU_GPU_AUTO && pref != LU_GPU_HARDWARE && pref != LU_GPU_SOFTWARE)
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: unknown device preference %d", (int)pref);
    lu_gpu_context *caller = lu_gpu_caller_in_use();
    if (caller) {
        /* A renderer that works in the caller's context: every GPU object it
         * makes lives there (lu_gpu_caller_use). */
        pthread_mutex_lock(&g_devices_mu);
        caller->refs++;
        pthread_mutex_unlock(&g_devices_mu);
        *out = caller;
        return LU_OK;
    }
    lu_result r = env_preference(&pref, err);
    if (r != LU_OK) return r;
    pthread_mutex_lock(&g_devices_mu);
    lu_gpu_context *ctx = g_devices[pref];
    if (ctx) {
        ctx->refs++;
    } else {
        /* The device serves every renderer of the process: none is charged for it. */
        lu_mem_account *renderer = lu_mem_account_use(NULL);
        r = context_create(&ctx, pref, err);
        lu_mem_account_use(renderer);
        if (r == LU_OK) {
            ctx->refs = 1;
            ctx->slot = (int)pref;
            g_devices[pref] = ctx;
        }
    }
    pthread_mutex_unlock(&g_devices_mu);
    if (r == LU_OK) *out = ctx;
    return r;
}

static lu_result context_create(lu_gpu_context **out, lu_gpu_device_pref pref, lu_error *err) {
    *out = NULL;
    if (atomic_load(&g_fault) == LU_GPU_FAULT_CREATE)
        return lu_fail(err, LU_ERR_BACKEND, "gpu: no OpenGL 4.5 context could be created (injected fault)");
    double t0 = lu_time_seconds();
    const char *client = NULL;
    lu_result r = egl_client(&client, err);
    if (r != LU_OK) return r;
    candidate_list *cands = lu_malloc(sizeof *cands);
    lu_gpu_context *ctx = lu_calloc(1, sizeof *ctx);
    if (!cands || !ctx) {
        lu_free(cands);
        lu_free(ctx);
        return lu_fail(err, LU_ERR_NOMEM, "gpu: out of memory");
    }
    r = list_candidates(client, pref, cands, err);
    if (r != LU_OK) {
        lu_free(cands);
        lu_free(ctx);
        return r;
    }
    memcpy(ctx->info.device_list, cands->device_list, sizeof ctx->info.device_list);

    static const char *const pref_names[] = {"auto", "hardware", "software"};
    char tried[640] = "";
    for (int i = 0; i < cands->count; i++) {
        char why[320];
        if (try_candidate(&cands->c[i], pref, ctx, why, sizeof why)) {
            lu_gpu_info *info = &ctx->info;
            snprintf(info->egl_path, sizeof info->egl_path, "%s",
                     cands->c[i].platform == EGL_PLATFORM_DEVICE_EXT ? "device" : "surfaceless");
            snprintf(info->device, sizeof info->device, "%s", cands->c[i].desc);
            lu_gpu_query_info(info);
            if (renderer_is_software(info->renderer)) info->is_software = true;
            info->loop_cap = strstr(info->renderer, "llvmpipe") != NULL;
            info->create_seconds = lu_time_seconds() - t0;
            lu_free(cands);
            *out = ctx;
            return LU_OK;
        }
        append(tried, sizeof tried, "%s%s", tried[0] ? "; " : "", cands->c[i].desc);
        append(tried, sizeof tried, ": %s%s", why, "");
    }
    int ncand = cands->count;
    char device_list[sizeof cands->device_list];
    memcpy(device_list, cands->device_list, sizeof device_list);
    lu_free(cands);
    lu_free(ctx);
    if (ncand == 0)
        return lu_fail(err, LU_ERR_BACKEND,
                       "gpu: no EGL display: no EGL device for preference %s (devices: %.300s) and no "
                       "EGL_MESA_platform_surfaceless (client extensions: %.250s)",
                       pref_names[pref], device_list, client);
    return lu_fail(err, LU_ERR_BACKEND, "gpu: no usable OpenGL 4.5 core context (preference %s): %s",
                   pref_names[pref], tried);
}

bool lu_gpu_hardware_probe(char *why, size_t why_size) {
    lu_gpu_device_pref pref = LU_GPU_AUTO;
    const char *client = NULL;
    lu_error err = {0};
    if (env_preference(&pref, &err) != LU_OK || egl_client(&client, &err) != LU_OK) {
        snprintf(why, why_size, "%s", err.message);
        return false;
    }
    if (pref == LU_GPU_SOFTWARE) {
        snprintf(why, why_size, "LUCENT_GPU=software");
        return false;
    }
    candidate_list *cands = lu_malloc(sizeof *cands);
    if (!cands) {
        snprintf(why, why_size, "out of memory");
        return false;
    }
    if (list_candidates(client, LU_GPU_HARDWARE, cands, &err) != LU_OK) {
        snprintf(why, why_size, "%s", err.message);
        lu_free(cands);
        return false;
    }
    /* The probe must leave the caller's EGL state as it was (a viewer's
     * window context may be current). */
    EGLenum api = eglQueryAPI();
    EGLDisplay cur_dpy = eglGetCurrentDisplay();
    EGLContext cur_ctx = eglGetCurrentContext();
    EGLSurface cur_draw = eglGetCurrentSurface(EGL_DRAW), cur_read = eglGetCurrentSurface(EGL_READ);
    bool found = false;
    char tried[400] = "";
    for (int i = 0; i < cands->count && !found; i++) {
        /* Where EGL lists its devices, the surfaceless platform reaches one of
         * them or llvmpipe: skipping it means a machine without a hardware
         * device loads no driver at all for this question. */
        if (cands->enumerated && cands->c[i].platform == EGL_PLATFORM_SURFACELESS_MESA) continue;
        lu_gpu_context probe = {0};
        char reason[320];
        if (try_candidate(&cands->c[i], LU_GPU_HARDWARE, &probe, reason, sizeof reason)) {
            eglMakeCurrent(probe.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
            eglDestroyContext(probe.display, probe.context);
            snprintf(why, why_size, "%s", cands->c[i].desc);
            found = true;
        } else {
            append(tried, sizeof tried, "%s%s", tried[0] ? "; " : "", cands->c[i].desc);
            append(tried, sizeof tried, ": %s%s", reason, "");
        }
    }
    if (!found)
        snprintf(why, why_size, "%s%.300s", tried[0] ? "tried " : "EGL devices: ",
                 tried[0] ? tried : cands->device_list);
    lu_free(cands);
    if (cur_ctx != EGL_NO_CONTEXT) {
        eglBindAPI(api);
        eglMakeCurrent(cur_dpy, cur_draw, cur_read, cur_ctx);
    } else if (found) {
        eglReleaseThread();
    }
    return found;
}

void lu_gpu_context_destroy(lu_gpu_context *ctx) {
    if (!ctx) return;
    pthread_mutex_lock(&g_devices_mu);
    bool last = --ctx->refs == 0;
    if (last && !ctx->caller && g_devices[ctx->slot] == ctx) g_devices[ctx->slot] = NULL;
    pthread_mutex_unlock(&g_devices_mu);
    if (!last) return;
    if (ctx->caller) {
        lu_gpu_caller_release(ctx);
        return;
    }
    if (eglGetCurrentContext() == ctx->context)
        eglMakeCurrent(ctx->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(ctx->display, ctx->context);
    /* frees this thread's EGL state once nothing is current on it */
    if (eglGetCurrentContext() == EGL_NO_CONTEXT) eglReleaseThread();
    lu_free(ctx);
}

void lu_gpu_info_get(const lu_gpu_context *ctx, lu_gpu_info *out) { *out = ctx->info; }

/* A GL context is current on one thread at a time, and the devices are
 * shared: every GPU renderer's prepare, render and destroy runs under this
 * one lock (recursive: a render may create or destroy inside), and leaves no
 * lucent context current, so the next thread can make it its own. */
static pthread_mutex_t g_serial;
static pthread_once_t g_serial_once = PTHREAD_ONCE_INIT;

static void serial_init(void) {
    pthread_mutexattr_t a;
    pthread_mutexattr_init(&a);
    pthread_mutexattr_settype(&a, PTHREAD_MUTEX_RECURSIVE);
    pthread_mutex_init(&g_serial, &a);
    pthread_mutexattr_destroy(&a);
}

static _Thread_local int g_serial_depth;

void lu_gpu_serial_enter(void) {
    pthread_once(&g_serial_once, serial_init);
    pthread_mutex_lock(&g_serial);
    g_serial_depth++;
}

void lu_gpu_serial_leave(void) {
    if (--g_serial_depth == 0) {
        pthread_mutex_lock(&g_devices_mu);
        EGLContext cur = eglGetCurrentContext();
        for (int i = 0; i < 3; i++)
            if (g_devices[i] && g_devices[i]->context == cur && cur != EGL_NO_CONTEXT)
                eglMakeCurrent(g_devices[i]->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        pthread_mutex_unlock(&g_devices_mu);
    }
    pthread_mutex_unlock(&g_serial);
}

bool lu_gpu_context_is_current(const lu_gpu_context *ctx) {
    if (ctx && ctx->caller) return lu_gpu_caller_is_current(ctx);
    return ctx && eglGetCurrentContext() == ctx->context;
}

lu_result lu_gpu_bind_context(lu_gpu_context *ctx, lu_error *err) {
    if (!ctx) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu: NULL context");
    if (ctx->lost) return lu_fail(err, LU_ERR_BACKEND, "gpu: the GPU context was lost (a device reset)");
    t_bound = ctx;
    if (ctx->caller) {
        /* Never made current by lucent: it is the caller's to make current. */
        if (lu_gpu_caller_is_current(ctx)) return LU_OK;
        return lu_fail(err, LU_ERR_BACKEND,
                       "gpu: the caller's OpenGL context this renderer was made in is not current on this thread");
    }
    if (eglGetCurrentContext() == ctx->context) return LU_OK;
    if (!eglBindAPI(EGL_OPENGL_API) ||
        !eglMakeCurrent(ctx->display, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx->context))
        return lu_fail(err, LU_ERR_BACKEND,
                       "gpu: cannot make the context current (%s); contexts are used from the thread "
                       "that created them",
                       egl_error_name(eglGetError()));
    return LU_OK;
}

lu_result lu_gpu_make_current(lu_gpu_context *ctx, lu_error *err) { return lu_gpu_bind_context(ctx, err); }

void lu_gpu_finish(lu_gpu_context *ctx) {
    if (lu_gpu_bind_context(ctx, NULL) == LU_OK) glFinish();
}

double lu_gpu_time_begin(lu_gpu_context *ctx) {
    lu_gpu_finish(ctx);
    return lu_time_seconds();
}

double lu_gpu_time_end(lu_gpu_context *ctx, double t0) {
    lu_gpu_finish(ctx);
    return lu_time_seconds() - t0;
}

static const char *gl_error_name(GLenum e) {
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "unknown GL error";
    }
}

lu_result lu_gpu_check_gl(const char *what, lu_error *err) {
    /* A reset shows first: after one, glGetError says nothing useful. */
    GLenum reset = glGetGraphicsResetStatus();
    if (reset == GL_NO_ERROR && atomic_load(&g_fault) == LU_GPU_FAULT_LOSE && atomic_fetch_sub(&g_fault_after, 1) == 1) {
        atomic_store(&g_fault, LU_GPU_FAULT_NONE);
        reset = GL_UNKNOWN_CONTEXT_RESET;
    }
    if (reset != GL_NO_ERROR) {
        mark_bound_lost();
        return lu_fail(err, LU_ERR_BACKEND, "gpu: %s: the GPU context was lost (%s)", what,
                       reset == GL_GUILTY_CONTEXT_RESET     ? "a reset this context caused"
                       : reset == GL_INNOCENT_CONTEXT_RESET ? "a reset another context caused"
                                                            : "a reset of unknown cause");
    }
    GLenum e = glGetError();
    if (e == GL_NO_ERROR) return LU_OK;
    while (glGetError() != GL_NO_ERROR) {
    }
    return lu_fail(err, e == GL_OUT_OF_MEMORY ? LU_ERR_NOMEM : LU_ERR_BACKEND, "gpu: %s: %s (0x%04x)", what,
                   gl_error_name(e), (unsigned)e);
}

#endif
