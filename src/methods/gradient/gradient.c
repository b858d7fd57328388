/* The gradient family's driver (Ren, Zhou, Lin, Guo 2008; the three methods
 * gradient, rbf and pervoxel are its modes, gradient_modes.c). All three end
 * in the same view march (lu_view_march.h with the source term from the
 * radiance grid). Per frame, each product rebuilt only when what it reads
 * changed (methods/frame.h): the density the CPU traces (the Gaussian fit,
 * gradient_fit.h, and its reconstruction), the sample set and its
 * evaluation (gradient_samples.c: the tracing on the backend, the splitting
 * control there), the cell lists of the final samples, the radiance grid
 * (one gather per voxel on the backend); then the march. The CPU traces the
 * reconstruction, the GPU the scene's grid textures (equal to it up to float
 * rounding). */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "methods/frame.h"
#include "methods/gradient/gradient_cpu.h"
#include "methods/methods.h"

/* ---- lifetime ---- */

void lu_gr_destroy(void *state) {
    lu_gr_state *st = state;
    if (!st) return;
    lu_gradient_gpu_destroy(st->gpu);
    lu_media_rays_free(&st->mr);
    /* pervoxel's dens are views of the scene's grids */
    for (int m = 0; m < st->nm && st->mode != LU_K_GR_PERVOXEL; m++) {
        if (st->dens) lu_grid_destroy(&st->dens[m]);
        if (st->fits) lu_gauss_fit_free(&st->fits[m]);
    }
    lu_free(st->dens);
    lu_free(st->fits);
    lu_free(st->smp);
    lu_free(st->tau);
    lu_free(st->E);
    lu_free(st->active);
    lu_free(st->Ev);
    lu_free(st->memo);
    for (int L = 0; L < LU_GR_MEMO_LEVELS; L++) lu_free(st->memo_map[L]);
    lu_free(st->final);
    lu_free(st->cell_begin);
    lu_free(st->cell_items);
    lu_free(st->field);
    lu_free(st);
}

