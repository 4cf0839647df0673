// SPDX-License-Identifier: Apache-2.0
// ADF metadata (see AdaptiveDistanceField.h): the meta:: keys that mark a grid as an ADF and
// describe its layout, domain and stated bounds.
#include "adf/AdfInternal.h"

#include <levelforge/core/Metadata.h>
#include <levelforge/io/VdbIO.h>

#include <cstdio>

namespace levelforge {
namespace adf_internal {

std::string boundLevelKey(int level)
{
    char key[64];
    std::snprintf(key, sizeof(key), meta::kAdfBoundLevelPattern, level);
    return key;
}

void stampAdfMetadata(openvdb::FloatGrid& grid, const CoordBBox& domain, const std::array<double, kAdfLevels>& bounds)
{
    grid.setGridClass(openvdb::GRID_UNKNOWN);
    grid.insertMeta(meta::kAdf, openvdb::StringMetadata(kAdfVersion));
    grid.insertMeta(meta::kAdfDomainMin, openvdb::Vec3IMetadata(domain.min().asVec3i()));
    grid.insertMeta(meta::kAdfDomainMax, openvdb::Vec3IMetadata(domain.max().asVec3i()));
    grid.insertMeta(meta::kAdfSampling,
                    openvdb::StringMetadata(
                        "samples at index points (world = index*voxel size); leaf voxels: the lattice values of "
                        "the block, active voxels = subdivided finest cells, nodes of size 2/4 inside a leaf are "
                        "subdivided iff they hold an active voxel; level-1 tile: value at its minimum corner, cell "
                        "8^3; level-2 tile: value at its minimum corner, cell 128^3; corners lying on a larger "
                        "cell's face or edge take that cell's trilinear value; trilinear reconstruction"));
    for (int l = 0; l < kAdfLevels; ++l) grid.insertMeta(boundLevelKey(l), openvdb::DoubleMetadata(bounds[size_t(l)]));
    grid.insertMeta(meta::kGenerator, openvdb::StringMetadata(generatorString()));
}

} // namespace adf_internal
} // namespace levelforge
