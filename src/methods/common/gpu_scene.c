/* The shared GPU scene (see gpu_scene.h). */
#include "methods/common/gpu_scene.h"
#include "volume/grid_internal.h"

#include <stdlib.h>
#include <string.h>

#include "methods/common/majorant.h"
#include "methods/methods.h"

struct lu_gpu_scene {
    lu_gpu_context *ctx;
    int medium_count;
    int grid_dims[LU_SCENE_MAX_MEDIA][3];    /* 0 for constant media */
    uint64_t grid_generation[LU_SCENE_MAX_MEDIA];   /* lu_grid.generation of the texture's values */
    lu_gpu_texture *grid[LU_SCENE_MAX_MEDIA];
    bool sparse[LU_SCENE_MAX_MEDIA];         /* the grid is a tree in the header buffer */
    size_t header_bytes;                     /* camera, tree records, trees */
    lu_majorant maj[LU_SCENE_MAX_MEDIA];     /* of the texture's values (lu_scene_layout.h) */
    lu_gpu_buffer *header, *media, *lights;
    size_t lights_bytes;
    /* What the media and lights buffers hold, so that a frame uploads only
     * what changed (a camera move: the header alone). Grid generations are
     * unique in the process (volume/grid.c), so a replaced emission grid
     * shows as a new one. */
    bool media_valid, lights_valid;
    bool majorants_changed;                  /* since the media buffer's upload */
    lu_k_medium held_media[LU_SCENE_MAX_MEDIA];
    uint64_t held_emission[LU_SCENE_MAX_MEDIA];   /* emission grid generation, 0: none */
    lu_k_light *held_lights;
    int held_light_count, held_light_cap;
    int media_uploads, light_uploads;
};

/* A sparse grid goes to the GPU as a tree only when its dense box would be
 * larger than this (or than a 3D texture may be): sampling a texture is
 * far cheaper there, and on llvmpipe a shader that reads trees takes
 * minutes to compile (docs/volumes.md "Sparse grids"). */
static uint64_t g_dense_texture_max = 256ull << 20;

void lu_gpu_scene_set_dense_limit(uint64_t bytes) { g_dense_texture_max = bytes; }

static bool medium_uses_tree(const lu_medium *m) {
    if (m->kind != LU_DENSITY_GRID || !lu_grid_is_sparse(&m->grid)) return false;
    const lu_grid *g = &m->grid;
    uint64_t dense = (uint64_t)g->nx * (uint64_t)g->ny * (uint64_t)g->nz * sizeof(float);
    return dense > g_dense_texture_max || g->nx > 2048 || g->ny > 2048 || g->nz > 2048;
}

const char *lu_gpu_scene_defines(const lu_scene *scene) {
    for (int m = 0; m < scene->medium_count; m++)
        if (medium_uses_tree(&scene->media[m])) return "#define LU_SCENE_TREES 1\n";
    return "";
}

lu_k_medium lu_medium_to_kernel(const lu_medium *m) {
    lu_k_medium k;
    memset(&k, 0, sizeof k);
    bool grid = m->kind == LU_DENSITY_GRID;
    const lu_affine a = grid ? m->world_to_index : lu_affine_identity();
    k.w2i_x = lu_v3(a.m[0][0], a.m[0][1], a.m[0][2]);
    k.w2i_y = lu_v3(a.m[1][0], a.m[1][1], a.m[1][2]);
    k.w2i_z = lu_v3(a.m[2][0], a.m[2][1], a.m[2][2]);
    k.w2i_t = lu_v3(a.m[0][3], a.m[1][3], a.m[2][3]);
    if (grid) {
        lu_aabb s = lu_grid_index_support(&m->grid);
        k.support_lo = s.lo;
        k.support_hi = s.hi;
    } else {
        k.support_lo = m->bounds.lo;
        k.support_hi = m->bounds.hi;
    }
    k.bounds_lo = m->bounds.lo;
    k.bounds_hi = m->bounds.hi;
    k.sigma_a = m->sigma_a;
    k.sigma_s = m->sigma_s;
    k.g = m->phase_g;
    k.density_scale = grid ? 1.0f : m->constant;
    k.eta = m->eta;
    k.constant = grid ? 0 : 1;
    k.bounded = m->has_boundary ? 1 : 0;
    k.max_pieces = grid ? m->grid.nx + m->grid.ny + m->grid.nz + 8 : 1;
    k.emission = (int)m->emission;
    k.le = m->emission != LU_EMISSION_NONE ? lu_v3_scale(m->le_color, m->le_scale) : lu_v3s(0.0f);
    return k;
}

