/* Per-frame inputs of the fixed-step view march, built with Embree (see
 * media_ray.h): camera hits and media spans, light views and shadow maps. */
#include "methods/common/media_ray.h"

#include <stdlib.h>
#include <string.h>

#include "kernels/lu_scene_layout.h"
#include "methods/common/lightview.h"
#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/common/opaque_accel.h"

lu_result lu_media_rays_init(lu_media_rays *mr, const lu_scene *scene, int shadow_res, bool want_normals,
                             lu_error *err) {
    memset(mr, 0, sizeof *mr);
    mr->shadow_res = shadow_res;
    mr->want_normals = want_normals;
    lu_result r = lu_opaque_accel_build(scene, &mr->opaque, &mr->opaque_object, err);
    mr->medium_count = scene->medium_count;
    size_t nm = scene->medium_count ? (size_t)scene->medium_count : 1u;
    mr->boundary = lu_calloc(nm, sizeof *mr->boundary);
    if (!mr->boundary && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "out of memory");
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++)
        if (scene->media[m].has_boundary) r = lu_mesh_accel_build(&scene->media[m].boundary, &mr->boundary[m], err);
    return r;
}

void lu_media_rays_free(lu_media_rays *mr) {
    if (mr->opaque) lu_accel_destroy(mr->opaque);
    for (int m = 0; m < mr->medium_count && mr->boundary; m++)
        if (mr->boundary[m]) lu_accel_destroy(mr->boundary[m]);
    lu_free(mr->boundary);
    lu_free(mr->opaque_object);
    lu_free(mr->hits);
    lu_free(mr->spans);
    lu_free(mr->normals);
    lu_free(mr->surface_vis);
    lu_free(mr->views);
    lu_free(mr->views_packed);
    lu_free(mr->view_table);
    lu_free(mr->shadow);
    lu_free(mr->bmap);
    for (int m = 0; m < mr->medium_count && mr->majorants; m++) lu_majorant_destroy(&mr->majorants[m]);
    lu_free(mr->majorants);
    memset(mr, 0, sizeof *mr);
}

void lu_media_ray_spans(const lu_media_rays *mr, lu_vec3 o, lu_vec3 d, float t_end, float *sp, float *normals) {
    for (int m = 0; m < mr->medium_count; m++) {
        float *nrm = normals ? normals + (size_t)m * LU_MR_NORMAL_FLOATS : NULL;
        if (nrm) memset(nrm, 0, LU_MR_NORMAL_FLOATS * sizeof *nrm);
        sp[2 * m] = 0.0f;
        sp[2 * m + 1] = LU_K_FAR;
        if (!mr->boundary[m]) continue;
        /* The first span inside the boundary along the ray (all of it for a
         * convex boundary). */
        lu_hit hs[2];
        int n = lu_accel_all_hits(mr->boundary[m], o, d, 0.0f, t_end, hs, 2);
        bool inside = lu_accel_inside(mr->boundary[m], o);
        if (inside) {
            sp[2 * m + 1] = n > 0 ? hs[0].t : LU_K_FAR;
            if (nrm && n > 0) memcpy(nrm + 3, &hs[0].ng, 12);
        } else if (n > 0) {
            sp[2 * m] = hs[0].t;
            sp[2 * m + 1] = n > 1 ? hs[1].t : LU_K_FAR;
            if (nrm) memcpy(nrm, &hs[0].ng, 12);
            if (nrm && n > 1) memcpy(nrm + 3, &hs[1].ng, 12);
        } else {
            sp[2 * m + 1] = 0.0f;
        }
    }
}

lu_result lu_media_rays_majorants(lu_media_rays *mr, const lu_frame *f, const lu_grid *dens, lu_error *err) {
    const lu_scene *scene = f->scene;
    if (!mr->majorants) {
        mr->majorants = lu_calloc(mr->medium_count ? (size_t)mr->medium_count : 1u, sizeof *mr->majorants);
        if (!mr->majorants) return lu_fail(err, LU_ERR_NOMEM, "out of memory for the majorant grids");
        mr->majorants_valid = false;
    }
    if (!lu_frame_stale(f, mr->majorants_valid, LU_CHANGE_MEDIA)) return LU_OK;
    mr->majorants_valid = false;
    lu_result r = LU_OK;
    for (int m = 0; m < mr->medium_count && r == LU_OK; m++) {
        lu_majorant_destroy(&mr->majorants[m]);
        const lu_medium *med = &scene->media[m];
        if (med->kind != LU_DENSITY_GRID) continue;
        const lu_grid *g = dens && lu_grid_has_values(&dens[m]) ? &dens[m] : &med->grid;
        r = lu_majorant_build(g, LU_SCENE_MAJORANT_BLOCK, &mr->majorants[m], err);
    }
    if (r != LU_OK) return r;
    mr->majorants_valid = true;
    lu_frame_rebuilt(f, "view_march.occupancy");
    return LU_OK;
}

