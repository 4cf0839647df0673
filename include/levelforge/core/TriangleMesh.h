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

/// @brief One attribute of a mesh's surface (a colour, a normal, a texture coordinate), stored
///        per triangle corner, so that seams (a vertex with a different UV or normal in each
///        face that uses it) stay exact. Read from OBJ / PLY files on request (MeshReadOptions in
///        io/MeshIO.h) and transferred to grids by mesh/AttributeTransfer.h.
struct MeshAttribute
{
    std::string name;          ///< Houdini's name: "Cd" (colour), "N" (normal), "uv", or a PLY property
    int components = 3;        ///< values per corner: 1 (float) or 3 (vector)
    /// triangleCount() * 3 * components values: component c of corner k (0, 1, 2 as in
    /// TriangleMesh::triangles[t]) of triangle t is values[(3 * t + k) * components + c].
    std::vector<float> values;
};

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
    /// Optional: per-corner attributes (see MeshAttribute), empty unless asked for when reading.
    /// Each one has triangleCount() * 3 * components values, in step with triangles (functions
    /// that reorder or filter triangles and keep faceIndex in step do not keep these: transfer
    /// attributes from the mesh as it was read).
    std::vector<MeshAttribute> attributes;

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
