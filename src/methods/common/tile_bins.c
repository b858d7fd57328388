/* Counting sort of (item, tile) pairs (see tile_bins.h). */
#include "methods/common/tile_bins.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static lu_result grow(int **p, size_t *cap, size_t need, lu_error *err) {
    if (need <= *cap) return LU_OK;
    size_t n = *cap ? *cap : 1024;
    while (n < need) n *= 2;
    int *q = lu_realloc(*p, n * sizeof *q);
    if (!q) return lu_fail(err, LU_ERR_NOMEM, "tile binning: out of memory (%zu entries)", n);
    *p = q;
    *cap = n;
    return LU_OK;
}

lu_result lu_tile_bins_build(lu_tile_bins *b, int width, int height, int tile, int count, const lu_k_rect *rects,
                             lu_error *err) {
    b->tile = tile;
    b->tiles_x = (width + tile - 1) / tile;
    b->tiles_y = (height + tile - 1) / tile;
    int ntiles = b->tiles_x * b->tiles_y;
    size_t fill_cap = b->start_cap;
    lu_result r = grow(&b->start, &b->start_cap, (size_t)ntiles + 1, err);
    if (r == LU_OK) r = grow(&b->fill, &fill_cap, (size_t)ntiles + 1, err);
    if (r != LU_OK) return r;
    memset(b->start, 0, ((size_t)ntiles + 1) * sizeof(int));
    for (int i = 0; i < count; i++) {
        lu_k_rect rc = rects[i];
        if (rc.x1 <= rc.x0 || rc.y1 <= rc.y0) continue;
        for (int ty = rc.y0 / tile; ty <= (rc.y1 - 1) / tile; ty++)
            for (int tx = rc.x0 / tile; tx <= (rc.x1 - 1) / tile; tx++) b->start[ty * b->tiles_x + tx + 1]++;
    }
    long long total = 0;
    for (int t = 0; t < ntiles; t++) {
        total += b->start[t + 1];
        if (total > INT32_MAX) return lu_fail(err, LU_ERR_LIMIT, "tile binning: more than %d item-tile pairs", INT32_MAX);
        b->start[t + 1] = (int)total;
    }
    r = grow(&b->list, &b->list_cap, total ? (size_t)total : 1u, err);
    if (r != LU_OK) return r;
    memcpy(b->fill, b->start, (size_t)ntiles * sizeof(int));
    for (int i = 0; i < count; i++) {
        lu_k_rect rc = rects[i];
        if (rc.x1 <= rc.x0 || rc.y1 <= rc.y0) continue;
        for (int ty = rc.y0 / tile; ty <= (rc.y1 - 1) / tile; ty++)
            for (int tx = rc.x0 / tile; tx <= (rc.x1 - 1) / tile; tx++) b->list[b->fill[ty * b->tiles_x + tx]++] = i;
    }
    b->entries = total;
    return LU_OK;
}

void lu_tile_bins_free(lu_tile_bins *b) {
    lu_free(b->start);
    lu_free(b->list);
    lu_free(b->fill);
    memset(b, 0, sizeof *b);
}
