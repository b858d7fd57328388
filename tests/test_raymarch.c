/* raymarch against the ground truth (`reference`, docs/architecture.md §2).
 *
 * raymarch is the reference's single-scattering integral with the Simpson
 * quadrature replaced by fixed midpoint steps (the optical depth to the
 * lights is the reference's exact kernel). On scenes where that is the only
 * difference — unbounded media, no opaque objects, so no shadow maps, no
 * boundary Fresnel — its error against the reference must vanish as the
 * step count grows: at least first order (each 4x more steps at least 4x
 * less error; the midpoint rule is second order for smooth integrands, first
 * order across a shadow or density discontinuity), down to the reference's
 * own tolerance (0.1 %, doubled for the two renders' errors).
 *
 * Where opaque objects cast shadows through shadow maps, the error at fine
 * steps is the maps' discretisation: it must shrink when the maps get finer.
 *
 * GPU = CPU on every bundled scene is test_cross_backend; here the GPU
 * renders the finest case too, so the convergence holds on both backends. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 32
#define H 24

static bool load(const char *name, lu_scene *s) {
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/%s.json", LU_SOURCE_DIR, name);
    lu_error err = {0};
    lu_result r = lu_scene_load(path, s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return false;
    s->camera.width = W;
    s->camera.height = H;
    return true;
}

static bool render(const lu_scene *s, const char *method, lu_backend b, int steps, int shadow_res, lu_image *img) {
    if (lu_test_skip_gpu(b)) return false;
    lu_kvlist set = {0};
    lu_error err = {0};
    if (steps > 0) {
        double v = steps, r = shadow_res;
        lu_kv_set_number(&set, "raymarch.steps", &v, 1, &err);
        lu_kv_set_number(&set, "raymarch.shadow_res", &r, 1, &err);
    }
    lu_renderer *rd = NULL;
    memset(img, 0, sizeof *img);
    lu_result rc = lu_renderer_create(method, s, &set, b, &rd, &err);
    if (rc == LU_OK) rc = lu_renderer_render(rd, s, img, &err);
    CHECK_OK(rc, &err);
    lu_renderer_destroy(rd);
    lu_kv_free(&set);
    return rc == LU_OK;
}

/* Error vs the reference for 32, 128, 512, 2048 steps. */
static void test_converges_to_reference(void) {
    static const char *const scenes[] = {"smoke_glow", "spot_shaft", "bunny_fog"};
    static const int steps[] = {32, 128, 512, 2048};
    for (int i = 0; i < 3; i++) {
        lu_scene s;
        if (!load(scenes[i], &s)) continue;
        CHECK_MSG(s.object_count == 0 && !s.media[0].has_boundary, "%s: no longer a pure-medium scene", scenes[i]);
        lu_image ref;
        if (!render(&s, "reference", LU_BACKEND_CPU, 0, 0, &ref)) {
            lu_scene_destroy(&s);
            continue;
        }
        double e[4];
        for (int k = 0; k < 4; k++) {
            lu_image img;
            e[k] = 1e30;
            if (!render(&s, "raymarch", LU_BACKEND_CPU, steps[k], 512, &img)) continue;
            e[k] = lu_test_rel_l2(&img, &ref);
            lu_image_destroy(&img);
        }
        fprintf(stderr, "  %-11s rel-L2 vs reference: %.2e (32 steps) %.2e (128) %.2e (512) %.2e (2048)\n", scenes[i],
                e[0], e[1], e[2], e[3]);
        for (int k = 1; k < 4; k++)
            CHECK_MSG(e[k] <= 0.25 * e[k - 1] || e[k] <= 2e-3, "%s: %d steps %.3g, %d steps %.3g", scenes[i],
                      steps[k - 1], e[k - 1], steps[k], e[k]);
        CHECK_MSG(e[3] <= 2e-3, "%s: 2048 steps still %.3g from the reference", scenes[i], e[3]);
        lu_image gpu;
        if (render(&s, "raymarch", LU_BACKEND_GPU, steps[3], 512, &gpu)) {
            double eg = lu_test_rel_l2(&gpu, &ref);
            fprintf(stderr, "  %-11s GPU, 2048 steps: %.2e\n", scenes[i], eg);
            CHECK(eg <= 2e-3);
            lu_image_destroy(&gpu);
        }
        lu_image_destroy(&ref);
        lu_scene_destroy(&s);
    }
}

