/* Private state of the path tracer, shared by its files: pathtrace.c (the
 * paths, their light connections, the render loop) and pathtrace_walk.c (free
 * flight through media and the subsurface walk's steps). Documented in
 * docs/pathtrace.md. */
#ifndef LU_PATHTRACE_STATE_H
#define LU_PATHTRACE_STATE_H

#include <lucent/lucent.h>

#include <stdatomic.h>

#include "methods/pathtrace/pathtrace_internal.h"

typedef struct pt_state pt_state;

/* Walk counters (pathtrace.stats): one block per thread, summed at the end.
 * Counting never draws random numbers, so it does not change an image. */
typedef struct pt_stats {
    uint64_t paths, segments;       /* camera samples; ray segments walked (one surface query each) */
    uint64_t vertices, sealed_vertices; /* volume scattering vertices; of those inside a sealed medium */
    uint64_t entries, inside_hits;  /* boundary crossings into a sealed medium; boundary hits from inside one */
    uint64_t reflected, tir;        /* inside hits sent back in by Fresnel reflection; of those, total */
    uint64_t exits, capped;         /* inside hits leaving; paths cut by the interface-event cap */
    uint64_t beam_vertices;         /* vertices connected to light beams */
    uint64_t pad[5];                /* one cache line apart per thread */
} pt_stats;
#define PT_COUNT(cs, field) \
    do {                    \
        if (cs) (cs)->field++; \
    } while (0)

/* ---- kernel context: how the shared kernels read media on the CPU ---- */
struct lu_k_ctx {
    const pt_state *st;
};
static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p);
static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz);

#include "kernels/lu_camera.h"
#include "methods/common/lu_march.h"
#include "kernels/lu_optics.h"
#include "methods/common/lu_sampling.h"
#include "methods/pathtrace/lu_tracking.h"


#define PT_MAX_BOUNDED 64 /* bounded media: one bit each in a path's inside mask */
#define PT_MAX_MEDIA 128
#define PT_MAX_CROSSINGS 256 /* surfaces a shadow ray may cross */
#define PT_MAX_SPECULAR 256  /* dielectric events per path */
#define PT_MAX_LIGHT_SEGMENTS 16

typedef struct pt_medium {
    lu_vec3 sigma_t;
    float sigma_max; /* largest channel of sigma_t */
    bool constant;
    float cdens; /* constant density */
    int bit;     /* bounded: its bit in the inside mask; -1 unbounded */
    bool refract;
    bool diffuse; /* Lambertian-transmitting boundary (boundary=diffuse) */
    float eta;
    float lambda;       /* a typical extinction (mean channel), for beam distance sampling */
    lu_pt_majorant maj; /* grid media */
    int max_pieces;     /* DDA bound for exact optical depth */
    lu_aabb box;        /* world box of non-zero density */
    lu_accel *inside;   /* its boundary alone, for inside tests */
    float v0[3], vlog[3]; /* constant media: Dwivedi's v0 per channel and ln((v0 + 1) / (v0 - 1)) */
    float guide_prob;     /* share of guided steps in the mixture; 0: not guided */
    uint32_t *neighbours; /* refracting boundaries: triangle adjacency (methods/common/mesh_adjacency.h) */
} pt_medium;

enum { SURF_OPAQUE = 0, SURF_BOUNDARY };
typedef struct pt_surf {
    int kind;
    int index; /* object or medium */
} pt_surf;

typedef struct pt_env {
    int light;       /* index in the scene's lights */
    int w, h;        /* distribution cells */
    float *cdf_rows; /* h + 1 */
    float *cdf_cols; /* h * (w + 1) */
    float *prob;     /* w * h, probability of each cell */
} pt_env;

typedef struct pt_beam {
    lu_vec3 o, u;
    float len;
    lu_vec3 flux;
    uint64_t mask;
    float lambda;
} pt_beam;

/* One light path found by manifold next-event estimation (pathtrace_mnee.c):
 * light -> refraction at s -> x. */
typedef struct pt_mnee_path {
    lu_vec3 s, ns;  /* boundary point and outward geometric normal there */
    lu_vec3 t;      /* refracted direction at s, travelling towards x */
    float dist;     /* |x - s| */
    float cos_i;    /* incidence cosine outside */
    float gain;     /* irradiance facing the light along t at x, before Fresnel and media, over the
                       irradiance at s facing the light */
    uint32_t prim;  /* boundary triangle of s */
} pt_mnee_path;

