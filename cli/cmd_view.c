/* lucent view SCENE.json — the interactive viewer: a GLFW window showing a
 * method's image, orbit/zoom camera, keys to move the selected light, switch
 * method and change its main quality knob, an on-screen overlay (frame time,
 * fps, method, backend, samples) in the built-in bitmap font
 * (src/viewer/lu_font.h), progressive accumulation for Monte Carlo methods,
 * and --screenshot FILE --frames N for scripted use (tests under Xvfb).
 *
 * The image is rendered by the method (CPU or its GPU path on its own
 * headless EGL context), tone mapped exactly as `lucent render -o x.png`
 * does (sRGB curve after 2^exposure), overlaid, and drawn with glDrawPixels
 * into the window's own context; the screenshot is read back from the
 * window (glReadPixels), so it shows what the window showed. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "viewer/lu_font.h"

static void usage(void) {
    printf("usage: lucent view SCENE.json [options]\n"
           "\n"
           "options:\n"
           "  --method M          method shown first (default: raymarch; Tab cycles through all)\n"
           "  --backend cpu|gpu   where methods run (default: gpu; a method without a GPU path\n"
           "                      runs on the CPU); LUCENT_GPU=auto|hardware|software picks the device\n"
           "  --set M.P=V         method parameters, as for render (repeatable)\n"
           "  --size WxH          image and window size (default: the scene camera's)\n"
           "  --exposure E        scale by 2^E before the sRGB curve (default 0)\n"
           "  --no-overlay        start with the overlay hidden\n"
           "  --compare           render the reference first (as key C does)\n"
           "  --screenshot FILE   render --frames frames, save the window's last frame (PNG), exit\n"
           "  --frames N          frames to render with --screenshot (default 1)\n"
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

typedef struct viewer {
    lu_scene scene;
    lu_camera cam0;            /* as loaded, for R */
    lu_light *lights0;
    const char *scene_path;
    lu_backend want_backend;
    lu_kvlist settings;
    int method_index;
    lu_renderer *r;
    bool need_create;          /* method, knob or light changed: prepare again */
    bool dirty;                /* the image must be rendered again */
    lu_image img;
    float *accum;              /* progressive: sum of passes */
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
    /* live error: the reference rendered (key C) for one camera and set of lights */
    lu_image ref;
    lu_camera ref_cam;
    lu_light *ref_lights;
    double rel_l2;             /* of the shown image against ref; < 0: none or stale */
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

static void reset_accumulation(viewer *v) {
    v->passes = 0;
    v->dirty = true;
}

/* (Re)creates the renderer when needed and renders one frame (one more pass
 * for progressive methods) into v->img. */
static bool render_frame(viewer *v) {
    lu_error err = {0};
    const lu_method *m = current_method(v);
    bool prog = progressive(v);
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
        lu_renderer_destroy(v->r);
        v->r = NULL;
        lu_result rc = lu_renderer_create(m->name, &v->scene, &s, backend_for(v), &v->r, &err);
        lu_kv_free(&s);
        if (rc != LU_OK) goto fail;
    } else if (v->need_create || !v->r) {
        lu_renderer_destroy(v->r);
        v->r = NULL;
        if (lu_renderer_create(m->name, &v->scene, &v->settings, backend_for(v), &v->r, &err) != LU_OK) goto fail;
    }
    v->need_create = false;
    v->prepare_ms = v->r->prepare_ms;
    if (lu_renderer_render(v->r, &v->scene, &v->img, &err) != LU_OK) goto fail;
    v->last_ms = v->r->last_render_ms + (prog ? v->r->prepare_ms : 0.0);
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

/* True when the cached reference was rendered for the current view and lights. */
static bool ref_current(const viewer *v) {
    return v->ref.rgb && memcmp(&v->ref_cam, &v->scene.camera, sizeof v->ref_cam) == 0 &&
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
    memcpy(v->ref_lights, v->scene.lights, (size_t)v->scene.light_count * sizeof *v->ref_lights);
    return true;
}