int lu_scene_kernel_lights(const lu_scene *scene, lu_k_light *out) {
    int n = 0;
    for (int l = 0; l < scene->light_count; l++)
        if (scene->lights[l].type != LU_LIGHT_ENVIRONMENT) out[n++] = lu_light_to_kernel(&scene->lights[l]);
    return n;
}

static void put4(float *dst, lu_vec3 v, float w) {
    dst[0] = v.x;
    dst[1] = v.y;
    dst[2] = v.z;
    dst[3] = w;
}

/* The packer side of lu_scene_layout.h's record tables (p: the record). */
#define PUT_XYZ(i, f) p[4 * (i)] = k.f.x, p[4 * (i) + 1] = k.f.y, p[4 * (i) + 2] = k.f.z;
#define PUT_WF(i, f) p[4 * (i) + 3] = k.f;
#define PUT_WI(i, f) p[4 * (i) + 3] = (float)k.f;

static uint64_t emission_generation(const lu_medium *md) {
    bool grid = md->emission == LU_EMISSION_GRID || md->emission == LU_EMISSION_BLACKBODY;
    return grid ? md->emission_grid.generation : 0;
}

/* True when the media buffer holds other records than this frame's. */
static bool media_stale(const lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec) {
    if (!gs->media_valid || gs->majorants_changed) return true;
    for (int m = 0; m < gs->medium_count; m++)
        if (memcmp(&gs->held_media[m], &rec->media[m], sizeof rec->media[m]) != 0 ||
            gs->held_emission[m] != emission_generation(&scene->media[m]))
            return true;
    return false;
}

static bool lights_stale(const lu_gpu_scene *gs, const lu_frame_records *rec) {
    return !gs->lights_valid || gs->held_light_count != rec->light_count ||
           (rec->light_count && memcmp(gs->held_lights, rec->lights, (size_t)rec->light_count * sizeof *rec->lights) != 0);
}

/* Remembers what went up (after a successful upload). */
static lu_result hold_records(lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec, bool media,
                              bool lights, lu_error *err) {
    if (media) {
        for (int m = 0; m < gs->medium_count; m++) {
            gs->held_media[m] = rec->media[m];
            gs->held_emission[m] = emission_generation(&scene->media[m]);
        }
        gs->majorants_changed = false;
        gs->media_valid = true;
    }
    if (lights) {
        gs->lights_valid = false;
        if (rec->light_count > gs->held_light_cap) {
            lu_k_light *p = lu_realloc(gs->held_lights, (size_t)rec->light_count * sizeof *p);
            if (!p) return lu_fail(err, LU_ERR_NOMEM, "gpu scene: out of memory");
            gs->held_lights = p;
            gs->held_light_cap = rec->light_count;
        }
        if (rec->light_count) memcpy(gs->held_lights, rec->lights, (size_t)rec->light_count * sizeof *rec->lights);
        gs->held_light_count = rec->light_count;
        gs->lights_valid = true;
    }
    return LU_OK;
}

