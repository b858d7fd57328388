/* Measured subsurface coefficients of Jensen, Marschner, Levoy and Hanrahan,
 * "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001, Table 1:
 * reduced scattering sigma_s' and absorption sigma_a in mm^-1 for R, G, B,
 * all measured with a relative index of refraction of 1.3. */
#include <lucent/scene.h>

#include <strings.h>

static const lu_material_preset k_presets[] = {
    {"apple", {2.29f, 2.39f, 1.97f}, {0.0030f, 0.0034f, 0.046f}, 1.3f},
    {"chicken1", {0.15f, 0.21f, 0.38f}, {0.015f, 0.077f, 0.19f}, 1.3f},
    {"chicken2", {0.19f, 0.25f, 0.32f}, {0.018f, 0.088f, 0.20f}, 1.3f},
    {"cream", {7.38f, 5.47f, 3.15f}, {0.0002f, 0.0028f, 0.0163f}, 1.3f},
    {"ketchup", {0.18f, 0.07f, 0.03f}, {0.061f, 0.97f, 1.45f}, 1.3f},
    {"marble", {2.19f, 2.62f, 3.00f}, {0.0021f, 0.0041f, 0.0071f}, 1.3f},
    {"potato", {0.68f, 0.70f, 0.55f}, {0.0024f, 0.0090f, 0.12f}, 1.3f},
    {"skimmilk", {0.70f, 1.22f, 1.90f}, {0.0014f, 0.0025f, 0.0142f}, 1.3f},
    {"skin1", {0.74f, 0.88f, 1.01f}, {0.032f, 0.17f, 0.48f}, 1.3f},
    {"skin2", {1.09f, 1.59f, 1.79f}, {0.013f, 0.070f, 0.145f}, 1.3f},
    {"spectralon", {11.6f, 20.4f, 14.9f}, {0.0f, 0.0f, 0.0f}, 1.3f},
    {"wholemilk", {2.55f, 3.21f, 3.77f}, {0.0011f, 0.0024f, 0.014f}, 1.3f},
};

const lu_material_preset *lu_material_presets(int *count) {
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
