// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief What every fuzz target shares: the LF_FUZZ_TARGET entry macro, the temporary input
///        file, the rule for exceptions and the checks of what a reader promises.
///
/// A target is one file, fuzz/Fuzz<Name>.cc, holding
///
///     LF_FUZZ_TARGET(name) { ... use data, size ...; return 0; }
///
/// Built with LEVELFORGE_BUILD_FUZZ (clang), the macro expands to libFuzzer's entry points
/// (LLVMFuzzerInitialize calls fuzz::initialize(), LLVMFuzzerTestOneInput is the body) and
/// each file becomes its own program, levelforge_fuzz_<name>. Built for the replay
/// (LEVELFORGE_FUZZ_REPLAY, any compiler), the body becomes a static function registered
/// under <name>, and fuzz/ReplayMain.cc runs the saved inputs of tests/data/fuzz/<name>/
/// through it (ctest Fuzz.Replay.<name>).
///
/// The rule: a levelforge::Error is the expected refusal of a bad input (runGuarded() swallows
/// it); any other exception (std::bad_alloc, std::length_error, an openvdb::Exception, a bare
/// std::exception) escaping the library is a finding, and so is a broken promise of a reader
/// (an index out of range, a non-finite sample after a successful read). A finding prints one
/// line saying what it was and calls abort() under libFuzzer (which then saves the input); in
/// the replay it throws ReplayFailure, which ReplayMain reports with the input's name.
///
/// Readers take paths: TempFile writes the input to a per-process file with the extension the
/// reader wants, in /dev/shm when it is writable, else $TMPDIR, else /tmp, and removes it; the
/// files of processes that crashed are removed by the next program's initialize().
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VolumeIO.h>

#include <openvdb/openvdb.h>

#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <vector>

#include <cxxabi.h>
#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

namespace levelforge::fuzz {

/// Thrown in the replay build instead of abort() when a target finds something.
class ReplayFailure : public std::runtime_error
{
public:
    /// @brief Constructs the failure.
    /// @param[in] msg  what the target found
    explicit ReplayFailure(const std::string& msg) : std::runtime_error(msg) {}
};

/// @brief Reports a finding: prints "levelforge fuzz: FINDING: <what>" on stderr, then aborts
///        (libFuzzer saves the input) or, in the replay build, throws ReplayFailure.
/// @param[in] what  what went wrong: exception type and message, or the broken promise
[[noreturn]] inline void finding(const std::string& what)
{
    std::fprintf(stderr, "levelforge fuzz: FINDING: %s\n", what.c_str());
    std::fflush(stderr);
#if defined(LEVELFORGE_FUZZ_REPLAY)
    throw ReplayFailure(what);
#else
    std::abort();
#endif
}

/// @brief The demangled type name of @p e.
/// @param[in] e  an exception
/// @return e.g. "std::bad_alloc", "openvdb::v10_0::IoError"
inline std::string typeName(const std::exception& e)
{
    const char* mangled = typeid(e).name();
    int status = 0;
    char* plain = abi::__cxa_demangle(mangled, nullptr, nullptr, &status);
    std::string name = (status == 0 && plain) ? plain : mangled;
    std::free(plain);
    return name;
}

/// @brief Runs @p body with the fuzzing rule: a levelforge::Error is an accepted refusal; any
///        other exception is a finding (see finding()).
/// @param[in] body  the reader call and the checks of its result
/// @return 0 (libFuzzer's "input processed")
template<typename Body>
int runGuarded(Body&& body)
{
    try {
        body();
    } catch (const levelforge::Error&) {
        // the input was refused with a typed, documented error: that is the expected outcome
#if defined(LEVELFORGE_FUZZ_REPLAY)
    } catch (const ReplayFailure&) {
        throw;
#endif
    } catch (const std::exception& e) {
        finding("uncaught " + typeName(e) + " escaped levelforge: " + std::string(e.what()).substr(0, 400));
    } catch (...) {
        finding("an exception of unknown type (not std::exception) escaped levelforge");
    }
    return 0;
}

/// @brief The folder for temporary inputs: /dev/shm when writable, else $TMPDIR, else /tmp.
/// @return the folder, without a trailing slash
inline const std::string& tempDirectory()
{
    static const std::string dir = [] {
        if (::access("/dev/shm", W_OK | X_OK) == 0) return std::string("/dev/shm");
        const char* t = std::getenv("TMPDIR");
        if (t && *t && ::access(t, W_OK | X_OK) == 0) return std::string(t);
        return std::string("/tmp");
    }();
    return dir;
}

/// @brief Removes the temporary inputs that crashed processes left behind (TempFile names of
///        processes that no longer run), then calls openvdb::initialize(). Every program calls
///        it once, before its first input.
inline void initialize()
{
    const std::string prefix = "levelforge-fuzz-";
    if (DIR* dir = ::opendir(tempDirectory().c_str())) {
        while (const dirent* e = ::readdir(dir)) {
            const std::string name = e->d_name;
            if (name.compare(0, prefix.size(), prefix) != 0) continue;
            const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
            if (pid > 0 && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH) {
                ::unlink((tempDirectory() + "/" + name).c_str());
            }
        }
        ::closedir(dir);
    }
    openvdb::initialize();
}

/// The fuzz input as a file (readers take paths): written on construction, removed on
/// destruction. The name is per process, so parallel fuzzing jobs do not collide.
class TempFile
{
public:
    /// @brief Writes @p size bytes at @p data to "<tempDirectory()>/levelforge-fuzz-<pid>-<n><suffix>".
    /// @param[in] data    the bytes
    /// @param[in] size    their number
    /// @param[in] suffix  the extension the reader needs, with its dot (".obj", ".nii.gz", "" for none)
    TempFile(const uint8_t* data, size_t size, const std::string& suffix)
    {
        static unsigned counter = 0;
        mPath = tempDirectory() + "/levelforge-fuzz-" + std::to_string(long(::getpid())) + "-" +
                std::to_string(counter++ % 8) + suffix;
        const int fd = ::open(mPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
        if (fd < 0) environmentError("cannot create");
        size_t done = 0;
        while (done < size) {
            const ssize_t n = ::write(fd, data + done, size - done);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) {
                ::close(fd);
                environmentError("cannot write");
            }
            done += size_t(n);
        }
        if (::close(fd) != 0) environmentError("cannot close");
    }
    ~TempFile() { ::unlink(mPath.c_str()); }
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;

