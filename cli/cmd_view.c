/* lucent view SCENE.json — the interactive viewer: a GLFW window showing a
 * method's image, orbit/zoom camera, keys to move the selected light, switch
 * method and change its main quality knob, an on-screen overlay (frame time,
 * fps, method, backend, samples) in the built-in bitmap font
 * (src/viewer/lu_font.h), progressive accumulation for Monte Carlo methods,
 * and --screenshot FILE --frames N for scripted use (tests under Xvfb).
 *
 * A frame budget (--budget, 33 ms): while the user interacts, frames are
 * rendered at a resolution scale chosen from the measured cost of the last
 * frames so that a frame fits the budget, and upsampled bilinearly to the
 * window; when input stops the scale doubles frame by frame back to 1, and
 * that last frame is the method's full image, as `lucent render` gives it.
 * A scene whose media follow time (sequences, an animated plume) plays in
 * real time (Space), steps a frame at a time (, and .) and shows its time
 * and frame in the overlay.
 * --script orbit|light|play --frames N --stats FILE.csv plays a scripted
 * interaction and records every frame (ms, scale, rel-L2 of the frames that
 * show the final view against a fresh renderer's full image of it).
 *
 * A CPU method's image is tone mapped exactly as `lucent render -o x.png`
 * does (sRGB curve after 2^exposure), overlaid, and drawn with glDrawPixels
 * into the window's own context. A GPU method works in the window's context
 * itself (lu_renderer_desc.gl_caller_context) and renders into a texture
 * there (lu_renderer_render_texture), which a fragment shader tone maps the
 * same way: its frames never pass through CPU memory, except to measure
 * them (the live error, --stats); --readback sends them through the CPU as
 * before. The screenshot is read back from the window (glReadPixels), so
 * it shows what the window showed.
 * Over 800 lines: one interactive loop and the state it drives (the budget,
 * refinement, the overlay, the live error, scripts, --stats, time). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "view_script.h"
#include "viewer/lu_font.h"

static void usage(void) {
    printf("usage: lucent view SCENE.json [options]\n"
           "\n"
           "options:\n"
           "  --method M          method shown first (default: raymarch; Tab cycles through all)\n"
           "  --backend cpu|gpu|auto  where methods run (default: auto: a hardware GPU when there\n"
           "                      is one, else the CPU; gpu forces the GPU backend, llvmpipe\n"
           "                      included; a method without a GPU path runs on the CPU);\n"
           "                      LUCENT_GPU=auto|hardware|software picks the GPU device\n"
           "  --budget MS         frame budget while interacting (default 33): frames are\n"
           "                      rendered at a reduced resolution that fits it and upsampled\n"
           "                      (bilinear); when input stops the resolution doubles per frame\n"
           "                      back to full, which is the image `lucent render` gives\n"
           "  --moving-set M.P=V  settings of the frames rendered while moving (repeatable;\n"
           "                      default afm.map_res=64 afm.samples=16 afm.steps=100; `none`\n"
           "                      drops the defaults); after the resolution, the quality\n"
           "                      refines to --set's\n"
           "  --set M.P=V         method parameters, as for render (repeatable)\n"
           "  --size WxH          image and window size (default: the scene camera's)\n"
           "  --exposure E        scale by 2^E before the sRGB curve (default 0)\n"
           "  --no-overlay        start with the overlay hidden\n"
           "  --readback          GPU methods render in their own context and their frames go through\n"
           "                      CPU memory to the window (default: into a texture of the window's)\n"
           "  --compare           render the reference first (as key C does)\n"
           "  --screenshot FILE   render --frames frames, save the window's last frame (PNG), exit\n"
           "                      (with --script: after the settle)\n"
           "  --frames N          frames to render with --screenshot (default 1), or the\n"
           "                      scripted frames with --script (default 8)\n"
           "  --time T            start at time T seconds (default: the scene's \"time\")\n"
           "  --script orbit|light|play|soak  play a scripted interaction and exit: each frame the\n"
           "                      camera (orbit) or the first light (light) turns 4 degrees\n"
           "                      about the camera's up axis through its look-at point, or the\n"
           "                      scene's time advances one frame, 1/fps (play); soak: both\n"
           "                      turns, the next method every 20 frames and a window resize\n"
           "                      every 60 (with --stats: resident memory per frame); after the N\n"
           "                      frames it renders with no input until the full image is\n"
           "                      shown (at most 60 s), then prints a summary line\n"
           "  --stats FILE.csv    one row per frame: frame,ms,scale,rel_l2,rss_kb,held_kb (frame 0:\n"
           "                      the start view; rel_l2: of the frames showing the final view,\n"
           "                      against a fresh renderer's full image of it; empty for the\n"
           "                      others; held_kb: what the renderer holds, GPU included)\n"
           "\n"
           "controls:\n"
           "  left drag           orbit the camera around its look-at point\n"
           "  wheel, PgUp/PgDn    zoom (move the camera along its view direction)\n"
           "  right drag, arrows  move the selected light around the look-at point\n"
           "                      (directional lights: turn the direction)\n"
           "  L                   select the next light\n"
           "  Tab / Shift+Tab     next / previous method\n"
           "  + / -               double / halve the method's main quality knob\n"
           "                      (raymarch.steps, bssrdf.splats, reference.steps, pathtrace: passes)\n"
           "  E / D               exposure up / down by 1/2 stop\n"
           "  C                   render the reference for this view; the overlay then shows\n"
           "                      the live rel-L2 of each frame against it (until the view\n"
           "                      or a light changes)\n"
           "  H                   show / hide the overlay\n"
           "  R                   reset camera and lights\n"
           "  Space               play / pause the scene's time (media that follow time:\n"
           "                      sequences, an animated plume), in real time\n"
           "  , / .               one frame (1/fps) back / forward; Home: the start time\n"
           "  Esc, Q              quit\n"
           "\n"
           "Monte Carlo methods (pathtrace) accumulate one pass per frame while nothing\n"
           "changes; the overlay shows the passes so far. Needs a display (X11); under\n"
           "CI use xvfb-run. Exits 1 with one line when no window can be opened.\n");
}

#ifndef LU_HAVE_GLFW

int lu_cmd_view(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (lu_cli_is_help(argv[i])) {
            usage();
            return LU_EXIT_OK;
        }
    fprintf(stderr, "lucent view: error: this lucent was built without the viewer (needs GLFW 3 and the GPU "
                    "backend: pkg-config glfw3, egl, epoxy)\n");
    return LU_EXIT_FAIL;
}

#else

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

/* The main quality knob per method: doubled by '+', halved by '-'. */
static const struct {
    const char *method, *param;
} k_knobs[] = {{"raymarch", "steps"}, {"bssrdf", "splats"}, {"reference", "steps"}, {"pathtrace", "spp"}};

/* After the last input, frames keep the reduced scale for this long before
 * refining, so a pause between key repeats or mouse events does not start a
 * full-resolution frame that would hold up the next one. */
#define LU_VIEW_GRACE_S 0.15
/* A scripted run stops refining this long after its last input. */
#define LU_VIEW_SETTLE_CAP_S 60.0
/* Settings of the frames rendered while moving (besides the lower
 * resolution), where a method's defaults spend far more than a moving image
 * needs: afm rebuilds its attenuation maps every frame, and at 64² texels and
 * 16 samples per texel they cost about a tenth; 100 view steps instead of
 * 500 a fifth of the march (docs/gpu.md, the viewer).
 * --moving-set adds to them, --moving-set none drops them. */
static const struct {
    const char *key;
    double value;
} k_moving[] = {{"afm.map_res", 64}, {"afm.samples", 16}, {"afm.steps", 100}};

/* Trailing frames of one view kept for --stats' rel-L2. */
#define LU_VIEW_STATS_KEEP 64

typedef struct stats_row {
    int frame;
    double ms, scale;
    float *shown;              /* the window-size linear image, while it shows the final view */
    double rel_l2;             /* < 0: not available */
    bool full;                 /* the full image: scale 1 at full quality (progressive: all passes) */
    long rss_kb;               /* the process's resident memory after the frame (0: unknown) */
    long held_kb;              /* what the renderer held then (lu_renderer_stats.memory, GPU included) */
} stats_row;

enum { Q_FULL = 0, Q_MOVING = 1 };

