/* The scene's time: numbered grid sequences and animated procedurals
 * (scene_time.h; the mapping from time to frames is in lucent/scene.h).
 *
 * A grid that follows time is produced whole for each time and swapped into
 * its medium with lu_grid_set_values. That keeps this file out of the grids'
 * storage: it speaks lu_grid in, lu_grid out, and the edit path gives the
 * frame stage its change (a new generation) and the GPU scene its re-upload.
 *
 * The frames of a NanoVDB sequence are each loaded over the box of their own
 * active voxels, which grows and shrinks as smoke moves; the medium's grid
 * covers the union of all the frames' boxes (found by reading every frame
 * once at load, which also finds a missing or mismatched frame before any
 * rendering), and each frame is re-embedded into it by its whole-voxel
 * offset. Medium bounds and transforms therefore never change with time. */
#include "scene/scene_time.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "volume/grid_internal.h"

struct lu_grid_anim {
    bool sequence;
    /* sequence */
    char path[1024];            /* with one run of '#' */
    char grid_name[64];
    int first, last;
    bool loop;
    int nx, ny, nz;             /* the union box, in the first frame's index space shifted to its corner */
    lu_affine map;
    /* procedural */
    char name[64];
    lu_kvlist params;
    char where[300];
    /* what the medium's grid holds now */
    int frame;
    double time;
};

void lu_grid_anim_free(lu_grid_anim *a) {
    if (!a) return;
    lu_kv_free(&a->params);
    lu_free(a);
}

bool lu_grid_anim_range(const lu_grid_anim *a, int *first, int *last) {
    if (!a || !a->sequence) return false;
    *first = a->first;
    *last = a->last;
    return true;
}

/* The frame a sequence shows for frame number f: held at its ends, or looped. */
static int wrap_frame(const lu_grid_anim *a, int f) {
    if (!a->loop) return f < a->first ? a->first : f > a->last ? a->last : f;
    long long n = (long long)a->last - a->first + 1, k = ((long long)f - a->first) % n;
    return (int)(a->first + (k < 0 ? k + n : k));
}

/* The run of '#' in path: its start and width; false when there is none, or
 * more than one. */
static bool hash_run(const char *path, size_t *at, int *width) {
    const char *p = strchr(path, '#');
    if (!p) return false;
    const char *q = p;
    while (*q == '#') q++;
    if (strchr(q, '#')) return false;
    *at = (size_t)(p - path);
    *width = (int)(q - p);
    return true;
}

void lu_grid_anim_frame_path(const lu_grid_anim *a, int frame, char *out, size_t size) {
    size_t at;
    int width;
    if (!hash_run(a->path, &at, &width)) {
        snprintf(out, size, "%s", a->path);
        return;
    }
    snprintf(out, size, "%.*s%0*d%s", (int)at, a->path, width, wrap_frame(a, frame), a->path + at + width);
}

static lu_vec3 voxel_size(const lu_affine *m) {
    return lu_v3(lu_v3_len(lu_v3(m->m[0][0], m->m[1][0], m->m[2][0])),
                 lu_v3_len(lu_v3(m->m[0][1], m->m[1][1], m->m[2][1])),
                 lu_v3_len(lu_v3(m->m[0][2], m->m[1][2], m->m[2][2])));
}

/* One frame's file: OpenVDB by its extension, else NanoVDB. */
static lu_result load_file(const char *path, const char *grid_name, lu_grid *g, lu_error *err) {
    return lu_path_has_suffix(path, ".vdb") ? lu_grid_load_vdb(path, grid_name, g, err)
                                            : lu_grid_load_nvdb(path, grid_name, g, err);
}

/* Loads frame f (a number in range) over the union box. */
static lu_result load_frame(const lu_grid_anim *a, int f, lu_grid *out, lu_error *err) {
    char path[1100];
    lu_grid_anim_frame_path(a, f, path, sizeof path);
    lu_grid g;
    lu_result r = load_file(path, a->grid_name[0] ? a->grid_name : NULL, &g, err);
    if (r != LU_OK) return r;
    lu_grid box = {0};
    box.index_to_world = a->map;
    int k[3];
    if (!lu_grid_shared_index_space(&box, &g, k) || k[0] < 0 || k[1] < 0 || k[2] < 0 || k[0] + g.nx > a->nx ||
        k[1] + g.ny > a->ny || k[2] + g.nz > a->nz) {
        lu_grid_destroy(&g);
        return lu_fail(err, LU_ERR_FORMAT, "%s: the file changed since the scene was loaded (its grid no longer lies "
                                           "in the sequence's box)", path);
    }
    r = lu_grid_embed(&g, k, a->nx, a->ny, a->nz, &a->map, out, err);
    lu_grid_destroy(&g);
    return r;
}

