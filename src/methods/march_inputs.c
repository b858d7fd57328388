/* Per-frame CPU inputs of camera-ray march kernels (see march_inputs.h):
 * Embree hits and bounded-media spans per pixel, light views and shadow
 * maps per light. Moved out of raymarch.c so every march method reads the
 * same buffers. */
#include "methods/march_inputs.h"

#include <stdlib.h>
#include <string.h>

#include "methods/gpu_scene.h"
#include "methods/lightview.h"
#include "methods/methods.h"

lu_result lu_march_inputs_init(lu_march_inputs *mi, const lu_scene *scene, int shadow_res, const char *who,
                               lu_error *err) {
    memset(mi, 0, sizeof *mi);
    mi->who = who;
    mi->res = shadow_res;
    lu_result r = LU_OK;
    int opaque_count = 0;
    for (int i = 0; i < scene->object_count; i++) opaque_count += scene->objects[i].material.type == LU_MATERIAL_DIFFUSE;
    if (opaque_count) {
        mi->opaque_object = calloc((size_t)opaque_count, sizeof *mi->opaque_object);
        if (!mi->opaque_object) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
        r = lu_accel_create(&mi->opaque, err);
        for (int i = 0; i < scene->object_count && r == LU_OK; i++) {
            if (scene->objects[i].material.type != LU_MATERIAL_DIFFUSE) continue;
            uint32_t id;
            r = lu_accel_add_mesh(mi->opaque, &scene->objects[i].mesh, &id, err);
            if (r == LU_OK) mi->opaque_object[id] = i;
        }
        if (r == LU_OK) r = lu_accel_commit(mi->opaque, err);
    }
    mi->medium_count = scene->medium_count;
    mi->boundary = calloc(scene->medium_count ? (size_t)scene->medium_count : 1u, sizeof *mi->boundary);
    if (!mi->boundary && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        if (!scene->media[m].has_boundary) continue;
        uint32_t id;
        r = lu_accel_create(&mi->boundary[m], err);
        if (r == LU_OK) r = lu_accel_add_mesh(mi->boundary[m], &scene->media[m].boundary, &id, err);
        if (r == LU_OK) r = lu_accel_commit(mi->boundary[m], err);
    }
    return r;
}

static void free_maps(lu_march_inputs *mi) {
    free(mi->views);
    free(mi->views_packed);
    free(mi->view_table);
    free(mi->shadow);
    free(mi->bmaps);
    free(mi->maps_lights);
    mi->views = NULL, mi->views_packed = NULL, mi->view_table = NULL, mi->shadow = NULL, mi->bmaps = NULL;
    mi->maps_lights = NULL;
    mi->bmap_floats = 0;
}

void lu_march_inputs_free(lu_march_inputs *mi) {
    if (mi->opaque) lu_accel_destroy(mi->opaque);
    for (int m = 0; m < mi->medium_count && mi->boundary; m++)
        if (mi->boundary[m]) lu_accel_destroy(mi->boundary[m]);
    free(mi->boundary);
    free(mi->opaque_object);
    free(mi->hits);
    free(mi->spans);
    free_maps(mi);
    memset(mi, 0, sizeof *mi);
}

/* ---- per-pixel hits and spans (Embree) ---- */

