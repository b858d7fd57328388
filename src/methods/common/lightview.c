/* Light views framing a region, and shadow maps ray cast with Embree. */
#include "methods/common/lightview.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

static float far_distance(lu_vec3 from, lu_aabb b) {
    float far2 = 0.0f;
    for (int i = 0; i < 8; i++) {
        lu_vec3 c = lu_v3(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
        lu_vec3 d = lu_v3_sub(c, from);
        far2 = fmaxf(far2, lu_v3_dot(d, d));
    }
    return sqrtf(far2);
}

void lu_lightviews_for_light(const lu_light *l, lu_aabb region, lu_lightviews *out) {
    memset(out, 0, sizeof *out);
    if (!lu_aabb_valid(region)) region = (lu_aabb){lu_v3s(-1.0f), lu_v3s(1.0f)};
    lu_vec3 centre = lu_v3_scale(lu_v3_add(region.lo, region.hi), 0.5f);
    float radius = 0.5f * lu_v3_len(lu_v3_sub(region.hi, region.lo)) * 1.01f + 1e-6f;
    switch (l->type) {
    case LU_LIGHT_DIRECTIONAL: {
        /* Orthographic over the region's bounding sphere; light travels along -direction. */
        lu_k_lightview *v = &out->view[0];
        v->axis_w = lu_v3_neg(l->direction);
        v->axis_u = lu_k_basis_u(v->axis_w);
        v->axis_v = lu_v3_cross(v->axis_w, v->axis_u);
        v->origin = lu_v3_madd(centre, v->axis_w, -radius);
        v->extent_u = v->extent_v = radius;
        v->depth_far = 2.0f * radius;
        v->ortho = 1;
        out->count = 1;
        break;
    }
    case LU_LIGHT_SPOT: {
        lu_k_lightview *v = &out->view[0];
        v->axis_w = l->direction;
        v->axis_u = lu_k_basis_u(v->axis_w);
        v->axis_v = lu_v3_cross(v->axis_w, v->axis_u);
        v->origin = l->position;
        float half = fminf(l->outer_deg, 85.0f) * (LU_PI / 180.0f);
        v->extent_u = v->extent_v = tanf(half);
        v->depth_far = far_distance(l->position, region);
        v->ortho = 0;
        out->count = 1;
        break;
    }
    case LU_LIGHT_POINT:
        for (int f = 0; f < 6; f++) out->view[f] = lu_k_cube_view(l->position, f, far_distance(l->position, region));
        out->count = 6;
        break;
    default:
        break;
    }
}

lu_result lu_lightviews_for_scene(const lu_scene *scene, lu_aabb region, float cube_widen, lu_k_lightview **views,
                                  float **packed, int **table, int *count, lu_error *err) {
    size_t nls = scene->light_count ? (size_t)scene->light_count : 1u;
    lu_free(*views);
    lu_free(*packed);
    lu_free(*table);
    *views = lu_calloc(nls * 6, sizeof **views);
    *packed = lu_calloc(nls * 6 * 16, sizeof **packed);
    *table = lu_calloc(nls * 2, sizeof **table);
    *count = 0;
    if (!*views || !*packed || !*table) return lu_fail(err, LU_ERR_NOMEM, "out of memory for light views");
    int k = 0;
    for (int l = 0; l < scene->light_count; l++) {
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) continue;
        lu_lightviews lv;
        lu_lightviews_for_light(&scene->lights[l], region, &lv);
        (*table)[2 * k] = *count;
        (*table)[2 * k + 1] = lv.count;
        for (int v = 0; v < lv.count; v++) {
            if (lv.count == 6) {
                lv.view[v].extent_u *= cube_widen;
                lv.view[v].extent_v *= cube_widen;
            }
            lu_lightview_pack(&lv.view[v], *packed + (size_t)*count * 16);
            (*views)[(*count)++] = lv.view[v];
        }
        k++;
    }
    return LU_OK;
}

int lu_lightviews_select(const lu_lightviews *v, lu_vec3 x) {
    if (v->count == 0) return -1;
    int i = v->count == 6 ? lu_k_cube_face(lu_v3_sub(x, v->view[0].origin)) : 0;
    return lu_k_lightview_inside(lu_k_lightview_project(v->view[i], x)) ? i : -1;
}

void lu_lightview_pack(const lu_k_lightview *w, float *p) {
    memcpy(p, &w->origin, 12);
    p[3] = (float)w->ortho;
    memcpy(p + 4, &w->axis_u, 12);
    p[7] = w->extent_u;
    memcpy(p + 8, &w->axis_v, 12);
    p[11] = w->extent_v;
    memcpy(p + 12, &w->axis_w, 12);
    p[15] = w->depth_far;
}

typedef struct shadow_job {
    const lu_accel *opaque;
    const lu_k_lightview *v;
    int res;
    float far_value;
    float *depth;
} shadow_job;

static void shadow_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    shadow_job *j = ctx;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < j->res; x++) {
            float d = j->far_value;
            if (j->opaque) {
                lu_k_lightray r = lu_k_lightview_ray(*j->v, ((float)x + 0.5f) / (float)j->res,
                                                     ((float)y + 0.5f) / (float)j->res);
                lu_hit h;
                if (lu_accel_closest(j->opaque, r.origin, r.dir, 0.0f, FLT_MAX, &h)) d = h.t;
            }
            j->depth[(size_t)y * j->res + x] = d;
        }
    }
}

lu_result lu_shadow_map_build(const lu_accel *opaque, const lu_k_lightview *v, int res, float far_value, float *depth,
                              lu_error *err) {
    if (res < 1 || res > LU_MAX_IMAGE_DIM) return lu_fail(err, LU_ERR_RANGE, "shadow map resolution %d out of range", res);
    shadow_job j = {opaque, v, res, far_value, depth};
    lu_parallel_for(res, 0, shadow_rows, &j, NULL);
    return LU_OK;
}
