/* lu_k_rm_near_light (methods/common/lu_near_light.h), the raymarch view march's
 * step mean of a point light's 1/d^2 (shared by raymarch, afm and gradient):
 * its two forms against the mean in double, and against each other where
 * the kernel switches from one to the other. The whole-image effect of the
 * step mean (a ray past a point light vs a closed form) is in
 * test_raymarch.c. */
#include "lu_test.h"

#include <lucent/lucent.h>

#include <math.h>
#include <stdlib.h>

#include "methods/common/lu_near_light.h"

/* The step's mean of 1/|p - x - s d|^2 over s in [sa, sb], times |p - x|^2,
 * in double from the two atans (no rearrangement shared with the kernel). */
static double near_light_double(lu_vec3 p, lu_vec3 x, lu_vec3 d, double sa, double sb) {
    double o[3] = {(double)p.x - x.x, (double)p.y - x.y, (double)p.z - x.z};
    double dd[3] = {d.x, d.y, d.z};
    double d2 = o[0] * o[0] + o[1] * o[1] + o[2] * o[2], tc = o[0] * dd[0] + o[1] * dd[1] + o[2] * dd[2];
    double perp[3] = {o[0] - tc * dd[0], o[1] - tc * dd[1], o[2] - tc * dd[2]};
    double b = sqrt(perp[0] * perp[0] + perp[1] * perp[1] + perp[2] * perp[2]);
    return (atan((sb - tc) / b) - atan((sa - tc) / b)) / (b * (sb - sa)) * d2;
}

/* lu_k_rm_near_light takes the series form of atan(z)/z away from the light
 * (z^2 <= LU_K_RM_NEAR_SERIES_Z2) and the atan2 form near it. Both against
 * the mean in double over random steps (light 0.5..1000 steps away, any
 * direction, sample anywhere in its step), and the two forms against each
 * other around the switch, where a seam would show: 1e-6 relative. */
static void test_near_light_forms(void) {
    srand(7);
    double worst_series = 0, worst_atan = 0, worst_atan_model = 0, worst_switch = 0;
    int n_series = 0, n_switch = 0, n_atan = 0;
    for (int i = 0; i < 20000; i++) {
        double r = 0.5 * pow(2000.0, rand() / (double)RAND_MAX);
        lu_vec3 w = lu_v3_norm(lu_v3((float)(rand() / (double)RAND_MAX - 0.5), (float)(rand() / (double)RAND_MAX - 0.5),
                                     (float)(rand() / (double)RAND_MAX - 0.5)));
        lu_vec3 d = lu_v3_norm(lu_v3((float)(rand() / (double)RAND_MAX - 0.5), (float)(rand() / (double)RAND_MAX - 0.5),
                                     (float)(rand() / (double)RAND_MAX - 0.5)));
        float h = 0.01f, u = (float)(rand() / (double)RAND_MAX);
        lu_vec3 x = lu_v3(0.3f, -0.2f, 0.1f), p = lu_v3_add(x, lu_v3_scale(w, (float)(r * h)));
        float sa = -u * h, sb = (1.0f - u) * h;
        /* b below 1% of the step: the mean hangs on b itself, which float
         * (d2 - tc^2) cannot resolve; the kernel's clamp is for that case. */
        double tc = lu_v3_dot(lu_v3_sub(p, x), d), d2 = r * r * h * h;
        if (d2 - tc * tc < 1e-4 * h * h) continue;
        double truth = near_light_double(p, x, d, sa, sb);
        double series = lu_k_rm_near_light_cut(p, x, d, sa, sb, 1.0f);
        double atan2_form = lu_k_rm_near_light_cut(p, x, d, sa, sb, 0.0f);
        double got = lu_k_rm_near_light(p, x, d, sa, sb);
        double b2 = d2 - tc * tc, D = b2 + (sb - tc) * (sa - tc), z2 = b2 * h * h / (D * D);
        if (D > 0 && z2 <= LU_K_RM_NEAR_SERIES_Z2) {
            CHECK(got == series);
            worst_series = fmax(worst_series, fabs(series / truth - 1.0));
            n_series++;
        } else {
            worst_atan = fmax(worst_atan, fabs(atan2_form / truth - 1.0));
            worst_atan_model = fmax(worst_atan_model, fabs(atan2_form / truth - 1.0) / (0x1p-24 * (2.0 * d2 / b2 + 32.0)));
            n_atan++;
        }
        if (D > 0 && z2 > 0.5 * LU_K_RM_NEAR_SERIES_Z2 && z2 < 2.0 * LU_K_RM_NEAR_SERIES_Z2) {
            worst_switch = fmax(worst_switch, fabs(series / atan2_form - 1.0));
            n_switch++;
        }
    }
    fprintf(stderr, "  series branch: %d steps, worst %.2g; atan2 branch: %d steps, worst %.2g (%.3g of its error model); at the switch: %d steps, forms differ by %.2g\n",
            n_series, worst_series, n_atan, worst_atan, worst_atan_model, n_switch, worst_switch);
    CHECK(n_series > 1000 && n_switch > 50);
    /* ~30 float roundings (6e-8 each): the dot products, and D, a sum of
     * nearly equal terms where the ray points at the light */
    CHECK(worst_series <= 2e-6);
    CHECK(worst_switch <= 1e-6);
    /* The atan2 form's error model, per step: float b^2 = d2 - tc^2 is off by
     * about u*(d2 + tc^2) <= 2u*d2 absolute, so b by u*d2/b^2 relative; the
     * step mean (atan(A/b) - atan(B/b)) / b has a relative sensitivity to b
     * between 1 and 2, which gives 2u*d2/b^2, plus ~30 roundings as above
     * (u = 2^-24). Near the light b is small and this term dominates. */
    CHECK(n_atan > 1000);
    CHECK(worst_atan_model <= 1.0);
}

int main(void) {
    RUN_TEST(test_near_light_forms);
    TEST_EXIT();
}
