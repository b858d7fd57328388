/* NanoVDB writing beyond lu_grid_save_nvdb (library-internal): a choice of
 * codec, and sparse grids of other value types, so tests and tools can make
 * the files a reader must accept or reject. Implemented with NanoVDB's own
 * C++ GridBuilder and io::writeGrids in grid_nvdb_write.cpp. */
#ifndef LU_VOLUME_NVDB_WRITE_H
#define LU_VOLUME_NVDB_WRITE_H

#include <lucent/grid.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum lu_nvdb_codec { LU_NVDB_CODEC_NONE = 0, LU_NVDB_CODEC_ZIP = 1 } lu_nvdb_codec;
typedef enum lu_nvdb_type { LU_NVDB_FLOAT = 0, LU_NVDB_DOUBLE, LU_NVDB_VEC3F } lu_nvdb_type;

/* lu_grid_save_nvdb with a codec. */
lu_result lu_nvdb_save_dense(const lu_grid *g, const char *path, lu_nvdb_codec codec, lu_error *err);

typedef struct lu_nvdb_sparse {
    const char *name;
    lu_nvdb_type type;
    size_t count;              /* active voxels */
    const int32_t (*ijk)[3];
    const float *values;       /* Vec3f grids store (v, v, v) */
    float background;
    double voxel_size;         /* map: uniform scale, no translation */
} lu_nvdb_sparse;

/* Writes all grids into one segment of one file (atomically). */
lu_result lu_nvdb_save_sparse(const char *path, const lu_nvdb_sparse *grids, int count, lu_nvdb_codec codec,
                              lu_error *err);

#ifdef __cplusplus
}
#endif
#endif
