/* ddod: SH projection of known functions (closed forms and independent
 * quadrature), the Gaussian line integral against quadrature, Poisson-disk
 * radii and count, the precomputed attenuation of a homogeneous sphere
 * against its analytic chord, the traced attenuation of the render path
 * against the same closed forms and its recomputation when the camera or a
 * light moves, the cache round trip and its errors, and images against
 * `reference` (and GPU against CPU). */
#include <lucent/lucent.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "lu_test.h"
#include "methods/ddod/ddod.h"
#include "methods/methods.h"
#include "kernels/lu_medium.h"

/* No context is needed for the pure functions of the kernel. */
struct lu_k_ctx {
    const float *sh;
};
static inline float lu_k_ddod_coeff(const struct lu_k_ctx *c, int index) { return c->sh[index]; }
static inline float lu_k_ddod_sample_f(const struct lu_k_ctx *c, int i, int k) { return 0.0f; }
static inline lu_vec3 lu_k_ddod_radiance(const struct lu_k_ctx *c, int i) { return lu_v3s(0.0f); }
static inline float lu_k_ddod_pixel_f(const struct lu_k_ctx *c, int pixel, int k) { return 0.0f; }
static inline int lu_k_ddod_tile_start(const struct lu_k_ctx *c, int tile) { return 0; }
static inline int lu_k_ddod_tile_item(const struct lu_k_ctx *c, int k) { return 0; }
static inline lu_vec3 lu_k_ddod_env_coeff(const struct lu_k_ctx *c, int k) { return lu_v3s(0.0f); }
static inline lu_vec3 lu_k_ddod_traced(const struct lu_k_ctx *c, int k) { return lu_v3s(0.0f); }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) {
    lu_k_medium k;
    memset(&k, 0, sizeof k);
    return k;
}
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return 0; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) {
    lu_k_light k;
    memset(&k, 0, sizeof k);
    return k;
}
#include "methods/ddod/lu_ddod.h"