typedef struct viewer {
    lu_scene scene;
    lu_camera cam0;            /* as loaded, for R */
    lu_light *lights0;
    const char *scene_path;
    lu_backend want_backend;
    lu_kvlist settings;
    lu_kvlist moving_settings; /* settings + k_moving + --moving-set */
    int method_index;
    lu_renderer *rq[2];        /* per quality (Q_FULL, Q_MOVING); r is the one used last */
    lu_renderer *r;
    bool need_create;          /* method, knob or light changed: prepare again */
    bool dirty;                /* the view changed: the image must be rendered again */
    int width, height;         /* the window and the full image */
    lu_image img;              /* the last render, at the render size (scale x window) */
    lu_image shown;            /* img upsampled to the window (linear) */
    struct tap *cols;          /* upsampling: the source columns of each window column */
    float *accum;              /* progressive: sum of passes (at the render size) */
    int passes;
    uint8_t *rgb;              /* displayed image, top row first */
    float exposure;
    bool overlay;
    int light;                 /* selected light */
    double last_ms, prepare_ms;
    double fps_t0;
    int fps_frames;
    double fps;
    bool dragging, dragging_light;
    double mx, my;
    char status[256];          /* last error, shown in the overlay */
    /* the frame budget */
    double budget_ms;
    double scale;              /* of the image shown (render width / window width) */
    int quality;               /* of the image shown: Q_FULL or Q_MOVING */
    double cost_px_ms[2];      /* per quality: render ms per pixel, smoothed over the last frames */
    double overhead_ms[2];     /* frame ms outside the method's render, smoothed */
    bool have_cost[2];
    double last_input;         /* glfwGetTime() of the last change of the view */
    /* live error: the reference rendered (key C) for one camera and set of lights */
    lu_image ref;
    lu_camera ref_cam;
    lu_light *ref_lights;
    double rel_l2;             /* of the shown image against ref; < 0: none or stale */
    /* time: media that follow it */
    bool animated, playing;
    double time0;              /* the start time, for Home */
    double play_clock;         /* glfwGetTime() of the last advance while playing */
    double ref_time;           /* the time the reference was rendered at */
    /* GPU methods in the window's own context (gl_caller_context) */
    GLFWwindow *win;
    bool direct;               /* GPU frames go into `tex`, never through CPU memory (no --readback) */
    bool in_texture;           /* the last frame is in tex, not (only) in img */
    bool measure;              /* frames are also read back into img: the live error or --stats need them */
    GLuint tex, prog, vao;     /* the frame (RGBA32F, render size), the tone-mapping program */
    int tex_w, tex_h;
    uint8_t *ovl;              /* direct: the overlay box, RGBA, top row first */
    int ovl_w, ovl_h;
    /* --stats */
    stats_row *rows;
    int row_count, row_cap;
    int view_first_row;        /* first row showing the current view */
} viewer;

static viewer *g_v;            /* GLFW callbacks reach the viewer through this */
static char g_glfw_error[512];

static void glfw_error(int code, const char *msg) { snprintf(g_glfw_error, sizeof g_glfw_error, "%s (GLFW %#x)", msg, code); }

static const lu_method *current_method(const viewer *v) {
    int n;
    return lu_methods(&n)[v->method_index];
}

static bool progressive(const viewer *v) { return strcmp(current_method(v)->name, "pathtrace") == 0; }

static lu_backend backend_for(const viewer *v) {
    const lu_method *m = current_method(v);
    if (v->want_backend == LU_BACKEND_AUTO) return lu_backend_resolve(LU_BACKEND_AUTO, m);
    return (m->backends & v->want_backend) ? v->want_backend : LU_BACKEND_CPU;
}

/* Value of a method parameter under the current settings. */
static double param_value(const viewer *v, const char *method, const char *param) {
    const lu_method *m = lu_method_find(method);
    double vals[64];
    lu_error err;
    if (!m || m->param_count > 64 || lu_method_resolve_params(m, &v->settings, vals, &err) != LU_OK) return 0;
    for (int i = 0; i < m->param_count; i++)
        if (strcmp(m->params[i].name, param) == 0) return vals[i];
    return 0;
}

/* Every change of what is shown goes through here: it is also the input
 * that the frame budget reacts to. */
static void reset_accumulation(viewer *v) {
    v->passes = 0;
    v->dirty = true;
    v->last_input = glfwGetTime();
}

/* ---- the frame budget ---- */

static int scaled(int full, double s) {
    long n = lround(full * s);
    return n < 1 ? 1 : n > full ? full : (int)n;
}

/* The smallest scale: 1/16, or 4 pixels on the short side if that is more. */
static double min_scale(const viewer *v) {
    int short_side = v->width < v->height ? v->width : v->height;
    return fmin(1.0, fmax(1.0 / 16.0, 4.0 / short_side));
}

/* The scale whose frame at quality q is predicted to fit the budget: frame ms = overhead
 * + render ms, render ms = cost per pixel x pixels. Changes under 10 % are
 * ignored so the render size (and the methods' buffers) stays put. */
static double budget_scale(const viewer *v, int q) {
    /* no measurement yet: the full quality keeps its scale (1 at start), the
     * moving quality starts small and grows from its first measured frame */
    if (!v->have_cost[q]) return q == Q_FULL ? v->scale : min_scale(v);
    double avail = fmax(v->budget_ms - v->overhead_ms[q], 0.25 * v->budget_ms);
    double s = sqrt(avail / (fmax(v->cost_px_ms[q], 1e-12) * v->width * v->height));
    s = fmin(1.0, fmax(min_scale(v), s));
    if (fabs(s - v->scale) < 0.1 * v->scale) s = v->scale;
    return s;
}

/* Folds one frame into the cost model: half the weight on the newest frame,
 * so a change of method or view cost is followed within a few frames. */
static void update_cost(viewer *v, double render_ms, double frame_ms) {
    int q = v->quality;
    double px = (double)v->img.width * v->img.height;
    double c = render_ms / px, o = fmax(0.0, frame_ms - render_ms);
    if (!v->have_cost[q]) {
        v->cost_px_ms[q] = c;
        v->overhead_ms[q] = o;
        v->have_cost[q] = true;
    } else {
        v->cost_px_ms[q] = 0.5 * (v->cost_px_ms[q] + c);
        v->overhead_ms[q] = 0.5 * (v->overhead_ms[q] + o);
    }
}

/* Whether the current method renders differently under the moving settings
 * (progressive methods never do: their passes restart on every change). */
static bool has_moving_quality(const viewer *v) {
    const lu_method *m = current_method(v);
    double a[LU_MAX_PARAMS], b[LU_MAX_PARAMS];
    lu_error err;
    if (progressive(v) || m->param_count > LU_MAX_PARAMS ||
        lu_method_resolve_params(m, &v->settings, a, &err) != LU_OK ||
        lu_method_resolve_params(m, &v->moving_settings, b, &err) != LU_OK)
        return false;
    return memcmp(a, b, (size_t)m->param_count * sizeof *a) != 0;
}

/* dst gets every entry of src (later entries replace earlier ones). */
static lu_result kv_copy(lu_kvlist *dst, const lu_kvlist *src, lu_error *err) {
    lu_result r = LU_OK;
    for (int i = 0; i < src->count && r == LU_OK; i++) {
        const lu_kv *kv = &src->items[i];
        r = kv->count ? lu_kv_set_number(dst, kv->key, kv->v, kv->count, err)
                      : lu_kv_set_string(dst, kv->key, kv->str, err);
    }
    return r;
}

static void destroy_renderers(viewer *v) {
    /* a renderer in the window's context frees its objects there */
    if (v->win) glfwMakeContextCurrent(v->win);
    for (int q = 0; q < 2; q++) {
        if (v->rq[q] == v->r) v->r = NULL;
        lu_renderer_destroy(v->rq[q]);
        v->rq[q] = NULL;
    }
    lu_renderer_destroy(v->r);
    v->r = NULL;
}

/* The direct path's frame: the renderer writes v->tex (made at the render
 * size) in the window's context; read back into v->img only to measure it. */
