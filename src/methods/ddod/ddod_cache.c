/* ddod's on-disk cache of the precomputation (ddod.h): the key over every
 * input the samples depend on, a checked file format, and prepare_set, which
 * loads a matching file or computes and writes one. */
#include "methods/ddod/ddod.h"
#include "core/fnv.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define DDOD_CACHE_VERSION 5

static void fnv_mesh(lu_fnv *f, const lu_mesh *m) {
    lu_fnv_bytes(f, &m->vertex_count, sizeof m->vertex_count);
    lu_fnv_bytes(f, &m->triangle_count, sizeof m->triangle_count);
    lu_fnv_bytes(f, m->positions, (size_t)m->vertex_count * sizeof *m->positions);
    lu_fnv_bytes(f, m->indices, (size_t)m->triangle_count * 3 * sizeof *m->indices);
}

uint64_t lu_ddod_key(const lu_scene *scene, const lu_ddod_params *p) {
    lu_fnv f = LU_FNV_INIT;
    int v = DDOD_CACHE_VERSION;
    lu_fnv_bytes(&f, &v, sizeof v);
    lu_fnv_bytes(&f, p, sizeof *p);
    for (int i = 0; i < scene->medium_count; i++) {
        const lu_medium *m = &scene->media[i];
        lu_fnv_bytes(&f, &m->kind, sizeof m->kind);
        lu_fnv_bytes(&f, &m->constant, sizeof m->constant);
        lu_fnv_bytes(&f, &m->sigma_a, sizeof m->sigma_a);
        lu_fnv_bytes(&f, &m->sigma_s, sizeof m->sigma_s);
        lu_fnv_bytes(&f, &m->eta, sizeof m->eta);
        lu_fnv_bytes(&f, &m->world_to_index, sizeof m->world_to_index);
        if (m->kind == LU_DENSITY_GRID) {
            lu_fnv_bytes(&f, &m->grid.nx, 3 * sizeof(int));
            if (m->grid.data) lu_fnv_bytes(&f, m->grid.data, (size_t)m->grid.nx * m->grid.ny * m->grid.nz * sizeof(float));
            else lu_fnv_bytes(&f, m->grid.tree, (size_t)m->grid.tree_bytes), lu_fnv_bytes(&f, m->grid.tree_lo, sizeof m->grid.tree_lo);
        }
        if (m->has_boundary) fnv_mesh(&f, &m->boundary);
    }
    for (int i = 0; i < scene->object_count; i++)
        if (scene->objects[i].material.type == LU_MATERIAL_DIFFUSE) fnv_mesh(&f, &scene->objects[i].mesh);
    return f.h;
}

static const char k_magic[8] = {'L', 'U', 'D', 'D', 'O', 'D', 'C', '\n'};

typedef struct cache_header {
    char magic[8];
    uint32_t version, sample_floats;
    uint64_t key;
    int32_t count, bands, channels, stride;
    double timing[6];
} cache_header;

static uint64_t payload_checksum(const lu_ddod_set *s) {
    lu_fnv f = LU_FNV_INIT;
    lu_fnv_bytes(&f, s->samples, (size_t)s->count * LU_K_DDOD_SAMPLE_FLOATS * sizeof(float));
    lu_fnv_bytes(&f, s->sh, (size_t)s->count * s->stride * sizeof(float));
    return f.h;
}

lu_result lu_ddod_cache_save(const char *path, uint64_t key, const lu_ddod_set *s, lu_error *err) {
    cache_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, k_magic, sizeof k_magic);
    h.version = DDOD_CACHE_VERSION;
    h.sample_floats = LU_K_DDOD_SAMPLE_FLOATS;
    h.key = key;
    h.count = s->count;
    h.bands = s->bands;
    h.channels = s->channels;
    h.stride = s->stride;
    h.timing[0] = s->timing.optical_depth_s;
    h.timing[1] = s->timing.divergence_s;
    h.timing[2] = s->timing.sampling_s;
    h.timing[3] = s->timing.sh_s;
    h.timing[4] = s->timing.total_s;
    h.timing[5] = s->timing.cpu_s;
    uint64_t sum = payload_checksum(s);
    lu_atomic_file af;
    lu_result r = lu_atomic_open(&af, path, err);
    if (r != LU_OK) return r;
    FILE *fp = af.fp;
    bool ok = fwrite(&h, sizeof h, 1, fp) == 1 &&
              fwrite(s->samples, sizeof(float), (size_t)s->count * LU_K_DDOD_SAMPLE_FLOATS, fp) ==
                  (size_t)s->count * LU_K_DDOD_SAMPLE_FLOATS &&
              fwrite(s->sh, sizeof(float), (size_t)s->count * s->stride, fp) == (size_t)s->count * s->stride &&
              fwrite(&sum, sizeof sum, 1, fp) == 1;
    if (!ok) {
        lu_atomic_abort(&af);
        return lu_fail(err, LU_ERR_IO, "%s: write failed: %s", path, strerror(errno));
    }
    return lu_atomic_commit(&af, err);
}

