/* Shared kernels: spherical harmonics (orthonormality by quadrature, closed
 * forms, the addition theorem, Lambert convolution constants, the projection
 * of an environment against closed forms within its derived error) and light
 * views (projection inverts the texel rays; shadow maps of a known occluder). */
#include <lucent/lucent.h>

#include <stdlib.h>

#include "lu_test.h"
#include "methods/common/lightview.h"
#include "methods/common/sh_env.h"

static const float *g_depth;
static int g_res;
struct lu_k_ctx;
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return g_depth[(size_t)j * g_res + i];
}
#include "methods/common/lu_shadowmap.h"
#include "methods/common/lu_sh.h"

static lu_vec3 dir_of(double ct, double phi) {
    double st = sqrt(fmax(0.0, 1.0 - ct * ct));
    return lu_v3((float)(st * cos(phi)), (float)(st * sin(phi)), (float)ct);
}

static void test_sh_orthonormal(void) {
    /* Gauss-Legendre in cos(theta) (16 nodes: exact for the degree <= 10
     * polynomials that products of equal-m bands are) and a uniform rule in
     * phi (exact for the trigonometric degree <= 10 of the products). */
    enum { NT = 16, NP = 32 };
    double gx[NT], gw[NT];
    lu_test_gauss_legendre(NT, gx, gw);
    static double gram[36][36];
    float y[LU_SH_MAX_COEFFS];
    for (int i = 0; i < NT; i++) {
        for (int k = 0; k < NP; k++) {
            lu_k_sh_eval(dir_of(gx[i], 2.0 * M_PI * (k + 0.5) / NP), 6, y);
            double w = gw[i] * (2.0 * M_PI / NP);
            for (int a = 0; a < 36; a++)
                for (int b = a; b < 36; b++) gram[a][b] += w * y[a] * y[b];
        }
    }
    double worst = 0.0;
    for (int a = 0; a < 36; a++)
        for (int b = a; b < 36; b++) worst = fmax(worst, fabs(gram[a][b] - (a == b ? 1.0 : 0.0)));
    fprintf(stderr, "  SH Gram matrix max deviation from identity: %.2g\n", worst);
    CHECK(worst < 1e-5);
}

static void test_sh_closed_forms(void) {
    float y[LU_SH_MAX_COEFFS];
    lu_vec3 d = lu_v3_norm(lu_v3(0.3f, -0.5f, 0.81f));
    lu_k_sh_eval(d, 3, y);
    CHECK_NEAR(y[0], 0.282095, 1e-6);
    CHECK_NEAR(y[1], 0.488603 * d.y, 1e-6);
    CHECK_NEAR(y[2], 0.488603 * d.z, 1e-6);
    CHECK_NEAR(y[3], 0.488603 * d.x, 1e-6);
    CHECK_NEAR(y[4], 1.092548 * d.x * d.y, 1e-6);
    CHECK_NEAR(y[5], 1.092548 * d.y * d.z, 1e-6);
    CHECK_NEAR(y[6], 0.315392 * (3 * d.z * d.z - 1), 1e-6);
    CHECK_NEAR(y[7], 1.092548 * d.x * d.z, 1e-6);
    CHECK_NEAR(y[8], 0.546274 * (d.x * d.x - d.y * d.y), 1e-6);
}

static void test_sh_addition_theorem(void) {
    /* sum_m Y_lm(a) Y_lm(b) = (2l + 1) / (4 pi) P_l(a . b), for every band. */
    unsigned s = 3;
    for (int trial = 0; trial < 200; trial++) {
        double r[4];
        for (int i = 0; i < 4; i++) {
            s = s * 1664525u + 1013904223u;
            r[i] = (s >> 8) / 16777216.0;
        }
        lu_vec3 a = dir_of(2 * r[0] - 1, 2 * M_PI * r[1]), b = dir_of(2 * r[2] - 1, 2 * M_PI * r[3]);
        float ya[LU_SH_MAX_COEFFS], yb[LU_SH_MAX_COEFFS];
        lu_k_sh_eval(a, 6, ya);
        lu_k_sh_eval(b, 6, yb);
        double t = lu_v3_dot(a, b);
        double P[6] = {1, t, 0.5 * (3 * t * t - 1), 0.5 * (5 * t * t * t - 3 * t),
                       (35 * pow(t, 4) - 30 * t * t + 3) / 8, (63 * pow(t, 5) - 70 * t * t * t + 15 * t) / 8};
        for (int l = 0; l < 6; l++) {
            double sum = 0;
            for (int m = -l; m <= l; m++) sum += ya[l * (l + 1) + m] * yb[l * (l + 1) + m];
            CHECK_NEAR(sum, (2 * l + 1) / (4 * M_PI) * P[l], 2e-5);
        }
    }
}