static double legendre_p(int l, double x) {
    double p0 = 1.0, p1 = x;
    if (l == 0) return 1.0;
    for (int k = 2; k <= l; k++) {
        double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    return p1;
}

/* Zonal coefficients c_l = 2 pi K_l int_{-1}^{1} f(mu) P_l(mu) dmu of a
 * function of cos(theta) about z, by 400-node Gauss-Legendre. */
static void zonal_coeffs(double (*f)(double, double), double param, int bands, double *c) {
    enum { N = 400 };
    static double x[N], w[N];
    static bool ready = false;
    if (!ready) lu_test_gauss_legendre(N, x, w), ready = true;
    for (int l = 0; l < bands; l++) {
        double s = 0.0;
        for (int i = 0; i < N; i++) s += w[i] * f(x[i], param) * legendre_p(l, x[i]);
        c[l] = 2.0 * M_PI * sqrt((2 * l + 1) / (4.0 * M_PI)) * s;
    }
}

static double f_lobe(double mu, double k) { return exp(-k * (1.0 - mu)); }  /* exp(-tau) lobe about z */

static void test_sh_projection(void) {
    enum { N = 2048 };
    lu_vec3 *dirs = malloc(N * sizeof *dirs);
    float *f = malloc(N * sizeof *f);
    lu_ddod_directions(N, dirs);
    float c[LU_SH_MAX_COEFFS];
    /* constant: only Y_00 = 1 / (2 sqrt(pi)), exactly (the Fibonacci set's
     * z values are symmetric, so odd bands vanish to rounding) */
    for (int j = 0; j < N; j++) f[j] = 0.7f;
    lu_ddod_sh_project(N, dirs, f, 6, c);
    CHECK_NEAR(c[0], 0.7 * 2.0 * sqrt(M_PI), 1e-5);
    double worst = 0.0;
    for (int k = 1; k < 36; k++) worst = fmax(worst, fabs(c[k]));
    CHECK_MSG(worst < 2e-3, "constant leaks %.3g into higher bands", worst);
    /* clamped cosine lobe: c_l0 = K_l A_l (Ramamoorthi-Hanrahan A_l, lu_sh.h) */
    for (int j = 0; j < N; j++) f[j] = fmaxf(dirs[j].z, 0.0f);
    lu_ddod_sh_project(N, dirs, f, 6, c);
    for (int l = 0; l < 6; l++) {
        double want = sqrt((2 * l + 1) / (4.0 * M_PI)) * lu_k_sh_lambert_band(l);
        CHECK_NEAR(c[l * (l + 1)], want, 3e-3);
    }
    /* narrow exp(-tau) lobes: the projected coefficients match independent
     * quadrature, and the reconstruction's L2 error over the sphere is the
     * truncation bound sqrt(int f^2 - sum c_l^2) of its order (Parseval). */
    double ks[2] = {2.0, 8.0};
    for (int t = 0; t < 2; t++) {
        double k = ks[t], zc[6];
        zonal_coeffs(f_lobe, k, 6, zc);
        for (int j = 0; j < N; j++) f[j] = (float)f_lobe(dirs[j].z, k);
        lu_ddod_sh_project(N, dirs, f, 6, c);
        for (int l = 0; l < 6; l++) CHECK_NEAR(c[l * (l + 1)], zc[l], 2e-3 * (1.0 + fabs(zc[0])));
        double f2 = (1.0 - exp(-4.0 * k)) * 2.0 * M_PI / (2.0 * k); /* int exp(-2k(1-mu)) */
        for (int bands = 3; bands <= 6; bands++) {
            double bound = f2;
            for (int l = 0; l < bands; l++) bound -= zc[l] * zc[l];
            bound = sqrt(fmax(bound, 0.0));
            double e2 = 0.0;
            struct lu_k_ctx ctx = {c};
            lu_ddod_sh_project(N, dirs, f, bands, c);
            for (int j = 0; j < N; j++) {
                double d = lu_k_ddod_sh_dot(&ctx, 0, bands, dirs[j]) - f[j];
                e2 += d * d * 4.0 * M_PI / N;
            }
            fprintf(stderr, "  exp(-%g(1-cos)) lobe, %d bands: L2 error %.4f, truncation bound %.4f\n", k, bands,
                    sqrt(e2), bound);
            CHECK(sqrt(e2) <= 1.02 * bound + 1e-3);
        }
    }
    /* the kernel's erf (A&S 7.1.26, 1.5e-7, plus float rounding) against libm */
    for (double x = -3.0; x <= 3.0; x += 0.25) CHECK_NEAR(lu_k_erf((float)x), erf(x), 5e-7);
    free(dirs);
    free(f);
}

/* The 8-band extension of lu_sh.h (64 coefficients) is orthonormal:
 * Gauss-Legendre in cos(theta) (16 nodes, exact to degree 31) times a
 * uniform phi rule (32 nodes, exact to trigonometric degree 31). */
static void test_sh_orthonormal_8(void) {
    enum { NT = 16, NP = 32, NC = 64 };
    double gx[NT], gw[NT];
    lu_test_gauss_legendre(NT, gx, gw);
    static double gram[NC][NC];
    float y[LU_SH_MAX_COEFFS];
    for (int i = 0; i < NT; i++)
        for (int k = 0; k < NP; k++) {
            double st = sqrt(1.0 - gx[i] * gx[i]), ph = 2.0 * M_PI * (k + 0.5) / NP;
            lu_k_sh_eval(lu_v3((float)(st * cos(ph)), (float)(st * sin(ph)), (float)gx[i]), 8, y);
            for (int a = 0; a < NC; a++)
                for (int b = a; b < NC; b++) gram[a][b] += gw[i] * (2.0 * M_PI / NP) * y[a] * y[b];
        }
    double worst = 0.0;
    for (int a = 0; a < NC; a++)
        for (int b = a; b < NC; b++) worst = fmax(worst, fabs(gram[a][b] - (a == b ? 1.0 : 0.0)));
    fprintf(stderr, "  SH (8 bands) Gram matrix max deviation from identity: %.2g\n", worst);
    CHECK(worst < 2e-5);
}

static void test_gauss_line(void) {
    lu_vec3 b = lu_v3(0.3f, -0.2f, 0.5f);
    float s = 0.17f;
    for (int t = 0; t < 20; t++) {
        lu_vec3 o = lu_v3(-1.0f + 0.1f * t, 0.05f * t - 0.4f, -2.0f);
        lu_vec3 d = lu_v3_norm(lu_v3(0.1f * (t % 5) - 0.2f, 0.03f * t - 0.3f, 1.0f));
        float t0 = 1.0f + 0.05f * t, t1 = 3.5f - 0.07f * t;
        /* 20000-point midpoint rule of the Gaussian along the segment */
        double q = 0.0;
        int n = 20000;
        for (int i = 0; i < n; i++) {
            double tt = t0 + (t1 - t0) * (i + 0.5) / n;
            double x = o.x + tt * d.x - b.x, y = o.y + tt * d.y - b.y, z = o.z + tt * d.z - b.z;
            q += exp(-(x * x + y * y + z * z) / (2.0 * s * s));
        }
        q *= (t1 - t0) / n;
        CHECK_NEAR(lu_k_ddod_gauss_line(o, d, b, s, t0, t1), q, 1e-6 + 1e-5 * q);
    }
    CHECK(lu_k_ddod_gauss_line(lu_v3s(0.0f), lu_v3(0, 0, 1), b, s, 2.0f, 1.0f) == 0.0f);
}

static void test_poisson(void) {
    /* radius grows along x from 0.03 to 0.12 over a 1 x 0.5 x 0.5 box */
    int n[3] = {40, 20, 20};
    float h = 0.025f;
    size_t nv = (size_t)n[0] * n[1] * n[2];
    float *rad = malloc(nv * sizeof *rad);
    for (int z = 0; z < n[2]; z++)
        for (int y = 0; y < n[1]; y++)
            for (int x = 0; x < n[0]; x++) rad[((size_t)z * n[1] + y) * n[0] + x] = 0.03f + 0.09f * (x + 0.5f) / n[0];
    lu_ddod_field f = {{n[0], n[1], n[2]}, lu_v3s(0.0f), h, rad};
    float *pts, *r;
    int count;
    lu_error err;
    CHECK_OK(lu_ddod_poisson(&f, 1.0f, 40000, 7, &pts, &r, &count, &err), &err);
    int bad = 0;
    for (int i = 0; i < count; i++)
        for (int j = i + 1; j < count; j++) {
            float dx = pts[3 * i] - pts[3 * j], dy = pts[3 * i + 1] - pts[3 * j + 1], dz = pts[3 * i + 2] - pts[3 * j + 2];
            float m = fmaxf(r[i], r[j]);
            bad += dx * dx + dy * dy + dz * dz < m * m;
        }
    CHECK_MSG(bad == 0, "%d pairs closer than their radius", bad);
    /* every point's radius is its voxel's */
    int wrong = 0, left = 0;
    for (int i = 0; i < count; i++) {
        int x = (int)(pts[3 * i] / h);
        wrong += fabsf(r[i] - (0.03f + 0.09f * (x + 0.5f) / n[0])) > 1e-6f;
        left += pts[3 * i] < 0.5f;
    }
    CHECK(wrong == 0);
    /* denser where the radius is smaller */
    CHECK_MSG(left > 2 * (count - left), "%d of %d points in the small-radius half", left, count);
    lu_free(pts);
    lu_free(r);
    free(rad);
}

static const char *k_sphere =
    "{\"camera\": {\"position\": [0, 0.6, 3.6], \"look_at\": [0, 0, 0], \"fov_y_deg\": 40, \"width\": 40, \"height\": 40},"
    " \"lights\": [{\"type\": \"point\", \"position\": [2.5, 2.0, 2.0], \"intensity\": [60, 60, 60]},"
    "              {\"type\": \"point\", \"position\": [-2.0, 1.0, -2.5], \"intensity\": [30, 30, 30]}],"
    " \"media\": [{\"density\": {\"constant\": 1}, \"sigma_s\": 1.6, \"sigma_a\": 0.1,"
    "   \"boundary\": {\"mesh\": {\"procedural\": \"sphere\", \"radius\": 1.0, \"subdivisions\": 5}, \"eta\": 1.3}}]}";

/* The chord from b to a unit sphere along w: -b.w + sqrt((b.w)^2 - |b|^2 + 1). */
static double chord(lu_vec3 b, lu_vec3 w) {
    double bw = lu_v3_dot(b, w), bb = lu_v3_dot(b, b);
    return -bw + sqrt(bw * bw - bb + 1.0);
}

static void test_sphere_attenuation(void) {
    lu_scene s;
    lu_error err;
    CHECK_OK(lu_scene_load_string(k_sphere, "sphere.json", &s, &err), &err);
    lu_ddod_params p = {48, 512, 3000, 6, 0.6f, 1, 0};
    lu_ddod_set set;
    CHECK_OK(lu_ddod_compute(&s, &p, &set, &err), &err);
    CHECK_MSG(abs(set.count - p.samples) <= p.samples / 10, "%d samples for a target of %d", set.count, p.samples);
    CHECK(set.channels == 1 && set.stride == 2 * 36);
    /* Every sample inside the sphere; psi from the SH against exp(-sigma_t
     * chord) and psi^F against the same times F_t at the exit: RMS over
     * samples and directions, deep samples (|b| < 0.6: smooth functions)
     * and all. */
    double e_deep = 0.0, e_all = 0.0, ef_deep = 0.0;
    int n_deep = 0, n_all = 0, outside = 0;
    struct lu_k_ctx ctx = {set.sh};
    lu_vec3 dirs[64];
    lu_ddod_directions(64, dirs);
    for (int i = 0; i < set.count; i++) {
        const float *sm = set.samples + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        lu_vec3 b = lu_v3(sm[0], sm[1], sm[2]);
        outside += lu_v3_len(b) > 1.0f;
        bool deep = lu_v3_len(b) < 0.6f;
        for (int j = 0; j < 64; j++) {
            lu_vec3 w = lu_v3_norm(lu_v3(dirs[j].x + 0.1f, dirs[j].y, dirs[j].z - 0.05f));
            double c = chord(b, w), want = exp(-1.7 * c);
            lu_vec3 x = lu_v3_madd(b, w, (float)c);
            double wantf = want * lu_k_fresnel_transmittance(lu_v3_dot(lu_v3_norm(x), w), 1.3f);
            double got = lu_k_ddod_sh_dot(&ctx, i * set.stride, 6, w);
            double gotf = lu_k_ddod_sh_dot(&ctx, i * set.stride + 36, 6, w);
            e_all += (got - want) * (got - want);
            n_all++;
            if (deep) {
                e_deep += (got - want) * (got - want);
                ef_deep += (gotf - wantf) * (gotf - wantf);
                n_deep++;
            }
        }
    }
    e_deep = sqrt(e_deep / n_deep);
    ef_deep = sqrt(ef_deep / n_deep);
    e_all = sqrt(e_all / n_all);
    fprintf(stderr, "  sphere psi RMS error: deep %.4f (with Fresnel %.4f), all %.4f\n", e_deep, ef_deep, e_all);
    CHECK(outside == 0);
    CHECK(e_deep < 0.01);
    CHECK(ef_deep < 0.01);
    CHECK(e_all < 0.05);
    lu_ddod_set_free(&set);
    lu_scene_destroy(&s);
}

/* The traced table of the render path (ddod.view_psi / light_psi =
 * traced) against the closed forms on the homogeneous unit sphere: towards
 * each point light exp(-sigma_t chord) F_t(exit), towards the camera
 * exp(-sigma_t chord). The boundary is a subdivided icosahedron, so each
 * entry is allowed what the facets can move it: a facet normal tilts by at
 * most delta (measured on the mesh: the largest angle between a face's
 * normal and its vertices, which lie on the sphere), so F_t may take any
 * value over [theta - delta, theta + delta]; the facets lie inside the
 * sphere by at most 1 - cos(delta), which shortens the chord by up to
 * that over cos(theta). Plus 1e-4 for float rounding. */
static void test_traced_sphere(void) {
    lu_scene s;
    lu_error err;
    CHECK_OK(lu_scene_load_string(k_sphere, "sphere.json", &s, &err), &err);
    const lu_mesh *mesh = &s.media[0].boundary;
    float delta = 0.0f;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        lu_vec3 p[3];
        for (int k = 0; k < 3; k++) p[k] = mesh->positions[mesh->indices[3 * t + k]];
        lu_vec3 ng = lu_v3_norm(lu_v3_cross(lu_v3_sub(p[1], p[0]), lu_v3_sub(p[2], p[0])));
        for (int k = 0; k < 3; k++) delta = fmaxf(delta, acosf(fminf(lu_v3_dot(ng, lu_v3_norm(p[k])), 1.0f)));
    }
    float sag = 1.0f - cosf(delta);
    lu_kvlist kv = {0};
    const char *sets[] = {"ddod.res=48", "ddod.dirs=32", "ddod.samples=3000", "ddod.cache=0", NULL};
    for (int i = 0; sets[i]; i++) CHECK_OK(lu_kv_parse_assignment(&kv, sets[i], &err), &err);
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_create("ddod", &s, &kv, LU_BACKEND_CPU, &r, &err), &err);
    lu_kv_free(&kv);
    lu_image img = {0};
    CHECK_OK(lu_image_create(&img, s.camera.width, s.camera.height, &err), &err);
    CHECK_OK(lu_renderer_render(r, &s, &img, &err), &err);
    int nl = 0, count = 0;
    const float *samples = NULL;
    const float *tab = lu_ddod_traced_table(r, &nl, &count, &samples);
    CHECK(tab != NULL && nl == 2 && count > 2000);
    double worst = 0.0, sq = 0.0;
    int n = 0, outside = 0;
    for (int i = 0; tab && i < count; i++) {
        const float *sm = samples + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        lu_vec3 b = lu_v3(sm[0], sm[1], sm[2]);
        for (int e = 0; e <= nl; e++) {
            lu_vec3 target = e == 0 ? s.camera.position : s.lights[e - 1].position;
            lu_vec3 w = lu_v3_norm(lu_v3_sub(target, b));
            double c = chord(b, w), att = exp(-1.7 * c);
            float cos_exit = lu_v3_dot(lu_v3_norm(lu_v3_madd(b, w, (float)c)), w);
            double want = att, slack = 1e-4 + att * (1.0 - exp(-1.7 * sag / fmaxf(cos_exit, 1e-3f)));
            if (e > 0) {
                float th = acosf(fminf(cos_exit, 1.0f));
                float f0 = lu_k_fresnel_transmittance(cos_exit, 1.3f);
                float fa = lu_k_fresnel_transmittance(cosf(fmaxf(th - delta, 0.0f)), 1.3f);
                float fb = lu_k_fresnel_transmittance(cosf(fminf(th + delta, 0.5f * (float)M_PI)), 1.3f);
                want *= f0;
                slack = slack * f0 + att * fmaxf(fabsf(fa - f0), fabsf(fb - f0));
            }
            const float *got = tab + ((size_t)i * (nl + 1) + e) * 4;
            double d = fabs(got[0] - want);
            CHECK(got[0] == got[1] && got[1] == got[2]);  /* grey sigma_t */
            sq += d * d;
            n++;
            outside += d > slack;
            worst = fmax(worst, d / slack);
        }
    }
    double rms = sqrt(sq / (n ? n : 1));
    fprintf(stderr,
            "  traced psi vs closed form (facet tilt %.3f rad): %d of %d entries outside their facet bound, worst "
            "%.2f of it; RMS %.2e\n",
            delta, outside, n, worst, rms);
    CHECK(n > 6000 && outside == 0);
    CHECK(rms < 5e-3);
    lu_image_destroy(&img);
    lu_renderer_destroy(r);
    lu_scene_destroy(&s);
}

