/* Rendering into the caller's texture (lu_renderer_render_texture with
 * lu_renderer_desc.gl_caller_context): the test plays the embedding
 * program. It makes its own OpenGL 4.5 context (EGL, surfaceless), current
 * on this thread, creates textures in it, and has renderers write frames
 * into them. Each texture, read back, must equal bit for bit the image the
 * same method gives through lu_renderer_render (GPU methods: in lucent's own
 * device context; the same driver runs the same kernels), rows flipped to
 * GL's bottom-to-top order, alpha 1, written on the GPU for GPU methods
 * (lu_renderer_stats.texture_direct) and uploaded for CPU ones; also a second frame after a camera
 * move, through the frame stage's update path. An RGBA16F texture holds the
 * image rounded to half precision. The errors: a texture of the wrong size,
 * a GPU renderer in lucent's own context, a caller's context that is not
 * current. No GPU context: skipped (77). */
#include "lu_test.h"

#ifdef LU_HAVE_GPU
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif

static EGLDisplay g_dpy;
static EGLContext g_ctx;

/* The embedding program's own context. */
static bool own_context(void) {
    g_dpy = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (g_dpy == EGL_NO_DISPLAY || !eglInitialize(g_dpy, NULL, NULL) || !eglBindAPI(EGL_OPENGL_API)) return false;
    static const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    g_ctx = eglCreateContext(g_dpy, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
    return g_ctx != EGL_NO_CONTEXT;
}
static void own_current(void) { eglMakeCurrent(g_dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, g_ctx); }

static GLuint make_texture(GLenum format, int w, int h) {
    GLuint t = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &t);
    glTextureStorage2D(t, 1, format, w, h);
    return t;
}

/* Largest |texture - image| (rows flipped), and whether alpha is 1 everywhere. */
static double texture_diff(GLuint t, const lu_image *img, bool *alpha_one) {
    size_t n = (size_t)img->width * img->height * 4;
    float *px = malloc(n * sizeof *px);
    if (!px) return 1e30;
    glGetTextureImage(t, 0, GL_RGBA, GL_FLOAT, (GLsizei)(n * sizeof *px), px);
    double worst = 0.0;
    *alpha_one = true;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *a = px + ((size_t)(img->height - 1 - y) * img->width + x) * 4;
            const float *b = img->rgb + ((size_t)y * img->width + x) * 3;
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs((double)a[c] - b[c]));
            *alpha_one = *alpha_one && a[3] == 1.0f;
        }
    free(px);
    return worst;
}

static double image_sum(const lu_image *img) {
    double s = 0.0;
    for (size_t i = 0; i < (size_t)img->width * img->height * 3; i++) s += img->rgb[i];
    return s;
}

static void turn_camera(lu_scene *s, float a) {
    lu_vec3 d = lu_v3_sub(s->camera.position, s->camera.look_at);
    float c = cosf(a), sn = sinf(a);
    s->camera.position = lu_v3_add(s->camera.look_at, lu_v3(c * d.x + sn * d.z, d.y, -sn * d.x + c * d.z));
}

/* One method: two frames into a caller's RGBA32F texture against the same
 * two frames through lu_renderer_render on `backend` in lucent's context. */
