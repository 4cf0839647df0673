// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target vdb: .vdb files through readVdbScalarGrid() (the sparse road: the header
///        pre-scan, OpenVDB's reader, the choice of the scalar grid, the transform checks, the
///        conversion to float) and, when that accepts the file, readVdbVolume() (the dense box,
///        one voxel of padding, a sample limit of 2^18: a few bytes of active tiles claim
///        millions of voxels legitimately, and filling them only slows the fuzzing down).
///
/// Checks: the grid returned is a non-null FloatGrid whose transform is linear, axis-aligned,
/// with positive scale; its tree can be walked; the dense volume keeps VolumeIO.h's promises.
#include "FuzzCommon.h"

#include <cmath>

LF_FUZZ_TARGET(vdb)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".vdb");
    return fuzz::runGuarded([&] {
        ReadVolumeOptions options = fuzz::fuzzVolumeOptions();
        VolumeInfo info;
        const openvdb::FloatGrid::Ptr grid = readVdbScalarGrid(file.path(), options, &info);
        if (!grid) fuzz::finding("readVdbScalarGrid returned a null grid");
        const openvdb::math::Transform& xf = grid->transform();
        if (!xf.isLinear()) fuzz::finding("readVdbScalarGrid returned a grid with a non-linear transform");
        const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
        for (int a = 0; a < 3; ++a) {
            if (!(m[a][a] > 0.0)) fuzz::finding("readVdbScalarGrid returned a grid whose scale along an axis is not > 0");
        }
        // walk the tree the way a consumer would (bounded: the trees come from small inputs)
        uint64_t values = 0;
        double sum = 0.0;
        for (auto it = grid->tree().cbeginValueOn(); it && values < 100000; ++it, ++values) sum += double(*it);
        const openvdb::CoordBBox bbox = grid->evalActiveVoxelBoundingBox();
        volatile double sink = sum + double(bbox.min().x()) + double(grid->activeVoxelCount());
        (void)sink;

        options.vdbPadding = 1;
        options.maxVoxels = uint64_t(1) << 18;
        const ScalarVolume vol = readVdbVolume(file.path(), options, &info);
        fuzz::checkVolumePromises(vol, "readVdbVolume");
    });
}