static bool frame_to_texture(viewer *v, const lu_scene *at, lu_error *err) {
    int w = at->camera.width, h = at->camera.height;
    if (!v->tex || v->tex_w != w || v->tex_h != h) {
        if (v->tex) glDeleteTextures(1, &v->tex);
        glCreateTextures(GL_TEXTURE_2D, 1, &v->tex);
        glTextureStorage2D(v->tex, 1, GL_RGBA32F, w, h);
        glTextureParameteri(v->tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTextureParameteri(v->tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(v->tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTextureParameteri(v->tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        v->tex_w = w;
        v->tex_h = h;
    }
    if (lu_renderer_render_texture(v->r, at, v->tex, err) != LU_OK) return false;
    if (!v->measure) return true;
    size_t n = (size_t)w * h * 4;
    float *px = malloc(n * sizeof *px);
    if (!px) {
        lu_fail(err, LU_ERR_NOMEM, "view: out of memory reading the frame back");
        return false;
    }
    glGetTextureImage(v->tex, 0, GL_RGBA, GL_FLOAT, (GLsizei)(n * sizeof *px), px);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < 3; c++)
                v->img.rgb[((size_t)y * w + x) * 3 + c] = px[((size_t)(h - 1 - y) * w + x) * 4 + c];
    free(px);
    return true;
}

/* Draws v->tex over the image's area of the window (top left, as
 * glDrawPixels places the CPU path's image), bilinear when the render is
 * smaller, through lu_srgb_encode's curve after the exposure gain. */
static const char k_display_vs[] =
    "#version 450\n"
    "out vec2 uv;\n"
    "void main() {\n"
    "    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));\n"
    "    uv = p;\n"
    "    gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0);\n"
    "}\n";
static const char k_display_fs[] =
    "#version 450\n"
    "in vec2 uv;\n"
    "out vec4 color;\n"
    "layout(binding = 0) uniform sampler2D frame;\n"
    "uniform float gain;\n"
    "float srgb(float x) {\n"
    "    if (!(x > 0.0)) return 0.0;\n"
    "    if (x <= 0.0031308) return 12.92 * x;\n"
    "    return 1.055 * pow(x, 1.0 / 2.4) - 0.055;\n"
    "}\n"
    "void main() {\n"
    "    vec3 c = texture(frame, uv).rgb * gain;\n"
    "    color = vec4(srgb(c.r), srgb(c.g), srgb(c.b), 1.0);\n"
    "}\n";

static GLuint compile_stage(GLenum kind, const char *src, char *log, size_t log_size) {
    GLuint sh = glCreateShader(kind);
    glShaderSource(sh, 1, &src, NULL);
    glCompileShader(sh);
    GLint ok = 0;
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        glGetShaderInfoLog(sh, (GLsizei)log_size, NULL, log);
        glDeleteShader(sh);
        return 0;
    }
    return sh;
}

/* The window's display program, or false (and the reason) where its
 * context cannot run it: GPU frames then take the --readback path. */
static bool display_init(viewer *v, char *why, size_t why_size) {
    if (epoxy_gl_version() < 45) {
        snprintf(why, why_size, "the window's OpenGL is %d.%d, not 4.5", epoxy_gl_version() / 10,
                 epoxy_gl_version() % 10);
        return false;
    }
    GLuint vs = compile_stage(GL_VERTEX_SHADER, k_display_vs, why, why_size);
    GLuint fs = vs ? compile_stage(GL_FRAGMENT_SHADER, k_display_fs, why, why_size) : 0;
    if (!vs || !fs) {
        glDeleteShader(vs);
        return false;
    }
    v->prog = glCreateProgram();
    glAttachShader(v->prog, vs);
    glAttachShader(v->prog, fs);
    glLinkProgram(v->prog);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(v->prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(v->prog, (GLsizei)why_size, NULL, why);
        glDeleteProgram(v->prog);
        v->prog = 0;
        return false;
    }
    glGenVertexArrays(1, &v->vao);
    return true;
}

/* (Re)creates the renderer when needed and renders one frame (one more pass
 * for progressive methods) at scale v->scale and quality v->quality into
 * v->img. */
static bool render_frame(viewer *v) {
    lu_error err = {0};
    const lu_method *m = current_method(v);
    bool prog = progressive(v);
    lu_scene at = v->scene;
    at.camera.width = scaled(v->width, v->scale);
    at.camera.height = scaled(v->height, v->scale);
    if (v->img.width != at.camera.width || v->img.height != at.camera.height) {
        lu_image_destroy(&v->img);
        memset(&v->img, 0, sizeof v->img);
        if (lu_image_create(&v->img, at.camera.width, at.camera.height, &err) != LU_OK) goto fail;
        v->passes = 0;
    }
    if (prog) {
        /* One pass per frame with a new seed; the viewer averages them. */
        lu_kvlist s = {0};
        for (int i = 0; i < v->settings.count; i++)
            if (strncmp(v->settings.items[i].key, "pathtrace.", 10) != 0 ||
                strcmp(v->settings.items[i].key, "pathtrace.spp") == 0 ||
                strcmp(v->settings.items[i].key, "pathtrace.seed") == 0)
                continue;
            else if (v->settings.items[i].count)
                lu_kv_set_number(&s, v->settings.items[i].key, v->settings.items[i].v, v->settings.items[i].count, &err);
            else
                lu_kv_set_string(&s, v->settings.items[i].key, v->settings.items[i].str, &err);
        double one = 1, seed = 1 + v->passes;
        lu_kv_set_number(&s, "pathtrace.spp", &one, 1, &err);
        lu_kv_set_number(&s, "pathtrace.seed", &seed, 1, &err);
        destroy_renderers(v);
        lu_result rc = lu_renderer_create(m->name, &at, &s, backend_for(v), &v->r, &err);
        lu_kv_free(&s);
        if (rc != LU_OK) goto fail;
    } else {
        if (v->need_create) destroy_renderers(v);   /* v->r is one of them: no dangling pointer if the create fails */
        v->need_create = false;
        int q = v->quality;
        lu_renderer_desc d = {.method = m->name, .backend = backend_for(v),
                              .settings = q == Q_MOVING ? &v->moving_settings : &v->settings,
                              .gl_caller_context = v->direct};
        glfwMakeContextCurrent(v->win);
        if (!v->rq[q] && lu_renderer_make(&d, &at, &v->rq[q], &err) != LU_OK) goto fail;
        v->r = v->rq[q];
    }
    v->need_create = false;
    v->prepare_ms = lu_cli_stats(v->r).prepare_ms;
    v->in_texture = v->direct && !prog && lu_cli_stats(v->r).backend == LU_BACKEND_GPU;
    if (v->in_texture) {
        if (!frame_to_texture(v, &at, &err)) goto fail;
    } else if (lu_renderer_render(v->r, &at, &v->img, &err) != LU_OK) {
        goto fail;
    }
    v->last_ms = lu_cli_stats(v->r).frame_ms + (prog ? v->prepare_ms : 0.0);
    size_t n = (size_t)v->img.width * v->img.height * 3;
    if (prog) {
        if (v->passes == 0) memset(v->accum, 0, n * sizeof(float));
        for (size_t i = 0; i < n; i++) v->accum[i] += v->img.rgb[i];
        v->passes++;
        float inv = 1.0f / (float)v->passes;
        for (size_t i = 0; i < n; i++) v->img.rgb[i] = v->accum[i] * inv;
    } else {
        v->passes = 1;
    }
    v->status[0] = '\0';
    v->dirty = false;
    return true;
fail:
    snprintf(v->status, sizeof v->status, "%.200s", err.message);
    fprintf(stderr, "lucent view: %s: %s\n", m->name, err.message);
    v->dirty = false;
    v->need_create = true;
    return false;
}

/* ---- upsampling and tone mapping ---- */

/* Bilinear: window pixel centre x maps to (x + 0.5) * rw / W - 0.5 in the
 * render image, clamped at the edges; at scale 1 it is a copy. */
typedef struct tap {
    int a, b;                  /* the two source pixels */
    float t;                   /* weight of b */
} tap;

static tap tap_at(int i, int src, int dst) {
    double f = (i + 0.5) * src / dst - 0.5;
    int a = (int)floor(f);
    tap p = {a, a + 1, (float)(f - a)};
    if (a < 0) p.a = p.b = 0, p.t = 0.0f;
    if (p.b > src - 1) p.b = src - 1;
    return p;
}

static void upsample_rows(void *ctx, int64_t y0, int64_t y1, int thread) {
    (void)thread;
    viewer *v = ctx;
    const lu_image *src = &v->img;
    int sw = src->width, W = v->width;
    for (int64_t y = y0; y < y1; y++) {
        float *dst = v->shown.rgb + (size_t)y * W * 3;
        tap ty = tap_at((int)y, src->height, v->height);
        const float *ra = src->rgb + (size_t)ty.a * sw * 3, *rb = src->rgb + (size_t)ty.b * sw * 3;
        for (int x = 0; x < W; x++) {
            const tap *tx = &v->cols[x];
            for (int c = 0; c < 3; c++) {
                float top = ra[tx->a * 3 + c] + tx->t * (ra[tx->b * 3 + c] - ra[tx->a * 3 + c]);
                float bot = rb[tx->a * 3 + c] + tx->t * (rb[tx->b * 3 + c] - rb[tx->a * 3 + c]);
                dst[x * 3 + c] = top + ty.t * (bot - top);
            }
        }
    }
}

static void upsample(viewer *v) {
    if (v->img.width == v->width && v->img.height == v->height) {
        memcpy(v->shown.rgb, v->img.rgb, (size_t)v->width * v->height * 3 * sizeof(float));
        return;
    }
    for (int x = 0; x < v->width; x++) v->cols[x] = tap_at(x, v->img.width, v->width);
    lu_parallel_for(v->height, 8, upsample_rows, v, NULL);
}

typedef struct tone_job {
    viewer *v;
    float gain;
} tone_job;

/* The byte the PNG writer (lu_image_save) makes of a linear value. */
static uint8_t tone_byte(float x) {
    float e = lu_srgb_encode(x);
    return (uint8_t)lrintf(255.0f * (e < 1.0f ? e : 1.0f));
}

/* tone_byte by the top 16 bits of the float: every float sharing them gives
 * the byte stored, or 0xFFFF where the bucket's two ends differ (then it is
 * computed). Exact because tone_byte does not decrease with the value: checked
 * over every float from 0 to 16 (above, it is 255), so equal ends mean
 * a constant bucket (negatives and NaN give 0 at both ends). A window
 * frame tone maps 3 values per pixel; powf on each cost as much as a cheap
 * method's moving frame. */
static uint16_t g_tone_lut[65536];

static void tone_lut_init(void) {
    for (uint32_t i = 0; i < 65536; i++) {
        uint32_t lo = i << 16, hi = lo | 0xFFFFu;
        float a, b;
        memcpy(&a, &lo, sizeof a);
        memcpy(&b, &hi, sizeof b);
        uint8_t ta = tone_byte(a), tb = tone_byte(b);
        g_tone_lut[i] = ta == tb ? ta : 0xFFFF;
    }
}

static void tone_rows(void *ctx, int64_t y0, int64_t y1, int thread) {
    (void)thread;
    const tone_job *j = ctx;
    size_t row = (size_t)j->v->width * 3;
    for (size_t i = (size_t)y0 * row; i < (size_t)y1 * row; i++) {
        float x = j->v->shown.rgb[i] * j->gain;
        uint32_t bits;
        memcpy(&bits, &x, sizeof bits);
        uint16_t t = g_tone_lut[bits >> 16];
        j->v->rgb[i] = t != 0xFFFF ? (uint8_t)t : tone_byte(x);
    }
}

/* True when the cached reference was rendered for the current view and lights. */
static bool ref_current(const viewer *v) {
    return v->ref.rgb && v->ref_time == v->scene.time && memcmp(&v->ref_cam, &v->scene.camera, sizeof v->ref_cam) == 0 &&
           memcmp(v->ref_lights, v->scene.lights, (size_t)v->scene.light_count * sizeof *v->ref_lights) == 0;
}

/* Renders `reference` (CPU, the --set reference.* settings) for the current
 * view and lights: the truth the overlay's live rel-L2 is measured against. */
static bool render_reference(viewer *v) {
    lu_error err = {0};
    lu_renderer *r = NULL;
    lu_image_destroy(&v->ref);
    memset(&v->ref, 0, sizeof v->ref);
    lu_result rc = lu_renderer_create("reference", &v->scene, &v->settings, LU_BACKEND_CPU, &r, &err);
    if (rc == LU_OK) rc = lu_renderer_render(r, &v->scene, &v->ref, &err);
    lu_renderer_destroy(r);
    if (rc != LU_OK) {
        lu_image_destroy(&v->ref);
        memset(&v->ref, 0, sizeof v->ref);
        snprintf(v->status, sizeof v->status, "reference: %.190s", err.message);
        return false;
    }
    v->ref_cam = v->scene.camera;
    v->ref_time = v->scene.time;
    memcpy(v->ref_lights, v->scene.lights, (size_t)v->scene.light_count * sizeof *v->ref_lights);
    return true;
}

static void update_error(viewer *v) {
    v->rel_l2 = -1.0;
    lu_metrics m;
    lu_error err;
    if (ref_current(v) && lu_image_compare(&v->shown, &v->ref, &m, &err) == LU_OK) v->rel_l2 = m.rel_l2;
}

/* Tone maps the shown image, then draws the overlay. */
static void compose(viewer *v) {
    int w = v->width, h = v->height;
    if (!v->in_texture) {
        tone_job job = {v, exp2f(v->exposure)};
        lu_parallel_for(h, 16, tone_rows, &job, NULL);
    }
    if (!v->overlay) return;
    int scale;
    char lines[6][160];
    int nl = v->animated ? 6 : 5;
    const lu_method *m = current_method(v);
    snprintf(lines[0], sizeof lines[0], "%s on %s", m->name, lu_backend_name(backend_for(v)));
    char err_text[48] = "";
    if (v->rel_l2 >= 0.0) snprintf(err_text, sizeof err_text, "  rel-L2 %.2g", v->rel_l2);
    else if (v->ref.rgb) snprintf(err_text, sizeof err_text, "  (C: new reference)");
    snprintf(lines[1], sizeof lines[1], "%.1f ms/frame  %.1f fps  prepare %.0f ms%s", v->last_ms, v->fps, v->prepare_ms,
             err_text);
    char knob[64] = "";
    for (size_t i = 0; i < sizeof k_knobs / sizeof k_knobs[0]; i++)
        if (strcmp(k_knobs[i].method, m->name) == 0 && strcmp(m->name, "pathtrace") != 0)
            snprintf(knob, sizeof knob, "  %s=%g", k_knobs[i].param, param_value(v, m->name, k_knobs[i].param));
    snprintf(lines[2], sizeof lines[2], "spp %d%s  exposure %+.1f", v->passes, knob, v->exposure);
    const lu_light *l = v->scene.light_count ? &v->scene.lights[v->light] : NULL;
    static const char *const kinds[] = {"point", "spot", "directional", "environment"};
    snprintf(lines[3], sizeof lines[3], "light %d/%d %s  %dx%d  scale %.2f%s  budget %.0f ms",
             v->scene.light_count ? v->light + 1 : 0, v->scene.light_count, l ? kinds[l->type] : "-", v->img.width,
             v->img.height, v->scale, v->quality == Q_MOVING ? " moving quality" : "", v->budget_ms);
    snprintf(lines[4], sizeof lines[4], "%.159s", v->status[0] ? v->status : "tab method  +/- quality  arrows light  h hide");
    if (v->animated) {
        int f0, f1;
        char range[48] = "";
        if (lu_scene_frame_range(&v->scene, &f0, &f1)) snprintf(range, sizeof range, " of %d-%d", f0, f1);
        snprintf(lines[5], sizeof lines[5], "time %.3f s  frame %d%s  %s  space play  , . step", v->scene.time,
                 lu_scene_frame_at(&v->scene, v->scene.time), range, v->playing ? "playing" : "paused");
    }
    int bw = 0;
    for (int i = 0; i < nl; i++) {
        int tw = lu_font_text_width(lines[i], 1);
        if (tw > bw) bw = tw;
    }
    /* double size when the widest line still fits */
    scale = 2 * bw + 12 <= w ? 2 : 1;
    bw *= scale;
    int lh = (LU_FONT_H + 3) * scale;
    int box_w = bw + 6 * scale, box_h = nl * lh + 4 * scale;
    static const uint8_t white[3] = {235, 235, 235}, amber[3] = {255, 190, 60}, red[3] = {255, 90, 80};
    if (!v->in_texture) {
        lu_font_backdrop(v->rgb, w, h, 0, 0, box_w, box_h);
        for (int i = 0; i < nl; i++)
            lu_font_draw(v->rgb, w, h, 3 * scale, 3 * scale + i * lh, lines[i], scale,
                         i == 0 ? amber : (i == 4 && v->status[0]) ? red : white);
        return;
    }
    /* The direct path's overlay: the text on its own, blended over the
     * drawn frame (alpha 3/4 on the box is lu_font_backdrop's quarter). */
    box_w = box_w < w ? box_w : w;
    box_h = box_h < h ? box_h : h;
    uint8_t *text = calloc((size_t)box_w * box_h, 3);
    uint8_t *ovl = realloc(v->ovl, (size_t)box_w * box_h * 4);
    if (!text || !ovl) {
        free(text);
        v->ovl = ovl;
        v->ovl_w = v->ovl_h = 0;
        return;
    }
    for (int i = 0; i < nl; i++)
        lu_font_draw(text, box_w, box_h, 3 * scale, 3 * scale + i * lh, lines[i], scale,
                     i == 0 ? amber : (i == 4 && v->status[0]) ? red : white);
    for (size_t i = 0; i < (size_t)box_w * box_h; i++) {
        const uint8_t *t = text + 3 * i;
        bool ink = t[0] | t[1] | t[2];
        ovl[4 * i] = t[0], ovl[4 * i + 1] = t[1], ovl[4 * i + 2] = t[2];
        ovl[4 * i + 3] = ink ? 255 : 191;
    }
    free(text);
    v->ovl = ovl;
    v->ovl_w = box_w;
    v->ovl_h = box_h;
}

static void draw(GLFWwindow *win, viewer *v) {
    int fw, fh;
    glfwGetFramebufferSize(win, &fw, &fh);
    glViewport(0, 0, fw, fh);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    /* rows bottom to top for GL: draw the top row at the top */
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelZoom(1.0f, -1.0f);
    glWindowPos2i(0, fh);
    if (!v->in_texture) {
        glDrawPixels(v->width, v->height, GL_RGB, GL_UNSIGNED_BYTE, v->rgb);
        glPixelZoom(1.0f, 1.0f);
        return;
    }
    glViewport(0, fh - v->height, v->width, v->height);
    glUseProgram(v->prog);
    glUniform1f(glGetUniformLocation(v->prog, "gain"), exp2f(v->exposure));
    glBindTextureUnit(0, v->tex);
    glBindVertexArray(v->vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindVertexArray(0);
    glUseProgram(0);
    glViewport(0, 0, fw, fh);
    if (v->overlay && v->ovl_w > 0) {
        glEnable(GL_BLEND);
        glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
        glDrawPixels(v->ovl_w, v->ovl_h, GL_RGBA, GL_UNSIGNED_BYTE, v->ovl);
        glDisable(GL_BLEND);
    }
    glPixelZoom(1.0f, 1.0f);
}

/* ---- camera and lights ---- */

static lu_vec3 rotate_y(lu_vec3 p, float a) {
    float c = cosf(a), s = sinf(a);
    return lu_v3(c * p.x + s * p.z, p.y, -s * p.x + c * p.z);
}

/* Rotates p about the horizontal axis perpendicular to it (elevation), keeping
 * it away from the poles. */
static lu_vec3 rotate_up(lu_vec3 p, float a) {
    float r = lu_v3_len(p);
    if (r <= 0.0f) return p;
    float el = asinf(fmaxf(-1.0f, fminf(1.0f, p.y / r))), az = atan2f(p.x, p.z);
    el = fmaxf(-1.5f, fminf(1.5f, el + a));
    return lu_v3(r * cosf(el) * sinf(az), r * sinf(el), r * cosf(el) * cosf(az));
}

static void orbit(viewer *v, float yaw, float pitch) {
    lu_camera *c = &v->scene.camera;
    lu_vec3 off = rotate_up(rotate_y(lu_v3_sub(c->position, c->look_at), yaw), pitch);
    c->position = lu_v3_add(c->look_at, off);
    reset_accumulation(v);
}

static void zoom(viewer *v, float factor) {
    lu_camera *c = &v->scene.camera;
    c->position = lu_v3_add(c->look_at, lu_v3_scale(lu_v3_sub(c->position, c->look_at), factor));
    reset_accumulation(v);
}

static void move_light(viewer *v, float yaw, float pitch) {
    if (v->scene.light_count == 0) return;
    lu_light *l = &v->scene.lights[v->light];
    lu_vec3 pivot = v->scene.camera.look_at;
    if (l->type == LU_LIGHT_DIRECTIONAL) {
        l->direction = lu_v3_norm(rotate_up(rotate_y(l->direction, yaw), pitch));
    } else if (l->type == LU_LIGHT_POINT || l->type == LU_LIGHT_SPOT) {
        lu_vec3 off = lu_v3_sub(l->position, pivot);
        lu_vec3 moved = rotate_up(rotate_y(off, yaw), pitch);
        /* a spot keeps aiming at the same offset from the pivot */
        if (l->type == LU_LIGHT_SPOT) l->direction = lu_v3_norm(rotate_up(rotate_y(l->direction, yaw), pitch));
        l->position = lu_v3_add(pivot, moved);
    } else {
        return;
    }
    /* The renderer's frame stage sees the light move and rebuilds only what
     * depends on that light. */
    reset_accumulation(v);
}

static void scale_knob(viewer *v, double f) {
    const lu_method *m = current_method(v);
    for (size_t i = 0; i < sizeof k_knobs / sizeof k_knobs[0]; i++) {
        if (strcmp(k_knobs[i].method, m->name) != 0 || strcmp(m->name, "pathtrace") == 0) continue;
        char key[64];
        snprintf(key, sizeof key, "%s.%s", m->name, k_knobs[i].param);
        double val = param_value(v, m->name, k_knobs[i].param) * f;
        for (int j = 0; j < m->param_count; j++)
            if (strcmp(m->params[j].name, k_knobs[i].param) == 0) {
                val = fmax(m->params[j].lo, fmin(m->params[j].hi, val));
                if (m->params[j].type != LU_PARAM_FLOAT) val = floor(val + 0.5);
            }
        lu_error err;
        lu_kv_set_number(&v->settings, key, &val, 1, &err);
        v->need_create = true;
        reset_accumulation(v);
    }
}

/* Puts the scene at `time`; a change of what the media hold is a change of
 * the view (the frame budget reacts to it as to any input). */
static void set_time(viewer *v, double time) {
    uint64_t before = 0, after = 0;
    for (int m = 0; m < v->scene.medium_count; m++)
        before += v->scene.media[m].grid.generation + v->scene.media[m].emission_grid.generation;
    lu_error err;
    if (lu_scene_set_time(&v->scene, time, &err) != LU_OK) {
        snprintf(v->status, sizeof v->status, "%.200s", err.message);
        v->playing = false;
        return;
    }
    for (int m = 0; m < v->scene.medium_count; m++)
        after += v->scene.media[m].grid.generation + v->scene.media[m].emission_grid.generation;
    if (after != before) reset_accumulation(v);
}

static void step_frame(viewer *v, int by) {
    if (!v->animated) return;
    v->playing = false;
    set_time(v, lu_scene_frame_time(&v->scene, lu_scene_frame_at(&v->scene, v->scene.time) + by));
}

/* The method `step` places on in the method table (Tab, Shift-Tab, the soak script). */
static void switch_method(viewer *v, int step) {
    int n;
    lu_methods(&n);
    v->method_index = (v->method_index + step) % n;
    v->need_create = true;
    v->have_cost[Q_FULL] = v->have_cost[Q_MOVING] = false;   /* another method: its own cost */
    reset_accumulation(v);
}

static void on_key(GLFWwindow *win, int key, int scancode, int action, int mods) {
    (void)scancode;
    viewer *v = g_v;
    if (action == GLFW_RELEASE) return;
    const float a = 0.08f;
    int n;
    lu_methods(&n);
    switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: glfwSetWindowShouldClose(win, GLFW_TRUE); break;
    case GLFW_KEY_LEFT: move_light(v, -a, 0); break;
    case GLFW_KEY_RIGHT: move_light(v, a, 0); break;
    case GLFW_KEY_UP: move_light(v, 0, a); break;
    case GLFW_KEY_DOWN: move_light(v, 0, -a); break;
    case GLFW_KEY_L:
        if (v->scene.light_count) v->light = (v->light + 1) % v->scene.light_count;
        break;
    case GLFW_KEY_TAB: switch_method(v, (mods & GLFW_MOD_SHIFT) ? n - 1 : 1); break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: scale_knob(v, 2.0); break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: scale_knob(v, 0.5); break;
    case GLFW_KEY_PAGE_UP: zoom(v, 0.9f); break;
    case GLFW_KEY_PAGE_DOWN: zoom(v, 1.0f / 0.9f); break;
    case GLFW_KEY_E: v->exposure += 0.5f; break;
    case GLFW_KEY_D: v->exposure -= 0.5f; break;
    case GLFW_KEY_H: v->overlay = !v->overlay; break;
    case GLFW_KEY_C:
        /* blocking: the reference takes seconds on a large image */
        if (render_reference(v)) update_error(v);
        break;
    case GLFW_KEY_SPACE:
        if (v->animated) {
            v->playing = !v->playing;
            v->play_clock = glfwGetTime();
        }
        break;
    case GLFW_KEY_PERIOD: step_frame(v, 1); break;
    case GLFW_KEY_COMMA: step_frame(v, -1); break;
    case GLFW_KEY_HOME:
        if (v->animated) set_time(v, v->time0);
        break;
    case GLFW_KEY_R:
        v->scene.camera = v->cam0;
        memcpy(v->scene.lights, v->lights0, (size_t)v->scene.light_count * sizeof *v->lights0);
        v->need_create = true;
        reset_accumulation(v);
        break;
    default: break;
    }
}

static void on_button(GLFWwindow *win, int button, int action, int mods) {
    (void)mods;
    if (button == GLFW_MOUSE_BUTTON_LEFT) g_v->dragging = action == GLFW_PRESS;
    else if (button == GLFW_MOUSE_BUTTON_RIGHT) g_v->dragging_light = action == GLFW_PRESS;
    else return;
    glfwGetCursorPos(win, &g_v->mx, &g_v->my);
}

static void on_cursor(GLFWwindow *win, double x, double y) {
    (void)win;
    viewer *v = g_v;
    if (!v->dragging && !v->dragging_light) return;
    double dx = x - v->mx, dy = y - v->my;
    v->mx = x;
    v->my = y;
    if (dx == 0 && dy == 0) return;
    if (v->dragging) orbit(v, (float)(-dx * 0.01), (float)(dy * 0.01));
    else move_light(v, (float)(dx * 0.01), (float)(-dy * 0.01));
}

static void on_scroll(GLFWwindow *win, double xoff, double yoff) {
    (void)win;
    (void)xoff;
    zoom(g_v, powf(0.9f, (float)yoff));
}

/* Saves the window's back buffer (what draw() put there) as an image. */
static bool save_screenshot(int w, int h, const char *path, lu_error *err) {
    uint8_t *px = malloc((size_t)w * h * 3);
    lu_image im = {0};
    if (!px || lu_image_create(&im, w, h, err) != LU_OK) {
        free(px);
        return false;
    }
    glReadBuffer(GL_BACK);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, px);
    /* back to linear, so the PNG writer's sRGB curve gives the same bytes */
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w * 3; x++)
            im.rgb[(size_t)y * w * 3 + x] = lu_srgb_decode(px[(size_t)(h - 1 - y) * w * 3 + x] / 255.0f);
    lu_image_save_desc save = {0};
    bool ok = lu_image_save(&im, path, &save, err) == LU_OK;
    lu_image_destroy(&im);
    free(px);
    return ok;
}