static lu_result upload_lights(lu_gpu_scene *gs, const lu_frame_records *rec, lu_error *err) {
    int light_count = rec->light_count, nl = light_count > 0 ? light_count : 1;
    size_t lbytes = (size_t)nl * LU_SCENE_LIGHT_VEC4 * 4 * sizeof(float);
    float *lights = lu_calloc((size_t)nl * LU_SCENE_LIGHT_VEC4 * 4, sizeof(float));
    if (!lights) return lu_fail(err, LU_ERR_NOMEM, "gpu scene: out of memory");
    for (int l = 0; l < light_count; l++) {
        float *p = lights + (size_t)l * LU_SCENE_LIGHT_VEC4 * 4;
        const lu_k_light k = rec->lights[l];
        LU_SCENE_LIGHT_RECORD(PUT_XYZ, PUT_WF, PUT_WI)
    }
    lu_result r = LU_OK;
    if (gs->lights && gs->lights_bytes < lbytes) {
        lu_gpu_buffer_destroy(gs->lights);
        gs->lights = NULL;
    }
    if (!gs->lights) {
        r = lu_gpu_buffer_create(gs->ctx, lbytes, lights, &gs->lights, err);
        gs->lights_bytes = lbytes;
    } else {
        r = lu_gpu_buffer_upload(gs->lights, 0, lights, lbytes, err);
    }
    lu_free(lights);
    return r;
}

static lu_result upload_media(lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec, lu_error *err) {
    size_t maj_floats = 0;
    for (int m = 0; m < gs->medium_count; m++) maj_floats += (size_t)gs->maj[m].nx * gs->maj[m].ny * gs->maj[m].nz;
    size_t emis_floats = 0;
    for (int m = 0; m < gs->medium_count; m++) {
        const lu_medium *md = &scene->media[m];
        if (md->emission == LU_EMISSION_GRID || md->emission == LU_EMISSION_BLACKBODY)
            emis_floats += (size_t)md->emission_grid.nx * md->emission_grid.ny * md->emission_grid.nz;
    }
    size_t table_floats = emis_floats ? 3 * LU_SCENE_BLACKBODY_N : 0;
    size_t media_floats = (size_t)LU_SCENE_MAJORANT_DATA * 4 + (maj_floats + emis_floats + table_floats + 3) / 4 * 4;
    if (maj_floats + emis_floats + table_floats >= (size_t)1 << 24) {
        return lu_fail(err, LU_ERR_LIMIT,
                       "gpu scene: %zu floats of majorants and emission grids; the GPU buffer addresses at most 2^24 "
                       "(offsets are exact floats)",
                       maj_floats + emis_floats + table_floats);
    }
    float *media = lu_calloc(media_floats, sizeof(float));
    if (!media) return lu_fail(err, LU_ERR_NOMEM, "gpu scene: out of memory");
    size_t at = 0;
    for (int m = 0; m < gs->medium_count; m++) {
        const lu_majorant *mj = &gs->maj[m];
        size_t n = (size_t)mj->nx * mj->ny * mj->nz;
        float *h = media + (size_t)(LU_SCENE_MAJORANT_HEADER + m) * 4;
        h[0] = (float)mj->nx;
        h[1] = (float)mj->ny;
        h[2] = (float)mj->nz;
        h[3] = (float)at;
        if (n) memcpy(media + (size_t)LU_SCENE_MAJORANT_DATA * 4 + at, mj->dmax, n * sizeof(float));
        at += n;
    }
    /* Grid and temperature emission after the majorants, then the blackbody table. */
    size_t table_at = at + emis_floats;
    for (int m = 0; m < gs->medium_count; m++) {
        const lu_medium *md = &scene->media[m];
        if (md->emission != LU_EMISSION_GRID && md->emission != LU_EMISSION_BLACKBODY) continue;
        const lu_grid *g = &md->emission_grid;
        size_t n = (size_t)g->nx * g->ny * g->nz;
        float *h = media + (size_t)(LU_SCENE_EMISSION_HEADER + 2 * m) * 4;
        h[0] = (float)g->nx;
        h[1] = (float)g->ny;
        h[2] = (float)g->nz;
        h[3] = (float)at;
        h[4] = md->temp_scale;
        h[5] = md->temp_offset;
        h[6] = (float)table_at;
        h[7] = 0.0f;
        memcpy(media + (size_t)LU_SCENE_MAJORANT_DATA * 4 + at, g->data, n * sizeof(float));
        at += n;
    }
    if (table_floats) lu_blackbody_table(media + (size_t)LU_SCENE_MAJORANT_DATA * 4 + table_at);
    for (int m = 0; m < scene->medium_count; m++) {
        const lu_k_medium k = rec->media[m];
        float *p = media + (size_t)m * LU_SCENE_MEDIUM_VEC4 * 4;
        LU_SCENE_MEDIUM_RECORD(PUT_XYZ, PUT_WF, PUT_WI)
    }
    size_t bytes = media_floats * sizeof(float);
    lu_result r = gs->media ? lu_gpu_buffer_upload(gs->media, 0, media, bytes, err)
                            : lu_gpu_buffer_create(gs->ctx, bytes, media, &gs->media, err);
    lu_free(media);
    return r;
}