lu_result lu_grid_anim_sequence(const char *path, const char *grid_name, int first, int last, bool loop, int frame,
                                lu_grid *g, lu_grid_anim **out, lu_error *err) {
    *out = NULL;
    memset(g, 0, sizeof *g);
    size_t at;
    int width;
    if (!strchr(path, '#'))
        return lu_fail(err, LU_ERR_SCENE, "\"%s\": a sequence's file name needs a run of '#' where the frame number "
                                          "goes (smoke_####.nvdb)", path);
    if (!hash_run(path, &at, &width))
        return lu_fail(err, LU_ERR_SCENE, "\"%s\": more than one run of '#' in a sequence's file name", path);
    if (first < 0 || last < first || (long long)last - first + 1 > LU_SEQUENCE_MAX_FRAMES)
        return lu_fail(err, LU_ERR_RANGE, "\"frames\" [%d, %d]: expected 0 <= first <= last and at most %d frames",
                       first, last, LU_SEQUENCE_MAX_FRAMES);
    if (strlen(path) >= sizeof((lu_grid_anim *)0)->path)
        return lu_fail(err, LU_ERR_LIMIT, "\"%.64s...\": path too long", path);
    lu_grid_anim *a = lu_calloc(1, sizeof *a);
    if (!a) return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    a->sequence = true;
    snprintf(a->path, sizeof a->path, "%s", path);
    snprintf(a->grid_name, sizeof a->grid_name, "%s", grid_name ? grid_name : "");
    a->first = first;
    a->last = last;
    a->loop = loop;
    /* Every frame once: each must load and share the first frame's index
     * space; the union of their boxes, in the first frame's voxels. */
    lu_grid ref = {0};
    char ref_path[1100] = "";
    int lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    lu_result r = LU_OK;
    for (int f = first; f <= last && r == LU_OK; f++) {
        char fp[1100];
        lu_grid_anim_frame_path(a, f, fp, sizeof fp);
        lu_grid fg;
        r = load_file(fp, a->grid_name[0] ? a->grid_name : NULL, &fg, err);
        if (r != LU_OK) {
            if (r == LU_ERR_IO) {
                char inner[sizeof err->message];
                snprintf(inner, sizeof inner, "%s", err->message);
                r = lu_fail(err, r, "frame %d of the sequence: %s", f, inner);
            }
            break;
        }
        int k[3] = {0, 0, 0};
        if (f == first) {
            ref.index_to_world = fg.index_to_world;
            snprintf(ref_path, sizeof ref_path, "%s", fp);
        } else if (!lu_grid_shared_index_space(&ref, &fg, k)) {
            lu_vec3 h0 = voxel_size(&ref.index_to_world), h1 = voxel_size(&fg.index_to_world);
            r = lu_fail(err, LU_ERR_FORMAT,
                        "%s: its grid does not line up with %s's: voxel size (%g, %g, %g) against (%g, %g, %g), or "
                        "another orientation, or an offset by a fraction of a voxel (every frame of a sequence must "
                        "share the first frame's voxels)",
                        fp, ref_path, (double)h1.x, (double)h1.y, (double)h1.z, (double)h0.x, (double)h0.y,
                        (double)h0.z);
        }
        const int n[3] = {fg.nx, fg.ny, fg.nz};
        for (int i = 0; i < 3 && r == LU_OK; i++) {
            lo[i] = f == first || k[i] < lo[i] ? k[i] : lo[i];
            hi[i] = f == first || k[i] + n[i] > hi[i] ? k[i] + n[i] : hi[i];
        }
        lu_grid_destroy(&fg);
    }
    if (r == LU_OK) {
        uint64_t voxels = (uint64_t)(hi[0] - lo[0]) * (uint64_t)(hi[1] - lo[1]) * (uint64_t)(hi[2] - lo[2]);
        if (voxels > LU_MAX_GRID_VOXELS)
            r = lu_fail(err, LU_ERR_LIMIT, "%s: the box holding every frame is %d x %d x %d voxels, over the limit of "
                                           "%llu", path, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2],
                        (unsigned long long)LU_MAX_GRID_VOXELS);
    }
    if (r == LU_OK) {
        a->nx = hi[0] - lo[0];
        a->ny = hi[1] - lo[1];
        a->nz = hi[2] - lo[2];
        lu_affine shift = lu_affine_translate(lu_v3((float)lo[0], (float)lo[1], (float)lo[2]));
        a->map = lu_affine_mul(&ref.index_to_world, &shift);
        a->frame = wrap_frame(a, frame);
        r = load_frame(a, a->frame, g, err);
    }
    if (r != LU_OK) {
        lu_grid_anim_free(a);
        return r;
    }
    *out = a;
    return LU_OK;
}

