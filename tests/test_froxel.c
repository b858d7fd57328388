/* froxel (docs/froxel.md): its grid converges to the view march it
 * discretises, its reprojection is the blend it claims, its GPU pass equals
 * its CPU loop, and bad grids are refused.
 *
 * Convergence. With one column per pixel (nx = W, ny = H) every column's
 * centre ray is its pixel's camera ray, and froxel shares everything else
 * with raymarch (the in-scattering kernel, the exact optical depth to the
 * lights, the shadow maps, the surface term): what is left is the depth
 * quadrature. raymarch with 16384 steps stands for the exact integral; its
 * own error obeys the bound below with its step length and is added to it.
 *
 * The bound. On one pixel the single-scattering integral is
 *   L = int f(t) dt,  f(t) = T(t) S(t),  T(t) = exp(-sigma_t int_0^t D).
 * The scene makes every term explicit: a box [-1, 1]^3 of constant density
 * 1 (sigma_s, sigma_a), lit by a directional light of irradiance E straight
 * from above (+y), isotropic phase, no opaque objects, black background.
 * Inside the box S = sigma_s E / (4 pi) exp(-sigma_t (1 - y)) <= f_max =
 * sigma_s E / (4 pi), and along a camera ray of direction d,
 * |S'| = sigma_t |d_y| S. froxel takes, in each slice [t_k, t_k + dz], S and
 * sigma_t D at the slice's midpoint c and integrates T_k exp(-sigma_c (t -
 * t_k)) S_c exactly (lu_froxel.h). Against the exact integral it errs by:
 *   - inside the box, where its transmittance is exact: int T |S - S_c| <=
 *     int T S sigma_t |d_y| |t - c| e^(sigma_t |d_y| dz / 2)
 *     <= (dz / 2) sigma_t |d_y| e^(sigma_t |d_y| dz / 2) L;
 *   - in the slices holding the box's entry and exit, where the midpoint
 *     sample is in or out of the box for the whole slice: each slice's
 *     source is wrong by at most dz f_max, together 2 dz f_max;
 *   - the entry slice's optical depth is wrong by at most sigma_t dz, which
 *     scales everything beyond it: (exp(sigma_t dz) - 1) L.
 * So per pixel |L_froxel - L| <= B(dz) = dz (2 f_max + (sigma_t |d_y| / 2)
 * e^(sigma_t |d_y| dz / 2) L) + (e^(sigma_t dz) - 1) L, with dz the thickest
 * slice and |d_y| <= tan(fov_y / 2). A pixel whose ray misses the box is 0
 * in both images (its column samples the same ray). raymarch errs the same
 * way with its step h, so |a - b| <= sqrt(sum over the box's pixels of
 * (B(dz) + B(h))^2), L taken from raymarch's image. The slices are uniform
 * in log(t - t_lo + n0) (lu_froxel.h), so the thickest is the last,
 * dz = (t_hi - t_lo + n0)(1 - R^(-1/nz)) <= (t_hi - t_lo + n0) ln R / nz.
 * The bound is first order in dz, and so is the error (the entry and exit
 * slices dominate), so it must also halve, roughly, with each doubling of
 * nz: asserted as a factor of at most 0.7 per doubling. The bound is an
 * upper one: the entry and exit slices err with a sign that changes from
 * pixel to pixel as the box face crosses the slices, so the measured
 * rel-L2 lies some 25x below it. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 48
#define H 36

/* Camera at z = 5 looking at the box [-1, 1]^3. */
#define K_BOX_SIGMA_S 0.5
#define K_BOX_SIGMA_A 0.1
#define K_BOX_E 3.0
static const char *k_box =
    "{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 48, \"height\": 36},"
    " \"background\": [0, 0, 0],"
    " \"lights\": [{\"type\": \"directional\", \"direction\": [0, 1, 0], \"irradiance\": [3, 3, 3]}],"
    " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": [0.5, 0.5, 0.5], \"sigma_a\": [0.1, 0.1, 0.1],"
    "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [2, 2, 2]}, \"eta\": 1.0}}]}";

typedef struct seq {
    lu_scene s;
    lu_renderer *r;
} seq;

