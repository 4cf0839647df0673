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
    /// Optional: for each triangle, the 0-based index of the input face (polygon) it came from,
    /// before triangulation (readMesh() fills it when a file face became several triangles or
    /// was dropped). Empty: triangle i is face i. When not empty it has one entry per triangle,
    /// and every function that reorders or filters triangles keeps it in step (see sourceFace()).
    std::vector<uint32_t> faceIndex;

    size_t vertexCount() const { return points.size(); }
    size_t triangleCount() const { return triangles.size(); }
    bool empty() const { return triangles.empty(); }

    /// @brief The input face (polygon) triangle @p t came from: faceIndex[t], or @p t when
    ///        faceIndex is empty.
    uint32_t sourceFace(size_t t) const { return faceIndex.empty() ? uint32_t(t) : faceIndex[t]; }

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
