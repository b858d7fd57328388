/* The frame stage (frame.h): what changed between two frames' scenes.
 *
 * Scenes are compared by value where the value is small (camera, lights,
 * coefficients) and by identity where it is not: a grid by its generation
 * stamp (lu_grid_set_values and lu_grid_apply give every edit a new one), a
 * mesh by its arrays and counts (objects are baked to world space, so a moved
 * object is a new mesh). A byte compare may call equal structs different
 * (padding); that costs a rebuild, never a wrong image. */
#include "methods/frame.h"

#include <stdlib.h>

#include "methods/common/gpu_scene.h"
#include "methods/methods.h"
#include <string.h>

struct lu_frame_stage {
    bool have;                       /* a previous frame rendered */
    unsigned forced;                 /* lu_frame_stage_invalidate bits for the next frame */
    lu_camera camera;
    lu_vec3 background;
    lu_light *lights;                /* shallow copies: pointers are compared, never followed */
    int light_count, light_cap;
    lu_medium *media;
    int medium_count, medium_cap;
    lu_object *objects;
    int object_count, object_cap;
    lu_frame_stats stats;
    lu_frame_records rec;
};

lu_result lu_frame_stage_create(lu_frame_stage **out, lu_error *err) {
    *out = lu_calloc(1, sizeof **out);
    return *out ? LU_OK : lu_fail(err, LU_ERR_NOMEM, "out of memory");
}

void lu_frame_stage_destroy(lu_frame_stage *s) {
    if (!s) return;
    lu_free(s->lights);
    lu_free(s->media);
    lu_free(s->objects);
    lu_frame_records_free(&s->rec);
    lu_free(s);
}

lu_result lu_frame_records_update(lu_frame_records *rec, const lu_scene *scene, lu_error *err) {
    const lu_camera *c = &scene->camera;
    rec->cam = lu_k_camera_make(c->position, c->look_at, c->up, c->fov_y_deg, c->width, c->height);
    if (scene->medium_count > rec->medium_cap) {
        lu_k_medium *m = lu_realloc(rec->media, (size_t)scene->medium_count * sizeof *m);
        if (!m) return lu_fail(err, LU_ERR_NOMEM, "frame records: out of memory");
        rec->media = m;
        rec->medium_cap = scene->medium_count;
    }
    if (scene->light_count > rec->light_cap) {
        size_t n = (size_t)scene->light_count;
        lu_k_light *l = lu_realloc(rec->lights, n * sizeof *l);
        if (l) rec->lights = l;
        lu_k_light *a = l ? lu_realloc(rec->scene_lights, n * sizeof *a) : NULL;
        if (a) rec->scene_lights = a;
        if (!l || !a) return lu_fail(err, LU_ERR_NOMEM, "frame records: out of memory");
        rec->light_cap = scene->light_count;
    }
    for (int m = 0; m < scene->medium_count; m++) rec->media[m] = lu_medium_to_kernel(&scene->media[m]);
    rec->medium_count = scene->medium_count;
    rec->light_count = scene->light_count ? lu_scene_kernel_lights(scene, rec->lights) : 0;
    for (int l = 0; l < scene->light_count; l++) rec->scene_lights[l] = lu_light_to_kernel(&scene->lights[l]);
    return LU_OK;
}

void lu_frame_records_free(lu_frame_records *rec) {
    lu_free(rec->media);
    lu_free(rec->lights);
    lu_free(rec->scene_lights);
    memset(rec, 0, sizeof *rec);
}

static bool same(const void *a, const void *b, size_t n) { return memcmp(a, b, n) == 0; }
#define SAME(a, b) same(&(a), &(b), sizeof(a))

static bool same_mesh(const lu_mesh *a, const lu_mesh *b) {
    return a->vertex_count == b->vertex_count && a->triangle_count == b->triangle_count &&
           a->positions == b->positions && a->normals == b->normals && a->indices == b->indices;
}

static bool same_camera(const lu_camera *a, const lu_camera *b) {
    return SAME(a->position, b->position) && SAME(a->look_at, b->look_at) && SAME(a->up, b->up) &&
           a->fov_y_deg == b->fov_y_deg && a->width == b->width && a->height == b->height;
}

static bool same_light(const lu_light *a, const lu_light *b) {
    return a->type == b->type && SAME(a->position, b->position) && SAME(a->direction, b->direction) &&
           SAME(a->intensity, b->intensity) && a->inner_deg == b->inner_deg && a->outer_deg == b->outer_deg &&
           a->env.rgb == b->env.rgb && a->env.width == b->env.width && a->env.height == b->env.height &&
           a->env_scale == b->env_scale;
}