/* The traced table follows the scene: moving a light recomputes only that
 * light's entries, moving the camera only the view entries, changing a
 * light's colour neither, adding or removing a light both; each frame then equals a fresh renderer's frame
 * of the changed scene bit for bit (same sample set), and a GPU renderer
 * kept across the same frames matches the CPU. */
static void test_traced_update(void) {
    lu_scene s;
    lu_error err;
    CHECK_OK(lu_scene_load_string(k_sphere, "sphere.json", &s, &err), &err);
    lu_kvlist kv = {0};
    const char *sets[] = {"ddod.res=32", "ddod.dirs=16", "ddod.samples=2000", "ddod.cache=0", NULL};
    for (int i = 0; sets[i]; i++) CHECK_OK(lu_kv_parse_assignment(&kv, sets[i], &err), &err);
    lu_renderer *r = NULL, *gpu = NULL;
    CHECK_OK(lu_renderer_create("ddod", &s, &kv, LU_BACKEND_CPU, &r, &err), &err);
    /* The GPU keeps its copy of the table between frames: it must follow too. */
    if (lu_renderer_create("ddod", &s, &kv, LU_BACKEND_GPU, &gpu, &err) != LU_OK)
        fprintf(stderr, "  GPU unavailable, skipped: %s\n", err.message);
    lu_image a = {0}, b = {0}, g = {0};
    CHECK_OK(lu_image_create(&a, s.camera.width, s.camera.height, &err), &err);
    CHECK_OK(lu_image_create(&b, s.camera.width, s.camera.height, &err), &err);
    CHECK_OK(lu_image_create(&g, s.camera.width, s.camera.height, &err), &err);
    lu_ddod_stats st;
    int want_view = 0, want_lights = 0, want_retraced = 0;
    for (int step = 0; step < 7; step++) {
        if (step == 1) s.lights[0].position = lu_v3(1.0f, 2.5f, -2.0f), want_lights++, want_retraced += 1;
        if (step == 2) s.camera.position = lu_v3(0.5f, 1.0f, 3.4f), want_view++;
        if (step == 3) s.lights[1].intensity = lu_v3(10.0f, 20.0f, 40.0f);
        if (step == 0) want_view++, want_lights++, want_retraced += 2;
        if (step == 5) {  /* a third light: the table grows (view entries retraced with it) */
            lu_light *l = lu_realloc(s.lights, 3 * sizeof *l);
            CHECK(l != NULL);
            if (!l) break;
            s.lights = l;
            s.lights[2] = s.lights[0];
            s.lights[2].position = lu_v3(-1.5f, -2.0f, 2.5f);
            s.light_count = 3;
            want_view++, want_lights++, want_retraced += 3;
        }
        if (step == 6) s.light_count = 2, want_view++, want_lights++, want_retraced += 2;
        CHECK_OK(lu_renderer_render(r, &s, &a, &err), &err);
        CHECK(lu_ddod_last_stats(r, &st));
        CHECK_MSG(st.traced_view_updates == want_view && st.traced_light_updates == want_lights,
                  "step %d: %d view and %d light updates, want %d and %d", step, st.traced_view_updates,
                  st.traced_light_updates, want_view, want_lights);
        CHECK_MSG(st.traced_lights_retraced == want_retraced, "step %d: %d lights retraced in all, want %d", step,
                  st.traced_lights_retraced, want_retraced);
        lu_renderer *fresh = NULL;
        CHECK_OK(lu_renderer_create("ddod", &s, &kv, LU_BACKEND_CPU, &fresh, &err), &err);
        CHECK_OK(lu_renderer_render(fresh, &s, &b, &err), &err);
        CHECK_MSG(memcmp(a.rgb, b.rgb, (size_t)a.width * a.height * 3 * sizeof(float)) == 0,
                  "step %d: the kept table differs from a fresh one", step);
        lu_renderer_destroy(fresh);
        if (gpu) {
            CHECK_OK(lu_renderer_render(gpu, &s, &g, &err), &err);
            double e = lu_test_rel_l2(&g, &a);
            CHECK_MSG(e < 1e-3, "step %d: GPU vs CPU rel-L2 %.3g", step, e);
        }
    }
    lu_kv_free(&kv);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
    lu_image_destroy(&g);
    lu_renderer_destroy(r);
    lu_renderer_destroy(gpu);
    lu_scene_destroy(&s);
}

