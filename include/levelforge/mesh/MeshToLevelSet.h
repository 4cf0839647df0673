// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The front door: triangle mesh → exact narrow-band signed (or unsigned) distance
///        FloatGrid.
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
///   4. the sign, by MeshToLevelSetOptions::sign (SignMode):
///      - Pseudonormal: the angle-weighted pseudonormal of the closest feature (§4.2; Bærentzen
///        & Aanæs 2005), computed on demand with PseudoNormals' arithmetic
///        (src/mesh/LazyPseudoNormals.h); inactive values by OpenVDB's signed flood fill;
///      - Winding: inside where |w| > 1/2, w the generalized winding number (Jacobson et al.
///        2013) by the fast winding number (Barill et al. 2018, mesh/FastWindingNumber.h). It is
///        not evaluated per voxel: w jumps only across the surface, and off it changes no faster
///        than the Biot–Savart bound of the mesh's boundary edges (0 for a closed, consistently
///        oriented mesh). In each leaf, two face-adjacent voxels u, v with d(u) + d(v) > 1 (voxels)
///        see no surface between them (the open balls of radius d cover the segment), so the
///        leaf's voxels fall into a few groups joined that way; w is estimated once per leaf, at
///        its voxel farthest from the surface, carried to the other groups by the signed count
///        of surface crossings (±1 each) and to each group's voxels with the gradient bound times
///        the hops; where that cannot decide (near a hole's rim, or |w| near 1/2), first-order
///        models (value and exact gradient, Hessian bound) per 4³ and 2³ block; then, where few
///        triangles are near, w split into the near triangles' exact sum plus a first-order
///        model of the rest (whose boundary is a few voxels away); as a last resort an
///        estimate per voxel. A lone open triangle beside closed parts is left out of w (alone
///        it never reaches 1/2, so that is exact). Tiles are signed per VDB node the same way
///        (signInactiveByWindingNumber(); docs/algorithm.md, "Sign modes");
///      - Unsigned: no sign: the exact distance to the surface, for any surface (open sheets,
///        cloth, soups); the band is the exterior width; the grid class is GRID_UNKNOWN;
///      - Auto (the default of meshToSdf() and the CLI; this function's default is
///        Pseudonormal): Pseudonormal when validateMesh() finds the mesh closed (watertight and
///        consistently oriented) and no connected part encloses a negative volume (inside out),
///        Winding otherwise; the stats say which and why.
///   5. with fillInterior, every inside voxel is active (see MeshToLevelSetOptions::fillInterior).
///
/// What is exact: every active voxel holds the Euclidean distance (computed in double precision,
/// stored as float) to the closest triangle. Its sign: Pseudonormal gives the true inside/outside
/// for closed, consistently oriented, non-self-intersecting meshes; for open or broken meshes it
/// is the pseudonormal's verdict and may be inconsistent far from the surface. Winding gives
/// the sign of |w| − 1/2 exactly wherever ||w| − 1/2| exceeds kWindingTolerance (0.02) plus the
/// estimate's error (measured below 1e-2, typically 2e-3, at the default accuracy β = 2);
/// nearer to 1/2 it is the fast estimate's verdict. The band is exact out to the requested widths: a voxel is active iff
/// -interiorWidth < d/voxelSize < exteriorWidth (Unsigned: d/voxelSize < exteriorWidth).
///
/// Output follows OpenVDB's level-set conventions: GRID_LEVEL_SET class (GRID_UNKNOWN when
/// unsigned), world-unit values, negative inside, background = exteriorWidth * voxelSize,
/// inactive voxels and tiles carry ±background, voxel centres at integer index coordinates.
/// The grid carries the metadata kSignMetadata ("pseudonormal", "winding" or "unsigned") and,
/// when filled, kFillInteriorMetadata. Results do not depend on the number of threads.
#pragma once

#include <levelforge/core/GridSpec.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/gpu/VulkanDevices.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

struct MeshReport;