static bool seq_open(seq *q, const char *json, const char *scene_file, const char *method, lu_backend b,
                     const char *settings) {
    memset(q, 0, sizeof *q);
    lu_error err = {0};
    lu_result rc;
    if (json) {
        rc = lu_scene_load_string(json, "froxel_test.json", &q->s, &err);
    } else {
        char path[1024];
        snprintf(path, sizeof path, "%s/scenes/%s.json", LU_SOURCE_DIR, scene_file);
        rc = lu_scene_load(path, &q->s, &err);
    }
    CHECK_OK(rc, &err);
    if (rc != LU_OK) return false;
    q->s.camera.width = W;
    q->s.camera.height = H;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, settings);
    rc = lu_renderer_create(method, &q->s, &kv, b, &q->r, &err);
    lu_kv_free(&kv);
    CHECK_OK(rc, &err);
    if (rc != LU_OK) {
        lu_scene_destroy(&q->s);
        return false;
    }
    return true;
}

static bool seq_frame(seq *q, lu_image *img) {
    lu_error err = {0};
    memset(img, 0, sizeof *img);
    lu_result rc = lu_renderer_render(q->r, &q->s, img, &err);
    CHECK_OK(rc, &err);
    return rc == LU_OK;
}

static void seq_close(seq *q) {
    lu_renderer_destroy(q->r);
    lu_scene_destroy(&q->s);
}

/* One frame of a fresh renderer. */
static bool render1(const char *json, const char *scene_file, const char *method, lu_backend b, const char *settings,
                    lu_image *img) {
    seq q;
    if (!seq_open(&q, json, scene_file, method, b, settings)) return false;
    bool ok = seq_frame(&q, img);
    seq_close(&q);
    return ok;
}

static double norm2(const lu_image *im) {
    double s = 0.0;
    for (size_t i = 0; i < (size_t)im->width * im->height * 3; i++) s += (double)im->rgb[i] * im->rgb[i];
    return sqrt(s);
}

static void test_converges_to_raymarch(void) {
    lu_image ref;
    if (!render1(k_box, NULL, "raymarch", LU_BACKEND_CPU, "raymarch.steps=16384 raymarch.jitter=0 raymarch.t_cut=0",
                 &ref))
        return;
    double ref_norm = norm2(&ref);
    CHECK_MSG(ref_norm > 0.0, "the box renders black");
    /* The slice distribution the driver builds (froxel.c, fx_grid): the
     * camera is 4 from the box, its far corners sqrt(1 + 1 + 36) away. */
    double t_lo = 4.0, t_hi = sqrt(38.0), near = 0.05;
    double n0 = fmax(t_lo, near * (t_hi - t_lo)), span = t_hi - t_lo + n0, lnR = log(span / n0);
    double sigma_t = K_BOX_SIGMA_S + K_BOX_SIGMA_A, dy = tan(20.0 * M_PI / 180.0);
    double f_max = K_BOX_SIGMA_S * K_BOX_E / (4.0 * M_PI);
    double h = 2.0 * sqrt(3.0) / 16384.0;   /* raymarch's step: the box diagonal / steps */
    static const int nz[] = {16, 32, 64, 128, 256};
    double e[5];
    for (int i = 0; i < 5; i++) {
        char set[256];
        snprintf(set, sizeof set, "froxel.nx=%d froxel.ny=%d froxel.nz=%d froxel.jitter=0 froxel.reproject=0 "
                 "froxel.t_cut=0", W, H, nz[i]);
        lu_image img;
        e[i] = 1e30;
        if (!render1(k_box, NULL, "froxel", LU_BACKEND_CPU, set, &img)) continue;
        e[i] = lu_test_rel_l2(&img, &ref);
        lu_image_destroy(&img);
        double dz = span * lnR / nz[i], sum = 0.0;
        for (size_t p = 0; p < (size_t)W * H * 3; p++) {
            double L = ref.rgb[p];
            if (L <= 0.0) continue;
            double B = 0.0;
            for (int r = 0; r < 2; r++) {
                double z = r ? h : dz;
                B += z * (2.0 * f_max + 0.5 * sigma_t * dy * exp(0.5 * sigma_t * dy * z) * L) + expm1(sigma_t * z) * L;
            }
            sum += B * B;
        }
        double bound = sqrt(sum) / ref_norm;
        fprintf(stderr, "  box nz %4d: rel-L2 vs raymarch %.4g (bound %.4g)\n", nz[i], e[i], bound);
        CHECK_MSG(e[i] <= bound, "nz %d: rel-L2 %.4g above the derived bound %.4g", nz[i], e[i], bound);
        if (i > 0)
            CHECK_MSG(e[i] <= 0.7 * e[i - 1], "nz %d -> %d: error %.4g -> %.4g, not first order", nz[i - 1], nz[i],
                      e[i - 1], e[i]);
    }
    lu_image_destroy(&ref);
}

/* The whole grid refined on a bundled scene with opaque objects and shadow
 * maps (dusty_room: a sun shaft through a window): columns, rows and slices
 * doubled together from a quarter of the image; the error must fall with
 * each step (the columns' lateral interpolation is first order at the
 * shaft's edges too). */
