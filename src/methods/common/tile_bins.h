/* Internal: binning of screen rectangles into square pixel tiles (a
 * counting sort), for methods that gather splats per tile (bssrdf's splats,
 * ddod's Gaussian balls). Per tile the items come in index order, so a
 * pixel's sum has one order on every backend.
 *
 *   lu_tile_bins b = {0};
 *   lu_tile_bins_build(&b, width, height, 16, count, rects, &err);
 *   for (int k = b.start[t]; k < b.start[t + 1]; k++) use(b.list[k]);
 *   lu_tile_bins_free(&b);
 * The arrays are reused (grown, never shrunk) across builds. */
#ifndef LU_METHODS_TILE_BINS_H
#define LU_METHODS_TILE_BINS_H

#include <lucent/lucent.h>

#include "methods/common/lu_screen_rect.h"

typedef struct lu_tile_bins {
    int tile, tiles_x, tiles_y;
    int *start;              /* tiles + 1 offsets into list */
    int *list;               /* item indices */
    int *fill;
    size_t start_cap, list_cap;
    long long entries;       /* item-tile pairs of the last build */
} lu_tile_bins;

/* rects[i]: pixels item i may touch (empty rects are skipped). Fails with
 * LU_ERR_LIMIT past INT32_MAX pairs, LU_ERR_NOMEM when memory runs out. */
lu_result lu_tile_bins_build(lu_tile_bins *b, int width, int height, int tile, int count, const lu_k_rect *rects,
                             lu_error *err);
void lu_tile_bins_free(lu_tile_bins *b);

#endif