static lu_result make_procedural(const lu_grid_anim *a, double time, lu_grid *g, lu_error *err) {
    lu_kvlist p = {0};
    lu_result r = LU_OK;
    for (int i = 0; i < a->params.count && r == LU_OK; i++) {
        const lu_kv *kv = &a->params.items[i];
        r = kv->count ? lu_kv_set_number(&p, kv->key, kv->v, kv->count, err) : lu_kv_set_string(&p, kv->key, kv->str, err);
    }
    if (r == LU_OK) r = lu_kv_set_number(&p, "time", &time, 1, err);
    if (r == LU_OK) r = lu_grid_procedural(a->name, &p, g, a->where, err);
    lu_kv_free(&p);
    return r;
}

lu_result lu_grid_anim_procedural(const char *name, const lu_kvlist *params, const char *where, double time,
                                  lu_grid *g, lu_grid_anim **out, lu_error *err) {
    *out = NULL;
    memset(g, 0, sizeof *g);
    if (lu_kv_find(params, "time"))
        return lu_fail(err, LU_ERR_SCENE, "%s: \"time\" is the scene's (its key \"time\", or --time)", where);
    lu_grid_anim *a = lu_calloc(1, sizeof *a);
    if (!a) return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    snprintf(a->name, sizeof a->name, "%s", name);
    snprintf(a->where, sizeof a->where, "%s", where);
    a->time = time;
    lu_result r = LU_OK;
    for (int i = 0; i < params->count && r == LU_OK; i++) {
        const lu_kv *kv = &params->items[i];
        r = kv->count ? lu_kv_set_number(&a->params, kv->key, kv->v, kv->count, err)
                      : lu_kv_set_string(&a->params, kv->key, kv->str, err);
    }
    if (r == LU_OK) r = make_procedural(a, time, g, err);
    if (r != LU_OK) {
        lu_grid_anim_free(a);
        return r;
    }
    *out = a;
    return LU_OK;
}

/* ---- the scene's clock ----------------------------------------------------- */

static double fps_of(const lu_scene *s) { return s->fps > 0.0 ? s->fps : LU_SCENE_DEFAULT_FPS; }

int lu_scene_frame_at(const lu_scene *s, double time) {
    double f = floor(time * fps_of(s) + 1e-6);
    return f < -2e9 ? -2000000000 : f > 2e9 ? 2000000000 : (int)f;
}

double lu_scene_frame_time(const lu_scene *s, int frame) { return frame / fps_of(s); }

bool lu_scene_animated(const lu_scene *s) {
    for (int m = 0; m < s->medium_count; m++)
        if (s->media[m].density_anim || s->media[m].emission_anim) return true;
    return false;
}

bool lu_scene_frame_range(const lu_scene *s, int *first, int *last) {
    bool any = false;
    for (int m = 0; m < s->medium_count; m++) {
        const lu_grid_anim *a[2] = {s->media[m].density_anim, s->media[m].emission_anim};
        for (int i = 0; i < 2; i++) {
            int f0, f1;
            if (!lu_grid_anim_range(a[i], &f0, &f1)) continue;
            if (!any || f0 < *first) *first = f0;
            if (!any || f1 > *last) *last = f1;
            any = true;
        }
    }
    return any;
}