static void test_grid_refinement_dusty_room(void) {
    lu_image ref;
    if (!render1(NULL, "dusty_room", "raymarch", LU_BACKEND_CPU, "raymarch.steps=2048 raymarch.jitter=0", &ref)) return;
    double prev = 1e30;
    for (int f = 4; f >= 1; f /= 2) {
        char set[256];
        snprintf(set, sizeof set, "froxel.nx=%d froxel.ny=%d froxel.nz=%d froxel.jitter=0 froxel.reproject=0", W / f,
                 H / f, 128 / f);
        lu_image img;
        if (!render1(NULL, "dusty_room", "froxel", LU_BACKEND_CPU, set, &img)) continue;
        double e = lu_test_rel_l2(&img, &ref);
        lu_image_destroy(&img);
        fprintf(stderr, "  dusty_room grid 1/%d: rel-L2 vs raymarch %.4g\n", f, e);
        CHECK_MSG(e < 0.85 * prev, "grid 1/%d: rel-L2 %.4g did not fall from %.4g", f, e, prev);
        prev = e;
    }
    lu_image_destroy(&ref);
}

/* Reprojection without jitter on a still camera maps each cell onto itself
 * (the blend of equal values): the frames equal the unblended frame. After
 * the camera moves, the lit volume is (1 - a) V_new + a R(V_old) and then,
 * still again, its distance from V_new shrinks by the blend weight a each
 * frame; so does the image's distance from a fresh render, once it is small
 * enough to be linear in the volume. */
static void test_reprojection(void) {
    const char *scene = "spot_shaft";
    const char *grid = "froxel.nx=24 froxel.ny=18 froxel.nz=32 froxel.jitter=0";
    char set[256];
    snprintf(set, sizeof set, "%s froxel.reproject=0", grid);
    lu_image plain;
    if (!render1(NULL, scene, "froxel", LU_BACKEND_CPU, set, &plain)) return;
    snprintf(set, sizeof set, "%s froxel.reproject=1 froxel.blend=0.5", grid);
    seq q;
    if (!seq_open(&q, NULL, scene, "froxel", LU_BACKEND_CPU, set)) {
        lu_image_destroy(&plain);
        return;
    }
    for (int n = 0; n < 3; n++) {
        lu_image img;
        if (!seq_frame(&q, &img)) break;
        double e = lu_test_rel_l2(&img, &plain);
        CHECK_MSG(e <= 1e-5, "still frame %d with reprojection: rel-L2 %.3g from the unblended frame", n, e);
        lu_image_destroy(&img);
    }
    /* move the camera sideways, render the new view fresh, then follow it */
    q.s.camera.position.x += 0.6f;
    lu_image fresh;
    lu_scene moved = q.s;
    bool ok = false;
    {
        lu_error err = {0};
        lu_kvlist kv = {0};
        snprintf(set, sizeof set, "%s froxel.reproject=0", grid);
        lu_test_settings(&kv, set);
        lu_renderer *r = NULL;
        lu_result rc = lu_renderer_create("froxel", &moved, &kv, LU_BACKEND_CPU, &r, &err);
        memset(&fresh, 0, sizeof fresh);
        if (rc == LU_OK) rc = lu_renderer_render(r, &moved, &fresh, &err);
        CHECK_OK(rc, &err);
        ok = rc == LU_OK;
        lu_renderer_destroy(r);
        lu_kv_free(&kv);
    }
    double e[8];
    for (int n = 0; ok && n < 8; n++) {
        lu_image img;
        if (!seq_frame(&q, &img)) break;
        e[n] = lu_test_rel_l2(&img, &fresh);
        lu_image_destroy(&img);
        fprintf(stderr, "  frame %d after the move: rel-L2 vs a fresh render %.4g\n", n, e[n]);
        if (n == 0) CHECK_MSG(e[0] > 1e-3, "the first frame after a move does not lag (rel-L2 %.3g)", e[0]);
        if (n >= 5) CHECK_MSG(fabs(e[n] / e[n - 1] - 0.5) < 0.1, "frame %d: error ratio %.3g, expected the blend 0.5", n,
                              e[n] / e[n - 1]);
    }
    if (ok) lu_image_destroy(&fresh);
    lu_image_destroy(&plain);
    seq_close(&q);
}

/* GPU = CPU on tiny images, frame by frame through a still sequence with
 * jitter and reprojection and a camera move (the history path). */