static void hit_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lu_march_inputs *mi = ctx;
    const lu_scene *s = mi->scene;
    const lu_camera *c = &s->camera;
    int nm = mi->medium_count;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < c->width; x++) {
            size_t px = (size_t)y * c->width + x;
            lu_vec3 o = c->position, d = lu_k_camera_dir(mi->cam, (float)x + 0.5f, (float)y + 0.5f);
            float *h = mi->hits + px * LU_MARCH_HIT_FLOATS;
            memset(h, 0, LU_MARCH_HIT_FLOATS * sizeof *h);
            h[3] = -1.0f;
            lu_hit hit;
            float t_end = LU_K_FAR;
            if (mi->opaque && lu_accel_closest(mi->opaque, o, d, 0.0f, LU_K_FAR, &hit)) {
                const lu_object *ob = &s->objects[mi->opaque_object[hit.mesh_id]];
                lu_vec3 n, ng;
                lu_hit_normals(&ob->mesh, &hit, d, &n, &ng);
                const lu_material *mt = &ob->material;
                memcpy(h, &n, 12);
                h[3] = hit.t;
                memcpy(h + 4, &ng, 12);
                memcpy(h + 8, &mt->albedo, 12);
                h[11] = mt->shininess;
                memcpy(h + 12, &mt->specular, 12);
                t_end = hit.t;
            }
            for (int m = 0; m < nm; m++) {
                float *sp = mi->spans + (px * (size_t)nm + m) * LU_MARCH_SPAN_FLOATS;
                memset(sp, 0, LU_MARCH_SPAN_FLOATS * sizeof *sp);
                sp[1] = LU_K_FAR;
                if (!mi->boundary[m]) continue;
                /* The first span inside the boundary along the ray (all of it
                 * for a convex boundary). */
                lu_hit hs[2];
                int n = lu_accel_all_hits(mi->boundary[m], o, d, 0.0f, t_end, hs, 2);
                bool inside = lu_accel_inside(mi->boundary[m], o);
                if (inside) {
                    sp[1] = n > 0 ? hs[0].t : LU_K_FAR;
                } else if (n > 0) {
                    sp[0] = hs[0].t;
                    sp[1] = n > 1 ? hs[1].t : LU_K_FAR;
                    /* entering: the boundary reflects (its material, normal towards the viewer) */
                    const lu_material *sm = &s->media[m].surface;
                    lu_vec3 ng = lu_v3_dot(hs[0].ng, d) > 0.0f ? lu_v3_neg(hs[0].ng) : hs[0].ng;
                    sp[2] = 1.0f;
                    memcpy(sp + 4, &ng, 12);
                    sp[7] = sm->shininess;
                    memcpy(sp + 8, &sm->albedo, 12);
                    memcpy(sp + 12, &sm->specular, 12);
                } else {
                    sp[1] = 0.0f;
                }
            }
        }
    }
}

static lu_result build_hits(lu_march_inputs *mi, const lu_scene *scene, lu_error *err) {
    const lu_camera *c = &scene->camera;
    size_t pixels = (size_t)c->width * c->height;
    if (pixels > mi->pixels_cap) {
        free(mi->hits);
        free(mi->spans);
        mi->hits = malloc(pixels * LU_MARCH_HIT_FLOATS * sizeof(float));
        mi->spans = malloc(pixels * (size_t)(mi->medium_count ? mi->medium_count : 1) * LU_MARCH_SPAN_FLOATS * sizeof(float));
        mi->pixels_cap = mi->hits && mi->spans ? pixels : 0;
        mi->hits_valid = false;
        if (!mi->hits || !mi->spans)
            return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for %zu pixels", mi->who, pixels);
    }
    if (mi->hits_valid && memcmp(&mi->hits_cam, c, sizeof *c) == 0) return LU_OK;
    mi->scene = scene;
    mi->cam = lu_k_camera_make(c->position, c->look_at, c->up, c->fov_y_deg, c->width, c->height);
    lu_parallel_for(c->height, 4, hit_rows, mi, NULL);
    mi->hits_cam = *c;
    mi->hits_valid = true;
    return LU_OK;
}

/* ---- boundary maps of bounded media, per light view (see march_inputs.h) ---- */

