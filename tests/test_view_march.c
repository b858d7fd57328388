/* The view march's savings (methods/common/lu_view_march.h, lu_march_blocks.h)
 * against independent numbers, through the kernel with a test-local context:
 *   - the majorant grid is conservative: at random points (inside, on block
 *     faces, outside the grid) the trilinear density lu_grid_sample never
 *     exceeds its block's majorant, and a block judged empty by
 *     lu_k_block_at has density exactly 0 all the way to the t_exit it gives;
 *   - shadow rays through the blocks equal the plain cell walk
 *     (lu_k_optical_depth) to float rounding while sampling less;
 *   - empty-space skipping leaves the march's radiance bit for bit as it was
 *     (the same kernel with every block reported dense), with fewer samples;
 *   - early termination on a homogeneous slab lit from the side, whose
 *     radiance is known in closed form: the full march equals it, and the
 *     terminated march's error is positive and within the stated bound
 *     t_cut * max(L_end, albedo * phase * E_in). */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"
#include "methods/common/lu_lightview.h"
#include "methods/common/majorant.h"

struct lu_k_ctx {
    lu_k_medium km;
    const lu_grid *grid;          /* NULL: constant medium */
    const lu_majorant *maj;
    int skip;                     /* 0: every block reported dense (no skipping) */
    lu_k_light kl;
};

static long g_density_calls;

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    (void)m;
    g_density_calls++;
    return c->grid ? lu_grid_sample(c->grid, p) : c->km.density_scale;
}
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    (void)m;
    if (!c->grid) return c->km.density_scale;
    return c->skip ? lu_majorant_at(c->maj, bx, by, bz) : 1.0f;
}
#include "lu_test_march.h"

#include "methods/common/lu_view_march.h"

static unsigned g_rng = 12345u;
static float frand(void) {
    g_rng = g_rng * 1664525u + 1013904223u;
    return (float)(g_rng >> 8) * (1.0f / 16777216.0f);
}

static const int k_spikes[3][3] = {{39, 7, 15}, {7, 31, 23}, {23, 15, 7}};

/* A sparse grid: a few blobs in a box of zeros, one touching the grid's
 * border (the zero border outside the grid must not hide it). */
static void sparse_grid(lu_grid *g) {
    lu_error err = {0};
    CHECK_OK(lu_grid_alloc(g, 41, 34, 27, &err), &err);
    const float c[4][4] = {{8, 8, 8, 6}, {30, 20, 14, 7}, {40, 33, 26, 5}, {20, 5, 20, 3}};
    for (int z = 0; z < g->nz; z++)
        for (int y = 0; y < g->ny; y++)
            for (int x = 0; x < g->nx; x++) {
                float v = 0.0f;
                for (int b = 0; b < 4; b++) {
                    float dx = x - c[b][0], dy = y - c[b][1], dz = z - c[b][2];
                    float r = sqrtf(dx * dx + dy * dy + dz * dz);
                    if (r < c[b][3]) v += 1.0f + 0.5f * (float)b;
                }
                g->data[((size_t)z * g->ny + y) * g->nx + x] = v;
            }
    /* Lone voxels at block borders (index 8k - 1 on every axis) away from the
     * blobs: only a block that counts its neighbours' border voxels bounds
     * the trilinear field next to them. */
    for (int i = 0; i < 3; i++) g->data[((size_t)k_spikes[i][2] * g->ny + k_spikes[i][1]) * g->nx + k_spikes[i][0]] = 2.0f;
    lu_grid_update_range(g);
}

static lu_k_medium grid_medium(const lu_grid *g) {
    lu_k_medium k;
    memset(&k, 0, sizeof k);
    k.w2i_x = lu_v3(1, 0, 0);
    k.w2i_y = lu_v3(0, 1, 0);
    k.w2i_z = lu_v3(0, 0, 1);
    k.support_lo = k.bounds_lo = lu_v3s(-1.0f);
    k.support_hi = k.bounds_hi = lu_v3((float)g->nx, (float)g->ny, (float)g->nz);
    k.sigma_a = lu_v3s(0.05f);
    k.sigma_s = lu_v3s(0.25f);
    k.density_scale = 1.0f;
    k.max_pieces = g->nx + g->ny + g->nz + 8;
    return k;
}

static struct lu_k_ctx ctx_grid(const lu_grid *g, const lu_majorant *mj) {
    struct lu_k_ctx c;
    memset(&c, 0, sizeof c);
    c.km = grid_medium(g);
    c.grid = g;
    c.maj = mj;
    c.skip = 1;
    return c;
}

static lu_vec3 random_dir(void) {
    for (;;) {
        lu_vec3 d = lu_v3(2 * frand() - 1, 2 * frand() - 1, 2 * frand() - 1);
        float l = lu_v3_len(d);
        if (l > 0.1f && l <= 1.0f) return lu_v3_scale(d, 1.0f / l);
    }
}