/// How the distance is signed (Houdini's VDB from Polygons: the default, *Preserve Holes*,
/// *Unsigned Distance*).
enum class SignMode
{
    Auto,         ///< Pseudonormal for closed, consistently oriented meshes, Winding otherwise
    Pseudonormal, ///< the angle-weighted pseudonormal of the closest feature (Bærentzen–Aanæs)
    Winding,      ///< inside where |w| > 1/2, w the generalized winding number (fast, Barill et al.)
    Unsigned      ///< no sign: the unsigned distance (any surface; not a level set)
};

/// "auto" / "pseudonormal" / "winding" / "unsigned"; throws InvalidArgumentError otherwise.
SignMode signModeFromString(const std::string& name);
/// The name signModeFromString() reads.
const char* toString(SignMode mode);

/// Grid metadata: the sign mode used, "pseudonormal" / "winding" / "unsigned" (StringMetadata).
inline constexpr const char* kSignMetadata = "levelforge:sign";
/// Grid metadata: true when every inside voxel is active (BoolMetadata).
inline constexpr const char* kFillInteriorMetadata = "levelforge:fill_interior";

/// @brief Options of meshToLevelSet().
///
/// GridSpec holds the voxel size or count, band widths in voxels or world units, grid name, voxel
/// budget and interrupter. The widths are rounded to float (the band limits are stored in float)
/// after conversion to voxels; maxVoxels bounds the estimated band voxels.
struct MeshToLevelSetOptions : GridSpec
{
    /// How the distance is signed (see SignMode and the file comment). The default here is
    /// Pseudonormal, this function's behaviour before the sign modes existed (bit for bit);
    /// the pipeline (meshToSdf()) and `levelforge mesh-to-sdf` default to Auto.
    SignMode sign = SignMode::Pseudonormal;
    /// Every voxel inside the surface is active and negative (Houdini's *Fill Interior*): the
    /// band's voxels keep their exact distances; deeper voxels hold −background, as active tiles
    /// where a whole tile is inside (a clamped distance, the value OpenVDB gives the inactive
    /// interior of a level set: O(surface) work instead of O(volume)). Not with Unsigned.
    bool fillInterior = false;
    /// Winding: the fast winding number's accuracy β (> 1; FastWindingNumberOptions::accuracy).
    double windingAccuracy = 2.0;
    /// Auto: an existing validateMesh() report of this mesh (not owned); null: validate here.
    const MeshReport* validation = nullptr;

    /// @name Compute device (gpu/VulkanDevices.h)
    /// Where the per-voxel search of the band leaves runs. Vulkan: the device finds each voxel's
    /// closest candidate triangle (a leaf's candidates: every triangle of a hierarchy cluster
    /// within the band limit of the leaf) in double precision, term for term as the CPU; the
    /// CPU then evaluates that one triangle again for the closest point, the sign and the band
    /// test, so the grid is bit-identical to the CPU path's (the closest-triangle index may
    /// differ where two triangles are exactly as close). Needs a device with shaderFloat64.
    /// Auto: Vulkan on a discrete GPU when the band has at least deviceMinLeaves candidate
    /// leaves, else the CPU; a device error then falls back to the CPU (stats say why).
    /// @{
    ComputeDevice device = ComputeDevice::Auto;
    uint64_t deviceMemoryBudget = 0;  ///< bytes per batch slot on the device; 0: automatic
    uint64_t deviceMinLeaves = 8192;  ///< Auto: smaller bands stay on the CPU
    /// @}