static void test_sh_lambert(void) {
    /* A_l = 2 pi * integral_0^1 t P_l(t) dt, by quadrature. */
    for (int l = 0; l < 6; l++) {
        double sum = 0;
        const int N = 200000;
        for (int i = 0; i < N; i++) {
            double t = (i + 0.5) / N;
            double P[6] = {1, t, 0.5 * (3 * t * t - 1), 0.5 * (5 * t * t * t - 3 * t),
                           (35 * pow(t, 4) - 30 * t * t + 3) / 8, (63 * pow(t, 5) - 70 * t * t * t + 15 * t) / 8};
            sum += t * P[l] / N;
        }
        CHECK_NEAR(lu_k_sh_lambert_band(l), 2 * M_PI * sum, 1e-5);
    }
}

/* Channels: the SH polar axis z, the map's polar axis y (lu_k_env_dir's
 * cos theta), and a constant. */
static lu_vec3 env_test_radiance(const void *user, lu_vec3 d) {
    (void)user;
    return lu_v3(d.z, d.y, 1.0f);
}

static void test_sh_env_project(void) {
    /* Exact values: a constant L projects to L 4 pi Y_00 = 2 sqrt(pi) L and
     * nothing else; L = z = sqrt(4 pi / 3) Y_10 (lu_sh.h: Y_10 = sqrt(3 / (4 pi)) z)
     * projects to sqrt(4 pi / 3) on Y_10 only, and L = y likewise on Y_1-1.
     * Error of the rule for an integrand f = L Y_k, a polynomial of degree
     * n = l + 1 (n = l for the constant) on the sphere: in the map's frame
     * (polar axis y) the phi sum over np equally spaced cell centres is exact
     * for the trigonometric degree <= n < np of f in phi, leaving 2 pi times
     * a 1D rule, sum_j g(theta_j) (cos theta_j0 - cos theta_j1), for g the phi
     * average of f, a trigonometric polynomial of degree n in theta with
     * |g| <= max |f|. Per cell (width h = pi / nt), Taylor about the centre:
     * the linear term leaves |g'| |cos theta_j| int t sin t dt <= |g'| h^3 / 12,
     * the remainder <= |g''| / 2 int t^2 dt = |g''| h^3 / 24; over nt cells and
     * with Bernstein's |g'| <= n |g|, |g''| <= n^2 |g|:
     *   |error| <= 2 pi^2 h^2 max|f| (n / 12 + n^2 / 24),
     * max|f| <= max|L| sqrt((2l + 1) / (4 pi)) (the addition theorem bounds
     * each Y_lm), and 0 for the constant's Y_00: that one is exact but for
     * rounding, as are the odd bands of the constant. Rounding (float
     * directions, Y and L, double sums) adds well under 1e-5. */
    int grids[2][2], nt, np;
    lu_sh_env_grid(8, 4, 1, &nt, &np);   /* ddod's smallest grid */
    CHECK(nt == 64 && np == 128);
    grids[0][0] = nt, grids[0][1] = np;
    lu_sh_env_grid(300, 100, 2, &nt, &np);   /* bssrdf's grid of a 300 x 100 map */
    CHECK(nt == 200 && np == 600);
    grids[1][0] = nt, grids[1][1] = np;
    lu_sh_env_grid(300, 100, 1, &nt, &np);
    CHECK(nt == 100 && np == 300);
    const int bands = LU_SH_MAX_BANDS;
    double c[3 * LU_SH_MAX_COEFFS];
    for (int g = 0; g < 2; g++) {
        for (int a = 0; a < 2; a++) {
            nt = grids[g][0], np = grids[g][1];
            lu_sh_env_project(env_test_radiance, NULL, nt, np, bands,
                              a ? LU_SH_ENV_ANGLES_FLOAT : LU_SH_ENV_ANGLES_DOUBLE, c);
            double h = M_PI / nt, worst[3] = {0, 0, 0}, worst_bound = 0;
            for (int k = 0; k < bands * bands; k++) {
                int l = (int)sqrt((double)k + 0.5);
                double ymax = sqrt((2 * l + 1) / (4 * M_PI));
                for (int ch = 0; ch < 3; ch++) {
                    int n = ch == 2 ? l : l + 1;
                    double exact = 0.0;
                    if (ch == 0 && k == 2) exact = sqrt(4 * M_PI / 3);
                    if (ch == 1 && k == 1) exact = sqrt(4 * M_PI / 3);
                    if (ch == 2 && k == 0) exact = 2 * sqrt(M_PI);
                    double bound = 2 * M_PI * M_PI * h * h * ymax * (n / 12.0 + n * n / 24.0);
                    if (ch == 2 && (l == 0 || (l & 1))) bound = 0.0;
                    double e = fabs(c[3 * k + ch] - exact);
                    CHECK(e <= bound + 1e-5);
                    worst[ch] = fmax(worst[ch], e);
                    worst_bound = fmax(worst_bound, bound);
                }
            }
            fprintf(stderr, "  env SH %dx%d (%s angles): c00 %.7f (2 sqrt(pi) %.7f), c10 %.7f, c1-1 %.7f "
                    "(sqrt(4pi/3) %.7f); worst errors z %.2g y %.2g const %.2g, largest bound %.2g\n",
                    nt, np, a ? "float" : "double", c[2], 2 * sqrt(M_PI), c[3 * 2], c[3 * 1 + 1],
                    sqrt(4 * M_PI / 3), worst[0], worst[1], worst[2], worst_bound);
        }
    }
}