/* Opaque occluders: at fine steps the shadow maps' resolution sets the error. */
static void test_shadow_maps_converge(void) {
    static const char *const scenes[] = {"smoke_box", "demo"};
    for (int i = 0; i < 2; i++) {
        lu_scene s;
        if (!load(scenes[i], &s)) continue;
        CHECK(s.object_count > 0);
        lu_image ref, a, b;
        if (render(&s, "reference", LU_BACKEND_CPU, 0, 0, &ref)) {
            if (render(&s, "raymarch", LU_BACKEND_CPU, 1024, 64, &a)) {
                if (render(&s, "raymarch", LU_BACKEND_CPU, 1024, 2048, &b)) {
                    double ea = lu_test_rel_l2(&a, &ref), eb = lu_test_rel_l2(&b, &ref);
                    fprintf(stderr, "  %-11s 1024 steps, rel-L2 vs reference: %.2e (64^2 maps) %.2e (2048^2)\n",
                            scenes[i], ea, eb);
                    CHECK_MSG(eb < ea, "%s: finer maps did not help (%.3g vs %.3g)", scenes[i], eb, ea);
                    lu_image_destroy(&b);
                }
                lu_image_destroy(&a);
            }
            lu_image_destroy(&ref);
        }
        lu_scene_destroy(&s);
    }
}

/* A camera ray passing a point light at distance b << step inside a
 * homogeneous medium (a box of constant density, eta 1: no Fresnel). The
 * in-scattered radiance has a closed form up to one smooth integral: with
 * t = tc + b tan(theta) the 1/d^2 peak becomes dtheta / b,
 *   L = sigma_s I / (4 pi b) int exp(-sigma_t ((t - t_in) + b / cos(theta))) dtheta,
 * done here by Simpson in double. A fixed step that samples 1/d^2 at its
 * midpoint is many times too bright when the sample lands beside the light
 * and too dark when the light sits between two samples; the step's mean of
 * 1/d^2 (lu_k_rm_near_light) leaves only the step's variation of the
 * transmittances, at most sigma_t h relative. */
static void test_ray_past_point_light(void) {
    const double sig_s = 0.2, sig_a = 0.05, sig_t = sig_s + sig_a, I = 10.0, b = 0.01;
    /* 16 steps across the box's diagonal 2 sqrt(3): the ray's 2 units take
     * ceil(16 / sqrt(3)) = 10 steps of h = 0.2, samples at z = 0.9, 0.7, ..., 0.1, -0.1, ...:
     * the light at z = 0.1 sits beside a sample, at z = 0 midway between two. */
    const double h = 0.2, zl[2] = {0.1, 0.0};
    for (int k = 0; k < 2; k++) {
        char json[1024];
        snprintf(json, sizeof json,
                 "{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_y_deg\": 10, \"width\": 1, \"height\": 1},"
                 " \"lights\": [{\"type\": \"point\", \"position\": [%.9g, 0, %.9g], \"intensity\": %.9g}],"
                 " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": %.9g, \"sigma_a\": %.9g,"
                 "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 2, 2]}, \"eta\": 1}}]}",
                 b, zl[k], I, sig_s, sig_a);
        lu_scene s;
        lu_error err = {0};
        lu_result r = lu_scene_load_string(json, LU_SOURCE_DIR "/scenes", &s, &err);
        CHECK_OK(r, &err);
        if (r != LU_OK) continue;
        /* camera ray o = (0, 0, 5), d = (0, 0, -1) inside the box for t in [4, 6] */
        double tc = 5.0 - zl[k], ta = atan((4.0 - tc) / b), tb = atan((6.0 - tc) / b), sum = 0.0;
        const int n = 200000;
        for (int i = 0; i <= n; i++) {
            double th = ta + (tb - ta) * i / n, t = tc + b * tan(th);
            double f = exp(-sig_t * ((t - 4.0) + b / cos(th)));
            sum += f * (i == 0 || i == n ? 1.0 : (i % 2 ? 4.0 : 2.0));
        }
        double truth = sig_s * I / (4.0 * LU_PI * b) * sum * (tb - ta) / (3.0 * n);
        lu_image img;
        if (render(&s, "raymarch", LU_BACKEND_CPU, 16, 16, &img)) {
            double got = lu_image_px(&img, 0, 0)[0];
            fprintf(stderr, "  light %s: march %.5g, closed form %.5g (%.2f %%)\n", k ? "between two samples" : "beside a sample", got,
                    truth, 100.0 * (got / truth - 1.0));
            CHECK_NEAR(got, truth, sig_t * h * truth);
            lu_image_destroy(&img);
        }
        lu_image gpu;
        if (render(&s, "raymarch", LU_BACKEND_GPU, 16, 16, &gpu)) {
            CHECK_NEAR(lu_image_px(&gpu, 0, 0)[0], truth, sig_t * h * truth);
            lu_image_destroy(&gpu);
        }
        lu_scene_destroy(&s);
    }
}