static void test_cache(void) {
    lu_scene s;
    lu_error err;
    CHECK_OK(lu_scene_load_string(k_sphere, "sphere.json", &s, &err), &err);
    lu_ddod_params p = {24, 32, 400, 3, 0.8f, 1, 2};
    lu_ddod_set a, b;
    CHECK_OK(lu_ddod_compute(&s, &p, &a, &err), &err);
    char path[256];
    snprintf(path, sizeof path, "%s/test_ddod_cache_%d.bin", LU_BINARY_DIR, (int)getpid());
    uint64_t key = lu_ddod_key(&s, &p);
    CHECK_OK(lu_ddod_cache_save(path, key, &a, &err), &err);
    CHECK_OK(lu_ddod_cache_load(path, key, &b, &err), &err);
    CHECK(b.count == a.count && b.stride == a.stride && b.timing.from_cache);
    CHECK(b.count > 0 && memcmp(a.samples, b.samples, (size_t)a.count * LU_K_DDOD_SAMPLE_FLOATS * 4) == 0);
    CHECK(b.count > 0 && memcmp(a.sh, b.sh, (size_t)a.count * a.stride * 4) == 0);
    lu_ddod_set_free(&b);
    /* other inputs: another key */
    lu_ddod_params q = p;
    q.dirs = 64;
    CHECK(lu_ddod_key(&s, &q) != key);
    CHECK(lu_ddod_cache_load(path, lu_ddod_key(&s, &q), &b, &err) == LU_ERR_FORMAT);
    CHECK_MSG(strstr(err.message, "key mismatch") && strstr(err.message, path), "%s", err.message);
    /* flipped payload byte: checksum */
    FILE *fp = fopen(path, "r+b");
    CHECK(fp != NULL);
    if (fp) {
        fseek(fp, 200, SEEK_SET);
        int c = fgetc(fp);
        fseek(fp, 200, SEEK_SET);
        fputc(c ^ 0x55, fp);
        fclose(fp);
    }
    CHECK(lu_ddod_cache_load(path, key, &b, &err) == LU_ERR_FORMAT);
    CHECK_MSG(strstr(err.message, "checksum"), "%s", err.message);
    /* truncated */
    CHECK(truncate(path, 300) == 0);
    CHECK(lu_ddod_cache_load(path, key, &b, &err) == LU_ERR_FORMAT);
    CHECK_MSG(strstr(err.message, "truncated"), "%s", err.message);
    /* not a cache file */
    fp = fopen(path, "wb");
    if (fp) {
        fputs("{\"camera\": 1}\n", fp);
        for (int i = 0; i < 100; i++) fputs("padding padding padding\n", fp);
        fclose(fp);
    }
    CHECK(lu_ddod_cache_load(path, key, &b, &err) == LU_ERR_FORMAT);
    CHECK_MSG(strstr(err.message, "magic"), "%s", err.message);
    /* the renderer reports it and fails (no silent recompute over a corrupt file) */
    char dir[256];
    snprintf(dir, sizeof dir, "%s/test_ddod_cache_dir_%d", LU_BINARY_DIR, (int)getpid());
    lu_set_cache_dir(dir, NULL);
    lu_kvlist set = {0};
    CHECK_OK(lu_kv_parse_assignment(&set, "ddod.res=24", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&set, "ddod.dirs=32", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&set, "ddod.samples=400", &err), &err);
    CHECK_OK(lu_kv_parse_assignment(&set, "ddod.bands=3", &err), &err);
    lu_renderer *r1 = NULL, *r2 = NULL;
    CHECK_OK(lu_renderer_create("ddod", &s, &set, LU_BACKEND_CPU, &r1, &err), &err);   /* computes, writes */
    CHECK_OK(lu_renderer_create("ddod", &s, &set, LU_BACKEND_CPU, &r2, &err), &err);   /* loads */
    lu_ddod_stats st1, st2;
    CHECK(lu_ddod_last_stats(r1, &st1) && !st1.precompute.from_cache);
    CHECK(lu_ddod_last_stats(r2, &st2) && st2.precompute.from_cache && st2.samples == st1.samples);
    lu_renderer_destroy(r1);
    lu_renderer_destroy(r2);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "for f in %s/ddod-*.bin; do printf 'garbage' > \"$f\"; done", dir);
    CHECK(system(cmd) == 0);
    CHECK(lu_renderer_create("ddod", &s, &set, LU_BACKEND_CPU, &r1, &err) == LU_ERR_FORMAT);
    CHECK_MSG(strstr(err.message, "delete the file"), "%s", err.message);
    snprintf(cmd, sizeof cmd, "rm -rf %s %s", dir, path);
    CHECK(system(cmd) == 0);
    lu_set_cache_dir(NULL, NULL);
    lu_kv_free(&set);
    lu_ddod_set_free(&a);
    lu_scene_destroy(&s);
}