/* ---- camera rays ---- */

typedef struct camera_job {
    lu_media_rays *mr;
    const lu_scene *scene;
    lu_k_camera cam;
} camera_job;

static void camera_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    camera_job *j = ctx;
    lu_media_rays *mr = j->mr;
    const lu_scene *s = j->scene;
    const lu_camera *c = &s->camera;
    int nm = mr->medium_count;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < c->width; x++) {
            size_t px = (size_t)y * c->width + x;
            lu_vec3 o = c->position, d = lu_k_camera_dir(j->cam, (float)x + 0.5f, (float)y + 0.5f);
            float *h = mr->hits + px * LU_MR_HIT_FLOATS;
            memset(h, 0, LU_MR_HIT_FLOATS * sizeof *h);
            h[3] = -1.0f;
            lu_hit hit;
            float t_end = LU_K_FAR;
            if (mr->opaque && lu_accel_closest(mr->opaque, o, d, 0.0f, LU_K_FAR, &hit)) {
                const lu_object *ob = &s->objects[mr->opaque_object[hit.mesh_id]];
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
            lu_media_ray_spans(mr, o, d, t_end, mr->spans + px * (size_t)nm * 2,
                               mr->normals ? mr->normals + px * (size_t)nm * LU_MR_NORMAL_FLOATS : NULL);
        }
    }
}

lu_result lu_media_rays_camera(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, lu_error *err) {
    const lu_scene *scene = f->scene;
    const lu_camera *c = &scene->camera;
    size_t pixels = (size_t)c->width * c->height;
    size_t nm = mr->medium_count ? (size_t)mr->medium_count : 1u;
    if (pixels > mr->pixels_cap) {
        lu_free(mr->hits);
        lu_free(mr->spans);
        lu_free(mr->normals);
        mr->hits = lu_malloc(pixels * LU_MR_HIT_FLOATS * sizeof(float));
        mr->spans = lu_malloc(pixels * nm * 2 * sizeof(float));
        mr->normals = mr->want_normals ? lu_malloc(pixels * nm * LU_MR_NORMAL_FLOATS * sizeof(float)) : NULL;
        bool ok = mr->hits && mr->spans && (mr->normals || !mr->want_normals);
        mr->pixels_cap = ok ? pixels : 0;
        mr->hits_valid = false;
        if (!ok) return lu_fail(err, LU_ERR_NOMEM, "out of memory for %zu pixels of ray inputs", pixels);
    }
    if (!lu_frame_stale(f, mr->hits_valid, LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY)) return LU_OK;
    mr->hits_valid = false;
    camera_job j = {mr, scene, cam};
    lu_parallel_for(c->height, 4, camera_rows, &j, NULL);
    mr->hits_valid = true;
    mr->hits_version++;
    lu_frame_rebuilt(f, "media_rays.camera");
    return LU_OK;
}

typedef struct vis_job {
    lu_media_rays *mr;
    const lu_scene *scene;
    lu_k_camera cam;
    const lu_k_light *kl;
    int nl;
    float eps;
    uint64_t lights;    /* kernel lights to recompute (bit 63: 63 and up) */
} vis_job;

static void vis_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    vis_job *j = ctx;
    const lu_camera *c = &j->scene->camera;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < c->width; x++) {
            size_t px = (size_t)y * c->width + x;
            const float *h = j->mr->hits + px * LU_MR_HIT_FLOATS;
            float *v = j->mr->surface_vis + px * (size_t)j->nl;
            for (int l = 0; l < j->nl; l++)
                if ((j->lights >> (l < 63 ? l : 63)) & 1u) v[l] = 1.0f;
            if (h[3] < 0.0f || !j->mr->opaque) continue;
            lu_vec3 d = lu_k_camera_dir(j->cam, (float)x + 0.5f, (float)y + 0.5f), ng;
            memcpy(&ng, h + 4, 12);
            lu_vec3 p = lu_v3_madd(lu_v3_madd(c->position, d, h[3]), ng, j->eps);
            for (int l = 0; l < j->nl; l++) {
                if (!((j->lights >> (l < 63 ? l : 63)) & 1u)) continue;
                lu_k_light_sample ls = lu_k_light_arrive(j->kl[l], p);
                v[l] = lu_accel_occluded(j->mr->opaque, p, ls.wl, 0.0f, ls.dist) ? 0.0f : 1.0f;
            }
        }
    }
}

