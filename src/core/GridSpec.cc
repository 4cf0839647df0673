// SPDX-License-Identifier: Apache-2.0
#include <levelforge/core/GridSpec.h>

#include <levelforge/core/Exceptions.h>

#include <cmath>
#include <sstream>
#include <string>

namespace levelforge {

double resolveVoxelSize(const TriangleMesh& mesh, const GridSpec& options)
{
    const double vs = options.voxelSize;
    if (std::isnan(vs) || std::isinf(vs) || vs < 0.0) {
        std::ostringstream os;
        os << "voxel size must be a positive number (world units), got " << vs;
        throw InvalidArgumentError(os.str());
    }
    if (vs > 0.0) return vs;
    if (options.voxelCount <= 0)
        throw InvalidArgumentError("give a positive voxel size or a positive voxel count (got voxel count " +
                                   std::to_string(options.voxelCount) + ")");
    const BBoxd b = mesh.bounds();
    if (mesh.triangles.empty() || b.min()[0] > b.max()[0])
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) + ": mesh has no triangles");
    const double extent = b.extents()[b.maxExtent()];
    if (!(extent > 0.0) || !std::isfinite(extent))
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) +
                               ": bounding box has zero or non-finite size; cannot derive a voxel size from a count");
    return extent / double(options.voxelCount);
}

} // namespace levelforge