static void test_majorant_conservative(void) {
    lu_grid g;
    sparse_grid(&g);
    lu_majorant mj;
    lu_error err = {0};
    CHECK_OK(lu_majorant_build(&g, LU_SCENE_MAJORANT_BLOCK, &mj, &err), &err);
    int empty = 0, total = mj.nx * mj.ny * mj.nz;
    for (int i = 0; i < total; i++) empty += mj.dmax[i] == 0.0f;
    CHECK_MSG(empty > total / 4 && empty < total, "%d of %d blocks empty: the test needs both kinds", empty, total);
    /* Random points: a third snapped to block faces, a third next to the lone
     * border voxels (where a block's border voxels decide). */
    int violations = 0, dense = 0;
    for (int i = 0; i < 400000; i++) {
        lu_vec3 p = lu_v3(-1.5f + frand() * (g.nx + 1.0f), -1.5f + frand() * (g.ny + 1.0f), -1.5f + frand() * (g.nz + 1.0f));
        if (i % 3 == 0) p.x = (float)(LU_SCENE_MAJORANT_BLOCK * (int)(frand() * 6.0f) - 1);
        if (i % 3 == 1) {
            const int *k = k_spikes[(i / 3) % 3];
            p = lu_v3(k[0] - 1 + 2 * frand(), k[1] - 1 + 2 * frand(), k[2] - 1 + 2 * frand());
        }
        float d = lu_grid_sample(&g, p);
        float q[3] = {(p.x + 1.0f) / LU_SCENE_MAJORANT_BLOCK, (p.y + 1.0f) / LU_SCENE_MAJORANT_BLOCK,
                      (p.z + 1.0f) / LU_SCENE_MAJORANT_BLOCK};
        float bound = lu_majorant_at(&mj, (int)floorf(q[0]), (int)floorf(q[1]), (int)floorf(q[2]));
        dense += d > 0.0f;
        if (d > bound) violations++;
    }
    CHECK_MSG(violations == 0, "%d points above their block's majorant", violations);
    CHECK(dense > 10000);
    /* lu_k_block_at: where it says empty, the density is 0 up to t_exit. */
    struct lu_k_ctx c = ctx_grid(&g, &mj);
    int judged = 0, wrong = 0;
    for (int i = 0; i < 20000; i++) {
        lu_vec3 o = lu_v3(frand() * g.nx, frand() * g.ny, frand() * g.nz), d = random_dir();
        float t_exit = 0.0f;
        float dmax = lu_k_block_at(&c, 0, o, d, 0.0f, &t_exit);
        if (dmax != 0.0f) continue;
        judged++;
        CHECK(t_exit > 0.0f);
        for (int k = 0; k <= 64; k++) {
            lu_vec3 p = lu_v3_madd(o, d, t_exit * (float)k / 64.0f);
            if (lu_grid_sample(&g, p) != 0.0f) wrong++;
        }
    }
    CHECK_MSG(judged > 1000 && wrong == 0, "%d points judged empty, %d samples with density before t_exit", judged,
              wrong);
    fprintf(stderr, "  %d of %d blocks empty; %d empty-block judgements, no density found in them\n", empty, total,
            judged);
    lu_majorant_destroy(&mj);
    lu_grid_destroy(&g);
}

static void test_optical_depth_blocks(void) {
    lu_grid g;
    sparse_grid(&g);
    lu_majorant mj;
    lu_error err = {0};
    CHECK_OK(lu_majorant_build(&g, LU_SCENE_MAJORANT_BLOCK, &mj, &err), &err);
    struct lu_k_ctx c = ctx_grid(&g, &mj);
    long calls_plain = 0, calls_blocks = 0;
    double worst = 0.0;
    int nonzero = 0;
    for (int i = 0; i < 3000; i++) {
        lu_vec3 o = lu_v3(-1 + frand() * (g.nx + 1), -1 + frand() * (g.ny + 1), -1 + frand() * (g.nz + 1));
        lu_vec3 d = random_dir();
        float a = 0.0f, b = 0.0f;
        if (!lu_k_box_clip(c.km.support_lo, c.km.support_hi, o, d, 0.0f, 1e30f, &a, &b)) continue;
        g_density_calls = 0;
        float plain = lu_k_optical_depth(&c, 0, o, d, a, b, c.km.max_pieces);
        calls_plain += g_density_calls;
        g_density_calls = 0;
        float blocks = lu_k_optical_depth_blocks(&c, 0, o, d, a, b, c.km.max_pieces);
        calls_blocks += g_density_calls;
        nonzero += plain > 0.0f;
        double e = fabs((double)blocks - plain) / (plain + 0.1);
        if (e > worst) worst = e;
    }
    CHECK_MSG(worst < 1e-5, "block walk differs from the cell walk by %.3g (relative to depth + 0.1)", worst);
    CHECK(nonzero > 300);
    CHECK_MSG(calls_blocks * 4 < calls_plain * 3, "block walk %ld density samples, cell walk %ld", calls_blocks, calls_plain);
    fprintf(stderr, "  optical depth: worst relative difference %.2g, density samples %ld -> %ld\n", worst, calls_plain,
            calls_blocks);
    lu_majorant_destroy(&mj);
    lu_grid_destroy(&g);
}