static void update_error(viewer *v) {
    v->rel_l2 = -1.0;
    lu_metrics m;
    lu_error err;
    if (ref_current(v) && lu_image_compare(&v->img, &v->ref, &m, &err) == LU_OK) v->rel_l2 = m.rel_l2;
}

/* Tone maps like the PNG writer (lu_image_save), then draws the overlay. */
static void compose(viewer *v) {
    int w = v->img.width, h = v->img.height;
    float gain = exp2f(v->exposure);
    for (size_t i = 0; i < (size_t)w * h * 3; i++) {
        float e = lu_srgb_encode(v->img.rgb[i] * gain);
        v->rgb[i] = (uint8_t)lrintf(255.0f * (e < 1.0f ? e : 1.0f));
    }
    if (!v->overlay) return;
    int scale;
    char lines[5][160];
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
    snprintf(lines[3], sizeof lines[3], "light %d/%d %s  %dx%d", v->scene.light_count ? v->light + 1 : 0,
             v->scene.light_count, l ? kinds[l->type] : "-", w, h);
    snprintf(lines[4], sizeof lines[4], "%s", v->status[0] ? v->status : "tab method  +/- quality  arrows light  h hide");
    int bw = 0;
    for (int i = 0; i < 5; i++) {
        int tw = lu_font_text_width(lines[i], 1);
        if (tw > bw) bw = tw;
    }
    /* double size when the widest line still fits */
    scale = 2 * bw + 12 <= w ? 2 : 1;
    bw *= scale;
    int lh = (LU_FONT_H + 3) * scale;
    lu_font_backdrop(v->rgb, w, h, 0, 0, bw + 6 * scale, 5 * lh + 4 * scale);
    static const uint8_t white[3] = {235, 235, 235}, amber[3] = {255, 190, 60}, red[3] = {255, 90, 80};
    for (int i = 0; i < 5; i++)
        lu_font_draw(v->rgb, w, h, 3 * scale, 3 * scale + i * lh, lines[i], scale,
                     i == 0 ? amber : (i == 4 && v->status[0]) ? red : white);
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
    glDrawPixels(v->img.width, v->img.height, GL_RGB, GL_UNSIGNED_BYTE, v->rgb);
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
    v->need_create = true;
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
        v->dirty = true;
        break;
    case GLFW_KEY_TAB:
        v->method_index = (v->method_index + ((mods & GLFW_MOD_SHIFT) ? n - 1 : 1)) % n;
        v->need_create = true;
        reset_accumulation(v);
        break;
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

int lu_cmd_view(int argc, char **argv) {
    const char *scene_path = NULL, *method = "raymarch", *shot = NULL;
    int width = 0, height = 0, frames = 1, rc = LU_EXIT_OK;
    bool compare = false;
    static viewer v;
    memset(&v, 0, sizeof v);
    v.want_backend = LU_BACKEND_GPU;
    v.overlay = true;
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
            if (!lu_cli_parse_backend(argv[++i], &v.want_backend)) rc = lu_cli_usage("view", "--backend takes cpu or gpu");
        } else if (strcmp(a, "--set") == 0 && has_next) {
            if (lu_kv_parse_assignment(&v.settings, argv[++i], &err) != LU_OK) rc = lu_cli_error("view", &err);
        } else if (strcmp(a, "--size") == 0 && has_next) {
            if (!lu_cli_parse_size(argv[++i], &width, &height)) rc = lu_cli_usage("view", "--size takes WxH");
        } else if (strcmp(a, "--exposure") == 0 && has_next) {
            char *end;
            v.exposure = strtof(argv[++i], &end);
            if (*end) rc = lu_cli_usage("view", "--exposure takes a number");
        } else if (strcmp(a, "--compare") == 0) {
            compare = true;
        } else if (strcmp(a, "--no-overlay") == 0) {
            v.overlay = false;
        } else if (strcmp(a, "--screenshot") == 0 && has_next) {
            shot = argv[++i];
        } else if (strcmp(a, "--frames") == 0 && has_next) {
            char *end;
            long n = strtol(argv[++i], &end, 10);
            if (*end || n < 1 || n > 1000000) rc = lu_cli_usage("view", "--frames takes a positive integer");
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
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&v.settings);
        return rc;
    }
    int n;
    const lu_method *const *all = lu_methods(&n);
    for (int i = 0; i < n; i++)
        if (all[i] == m0) v.method_index = i;

    rc = lu_cli_load_scene("view", scene_path, width, height, &v.scene);
    if (rc != LU_EXIT_OK) {
        lu_kv_free(&v.settings);
        return rc;
    }
    v.cam0 = v.scene.camera;
    int w = v.scene.camera.width, h = v.scene.camera.height;
    v.lights0 = malloc((size_t)(v.scene.light_count ? v.scene.light_count : 1) * sizeof *v.lights0);
    v.ref_lights = malloc((size_t)(v.scene.light_count ? v.scene.light_count : 1) * sizeof *v.ref_lights);
    v.rel_l2 = -1.0;
    v.accum = malloc((size_t)w * h * 3 * sizeof(float));
    v.rgb = malloc((size_t)w * h * 3);
    GLFWwindow *win = NULL;
    if (!v.lights0 || !v.ref_lights || !v.accum || !v.rgb || lu_image_create(&v.img, w, h, &err) != LU_OK) {
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
    glfwSetKeyCallback(win, on_key);
    glfwSetMouseButtonCallback(win, on_button);
    glfwSetCursorPosCallback(win, on_cursor);
    glfwSetScrollCallback(win, on_scroll);
    v.need_create = true;
    v.dirty = true;
    if (compare && !render_reference(&v)) fprintf(stderr, "lucent view: %s\n", v.status);
    v.fps_t0 = glfwGetTime();
    int frame = 0;
    while (!glfwWindowShouldClose(win)) {
        /* Deterministic methods render again only after a change;
         * progressive ones keep adding passes (until one fails); --screenshot
         * renders every frame. */
        bool render_now = v.dirty || (progressive(&v) && !v.status[0]) || shot;
        if (render_now) {
            if (render_frame(&v)) update_error(&v);
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
        if (shot && ++frame >= frames) {
            glFinish();
            if (!save_screenshot(w, h, shot, &err)) {
                rc = lu_cli_error("view", &err);
            } else {
                fprintf(stderr, "lucent view: %s after %d frames of %s on %s (last %.1f ms)", shot, frames,
                        current_method(&v)->name, lu_backend_name(backend_for(&v)), v.last_ms);
                if (v.rel_l2 >= 0.0) fprintf(stderr, ", rel-L2 vs reference %.6g", v.rel_l2);
                fputc('\n', stderr);
                if (v.status[0]) rc = LU_EXIT_FAIL;
            }
            break;
        }
        glfwSwapBuffers(win);
        if (render_now) glfwPollEvents();
        else glfwWaitEventsTimeout(0.25);
    }
    /* the method's contexts go before the window's */
    lu_renderer_destroy(v.r);
    v.r = NULL;
    glfwDestroyWindow(win);
    /* No glfwTerminate: it closes the display and unloads the GL driver, and
     * Mesa 22.3's swrast_dri.so leaks on every unload (LeakSanitizer; the same
     * reason the GPU backend never terminates its EGL displays, context.c).
     * The process ends right after this command. */
done:
    lu_renderer_destroy(v.r);
    lu_image_destroy(&v.img);
    lu_image_destroy(&v.ref);
    free(v.ref_lights);
    free(v.accum);
    free(v.rgb);
    free(v.lights0);
    lu_scene_destroy(&v.scene);
    lu_kv_free(&v.settings);
    return rc;
}

#endif