static void check_method(const char *scene_name, const char *method, const char *setting, lu_backend backend) {
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", scene_name);
    lu_error err = {0};
    lu_scene s;
    CHECK_OK(lu_scene_load(path, &s, &err), &err);
    if (err.code != LU_OK) return;
    s.camera.width = 24;
    s.camera.height = 16;
    lu_vec3 c0 = s.camera.position;
    const char *set[] = {setting, NULL};

    lu_image want[2] = {{0}};
    lu_renderer *plain = NULL;
    lu_renderer_desc pd = {.method = method, .backend = backend, .set = set};
    CHECK_OK(lu_renderer_make(&pd, &s, &plain, &err), &err);
    for (int f = 0; f < 2 && plain; f++) {
        if (f) turn_camera(&s, 0.3f);
        CHECK_OK(lu_renderer_render(plain, &s, &want[f], &err), &err);
    }
    if (plain && backend == LU_BACKEND_GPU) {
        /* lucent's own context cannot write the caller's textures */
        own_current();
        GLuint t = make_texture(GL_RGBA32F, 24, 16);
        CHECK(lu_renderer_render_texture(plain, &s, t, &err) == LU_ERR_UNSUPPORTED);
        glDeleteTextures(1, &t);
    }
    lu_renderer_destroy(plain);
    s.camera.position = c0;

    own_current();
    lu_renderer *r = NULL;
    lu_renderer_desc d = {.method = method, .backend = backend, .set = set, .gl_caller_context = true};
    CHECK_OK(lu_renderer_make(&d, &s, &r, &err), &err);
    GLuint tex = make_texture(GL_RGBA32F, 24, 16);
    for (int f = 0; f < 2 && r && want[f].rgb; f++) {
        if (f) turn_camera(&s, 0.3f);
        CHECK_OK(lu_renderer_render_texture(r, &s, tex, &err), &err);
        bool alpha_one = false;
        double d1 = texture_diff(tex, &want[f], &alpha_one);
        CHECK_MSG(d1 == 0.0, "%s on %s, frame %d: texture differs from the rendered image by %g", method,
                  lu_backend_name(backend), f, d1);
        CHECK_MSG(alpha_one, "%s, frame %d: alpha is not 1", method, f);
        CHECK_MSG(image_sum(&want[f]) > 0.0, "%s, frame %d: the image is black", method, f);
        lu_renderer_stats st;
        CHECK_OK(lu_renderer_get_stats(r, &st, &err), &err);
        CHECK_MSG(st.texture_direct == (backend == LU_BACKEND_GPU), "%s on %s: texture_direct %d", method,
                  lu_backend_name(backend), (int)st.texture_direct);
    }
    if (r && want[1].rgb) {
        /* Half precision: the image rounded to 11 significant bits. */
        GLuint half = make_texture(GL_RGBA16F, 24, 16);
        CHECK_OK(lu_renderer_render_texture(r, &s, half, &err), &err);
        size_t n = (size_t)24 * 16 * 4;
        float *px = malloc(n * sizeof *px);
        glGetTextureImage(half, 0, GL_RGBA, GL_FLOAT, (GLsizei)(n * sizeof *px), px);
        double worst = 0.0;
        for (int y = 0; y < 16; y++)
            for (int x = 0; x < 24; x++)
                for (int c = 0; c < 3; c++) {
                    double a = px[((size_t)(15 - y) * 24 + x) * 4 + c], b = want[1].rgb[((size_t)y * 24 + x) * 3 + c];
                    worst = fmax(worst, fabs(a - b) / fmax(fabs(b), 6.1e-5));
                }
        free(px);
        CHECK_MSG(worst <= 1.0 / 1024.0, "%s: RGBA16F texture off by %g relative (half precision: 2^-11)", method,
                  worst);
        glDeleteTextures(1, &half);

        /* The wrong size is an error naming both sizes. */
        GLuint small = make_texture(GL_RGBA32F, 8, 8);
        CHECK(lu_renderer_render_texture(r, &s, small, &err) == LU_ERR_INVALID_ARG);
        CHECK(strstr(err.message, "8x8") != NULL);
        glDeleteTextures(1, &small);

        /* The caller's context must be current. */
        if (backend == LU_BACKEND_GPU) {
            eglMakeCurrent(g_dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
            CHECK(lu_renderer_render_texture(r, &s, tex, &err) == LU_ERR_BACKEND);
            own_current();
        }
    }
    glDeleteTextures(1, &tex);
    lu_renderer_destroy(r);
    lu_image_destroy(&want[0]);
    lu_image_destroy(&want[1]);
    lu_scene_destroy(&s);
}
#endif

int main(void) {
#ifndef LU_HAVE_GPU
    TEST_EXIT_SKIPPED("built without the GPU backend");
#else
    lu_error err = {0};
    lu_scene s;
    lu_renderer *probe = NULL;
    CHECK_OK(lu_scene_load(LU_SOURCE_DIR "/scenes/smoke_box.json", &s, &err), &err);
    s.camera.width = 8;
    s.camera.height = 8;
    lu_result pr = lu_renderer_create("raymarch", &s, NULL, LU_BACKEND_GPU, &probe, &err);
    lu_renderer_destroy(probe);
    if (pr == LU_ERR_BACKEND) {
        lu_scene_destroy(&s);
        TEST_EXIT_SKIPPED("no GPU context");
    }
    if (!own_context()) {
        lu_scene_destroy(&s);
        TEST_EXIT_SKIPPED("no surfaceless EGL context for the embedding program");
    }
    /* No context current: a caller's-context renderer cannot be made. */
    eglMakeCurrent(g_dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    lu_renderer_desc d = {.method = "raymarch", .backend = LU_BACKEND_GPU, .gl_caller_context = true};
    lu_renderer *r = NULL;
    CHECK(lu_renderer_make(&d, &s, &r, &err) == LU_ERR_BACKEND);
    CHECK(strstr(err.message, "current") != NULL);
    lu_scene_destroy(&s);

    check_method("smoke_box", "raymarch", "raymarch.steps=48", LU_BACKEND_GPU);
    check_method("bssrdf_spheres", "bssrdf", "bssrdf.splats=256", LU_BACKEND_GPU);
    check_method("smoke_box", "raymarch", "raymarch.steps=48", LU_BACKEND_CPU);
    eglMakeCurrent(g_dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(g_dpy, g_ctx);
    TEST_EXIT();
#endif
}
