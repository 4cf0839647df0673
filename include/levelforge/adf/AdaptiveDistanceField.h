// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Adaptively sampled distance fields on the VDB tile hierarchy: triangle mesh → ADF
///        (a FloatGrid with a C0 trilinear reconstruction), queries, ADF → level set, CSG.
///
/// Algorithm: Yin, Liu, Wu, "Fast Computing Adaptively Sampled Distance Field on GPU", Pacific
/// Graphics 2011, on the CPU with TBB, with the paper's bit-pyramid octree replaced by the VDB
/// tree itself (no dense bit arrays):
///
///   index space   sample (i,j,k) lies at world (i,j,k)·h (h = finest voxel size); the finest
///                 cell c = [c, c+1)³ has the 8 samples c + {0,1}³ as corners. (The mesh is
///                 voxelized with cell space q = p/h, so boundary cells are exactly these cells.)
///   octree        M  = boundary cells (TriangleListTree: cells a triangle overlaps, §4.1);
///                 M' = M dilated by one cell (26-neighbourhood), so that every corner of a cell
///                 of M is surrounded by finest cells and never lies on a coarse cell's face.
///                 Node sizes 1, 2, 4 live inside an 8³ VDB leaf (a node is subdivided when it
///                 holds a cell of M'); an unsubdivided 8³ block is a level-1 tile; a 128³ block
///                 is an internal-1 node when it or one of its 26 neighbours holds a leaf
///                 (grading: leaves never touch a 128³ cell), else a level-2 tile. Marking
///                 bottom-up is just VDB topology.
///   samples (§5.2)
///     type-1      corners of cells of M: exact distance, angle-weighted pseudonormal sign,
///                 searching the 4×4×4 cells around the sample (§6.1) nearest-first;
///     type-2      the other free corners inside a leaf: the distance to the triangles listed
///                 in the leaf's gathered region (the 8³ leaf ± 4 cells; §6.2's block strategy:
///                 one gather of the (n+8)³ lists is shared by the leaf's 512 samples, like the
///                 paper's 8 lists of a level-1 node in §7.1). Exact when the nearest listed
///                 triangle is within the 4 cells (a closer one would be listed); otherwise d
///                 lies in [max(4, e − √3/2), min(d̃, e + √3/2)] voxels (e: the type-3 rule) and
///                 the midpoint is stored, so |error| ≤ √3/2 voxel (stats.type2MaxBoundVoxels);
///                 sign: the pseudonormal of the nearest listed point (the segment to it stays
///                 in the convex region, so it crosses no triangle first);
///     type-3      corners of level-1 and level-2 tiles: distance to the nearest centre of a cell
///                 of M (§7.2, searched over all of M, not only the siblings), so
///                 |d̃ − d| ≤ √3/2 voxel; the sign is copied from the type-1 samples (a signed
///                 flood fill of the type-1 band, which generalises §7.2's corner rule and is
///                 right for every sample of a closed mesh).
///   continuity    a corner of a small cell lying on the face or edge of a larger neighbour
///                 ("hanging") takes the larger cell's trilinear value (coarsest cell first), so
///                 the trilinear reconstruction is C0 everywhere, also across level changes.
///                 Type-1 samples are never hanging (that is what the dilation M' is for).
///   storage       one FloatGrid, transform h: leaf voxels hold the lattice values of their
///                 block (all 512, hanging ones already resolved), active voxels = the cells of
///                 M' (the refinement pattern); a level-1 tile holds the value at its minimum
///                 corner, a level-2 tile likewise. One layer of tiles past the domain's maximum
///                 faces stores the last corners. Metadata meta::kAdf etc. (core/Metadata.h).
///   error         what is exact: type-1 samples (double, stored as float). What is
///                 approximate: type-2/3 samples (bounds above) and the trilinear reconstruction
///                 between samples. The builder states a bound per level, and proves it: for
///                 every cell it evaluates the reconstruction rec at the 27 points of the cell's
///                 half-size grid (corners + Frisken's 19 test points: centre, face and edge
///                 midpoints, Frisken et al. 2000, below) against the level's sample function
///                 f (type-2 rule inside leaves, type-3 rule in tiles), adds f's own bound, and
///                 adds (1 + max|∇rec|)·(√3/4)·size for the points in between (every point of the
///                 cell is within (√3/4)·size of one of the 27; d is 1-Lipschitz and the gradient
///                 of a trilinear function is bounded by its edge differences). The bound is
///                 loose for big cells (a 128³ cell cannot do better than ~55 voxels), tight near
///                 the surface; measured errors are reported next to it (docs/adf.md).
///                 Refinement mode (toleranceVoxels > 0): tiles failing Frisken's criterion
///                 (|rec − f| > tolerance at one of the 19 test points) are subdivided (level-2 →
///                 level-1 tiles → a leaf of finest cells) until every tile passes.
/// Distances are signed world units, negative inside. The sign is exact for closed,
/// consistently oriented meshes (as in MeshToLevelSet.h). Queries outside the domain return the
/// value at the nearest domain point plus the distance to it (an upper bound of |d|).
///
/// References: K. Yin, Y. Liu, E. Wu, "Fast Computing Adaptively Sampled Distance Field on
/// GPU", Pacific Graphics 2011; S. F. Frisken, R. N. Perry, A. P. Rockwood,
/// T. R. Jones, "Adaptively Sampled Distance Fields: A General Representation of Shape for
/// Computer Graphics", SIGGRAPH 2000.
#pragma once

