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

/// Path of a file under ../shared/data, or skips the current test with a message.
#define LEVELFORGE_SHARED_FILE_OR_SKIP(var, relative)                                             \
    std::string var;                                                                              \
    do {                                                                                          \
        const std::string dir_ = ::levelforge_test::sharedDataDir();                              \
        if (dir_.empty()) GTEST_SKIP() << "../shared/data not present; skipping " << relative;    \
        var = dir_ + "/" + relative;                                                              \
        if (!std::filesystem::exists(var)) GTEST_SKIP() << var << " not present; skipping";       \
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