static void test_lightview_roundtrip(void) {
    lu_light lights[3] = {0};
    lights[0].type = LU_LIGHT_SPOT;
    lights[0].position = lu_v3(1, 4, 2);
    lights[0].direction = lu_v3_norm(lu_v3(-0.2f, -1, -0.4f));
    lights[0].outer_deg = 30;
    lights[1].type = LU_LIGHT_DIRECTIONAL;
    lights[1].direction = lu_v3_norm(lu_v3(0.3f, 1, 0.2f));
    lights[2].type = LU_LIGHT_POINT;
    lights[2].position = lu_v3(0.2f, 0.1f, -0.3f);
    lu_aabb region = {{-1, -1, -1}, {1, 1, 1}};
    for (int li = 0; li < 3; li++) {
        lu_lightviews vs;
        lu_lightviews_for_light(&lights[li], region, &vs);
        CHECK(vs.count == (li == 2 ? 6 : 1));
        for (int f = 0; f < vs.count; f++) {
            for (int k = 0; k < 50; k++) {
                float u = 0.02f + 0.96f * (float)((k * 37) % 50) / 50.0f, v = 0.02f + 0.96f * (float)((k * 11) % 50) / 50.0f;
                lu_k_lightray r = lu_k_lightview_ray(vs.view[f], u, v);
                float t = 0.5f + 0.05f * (float)k;
                lu_vec3 x = lu_v3_madd(r.origin, r.dir, t);
                lu_vec3 uvd = lu_k_lightview_project(vs.view[f], x);
                CHECK_NEAR(uvd.x, u, 1e-5);
                CHECK_NEAR(uvd.y, v, 1e-5);
                CHECK_NEAR(uvd.z, t, 1e-4);
                if (vs.count == 6) CHECK(lu_lightviews_select(&vs, x) == f);
            }
        }
        /* Every point of the region is seen by some view. */
        for (int k = 0; k < 200; k++) {
            lu_vec3 x = lu_v3(-1 + 2 * (float)((k * 7) % 200) / 200, -1 + 2 * (float)((k * 13) % 200) / 200,
                              -1 + 2 * (float)((k * 29) % 200) / 200);
            CHECK(lu_lightviews_select(&vs, x) >= 0);
        }
    }
}