static const char *k_layered =
    "{\"camera\": {\"position\": [2.4, 1.5, 3.2], \"look_at\": [0, 0, 0], \"fov_y_deg\": 38, \"width\": 40, \"height\": 40},"
    " \"lights\": [{\"type\": \"point\", \"position\": [-2.2, 2.5, 2.0], \"intensity\": [36, 34, 30]},"
    "              {\"type\": \"directional\", \"direction\": [0.3, 0.4, -1.0], \"irradiance\": [0.6, 0.7, 0.9]}],"
    " \"media\": [{\"density\": {\"procedural\": \"layered_cube\", \"size\": [2, 2, 2], \"resolution\": 32,"
    "   \"layers\": 6, \"low\": 0.15, \"high\": 1.0, \"axis\": 1},"
    "   \"sigma_s\": [2.2, 2.0, 1.8], \"sigma_a\": [0.1, 0.12, 0.15],"
    "   \"boundary\": {\"mesh\": {\"procedural\": \"box\", \"size\": [1.8, 1.8, 1.8]}, \"eta\": 1.3}}]}";


static bool render(const lu_scene *s, const char *method, lu_backend be, const char *const *sets, lu_image *img) {
    lu_error err;
    lu_kvlist kv = {0};
    for (int i = 0; sets && sets[i]; i++) CHECK_OK(lu_kv_parse_assignment(&kv, sets[i], &err), &err);
    lu_renderer *r = NULL;
    lu_result res = lu_renderer_create(method, s, &kv, be, &r, &err);
    lu_kv_free(&kv);
    if (res != LU_OK) {
        if (be == LU_BACKEND_GPU) {
            fprintf(stderr, "  GPU unavailable, skipped: %s\n", err.message);
            return false;
        }
        CHECK_OK(res, &err);
        return false;
    }
    CHECK_OK(lu_renderer_render(r, s, img, &err), &err);
    lu_renderer_destroy(r);
    return true;
}

