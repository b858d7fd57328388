/* Measured subsurface coefficients of Jensen, Marschner, Levoy and Hanrahan,
 * "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001, Table 1:
 * reduced scattering sigma_s' and absorption sigma_a in mm^-1 for R, G, B,
 * all measured with a relative index of refraction of 1.3. */
#include <lucent/scene.h>

#include <pthread.h>
#include <strings.h>

#include "methods/bssrdf/bssrdf_profile.h"

/* The last entries are authored as albedo + mean free path; their
 * coefficients are filled in once, by the same inversion the scene loader
 * applies to "subsurface_albedo" / "mean_free_path_mm":
 *   jade_mfp: Rohat 2011's green jade (Table 6.4, sigma_s' 0.66/0.80/0.70,
 *     sigma_a 0.22/0.012/0.15 per mm, eta 1.61), re-expressed as its dipole
 *     albedo and mean free path, rounded;
 *   skin_mfp: Jensen et al.'s skin1 at eta 1.3, re-expressed the same way. */
static lu_material_preset k_presets[] = {
    {"apple", {2.29f, 2.39f, 1.97f}, {0.0030f, 0.0034f, 0.046f}, 1.3f, {0}, {0}},
    {"chicken1", {0.15f, 0.21f, 0.38f}, {0.015f, 0.077f, 0.19f}, 1.3f, {0}, {0}},
    {"chicken2", {0.19f, 0.25f, 0.32f}, {0.018f, 0.088f, 0.20f}, 1.3f, {0}, {0}},
    {"cream", {7.38f, 5.47f, 3.15f}, {0.0002f, 0.0028f, 0.0163f}, 1.3f, {0}, {0}},
    {"ketchup", {0.18f, 0.07f, 0.03f}, {0.061f, 0.97f, 1.45f}, 1.3f, {0}, {0}},
    {"marble", {2.19f, 2.62f, 3.00f}, {0.0021f, 0.0041f, 0.0071f}, 1.3f, {0}, {0}},
    {"potato", {0.68f, 0.70f, 0.55f}, {0.0024f, 0.0090f, 0.12f}, 1.3f, {0}, {0}},
    {"skimmilk", {0.70f, 1.22f, 1.90f}, {0.0014f, 0.0025f, 0.0142f}, 1.3f, {0}, {0}},
    {"skin1", {0.74f, 0.88f, 1.01f}, {0.032f, 0.17f, 0.48f}, 1.3f, {0}, {0}},
    {"skin2", {1.09f, 1.59f, 1.79f}, {0.013f, 0.070f, 0.145f}, 1.3f, {0}, {0}},
    {"spectralon", {11.6f, 20.4f, 14.9f}, {0.0f, 0.0f, 0.0f}, 1.3f, {0}, {0}},
    {"wholemilk", {2.55f, 3.21f, 3.77f}, {0.0011f, 0.0024f, 0.014f}, 1.3f, {0}, {0}},
    {"jade_mfp", {0}, {0}, 1.61f, {0.158f, 0.502f, 0.201f}, {1.136f, 1.232f, 1.176f}},
    {"skin_mfp", {0}, {0}, 1.3f, {0.436f, 0.227f, 0.131f}, {1.295f, 0.952f, 0.671f}},
};

void lu_material_from_albedo(const float albedo[3], const float mfp_mm[3], float eta, lu_vec3 *sigma_s_prime,
                             lu_vec3 *sigma_a) {
    float sp[3], sa[3];
    for (int c = 0; c < 3; c++) {
        double a = lu_bssrdf_invert_albedo(albedo[c], eta), st = 1.0 / mfp_mm[c];
        sp[c] = (float)(a * st);
        sa[c] = (float)((1.0 - a) * st);
    }
    *sigma_s_prime = lu_v3(sp[0], sp[1], sp[2]);
    *sigma_a = lu_v3(sa[0], sa[1], sa[2]);
}

static pthread_once_t g_presets_once = PTHREAD_ONCE_INIT;

static void fill_authored(void) {
    for (size_t i = 0; i < sizeof k_presets / sizeof k_presets[0]; i++) {
        lu_material_preset *p = &k_presets[i];
        if (!(p->albedo[0] > 0.0f)) continue;
        lu_vec3 sp, sa;
        lu_material_from_albedo(p->albedo, p->mfp_mm, p->eta, &sp, &sa);
        for (int c = 0; c < 3; c++) {
            p->sigma_s_prime[c] = lu_v3_get(sp, c);
            p->sigma_a[c] = lu_v3_get(sa, c);
        }
    }
}

const lu_material_preset *lu_material_presets(int *count) {
    pthread_once(&g_presets_once, fill_authored);
    *count = (int)(sizeof k_presets / sizeof k_presets[0]);
    return k_presets;
}

const lu_material_preset *lu_material_preset_find(const char *name) {
    int n;
    const lu_material_preset *all = lu_material_presets(&n);
    for (int i = 0; i < n; i++)
        if (strcasecmp(all[i].name, name) == 0) return &all[i];
    return NULL;
}

float lu_sigma_a_from_ior_imag(float k, float lambda_nm) {
    /* lambda in mm = lambda_nm * 1e-6 */
    return 4.0f * LU_PI * k / (lambda_nm * 1e-6f);
}