#include <levelforge/core/CsgOperation.h>
#include <levelforge/core/GridSpec.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/levelset/LevelSetCsg.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <cstdint>
#include <string>

namespace levelforge {

/// Options of meshToAdaptiveDistanceField(). From GridSpec it reads voxelSize / voxelCount (the
/// finest voxel size h; voxelCount counts finest voxels along the longest axis of the mesh
/// bounding box, the paper's "resolution"), gridName (default "adf"), maxVoxels (the dense
/// equivalent of the domain, default 64 Gi; 0 = no limit) and interrupter. The ADF covers a
/// padded domain, not a band: exteriorWidth, interiorWidth and units are ignored.
struct AdaptiveDistanceFieldOptions : GridSpec
{
    AdaptiveDistanceFieldOptions()
    {
        gridName = "adf";
        maxVoxels = 64ull << 30;
    }
    /// Margin of the domain around the mesh bounding box, finest voxels (>= 0). The domain is
    /// then rounded out to whole 128³ blocks.
    double paddingVoxels = 8.0;
    /// Refinement mode (Frisken): 0 = off (the paper's fixed sampling). > 0: tiles whose
    /// reconstruction deviates from the type-3 function by more than this at a test point are
    /// subdivided. Voxels.
    double toleranceVoxels = 0.0;
    /// Compute the per-level stated bound (AdaptiveDistanceFieldStats::levelBoundVoxels). It
    /// costs about one extra type-2 pass; refinement mode always checks the tiles.
    bool computeBounds = true;
    /// Check every boundStride-th finest cell only (1 = all, a proof; > 1: a measurement).
    int boundStride = 1;
};

/// Levels of the reconstruction: cell sizes 1, 2, 4, 8 (level-1 tile), 128 (level-2 tile).
constexpr int kAdfLevels = 5;
constexpr int kAdfCellSize[kAdfLevels] = {1, 2, 4, 8, 128};

/// The paper's Table 1 and memory figures, filled by meshToAdaptiveDistanceField().
struct AdaptiveDistanceFieldStats
{
    double voxelSize = 0.0;
    uint64_t triangles = 0;
    uint64_t boundaryCells = 0;            ///< |M|
    uint64_t leaves = 0, level1Tiles = 0, level2Tiles = 0;
    uint64_t type1 = 0, type2 = 0, type3 = 0, hanging = 0; ///< sample counts
    uint64_t type2Wide = 0;                ///< type-2 samples beyond the gather radius (certified by the type-3 rule)
    uint64_t refinedTiles = 0;             ///< tiles subdivided by the refinement mode
    std::array<uint64_t, kAdfLevels> cells{};           ///< reconstruction cells per level
    /// Stated bound per level, voxels: for every cell of the level (every boundStride-th finest
    /// cell), max |rec - f| over its 27 test points and corners + f's own bound + the Lipschitz
    /// term (1 + max|∇rec|)·(√3/4)·size, which covers the points between (d is 1-Lipschitz).
    /// -1 when the level is empty or bounds were not computed.
    std::array<double, kAdfLevels> levelBoundVoxels{{-1, -1, -1, -1, -1}};
    /// Frisken's criterion alone: max |rec - f| + f's bound at the 19 test points, voxels.
    std::array<double, kAdfLevels> levelTestPointVoxels{{-1, -1, -1, -1, -1}};
    double type2MaxBoundVoxels = 0.0;      ///< largest type-2 certificate, voxels
    uint64_t domainVoxels = 0;             ///< dense equivalent (finest voxels in the domain)
    uint64_t memoryBytes = 0;              ///< grid tree memUsage()
    /// Wall-clock seconds, as in Table 1.
    double secondsVoxelize = 0, secondsOctree = 0, secondsType1 = 0, secondsType2 = 0,
           secondsType3 = 0, secondsFinish = 0, secondsBounds = 0;
    /// @brief Sum of the stage times, seconds.
    double secondsTotal() const
    {
        return secondsVoxelize + secondsOctree + secondsType1 + secondsType2 + secondsType3 +
               secondsFinish + secondsBounds;
    }
};

/// A continuous signed distance field reconstructed from an ADF grid (see the file comment).
/// Cheap to copy (shares the grid). Queries are thread-safe.
class AdaptiveDistanceField
{
public:
    AdaptiveDistanceField() = default;
    /// @brief Wraps a grid written by this class (e.g. read from a .vdb).
    /// @param[in] grid  an ADF grid (isAdaptiveDistanceField)
    /// @throws InvalidArgumentError if the grid is null, not an ADF, or its metadata is
    ///         inconsistent (no domain, a domain not made of whole 128³ blocks, a non-linear
    ///         transform or non-cubic voxels), or its tree is not an ADF layout (leaves outside
    ///         the domain, a block holding leaves next to one that is not subdivided, ...: one
    ///         pass over the tree, so that no query can recurse without end)
    explicit AdaptiveDistanceField(openvdb::FloatGrid::ConstPtr grid);