/* What the medium scatters and absorbs, and where its density is. */
static bool same_medium_values(const lu_medium *a, const lu_medium *b) {
    return a->kind == b->kind && a->constant == b->constant && SAME(a->sigma_a, b->sigma_a) &&
           SAME(a->sigma_s, b->sigma_s) && a->phase_g == b->phase_g && a->eta == b->eta &&
           SAME(a->surface, b->surface) && a->from_object == b->from_object && a->grid.data == b->grid.data &&
           a->grid.tree == b->grid.tree && a->grid.generation == b->grid.generation && SAME(a->index_to_world, b->index_to_world) &&
           a->emission == b->emission && SAME(a->le_color, b->le_color) && a->le_scale == b->le_scale &&
           a->temp_scale == b->temp_scale && a->temp_offset == b->temp_offset &&
           a->emission_grid.data == b->emission_grid.data && a->emission_grid.generation == b->emission_grid.generation;
}

/* Where the medium is: its transform, box, grid size and boundary mesh. */
static bool same_medium_geometry(const lu_medium *a, const lu_medium *b) {
    return SAME(a->index_to_world, b->index_to_world) && SAME(a->bounds, b->bounds) && a->grid.nx == b->grid.nx &&
           a->grid.ny == b->grid.ny && a->grid.nz == b->grid.nz && a->has_boundary == b->has_boundary &&
           same_mesh(&a->boundary, &b->boundary);
}

lu_result lu_frame_stage_begin(lu_frame_stage *s, const lu_scene *scene, lu_frame *f, lu_error *err) {
    f->scene = scene;
    f->stats = &s->stats;
    f->rec = &s->rec;
    lu_result r = lu_frame_records_update(&s->rec, scene, err);
    if (r != LU_OK) return r;
    if (!s->have) {
        f->changed = LU_CHANGE_ALL;
        f->lights_changed = ~0ull;
        return LU_OK;
    }
    unsigned c = s->forced;
    uint64_t lights = 0;
    if (!same_camera(&scene->camera, &s->camera)) c |= LU_CHANGE_CAMERA;
    if (!SAME(scene->background, s->background)) c |= LU_CHANGE_BACKGROUND;
    if (scene->light_count != s->light_count) {
        lights = ~0ull;
    } else {
        for (int l = 0; l < scene->light_count; l++) {
            if (same_light(&scene->lights[l], &s->lights[l])) continue;
            lights |= 1ull << (l < 63 ? l : 63);
            /* A light turning into or out of an environment light shifts the
             * kernel index of every light after it (lu_frame_kernel_lights_changed). */
            if ((scene->lights[l].type == LU_LIGHT_ENVIRONMENT) != (s->lights[l].type == LU_LIGHT_ENVIRONMENT))
                lights = ~0ull;
        }
    }
    if (s->forced & LU_CHANGE_LIGHTS) lights = ~0ull;
    if (lights) c |= LU_CHANGE_LIGHTS;
    if (scene->medium_count != s->medium_count) {
        c |= LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY;
    } else {
        for (int m = 0; m < scene->medium_count; m++) {
            if (!same_medium_values(&scene->media[m], &s->media[m])) c |= LU_CHANGE_MEDIA;
            if (!same_medium_geometry(&scene->media[m], &s->media[m])) c |= LU_CHANGE_GEOMETRY;
        }
    }
    if (scene->object_count != s->object_count) {
        c |= LU_CHANGE_GEOMETRY;
    } else {
        for (int o = 0; o < scene->object_count; o++)
            if (!same_mesh(&scene->objects[o].mesh, &s->objects[o].mesh) ||
                !SAME(scene->objects[o].material, s->objects[o].material))
                c |= LU_CHANGE_GEOMETRY;
    }
    f->changed = c;
    f->lights_changed = lights;
    return LU_OK;
}

static lu_result copy_array(void **dst, int *cap, const void *src, int count, size_t size, lu_error *err) {
    if (count > *cap) {
        void *p = lu_realloc(*dst, (size_t)count * size);
        if (!p) return lu_fail(err, LU_ERR_NOMEM, "out of memory");
        *dst = p;
        *cap = count;
    }
    if (count) memcpy(*dst, src, (size_t)count * size);
    return LU_OK;
}

