// SPDX-License-Identifier: Apache-2.0
// Converts a built-in sphere through the installed library, as a downstream project would:
// the exact band alone, and the whole pipeline with a swept band; exits 0 when both are sane.
// It also includes one header by its pre-0.2 path, which must still compile (forwarding header).
#define LEVELFORGE_NO_MOVED_HEADER_WARNINGS
#include <levelforge/MeshToLevelSet.h> // moved to levelforge/mesh/MeshToLevelSet.h
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <cstdio>

int main()
{
    const levelforge::TriangleMesh sphere = levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 3);
    levelforge::MeshToLevelSetOptions options;
    options.voxelCount = 32;
    const openvdb::FloatGrid::Ptr grid = levelforge::meshToLevelSet(sphere, options);
    std::printf("consumer: %llu active voxels\n", (unsigned long long)grid->activeVoxelCount());

    levelforge::MeshToSdfOptions wide;
    wide.voxelCount = 32;
    wide.exteriorWidth = wide.interiorWidth = 6.0;
    wide.expansion = levelforge::Expansion::Sweep;
    const openvdb::FloatGrid::Ptr swept = levelforge::meshToSdf(sphere, wide);
    std::printf("consumer: %llu active voxels after the sweep\n", (unsigned long long)swept->activeVoxelCount());
    return grid->activeVoxelCount() > 1000 && grid->getGridClass() == openvdb::GRID_LEVEL_SET &&
                   swept->activeVoxelCount() > grid->activeVoxelCount()
               ? 0
               : 1;
}