/* Packs the records (lu_scene_layout.h) and uploads those that changed. */
static lu_result upload_records(lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec, lu_error *err) {
    const lu_camera *c = &scene->camera;
    const lu_k_camera cam = rec->cam;
    int light_count = rec->light_count;
    bool up_media = media_stale(gs, scene, rec), up_lights = lights_stale(gs, rec);
    /* Until an upload succeeds, its buffer is not known to hold this frame's records. */
    if (up_media) gs->media_valid = false;
    if (up_lights) gs->lights_valid = false;
    lu_result r = LU_OK;
    if (up_lights) r = upload_lights(gs, rec, err), gs->light_uploads += r == LU_OK;
    if (r == LU_OK && up_media) r = upload_media(gs, scene, rec, err), gs->media_uploads += r == LU_OK;
    if (r == LU_OK) r = hold_records(gs, scene, rec, up_media, up_lights, err);
    float header[LU_SCENE_HEADER_VEC4 * 4];
    put4(header, c->position, (float)c->width);
    put4(header + 4, cam.right, (float)c->height);
    put4(header + 8, cam.up, (float)scene->medium_count);
    put4(header + 12, cam.forward, (float)light_count);
    if (r == LU_OK) r = lu_gpu_buffer_upload(gs->header, 0, header, sizeof header, err);
    return r;
}

/* The header buffer past the camera: the tree records and the sparse grids'
 * trees (lu_scene_layout.h), made (again, when a sparse grid was replaced)
 * at the size they need. */
static size_t align32(uint64_t n) { return (size_t)((n + 31u) / 32u * 32u); }

static lu_result upload_trees(lu_gpu_scene *gs, const lu_scene *scene, lu_error *err) {
    uint64_t total = LU_SCENE_TREES_BYTE;
    for (int m = 0; m < scene->medium_count; m++) {
        if (!gs->sparse[m]) continue;
        const lu_grid *g = &scene->media[m].grid;
        lu_k_tree t = lu_grid_tree_view(g);
        uint32_t tiles = pnanovdb_root_get_tile_count(t.buf, t.root);
        if (tiles > LU_TREE_GPU_ROOT_TILES)
            return lu_fail(err, LU_ERR_LIMIT,
                           "gpu scene: grid \"%s\" has %u root tiles; the GPU reads at most %d (a box up to 4096 "
                           "voxels a side, LU_TREE_GPU_ROOT_TILES): render this scene on the CPU",
                           g->name, tiles, LU_TREE_GPU_ROOT_TILES);
        total += align32(g->tree_bytes);
    }
    lu_gpu_info info;
    lu_gpu_info_get(gs->ctx, &info);
    if (total > (uint64_t)info.max_ssbo_size || total > UINT32_MAX)
        return lu_fail(err, LU_ERR_LIMIT,
                       "gpu scene: the sparse grids' trees need a %llu-byte storage buffer; this GPU's largest is "
                       "%lld bytes (GL_MAX_SHADER_STORAGE_BLOCK_SIZE; lucent info --gpu): render this scene on the CPU",
                       (unsigned long long)total, (long long)info.max_ssbo_size);
    uint32_t table[LU_SCENE_TREE_TABLE + LU_SCENE_TREE_WORDS * LU_SCENE_MAX_MEDIA];
    memset(table, 0, sizeof table);
    size_t at = LU_SCENE_TREES_BYTE;
    for (int m = 0; m < scene->medium_count; m++) {
        if (!gs->sparse[m]) continue;
        const lu_grid *g = &scene->media[m].grid;
        uint32_t *t = table + LU_SCENE_TREE_TABLE + LU_SCENE_TREE_WORDS * m;
        t[0] = (uint32_t)(at + lu_grid_tree_view(g).root.address.byte_offset);
        for (int a = 0; a < 3; a++) t[1 + a] = (uint32_t)g->tree_lo[a];
        t[4] = (uint32_t)g->nx, t[5] = (uint32_t)g->ny, t[6] = (uint32_t)g->nz;
        t[7] = 1u;
        at += align32(g->tree_bytes);
    }
    lu_result r = LU_OK;
    if (gs->header && gs->header_bytes < total) {
        lu_gpu_buffer_destroy(gs->header);
        gs->header = NULL;
    }
    if (!gs->header) {
        r = lu_gpu_buffer_create(gs->ctx, (size_t)total, NULL, &gs->header, err);
        if (r != LU_OK) return r;
        gs->header_bytes = (size_t)total;
    }
    r = lu_gpu_buffer_upload(gs->header, 0, table, sizeof table, err);
    at = LU_SCENE_TREES_BYTE;
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        if (!gs->sparse[m]) continue;
        const lu_grid *g = &scene->media[m].grid;
        r = lu_gpu_buffer_upload(gs->header, at, g->tree, (size_t)g->tree_bytes, err);
        at += align32(g->tree_bytes);
    }
    return r;
}

