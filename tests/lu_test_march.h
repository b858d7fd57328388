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

#endif
