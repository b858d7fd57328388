/* Internal: the gradient family's CPU-side state and the kernel hooks of
 * lu_gradient.h on the CPU, shared by the driver (gradient.c), the sampling
 * and splitting (gradient_samples.c) and the three method tables
 * (gradient_modes.c). */
#ifndef LU_METHODS_GRADIENT_CPU_H
#define LU_METHODS_GRADIENT_CPU_H

#include <lucent/lucent.h>

#include "methods/common/gpu_scene.h"
#include "methods/common/media_ray.h"
#include "methods/common/view_march.h"
#include "methods/frame.h"
#include "methods/gradient/gradient.h"
#include "methods/gradient/gradient_fit.h"

/* ---- kernel context: the hooks of lu_gradient.h / lu_view_march.h on the CPU ---- */
struct lu_k_ctx {
    const lu_grid *dens;          /* per medium: the density traced (lu_gr_state.dens; data NULL: constant) */
    const lu_k_medium *km;
    int nm;
    const lu_k_light *kl;
    int nl;
    const lu_media_rays *mr;
    lu_k_gr_params G;
    const float *field;
    const int *cell_begin, *cell_items;
    const float *samples;
    const float *surf;            /* 8 floats per medium: boundary material */
    const lu_medium *media;       /* the scene's, for emission */
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    return lu_grid_has_values(&c->dens[m]) ? lu_grid_sample(&c->dens[m], p) : c->km[m].density_scale;
}
static inline lu_vec3 lu_k_emission(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    return lu_medium_emission(&c->media[m], p);
}
static inline int lu_k_medium_count(const struct lu_k_ctx *c) { return c->nm; }
static inline lu_k_medium lu_k_medium_get(const struct lu_k_ctx *c, int m) { return c->km[m]; }
static inline int lu_k_light_count(const struct lu_k_ctx *c) { return c->nl; }
static inline lu_k_light lu_k_light_get(const struct lu_k_ctx *c, int l) { return c->kl[l]; }
static inline float lu_k_shadow_depth(const struct lu_k_ctx *c, int map, int i, int j) {
    return c->mr->shadow[((size_t)map * c->mr->shadow_res + j) * c->mr->shadow_res + i];
}
static inline int lu_k_rm_view_first(const struct lu_k_ctx *c, int l) { return c->mr->view_table[2 * l]; }
static inline int lu_k_rm_view_count(const struct lu_k_ctx *c, int l) { return c->mr->view_table[2 * l + 1]; }
static inline lu_k_lightview lu_k_rm_view(const struct lu_k_ctx *c, int v) { return c->mr->views[v]; }
static inline float lu_k_rm_hit_fetch(const struct lu_k_ctx *c, int pixel, int k) {
    return c->mr->hits[(size_t)pixel * LU_MR_HIT_FLOATS + k];
}
static inline float lu_k_rm_span(const struct lu_k_ctx *c, int pixel, int m, int end) {
    return c->mr->spans[((size_t)pixel * c->nm + m) * 2 + end];
}
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    return lu_grid_has_values(&c->dens[m]) ? lu_majorant_at(&c->mr->majorants[m], bx, by, bz) : c->km[m].density_scale;
}
static inline lu_k_gr_params lu_k_gr_get(const struct lu_k_ctx *c) { return c->G; }
static inline lu_vec3 lu_k_gr_field(const struct lu_k_ctx *c, int i) {
    const float *f = c->field + 3 * (size_t)i;
    return lu_v3(f[0], f[1], f[2]);
}
static inline float lu_k_gr_bmap_at(const struct lu_k_ctx *c, int k) { return c->mr->bmap[k]; }
static inline float lu_k_gr_surf(const struct lu_k_ctx *c, int k) {
    if (k < c->G.surf_normals_at) return c->surf[k];
    if (k < c->G.surf_vis_at) return c->mr->normals[k - c->G.surf_normals_at];
    return c->mr->surface_vis[k - c->G.surf_vis_at];
}
static inline int lu_k_gr_cell_begin(const struct lu_k_ctx *c, int cell) { return c->cell_begin[cell]; }
static inline int lu_k_gr_cell_end(const struct lu_k_ctx *c, int cell) { return c->cell_begin[cell + 1]; }
static inline int lu_k_gr_cell_item(const struct lu_k_ctx *c, int k) { return c->cell_items[k]; }
static inline float lu_k_gr_sample_fetch(const struct lu_k_ctx *c, int j, int k) {
    return c->samples[(size_t)j * LU_K_GR_SAMPLE_FLOATS + k];
}

#include "methods/gradient/lu_gradient.h"

