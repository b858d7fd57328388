// NanoVDB writer: NanoVDB's own GridBuilder builds the sparse tree (it turns
// constant all-active leaves and lower nodes into tiles) and io::writeGrids
// lays out the file container. writeGrids seeks past the end of its stream
// (it writes the headers last), which a string stream cannot do, so it writes
// a temporary file that is renamed into place only when complete.
#define NANOVDB_USE_ZIP
#include <nanovdb/util/GridBuilder.h>
#include <nanovdb/util/IO.h>

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <new>
#include <string>
#include <vector>

#include "nvdb_write.h"

namespace {

nanovdb::io::Codec to_codec(lu_nvdb_codec c) {
    return c == LU_NVDB_CODEC_ZIP ? nanovdb::io::Codec::ZIP : nanovdb::io::Codec::NONE;
}

lu_result write_atomic(std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> &handles, lu_nvdb_codec codec,
                       const char *path, lu_error *err) {
    const std::string temp = std::string(path) + ".tmp." + std::to_string(static_cast<long>(getpid()));
    {
        std::ofstream os(temp, std::ios::out | std::ios::binary | std::ios::trunc);
        if (!os.is_open())
            return lu_fail(err, LU_ERR_IO, "%s: cannot open for writing: %s", path, std::strerror(errno));
        try {
            nanovdb::io::writeGrids<nanovdb::HostBuffer, std::vector>(os, handles, to_codec(codec));
            os.flush();
        } catch (...) {
            os.close();
            std::remove(temp.c_str());
            throw;
        }
        os.close();
        if (!os) {
            std::remove(temp.c_str());
            return lu_fail(err, LU_ERR_IO, "%s: write failed", path);
        }
    }
    if (std::rename(temp.c_str(), path) != 0) {
        int e = errno;
        std::remove(temp.c_str());
        return lu_fail(err, LU_ERR_IO, "%s: cannot rename temporary file into place: %s", path, std::strerror(e));
    }
    return LU_OK;
}

// Map::set takes OpenVDB's row-vector matrices (it stores the transpose), so
// the column-vector index_to_world goes in transposed.
bool make_map(const lu_affine &a, nanovdb::Map &map) {
    double m[3][3], t[3];
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) m[i][j] = a.m[i][j];
        t[i] = a.m[i][3];
    }
    double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return false;
    double inv[3][3] = {
        {c00 / det, (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det, (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det},
        {c01 / det, (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det, (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det},
        {c02 / det, (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det, (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det},
    };
    double mt[3][3], it[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            mt[i][j] = m[j][i];
            it[i][j] = inv[j][i];
        }
    map.set(mt, it, t, 1.0);
    return true;
}

template <typename Fn>
lu_result guarded(const char *path, lu_error *err, Fn &&fn) {
    try {
        return fn();
    } catch (const std::bad_alloc &) {
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory building the NanoVDB grid", path);
    } catch (const std::exception &e) {
        return lu_fail(err, LU_ERR_IO, "%s: NanoVDB writer: %s", path, e.what());
    }
}

template <typename ValueT>
nanovdb::GridHandle<nanovdb::HostBuffer> sparse_handle(const lu_nvdb_sparse &s, const ValueT &bg,
                                                       ValueT (*conv)(float), nanovdb::GridClass cls) {
    nanovdb::GridBuilder<ValueT> builder(bg, cls);
    auto acc = builder.getAccessor();
    for (size_t i = 0; i < s.count; i++)
        acc.setValue(nanovdb::Coord(s.ijk[i][0], s.ijk[i][1], s.ijk[i][2]), conv(s.values[i]));
    return builder.template getHandle<>(s.voxel_size, nanovdb::Vec3d(0.0), s.name ? s.name : "");
}

float to_float(float v) { return v; }
double to_double(float v) { return v; }
nanovdb::Vec3f to_vec3f(float v) { return nanovdb::Vec3f(v); }

} // namespace

extern "C" lu_result lu_nvdb_save_dense(const lu_grid *g, const char *path, lu_nvdb_codec codec, lu_error *err) {
    if (!g || !g->data || g->nx < 1 || g->ny < 1 || g->nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: cannot save an empty grid", path);
    size_t n = static_cast<size_t>(g->nx) * static_cast<size_t>(g->ny) * static_cast<size_t>(g->nz);
    for (size_t i = 0; i < n; i++) {
        float v = g->data[i];
        if (!std::isfinite(v))
            return lu_fail(err, LU_ERR_NONFINITE, "%s: voxel %zu is not a finite number", path, i);
        if (v < 0.0f) return lu_fail(err, LU_ERR_RANGE, "%s: voxel %zu has negative density %g", path, i, (double)v);
    }
    nanovdb::Map map;
    if (!make_map(g->index_to_world, map))
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: the grid's index-to-world map is singular or not finite", path);
    return guarded(path, err, [&]() -> lu_result {
        // Background 0: the builder leaves voxels equal to it inactive, which
        // is the "zero outside" convention of lu_grid.
        nanovdb::GridBuilder<float> builder(0.0f, nanovdb::GridClass::FogVolume);
        const int nx = g->nx, ny = g->ny;
        const float *data = g->data;
        builder(
            [=](const nanovdb::Coord &ijk) -> float {
                return data[(static_cast<size_t>(ijk[2]) * ny + ijk[1]) * nx + ijk[0]];
            },
            nanovdb::CoordBBox(nanovdb::Coord(0), nanovdb::Coord(g->nx - 1, g->ny - 1, g->nz - 1)));
        std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
        handles.push_back(builder.getHandle<>(map, g->name[0] ? g->name : "density"));
        return write_atomic(handles, codec, path, err);
    });
}

extern "C" lu_result lu_grid_save_nvdb(const lu_grid *g, const char *path, lu_error *err) {
    if (g && lu_grid_is_sparse(g)) {
        // The builder reads voxels from an array: a sparse grid is expanded
        // first (the dense limit applies).
        lu_grid d;
        lu_result r = lu_grid_densify(g, &d, err);
        if (r == LU_OK) r = lu_nvdb_save_dense(&d, path, LU_NVDB_CODEC_NONE, err);
        lu_grid_destroy(&d);
        return r;
    }
    return lu_nvdb_save_dense(g, path, LU_NVDB_CODEC_NONE, err);
}

extern "C" lu_result lu_nvdb_save_sparse(const char *path, const lu_nvdb_sparse *grids, int count,
                                         lu_nvdb_codec codec, lu_error *err) {
    if (!grids || count < 1) return lu_fail(err, LU_ERR_INVALID_ARG, "%s: no grids to write", path);
    for (int i = 0; i < count; i++)
        if (!(grids[i].voxel_size > 0.0) || (grids[i].count && (!grids[i].ijk || !grids[i].values)))
            return lu_fail(err, LU_ERR_INVALID_ARG, "%s: grid %d has no voxel data or a non-positive voxel size", path,
                           i);
    return guarded(path, err, [&]() -> lu_result {
        std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
        for (int i = 0; i < count; i++) {
            const lu_nvdb_sparse &s = grids[i];
            switch (s.type) {
            case LU_NVDB_DOUBLE:
                handles.push_back(sparse_handle<double>(s, s.background, to_double, nanovdb::GridClass::Unknown));
                break;
            case LU_NVDB_VEC3F:
                handles.push_back(sparse_handle<nanovdb::Vec3f>(s, nanovdb::Vec3f(s.background), to_vec3f,
                                                                nanovdb::GridClass::Unknown));
                break;
            default:
                handles.push_back(sparse_handle<float>(s, s.background, to_float, nanovdb::GridClass::FogVolume));
                break;
            }
        }
        return write_atomic(handles, codec, path, err);
    });
}