    /// @brief False for a default-constructed (empty) ADF.
    bool valid() const { return bool(mGrid); }
    /// @brief The ADF grid (see the file comment for its layout).
    openvdb::FloatGrid::ConstPtr grid() const { return mGrid; }
    /// @brief The finest voxel edge length h, world units.
    double voxelSize() const { return mH; }
    /// @brief Domain of the reconstruction, index space (sample lattice, inclusive).
    const openvdb::CoordBBox& indexDomain() const { return mDomain; }
    /// @brief Domain of the reconstruction, world units.
    openvdb::BBoxd worldDomain() const;

    /// @brief Signed distance at a world point (C0 trilinear reconstruction).
    /// @param[in] worldPoint  the point, world units; outside the domain the result is the value
    ///                        at the nearest domain point plus the distance to it
    /// @return the signed distance, world units, negative inside
    double distance(const Vec3d& worldPoint) const;
    /// @brief Gradient of the reconstruction in the cell holding the point.
    /// @param[in] worldPoint  the point, world units
    /// @return the gradient, world units per world unit
    Vec3d gradient(const Vec3d& worldPoint) const;
    /// @brief Level of the cell holding the point.
    /// @param[in] worldPoint  the point, world units
    /// @return the index into kAdfCellSize; -1 outside the domain
    int level(const Vec3d& worldPoint) const;
    /// @brief Stated bound of a level (metadata meta::kAdfBoundLevelPattern).
    /// @param[in] level  index into kAdfCellSize
    /// @return the bound, voxels; -1 if unknown
    double levelBoundVoxels(int level) const { return mBounds[size_t(level)]; }

    /// @brief Value of a lattice point, hanging points resolved.
    /// @param[in] ijk  the lattice point (index space), inside the domain
    /// @return the signed distance, world units
    double latticeValue(const openvdb::Coord& ijk) const;

private:
    openvdb::FloatGrid::ConstPtr mGrid;
    double mH = 1.0;
    openvdb::CoordBBox mDomain;
    std::array<double, kAdfLevels> mBounds{{-1, -1, -1, -1, -1}};
};

/// @brief Builds the ADF of a mesh (see the file comment).
/// @param[in]  mesh     the triangle mesh, world units; closed and consistently oriented for an
///                      exact sign
/// @param[in]  options  finest voxel size or count, padding, refinement, bounds, grid name,
///                      voxel budget, interrupter
/// @param[out] stats    if not null: the counts, bounds and stage times
/// @return the ADF (grid named options.gridName, linear transform of voxel size h)
/// @throws InvalidArgumentError for a bad voxel size or count, padding or tolerance;
/// @throws InvalidMeshError for an unusable mesh (requireUsableMesh) or one whose triangles
///         are all degenerate;
/// @throws ResourceLimitError if the domain exceeds options.maxVoxels or the index coordinates
///         would exceed 1e9;
/// @throws InterruptedError if the interrupter asks to stop.
AdaptiveDistanceField meshToAdaptiveDistanceField(const TriangleMesh& mesh,
                                                  const AdaptiveDistanceFieldOptions& options = {},
                                                  AdaptiveDistanceFieldStats* stats = nullptr);

/// @brief Whether a grid is an ADF written by this header's builders.
/// @param[in] grid  any grid
/// @return true if it is a FloatGrid carrying the meta::kAdf metadata
bool isAdaptiveDistanceField(const openvdb::GridBase& grid);

/// @brief An ordinary narrow-band level set sampled from the ADF at the voxel centres i·h.
/// @param[in] adf              the ADF
/// @param[in] halfWidthVoxels  band half-width, finest voxels (> 0): the voxels with
///                             |d| < halfWidthVoxels·h are active
/// @return a GRID_LEVEL_SET grid on the ADF's transform, background halfWidthVoxels·h, signed
///         flood filled
/// @throws InvalidArgumentError for an empty ADF or a half-width that is not a positive number
openvdb::FloatGrid::Ptr adaptiveDistanceFieldToLevelSet(const AdaptiveDistanceField& adf,
                                                        double halfWidthVoxels = 3.0);

/// @brief CSG of two ADFs, as in the paper's Figure 10: min(a, b), max(a, b), max(a, −b).
///
/// The result's cells are the finer of the two at every place, its samples are op(a, b) at the
/// result's lattice points, hanging points resolved again (C0). Its stated bounds are the
/// larger of the inputs'.
/// @param[in] a   the first ADF; its grid name is the result's
/// @param[in] b   the second ADF, with the same voxel size and lattice (the transforms agree)
/// @param[in] op  the operation (core/CsgOperation.h)
/// @return the ADF of op(a, b)
/// @throws InvalidArgumentError for an empty input or mismatched transforms
AdaptiveDistanceField csgAdaptiveDistanceFields(const AdaptiveDistanceField& a,
                                                const AdaptiveDistanceField& b, CsgOperation op);

} // namespace levelforge