    /// @brief The file's path.
    const std::string& path() const { return mPath; }

private:
    [[noreturn]] void environmentError(const char* what) const
    {
        // Not a finding: the machine cannot hold the input (disk full, no temp folder).
        std::fprintf(stderr, "levelforge fuzz: %s temporary file %s: %s\n", what, mPath.c_str(), std::strerror(errno));
        std::exit(2);
    }

    std::string mPath;
};

/// @brief Checks what readMesh() promises of a mesh it returns (MeshIO.h): at least one
///        triangle, every index within the vertices, every coordinate finite. A broken promise
///        is a finding.
/// @param[in] mesh  the mesh readMesh() returned
/// @param[in] what  the reader, for the message
inline void checkMeshPromises(const TriangleMesh& mesh, const char* what)
{
    if (mesh.triangles.empty()) finding(std::string(what) + " returned a mesh without triangles");
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(mesh.points[i][a])) {
                finding(std::string(what) + " returned vertex " + std::to_string(i) + " with a non-finite coordinate");
            }
        }
    }
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
            if (mesh.triangles[t][k] == mesh.triangles[t][(k + 1) % 3]) {
                finding(std::string(what) + " returned triangle " + std::to_string(t) + " with a repeated corner " +
                        std::to_string(mesh.triangles[t][k]) + " (faces with fewer than three distinct corners are dropped)");
            }
            if (mesh.triangles[t][k] >= mesh.points.size()) {
                finding(std::string(what) + " returned triangle " + std::to_string(t) + " with index " +
                        std::to_string(mesh.triangles[t][k]) + " of " + std::to_string(mesh.points.size()) +
                        " vertices");
            }
        }
    }
}

