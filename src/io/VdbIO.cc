// levelforge — reading and writing .vdb files safely (see VdbIO.h).
#include <levelforge/io/VdbIO.h>

#include <levelforge/core/Exceptions.h>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <system_error>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#ifndef LEVELFORGE_VERSION
#define LEVELFORGE_VERSION "unknown"
#endif

namespace fs = std::filesystem;

namespace levelforge {

namespace vdbio_internal {

std::string quoted(const std::string& s) { return "'" + s + "'"; }

std::string errnoText(int err) { return std::strerror(err); }

/// Directory that will hold `path` ("." for a bare file name).
fs::path parentDir(const std::string& path)
{
    fs::path parent = fs::path(path).parent_path();
    return parent.empty() ? fs::path(".") : parent;
}

/// Throws IoError if `path` cannot be written as a new or replaced file (see checkOutputPath).
void checkLocation(const std::string& path)
{
    if (path.empty()) throw IoError("cannot write a .vdb file: empty output path");
    const fs::path dir = parentDir(path);
    std::error_code ec;
    if (!fs::exists(dir, ec)) {
        throw IoError("cannot write " + quoted(path) + ": directory " + quoted(dir.string()) +
                      " does not exist");
    }
    if (!fs::is_directory(dir, ec)) {
        throw IoError("cannot write " + quoted(path) + ": " + quoted(dir.string()) +
                      " is not a directory");
    }
    if (fs::is_directory(path, ec)) {
        throw IoError("cannot write " + quoted(path) + ": it is a directory");
    }
    if (::access(dir.c_str(), W_OK | X_OK) != 0) {
        throw IoError("cannot write " + quoted(path) + ": directory " + quoted(dir.string()) +
                      ": " + errnoText(errno));
    }
}

/// Creates an empty, uniquely named temporary file next to `path` (mode 0666 & ~umask, like
/// any other file the user creates) and returns its name. Throws IoError.
std::string createTempFile(const std::string& path)
{
    checkLocation(path);
    const fs::path dir = parentDir(path);
    std::random_device rd;
    std::mt19937_64 rng((uint64_t(rd()) << 32) ^ uint64_t(rd()) ^
                        uint64_t(std::chrono::steady_clock::now().time_since_epoch().count()));
    const std::string base = fs::path(path).filename().string();
    for (int attempt = 0; attempt < 100; ++attempt) {
        char suffix[40];
        std::snprintf(suffix, sizeof(suffix), ".%ld-%08llx.tmp", long(::getpid()),
                      static_cast<unsigned long long>(rng() & 0xffffffffull));
        const std::string tmp = (dir / ("." + base + suffix)).string();
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            ::close(fd);
            return tmp;
        }
        if (errno != EEXIST) {
            throw IoError("cannot write " + quoted(path) + ": cannot create a file in " +
                          quoted(dir.string()) + ": " + errnoText(errno));
        }
    }
    throw IoError("cannot write " + quoted(path) + ": no free temporary file name in " +
                  quoted(dir.string()));
}

/// Flushes a file's data to disk; returns errno or 0.
int syncFile(const std::string& file, bool directory = false)
{
    const int fd = ::open(file.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
    if (fd < 0) return errno;
    int err = 0;
    if (::fsync(fd) != 0) err = errno;
    ::close(fd);
    return err;
}

} // namespace vdbio_internal

std::string generatorString() { return std::string("levelforge ") + LEVELFORGE_VERSION; }

void writeGridsAtomic(const std::string& path, const openvdb::GridPtrVec& grids,
                      const openvdb::MetaMap& fileMeta)
{
    using namespace vdbio_internal;
    openvdb::initialize();

    const std::string tmp = createTempFile(path);
    auto fail = [&](const std::string& cause) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw IoError("cannot write " + quoted(path) + ": " + cause);
    };

    try {
        openvdb::io::File file(tmp);
        uint32_t compression = openvdb::io::COMPRESS_ACTIVE_MASK;
        compression |= openvdb::io::Archive::hasBloscCompression() ? openvdb::io::COMPRESS_BLOSC
                                                                   : openvdb::io::COMPRESS_ZIP;
        file.setCompression(compression);
        file.write(grids, fileMeta);
        file.close();
    } catch (const std::exception& e) {
        fail(e.what());
    } catch (...) {
        fail("unknown error while writing");
    }

    // OpenVDB writes through an std::ofstream whose errors (disk full, quota) it does not
    // report: flush to disk, then read the header and every grid's metadata back.
    if (const int err = syncFile(tmp)) fail(errnoText(err));
    try {
        openvdb::io::File check(tmp);
        check.open(/*delayLoad=*/false);
        const auto meta = check.readAllGridMetadata();
        check.close();
        if (!meta || meta->size() != grids.size()) fail("the written file does not read back");
    } catch (const IoError&) {
        throw;
    } catch (const std::exception& e) {
        fail(std::string("the written file does not read back (disk full?): ") + e.what());
    }

    if (std::rename(tmp.c_str(), path.c_str()) != 0) fail(errnoText(errno));
    syncFile(parentDir(path).string(), /*directory=*/true); // best effort
}

void checkOutputPath(const std::string& path) { vdbio_internal::checkLocation(path); }

openvdb::GridPtrVecPtr readGrids(const std::string& path)
{
    using namespace vdbio_internal;
    openvdb::initialize();
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError("cannot read " + quoted(path) + ": no such file");
    if (!fs::is_regular_file(path, ec)) {
        throw IoError("cannot read " + quoted(path) + ": not a regular file");
    }
    if (::access(path.c_str(), R_OK) != 0) {
        throw IoError("cannot read " + quoted(path) + ": " + errnoText(errno));
    }

    openvdb::io::File file(path);
    try {
        file.open(/*delayLoad=*/false);
    } catch (const std::exception& e) {
        throw IoError("cannot read " + quoted(path) + ": not a VDB file (" + e.what() + ")");
    }
    try {
        openvdb::GridPtrVecPtr grids = file.getGrids();
        file.close();
        if (!grids) throw IoError("no grids");
        return grids;
    } catch (const std::exception& e) {
        throw IoError("cannot read " + quoted(path) + ": corrupt VDB file (" + e.what() + ")");
    }
}

void stampLevelSetMetadata(openvdb::GridBase& grid, double exteriorBandVoxels,
                           double interiorBandVoxels, const std::string& source,
                           const std::string& method)
{
    grid.setGridClass(openvdb::GRID_LEVEL_SET);
    grid.insertMeta("levelforge:exterior_band_voxels",
                    openvdb::FloatMetadata(static_cast<float>(exteriorBandVoxels)));
    grid.insertMeta("levelforge:interior_band_voxels",
                    openvdb::FloatMetadata(static_cast<float>(interiorBandVoxels)));
    grid.insertMeta("levelforge:source", openvdb::StringMetadata(source));
    grid.insertMeta("levelforge:generator", openvdb::StringMetadata(generatorString()));
    grid.insertMeta("levelforge:method", openvdb::StringMetadata(method));
}

} // namespace levelforge