lu_result lu_gr_prepare_mode(const lu_scene *scene, const double *params, int param_count,
                             const lu_param_desc *defaults, lu_backend backend, int mode, void **out, lu_error *err) {
    const char *who = mode == LU_K_GR_GRADIENT ? "gradient" : mode == LU_K_GR_RBF ? "rbf" : "pervoxel";
    lu_gr_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
    st->mode = mode;
    st->backend = backend;
    /* Defaults for the sample parameters pervoxel does not have. */
    for (int i = 0; i < P_COUNT; i++) st->p[i] = defaults[i].def;
    for (int i = 0; i < param_count; i++) st->p[i] = params[i];
    st->nm = scene->medium_count;
    lu_result r = LU_OK;
    if (scene->medium_count < 1)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "%s: the scene has no participating medium (it renders media only)", who);
    else if (scene->medium_count > LU_K_RM_MAX_MEDIA)
        r = lu_fail(err, LU_ERR_LIMIT, "%s: %d media (at most %d)", who, scene->medium_count, LU_K_RM_MAX_MEDIA);
    for (int m = 1; m < scene->medium_count && r == LU_OK; m++)
        if (scene->media[m].phase_g != scene->media[0].phase_g)
            r = lu_fail(err, LU_ERR_UNSUPPORTED,
                        "%s: media %d and 0 have different phase_g (%g vs %g); the source radiance field holds one phase",
                        who, m, scene->media[m].phase_g, scene->media[0].phase_g);
    st->eps = lu_scene_ray_epsilon(scene);
    st->who = who;
    if (r == LU_OK) r = lu_media_rays_init(&st->mr, scene, (int)st->p[P_SHADOW_RES], true, err);
    size_t nm = scene->medium_count ? (size_t)scene->medium_count : 1u;
    st->dens = lu_calloc(nm, sizeof *st->dens);
    st->fits = lu_calloc(nm, sizeof *st->fits);
    if ((!st->dens || !st->fits) && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", who);
    if (r == LU_OK && backend == LU_BACKEND_GPU) r = lu_gradient_gpu_create(scene, &st->gpu, err);
    if (r != LU_OK) {
        lu_gr_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

/* ---- the density the CPU traces ---- */

/* Finest density voxel and largest grid dimension: the scales of delta1,
 * the radiance grid and the splitting levels. */
static void density_scales(lu_gr_state *st, const lu_scene *scene) {
    st->box = lu_scene_media_bounds(scene);
    st->density_voxel = 0.0f;
    st->density_res = 0;
    for (int m = 0; m < scene->medium_count; m++) {
        const lu_medium *med = &scene->media[m];
        if (med->kind != LU_DENSITY_GRID) continue;
        float vs = lu_gr_index_scale(&med->index_to_world);
        if (st->density_voxel == 0.0f || vs < st->density_voxel) st->density_voxel = vs;
        int dm = med->grid.nx > med->grid.ny ? med->grid.nx : med->grid.ny;
        if (med->grid.nz > dm) dm = med->grid.nz;
        if (dm > st->density_res) st->density_res = dm;
    }
    if (st->density_res == 0) st->density_res = 64;
    if (st->density_voxel == 0.0f && lu_aabb_valid(st->box))
        st->density_voxel = lu_v3_maxc(lu_v3_sub(st->box.hi, st->box.lo)) / 64.0f;
}

/* pervoxel traces the scene's grids as they are; the sample methods the
 * Gaussian representation (product "gradient.fit": the density's values and
 * geometry), which also places their initial samples. */
static lu_result update_density(lu_gr_state *st, const lu_frame *frame, lu_error *err) {
    const lu_scene *scene = frame->scene;
    if (st->mode == LU_K_GR_PERVOXEL) {
        for (int m = 0; m < st->nm; m++)
            st->dens[m] = scene->media[m].kind == LU_DENSITY_GRID ? scene->media[m].grid : (lu_grid){0};
        return LU_OK;
    }
    if (!lu_frame_stale(frame, st->fit_valid, LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY)) return LU_OK;
    st->fit_valid = false;
    st->stats.gaussians = 0;
    st->stats.fit_ms = st->stats.reconstruct_ms = 0.0;
    double worst_fit = 0.0;
    lu_result r = LU_OK;
    for (int m = 0; m < st->nm && r == LU_OK; m++) {
        lu_grid_destroy(&st->dens[m]);
        lu_gauss_fit_free(&st->fits[m]);
        const lu_medium *med = &scene->media[m];
        if (med->kind != LU_DENSITY_GRID) continue;
        r = lu_gauss_fit_grid(&med->grid, (int)st->p[P_GAUSSIANS], (float)st->p[P_MAX_RADIUS], &st->fits[m], err);
        if (r != LU_OK) break;
        st->stats.gaussians += st->fits[m].count;
        st->stats.fit_ms += st->fits[m].ms;
        if (st->fits[m].rel_l2 > worst_fit) worst_fit = st->fits[m].rel_l2;
        double t0 = lu_time_seconds();
        r = lu_gauss_reconstruct(&st->fits[m], &st->dens[m], err);
        st->stats.reconstruct_ms += 1e3 * (lu_time_seconds() - t0);
    }
    st->stats.fit_rel_l2 = worst_fit;
    if (r != LU_OK) return r;
    st->fit_valid = true;
    lu_frame_rebuilt(frame, "gradient.fit");
    return LU_OK;
}

/* ---- radiance grid and march on the CPU ---- */

static void field_range(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lu_gr_state *st = ctx;
    for (int64_t i = begin; i < end; i++) {
        lu_vec3 v = lu_k_gr_voxel(&st->kctx, st->kctx.G, (int)i);
        memcpy(st->field + 3 * (size_t)i, &v, 12);
    }
}

static void march_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lu_gr_state *st = ctx;
    const lu_camera *c = &st->scene->camera;
    lu_k_rm_params P;
    P.background = st->frame.background;
    P.step = st->frame.step;
    P.eps = st->frame.eps;
    P.jitter = 0;
    P.map_res = st->kctx.G.map_res;
    P.t_cut = st->frame.t_cut;
    P.ms = st->kctx.G.ms; /* unused: the octaves are in the radiance grid */
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < c->width; x++) {
            int px = (int)(y * c->width + x);
            lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + 0.5f, (float)y + 0.5f);
            lu_vec3 L = lu_k_gr_radiance(&st->kctx, P, px, c->position, d);
            float *o = lu_image_px(st->out, x, (int)y);
            o[0] = L.x;
            o[1] = L.y;
            o[2] = L.z;
        }
}

/* Fraction of radiance voxels with density whose field is exactly 0 (no
 * valid sphere holds them, or every light is blocked there); every 7th
 * voxel, only when the stats are printed. */
static double uncovered_fraction(lu_gr_state *st) {
    if (st->mode == LU_K_GR_PERVOXEL) return 0.0;
    const lu_k_gr_params *G = &st->kctx.G;
    size_t nv = (size_t)G->nx * G->ny * G->nz, dense = 0, bare = 0;
    for (size_t i = 0; i < nv; i += 7) {
        lu_vec3 p = lu_k_gr_voxel_pos(*G, (int)i);
        if (!(lu_k_gr_total_density(&st->kctx, p) > 0.0f)) continue;
        dense++;
        const float *f = st->field + 3 * i;
        if (f[0] == 0.0f && f[1] == 0.0f && f[2] == 0.0f) bare++;
    }
    return dense ? (double)bare / (double)dense : 0.0;
}