/// @brief Checks what the volume readers promise of a volume they return (VolumeIO.h): dims
///        > 0 matching the data, finite spacing > 0, finite origin, finite samples. A broken
///        promise is a finding.
/// @param[in] vol   the volume a reader returned
/// @param[in] what  the reader, for the message
inline void checkVolumePromises(const ScalarVolume& vol, const char* what)
{
    const std::string w(what);
    if (vol.dims.x() <= 0 || vol.dims.y() <= 0 || vol.dims.z() <= 0) finding(w + " returned a volume with dims <= 0");
    if (vol.data.size() != vol.voxelCount()) {
        finding(w + " returned " + std::to_string(vol.data.size()) + " samples for dims of " +
                std::to_string(vol.voxelCount()));
    }
    for (int a = 0; a < 3; ++a) {
        if (!(vol.spacing[a] > 0.0) || !std::isfinite(vol.spacing[a])) finding(w + " returned a spacing that is not finite and > 0");
        if (!std::isfinite(vol.origin[a])) finding(w + " returned a non-finite origin");
    }
    for (size_t i = 0; i < vol.data.size(); ++i) {
        if (!std::isfinite(vol.data[i])) finding(w + " returned non-finite sample " + std::to_string(i));
    }
}

/// @brief Reads the input as a mesh file with the extension @p suffix (readMesh() chooses the
///        reader by it) and checks the promises of the result (checkMeshPromises()).
/// @param[in] data    the input
/// @param[in] size    its size
/// @param[in] suffix  ".obj", ".off", ".ply", ".stl", ".stla" or ".stlb"
/// @return 0
inline int fuzzMeshFile(const uint8_t* data, size_t size, const char* suffix)
{
    TempFile file(data, size, suffix);
    return runGuarded([&] {
        MeshReadInfo info;
        const TriangleMesh mesh = readMesh(file.path(), info);
        checkMeshPromises(mesh, (std::string("readMesh(") + suffix + ")").c_str());
    });
}

/// Largest volume the volume targets accept (ReadVolumeOptions::maxVoxels): 4 Mi samples, 16 MiB
/// of floats, so that a header cannot legitimately ask for more than libFuzzer's memory limit.
constexpr uint64_t kMaxFuzzVoxels = uint64_t(1) << 22;

/// @brief ReadVolumeOptions with the fuzzing sample limit.
inline ReadVolumeOptions fuzzVolumeOptions()
{
    ReadVolumeOptions options;
    options.maxVoxels = kMaxFuzzVoxels;
    return options;
}

/// @brief A little-endian integer from the fuzz input (missing bytes read as 0).
/// @param[in] data    the input
/// @param[in] size    its size
/// @param[in] offset  where the integer starts
/// @return the value
template<typename T>
T takeLE(const uint8_t* data, size_t size, size_t offset)
{
    using U = std::make_unsigned_t<T>;
    U v = 0;
    for (size_t b = 0; b < sizeof(T); ++b) {
        const U byte = offset + b < size ? U(data[offset + b]) : U(0);
        v = U(v | U(byte << (8 * b)));
    }
    T out;
    std::memcpy(&out, &v, sizeof(T));
    return out;
}

#if defined(LEVELFORGE_FUZZ_REPLAY)
/// A target's body, as the replay calls it.
using TargetFunction = int (*)(const uint8_t* data, size_t size);

/// A registered target.
struct RegisteredTarget
{
    const char* name;
    TargetFunction function;
};

/// @brief The targets of the replay program, in registration order.
inline std::vector<RegisteredTarget>& registry()
{
    static std::vector<RegisteredTarget> targets;
    return targets;
}

/// @brief Registers @p function under @p name (LF_FUZZ_TARGET does this at start-up).
/// @return true
inline bool registerTarget(const char* name, TargetFunction function)
{
    registry().push_back({name, function});
    return true;
}
#endif

} // namespace levelforge::fuzz

#if defined(LEVELFORGE_FUZZ_REPLAY)
/// Defines the body of the fuzz target @p name (replay build: a registered static function).
#define LF_FUZZ_TARGET(name)                                                                       \
    static int lfFuzzTarget_##name(const uint8_t* data, size_t size);                              \
    [[maybe_unused]] static const bool lfFuzzRegistered_##name =                                   \
        ::levelforge::fuzz::registerTarget(#name, &lfFuzzTarget_##name);                           \
    static int lfFuzzTarget_##name(const uint8_t* data, size_t size)
#else
/// Defines the body of the fuzz target @p name (libFuzzer build: its entry points).
#define LF_FUZZ_TARGET(name)                                                                       \
    extern "C" int LLVMFuzzerInitialize(int*, char***)                                             \
    {                                                                                              \
        ::levelforge::fuzz::initialize();                                                          \
        return 0;                                                                                  \
    }                                                                                              \
    extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
#endif
