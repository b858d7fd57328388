/* Internal: the CPU hooks of methods/common/lu_view_march.h over an lu_view_march_frame.
 * Include after defining `struct lu_k_ctx` that starts with
 * LU_K_CTX_VIEW_MARCH_MEMBERS (kernel_ctx.h; raymarch.c and afm.c share
 * them, afm's context adds its maps). */
#ifndef LU_METHODS_RAYMARCH_HOOKS_H
#define LU_METHODS_RAYMARCH_HOOKS_H

#include "methods/raymarch/raymarch.h"
#include "methods/common/scene_hooks.h"

/* lu_k_rm_params of a frame (defined in raymarch.c, after the kernel). */
struct lu_k_rm_params lu_view_march_frame_params(const lu_view_march_frame *f);

static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return c->f->shadow[((size_t)map * c->f->map_res + j) * c->f->map_res + i];
}
static inline int lu_k_rm_view_first(const struct lu_k_ctx *c, int l) { return c->f->view_table[2 * l]; }
static inline int lu_k_rm_view_count(const struct lu_k_ctx *c, int l) { return c->f->view_table[2 * l + 1]; }
static inline lu_k_lightview lu_k_rm_view(const struct lu_k_ctx *c, int v) { return c->views[v]; }
static inline float lu_k_rm_hit_fetch(const struct lu_k_ctx *c, int pixel, int k) {
    return c->f->hits[(size_t)pixel * 16 + k];
}
static inline float lu_k_rm_span(const struct lu_k_ctx *c, int pixel, int m, int end) {
    return c->f->spans[((size_t)pixel * c->nm + m) * 2 + end];
}
/* Without a frame's majorants (a caller building AFM maps alone) every
 * block counts as dense: nothing is skipped. */
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    if (c->km[m].constant) return c->km[m].density_scale;
    return c->f && c->f->majorants ? lu_majorant_at(&c->f->majorants[m], bx, by, bz) : 1.0f;
}

#endif