lu_result lu_gr_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    lu_gr_state *st = state;
    if (scene->medium_count != st->nm)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: the scene's media changed since prepare", st->who);
    st->scene = scene;
    st->out = out;
    const lu_camera *c = &scene->camera;
    st->cam = frame->rec->cam;
    st->km = frame->rec->media;
    const lu_k_light *kl = st->kl = frame->rec->lights;
    st->nl = frame->rec->light_count;
    lu_result r = lu_media_rays_camera(&st->mr, frame, st->cam, err);
    if (r == LU_OK) r = lu_media_rays_maps(&st->mr, frame, kl, st->nl, err);
    if (r == LU_OK) r = lu_media_rays_boundary_maps(&st->mr, frame, kl, st->nl, err);
    if (r == LU_OK) r = lu_media_rays_surface_vis(&st->mr, frame, st->cam, kl, st->nl, st->eps, err);
    if (r == LU_OK) r = update_density(st, frame, err);
    /* The CPU marches the reconstruction st->dens: its majorants are of it. */
    if (r == LU_OK) r = lu_media_rays_majorants(&st->mr, frame, st->dens, err);
    if (r != LU_OK) return r;
    density_scales(st, scene);

    /* Radiance grid over the media box: cubic voxels, `grid` along the longest side. */
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float emax = fmaxf(lu_v3_maxc(ext), 1e-6f);
    int res = (int)st->p[P_GRID] > 0 ? (int)st->p[P_GRID] : st->density_res;
    float vox = emax / (float)res;
    lu_k_gr_params G;
    memset(&G, 0, sizeof G);
    G.cam = c->position;
    G.delta1 = (float)st->p[P_DELTA1] * st->density_voxel;
    G.lo = st->box.lo;
    G.delta2 = (float)st->p[P_DELTA2] * vox;
    G.voxel = lu_v3s(vox);
    G.g = scene->media[0].phase_g;
    G.nx = (int)fmaxf(1.0f, ceilf(ext.x / vox - 1e-3f));
    G.ny = (int)fmaxf(1.0f, ceilf(ext.y / vox - 1e-3f));
    G.nz = (int)fmaxf(1.0f, ceilf(ext.z / vox - 1e-3f));
    G.normalize = (int)st->p[P_NORMALIZE];
    float cell = emax / 32.0f;
    G.cell = lu_v3s(cell);
    G.cx = (int)fmaxf(1.0f, ceilf(ext.x / cell));
    G.cy = (int)fmaxf(1.0f, ceilf(ext.y / cell));
    G.cz = (int)fmaxf(1.0f, ceilf(ext.z / cell));
    G.rbf_floor = 1e-6f;
    G.mode = st->mode;
    G.map_res = st->mr.shadow_res;
    G.bviews_at = st->mr.bmap_views_at;
    G.bmaps_at = st->mr.bmap_maps_at;
    G.bview_count = st->mr.bmap_view_count;
    G.surf_normals_at = 8 * st->nm;
    G.surf_vis_at = G.surf_normals_at + c->width * c->height * st->nm * LU_MR_NORMAL_FLOATS;
    G.reflect = 0;
    G.ms = lu_view_march_ms(st->p + P_MS);
    for (int m = 0; m < st->nm; m++) {
        const lu_material *sm = &scene->media[m].surface;
        float *q = st->surf + 8 * m;
        q[0] = sm->albedo.x, q[1] = sm->albedo.y, q[2] = sm->albedo.z, q[3] = sm->shininess;
        q[4] = sm->specular.x, q[5] = sm->specular.y, q[6] = sm->specular.z, q[7] = 0.0f;
        G.reflect |= scene->media[m].has_boundary;
    }
    st->stats.grid[0] = G.nx, st->stats.grid[1] = G.ny, st->stats.grid[2] = G.nz;
    st->kctx = (struct lu_k_ctx){st->dens, st->km, st->nm, st->kl, st->nl, &st->mr, G, NULL, NULL, NULL, NULL, st->surf,
                                 scene->media};

    lu_aabb mb = st->box;
    float diag = lu_aabb_valid(mb) ? lu_v3_len(lu_v3_sub(mb.hi, mb.lo)) : 1.0f;
    lu_gradient_frame *f = &st->frame;
    f->G = G;
    f->background = scene->background;
    f->step = fmaxf(diag, 1e-6f) / (float)st->p[P_STEPS];
    f->eps = st->eps;
    f->jitter = 0;
    f->t_cut = (float)st->p[P_T_CUT];
    f->width = c->width;
    f->height = c->height;
    f->medium_count = scene->medium_count;
    f->light_count = st->nl;
    f->rec = frame->rec;
    f->mr = &st->mr;
    f->surf = st->surf;

    /* Splitting levels (the finest grid stays at half the density resolution or coarser). */
    int levels = st->mode != LU_K_GR_PERVOXEL ? (int)st->p[P_LEVELS] : 0;
    while (levels > 0 && (16 << (levels - 1)) > (st->density_res + 1) / 2) levels--;
    /* The light-side products, samples and radiance grid, read the lights,
     * the media and their geometry; the camera too where the source radiance
     * depends on the view direction (an anisotropic phase, Eq. 1) or the
     * splitting weighs each sample's error by its transmittance to the camera
     * (Eq. 5). */
    unsigned light_side = LU_CHANGE_LIGHTS | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY;
    bool rebuild = lu_frame_stale(frame, st->light_valid, light_side | (G.g != 0.0f || levels > 0 ? LU_CHANGE_CAMERA : 0u));
    /* The sample evaluations (roots and split vertices) without tau_v read
     * the camera only through the phase. */
    bool keep = !lu_frame_stale(frame, st->evals_valid, light_side | (G.g != 0.0f ? LU_CHANGE_CAMERA : 0u));
    double t0 = lu_time_seconds();
    st->stats.ms_samples = st->stats.ms_field = 0.0;
    st->stats.evaluated = 0;
    if (rebuild) {
        st->light_valid = false;
        memset(st->stats.level_samples, 0, sizeof st->stats.level_samples);
        memset(st->stats.split, 0, sizeof st->stats.split);
        st->stats.root_samples = st->stats.fill_samples = st->stats.samples = 0;
        st->stats.cell_items = 0;
        if (!keep) st->evals_valid = false;
        r = st->mode != LU_K_GR_PERVOXEL ? lu_gr_build_samples(st, scene, levels, keep, err) : lu_gr_empty_cells(st, err);
        if (r != LU_OK) return r;
        st->stats.ms_samples = 1e3 * (lu_time_seconds() - t0);
        if (st->mode != LU_K_GR_PERVOXEL && !keep) lu_frame_rebuilt(frame, "gradient.samples");
        st->evals_valid = true;
    }
    f->samples = st->final;
    f->sample_count = st->nfinal;
    f->cell_begin = st->cell_begin;
    f->cell_items = st->cell_items;
    f->cell_item_count = st->cell_begin[G.cx * G.cy * G.cz];

    size_t nv = (size_t)G.nx * G.ny * G.nz;
    if (nv > st->field_cap) {
        lu_free(st->field);
        st->field = lu_malloc(nv * 3 * sizeof(float));
        st->field_cap = st->field ? nv : 0;
        if (!st->field) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for a %zu-voxel radiance grid", st->who, nv);
    }
    st->kctx.field = st->field;
    st->kctx.cell_begin = st->cell_begin;
    st->kctx.cell_items = st->cell_items;
    st->kctx.samples = st->final;
    if (st->backend == LU_BACKEND_GPU) {
        r = lu_gradient_gpu_render(st->gpu, scene, f, rebuild, out, &st->stats.ms_field, &st->stats.ms_march, err);
    } else {
        t0 = lu_time_seconds();
        if (rebuild) lu_parallel_for((int64_t)nv, 256, field_range, st, NULL);
        double t1 = lu_time_seconds();
        st->stats.ms_field = 1e3 * (t1 - t0);
        lu_frame_for_rows(frame, 1, march_rows, st, NULL);
        st->stats.ms_march = 1e3 * (lu_time_seconds() - t1);
        if (lu_log_enabled(LU_LOG_DEBUG)) st->stats.uncovered = uncovered_fraction(st);
    }
    if (r != LU_OK) return r;
    if (rebuild) {
        st->light_valid = true;
        lu_frame_rebuilt(frame, "gradient.radiance_grid");
    }
    if (lu_log_enabled(LU_LOG_DEBUG))
        lu_log_msg(LU_LOG_DEBUG,
                "%s: gaussians %d (fit rel-L2 %.4f, %.1f ms), roots %d (fill %d), evaluated %d, final samples %d, levels "
                "%d/%d/%d/%d, "
                "split %d/%d/%d, grid %dx%dx%d, cell items %lld, uncovered %.4f, ms samples %.2f field %.2f march "
                "%.2f\n",
                st->who, st->stats.gaussians, st->stats.fit_rel_l2, st->stats.fit_ms, st->stats.root_samples,
                st->stats.fill_samples, st->stats.evaluated, st->stats.samples, st->stats.level_samples[0], st->stats.level_samples[1], st->stats.level_samples[2],
                st->stats.level_samples[3], st->stats.split[0], st->stats.split[1], st->stats.split[2], G.nx, G.ny,
                G.nz, st->stats.cell_items, st->stats.uncovered, st->stats.ms_samples, st->stats.ms_field,
                st->stats.ms_march);
    return LU_OK;
}