/* The window's context: EGL first (the method's GPU contexts are EGL too, so
 * one thread switches between EGL contexts only), then the native API. */
static GLFWwindow *open_window(int w, int h, const char *title) {
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
    GLFWwindow *win = glfwCreateWindow(w, h, title, NULL, NULL);
    if (win) return win;
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_NATIVE_CONTEXT_API);
    return glfwCreateWindow(w, h, title, NULL, NULL);
}

/* ---- --stats ---- */


/* A row per frame; the frame's image is kept while it shows the view of the
 * last rows (a new view drops the older images: they can never be compared
 * against the final view). */
static bool stats_add(viewer *v, int frame, double ms, bool new_view) {
    if (v->row_count == v->row_cap) {
        int cap = v->row_cap ? 2 * v->row_cap : 64;
        stats_row *rows = realloc(v->rows, (size_t)cap * sizeof *rows);
        if (!rows) return false;
        v->rows = rows;
        v->row_cap = cap;
    }
    if (new_view) {
        for (int i = v->view_first_row; i < v->row_count; i++) {
            free(v->rows[i].shown);
            v->rows[i].shown = NULL;
        }
        v->view_first_row = v->row_count;
    }
    if (v->row_count - LU_VIEW_STATS_KEEP >= v->view_first_row) {
        free(v->rows[v->row_count - LU_VIEW_STATS_KEEP].shown);
        v->rows[v->row_count - LU_VIEW_STATS_KEEP].shown = NULL;
    }
    stats_row *r = &v->rows[v->row_count++];
    size_t n = (size_t)v->width * v->height * 3;
    /* progressive methods get no rel_l2 (stats_compare), so nothing to keep */
    *r = (stats_row){frame, ms, (double)v->img.width / v->width, progressive(v) ? NULL : malloc(n * sizeof(float)),
                     -1.0,
                     v->img.width == v->width && v->img.height == v->height && v->quality == Q_FULL &&
                         (!progressive(v) || v->passes >= param_value(v, "pathtrace", "spp")),
                     0, 0};
    if (r->shown) memcpy(r->shown, v->shown.rgb, n * sizeof(float));
    r->rss_kb = lu_resident_kb();
    lu_memory held = lu_cli_stats(v->r).memory;
    r->held_kb = (long)((held.bytes + held.accel_bytes + held.gpu_bytes) / 1024);
    return true;
}