    /// @brief Brick restriction of distributed runs (distributed/DistributedMeshToSdf.h); null
    ///        (default): the whole band. Not owned.
    ///
    /// When set (even to an empty list), only the output leaves whose origin lies in one of these
    /// index-space boxes are computed, and only the triangles that come within the band limit
    /// (plus one voxel) of a box enter the closest-triangle hierarchy. Each leaf computed is
    /// bit-identical to the same leaf of the unrestricted run: a voxel's value depends only on
    /// the triangles within the band limit of it, and ties between equally close triangles go to
    /// the smaller index, which the restriction keeps (the mesh itself is not renumbered). The
    /// result is the leaves only: no signed flood fill, so tiles keep the background (the caller
    /// merges the parts and finishes the union once: finishBrickUnion()). Pseudonormal and
    /// Unsigned only, not with fillInterior (InvalidArgumentError): the winding number's tile
    /// signs and the interior fill are passes over the whole tree.
    const std::vector<openvdb::CoordBBox>* onlyLeavesIn = nullptr;
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
    uint64_t leafPasses = 0;              ///< of those, leaves computed by one vectorised pass over their
                                          ///< few nearby triangles (at most 128) instead of a search per voxel
    uint64_t candidateVoxels = 0;         ///< voxels searched (512 per candidate leaf with anything in reach)
    uint64_t activeVoxels = 0;            ///< voxels in the output band
    uint64_t distanceEvaluations = 0;     ///< exact (double-precision) point–triangle distance evaluations
    uint64_t boundTests = 0;              ///< single-precision triangle lower bounds computed
    uint64_t nodeTests = 0;               ///< box distances of hierarchy nodes computed
    /// Wall-clock seconds: set-up, pseudonormals and the hierarchy; candidate leaves; distances
    /// (with the winding signs of the band's leaves); tree assembly, flood fill or tile signs, fill.
    double secondsHierarchy = 0, secondsCandidates = 0, secondsDistance = 0, secondsFinish = 0;

    /// @name Sign
    /// @{
    SignMode sign = SignMode::Pseudonormal; ///< the mode used (never Auto)
    std::string signReason;                 ///< why (Auto: what validation found)
    uint64_t windingEvaluations = 0;        ///< fast winding number evaluations (leaves and tiles)
    uint64_t windingGroups = 0;             ///< groups of voxels / tiles signed from one evaluation
    uint64_t windingIndividual = 0;         ///< voxels / tiles that needed their own evaluation
    uint64_t currentEdges = 0;              ///< boundary-current edges (0: w piecewise constant)
    uint64_t insideTiles = 0;               ///< tiles set inside (any level)
    uint64_t filledVoxels = 0;              ///< fillInterior: voxels activated (tiles by volume)
    double secondsWinding = 0;              ///< building the fast winding number
    /// @}

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

    /// @name Compute device
    /// @{
    std::string device = "cpu";           ///< "cpu", or "vulkan: <device name> (<type>)"
    std::string deviceNote;               ///< Auto on the CPU, or a fallback: why
    uint64_t deviceBatches = 0;           ///< batches of leaves dispatched
    uint64_t devicePairs = 0;             ///< voxel–triangle distances computed on the device
    uint64_t deviceBytesUp = 0, deviceBytesDown = 0, devicePeakBytes = 0; ///< transfers, device memory
    double secondsDeviceWait = 0;         ///< the CPU waiting for the device
    double secondsDeviceCopy = 0;         ///< copies into and out of staging memory
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
/// Throws InvalidArgumentError (bad options, fillInterior with Unsigned), InvalidMeshError
/// (empty mesh, NaN, bad index), ResourceLimitError (band too large), InterruptedError.
/// @param[in]  mesh     the surface, world units, counter-clockwise seen from outside; degenerate
///                      (zero-area) triangles are skipped
/// @param[in]  options  voxel size or count, band widths (voxels or world units), grid name,
///                      voxel budget, interrupter, sign mode, fill (see MeshToLevelSetOptions)
/// @param[out] stats    optional: counters and stage times of this run
/// @return a GRID_LEVEL_SET FloatGrid (GRID_UNKNOWN when unsigned) named options.gridName, with
///         a linear transform of the resolved voxel size; values in world units, negative
///         inside, background exteriorWidth * voxelSize
/// @throws InvalidArgumentError bad options (voxel size, voxel count, band widths, winding
///         accuracy, fillInterior with SignMode::Unsigned)
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
