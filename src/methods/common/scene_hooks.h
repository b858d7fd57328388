/* Internal: the generic CPU hooks of kernels that read media and lights
 * (lu_k_density, lu_k_medium_count/get, lu_k_light_count/get). Include after
 * defining `struct lu_k_ctx` that starts with LU_K_CTX_SCENE_MEMBERS (kernel_ctx.h)
 * (raymarch, afm through view_march_hooks.h, and ddod). The GPU twins are in
 * kernels/lu_scene_gpu.glsl. */
#ifndef LU_METHODS_SCENE_HOOKS_H
#define LU_METHODS_SCENE_HOOKS_H

#include <lucent/lucent.h>

#include "kernels/lu_medium.h"
#include "kernels/lu_optics.h"

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const lu_medium *med = &c->media[m];
    return med->kind == LU_DENSITY_CONSTANT ? med->constant : lu_grid_sample(&med->grid, p);
}
static inline int lu_k_medium_count(const struct lu_k_ctx *c) { return c->nm; }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) { return c->km[m]; }
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return c->nl; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) { return c->kl[l]; }

#endif