lu_result lu_frame_stage_end(lu_frame_stage *s, const lu_scene *scene, bool ok, lu_error *err) {
    s->have = false;
    if (!ok) return LU_OK;
    lu_result r = copy_array((void **)&s->lights, &s->light_cap, scene->lights, scene->light_count, sizeof *s->lights, err);
    if (r == LU_OK)
        r = copy_array((void **)&s->media, &s->medium_cap, scene->media, scene->medium_count, sizeof *s->media, err);
    if (r == LU_OK)
        r = copy_array((void **)&s->objects, &s->object_cap, scene->objects, scene->object_count, sizeof *s->objects,
                       err);
    if (r != LU_OK) return r;
    s->light_count = scene->light_count;
    s->medium_count = scene->medium_count;
    s->object_count = scene->object_count;
    s->camera = scene->camera;
    s->background = scene->background;
    s->forced = 0;
    s->have = true;
    return LU_OK;
}

void lu_frame_stage_invalidate(lu_frame_stage *s, unsigned what) { s->forced |= what & LU_CHANGE_ALL; }

const lu_frame_stats *lu_frame_stage_stats(const lu_frame_stage *s) { return &s->stats; }

void lu_frame_rebuilt(const lu_frame *f, const char *product) {
    lu_frame_stats *st = f->stats;
    if (!st) return;
    for (int i = 0; i < st->count; i++)
        if (strcmp(st->product[i].name, product) == 0) {
            st->product[i].rebuilds++;
            return;
        }
    if (st->count == LU_FRAME_MAX_PRODUCTS) return;
    st->product[st->count].name = product;
    st->product[st->count].rebuilds = 1;
    st->count++;
}

uint64_t lu_frame_kernel_lights_changed(const lu_frame *f) {
    if (!(f->changed & LU_CHANGE_LIGHTS)) return 0;
    if (f->lights_changed == ~0ull) return ~0ull;
    uint64_t out = 0;
    for (int l = 0, k = 0; l < f->scene->light_count; l++) {
        if (f->scene->lights[l].type == LU_LIGHT_ENVIRONMENT) continue;
        if (lu_frame_light_changed(f, l)) out |= 1ull << (k < 63 ? k : 63);
        k++;
    }
    return out;
}

/* ---- bands of rows (lu_renderer_render_rows) ---- */

typedef struct band_job {
    lu_range_fn fn;
    void *ctx;
    int64_t first;                   /* the band's first row (or tile) */
} band_job;

static void band_range(void *ctx, int64_t begin, int64_t end, int thread) {
    const band_job *j = ctx;
    j->fn(j->ctx, j->first + begin, j->first + end, thread);
}

/* The next band of rows clipped to the image, or false when the source is
 * done. An empty or reversed band after clipping is skipped. */
static bool next_band(const lu_frame *f, int height, int *y0, int *y1) {
    for (;;) {
        if (!f->rows(f->rows_user, y0, y1)) return false;
        if (*y0 < 0) *y0 = 0;
        if (*y1 > height) *y1 = height;
        if (*y0 < *y1) return true;
    }
}

void lu_frame_for_rows(const lu_frame *f, int64_t grain, lu_range_fn fn, void *ctx, const char *progress_label) {
    int height = f->scene->camera.height;
    if (!f->rows) {
        lu_parallel_for(height, grain, fn, ctx, progress_label);
        return;
    }
    int y0, y1;
    while (next_band(f, height, &y0, &y1)) {
        double t0 = lu_time_seconds();
        band_job j = {fn, ctx, y0};
        lu_parallel_for(y1 - y0, grain, band_range, &j, NULL);
        if (f->rows_seconds) *f->rows_seconds += lu_time_seconds() - t0;
    }
}

void lu_frame_for_tiles(const lu_frame *f, int tile, int tiles_x, int tiles_y, lu_range_fn fn, void *ctx) {
    if (!f->rows) {
        lu_parallel_for((int64_t)tiles_x * tiles_y, 1, fn, ctx, NULL);
        return;
    }
    int y0, y1;
    while (next_band(f, f->scene->camera.height, &y0, &y1)) {
        double t0 = lu_time_seconds();
        int ty0 = y0 / tile, ty1 = (y1 + tile - 1) / tile;
        if (ty1 > tiles_y) ty1 = tiles_y;
        band_job j = {fn, ctx, (int64_t)ty0 * tiles_x};
        /* Tiles of one tile row are consecutive indices. */
        if (ty0 < ty1) lu_parallel_for((int64_t)(ty1 - ty0) * tiles_x, 1, band_range, &j, NULL);
        if (f->rows_seconds) *f->rows_seconds += lu_time_seconds() - t0;
    }
}
