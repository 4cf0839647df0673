// Converts a built-in sphere through the installed library; exits 0 when the band is sane.
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <cstdio>

int main()
{
    const levelforge::TriangleMesh sphere = levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 3);
    levelforge::MeshToLevelSetOptions options;
    options.voxelCount = 32;
    const openvdb::FloatGrid::Ptr grid = levelforge::meshToLevelSet(sphere, options);
    std::printf("consumer: %llu active voxels\n", (unsigned long long)grid->activeVoxelCount());
    return grid->activeVoxelCount() > 1000 && grid->getGridClass() == openvdb::GRID_LEVEL_SET ? 0 : 1;
}