lu_result lu_gpu_scene_create(lu_gpu_context *ctx, const lu_scene *scene, lu_gpu_scene **out, lu_error *err) {
    *out = NULL;
    if (!ctx || !scene) return lu_fail(err, LU_ERR_INVALID_ARG, "gpu scene: no context or scene");
    if (scene->medium_count > LU_SCENE_MAX_MEDIA)
        return lu_fail(err, LU_ERR_LIMIT, "gpu scene: %d media, the GPU backend takes at most %d",
                       scene->medium_count, LU_SCENE_MAX_MEDIA);
    lu_gpu_scene *gs = lu_calloc(1, sizeof *gs);
    if (!gs) return lu_fail(err, LU_ERR_NOMEM, "gpu scene: out of memory");
    gs->ctx = ctx;
    gs->medium_count = scene->medium_count;
    lu_result r = LU_OK;
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        const lu_medium *med = &scene->media[m];
        if (med->kind != LU_DENSITY_GRID) continue;
        gs->grid_dims[m][0] = med->grid.nx;
        gs->grid_dims[m][1] = med->grid.ny;
        gs->grid_dims[m][2] = med->grid.nz;
        gs->sparse[m] = medium_uses_tree(med);
        if (!gs->sparse[m]) {
            lu_grid dense = {0};
            if (lu_grid_is_sparse(&med->grid)) r = lu_grid_densify(&med->grid, &dense, err);
            if (r == LU_OK)
                r = lu_gpu_texture3d_create(ctx, med->grid.nx, med->grid.ny, med->grid.nz,
                                            dense.data ? dense.data : med->grid.data, &gs->grid[m], err);
            lu_grid_destroy(&dense);
        }
        if (r == LU_OK) r = lu_majorant_build(&med->grid, LU_SCENE_MAJORANT_BLOCK, &gs->maj[m], err);
        gs->grid_generation[m] = med->grid.generation;
    }
    if (r == LU_OK) r = upload_trees(gs, scene, err);
    /* Buffers from the start, so that binding before the first frame's update is safe. */
    lu_frame_records rec = {0};
    if (r == LU_OK) r = lu_frame_records_update(&rec, scene, err);
    if (r == LU_OK) r = upload_records(gs, scene, &rec, err);
    lu_frame_records_free(&rec);
    if (r != LU_OK) {
        lu_gpu_scene_destroy(gs);
        return r;
    }
    *out = gs;
    return LU_OK;
}