struct pt_state {
    int spp, max_depth, rr_depth, light_paths;
    bool rr, jitter;
    int spectral;
    bool equiangular;
    int transmittance;
    bool stats;
    bool guide;
    pt_stats *stats_buf; /* per thread, when stats */
    uint32_t seed;
    int boundary_mode;
    float block;
    lu_accel *surf;
    pt_surf *surf_info;
    int surf_count;
    pt_medium *media;
    int medium_count;
    pt_env *envs;
    int env_count;
    float eps;
    bool have_refract;
    uint64_t refract_bits; /* inside-mask bits of refracting media */
    uint64_t sealed_bits;  /* refracting or diffuse: no shadow ray crosses their boundary */
    int bit_medium[PT_MAX_BOUNDED]; /* medium of each inside-mask bit */
    int delta_light_count;
    lu_vec3 refract_center;
    float refract_radius;
    lu_vec3 scene_center;
    float scene_radius;
    /* Per render: */
    const lu_scene *scene;
    struct lu_k_ctx kctx;
    lu_k_camera cam;
    const lu_k_light *klights;   /* the frame's records: every light in scene order */
    uint64_t *light_mask; /* inside mask at each light's position */
    uint64_t camera_mask;
    bool have_delta_lights;
    bool have_point_lights; /* point or spot */
    double *accum;
    pt_beam *beam_buf; /* beam_cap per thread */
    int beam_cap;
    lu_image *out;
    int pass_begin, pass_end;
    atomic_llong rows_done;
    lu_progress progress;
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const pt_medium *pm = &c->st->media[m];
    return pm->constant ? pm->cdens : lu_grid_sample(&c->st->scene->media[m].grid, p);
}

static inline float lu_k_majorant(const struct lu_k_ctx *c, int m, int bx, int by, int bz) {
    const pt_medium *pm = &c->st->media[m];
    return pm->constant ? pm->cdens : lu_pt_majorant_at(&pm->maj, bx, by, bz);
}

/* ---- helpers --------------------------------------------------------------------- */

static inline bool medium_active(const pt_medium *pm, uint64_t mask) { return pm->bit < 0 || ((mask >> pm->bit) & 1u); }

static inline uint64_t mask_set(uint64_t mask, int bit, bool inside) {
    return inside ? mask | ((uint64_t)1 << bit) : mask & ~((uint64_t)1 << bit);
}

static inline lu_vec3 offset_point(lu_vec3 p, lu_vec3 ng, lu_vec3 dir, float eps) {
    return lu_v3_madd(p, ng, lu_v3_dot(ng, dir) > 0.0f ? eps : -eps);
}

static inline float rnd(lu_k_rng *r) { return lu_k_rng_float(r); }

/* Interval of the ray inside medium m's box, within [0, t_end]. */
static inline bool medium_span(const pt_medium *pm, lu_vec3 o, lu_vec3 d, float t_end, float *a, float *b) {
    return lu_aabb_ray(pm->box, o, d, 0.0f, t_end, a, b) && *b > *a;
}

typedef struct pt_flight {
    int event; /* LU_K_EVENT_SCATTER, or -1: reached t_end; LU_K_EVENT_ABSORB: path ended */
    int medium;
    float t;
    /* Emission met on the way, already weighted: at every tentative
     * collision x (real or null) of majorant mu, beta sigma_a(x) Le(x) /
     * (mu avg(r)), beta and r as they stand before that collision's event
     * (pbrt-v4's volumetric path tracer; unbiased for the integral of
     * T sigma_a Le along the flight as null-collision estimators are). */
    lu_vec3 le;
} pt_flight;

/* pathtrace_walk.c */

/* Free flight over (0, t_end) through every medium active under `mask`.
 * hero >= 0: hero-channel sampling (r tracks the spectral MIS ratios);
 * hero < 0: spectral tracking. */
pt_flight lu_pt_free_flight(const pt_state *st, lu_vec3 o, lu_vec3 d, float t_end, uint64_t mask, lu_vec3 *beta,
                            lu_vec3 *r, int hero, lu_k_rng *rng);
/* The ray cast to the next surface fused with lu_pt_free_flight (same random
 * numbers, same result) when every medium along the ray is constant and
 * contains its origin; false, having drawn nothing, otherwise. */
bool lu_pt_free_flight_to_surface(const pt_state *st, lu_vec3 o, lu_vec3 d, uint64_t mask, lu_vec3 *beta, lu_vec3 *r,
                                  int hero, lu_k_rng *rng, pt_flight *f, lu_hit *hit, bool *has);
/* guide=dwivedi: whether a vertex in medium m takes guided steps, and the step. */
bool lu_pt_guide_applies(const pt_state *st, int m, uint64_t mask);
pt_flight lu_pt_guided_step(const pt_state *st, int m, lu_vec3 o, lu_vec3 d, lu_vec3 n_out, bool guided, float phase,
                            int hero, lu_vec3 *beta, lu_vec3 *r, lu_k_rng *rng, lu_hit *hit, bool *has);

/* pathtrace_mnee.c: from x inside refracting medium m, the points on m's
 * boundary where light kl refracts towards x: a walk over the facets from
 * the first one each ray from x along seeds[k] meets, then the patch of
 * neighbouring facets that also hold one. Returns how many (at most cap),
 * each on its own facet. */
#define PT_MNEE_MAX 16
int lu_pt_mnee_solve(const pt_state *st, int m, lu_k_light kl, lu_vec3 x, const lu_vec3 *seeds, int nseeds,
                     pt_mnee_path *out, int cap);

#endif