lu_result lu_ddod_cache_load(const char *path, uint64_t key, lu_ddod_set *s, lu_error *err) {
    memset(s, 0, sizeof *s);
    FILE *fp;
    uint64_t size;
    lu_result r = lu_open_regular(path, (void **)&fp, &size, err);
    if (r != LU_OK) return r;
    cache_header h;
    const char *why = NULL;
    char buf[160];
    if (size < sizeof h || fread(&h, sizeof h, 1, fp) != 1) {
        why = "truncated header";
    } else if (memcmp(h.magic, k_magic, sizeof k_magic) != 0) {
        why = "not a ddod cache file (bad magic)";
    } else if (h.version != DDOD_CACHE_VERSION) {
        snprintf(buf, sizeof buf, "cache version %u, this build reads %d", h.version, DDOD_CACHE_VERSION);
        why = buf;
    } else if (h.key != key) {
        why = "made for other inputs (key mismatch)";
    } else if (h.sample_floats != LU_K_DDOD_SAMPLE_FLOATS || h.count <= 0 || h.count > 100000000 || h.bands < 1 ||
               h.bands > LU_SH_MAX_BANDS || (h.channels != 1 && h.channels != 3) ||
               h.stride != 2 * h.channels * h.bands * h.bands) {
        why = "inconsistent header fields";
    } else {
        uint64_t want = sizeof h + ((uint64_t)h.count * (LU_K_DDOD_SAMPLE_FLOATS + (uint64_t)h.stride)) * 4u + 8u;
        if (size != want) {
            snprintf(buf, sizeof buf, "%s: %llu bytes, expected %llu", size < want ? "truncated" : "trailing bytes",
                     (unsigned long long)size, (unsigned long long)want);
            why = buf;
        }
    }
    if (!why) {
        s->count = h.count;
        s->bands = h.bands;
        s->channels = h.channels;
        s->stride = h.stride;
        s->samples = lu_malloc((size_t)h.count * LU_K_DDOD_SAMPLE_FLOATS * sizeof(float));
        s->sh = lu_malloc((size_t)h.count * h.stride * sizeof(float));
        uint64_t sum = 0;
        if (!s->samples || !s->sh) {
            fclose(fp);
            lu_ddod_set_free(s);
            return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
        }
        if (fread(s->samples, sizeof(float), (size_t)h.count * LU_K_DDOD_SAMPLE_FLOATS, fp) !=
                (size_t)h.count * LU_K_DDOD_SAMPLE_FLOATS ||
            fread(s->sh, sizeof(float), (size_t)h.count * h.stride, fp) != (size_t)h.count * h.stride ||
            fread(&sum, sizeof sum, 1, fp) != 1)
            why = "read failed";
        else if (sum != payload_checksum(s))
            why = "checksum mismatch (the file is corrupt)";
    }
    fclose(fp);
    if (why) {
        lu_ddod_set_free(s);
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s; delete the file to recompute", path, why);
    }
    s->timing.optical_depth_s = h.timing[0];
    s->timing.divergence_s = h.timing[1];
    s->timing.sampling_s = h.timing[2];
    s->timing.sh_s = h.timing[3];
    s->timing.total_s = h.timing[4];
    s->timing.cpu_s = h.timing[5];
    s->timing.from_cache = true;
    return LU_OK;
}

lu_result lu_ddod_prepare_set(const lu_scene *scene, const lu_ddod_params *p, bool use_cache, lu_ddod_set *out,
                              lu_error *err) {
    /* No cache folder (the host named none): compute every time. */
    if (!use_cache || !lu_cache_enabled()) return lu_ddod_compute(scene, p, out, err);
    uint64_t key = lu_ddod_key(scene, p);
    char name[64], path[1100];
    snprintf(name, sizeof name, "ddod-%016llx.bin", (unsigned long long)key);
    lu_result r = lu_cache_path(name, false, path, sizeof path, err);
    if (r != LU_OK) return r;
    struct stat stt;
    if (stat(path, &stt) == 0) return lu_ddod_cache_load(path, key, out, err);
    r = lu_ddod_compute(scene, p, out, err);
    if (r != LU_OK) return r;
    r = lu_cache_path(name, true, path, sizeof path, err);
    if (r == LU_OK) r = lu_ddod_cache_save(path, key, out, err);
    if (r != LU_OK) lu_ddod_set_free(out);
    return r;
}