/* Distance along d from o (inside the box |x_a| <= half_a) to where the ray
 * leaves it, and the axis of the face it leaves through. */
static double box_exit(const double half[3], const double o[3], const double d[3], int *axis) {
    double t = 1e30;
    *axis = 0;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) continue;
        double ta = ((d[a] > 0 ? half[a] : -half[a]) - o[a]) / d[a];
        if (ta < t) t = ta, *axis = a;
    }
    return t;
}

/* Opaque surfaces seen by the camera are lit with exact visibility, by every
 * method that lights them through lu_view_march.h (raymarch, afm, gradient and
 * its baselines rbf and pervoxel): a room of zero-thickness walls (4 x 2 x 4
 * around the origin; the only medium, which gradient needs, sits behind the
 * room at x = -8, where neither camera rays nor the sun's paths reach) lit by a
 * directional light through a window in its +X wall, the camera inside. A
 * visible point p of a wall with inward normal n is lit iff n . wl > 0 and
 * the ray p + s wl leaves the (convex) room through the window, so in closed
 * form each pixel is either albedo / pi * E * (n . wl) or 0. Shadow maps got
 * this wrong along the room's edges (a texel-centre ray passing just outside
 * the room sees no occluder) and at the sun patch's edges (normal offset and
 * depth bias; 28 of these 3072 pixels): dusty_room was 0.32 rel-L2 off,
 * now 0.015 (docs/gpu.md); gradient 0.34 -> 0.09. Pixels whose camera hit or whose exit through the
 * +X wall lies within 1e-4 of an edge where the answer changes are left out
 * (float rounding may fall either side). */