static void test_gpu_equals_cpu(void) {
    if (lu_test_skip_gpu(LU_BACKEND_GPU)) return;
    static const char *const scenes[] = {"dusty_room", "smoke_glow", "layered_cube"};
    const char *set = "froxel.nx=24 froxel.ny=18 froxel.nz=24 froxel.shadow_res=128";
    for (int i = 0; i < 3; i++) {
        seq c, g;
        if (!seq_open(&c, NULL, scenes[i], "froxel", LU_BACKEND_CPU, set)) continue;
        if (!seq_open(&g, NULL, scenes[i], "froxel", LU_BACKEND_GPU, set)) {
            seq_close(&c);
            continue;
        }
        for (int n = 0; n < 3; n++) {
            if (n == 2) {
                c.s.camera.position.y += 0.2f;
                g.s.camera.position.y += 0.2f;
            }
            lu_image a, b;
            if (!seq_frame(&c, &a)) break;
            if (!seq_frame(&g, &b)) {
                lu_image_destroy(&a);
                break;
            }
            double e = lu_test_rel_l2(&b, &a);
            fprintf(stderr, "  %s frame %d: GPU vs CPU rel-L2 %.3g\n", scenes[i], n, e);
            CHECK_MSG(norm2(&a) > 0.0, "%s: black image", scenes[i]);
            CHECK_MSG(e <= 1e-4, "%s frame %d: GPU vs CPU rel-L2 %.3g", scenes[i], n, e);
            lu_image_destroy(&a);
            lu_image_destroy(&b);
        }
        seq_close(&c);
        seq_close(&g);
    }
}

/* Culling leaves unlit only cells beyond every ray end of the pixels that
 * read their column, so the image is the unculled one: on scenes with
 * opaque objects in and around the media, both backends. */
static void test_cull_invisible(void) {
    static const char *const scenes[] = {"dusty_room", "demo", "cube_torus"};
    for (int i = 0; i < 3; i++)
        for (int b = 0; b < 2; b++) {
            lu_backend be = b ? LU_BACKEND_GPU : LU_BACKEND_CPU;
            if (lu_test_skip_gpu(be)) continue;
            const char *grid = "froxel.nx=24 froxel.ny=18 froxel.nz=32 froxel.jitter=0 froxel.reproject=0";
            char set[256];
            lu_image a, c;
            snprintf(set, sizeof set, "%s froxel.cull=0", grid);
            if (!render1(NULL, scenes[i], "froxel", be, set, &a)) continue;
            snprintf(set, sizeof set, "%s froxel.cull=1", grid);
            if (render1(NULL, scenes[i], "froxel", be, set, &c)) {
                double e = lu_test_rel_l2(&c, &a);
                CHECK_MSG(e <= 1e-6, "%s (%s): culled image differs by rel-L2 %.3g", scenes[i], b ? "gpu" : "cpu", e);
                lu_image_destroy(&c);
            }
            lu_image_destroy(&a);
        }
}

static void test_bad_settings(void) {
    static const char *const bad[] = {"froxel.nx=0",       "froxel.ny=5000",   "froxel.nz=0",
                                      "froxel.nz=2000",    "froxel.blend=1",   "froxel.near=0",
                                      "froxel.nx=2.5",     "froxel.jitter=2",  "froxel.nx=4096 froxel.ny=4096 froxel.nz=8"};
    lu_scene s;
    lu_error err = {0};
    CHECK_OK(lu_scene_load_string(k_box, "froxel_test.json", &s, &err), &err);
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        lu_kvlist kv = {0};
        lu_test_settings(&kv, bad[i]);
        lu_renderer *r = NULL;
        lu_error e2 = {0};
        lu_result rc = lu_renderer_create("froxel", &s, &kv, LU_BACKEND_CPU, &r, &e2);
        CHECK_MSG(rc == LU_ERR_RANGE, "%s: expected a range error, got %d (%s)", bad[i], (int)rc, e2.message);
        CHECK_MSG(strstr(e2.message, "froxel") != NULL || strstr(e2.message, "nx") != NULL, "%s: message \"%s\"", bad[i],
                  e2.message);
        fprintf(stderr, "  %-44s -> %s\n", bad[i], e2.message);
        lu_renderer_destroy(r);
        lu_kv_free(&kv);
    }
    lu_scene_destroy(&s);
}

int main(void) {
    RUN_TEST(test_bad_settings);
    RUN_TEST(test_converges_to_raymarch);
    RUN_TEST(test_grid_refinement_dusty_room);
    RUN_TEST(test_reprojection);
    RUN_TEST(test_gpu_equals_cpu);
    RUN_TEST(test_cull_invisible);
    TEST_EXIT();
}