/* The grid anim shows at `time`, or *fresh false when the grid holds it already. */
static lu_result anim_at(const lu_scene *s, const lu_grid_anim *a, double time, lu_grid *g, bool *fresh,
                         lu_error *err) {
    *fresh = false;
    if (a->sequence) {
        int f = wrap_frame(a, lu_scene_frame_at(s, time));
        if (f == a->frame) return LU_OK;
        *fresh = true;
        return load_frame(a, f, g, err);
    }
    if (time == a->time) return LU_OK;
    *fresh = true;
    return make_procedural(a, time, g, err);
}

static void anim_shown(lu_grid_anim *a, const lu_scene *s, double time) {
    if (a->sequence) a->frame = wrap_frame(a, lu_scene_frame_at(s, time));
    else a->time = time;
}

lu_result lu_scene_set_time(lu_scene *s, double time, lu_error *err) {
    if (!s) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_scene_set_time: no scene");
    if (!isfinite(time)) return lu_fail(err, LU_ERR_NONFINITE, "%s: time is not a finite number", s->path);
    int n = s->medium_count;
    lu_grid *dens = n ? lu_calloc((size_t)n, sizeof *dens) : NULL, *emis = n ? lu_calloc((size_t)n, sizeof *emis) : NULL;
    bool *dnew = n ? lu_calloc((size_t)n, sizeof *dnew) : NULL, *enew = n ? lu_calloc((size_t)n, sizeof *enew) : NULL;
    lu_result r = n && (!dens || !emis || !dnew || !enew) ? lu_fail(err, LU_ERR_NOMEM, "out of memory") : LU_OK;
    /* Every new grid first, so a failure changes nothing. */
    for (int m = 0; m < n && r == LU_OK; m++) {
        const lu_medium *md = &s->media[m];
        if (md->density_anim) r = anim_at(s, md->density_anim, time, &dens[m], &dnew[m], err);
        if (r == LU_OK && dnew[m] && (dens[m].nx != md->grid.nx || dens[m].ny != md->grid.ny || dens[m].nz != md->grid.nz))
            r = lu_fail(err, LU_ERR_INVALID_ARG, "%s: medium %d: the grid for time %g is %dx%dx%d, the medium's %dx%dx%d",
                        s->path, m, time, dens[m].nx, dens[m].ny, dens[m].nz, md->grid.nx, md->grid.ny, md->grid.nz);
        if (r == LU_OK && md->emission_anim) {
            lu_grid e = {0};
            r = anim_at(s, md->emission_anim, time, &e, &enew[m], err);
            int k[3];
            if (r == LU_OK && enew[m]) {
                /* Into the density grid's voxels, as the loader embedded it. */
                if (!lu_grid_shared_index_space(&md->grid, &e, k))
                    r = lu_fail(err, LU_ERR_SCENE, "%s: medium %d: the emission grid for time %g left the density's "
                                                   "index space", s->path, m, time);
                else
                    r = lu_grid_embed(&e, k, md->grid.nx, md->grid.ny, md->grid.nz, &md->grid.index_to_world, &emis[m],
                                      err);
            }
            lu_grid_destroy(&e);
        }
    }
    for (int m = 0; m < n && r == LU_OK; m++) {
        lu_medium *md = &s->media[m];
        if (dnew[m]) {
            r = lu_grid_set_values(&md->grid, dens[m].data, (size_t)md->grid.nx * md->grid.ny * md->grid.nz, err);
            if (r == LU_OK) anim_shown(md->density_anim, s, time);
        }
        if (r == LU_OK && enew[m]) {
            r = lu_grid_set_values(&md->emission_grid, emis[m].data,
                                   (size_t)md->emission_grid.nx * md->emission_grid.ny * md->emission_grid.nz, err);
            if (r == LU_OK) anim_shown(md->emission_anim, s, time);
        }
    }
    for (int m = 0; m < n; m++) {
        if (dens) lu_grid_destroy(&dens[m]);
        if (emis) lu_grid_destroy(&emis[m]);
    }
    lu_free(dens);
    lu_free(emis);
    lu_free(dnew);
    lu_free(enew);
    if (r == LU_OK) s->time = time;
    return r;
}