lu_result lu_gpu_scene_update(lu_gpu_scene *gs, const lu_scene *scene, const lu_frame_records *rec, lu_error *err) {
    if (scene->medium_count != gs->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "gpu scene: the scene has %d media, %d were uploaded",
                       scene->medium_count, gs->medium_count);
    for (int m = 0; m < scene->medium_count; m++) {
        const lu_medium *med = &scene->media[m];
        bool grid = med->kind == LU_DENSITY_GRID;
        /* A sparse grid may be replaced by another of any size (its tree is
         * uploaded again); a dense one keeps its texture's size. */
        if (grid && gs->sparse[m] && medium_uses_tree(med)) continue;
        if ((grid != (gs->grid[m] != NULL)) ||
            (grid && (med->grid.nx != gs->grid_dims[m][0] || med->grid.ny != gs->grid_dims[m][1] ||
                      med->grid.nz != gs->grid_dims[m][2])))
            return lu_fail(err, LU_ERR_INVALID_ARG, "gpu scene: medium %d's grid changed since the upload", m);
    }
    /* Density edits (lu_grid_set_values, lu_grid_apply) give the grid a new
     * generation: its values go up again, the texture object stays. */
    lu_result r = LU_OK;
    bool trees = false;
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        const lu_grid *g = &scene->media[m].grid;
        if (gs->sparse[m] && g->generation != gs->grid_generation[m]) {
            trees = true;
            lu_majorant_destroy(&gs->maj[m]);
            gs->majorants_changed = true;
            r = lu_majorant_build(g, LU_SCENE_MAJORANT_BLOCK, &gs->maj[m], err);
            if (r == LU_OK) gs->grid_generation[m] = g->generation;
            continue;
        }
        if (!gs->grid[m] || g->generation == gs->grid_generation[m]) continue;
        lu_grid dense = {0};
        if (lu_grid_is_sparse(g)) r = lu_grid_densify(g, &dense, err);
        if (r == LU_OK) r = lu_gpu_texture3d_upload(gs->grid[m], dense.data ? dense.data : g->data, err);
        lu_grid_destroy(&dense);
        /* Same block counts (same dims): the buffer keeps its size. */
        if (r == LU_OK) {
            lu_majorant_destroy(&gs->maj[m]);
            gs->majorants_changed = true;
            r = lu_majorant_build(g, LU_SCENE_MAJORANT_BLOCK, &gs->maj[m], err);
        }
        if (r == LU_OK) gs->grid_generation[m] = g->generation;
    }
    if (r == LU_OK && trees) r = upload_trees(gs, scene, err);
    return r == LU_OK ? upload_records(gs, scene, rec, err) : r;
}

void lu_gpu_scene_uploads(const lu_gpu_scene *gs, int *media, int *lights) {
    *media = gs->media_uploads;
    *lights = gs->light_uploads;
}

lu_result lu_gpu_scene_bind(lu_gpu_scene *gs, lu_error *err) {
    lu_result r = lu_gpu_buffer_bind(gs->header, LU_SCENE_BINDING_HEADER, err);
    if (r == LU_OK) r = lu_gpu_buffer_bind(gs->media, LU_SCENE_BINDING_MEDIA, err);
    if (r == LU_OK) r = lu_gpu_buffer_bind(gs->lights, LU_SCENE_BINDING_LIGHTS, err);
    for (int m = 0; m < gs->medium_count && r == LU_OK; m++)
        if (gs->grid[m]) r = lu_gpu_texture_bind(gs->grid[m], LU_SCENE_UNIT_GRID0 + m, err);
    return r;
}

void lu_gpu_scene_destroy(lu_gpu_scene *gs) {
    if (!gs) return;
    for (int m = 0; m < LU_SCENE_MAX_MEDIA; m++) {
        lu_gpu_texture_destroy(gs->grid[m]);
        lu_majorant_destroy(&gs->maj[m]);
    }
    lu_gpu_buffer_destroy(gs->header);
    lu_gpu_buffer_destroy(gs->media);
    lu_free(gs->held_lights);
    lu_gpu_buffer_destroy(gs->lights);
    lu_free(gs);
}