/* The truth for the final view: a fresh renderer (same method, settings and
 * backend) renders it at full size, as `lucent render` would. Deterministic
 * methods only: a progressive method's passes have no single full image. */
static void stats_compare(viewer *v) {
    if (progressive(v) || v->row_count == 0) return;
    lu_error err = {0};
    lu_renderer *r = NULL;
    lu_image full = {0}, frame = {0};
    lu_result rc = lu_renderer_create(current_method(v)->name, &v->scene, &v->settings, backend_for(v), &r, &err);
    if (rc == LU_OK) rc = lu_renderer_render(r, &v->scene, &full, &err);
    lu_renderer_destroy(r);
    if (rc == LU_OK) rc = lu_image_create(&frame, v->width, v->height, &err);
    if (rc != LU_OK) {
        fprintf(stderr, "lucent view: --stats: no full image of the final view: %s\n", err.message);
    } else {
        size_t n = (size_t)v->width * v->height * 3;
        for (int i = v->view_first_row; i < v->row_count; i++) {
            lu_metrics m;
            if (!v->rows[i].shown) continue;
            memcpy(frame.rgb, v->rows[i].shown, n * sizeof(float));
            if (lu_image_compare(&frame, &full, &m, &err) == LU_OK) v->rows[i].rel_l2 = m.rel_l2;
        }
    }
    lu_image_destroy(&full);
    lu_image_destroy(&frame);
}