static void test_shadow_map(void) {
    /* A square occluder at y = 1 (|x|, |z| < 0.5) under a directional light
     * straight down: the map holds the distance to it inside its footprint,
     * and points below it are shadowed while points beside it are lit. */
    lu_mesh quad = {0};
    lu_error err;
    CHECK_OK(lu_mesh_alloc(&quad, 4, 2, &err), &err);
    lu_vec3 p[4] = {{-0.5f, 1, -0.5f}, {0.5f, 1, -0.5f}, {0.5f, 1, 0.5f}, {-0.5f, 1, 0.5f}};
    uint32_t idx[6] = {0, 2, 1, 0, 3, 2};
    for (int i = 0; i < 4; i++) quad.positions[i] = p[i];
    for (int i = 0; i < 6; i++) quad.indices[i] = idx[i];
    lu_mesh_compute_normals(&quad);
    lu_accel *acc;
    uint32_t id;
    CHECK_OK(lu_accel_create(&acc, &err), &err);
    CHECK_OK(lu_accel_add_mesh(acc, &quad, &id, &err), &err);
    CHECK_OK(lu_accel_commit(acc, &err), &err);
    lu_light sun = {0};
    sun.type = LU_LIGHT_DIRECTIONAL;
    sun.direction = lu_v3(0, 1, 0);
    lu_lightviews vs;
    lu_lightviews_for_light(&sun, (lu_aabb){{-2, -1, -2}, {2, 2, 2}}, &vs);
    g_res = 64;
    float *depth = malloc(sizeof(float) * 64 * 64);
    CHECK_OK(lu_shadow_map_build(acc, &vs.view[0], 64, 1e30f, depth, &err), &err);
    g_depth = depth;
    lu_vec3 below = lu_v3(0.1f, 0.0f, -0.2f), beside = lu_v3(1.2f, 0.0f, 0.3f), above = lu_v3(0.1f, 1.5f, 0.1f);
    lu_vec3 uvd = lu_k_lightview_project(vs.view[0], below);
    /* The stored depth over the occluder is the plane distance from the view origin. */
    lu_vec3 top = lu_k_lightview_project(vs.view[0], lu_v3(0.1f, 1.0f, -0.2f));
    int i = (int)(uvd.x * 64), j = (int)(uvd.y * 64);
    CHECK_NEAR(depth[j * 64 + i], top.z, 1e-4);
    CHECK_NEAR(lu_k_shadow_visibility(NULL, 0, 64, uvd, 1e-3f), 0.0, 1e-6);
    CHECK_NEAR(lu_k_shadow_visibility(NULL, 0, 64, lu_k_lightview_project(vs.view[0], beside), 1e-3f), 1.0, 1e-6);
    CHECK_NEAR(lu_k_shadow_visibility(NULL, 0, 64, lu_k_lightview_project(vs.view[0], above), 1e-3f), 1.0, 1e-6);
    free(depth);
    lu_accel_destroy(acc);
    lu_mesh_destroy(&quad);
}

static void test_shadow_cube_seam(void) {
    /* A point light enclosed by a blocker at distance 1 (every cube face's
     * map holds depth 1): every point farther away is in shadow, including
     * points next to the seam of two faces whose normal offset crosses into
     * the neighbouring face (they once came out lit, drawing lines). */
    lu_light lamp = {0};
    lamp.type = LU_LIGHT_POINT;
    lu_lightviews vs;
    lu_lightviews_for_light(&lamp, (lu_aabb){{-8, -8, -8}, {8, 8, 8}}, &vs);
    CHECK(vs.count == 6);
    g_res = 32;
    float *depth = malloc(sizeof(float) * 32 * 32);
    for (int k = 0; k < 32 * 32; k++) depth[k] = 1.0f;
    g_depth = depth;
    int checked = 0;
    for (int k = 0; k < 200; k++) {
        /* Just on the +x side of the x = y seam, normal pointing into +y. */
        float t = -0.9f + 1.8f * (float)k / 199.0f;
        lu_vec3 x = lu_v3_scale(lu_v3_norm(lu_v3(1.0f, 0.999f, t)), 5.0f);
        int face = lu_lightviews_select(&vs, x);
        if (face < 0) continue;
        checked++;
        CHECK_NEAR(lu_k_shadow_lookup(NULL, vs.view[face], 0, 32, x, lu_v3(0, 1, 0)), 0.0, 1e-6);
        /* and a point in front of the blocker stays lit */
        lu_vec3 near = lu_v3_scale(lu_v3_norm(x), 0.5f);
        CHECK_NEAR(lu_k_shadow_lookup(NULL, vs.view[lu_lightviews_select(&vs, near)], 0, 32, near, lu_v3(0, 1, 0)), 1.0, 1e-6);
    }
    CHECK(checked > 150);
    free(depth);
}

int main(void) {
    RUN_TEST(test_sh_orthonormal);
    RUN_TEST(test_sh_closed_forms);
    RUN_TEST(test_sh_addition_theorem);
    RUN_TEST(test_sh_lambert);
    RUN_TEST(test_sh_env_project);
    RUN_TEST(test_lightview_roundtrip);
    RUN_TEST(test_shadow_map);
    RUN_TEST(test_shadow_cube_seam);
    TEST_EXIT();
}
