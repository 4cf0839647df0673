// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The front door: triangle mesh → exact narrow-band signed distance FloatGrid.
///
/// Algorithm: after Chang, Cha, Ihm, "Computing Local Signed Distance Fields for Large Polygonal
/// Models", CGF 2008, in sparse VDB trees, with a hierarchy in place of the paper's cell lists
/// (docs/algorithm.md):
///   1. a closest-triangle hierarchy (median splits, clusters of 8 triangles with
///      single-precision distance kernels; src/mesh/TriangleHierarchy.h);
///   2. candidate output leaves: every leaf within the band limit of a triangle, found by
///      rasterizing hierarchy boxes and, for large triangles, recursive triangle–box tests; their
///      count is the voxel budget checked against maxVoxels before anything is allocated;
///   3. per voxel, §4.1's culling on the hierarchy: the previous voxel's triangle bounds the
///      search, boxes and single-precision distances prune, survivors are evaluated exactly;
///   4. sign from the angle-weighted pseudonormal of the closest feature (§4.2), computed on
///      demand with PseudoNormals' arithmetic (src/mesh/LazyPseudoNormals.h).
///
/// What is exact: every active voxel holds the Euclidean distance (computed in double precision,
/// stored as float) to the closest triangle, signed by the pseudonormal rule. That rule gives the
/// true inside/outside for closed, consistently oriented, non-self-intersecting meshes; for open
/// or broken meshes the sign is the pseudonormal's verdict and may be inconsistent far from
/// the surface. The band is exact out to the requested widths: a voxel is active iff
/// -interiorWidth < d/voxelSize < exteriorWidth.
///
/// Output follows OpenVDB's level-set conventions: GRID_LEVEL_SET class, world-unit values,
/// negative inside, background = exteriorWidth * voxelSize, inactive voxels and tiles carry
/// ±background (signed flood fill), voxel centres at integer index coordinates.
#pragma once

#include <levelforge/core/GridSpec.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <cstdint>
#include <string>

namespace levelforge {

/// @brief Options of meshToLevelSet(): everything is in GridSpec.
///
/// GridSpec holds the voxel size or count, band widths in voxels or world units, grid name, voxel
/// budget and interrupter. The widths are rounded to float (the band limits are stored in float)
/// after conversion to voxels; maxVoxels bounds the estimated band voxels.
struct MeshToLevelSetOptions : GridSpec
{
};

/// @brief Counters of meshToLevelSet(): the hierarchy, the candidate leaves and the search.
struct MeshToLevelSetStats
{
    double voxelSize = 0.0;               ///< world units
    uint64_t triangles = 0;               ///< triangles used (degenerate ones skipped)
    uint64_t skippedDegenerate = 0;       ///< zero-area triangles left out
    uint64_t hierarchyNodes = 0;          ///< nodes of the closest-triangle hierarchy
    uint64_t clusters = 0;                ///< its leaves (clusters of up to 8 triangles)
    uint64_t candidateLeaves = 0;         ///< output leaves searched (within the band limit of a node box)
    uint64_t candidateVoxels = 0;         ///< voxels searched (512 per candidate leaf with anything in reach)
    uint64_t activeVoxels = 0;            ///< voxels in the output band
    uint64_t distanceEvaluations = 0;     ///< exact (double-precision) point–triangle distance evaluations
    uint64_t boundTests = 0;              ///< single-precision triangle lower bounds computed
    uint64_t nodeTests = 0;               ///< box distances of hierarchy nodes computed
    /// Wall-clock seconds: set-up, pseudonormals and the hierarchy; candidate leaves; distances;
    /// tree assembly and flood fill.
    double secondsHierarchy = 0, secondsCandidates = 0, secondsDistance = 0, secondsFinish = 0;

    /// @name Counters of the 0.1 road (microtriangle voxelization and per-cell triangle lists)
    /// Kept for source compatibility; the hierarchy road leaves them 0. secondsVoxelize and
    /// secondsLists repeat secondsHierarchy and secondsCandidates. Removed in 0.3.
    /// @{
    uint64_t microtriangles = 0;
    std::array<uint64_t, 4> caseCounts{};
    uint64_t boundaryCells = 0;
    uint64_t triangleListEntries = 0;
    uint64_t localCells = 0;
    double secondsVoxelize = 0, secondsLists = 0;
    /// @}

    /// @brief Exact distance evaluations per output voxel (the cost of the culled search).
    /// @return distanceEvaluations / activeVoxels, or 0 when there are no active voxels
    double evaluationsPerActiveVoxel() const
    {
        return activeVoxels ? double(distanceEvaluations) / double(activeVoxels) : 0.0;
    }
};

/// @brief Converts a triangle mesh to an exact narrow-band level set (see the file comment).
///
/// Throws InvalidArgumentError (bad options), InvalidMeshError (empty mesh, NaN, bad index),
/// ResourceLimitError (band too large), InterruptedError.
/// @param[in]  mesh     the surface, world units, counter-clockwise seen from outside; degenerate
///                      (zero-area) triangles are skipped
/// @param[in]  options  voxel size or count, band widths (voxels or world units), grid name,
///                      voxel budget, interrupter (see MeshToLevelSetOptions)
/// @param[out] stats    optional: counters and stage times of this run
/// @return a GRID_LEVEL_SET FloatGrid named options.gridName, with a linear transform of the
///         resolved voxel size; values in world units, negative inside, background
///         exteriorWidth * voxelSize
/// @throws InvalidArgumentError bad options (voxel size, voxel count, band widths)
/// @throws InvalidMeshError empty mesh, NaN/Inf coordinate, bad index, or every triangle
///         degenerate
/// @throws ResourceLimitError band too large for maxVoxels, or a voxel size so small that index
///         coordinates would pass 1e9
/// @throws InterruptedError the interrupter asked to stop
openvdb::FloatGrid::Ptr meshToLevelSet(const TriangleMesh& mesh,
                                       const MeshToLevelSetOptions& options = {},
                                       MeshToLevelSetStats* stats = nullptr);

/// @brief A level set and, for each of its active voxels, the offset from the voxel centre to
///        the closest point of the mesh (index space, voxel units; the point of the triangle that
///        decided the exact distance) and that triangle's index in mesh.triangles.
///
/// Both grids have the same transform and active topology as the level set.
struct LevelSetWithClosestPoints
{
    openvdb::FloatGrid::Ptr levelSet;
    openvdb::Vec3fGrid::Ptr closestPoints;
    openvdb::Int32Grid::Ptr closestTriangles;
};

/// @brief meshToLevelSet() that also returns the closest-point offsets — the exact shell of
///        vectors that the Vector expansion (docs/expansion.md, Satherley–Jones §4.3) propagates.
/// @param[in]  mesh     the surface, world units (as for meshToLevelSet())
/// @param[in]  options  as for meshToLevelSet()
/// @param[out] stats    optional: counters and stage times of this run
/// @return the level set (identical to meshToLevelSet()'s), the closest-point offsets (index
///         space, voxel units; grid named options.gridName + "_closest") and the closest
///         triangles (grid named options.gridName + "_triangle", background -1)
/// @throws InvalidArgumentError bad options
/// @throws InvalidMeshError empty mesh, NaN/Inf coordinate, bad index, or every triangle
///         degenerate
/// @throws ResourceLimitError band too large, or index coordinates past 1e9
/// @throws InterruptedError the interrupter asked to stop
LevelSetWithClosestPoints meshToLevelSetWithClosestPoints(const TriangleMesh& mesh,
                                                          const MeshToLevelSetOptions& options = {},
                                                          MeshToLevelSetStats* stats = nullptr);

} // namespace levelforge