lu_result lu_media_rays_surface_vis(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, const lu_k_light *kl,
                                    int nl, float eps, lu_error *err) {
    const lu_scene *scene = f->scene;
    const lu_camera *c = &scene->camera;
    size_t n = (size_t)c->width * c->height * (size_t)(nl ? nl : 1);
    if (n > mr->surface_vis_cap) {
        lu_free(mr->surface_vis);
        mr->surface_vis = lu_malloc(n * sizeof(float));
        mr->surface_vis_cap = mr->surface_vis ? n : 0;
        mr->vis_valid = false;
        if (!mr->surface_vis) return lu_fail(err, LU_ERR_NOMEM, "out of memory for surface visibility");
    }
    /* A moved light leaves the other lights' columns as they are. */
    uint64_t lights = ~0ull;
    if (mr->vis_valid && nl == mr->vis_nl && !(f->changed & (LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY)))
        lights = lu_frame_kernel_lights_changed(f);
    if (!lights) return LU_OK;
    mr->vis_valid = false;
    vis_job j = {mr, scene, cam, kl, nl, eps, lights};
    lu_parallel_for(c->height, 4, vis_rows, &j, NULL);
    mr->vis_valid = true;
    mr->vis_nl = nl;
    mr->vis_version++;
    for (int l = 0; l < nl; l++)
        if ((lights >> (l < 63 ? l : 63)) & 1u) lu_frame_rebuilt(f, "media_rays.surface_vis");
    return LU_OK;
}

/* ---- shadow maps of the opaque objects, per light view ---- */

lu_result lu_media_rays_maps(lu_media_rays *mr, const lu_frame *f, const lu_k_light *kl, int nl, lu_error *err) {
    const lu_scene *scene = f->scene;
    if (!lu_frame_stale(f, mr->maps_valid, LU_CHANGE_LIGHTS | LU_CHANGE_GEOMETRY)) return LU_OK;
    size_t nls = nl ? (size_t)nl : 1u;
    lu_free(mr->shadow);
    mr->shadow = NULL;
    mr->maps_valid = false;
    lu_result r = lu_lightviews_for_scene(scene, lu_scene_bounds(scene), 1.0f, &mr->views, &mr->views_packed,
                                          &mr->view_table, &mr->view_count, err);
    if (r != LU_OK) return r;
    if (!mr->opaque) {
        /* Without opaque objects nothing casts: no views, visibility 1. */
        mr->view_count = 0;
        memset(mr->view_table, 0, nls * 2 * sizeof *mr->view_table);
    }
    if (mr->opaque) {
        size_t texels = (size_t)mr->shadow_res * mr->shadow_res;
        mr->shadow = lu_malloc((mr->view_count ? (size_t)mr->view_count : 1u) * texels * sizeof(float));
        if (!mr->shadow) return lu_fail(err, LU_ERR_NOMEM, "out of memory for shadow maps");
        for (int v = 0; v < mr->view_count; v++) {
            r = lu_shadow_map_build(mr->opaque, &mr->views[v], mr->shadow_res, 1e30f, mr->shadow + v * texels, err);
            if (r != LU_OK) return r;
        }
    } else {
        mr->shadow = lu_calloc(1, sizeof(float));
        if (!mr->shadow) return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    }
    mr->maps_valid = true;
    mr->maps_version++;
    lu_frame_rebuilt(f, "media_rays.maps");
    return LU_OK;
}

/* ---- boundary maps ---- */

typedef struct bmap_job {
    const lu_media_rays *mr;
    const lu_scene *scene;
    const lu_k_lightview *views;
} bmap_job;

