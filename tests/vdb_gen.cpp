// Writes the OpenVDB files the .vdb tests read, through libopenvdb itself
// (so they are files as OpenVDB writes them, not hand-made bytes):
//   fog.vdb      grids in this order: "velocity" (vec3s), "temperature"
//                (float), "density" (float fog), "empty" (float, no active
//                voxels), "sdf" (float level set), "frustum" (float, frustum
//                map), "twice" (double); BLOSC-compressed (OpenVDB's default)
//   fog_zip.vdb, fog_none.vdb   "density" alone, ZIP / no compression
//   fog_half.vdb "density" saved as 16-bit floats
//   vec_only.vdb "velocity" alone;  no_grids.vdb  a file without grids
//   twin.vdb     "density": a smooth blob for the .vdb = .nvdb render test
//   tiny_zip.vdb, tiny_blosc.vdb, tiny_two.vdb   small fuzz seeds
//   fog_map.txt  "i j k x y z" for the corners of density's active box,
//                world positions from OpenVDB's own Transform::indexToWorld
// density(i,j,k) = ((7i + 3j + 5k) mod 11 + 1) / 8 over i in [-5,10],
// j in [3,14], k in [-9,2]; the tests compute the same values.
// Usage: lu_vdb_gen OUTPUT_DIR
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace {

const openvdb::Coord kLo(-5, 3, -9), kHi(10, 14, 2);

float density_value(int i, int j, int k) {
    int m = ((7 * i + 3 * j + 5 * k) % 11 + 11) % 11;
    return static_cast<float>(m + 1) / 8.0f;
}

openvdb::math::Transform::Ptr fog_transform() {
    // Scale, then rotate about a tilted axis, then shift: every entry of the
    // matrix differs, so a transposed or dropped part shows.
    openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(0.07);
    xf->postRotate(0.5, openvdb::math::Y_AXIS);
    xf->postRotate(-0.3, openvdb::math::X_AXIS);
    xf->postTranslate(openvdb::Vec3d(0.4, -0.3, 0.2));
    return xf;
}

openvdb::FloatGrid::Ptr density_grid() {
    openvdb::FloatGrid::Ptr g = openvdb::FloatGrid::create(0.0f);
    auto acc = g->getAccessor();
    for (int k = kLo.z(); k <= kHi.z(); k++)
        for (int j = kLo.y(); j <= kHi.y(); j++)
            for (int i = kLo.x(); i <= kHi.x(); i++) acc.setValue(openvdb::Coord(i, j, k), density_value(i, j, k));
    g->setName("density");
    g->setGridClass(openvdb::GRID_FOG_VOLUME);
    g->setTransform(fog_transform());
    return g;
}

bool write(const std::string &path, const openvdb::GridPtrVec &grids, uint32_t compression) {
    try {
        openvdb::io::File file(path);
        file.setCompression(compression);
        file.write(grids);
        file.close();
    } catch (const std::exception &e) {
        std::fprintf(stderr, "lu_vdb_gen: %s: %s\n", path.c_str(), e.what());
        return false;
    }
    return true;
}

} // namespace