/* ddod against the truth at reduced settings (the defaults are measured in
 * docs/ddod.md): small images, fewer samples, so the tolerance is wider
 * than the 2 % target. Both the default (traced view and light
 * attenuation) and the paper's SH-only path; one precomputation per scene
 * (a cache folder of this test). */
static void test_images(void) {
    const char *scenes[2] = {k_sphere, k_layered};
    /* Bounds: the measured rel-L2 at these settings times ~1.3 (the sample
     * set is deterministic; the margin is for other compilers' float
     * rounding and future sampling changes). Default (traced): measured
     * 0.0283 (sphere), 0.0824 (layered cube: the Gaussians blur its density
     * steps; docs/ddod.md). Paper path (SH for view and lights): measured
     * 0.0325 and 0.147: 25 SH coefficients cannot follow the attenuation's
     * sharp fall-off near the cube's faces and edges. */
    const double tol[2][2] = {{0.04, 0.10}, {0.045, 0.19}};
    const char *traced[] = {"ddod.res=48", "ddod.dirs=128", "ddod.samples=15000", NULL};
    const char *paper[] = {"ddod.res=48", "ddod.dirs=128", "ddod.samples=15000", "ddod.view_psi=sh",
                           "ddod.light_psi=sh", NULL};
    const char *const *sets[2] = {traced, paper};
    char dir[256];
    snprintf(dir, sizeof dir, "%s/test_ddod_images_%d", LU_BINARY_DIR, (int)getpid());
    lu_set_cache_dir(dir, NULL);
    for (int k = 0; k < 2; k++) {
        lu_scene s;
        lu_error err;
        CHECK_OK(lu_scene_load_string(scenes[k], "scene.json", &s, &err), &err);
        lu_image ref = {0};
        if (render(&s, "reference", LU_BACKEND_CPU, NULL, &ref))
            for (int v = 0; v < 2; v++) {
                lu_image cpu = {0}, gpu = {0};
                if (render(&s, "ddod", LU_BACKEND_CPU, sets[v], &cpu)) {
                    double e = lu_test_rel_l2(&cpu, &ref);
                    fprintf(stderr, "  scene %d, %s: ddod vs reference rel-L2 %.4f\n", k, v ? "SH (paper)" : "traced", e);
                    CHECK(e < tol[v][k]);
                    if (lu_method_find("ddod")->backends & LU_BACKEND_GPU &&
                        render(&s, "ddod", LU_BACKEND_GPU, sets[v], &gpu)) {
                        double g = lu_test_rel_l2(&gpu, &cpu);
                        fprintf(stderr, "  scene %d: GPU vs CPU rel-L2 %.2g\n", k, g);
                        CHECK(g < 1e-3);
                    }
                }
                lu_image_destroy(&cpu);
                lu_image_destroy(&gpu);
            }
        lu_image_destroy(&ref);
        lu_scene_destroy(&s);
    }
    lu_set_cache_dir(NULL, NULL);
    lu_test_remove_dir(dir);
}