static void bmap_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    const bmap_job *j = ctx;
    const lu_media_rays *mr = j->mr;
    int res = mr->shadow_res, nm = mr->medium_count;
    for (int64_t row = begin; row < end; row++) {
        int y = (int)(row % res), m = (int)((row / res) % nm), v = (int)(row / ((int64_t)res * nm));
        float *out = mr->bmap + mr->bmap_maps_at + (((size_t)v * nm + m) * res + y) * (size_t)res * LU_MR_BMAP_FLOATS;
        const lu_k_lightview *vw = &j->views[v];
        const lu_accel *acc = mr->boundary[m];
        float eta = j->scene->media[m].eta;
        /* A light inside the boundary (perspective views start at the light): the segment starts there. */
        bool light_inside = acc && !vw->ortho && lu_accel_inside(acc, vw->origin);
        for (int i = 0; i < res; i++) {
            float *t = out + (size_t)i * LU_MR_BMAP_FLOATS;
            t[0] = 1.0f, t[1] = 0.0f, t[2] = 1.0f, t[3] = 1.0f;
            if (!acc) continue;
            lu_k_lightray ray = lu_k_lightview_ray(*vw, ((float)i + 0.5f) / (float)res, ((float)y + 0.5f) / (float)res);
            lu_hit hs[2];
            int n = lu_accel_all_hits(acc, ray.origin, ray.dir, 0.0f, LU_K_FAR, hs, 2);
            /* depth along the texel's ray is t for both view kinds (unit dir; ortho rays start on the view plane) */
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

lu_result lu_media_rays_boundary_maps(lu_media_rays *mr, const lu_frame *f, const lu_k_light *kl, int nl,
                                      lu_error *err) {
    const lu_scene *scene = f->scene;
    if (!lu_frame_stale(f, mr->bmap_valid, LU_CHANGE_LIGHTS | LU_CHANGE_GEOMETRY)) return LU_OK;
    bool bounded = false;
    for (int m = 0; m < mr->medium_count; m++) bounded = bounded || mr->boundary[m];
    lu_free(mr->bmap);
    mr->bmap = NULL;
    mr->bmap_floats = 0;
    mr->bmap_view_count = 0;
    mr->bmap_valid = false;
    size_t nls = nl ? (size_t)nl : 1u;
    lu_k_lightview *views = NULL;
    float *packed = NULL;
    int *table = NULL, count = 0;
    lu_result r = LU_OK;
    if (bounded) r = lu_lightviews_for_scene(scene, lu_scene_bounds(scene), 1.0f, &views, &packed, &table, &count, err);
    if (r == LU_OK) {
        size_t texels = (size_t)mr->shadow_res * mr->shadow_res;
        mr->bmap_views_at = (int)(2 * nls);
        mr->bmap_maps_at = mr->bmap_views_at + count * LU_RM_VIEW_FLOATS;
        mr->bmap_floats = (size_t)mr->bmap_maps_at + (size_t)count * mr->medium_count * texels * LU_MR_BMAP_FLOATS;
        mr->bmap = lu_calloc(mr->bmap_floats, sizeof(float));
        if (!mr->bmap) r = lu_fail(err, LU_ERR_NOMEM, "out of memory for boundary maps");
    }
    if (r == LU_OK && bounded) {
        for (int l = 0; l < 2 * nl; l++) mr->bmap[l] = (float)table[l];
        memcpy(mr->bmap + mr->bmap_views_at, packed, (size_t)count * LU_RM_VIEW_FLOATS * sizeof(float));
        mr->bmap_view_count = count;
        bmap_job j = {mr, scene, views};
        lu_parallel_for((int64_t)count * mr->medium_count * mr->shadow_res, 8, bmap_rows, &j, NULL);
    }
    lu_free(views);
    lu_free(packed);
    lu_free(table);
    if (r != LU_OK) return r;
    mr->bmap_valid = true;
    mr->bmap_version++;
    lu_frame_rebuilt(f, "media_rays.boundary_maps");
    return LU_OK;
}

lu_result lu_media_rays_view_march(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, const lu_k_light *kl, int nl,
                                   float eps, lu_error *err) {
    lu_result r = lu_media_rays_camera(mr, f, cam, err);
    if (r == LU_OK) r = lu_media_rays_maps(mr, f, kl, nl, err);
    if (r == LU_OK) r = lu_media_rays_surface_vis(mr, f, cam, kl, nl, eps, err);
    if (r == LU_OK) r = lu_media_rays_majorants(mr, f, NULL, err);
    return r;
}
