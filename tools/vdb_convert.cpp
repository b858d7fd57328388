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
// Usage: lucent-vdb-convert [--grid NAME] [--max-memory MIB] [--] INPUT.vdb > OUTPUT.nvdb
//   NAME: the grid to convert; without it (or empty) the first float grid.
//   MIB: cap on this process's data (0: none; default 1 GiB + 32 x file size).
//   Standard output must be seekable (a file or a memfd): NanoVDB's writer
//   writes its headers last and seeks back for them.
// Exit status: 0 on success, else the lu_result code of the failure
// (include/lucent/core.h); standard error then carries one line,
// "INPUT: reason".
#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include <ext/stdio_filebuf.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
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

int convert(const char *path, const std::string &want, long max_memory_mib) {
    if (lseek(STDOUT_FILENO, 0, SEEK_CUR) < 0)
        fail(LU_ERR_INVALID_ARG, "standard output must be a file (the NanoVDB writer seeks)");

    // A size field that a truncated or hostile file gets wrong makes OpenVDB
    // allocate (and zero) whatever it says: one truncated test file asked
    // for 7.5 GB. A cap on this process's data turns that into bad_alloc.
    // The default, 1 GiB plus 32 times the file's size, is far above what a
    // real grid needs (its tree plus the NanoVDB copy take a few times its
    // compressed size); --max-memory overrides it.
    struct stat st;
    if (stat(path, &st) == 0 && max_memory_mib != 0) {
        double cap = max_memory_mib > 0 ? max_memory_mib * 1048576.0 : 1073741824.0 + 32.0 * (double)st.st_size;
        struct rlimit rl;
        if (getrlimit(RLIMIT_DATA, &rl) == 0) {
            rlim_t want_cap = cap >= (double)RLIM_INFINITY ? RLIM_INFINITY : static_cast<rlim_t>(cap);
            if (rl.rlim_max == RLIM_INFINITY || want_cap < rl.rlim_max) rl.rlim_cur = want_cap;
            setrlimit(RLIMIT_DATA, &rl);
        }
    }

    openvdb::initialize();
    // OpenVDB's stream reader rather than io::File: io::File seeks to each
    // grid's recorded offset and reads without checking the stream, so a
    // truncated file reads back as a grid of zeros; the stream reader goes
    // through the file in order, and a read past its end leaves the stream
    // failed, which is checked below. It reads every grid of the file (each
    // fully, no delayed loading), so a file holding big grids besides the
    // chosen one costs their time and memory here.
    // Opening it here tells a missing or unreadable file from a malformed
    // one (OpenVDB reports both as IoError).
    std::ifstream is(path, std::ios::in | std::ios::binary);
    if (!is) fail(LU_ERR_IO, std::string("cannot open: ") + std::strerror(errno));
    // The first read past the end throws at once: OpenVDB does not check
    // the stream, and a count misread from a malformed file would otherwise
    // go on "reading" a failed stream (one mutated test file took 36 s).
    is.exceptions(std::ios::failbit | std::ios::badbit);
    openvdb::GridPtrVecPtr grids = openvdb::io::Stream(is, /*delayLoad=*/false).getGrids();
    if (is.fail())
        fail(LU_ERR_FORMAT, "truncated or malformed: OpenVDB's reader ran past the end of the file");
    if (!grids) fail(LU_ERR_FORMAT, "OpenVDB read no grid table");
    openvdb::GridBase::Ptr pick;
    for (const openvdb::GridBase::Ptr &g : *grids) {
        if (want.empty() ? g->isType<openvdb::FloatGrid>() : g->getName() == want) {
            pick = g;
            break;
        }
    }
    if (!pick) {
        if (want.empty()) fail(LU_ERR_UNSUPPORTED, "no float grid in the file (it has " + list_grids(*grids) + ")");
        fail(LU_ERR_INVALID_ARG, "no grid named \"" + want + "\" (the file has " + list_grids(*grids) + ")");
    }
    const std::string name = pick->getName();
    if (!pick->isType<openvdb::FloatGrid>())
        fail(LU_ERR_UNSUPPORTED, "grid \"" + name + "\" holds " + pick->valueType() + " values; only float grids are read");
    openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(pick);
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
    long max_memory_mib = -1;   // -1: the default cap
    int i = 1;
    for (; i < argc; i++) {
        if (std::strcmp(argv[i], "--grid") == 0 && i + 1 < argc) {
            want = argv[++i];
        } else if (std::strcmp(argv[i], "--max-memory") == 0 && i + 1 < argc) {
            char *end;
            max_memory_mib = std::strtol(argv[++i], &end, 10);
            if (*end || max_memory_mib < 0) fail(LU_ERR_INVALID_ARG, "--max-memory takes a number of MiB (0: no cap)");
        } else if (std::strcmp(argv[i], "--") == 0) {
            i++;
            break;
        } else {
            break;
        }
    }
    if (i != argc - 1) fail(LU_ERR_INVALID_ARG, "usage: lucent-vdb-convert [--grid NAME] [--max-memory MIB] [--] INPUT.vdb > OUTPUT.nvdb");
    g_input = argv[i];
    try {
        return convert(argv[i], want, max_memory_mib);
    } catch (const std::ios_base::failure &) {
        fail(LU_ERR_FORMAT, "truncated or malformed: OpenVDB's reader ran past the end of the file");
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
