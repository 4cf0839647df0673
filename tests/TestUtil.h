// SPDX-License-Identifier: Apache-2.0
// Shared helpers for the levelforge test suite.
#pragma once

#include <gtest/gtest.h>

#include <levelforge/core/DenseVolume.h>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>

namespace levelforge_test {

/// ../shared/data (or $LEVELFORGE_SHARED_DATA); empty string when absent.
inline std::string sharedDataDir()
{
    if (const char* env = std::getenv("LEVELFORGE_SHARED_DATA")) {
        if (std::filesystem::is_directory(env)) return env;
    }
#ifdef LEVELFORGE_SHARED_DATA_DIR
    if (std::filesystem::is_directory(LEVELFORGE_SHARED_DATA_DIR)) return LEVELFORGE_SHARED_DATA_DIR;
#endif
    return {};
}

/// True when the environment sets LEVELFORGE_REQUIRE_SHARED_DATA=1 (a CI that provides
/// ../shared/data): a test that needs the shared data and does not find it then FAILS instead of
/// skipping, so that missing data cannot pass unnoticed.
inline bool sharedDataRequired()
{
    const char* v = std::getenv("LEVELFORGE_REQUIRE_SHARED_DATA");
    return v && std::string(v) == "1";
}

/// Leaves the current test because shared data is missing: a visible skip, or a failure when
/// LEVELFORGE_REQUIRE_SHARED_DATA=1. `message` is streamed (`"x " << y` works).
#define LF_SHARED_DATA_MISSING(message)                                                           \
    do {                                                                                          \
        std::ostringstream lfMsg_;                                                                \
        lfMsg_ << message;                                                                        \
        if (::levelforge_test::sharedDataRequired()) {                                            \
            FAIL() << lfMsg_.str() << " (LEVELFORGE_REQUIRE_SHARED_DATA=1: shared data required)"; \
        } else {                                                                                  \
            GTEST_SKIP() << lfMsg_.str() << "; skipping";                                         \
        }                                                                                         \
    } while (0)

/// Skips the current test (fails it with LEVELFORGE_REQUIRE_SHARED_DATA=1) when ../shared/data
/// is absent. Use it first in every test that reads ../shared/data.
#define LF_SKIP_WITHOUT_SHARED_DATA()                                                             \
    do {                                                                                          \
        if (::levelforge_test::sharedDataDir().empty())                                           \
            LF_SHARED_DATA_MISSING("../shared/data not present (or $LEVELFORGE_SHARED_DATA)");    \
    } while (0)

/// Path of a file under ../shared/data, or skips the current test with a message (fails it
/// with LEVELFORGE_REQUIRE_SHARED_DATA=1).
#define LEVELFORGE_SHARED_FILE_OR_SKIP(var, relative)                                             \
    std::string var;                                                                              \
    do {                                                                                          \
        LF_SKIP_WITHOUT_SHARED_DATA();                                                            \
        var = ::levelforge_test::sharedDataDir() + "/" + relative;                                \
        if (!std::filesystem::exists(var)) LF_SHARED_DATA_MISSING(var << " not present");         \
    } while (0)

/// Whether this CPU runs AVX2 code (x86 with GCC/Clang; false elsewhere).
inline bool cpuHasAvx2()
{
#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2");
#else
    return false;
#endif
}

/// Skips, visibly, a test comparing an AVX2 build with the baseline on a CPU without AVX2 (there
/// the comparison would be the baseline against itself).
#define LF_SKIP_WITHOUT_AVX2()                                                                    \
    do {                                                                                          \
        if (!::levelforge_test::cpuHasAvx2())                                                     \
            GTEST_SKIP() << "this CPU has no AVX2: the AVX2 build cannot run, and comparing the "  \
                            "baseline with itself would prove nothing";                           \
    } while (0)

/// A fresh scratch directory for one test.
inline std::filesystem::path scratchDir(const std::string& name)
{
#ifdef LEVELFORGE_TEST_TMP_DIR
    std::filesystem::path p = std::filesystem::path(LEVELFORGE_TEST_TMP_DIR) / name;
#else
    std::filesystem::path p = std::filesystem::temp_directory_path() / ("levelforge_" + name);
#endif
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    return p;
}

/// A random binary mask (each voxel set with probability `density`), reproducible by `seed`.
inline levelforge::MaskVolume randomMask(const openvdb::Coord& dims, double density, unsigned seed,
                                         const openvdb::Vec3d& spacing)
{
    levelforge::MaskVolume m(dims, 0, spacing);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (auto& v : m.data) v = u(rng) < density ? 1 : 0;
    return m;
}

/// Lines of @p text that start with @p prefix (e.g. "levelforge: error:").
inline int countLines(const std::string& text, const std::string& prefix)
{
    int n = 0;
    std::istringstream is(text);
    for (std::string line; std::getline(is, line);) {
        if (line.rfind(prefix, 0) == 0) ++n;
    }
    return n;
}

} // namespace levelforge_test
