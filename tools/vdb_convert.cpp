// lucent-vdb-convert: reads one float grid of an OpenVDB (.vdb) file and
// writes it to standard output as a NanoVDB file (one grid, uncompressed).
//
// This is the only program of the project that runs OpenVDB's reader, and it
// runs as a child of the library (src/volume/grid_vdb.c), never inside it.
// OpenVDB's reader trusts the sizes and offsets it finds in the file, so a
// malformed or hostile file can crash it or make it read out of bounds; in a
// process of its own such a crash ends the converter, and the library reports
// it as an error naming the file (docs/volumes.md, ".vdb input"). The library
// and everything linking it (the CLI, the viewer, programs embedding lucent)
// also stay free of OpenVDB, TBB, Blosc and Boost.
//
// Usage: lucent-vdb-convert [--grid NAME] [--] INPUT.vdb > OUTPUT.nvdb
//   NAME: the grid to convert; without it (or empty) the first float grid.
//   Standard output must be seekable (a file or a memfd): NanoVDB's writer
//   writes its headers last and seeks back for them.
// Exit status: 0 on success, else the lu_result code of the failure
// (include/lucent/core.h); standard error then carries one line,
// "INPUT: reason".
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include <ext/stdio_filebuf.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <ostream>
#include <string>

#include <lucent/core.h>

namespace {

const char *g_input = "lucent-vdb-convert";

[[noreturn]] void fail(lu_result code, const std::string &reason) {
    std::fprintf(stderr, "%s: %s\n", g_input, reason.c_str());
    std::fflush(stderr);
    std::_Exit(static_cast<int>(code));
}

// '"density" (float), "velocity" (vec3s)': what the file holds, in file
// order, for a name that is not there.
std::string list_grids(const openvdb::GridPtrVec &grids) {
    std::string out;
    for (const openvdb::GridBase::Ptr &g : grids) {
        if (!out.empty()) out += ", ";
        out += "\"" + g->getName() + "\" (" + g->valueType() + ")";
    }
    return out.empty() ? std::string("no grids") : out;
}

int convert(const char *path, const std::string &want) {
    // Opening the file first tells a missing or unreadable file from a
    // malformed one (OpenVDB reports both as IoError).
    std::FILE *probe = std::fopen(path, "rb");
    if (!probe) fail(LU_ERR_IO, std::string("cannot open: ") + std::strerror(errno));
    std::fclose(probe);
    if (lseek(STDOUT_FILENO, 0, SEEK_CUR) < 0)
        fail(LU_ERR_INVALID_ARG, "standard output must be a file (the NanoVDB writer seeks)");

    openvdb::initialize();
    openvdb::io::File file(path);
    // No delayed loading: everything is read now, in this process, rather
    // than paged in later from a mapping of a file that may change.
    file.open(false);
    // Descriptors only, in file order (beginName() would go by name), so
    // "the first float grid" means what it means for .nvdb files.
    openvdb::GridPtrVecPtr metas = file.readAllGridMetadata();
    std::string name;
    bool found = false;
    for (const openvdb::GridBase::Ptr &meta : *metas) {
        if (want.empty() ? meta->isType<openvdb::FloatGrid>() : meta->getName() == want) {
            name = meta->getName();
            found = true;
            if (!meta->isType<openvdb::FloatGrid>())
                fail(LU_ERR_UNSUPPORTED, "grid \"" + name + "\" holds " + meta->valueType() +
                                             " values; only float grids are read");
            break;
        }
    }
    if (!found) {
        if (want.empty()) fail(LU_ERR_UNSUPPORTED, "no float grid in the file (it has " + list_grids(*metas) + ")");
        fail(LU_ERR_INVALID_ARG, "no grid named \"" + want + "\" (the file has " + list_grids(*metas) + ")");
    }
    openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(name));
    file.close();
    if (!grid) fail(LU_ERR_FORMAT, "grid \"" + name + "\" did not read back as a float grid");
    // NanoVDB keeps one affine map; a frustum (or other non-linear) map would
    // be replaced by an affine approximation, moving the volume.
    if (!grid->transform().isLinear())
        fail(LU_ERR_UNSUPPORTED, "grid \"" + name + "\" has a non-linear (" + grid->transform().mapType() +
                                     ") transform; only linear index-to-world maps are read");
    if (grid->activeVoxelCount() == 0) fail(LU_ERR_UNSUPPORTED, "grid \"" + name + "\" has no active voxels");

    nanovdb::GridHandle<nanovdb::HostBuffer> handle = nanovdb::openToNanoVDB(*grid);
    __gnu_cxx::stdio_filebuf<char> buf(STDOUT_FILENO, std::ios::out | std::ios::binary);
    std::ostream os(&buf);
    nanovdb::io::writeGrid(os, handle, nanovdb::io::Codec::NONE);
    os.flush();
    if (!os) fail(LU_ERR_IO, "writing the NanoVDB grid to standard output failed");
    return 0;
}

} // namespace

int main(int argc, char **argv) {
    std::string want;
    int i = 1;
    for (; i < argc; i++) {
        if (std::strcmp(argv[i], "--grid") == 0 && i + 1 < argc) {
            want = argv[++i];
        } else if (std::strcmp(argv[i], "--") == 0) {
            i++;
            break;
        } else {
            break;
        }
    }
    if (i != argc - 1) fail(LU_ERR_INVALID_ARG, "usage: lucent-vdb-convert [--grid NAME] [--] INPUT.vdb > OUTPUT.nvdb");
    g_input = argv[i];
    try {
        return convert(argv[i], want);
    } catch (const std::bad_alloc &) {
        fail(LU_ERR_NOMEM, "out of memory reading the grid (a malformed file can claim huge sizes)");
    } catch (const openvdb::Exception &e) {
        fail(LU_ERR_FORMAT, std::string("OpenVDB cannot read the file: ") + e.what());
    } catch (const std::exception &e) {
        fail(LU_ERR_FORMAT, std::string("reading the file failed: ") + e.what());
    } catch (...) {
        fail(LU_ERR_FORMAT, "reading the file failed (unknown exception)");
    }
}
