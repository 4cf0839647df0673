// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The indexed triangle mesh every algorithm consumes.
///
/// Positions are stored in double precision, world units; triangles index into them. A mesh is
/// produced by MeshIO (files, through OpenMesh) or MeshShapes (procedural shapes) and is checked
/// by MeshValidation before conversion. Nothing here allocates per triangle.
#pragma once

#include <openvdb/math/BBox.h>
#include <openvdb/math/Vec3.h>

#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

using Vec3d = openvdb::math::Vec3<double>;
using Vec3I = openvdb::math::Vec3<uint32_t>;
using BBoxd = openvdb::math::BBox<Vec3d>;

/// @brief Vertex positions (world units) and triangles indexing them.
struct TriangleMesh
{
    std::vector<Vec3d> points;     ///< vertex positions, world units
    std::vector<Vec3I> triangles;  ///< vertex indices, counter-clockwise seen from outside
    std::string source;            ///< file path or a description of the generator (for messages)

    size_t vertexCount() const { return points.size(); }
    size_t triangleCount() const { return triangles.size(); }
    bool empty() const { return triangles.empty(); }

    /// @brief Bounding box of the vertices that triangles use (world units).
    /// @return the box; an empty box if there are no triangles
    BBoxd bounds() const
    {
        BBoxd b; // default-constructed BBox is empty (min = +max, max = -max)
        for (const Vec3I& t : triangles)
            for (int k = 0; k < 3; ++k) b.expand(points[t[k]]);
        return b;
    }
};

} // namespace levelforge
