// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Transfer of a mesh's surface attributes (colour, normal, UV, ...) to grids: each
///        active voxel gets the attribute at its closest point on the surface (Houdini's
///        *VDB from Polygons* attribute transfer).
///
/// Given the closest triangle of every active voxel (the Int32 grid of the exact band,
/// meshToLevelSetWithClosestPoints() in mesh/MeshToLevelSet.h), the value at voxel ijk is the
/// barycentric interpolation of the attribute's three corner values (TriangleMesh::attributes,
/// stored per corner, so seams are kept) at the closest point of that triangle to the voxel
/// centre. The closest point and its barycentric coordinates are exact up to double rounding
/// (Voronoi-region classification, as core/TriangleDistance.h); the interpolation is done in
/// double and stored as float. So an attribute that is linear over the surface (a colour ramp
/// on a plane) is reproduced exactly up to float rounding; elsewhere it is the piecewise-linear
/// interpolant of the corner values, as Houdini and OpenVDB's tools transfer point attributes.
/// Where several triangles are equally close (on an edge, a vertex, a crease) the one the band
/// chose decides; with per-vertex attributes both give the same value on the shared edge.
/// Normals are interpolated as given (not renormalised).
///
/// Parallel over the leaves of the closest-triangle grid (TBB), no allocation per voxel; the
/// result does not depend on the number of threads.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>
#include <vector>

namespace levelforge {

/// Options of transferAttribute().
struct AttributeTransferOptions
{
    /// The output grid's name; empty (default): the attribute's name ("Cd", "N", "uv", ...).
    std::string gridName;
    /// Optional: polled once per leaf; InterruptedError when it says stop.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief The attribute of @p mesh named @p name.
/// @throws InvalidArgumentError "<mesh source>: no vertex attribute 'X' (it has: Cd, N)" when
///         the mesh has none of that name; InvalidMeshError when its value count is not
///         triangleCount() * 3 * components (the mesh was changed after reading).
const MeshAttribute& findMeshAttribute(const TriangleMesh& mesh, const std::string& name);

/// @brief The attribute @p name of @p mesh at the closest point of every active voxel of
///        @p closestTriangles (see the file comment).
/// @param[in] mesh              the mesh, with the attribute (TriangleMesh::attributes)
/// @param[in] name              the attribute's name
/// @param[in] closestTriangles  for each active voxel, the index of its closest triangle of
///                              @p mesh; its transform maps voxels to the world frame of
///                              @p mesh. Voxels whose index is out of range are left inactive.
/// @param[in] options           name of the grid, interrupter
/// @return a FloatGrid (1 component) or a Vec3SGrid (3 components; "N" has vector type
///         covariant-normalize, others invariant), with the transform and the active voxels of
///         @p closestTriangles (active tiles are left inactive), background 0, grid class
///         unknown
/// @throws InvalidArgumentError (no such attribute, a component count other than 1 or 3),
///         InvalidMeshError (value count out of step), InterruptedError.
openvdb::GridBase::Ptr transferAttribute(const TriangleMesh& mesh, const std::string& name,
                                         const openvdb::Int32Grid& closestTriangles,
                                         const AttributeTransferOptions& options = {});

} // namespace levelforge
