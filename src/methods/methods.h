/* Internal: the method tables and helpers every method driver shares. */
#ifndef LU_METHODS_INTERNAL_H
#define LU_METHODS_INTERNAL_H

#include <lucent/lucent.h>

#include "kernels/lu_optics.h"

/* The renderer behind the public handle (lu_renderer in method.h). Only the
 * wrapper (method.c) writes it; a method's own stats query may read state. */
struct lu_renderer {
    const lu_method *method;
    lu_backend backend;      /* resolved: CPU or GPU, never AUTO */
    double params[LU_MAX_PARAMS];
    void *state;
    lu_progressive progressive;  /* see lu_renderer_set_progressive */
    struct lu_frame_stage *stage;   /* what the previous frame rendered */
    int frames;                     /* frames rendered since create or the last failed frame */
    lu_renderer_stats stats;
    struct lu_gpu_context *caller;  /* gl_caller_context: the caller's context the GPU work runs in */
    lu_image texture_image;         /* lu_renderer_render_texture's CPU frame, kept between frames */
    struct lu_mem_account *account; /* charged with what its calls allocate (core/memory.h) */
};

extern const lu_method lu_method_reference;
extern const lu_method lu_method_bssrdf;
extern const lu_method lu_method_pathtrace;
extern const lu_method lu_method_raymarch;
extern const lu_method lu_method_afm;
extern const lu_method lu_method_gradient;
extern const lu_method lu_method_rbf;
extern const lu_method lu_method_pervoxel;
extern const lu_method lu_method_ddod;
extern const lu_method lu_method_froxel;

/* Offset for secondary rays leaving a surface: a fixed fraction of the
 * scene's size, so it neither self-intersects nor skips thin features at any
 * scale (every method uses the same one). */
static inline float lu_scene_ray_epsilon(const lu_scene *scene) {
    lu_aabb bounds = lu_scene_bounds(scene);
    float size = lu_aabb_valid(bounds) ? lu_v3_maxc(lu_v3_sub(bounds.hi, bounds.lo)) : 1.0f;
    return 1e-5f * fmaxf(size, 1e-3f);
}

/* The kernel-side light record (cone angles as cosines). */
static inline lu_k_light lu_light_to_kernel(const lu_light *l) {
    lu_k_light k;
    k.position = l->position;
    k.direction = l->direction;
    k.intensity = l->intensity;
    k.cos_inner = cosf(l->inner_deg * (LU_PI / 180.0f));
    k.cos_outer = cosf(l->outer_deg * (LU_PI / 180.0f));
    k.type = l->type == LU_LIGHT_POINT ? LU_K_LIGHT_POINT
             : l->type == LU_LIGHT_SPOT ? LU_K_LIGHT_SPOT
                                        : LU_K_LIGHT_DIRECTIONAL;
    return k;
}

/* Normals at a camera-ray hit of `mesh` along d: the interpolated shading
 * normal n and the geometric normal ng, both turned to face the viewer
 * (n onto ng's side). */
static inline void lu_hit_normals(const lu_mesh *mesh, const lu_hit *hit, lu_vec3 d, lu_vec3 *n_out, lu_vec3 *ng_out) {
    const uint32_t *tri = &mesh->indices[3u * hit->prim_id];
    float w0 = 1.0f - hit->u - hit->v;
    lu_vec3 n = lu_v3_add(lu_v3_add(lu_v3_scale(mesh->normals[tri[0]], w0), lu_v3_scale(mesh->normals[tri[1]], hit->u)),
                          lu_v3_scale(mesh->normals[tri[2]], hit->v));
    n = lu_v3_norm(n);
    lu_vec3 ng = hit->ng;
    if (lu_v3_dot(ng, d) > 0.0f) ng = lu_v3_neg(ng);
    if (lu_v3_dot(n, ng) < 0.0f) n = lu_v3_neg(n);
    *n_out = n;
    *ng_out = ng;
}

/* Bilinear lookup of an equirectangular radiance map (u wraps, v clamps),
 * times scale; the mapping is lu_k_env_u / lu_k_env_v (lu_optics.h). */
static inline lu_vec3 lu_env_lookup(const lu_image *im, float scale, lu_vec3 dir) {
    float u = lu_k_env_u(dir) * (float)im->width - 0.5f, v = lu_k_env_v(dir) * (float)im->height - 0.5f;
    float fx = floorf(u), fy = floorf(v);
    float ax = u - fx, ay = v - fy;
    lu_vec3 acc = lu_v3s(0.0f);
    for (int j = 0; j < 2; j++) {
        int y = (int)fy + j;
        y = y < 0 ? 0 : (y >= im->height ? im->height - 1 : y);
        for (int i = 0; i < 2; i++) {
            int x = ((int)fx + i) % im->width;
            if (x < 0) x += im->width;
            const float *p = lu_image_px(im, x, y);
            float wgt = (i ? ax : 1.0f - ax) * (j ? ay : 1.0f - ay);
            acc = lu_v3_madd(acc, lu_v3(p[0], p[1], p[2]), wgt);
        }
    }
    return lu_v3_scale(acc, scale);
}

/* LU_ERR_UNSUPPORTED naming the first emissive medium, for the methods that
 * do not march the view ray (ddod, bssrdf); LU_OK when none emits. */
static inline lu_result lu_refuse_emission(const lu_scene *scene, const char *method, lu_error *err) {
    for (int m = 0; m < scene->medium_count; m++)
        if (scene->media[m].emission != LU_EMISSION_NONE)
            return lu_fail(err, LU_ERR_UNSUPPORTED,
                           "%s: medium %d of %s is emissive, and %s does not march the view ray to add emission "
                           "(use reference, pathtrace, a march method: raymarch, afm, gradient, rbf, pervoxel, or froxel)",
                           method, m, scene->path[0] ? scene->path : "the scene", method);
    return LU_OK;
}

#endif