/* The precomputation's result does not depend on the thread count: the
 * first moment is summed in integers, the darts are thrown serially, and
 * every other stage writes per sample or per direction. A grid medium (the
 * layered cube: sweeps for the sample attenuation too) and a constant one. */
static void test_thread_invariance(void) {
    const char *scenes[2] = {k_sphere, k_layered};
    for (int k = 0; k < 2; k++) {
        lu_scene s;
        lu_error err;
        CHECK_OK(lu_scene_load_string(scenes[k], "scene.json", &s, &err), &err);
        lu_ddod_params p = {32, 48, 1500, 4, 0.8f, 3, 4};
        lu_ddod_set a, b;
        lu_set_thread_count(1, NULL);
        CHECK_OK(lu_ddod_compute(&s, &p, &a, &err), &err);
        lu_set_thread_count(3, NULL);
        CHECK_OK(lu_ddod_compute(&s, &p, &b, &err), &err);
        CHECK(a.count > 0 && a.count == b.count && a.stride == b.stride);
        if (a.count > 0 && a.count == b.count && a.stride == b.stride) {
            CHECK(memcmp(a.samples, b.samples, (size_t)a.count * LU_K_DDOD_SAMPLE_FLOATS * sizeof(float)) == 0);
            CHECK(memcmp(a.sh, b.sh, (size_t)a.count * a.stride * sizeof(float)) == 0);
        }
        lu_ddod_set_free(&a);
        lu_ddod_set_free(&b);
        lu_scene_destroy(&s);
    }
    lu_set_thread_count(0, NULL);
}

int main(void) {
    RUN_TEST(test_sh_projection);
    RUN_TEST(test_sh_orthonormal_8);
    RUN_TEST(test_gauss_line);
    RUN_TEST(test_poisson);
    RUN_TEST(test_sphere_attenuation);
    RUN_TEST(test_traced_sphere);
    RUN_TEST(test_traced_update);
    RUN_TEST(test_cache);
    RUN_TEST(test_thread_invariance);
    RUN_TEST(test_images);
    TEST_EXIT();
}
