/* The bssrdf method's GPU pass (see bssrdf_gpu.h). */
#include "methods/bssrdf/bssrdf_gpu.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "methods/common/gpu_method.h"

enum { B_DATA, B_SHADOW, B_SPLATS, B_GBUF, B_TSTART, B_TLIST, B_OUT, B_SCATTER, B_COUNT };

/* Splats one dispatch sums per tile: under llvmpipe's 65535 loop iterations
 * per invocation (bssrdf.comp) with room for the shading pass's loops. */
#define LU_BSSRDF_GPU_CHUNK 32768

struct lu_bssrdf_gpu {
    lu_gpu_method m;          /* no scene records: slots B_* from binding 0 */
    size_t size[B_COUNT];
    float *staging;           /* the concatenated fetch arrays */
    size_t staging_cap, staging_floats;
    size_t off[6];
    bool have[B_COUNT];       /* slot holds the previous frame's upload */
};

lu_result lu_bssrdf_gpu_create(lu_bssrdf_gpu **out, lu_error *err) {
    static const lu_gpu_method_program programs[] = {{"methods/bssrdf/bssrdf.comp", NULL}, {NULL, NULL}};
    lu_gpu_method *m;
    lu_result r = lu_gpu_method_create(sizeof(lu_bssrdf_gpu), NULL, programs, "bssrdf", &m, err);
    *out = (lu_bssrdf_gpu *)m;   /* NULL on failure */
    return r;
}

void lu_bssrdf_gpu_destroy(lu_bssrdf_gpu *g) {
    if (!g) return;
    lu_free(g->staging);
    lu_gpu_method_destroy(&g->m);
}

static lu_result put(lu_bssrdf_gpu *g, int i, const void *data, size_t bytes, bool keep, lu_error *err) {
    if (bytes == 0) bytes = 16, data = NULL;
    keep = keep && data && g->have[i] && g->m.buf[i] && g->size[i] >= bytes;
    g->have[i] = false;
    if (keep) data = NULL;
    if (!g->m.buf[i] || g->size[i] < bytes) {
        lu_gpu_buffer_destroy(g->m.buf[i]);
        g->m.buf[i] = NULL;
        size_t cap = g->size[i] ? g->size[i] : 4096;
        while (cap < bytes) cap *= 2;
        lu_result r = lu_gpu_buffer_create(g->m.ctx, cap, NULL, &g->m.buf[i], err);
        if (r != LU_OK) return r;
        g->size[i] = cap;
    }
    if (data) {
        lu_result r = lu_gpu_buffer_upload(g->m.buf[i], 0, data, bytes, err);
        if (r != LU_OK) return r;
    }
    g->have[i] = keep || data;
    return lu_gpu_buffer_bind(g->m.buf[i], i, err);
}

lu_result lu_bssrdf_gpu_render(lu_bssrdf_gpu *g, const lu_bssrdf_gpu_frame *f, lu_image *out, lu_error *err) {
    size_t total = 0, off[6];
    for (int b = 0; b < 6; b++) {
        off[b] = total;
        total += f->count[b];
    }
    if (total > (size_t)INT32_MAX) return lu_fail(err, LU_ERR_LIMIT, "bssrdf: GPU data of %zu floats", total);
    bool keep_data = !(f->changed & LU_BSSRDF_GPU_DATA) && total == g->staging_floats &&
                     memcmp(off, g->off, sizeof off) == 0;
    if (!keep_data) {
        if (total > g->staging_cap) {
            float *s = lu_realloc(g->staging, total * sizeof *s);
            if (!s) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
            g->staging = s;
            g->staging_cap = total;
        }
        for (int b = 0; b < 6; b++) memcpy(g->staging + off[b], f->buf[b], f->count[b] * sizeof(float));
        g->staging_floats = total;
        memcpy(g->off, off, sizeof off);
    }
    size_t pixels = (size_t)f->width * f->height;
    int ntiles = f->tiles_x * f->tiles_y;
    unsigned c = f->changed;
    lu_result r = put(g, B_DATA, g->staging, total * sizeof(float), keep_data, err);
    if (r == LU_OK)
        r = put(g, B_SHADOW, f->shadow, f->shadow_count * sizeof(float), !(c & LU_BSSRDF_GPU_SHADOW), err);
    if (r == LU_OK)
        r = put(g, B_SPLATS, f->splats, (size_t)f->splat_count * f->splat_bytes, !(c & LU_BSSRDF_GPU_SPLATS), err);
    if (r == LU_OK) r = put(g, B_GBUF, f->gbuf, pixels * 32, !(c & LU_BSSRDF_GPU_GBUF), err);
    if (r == LU_OK)
        r = put(g, B_TSTART, f->tile_start, ((size_t)ntiles + 1) * sizeof(int), !(c & LU_BSSRDF_GPU_TILES), err);
    if (r == LU_OK) r = put(g, B_TLIST, f->tile_list, f->list_count * sizeof(int), !(c & LU_BSSRDF_GPU_TILES), err);
    if (r == LU_OK) r = put(g, B_OUT, NULL, pixels * 3 * sizeof(float), false, err);
    if (r != LU_OK) {
        memset(g->have, 0, sizeof g->have);
        return r;
    }
    for (int b = 0; b < 6; b++) {
        char name[32];
        snprintf(name, sizeof name, "u_buf_off[%d]", b);
        lu_gpu_uniform_int(g->m.prog[0], name, (int)off[b]);
    }
    lu_gpu_uniform_int(g->m.prog[0], "u_map_res", f->map_res);
    lu_gpu_uniform_int(g->m.prog[0], "u_width", f->width);
    lu_gpu_uniform_int(g->m.prog[0], "u_height", f->height);
    lu_gpu_uniform_int(g->m.prog[0], "u_tiles_x", f->tiles_x);
    lu_gpu_uniform_vec3(g->m.prog[0], "u_cam_right", f->cam_right.x, f->cam_right.y, f->cam_right.z);
    lu_gpu_uniform_vec3(g->m.prog[0], "u_cam_up", f->cam_up.x, f->cam_up.y, f->cam_up.z);
    lu_gpu_uniform_vec3(g->m.prog[0], "u_cam_forward", f->cam_forward.x, f->cam_forward.y, f->cam_forward.z);
    if (r == LU_OK) r = put(g, B_SCATTER, NULL, pixels * 4 * sizeof(float), false, err);
    int longest = 0;
    for (int t = 0; t < ntiles; t++)
        if (f->tile_start[t + 1] - f->tile_start[t] > longest) longest = f->tile_start[t + 1] - f->tile_start[t];
    lu_gpu_uniform_int(g->m.prog[0], "u_chunk_len", LU_BSSRDF_GPU_CHUNK);
    for (int k0 = 0; r == LU_OK; k0 += LU_BSSRDF_GPU_CHUNK) {
        int last = k0 + LU_BSSRDF_GPU_CHUNK >= longest;
        lu_gpu_uniform_int(g->m.prog[0], "u_chunk_begin", k0);
        lu_gpu_uniform_int(g->m.prog[0], "u_finish", last);
        r = lu_gpu_dispatch(g->m.prog[0], (unsigned)f->tiles_x, (unsigned)f->tiles_y, 1, err);
        if (last) break;
    }
    if (r == LU_OK) r = lu_gpu_output(g->m.buf[B_OUT], out->width, out->height, out->rgb, err);
    if (r != LU_OK) memset(g->have, 0, sizeof g->have);
    return r;
}
