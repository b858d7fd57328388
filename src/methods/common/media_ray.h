/* Internal: the per-frame inputs of the fixed-step view march (methods
 * raymarch and afm), built on the CPU with Embree so both backends read
 * identical numbers (the GPU has no ray tracer):
 *   - per camera ray, the first opaque hit (lu_k_rm_hit layout, 16 floats)
 *     and each medium's first span inside its boundary mesh (2 floats);
 *   - per non-environment light, light views framing the scene and shadow
 *     maps of the opaque objects (lightview.h);
 *   - for any ray, the first span of every medium with the boundary's
 *     normals at its ends (lu_media_ray_spans), e.g. for light rays. */
#ifndef LU_METHODS_MEDIA_RAY_H
#define LU_METHODS_MEDIA_RAY_H

#include <lucent/lucent.h>

#include "kernels/lu_camera.h"
#include "methods/common/lu_lightview.h"
#include "kernels/lu_optics.h"
#include "methods/common/majorant.h"

/* Packed light view: origin + ortho, axis_u + extent_u, axis_v + extent_v,
 * axis_w + depth_far (16 floats, std430 vec4[4]). */
#define LU_RM_VIEW_FLOATS 16

/* Floats per camera-ray opaque hit (the kernels' lu_k_rm_hit). */
#define LU_MR_HIT_FLOATS 16

/* Floats per medium in the optional span normals: entry normal, exit normal
 * (outward geometric normals; zero where the span has no boundary end). */
#define LU_MR_NORMAL_FLOATS 6

typedef struct lu_media_rays {
    lu_accel *opaque;            /* diffuse objects; NULL when there are none */
    int *opaque_object;          /* accel mesh id -> scene object index */
    lu_accel **boundary;         /* per medium, NULL when unbounded */
    int medium_count;
    bool want_normals;           /* also fill `normals` for camera rays */
    /* Each product below is rebuilt only when the frame (methods/frame.h)
     * changed what it depends on; call the builders every frame. */
    /* camera rays: camera, geometry */
    float *hits, *spans, *normals;
    size_t pixels_cap;
    bool hits_valid;
    unsigned hits_version;
    /* opaque visibility of each light at each pixel's surface hit (optional):
     * camera, geometry, and per light its own changes */
    float *surface_vis;          /* pixels * nl */
    size_t surface_vis_cap;
    int vis_nl;
    bool vis_valid;
    unsigned vis_version;        /* changes whenever some light's column is rebuilt */
    /* light views and shadow maps: lights, geometry */
    int shadow_res;
    lu_k_lightview *views;
    float *views_packed;         /* view_count * LU_RM_VIEW_FLOATS */
    int *view_table;             /* per light: first view, view count */
    float *shadow;               /* view_count * res * res depths */
    int view_count;
    bool maps_valid;
    unsigned maps_version;       /* changes whenever views or shadow maps are rebuilt */
    /* boundary maps (lu_media_rays_boundary_maps): lights, geometry;
     * one float buffer, LU_MR_BMAP_HEADER: [view table as floats (2 per light)]
     * [views, LU_RM_VIEW_FLOATS each][maps: view * medium_count + m, res x res
     * texels of LU_MR_BMAP_FLOATS]; offsets in bmap_views_at, bmap_maps_at */
    float *bmap;
    size_t bmap_floats;
    int bmap_views_at, bmap_maps_at, bmap_view_count;
    bool bmap_valid;
    unsigned bmap_version;
    /* majorant grids of the view march's empty-space skipping
     * (lu_media_rays_majorants, product "view_march.occupancy"): media */
    lu_majorant *majorants;      /* per medium; dmax NULL for constant media */
    bool majorants_valid;
} lu_media_rays;

/* Floats per boundary-map texel: depth a < depth b of the light ray's segment
 * inside the medium's boundary (b <= a: none), F_t at a, F_t at b (1 where the
 * segment ends at the light rather than at a crossing). */
#define LU_MR_BMAP_FLOATS 4

/* Builds the accelerations (opaque objects, boundary meshes). */
lu_result lu_media_rays_init(lu_media_rays *mr, const lu_scene *scene, int shadow_res, bool want_normals,
                             lu_error *err);
void lu_media_rays_free(lu_media_rays *mr);

/* Camera-ray hits and spans (and normals when wanted) for the scene's camera. */
lu_result lu_media_rays_camera(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, lu_error *err);

/* Light views and shadow maps for the kernel lights kl[0..nl) (scene order,
 * environment lights left out). */
lu_result lu_media_rays_maps(lu_media_rays *mr, const lu_frame *f, const lu_k_light *kl, int nl, lu_error *err);

/* Boundary maps of the bounded media for the kernel lights kl[0..nl) (see
 * the struct): shadow rays can then clip a bounded medium to its boundary
 * (exactly for a convex one) and carry the Fresnel transmittance of each
 * crossing, as the reference does. No bounded medium: bmap_view_count 0. */
lu_result lu_media_rays_boundary_maps(lu_media_rays *mr, const lu_frame *f, const lu_k_light *kl, int nl,
                                      lu_error *err);

/* Exact opaque visibility (Embree occlusion) of the kernel lights kl[0..nl)
 * at every camera ray's surface hit, offset by eps along the geometric
 * normal: surface_vis[pixel * nl + l] in {0, 1} (1 where the ray hits no
 * surface). Call after lu_media_rays_camera and lu_media_rays_maps (same
 * lights); kept while neither changes, and per light while that light does not. */
lu_result lu_media_rays_surface_vis(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, const lu_k_light *kl,
                                    int nl, float eps, lu_error *err);

/* Per grid medium, the majorant grid (blocks of LU_SCENE_MAJORANT_BLOCK^3
 * voxels) of the density the march samples: dens[m] when dens is given and
 * dens[m].data is set (a method marching its own reconstruction of the
 * grid), the scene's grid otherwise. Rebuilt when the frame's media changed. */
lu_result lu_media_rays_majorants(lu_media_rays *mr, const lu_frame *f, const lu_grid *dens, lu_error *err);

/* A view-march frame's products in order, each kept while its inputs are:
 * camera rays, shadow maps, exact surface visibility and the majorants of
 * the scene's grids (raymarch, afm and froxel march the scene's own grids). */
lu_result lu_media_rays_view_march(lu_media_rays *mr, const lu_frame *f, lu_k_camera cam, const lu_k_light *kl, int nl,
                                   float eps, lu_error *err);

/* The first span of each medium along o + t d, t in [0, t_end]: sp[2m],
 * sp[2m+1] (empty: sp[2m+1] <= sp[2m]; unbounded media: [0, LU_K_FAR]).
 * normals (NULL, or medium_count * LU_MR_NORMAL_FLOATS) gets the boundary's
 * outward normals at the span's ends. A convex boundary has one span. */
void lu_media_ray_spans(const lu_media_rays *mr, lu_vec3 o, lu_vec3 d, float t_end, float *sp, float *normals);

#endif