static void test_skipping_bit_exact(void) {
    lu_grid g;
    sparse_grid(&g);
    lu_majorant mj;
    lu_error err = {0};
    CHECK_OK(lu_majorant_build(&g, LU_SCENE_MAJORANT_BLOCK, &mj, &err), &err);
    struct lu_k_ctx c = ctx_grid(&g, &mj);
    c.kl.type = LU_K_LIGHT_POINT;
    c.kl.position = lu_v3(20, 40, 10);
    c.kl.intensity = lu_v3(300, 250, 200);
    lu_k_rm_params P;
    memset(&P, 0, sizeof P);
    P.step = 0.37f;
    P.map_res = 1;
    P.t_cut = 0.0f;
    long calls[2] = {0, 0};
    int differ = 0, lit = 0;
    lu_vec3 cam = lu_v3(-15.0f, 12.0f, 40.0f);
    for (int i = 0; i < 600; i++) {
        lu_vec3 target = lu_v3(frand() * g.nx, frand() * g.ny, frand() * g.nz);
        lu_vec3 d = lu_v3_norm(lu_v3_sub(target, cam));
        lu_vec3 L[2];
        for (int s = 0; s < 2; s++) {
            c.skip = s;
            g_density_calls = 0;
            L[s] = lu_k_rm_radiance(&c, P, 0, cam, d, 0.5f);
            calls[s] += g_density_calls;
        }
        if (memcmp(&L[0], &L[1], sizeof L[0]) != 0) differ++;
        lit += L[0].x > 0.0f;
    }
    CHECK_MSG(differ == 0, "%d of 600 rays differ with skipping", differ);
    CHECK(lit > 100);
    CHECK_MSG(calls[1] < calls[0], "density samples with skipping %ld, without %ld", calls[1], calls[0]);
    fprintf(stderr, "  march: 600 rays identical with and without skipping; density samples %ld -> %ld\n", calls[0],
            calls[1]);
    lu_majorant_destroy(&mj);
    lu_grid_destroy(&g);
}

/* Homogeneous slab |x| <= w, |y| <= 1, 0 <= z <= D seen along -z from above,
 * lit by a directional light along +x: every point of the camera ray receives
 * E exp(-sigma_t w), so
 *   L = albedo * E exp(-sigma_t w) / (4 pi) * (1 - exp(-sigma_t D)) + B exp(-sigma_t D). */
static void test_early_termination_slab(void) {
    const float sig_t = 1.0f, albedo = 0.8f, w = 0.01f, D = 8.0f, E = 4.0f * (float)LU_PI, B = 0.1f;
    struct lu_k_ctx c;
    lu_test_march_slab(&c, sig_t, albedo, w, D, E);
    lu_k_rm_params P;
    memset(&P, 0, sizeof P);
    P.background = lu_v3s(B);
    P.step = 0.01f;
    P.map_res = 1;
    double Ein = E * exp(-sig_t * w), pe = albedo * Ein / (4.0 * LU_PI);
    double exact = pe * (1.0 - exp(-sig_t * D)) + B * exp(-sig_t * D);
    lu_vec3 o = lu_v3(0, 0, D + 1.0f), d = lu_v3(0, 0, -1);
    P.t_cut = 0.0f;
    double full = lu_k_rm_radiance(&c, P, 0, o, d, 0.5f).x;
    CHECK_MSG(fabs(full - exact) <= 1e-5 * exact, "full march %.8g, closed form %.8g", full, exact);
    const float cuts[3] = {0.2f, 0.05f, 0.01f};
    for (int k = 0; k < 3; k++) {
        P.t_cut = cuts[k];
        double cut = lu_k_rm_radiance(&c, P, 0, o, d, 0.5f).x;
        double error = exact - cut, bound = cuts[k] * fmax(B, pe);
        fprintf(stderr, "  t_cut %.2f: error %.5g, bound %.5g (%.0f %% of it)\n", cuts[k], error, bound,
                100.0 * error / bound);
        /* Positive: the march did stop; within the bound plus float rounding;
         * and not far below it (the slab's in-scattering is the bound's
         * maximum everywhere, so only the last step's overshoot separates them). */
        CHECK_MSG(error > 0.5 * bound && error <= bound + 1e-5 * exact, "t_cut %g: error %.6g, bound %.6g", cuts[k],
                  error, bound);
    }
}

int main(void) {
    RUN_TEST(test_majorant_conservative);
    RUN_TEST(test_optical_depth_blocks);
    RUN_TEST(test_skipping_bit_exact);
    RUN_TEST(test_early_termination_slab);
    TEST_EXIT();
}
