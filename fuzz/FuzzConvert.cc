// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target convert: whatever mesh a reader accepts goes through a tiny conversion,
///        meshToLevelSet() with 16 voxels along the longest side, a 2-voxel band and a budget of
///        2^20 band voxels.
///
/// The reader is chosen from the content, so that the seeds of every mesh target work
/// unchanged: "ply" → .ply, "OFF" (also "COFF", "NOFF", ...) → .off, "solid" or a size of
/// 84 + 50 × (the count at byte 80) → .stl, anything else → .obj.
///
/// Checks (MeshToLevelSet.h): the result is a GRID_LEVEL_SET FloatGrid whose background is the
/// exterior width in world units and whose active values are finite and inside the band.
#include "FuzzCommon.h"

#include <levelforge/mesh/MeshToLevelSet.h>

#include <cmath>
#include <cstring>

namespace {

/// The extension of the reader for @p data (see the file comment).
const char* meshSuffix(const uint8_t* data, size_t size)
{
    auto startsWith = [&](const char* s) { return size >= std::strlen(s) && std::memcmp(data, s, std::strlen(s)) == 0; };
    if (startsWith("ply")) return ".ply";
    if (size >= 84) {
        const uint32_t n = levelforge::fuzz::takeLE<uint32_t>(data, size, 80);
        if (uint64_t(size) == 84 + 50 * uint64_t(n)) return ".stl";
    }
    if (startsWith("solid")) return ".stl";
    const size_t head = std::min<size_t>(size, 8);
    for (size_t i = 0; i + 3 <= head; ++i) {
        if (std::memcmp(data + i, "OFF", 3) == 0) return ".off";
    }
    return ".obj";
}

} // namespace

LF_FUZZ_TARGET(convert)
{
    using namespace levelforge;
    const char* suffix = meshSuffix(data, size);
    fuzz::TempFile file(data, size, suffix);
    return fuzz::runGuarded([&] {
        const TriangleMesh mesh = readMesh(file.path());
        MeshToLevelSetOptions options;
        options.voxelCount = 16;
        options.exteriorWidth = 2.0;
        options.interiorWidth = 2.0;
        options.maxVoxels = uint64_t(1) << 20;
        MeshToLevelSetStats stats;
        const openvdb::FloatGrid::Ptr grid = meshToLevelSet(mesh, options, &stats);
        if (!grid) fuzz::finding("meshToLevelSet returned a null grid");
        if (grid->getGridClass() != openvdb::GRID_LEVEL_SET) fuzz::finding("meshToLevelSet returned a grid that is not a level set");
        const double h = grid->voxelSize()[0];
        const double background = double(grid->background());
        if (!(h > 0.0) || !std::isfinite(h)) fuzz::finding("meshToLevelSet returned a voxel size that is not finite and > 0");
        if (!(std::fabs(background - options.exteriorWidth * h) <= 1e-5 * background)) {
            fuzz::finding("meshToLevelSet: background " + std::to_string(background) + " is not exteriorWidth * voxelSize = " +
                          std::to_string(options.exteriorWidth * h));
        }
        const double limit = std::max(options.exteriorWidth, options.interiorWidth) * h * (1.0 + 1e-5);
        for (auto it = grid->tree().cbeginValueOn(); it; ++it) {
            const float v = *it;
            if (!std::isfinite(v)) fuzz::finding("meshToLevelSet: active value " + std::to_string(v) + " is not finite");
            if (std::fabs(double(v)) > limit) {
                fuzz::finding("meshToLevelSet: active value " + std::to_string(v) + " is outside the band of " +
                              std::to_string(limit));
            }
        }
    });
}