_Static_assert(LU_K_RM_HIT_FLOATS == LU_MR_HIT_FLOATS, "hit record size");
_Static_assert(LU_MR_BMAP_FLOATS == 4, "lu_k_gr_light_transmittance reads 4 floats per texel");
_Static_assert(LU_K_RM_MAX_MEDIA == 8, "lu_k_gr_inscatter takes dens[8]");

/* ---- parameters: pervoxel's are the first P_PERVOXEL_COUNT ---- */
enum {
    P_STEPS, P_SHADOW_RES, P_GRID, P_DELTA1, P_NORMALIZE, P_T_CUT, P_MS,
    P_PERVOXEL_COUNT = P_MS + LU_VIEW_MARCH_MS_PARAM_COUNT,
    P_GAUSSIANS = P_PERVOXEL_COUNT, P_MAX_RADIUS, P_SEEDS, P_DELTA2, P_LEVELS, P_EPSILON, P_COUNT
};

/* Splitting levels whose vertices are kept (the `levels` parameter's maximum). */
#define LU_GR_MEMO_LEVELS 3

typedef struct lu_gr_state {
    int mode;                  /* LU_K_GR_* */
    lu_backend backend;
    double p[P_COUNT];
    const char *who;           /* method name for messages */
    lu_media_rays mr;          /* camera hits/spans, light views, shadow maps */
    int nm;
    lu_grid *dens;             /* per medium: the density the CPU traces, the reconstruction (pervoxel: views of
                                * the scene's grids); data NULL for constant media */
    lu_gauss_fit *fits;        /* per medium */
    bool fit_valid;            /* fits and dens match the scene's media ("gradient.fit") */
    bool evals_valid;          /* the kept sample evaluations ("gradient.samples") */
    bool light_valid;          /* splitting, final set, cell lists, radiance grid ("gradient.radiance_grid") */
    const lu_k_medium *km;     /* the frame's records (frame.h) */
    const lu_k_light *kl;
    int nl;
    float eps;
    float density_voxel;       /* world size of the finest density voxel */
    int density_res;           /* largest density grid dimension */
    lu_aabb box;               /* radiance grid box */
    /* samples: all evaluated this frame; active ones form the final set */
    float *smp;
    float *tau, *E;
    unsigned char *active;
    int n, cap;
    float *Ev;                 /* per sample: E_j without tau_v */
    /* Evaluations kept while the lights, the media and their geometry stay
     * (and the camera, where an anisotropic phase reads it): the roots,
     * smp[0 .. nroots), and every split vertex evaluated so far (memo:
     * records of LU_K_GR_SAMPLE_FLOATS + 1 floats, the last E_j without
     * tau_v; memo_map[L]: level L's vertex -> record, -1 when not yet). */
    int nroots, nfill;
    int *memo_map[LU_GR_MEMO_LEVELS];
    size_t memo_map_cap[LU_GR_MEMO_LEVELS];
    float *memo;
    int memo_n, memo_cap;
    float *final;              /* compacted final samples */
    int nfinal;
    int *cell_begin, *cell_items;
    size_t cells_cap, items_cap;
    float *field;
    size_t field_cap;
    float surf[8 * LU_K_RM_MAX_MEDIA]; /* boundary materials (lu_k_gr_surf) */
    lu_gradient_stats stats;
    struct lu_k_ctx kctx;
    lu_gradient_frame frame;
    lu_k_camera cam;
    const lu_scene *scene;
    lu_image *out;
    lu_gradient_gpu *gpu;
} lu_gr_state;

/* World length of one index unit of a medium (cube root of the map's volume scale). */
static inline float lu_gr_index_scale(const lu_affine *a) {
    const float(*m)[4] = a->m;
    float det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    return cbrtf(fabsf(det));
}

/* The driver (gradient.c), behind the method tables of gradient_modes.c:
 * params has param_count values, the rest of P_COUNT take defaults[i].def. */
lu_result lu_gr_prepare_mode(const lu_scene *scene, const double *params, int param_count,
                             const lu_param_desc *defaults, lu_backend backend, int mode, void **out, lu_error *err);
lu_result lu_gr_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err);
void lu_gr_destroy(void *state);

/* Sampling and splitting (gradient_samples.c). Samples: the roots, then
 * `levels` splitting levels, the final set and its cell lists over
 * st->kctx.G; keep: the kept evaluations are valid (lu_gr_state);
 * empty_cells: pervoxel's empty lists. */
lu_result lu_gr_build_samples(lu_gr_state *st, const lu_scene *scene, int levels, bool keep, lu_error *err);
lu_result lu_gr_empty_cells(lu_gr_state *st, lu_error *err);

#endif