static bool stats_write(const viewer *v, const char *path, lu_error *err) {
    lu_atomic_file f;
    if (lu_atomic_open(&f, path, err) != LU_OK) return false;
    FILE *fp = f.fp;
    fprintf(fp, "frame,ms,scale,rel_l2,rss_kb,held_kb\n");
    for (int i = 0; i < v->row_count; i++) {
        const stats_row *r = &v->rows[i];
        fprintf(fp, "%d,%.3f,%.4f,", r->frame, r->ms, r->scale);
        if (r->rel_l2 >= 0.0) fprintf(fp, "%.6g", r->rel_l2);
        fprintf(fp, ",%ld,%ld\n", r->rss_kb, r->held_kb);
    }
    return lu_atomic_commit(&f, err) == LU_OK;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One line: the moving frames' median, the settle, the final error. Frame
 * `last_input` is the last scripted one; settle times add the ms of the
 * frames after it. */
static void script_summary(const viewer *v, lu_view_script kind, int frames) {
    size_t cap = (size_t)(frames > 0 ? frames : 1);
    double *ms = malloc(cap * sizeof *ms), *sc = malloc(cap * sizeof *sc);
    int n = 0;
    for (int i = 0; ms && sc && i < v->row_count; i++)
        if (v->rows[i].frame >= 1 && v->rows[i].frame <= frames) {
            ms[n] = v->rows[i].ms;
            sc[n++] = v->rows[i].scale;
        }
    if (n == 0) {
        free(ms);
        free(sc);
        return;
    }
    qsort(ms, (size_t)n, sizeof *ms, cmp_double);
    qsort(sc, (size_t)n, sizeof *sc, cmp_double);
    double med = n % 2 ? ms[n / 2] : 0.5 * (ms[n / 2 - 1] + ms[n / 2]);
    double med_scale = n % 2 ? sc[n / 2] : 0.5 * (sc[n / 2 - 1] + sc[n / 2]);
    double settle = 0.0, within2 = -1.0, full = -1.0;
    const stats_row *last = &v->rows[v->row_count - 1];
    for (int i = 0; i < v->row_count; i++) {
        const stats_row *r = &v->rows[i];
        if (r->frame < frames) continue;
        if (r->frame > frames) settle += r->ms;
        if (within2 < 0.0 && r->rel_l2 >= 0.0 && r->rel_l2 <= 0.02) within2 = settle;
        if (full < 0.0 && r->full) full = settle;
    }
    fprintf(stderr, "lucent view: script %s, %d frames of %s on %s: median %.1f ms (%.1f fps) at median scale %.3g; ",
            lu_view_script_name(kind), frames, current_method(v)->name, lu_backend_name(backend_for(v)), med,
            1e3 / med, med_scale);
    if (full >= 0.0) fprintf(stderr, "full image %.0f ms after the last input", full);
    else fprintf(stderr, "full image not reached");
    if (within2 >= 0.0) fprintf(stderr, ", within 2 %% of a fresh render after %.0f ms", within2);
    if (last->rel_l2 >= 0.0) fprintf(stderr, ", last frame rel-L2 %.3g", last->rel_l2);
    fputc('\n', stderr);
    free(ms);
    free(sc);
}

int lu_cmd_view(int argc, char **argv) {
    const char *scene_path = NULL, *method = "raymarch", *shot = NULL, *stats_path = NULL;
    bool time_given = false;
    double start_time = 0.0;
    int width = 0, height = 0, frames = -1, rc = LU_EXIT_OK;
    bool compare = false, moving_defaults = true, readback = false;
    lu_kvlist moving_extra = {0};
    lu_view_script script = LU_VIEW_SCRIPT_NONE;
    static viewer v;
    memset(&v, 0, sizeof v);
    v.want_backend = LU_BACKEND_AUTO;
    v.overlay = true;
    v.budget_ms = 33.0;
    lu_error err = {0};
    for (int i = 1; i < argc && rc == LU_EXIT_OK; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        if (lu_cli_is_help(a)) {
            usage();
            lu_kv_free(&v.settings);
            return LU_EXIT_OK;
        } else if (strcmp(a, "--method") == 0 && has_next) {
            method = argv[++i];
        } else if (strcmp(a, "--backend") == 0 && has_next) {
            if (!lu_cli_parse_backend(argv[++i], &v.want_backend))
                rc = lu_cli_usage("view", "--backend takes cpu, gpu or auto");
        } else if (strcmp(a, "--set") == 0 && has_next) {
            if (lu_kv_parse_assignment(&v.settings, argv[++i], &err) != LU_OK) rc = lu_cli_error("view", &err);
        } else if (strcmp(a, "--moving-set") == 0 && has_next) {
            if (strcmp(argv[++i], "none") == 0) moving_defaults = false;
            else if (lu_kv_parse_assignment(&moving_extra, argv[i], &err) != LU_OK) rc = lu_cli_error("view", &err);
        } else if (strcmp(a, "--size") == 0 && has_next) {
            if (!lu_cli_parse_size(argv[++i], &width, &height)) rc = lu_cli_usage("view", "--size takes WxH");
        } else if (strcmp(a, "--exposure") == 0 && has_next) {
            char *end;
            v.exposure = strtof(argv[++i], &end);
            if (*end) rc = lu_cli_usage("view", "--exposure takes a number");
        } else if (strcmp(a, "--budget") == 0 && has_next) {
            char *end;
            v.budget_ms = strtod(argv[++i], &end);
            if (*end || end == argv[i] || !(v.budget_ms > 0.0 && v.budget_ms <= 60000.0))
                rc = lu_cli_usage("view", "--budget takes milliseconds in (0, 60000] (\"%s\")", argv[i]);
        } else if (strcmp(a, "--compare") == 0) {
            compare = true;
        } else if (strcmp(a, "--readback") == 0) {
            readback = true;
        } else if (strcmp(a, "--no-overlay") == 0) {
            v.overlay = false;
        } else if (strcmp(a, "--screenshot") == 0 && has_next) {
            shot = argv[++i];
        } else if (strcmp(a, "--script") == 0 && has_next) {
            if (!lu_view_script_parse(argv[++i], &script))
                rc = lu_cli_usage("view", "--script takes orbit, light, play or soak (\"%s\")", argv[i]);
        } else if (strcmp(a, "--time") == 0 && has_next) {
            char *end;
            start_time = strtod(argv[++i], &end);
            time_given = true;
            if (*end || end == argv[i] || !isfinite(start_time) || fabs(start_time) > 1e6)
                rc = lu_cli_usage("view", "--time takes seconds in [-1e6, 1e6] (\"%s\")", argv[i]);
        } else if (strcmp(a, "--stats") == 0 && has_next) {
            stats_path = argv[++i];
        } else if (strcmp(a, "--frames") == 0 && has_next) {
            char *end;
            long n = strtol(argv[++i], &end, 10);
            if (*end || end == argv[i] || n < 1 || n > 1000000)
                rc = lu_cli_usage("view", "--frames takes a positive integer (\"%s\")", argv[i]);
            frames = (int)n;
        } else if (a[0] == '-') {
            rc = lu_cli_usage("view", "unknown or incomplete option \"%s\"", a);
        } else if (!scene_path) {
            scene_path = a;
        } else {
            rc = lu_cli_usage("view", "unexpected argument \"%s\"", a);
        }
    }
    if (rc == LU_EXIT_OK && !scene_path) rc = lu_cli_usage("view", "missing SCENE.json");
    if (rc == LU_EXIT_OK && shot && lu_image_format_from_path(shot) != LU_IMAGE_PNG)
        rc = lu_cli_usage("view", "--screenshot writes PNG (\"%s\")", shot);
    const lu_method *m0 = rc == LU_EXIT_OK ? lu_method_find(method) : NULL;
    if (rc == LU_EXIT_OK && !m0) rc = lu_cli_usage("view", "no method named \"%s\" (see lucent methods)", method);
    if (rc == LU_EXIT_OK && lu_settings_validate(&v.settings, &err) != LU_OK) rc = lu_cli_error("view", &err);
    /* the moving settings: --set, then the defaults, then --moving-set; each
     * method must accept them */
    if (rc == LU_EXIT_OK && kv_copy(&v.moving_settings, &v.settings, &err) != LU_OK) rc = lu_cli_error("view", &err);
    for (size_t i = 0; moving_defaults && rc == LU_EXIT_OK && i < sizeof k_moving / sizeof k_moving[0]; i++)
        if (lu_kv_set_number(&v.moving_settings, k_moving[i].key, &k_moving[i].value, 1, &err) != LU_OK)
            rc = lu_cli_error("view", &err);
    if (rc == LU_EXIT_OK && kv_copy(&v.moving_settings, &moving_extra, &err) != LU_OK) rc = lu_cli_error("view", &err);
    if (rc == LU_EXIT_OK && lu_settings_validate(&moving_extra, &err) != LU_OK) {
        fprintf(stderr, "lucent view: error: --moving-set: %s\n", err.message);
        rc = LU_EXIT_FAIL;
    }
    {
        int nm;
        const lu_method *const *ms = lu_methods(&nm);
        double vals[LU_MAX_PARAMS];
        for (int i = 0; i < nm && rc == LU_EXIT_OK; i++)
            if (lu_method_resolve_params(ms[i], &v.moving_settings, vals, &err) != LU_OK) {
                fprintf(stderr, "lucent view: error: --moving-set: %s\n", err.message);
                rc = LU_EXIT_FAIL;
            }
    }
    lu_kv_free(&moving_extra);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&v.settings);
        lu_kv_free(&v.moving_settings);
        return rc;
    }
    if (frames < 0) frames = script ? 8 : 1;
    int n;
    const lu_method *const *all = lu_methods(&n);
    for (int i = 0; i < n; i++)
        if (all[i] == m0) v.method_index = i;

    rc = lu_cli_load_scene("view", scene_path, width, height, &v.scene);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&v.settings);
        lu_kv_free(&v.moving_settings);
        return rc;
    }
    char why[200];
    if (time_given && lu_scene_set_time(&v.scene, start_time, &err) != LU_OK) rc = lu_cli_error("view", &err);
    if (rc == LU_EXIT_OK && !lu_view_script_check(&v.scene, script, why, sizeof why))
        rc = lu_cli_usage("view", "--script %s: %s (%s)", lu_view_script_name(script), why, scene_path);
    if (rc != LU_EXIT_OK) {
        lu_scene_destroy(&v.scene);
        lu_kv_free(&v.settings);
        lu_kv_free(&v.moving_settings);
        return rc;
    }
    v.cam0 = v.scene.camera;
    v.animated = lu_scene_animated(&v.scene);
    v.time0 = v.scene.time;
    int w = v.scene.camera.width, h = v.scene.camera.height;
    v.width = w;
    v.height = h;
    v.scale = 1.0;
    v.last_input = -1e9;
    v.lights0 = malloc((size_t)(v.scene.light_count ? v.scene.light_count : 1) * sizeof *v.lights0);
    v.ref_lights = malloc((size_t)(v.scene.light_count ? v.scene.light_count : 1) * sizeof *v.ref_lights);
    v.rel_l2 = -1.0;
    v.accum = malloc((size_t)w * h * 3 * sizeof(float));
    v.rgb = malloc((size_t)w * h * 3);
    v.cols = malloc((size_t)w * sizeof *v.cols);
    tone_lut_init();
    GLFWwindow *win = NULL;
    if (!v.lights0 || !v.ref_lights || !v.accum || !v.rgb || !v.cols || lu_image_create(&v.shown, w, h, &err) != LU_OK) {
        fprintf(stderr, "lucent view: error: out of memory for a %dx%d image\n", w, h);
        rc = LU_EXIT_FAIL;
        goto done;
    }
    memcpy(v.lights0, v.scene.lights, (size_t)v.scene.light_count * sizeof *v.lights0);
    g_v = &v;

    glfwSetErrorCallback(glfw_error);
    if (!glfwInit()) {
        fprintf(stderr,
                "lucent view: error: no display: %s; the viewer needs a window (set DISPLAY, or run under "
                "xvfb-run); `lucent render` works without one\n",
                g_glfw_error[0] ? g_glfw_error : "glfwInit failed");
        rc = LU_EXIT_FAIL;
        goto done;
    }
    char title[300];
    snprintf(title, sizeof title, "lucent view %s", scene_path);
    win = open_window(w, h, title);
    if (!win) {
        fprintf(stderr, "lucent view: error: cannot open a %dx%d OpenGL window: %s\n", w, h,
                g_glfw_error[0] ? g_glfw_error : "glfwCreateWindow failed");
        rc = LU_EXIT_FAIL;
        glfwTerminate();
        goto done;
    }
    /* the auto decision and its note, once a window shows that the viewer can run */
    lu_cli_resolve_backend("view", v.want_backend, NULL);
    v.win = win;
    glfwMakeContextCurrent(win);
    if (!readback) {
        char no_direct[256] = "";
        v.direct = display_init(&v, no_direct, sizeof no_direct);
        if (!v.direct && v.want_backend != LU_BACKEND_CPU)
            fprintf(stderr, "lucent view: note: GPU frames go through CPU memory: %s\n", no_direct);
    }
    glfwSetKeyCallback(win, on_key);
    glfwSetMouseButtonCallback(win, on_button);
    glfwSetCursorPosCallback(win, on_cursor);
    glfwSetScrollCallback(win, on_scroll);
    v.need_create = true;
    v.dirty = true;
    if (compare && !render_reference(&v)) fprintf(stderr, "lucent view: %s\n", v.status);
    v.fps_t0 = glfwGetTime();
    int frame = 0, shown_frames = 0, script_frame = 0;
    int soak_refused = 0, method_count = 0;   /* soak: methods refused in a row; the table's size */
    lu_methods(&method_count);
    double script_end = 0.0;
    bool settled = false;
    double spp_goal = progressive(&v) ? param_value(&v, "pathtrace", "spp") : 1.0;
    while (!glfwWindowShouldClose(win)) {
        double t0 = glfwGetTime();
        bool scripted_step = script && script_frame < frames && shown_frames > 0;
        if (v.playing && !script) {
            /* real time: the clock advances by the wall time since the last frame */
            set_time(&v, v.scene.time + (t0 - v.play_clock));
            v.play_clock = t0;
        }
        if (scripted_step) {
            script_frame++;
            lu_view_script_apply(&v.scene, &v.cam0, v.scene.light_count ? &v.lights0[0] : NULL, script, script_frame);
            if (script == LU_VIEW_SCRIPT_SOAK && script_frame % LU_VIEW_SOAK_METHOD_EVERY == 0) switch_method(&v, 1);
            if (script == LU_VIEW_SCRIPT_SOAK && script_frame % LU_VIEW_SOAK_RESIZE_EVERY == 0) {
                /* the window alternates between its size and 3/2 of it; the image keeps its size */
                bool big = (script_frame / LU_VIEW_SOAK_RESIZE_EVERY) % 2 == 1;
                glfwSetWindowSize(win, big ? v.width * 3 / 2 : v.width, big ? v.height * 3 / 2 : v.height);
            }
            if (script == LU_VIEW_SCRIPT_PLAY) {
                lu_result tr = lu_scene_set_time(&v.scene, v.time0 + lu_scene_frame_time(&v.scene, script_frame), &err);
                if (tr != LU_OK) {
                    rc = lu_cli_error("view", &err);
                    break;
                }
            }
            reset_accumulation(&v);
            if (script_frame == frames) script_end = t0;
        }
        /* Interacting: a change within the grace time (scripted: this
         * frame's step), or a drag in progress. */
        bool interacting = script ? scripted_step
                                  : v.dragging || v.dragging_light || t0 - v.last_input < LU_VIEW_GRACE_S;
        bool render_now = false, new_view = v.dirty;
        if (v.dirty) {
            v.quality = interacting && has_moving_quality(&v) ? Q_MOVING : Q_FULL;
            v.scale = interacting ? budget_scale(&v, v.quality) : 1.0;
            render_now = true;
        } else if ((v.scale < 1.0 || v.quality != Q_FULL) && !interacting && !v.status[0]) {
            /* refine: the resolution doubles, then the quality goes to full */
            if (v.scale < 1.0) {
                v.scale = fmin(1.0, 2.0 * v.scale);
                if (v.scale > 0.75) v.scale = 1.0;   /* the last step goes to full, not to 0.8 */
            } else {
                v.quality = Q_FULL;
            }
            render_now = true;
        } else if (progressive(&v) && !v.status[0] && (!script || v.passes < spp_goal)) {
            render_now = true;
        } else if (shot && !script) {
            render_now = true;
        }
        if (script && !scripted_step && shown_frames > 0 && !render_now) settled = true;
        if (script && script_frame == frames && t0 - script_end > LU_VIEW_SETTLE_CAP_S) settled = true;
        if (settled && script) {
            if (v.scale < 1.0 || v.quality != Q_FULL || (progressive(&v) && v.passes < spp_goal))
                fprintf(stderr, "lucent view: the full image was not reached %.0f s after the last input\n",
                        LU_VIEW_SETTLE_CAP_S);
            break;
        }
        double render_ms = -1.0;
        if (render_now) {
            v.measure = stats_path != NULL || v.ref.rgb != NULL;
            if (render_frame(&v)) {
                render_ms = lu_cli_stats(v.r).frame_ms;
                if (!v.in_texture || v.measure) {
                    upsample(&v);
                    update_error(&v);
                }
                soak_refused = 0;
            } else if (script == LU_VIEW_SCRIPT_SOAK && ++soak_refused < method_count) {
                /* a method this scene does not suit: the next one, as Tab would */
                switch_method(&v, 1);
                v.status[0] = '\0';
                v.dirty = true;
                continue;
            } else if (script) {
                rc = LU_EXIT_FAIL;
                break;
            }
            v.fps_frames++;
            double now = glfwGetTime();
            if (now - v.fps_t0 >= 0.5 || v.fps_frames == 1) {
                v.fps = v.fps_frames / fmax(now - v.fps_t0, 1e-9);
                v.fps_t0 = now;
                v.fps_frames = 0;
            }
        }
        glfwMakeContextCurrent(win);   /* the method's GPU path made its own context current */
        compose(&v);
        draw(win, &v);
        bool last_shot = shot && !script && ++frame >= frames;
        if (!last_shot) glfwSwapBuffers(win);
        if (render_now) {
            double frame_ms = 1e3 * (glfwGetTime() - t0);
            if (render_ms >= 0.0) update_cost(&v, render_ms, frame_ms);
            if (stats_path && !stats_add(&v, shown_frames, frame_ms, new_view)) {
                fprintf(stderr, "lucent view: error: out of memory for --stats\n");
                rc = LU_EXIT_FAIL;
                break;
            }
            shown_frames++;
        }
        if (last_shot) break;
        if (script || render_now || v.playing) glfwPollEvents();
        else if ((v.scale < 1.0 || v.quality != Q_FULL) && !v.dragging && !v.dragging_light && !v.status[0])
            /* wake when the grace time ends, to refine */
            glfwWaitEventsTimeout(fmax(0.001, LU_VIEW_GRACE_S - (glfwGetTime() - v.last_input)));
        else glfwWaitEventsTimeout(0.25);
    }
    if (rc == LU_EXIT_OK && shot) {
        /* script: the settled frame is in the back buffer again (draw above) */
        if (script) {
            glfwMakeContextCurrent(win);
            compose(&v);
            draw(win, &v);
        }
        glFinish();
        if (!save_screenshot(w, h, shot, &err)) {
            rc = lu_cli_error("view", &err);
        } else {
            fprintf(stderr, "lucent view: %s after %d frames of %s on %s (last %.1f ms)", shot,
                    script ? shown_frames : frames, current_method(&v)->name, lu_backend_name(backend_for(&v)), v.last_ms);
            if (v.rel_l2 >= 0.0) fprintf(stderr, ", rel-L2 vs reference %.6g", v.rel_l2);
            fputc('\n', stderr);
            if (v.status[0]) rc = LU_EXIT_FAIL;
        }
    }
    if (rc == LU_EXIT_OK && stats_path) {
        stats_compare(&v);
        if (!stats_write(&v, stats_path, &err)) rc = lu_cli_error("view", &err);
    }
    if (rc == LU_EXIT_OK && script) script_summary(&v, script, frames);
    /* the method's contexts go before the window's */
    destroy_renderers(&v);
    glfwMakeContextCurrent(win);
    if (v.tex) glDeleteTextures(1, &v.tex);
    if (v.prog) glDeleteProgram(v.prog);
    if (v.vao) glDeleteVertexArrays(1, &v.vao);
    glfwDestroyWindow(win);
    v.win = NULL;
    /* No glfwTerminate: it closes the display and unloads the GL driver, and
     * Mesa 22.3's swrast_dri.so leaks on every unload (LeakSanitizer; the same
     * reason the GPU backend never terminates its EGL displays, context.c).
     * The process ends right after this command. */
done:
    destroy_renderers(&v);
    lu_image_destroy(&v.img);
    lu_image_destroy(&v.shown);
    lu_image_destroy(&v.ref);
    for (int i = 0; i < v.row_count; i++) free(v.rows[i].shown);
    free(v.rows);
    free(v.ref_lights);
    free(v.accum);
    free(v.ovl);
    free(v.rgb);
    free(v.cols);
    free(v.lights0);
    lu_scene_destroy(&v.scene);
    lu_kv_free(&v.settings);
    lu_kv_free(&v.moving_settings);
    return rc;
}

#endif