static void bmap_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lu_march_inputs *mi = ctx;
    int res = mi->res, nm = mi->medium_count;
    for (int64_t row = begin; row < end; row++) {
        int j = (int)(row % res), m = (int)((row / res) % nm), v = (int)(row / ((int64_t)res * nm));
        float *out = mi->bmaps + (((size_t)v * nm + m) * res + j) * (size_t)res * LU_MARCH_BMAP_FLOATS;
        const lu_k_lightview *vw = &mi->views[v];
        const lu_accel *acc = mi->boundary[m];
        float eta = mi->scene->media[m].eta;
        /* A light inside the boundary (perspective views start at the light): the segment starts there. */
        bool light_inside = acc && !vw->ortho && lu_accel_inside(acc, vw->origin);
        for (int i = 0; i < res; i++) {
            float *t = out + (size_t)i * LU_MARCH_BMAP_FLOATS;
            t[0] = 1.0f, t[1] = 0.0f, t[2] = 1.0f, t[3] = 1.0f;
            if (!acc) continue;
            lu_k_lightray ray = lu_k_lightview_ray(*vw, ((float)i + 0.5f) / (float)res, ((float)j + 0.5f) / (float)res);
            lu_hit hs[2];
            int n = lu_accel_all_hits(acc, ray.origin, ray.dir, 0.0f, LU_K_FAR, hs, 2);
            /* depth along the texel's ray: t for both view kinds (unit dir; ortho rays start on the view plane) */
            if (light_inside) {
                t[0] = 0.0f;
                t[1] = n > 0 ? hs[0].t : LU_K_FAR;
                t[3] = n > 0 ? lu_k_fresnel_transmittance(lu_v3_dot(hs[0].ng, ray.dir), eta) : 1.0f;
            } else if (n > 0) {
                t[0] = hs[0].t;
                t[1] = n > 1 ? hs[1].t : LU_K_FAR;
                t[2] = lu_k_fresnel_transmittance(lu_v3_dot(hs[0].ng, ray.dir), eta);
                t[3] = n > 1 ? lu_k_fresnel_transmittance(lu_v3_dot(hs[1].ng, ray.dir), eta) : 1.0f;
            }
        }
    }
}

/* ---- shadow maps of the opaque objects, per light view ---- */

static lu_result build_maps(lu_march_inputs *mi, const lu_scene *scene, const lu_k_light *kl, int nl, lu_error *err) {
    if (mi->maps_valid && nl == mi->maps_nl && memcmp(mi->maps_lights, kl, (size_t)nl * sizeof *kl) == 0)
        return LU_OK;
    size_t nlc = nl ? (size_t)nl : 1u;
    free_maps(mi);
    mi->views = calloc(nlc * 6, sizeof *mi->views);
    mi->views_packed = calloc(nlc * 6 * LU_MARCH_VIEW_FLOATS, sizeof(float));
    mi->view_table = calloc(nlc * 2, sizeof(int));
    mi->maps_lights = malloc(nlc * sizeof *mi->maps_lights);
    mi->shadow = NULL;
    mi->view_count = 0;
    mi->maps_valid = false;
    if (!mi->views || !mi->views_packed || !mi->view_table || !mi->maps_lights)
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", mi->who);
    /* Without opaque objects or bounded media: no views, visibility 1. */
    bool bounded = false;
    for (int m = 0; m < mi->medium_count; m++) bounded = bounded || mi->boundary[m];
    if (mi->opaque || bounded) {
        lu_aabb region = lu_scene_bounds(scene);
        int k = 0;
        for (int l = 0; l < scene->light_count; l++) {
            if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) continue;
            lu_lightviews lv;
            lu_lightviews_for_light(&scene->lights[l], region, &lv);
            mi->view_table[2 * k] = mi->view_count;
            mi->view_table[2 * k + 1] = lv.count;
            for (int v = 0; v < lv.count; v++) {
                const lu_k_lightview *w = &lv.view[v];
                float *p = mi->views_packed + (size_t)mi->view_count * LU_MARCH_VIEW_FLOATS;
                memcpy(p, &w->origin, 12);
                p[3] = (float)w->ortho;
                memcpy(p + 4, &w->axis_u, 12);
                p[7] = w->extent_u;
                memcpy(p + 8, &w->axis_v, 12);
                p[11] = w->extent_v;
                memcpy(p + 12, &w->axis_w, 12);
                p[15] = w->depth_far;
                mi->views[mi->view_count++] = *w;
            }
            k++;
        }
        size_t texels = (size_t)mi->res * mi->res;
        mi->shadow = malloc((mi->view_count ? (size_t)mi->view_count : 1u) * texels * sizeof(float));
        if (!mi->shadow) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for shadow maps", mi->who);
        for (int v = 0; v < mi->view_count; v++) {
            lu_result r = lu_shadow_map_build(mi->opaque, &mi->views[v], mi->res, 1e30f, mi->shadow + v * texels, err);
            if (r != LU_OK) return r;
        }
        if (bounded) {
            mi->bmap_floats = (size_t)(mi->view_count ? mi->view_count : 1) * mi->medium_count * texels * LU_MARCH_BMAP_FLOATS;
            mi->bmaps = malloc(mi->bmap_floats * sizeof(float));
            if (!mi->bmaps) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for boundary maps", mi->who);
            mi->scene = scene;
            lu_parallel_for((int64_t)mi->view_count * mi->medium_count * mi->res, 8, bmap_rows, mi, NULL);
        }
    } else {
        mi->shadow = calloc(1, sizeof(float));
        if (!mi->shadow) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", mi->who);
    }
    memcpy(mi->maps_lights, kl, (size_t)nl * sizeof *kl);
    mi->maps_nl = nl;
    mi->maps_valid = true;
    mi->maps_version++;
    return LU_OK;
}