static void test_surfaces_exact_visibility(void) {
    const double wl_raw[3] = {1.0, 0.6, 0.3}, E = 3.0, albedo = 0.5;
    const double win[4] = {-1.2, -0.5, 1.2, 0.9}; /* z0, y0, z1, y1 on the x = 2 wall */
    const double half[3] = {2.0, 1.0, 2.0}, margin = 1e-4;
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [-1.7, 0.7, -1.6], \"look_at\": [0.6, -0.8, 0.9], \"fov_y_deg\": 80,"
             "  \"width\": 64, \"height\": 48},"
             " \"lights\": [{\"type\": \"directional\", \"direction\": [%g, %g, %g], \"irradiance\": %g}],"
             " \"media\": [{\"density\": {\"procedural\": \"smoke_plume\", \"center\": [-8, 0, 0], \"size\": [1, 1, 1],"
             "   \"resolution\": 16, \"seed\": 4}, \"sigma_s\": [1, 1, 1], \"sigma_a\": [0.1, 0.1, 0.1]}],"
             " \"objects\": [{\"mesh\": {\"procedural\": \"room\", \"size\": [4, 2, 4], \"window\": [%g, %g, %g, %g]},"
             "   \"material\": {\"type\": \"diffuse\", \"albedo\": %g}}]}",
             wl_raw[0], wl_raw[1], wl_raw[2], E, win[0], win[1], win[2], win[3], albedo);
    lu_scene s;
    lu_error err = {0};
    lu_result r = lu_scene_load_string(json, LU_SOURCE_DIR "/scenes", &s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    double wn = sqrt(wl_raw[0] * wl_raw[0] + wl_raw[1] * wl_raw[1] + wl_raw[2] * wl_raw[2]);
    double wl[3] = {wl_raw[0] / wn, wl_raw[1] / wn, wl_raw[2] / wn};
    int w = s.camera.width, h = s.camera.height;
    double *truth = calloc((size_t)w * h, sizeof *truth);
    bool *skip = calloc((size_t)w * h, sizeof *skip);
    int lit = 0;
    for (int y = 0; y < h && truth && skip; y++)
        for (int x = 0; x < w; x++) {
            lu_vec3 of, df;
            lu_camera_ray(&s.camera, x + 0.5f, y + 0.5f, &of, &df);
            double o[3] = {of.x, of.y, of.z}, d[3] = {df.x, df.y, df.z};
            /* the camera is inside: the hit is where the ray leaves the box */
            int face;
            double t = box_exit(half, o, d, &face);
            double p[3], n[3] = {0, 0, 0};
            for (int a = 0; a < 3; a++) p[a] = o[a] + t * d[a];
            n[face] = d[face] > 0 ? -1.0 : 1.0;
            double cl = n[0] * wl[0] + n[1] * wl[1] + n[2] * wl[2];
            /* a hit near another face's plane could be on either face */
            for (int a = 0; a < 3; a++)
                if (a != face && fabs(fabs(p[a]) - half[a]) < margin) skip[y * w + x] = true;
            if (cl <= 0.0) continue;
            /* where the ray to the light leaves the room */
            int exit;
            double sx = box_exit(half, p, wl, &exit);
            if (exit != 0) continue;
            double ey = p[1] + sx * wl[1], ez = p[2] + sx * wl[2];
            double in = fmin(fmin(ey - win[1], win[3] - ey), fmin(ez - win[0], win[2] - ez));
            if (fabs(in) < margin) skip[y * w + x] = true;
            if (in > 0.0) {
                truth[y * w + x] = albedo / LU_PI * E * cl;
                lit++;
            }
        }
    CHECK_MSG(lit > w * h / 20, "the sun patch covers only %d pixels", lit);
    static const char *const methods[] = {"raymarch", "afm", "gradient", "rbf", "pervoxel"};
    for (int k = 0; k < 10 && truth && skip; k++) {
        const char *method = methods[k / 2];
        int b = k % 2;
        lu_image img;
        if (!render(&s, method, b ? LU_BACKEND_GPU : LU_BACKEND_CPU, k < 2 ? 16 : 0, 512, &img)) continue;
        int wrong = 0, first = -1, used = 0;
        double got_first = 0.0;
        for (int i = 0; i < w * h; i++) {
            if (skip[i]) continue;
            used++;
            double got = img.rgb[3 * i];
            if (fabs(got - truth[i]) > 1e-4 * albedo / LU_PI * E + 1e-4 * truth[i]) {
                if (first < 0) first = i, got_first = got;
                wrong++;
            }
        }
        fprintf(stderr, "  %s %s: %d of %d pixels differ from the closed form (%d lit, %d on edges left out)\n",
                method, b ? "GPU" : "CPU", wrong, used, lit, w * h - used);
        CHECK_MSG(wrong == 0, "%s %s: %d pixels wrong, first (%d, %d): %.6g, closed form %.6g", method,
                  b ? "GPU" : "CPU", wrong,
                  first % w, first / w, got_first, first >= 0 ? truth[first] : 0.0);
        lu_image_destroy(&img);
    }
    free(truth);
    free(skip);
    lu_scene_destroy(&s);
}

int main(void) {
    RUN_TEST(test_converges_to_reference);
    RUN_TEST(test_shadow_maps_converge);
    RUN_TEST(test_ray_past_point_light);
    RUN_TEST(test_surfaces_exact_visibility);
    TEST_EXIT();
}
