/* Kernel hooks of the view march (src/methods/common/lu_view_march.h) for a
 * test context of one medium `km` and one light `kl`: no emission, no opaque
 * objects (every camera ray misses), each ray's medium span the whole line,
 * no light views (no shadow map is read). The test defines struct lu_k_ctx
 * with members km and kl, and lu_k_density and lu_k_majorant, first. */
#ifndef LU_TEST_MARCH_H
#define LU_TEST_MARCH_H

static inline int lu_k_medium_count(const struct lu_k_ctx *c) { return 1; }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) { return c->km; }
static inline lu_vec3 lu_k_emission(const struct lu_k_ctx *c, int m, lu_vec3 p) { return lu_v3s(0.0f); }
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return 1; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) { return c->kl; }
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) { return 1e30f; }
static inline int lu_k_rm_view_first(const struct lu_k_ctx *c, int l) { return 0; }
static inline int lu_k_rm_view_count(const struct lu_k_ctx *c, int l) { return 0; }
static inline lu_k_lightview lu_k_rm_view(const struct lu_k_ctx *c, int v) {
    lu_k_lightview w;
    memset(&w, 0, sizeof w);
    return w;
}
static inline float lu_k_rm_hit_fetch(const struct lu_k_ctx *c, int pixel, int k) { return k == 3 ? -1.0f : 0.0f; }
static inline float lu_k_rm_span(const struct lu_k_ctx *c, int pixel, int m, int end) { return end ? 1e30f : 0.0f; }

/* The slab |x| <= w, |y| <= 1, 0 <= z <= D of constant extinction sig_t and
 * albedo (identity transform, phase g 0), lit by a directional light of
 * irradiance E along +x: the closed-form cases of the view-march tests. */
static inline void lu_test_march_slab(struct lu_k_ctx *c, float sig_t, float albedo, float w, float D, float E) {
    memset(c, 0, sizeof *c);
    c->km.w2i_x = lu_v3(1, 0, 0);
    c->km.w2i_y = lu_v3(0, 1, 0);
    c->km.w2i_z = lu_v3(0, 0, 1);
    c->km.bounds_lo = c->km.support_lo = lu_v3(-w, -1, 0);
    c->km.bounds_hi = c->km.support_hi = lu_v3(w, 1, D);
    c->km.sigma_s = lu_v3s(albedo * sig_t);
    c->km.sigma_a = lu_v3s((1.0f - albedo) * sig_t);
    c->km.density_scale = 1.0f;
    c->km.constant = 1;
    c->km.max_pieces = 1;
    c->kl.type = LU_K_LIGHT_DIRECTIONAL;
    c->kl.direction = lu_v3(1, 0, 0);
    c->kl.intensity = lu_v3s(E);
}

#endif
