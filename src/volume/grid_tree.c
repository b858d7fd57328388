/* Sparse grids: walking a validated NanoVDB float tree node by node (see
 * grid_internal.h). The loader (grid_nvdb_read.c) checks every node address
 * before a grid is handed out, so this walk trusts the tree. */
#include "volume/grid_internal.h"

#include <math.h>
#include <string.h>

bool lu_nvdb_key_origin(uint64_t key, int64_t o[3]) {
    /* Root tile keys pack the upper node origin >> 12 into 21 bits per axis. */
    uint64_t part[3] = {(key >> 42) & 0x1FFFFFu, (key >> 21) & 0x1FFFFFu, key & 0x1FFFFFu};
    if (key >> 63) return false;
    for (int i = 0; i < 3; i++) {
        if (part[i] > 0xFFFFFu) return false;
        int64_t v = (int64_t)(part[i] << 12);
        o[i] = v >= ((int64_t)1 << 31) ? v - ((int64_t)1 << 32) : v;
    }
    return true;
}

static void visit_lower(const lu_k_tree *t, pnanovdb_lower_handle_t lower, int64_t ox, int64_t oy, int64_t oz,
                        lu_tree_visit_fn fn, void *ctx) {
    const pnanovdb_grid_type_t gt = PNANOVDB_GRID_TYPE_FLOAT;
    for (uint32_t n = 0; n < PNANOVDB_LOWER_TABLE_COUNT; n++) {
        int64_t o[3] = {ox + (int64_t)((n >> 8) & 15u) * 8, oy + (int64_t)((n >> 4) & 15u) * 8,
                        oz + (int64_t)(n & 15u) * 8};
        if (pnanovdb_lower_get_child_mask(t->buf, lower, n)) {
            pnanovdb_leaf_handle_t leaf = pnanovdb_lower_get_child(gt, t->buf, lower, n);
            pnanovdb_address_t a = pnanovdb_leaf_get_table_address(gt, t->buf, leaf, 0);
            fn(ctx, o, 8, (const float *)((const unsigned char *)t->buf.data + a.byte_offset), 0.0f);
        } else {
            float v = pnanovdb_read_float(t->buf, pnanovdb_lower_get_table_address(gt, t->buf, lower, n));
            if (v != 0.0f) fn(ctx, o, 8, NULL, v);
        }
    }
}

static void visit_upper(const lu_k_tree *t, pnanovdb_upper_handle_t upper, int64_t ox, int64_t oy, int64_t oz,
                        lu_tree_visit_fn fn, void *ctx) {
    const pnanovdb_grid_type_t gt = PNANOVDB_GRID_TYPE_FLOAT;
    for (uint32_t n = 0; n < PNANOVDB_UPPER_TABLE_COUNT; n++) {
        int64_t x = ox + (int64_t)((n >> 10) & 31u) * 128, y = oy + (int64_t)((n >> 5) & 31u) * 128,
                z = oz + (int64_t)(n & 31u) * 128;
        if (pnanovdb_upper_get_child_mask(t->buf, upper, n)) {
            visit_lower(t, pnanovdb_upper_get_child(gt, t->buf, upper, n), x, y, z, fn, ctx);
        } else {
            float v = pnanovdb_read_float(t->buf, pnanovdb_upper_get_table_address(gt, t->buf, upper, n));
            int64_t o[3] = {x, y, z};
            if (v != 0.0f) fn(ctx, o, 128, NULL, v);
        }
    }
}

void lu_grid_tree_visit(const lu_grid *g, lu_tree_visit_fn fn, void *ctx) {
    if (!g->tree) return;
    const pnanovdb_grid_type_t gt = PNANOVDB_GRID_TYPE_FLOAT;
    lu_k_tree t = lu_grid_tree_view(g);
    uint32_t tiles = pnanovdb_root_get_tile_count(t.buf, t.root);
    for (uint32_t i = 0; i < tiles; i++) {
        pnanovdb_root_tile_handle_t tile = pnanovdb_root_get_tile(gt, t.root, i);
        int64_t o[3];
        if (!lu_nvdb_key_origin(pnanovdb_root_tile_get_key(t.buf, tile), o)) continue;
        if (pnanovdb_root_tile_get_child(t.buf, tile) != 0) {
            visit_upper(&t, pnanovdb_root_get_child(gt, t.buf, t.root, tile), o[0], o[1], o[2], fn, ctx);
        } else {
            float v = pnanovdb_read_float(
                t.buf, pnanovdb_address_offset(tile.address, PNANOVDB_GRID_TYPE_GET(gt, root_tile_off_value)));
            if (v != 0.0f) fn(ctx, o, 4096, NULL, v);
        }
    }
}

bool lu_grid_tree_clip(const lu_grid *g, const int64_t origin[3], int dim, int lo[3], int hi[3]) {
    const int n[3] = {g->nx, g->ny, g->nz};
    for (int a = 0; a < 3; a++) {
        int64_t l = origin[a] - g->tree_lo[a], h = l + dim;
        if (l < 0) l = 0;
        if (h > n[a]) h = n[a];
        if (l >= h) return false;
        lo[a] = (int)l;
        hi[a] = (int)h;
    }
    return true;
}