lu_result lu_march_inputs_update(lu_march_inputs *mi, const lu_scene *scene, const lu_k_light *kl, int nl,
                                 lu_error *err) {
    if (scene->medium_count != mi->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: the scene's media changed since prepare", mi->who);
    lu_result r = build_hits(mi, scene, err);
    if (r == LU_OK) r = build_maps(mi, scene, kl, nl, err);
    return r;
}

/* ---- the same on the GPU ---- */

lu_result lu_march_inputs_gpu_put(lu_march_inputs_gpu *g, lu_gpu_context *ctx, const lu_march_inputs *mi,
                                  const lu_scene *scene, int nl, int first_binding, lu_error *err) {
    size_t pixels = (size_t)scene->camera.width * scene->camera.height;
    size_t texels = (size_t)mi->res * mi->res;
    const void *data[LU_MARCH_GPU_BUFFERS] = {mi->hits, mi->spans, mi->views_packed, mi->view_table, mi->shadow, mi->bmaps};
    size_t bytes[LU_MARCH_GPU_BUFFERS] = {pixels * LU_MARCH_HIT_FLOATS * sizeof(float),
                                          pixels * (size_t)mi->medium_count * LU_MARCH_SPAN_FLOATS * sizeof(float),
                                          (size_t)mi->view_count * LU_MARCH_VIEW_FLOATS * sizeof(float),
                                          (size_t)nl * 2 * sizeof(int),
                                          (size_t)mi->view_count * texels * sizeof(float),
                                          mi->bmap_floats * sizeof(float)};
    /* Shadow and boundary maps change only with the lights: kept when the CPU kept them. */
    bool same = g->maps_uploaded && g->maps_version == mi->maps_version;
    lu_result r = LU_OK;
    for (int i = 0; i < LU_MARCH_GPU_BUFFERS && r == LU_OK; i++)
        r = lu_gpu_slot_put(ctx, &g->buf[i], &g->size[i], first_binding + i, same && i >= 4 ? NULL : data[i], bytes[i], err);
    g->maps_uploaded = r == LU_OK;
    g->maps_version = mi->maps_version;
    return r;
}

void lu_march_inputs_gpu_free(lu_march_inputs_gpu *g) {
    for (int i = 0; i < LU_MARCH_GPU_BUFFERS; i++) lu_gpu_buffer_destroy(g->buf[i]);
    memset(g, 0, sizeof *g);
}