int main(int argc, char **argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: lu_vdb_gen OUTPUT_DIR\n");
        return 2;
    }
    const std::string dir = argv[1];
    openvdb::initialize();
    const uint32_t blosc = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;

    openvdb::Vec3SGrid::Ptr velocity = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    velocity->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1.0f, 2.0f, 3.0f));
    velocity->setName("velocity");
    openvdb::FloatGrid::Ptr density = density_grid();
    openvdb::FloatGrid::Ptr temperature = openvdb::FloatGrid::create(0.0f);
    for (int i = 0; i < 4; i++) temperature->tree().setValue(openvdb::Coord(i, 0, 0), 300.0f + 100.0f * i);
    temperature->setName("temperature");
    openvdb::FloatGrid::Ptr empty = openvdb::FloatGrid::create(0.0f);
    empty->setName("empty");
    openvdb::FloatGrid::Ptr sdf = openvdb::FloatGrid::create(0.1f);
    sdf->tree().setValue(openvdb::Coord(0, 0, 0), -0.05f);
    sdf->setName("sdf");
    sdf->setGridClass(openvdb::GRID_LEVEL_SET);
    openvdb::FloatGrid::Ptr frustum = openvdb::FloatGrid::create(0.0f);
    frustum->tree().setValue(openvdb::Coord(2, 2, 2), 1.0f);
    frustum->setName("frustum");
    frustum->setTransform(openvdb::math::Transform::createFrustumTransform(
        openvdb::BBoxd(openvdb::Vec3d(0.0), openvdb::Vec3d(8.0)), 0.5, 2.0, 0.25));
    openvdb::DoubleGrid::Ptr twice = openvdb::DoubleGrid::create(0.0);
    twice->tree().setValue(openvdb::Coord(0, 0, 0), 2.0);
    twice->setName("twice");

    bool ok = write(dir + "/fog.vdb", {velocity, temperature, density, empty, sdf, frustum, twice}, blosc);
    ok = ok && write(dir + "/fog_zip.vdb", {density}, openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    ok = ok && write(dir + "/fog_none.vdb", {density}, openvdb::io::COMPRESS_NONE);
    openvdb::FloatGrid::Ptr as_half = density->deepCopy();
    as_half->setSaveFloatAsHalf(true);
    ok = ok && write(dir + "/fog_half.vdb", {as_half}, blosc);
    ok = ok && write(dir + "/vec_only.vdb", {velocity}, blosc);
    ok = ok && write(dir + "/no_grids.vdb", {}, blosc);

    // A Gaussian blob of radius ~10 voxels around an off-centre point, under
    // a scaled and shifted map: something with light and shade to render.
    openvdb::FloatGrid::Ptr blob = openvdb::FloatGrid::create(0.0f);
    {
        auto acc = blob->getAccessor();
        for (int k = -14; k <= 14; k++)
            for (int j = -12; j <= 12; j++)
                for (int i = -16; i <= 16; i++) {
                    double r2 = (i - 1.5) * (i - 1.5) / 100.0 + (j + 0.5) * (j + 0.5) / 64.0 + k * k / 81.0;
                    float v = static_cast<float>(2.0 * std::exp(-2.0 * r2));
                    if (v > 1e-3f) acc.setValue(openvdb::Coord(i + 20, j - 7, k + 3), v);
                }
    }
    blob->setName("density");
    blob->setGridClass(openvdb::GRID_FOG_VOLUME);
    openvdb::math::Transform::Ptr bxf = openvdb::math::Transform::createLinearTransform(0.045);
    bxf->postTranslate(openvdb::Vec3d(-0.9, 0.33, -0.1));
    blob->setTransform(bxf);
    ok = ok && write(dir + "/twin.vdb", {blob}, blosc);

    // Fuzz seeds (fuzz/corpus/fuzz_vdb/): 4 x 3 x 2 voxels inside one leaf,
    // so the files stay at a few hundred bytes.
    openvdb::FloatGrid::Ptr tiny = openvdb::FloatGrid::create(0.0f);
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 3; j++)
            for (int i = 0; i < 4; i++) tiny->tree().setValue(openvdb::Coord(i + 1, j + 2, k + 3), density_value(i, j, k));
    tiny->setName("density");
    tiny->setGridClass(openvdb::GRID_FOG_VOLUME);
    tiny->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    ok = ok && write(dir + "/tiny_zip.vdb", {tiny}, openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    ok = ok && write(dir + "/tiny_blosc.vdb", {tiny}, blosc);
    openvdb::Vec3SGrid::Ptr tiny_vec = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    tiny_vec->tree().setValue(openvdb::Coord(1, 1, 1), openvdb::Vec3s(1.0f));
    tiny_vec->setName("velocity");
    ok = ok && write(dir + "/tiny_two.vdb", {tiny_vec, tiny}, openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);

    const std::string map_path = dir + "/fog_map.txt";
    std::FILE *fp = std::fopen(map_path.c_str(), "w");
    if (!fp) {
        std::fprintf(stderr, "lu_vdb_gen: cannot write %s\n", map_path.c_str());
        return 1;
    }
    openvdb::math::Transform::Ptr xf = fog_transform();
    for (int c = 0; c < 8; c++) {
        openvdb::Coord ijk((c & 1) ? kHi.x() : kLo.x(), (c & 2) ? kHi.y() : kLo.y(), (c & 4) ? kHi.z() : kLo.z());
        openvdb::Vec3d w = xf->indexToWorld(ijk);
        std::fprintf(fp, "%d %d %d %.17g %.17g %.17g\n", ijk.x(), ijk.y(), ijk.z(), w.x(), w.y(), w.z());
    }
    if (std::fclose(fp) != 0) ok = false;
    return ok ? 0 : 1;
}
