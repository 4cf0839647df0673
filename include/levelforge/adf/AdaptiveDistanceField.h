// levelforge — adaptively sampled distance fields on the VDB tile hierarchy.
//
// Algorithm: Yin, Liu, Wu, "Fast Computing Adaptively Sampled Distance Field on GPU", Pacific
// Graphics 2011 (../shared/papers/002_*), on the CPU with TBB, with the paper's bit-pyramid
// octree replaced by the VDB tree itself (no dense bit arrays):
//
//   index space   sample (i,j,k) lies at world (i,j,k)·h (h = finest voxel size); the finest
//                 cell c = [c, c+1)³ has the 8 samples c + {0,1}³ as corners. (The mesh is
//                 voxelized with cell space q = p/h, so boundary cells are exactly these cells.)
//   octree        M  = boundary cells (TriangleListTree: cells a triangle overlaps, §4.1);
//                 M' = M dilated by one cell (26-neighbourhood), so that every corner of a cell
//                 of M is surrounded by finest cells and never lies on a coarse cell's face.
//                 Node sizes 1, 2, 4 live inside an 8³ VDB leaf (a node is subdivided when it
//                 holds a cell of M'); an unsubdivided 8³ block is a level-1 tile; a 128³ block
//                 is an internal-1 node when it or one of its 26 neighbours holds a leaf
//                 (grading: leaves never touch a 128³ cell), else a level-2 tile. Marking
//                 bottom-up is just VDB topology.
//   samples (§5.2)
//     type-1      corners of cells of M: exact distance, angle-weighted pseudonormal sign,
//                 searching the 4×4×4 cells around the sample (§6.1) nearest-first;
//     type-2      the other free corners inside a leaf: the distance to the triangles listed
//                 in the leaf's gathered region (the 8³ leaf ± 4 cells; §6.2's block strategy:
//                 one gather of the (n+8)³ lists is shared by the leaf's 512 samples, like the
//                 paper's 8 lists of a level-1 node in §7.1). Exact when the nearest listed
//                 triangle is within the 4 cells (a closer one would be listed); otherwise d
//                 lies in [max(4, e − √3/2), min(d̃, e + √3/2)] voxels (e: the type-3 rule) and
//                 the midpoint is stored, so |error| ≤ √3/2 voxel (stats.type2MaxBoundVoxels);
//                 sign: the pseudonormal of the nearest listed point (the segment to it stays
//                 in the convex region, so it crosses no triangle first);
//     type-3      corners of level-1 and level-2 tiles: distance to the nearest centre of a cell
//                 of M (§7.2, searched over all of M, not only the siblings), so
//                 |d̃ − d| ≤ √3/2 voxel; the sign is copied from the type-1 samples (a signed
//                 flood fill of the type-1 band, which generalises §7.2's corner rule and is
//                 right for every sample of a closed mesh).
//   continuity    a corner of a small cell lying on the face or edge of a larger neighbour
//                 ("hanging") takes the larger cell's trilinear value (coarsest cell first), so
//                 the trilinear reconstruction is C0 everywhere, also across level changes.
//                 Type-1 samples are never hanging (that is what the dilation M' is for).
//   storage       one FloatGrid, transform h: leaf voxels hold the lattice values of their
//                 block (all 512, hanging ones already resolved), active voxels = the cells of
//                 M' (the refinement pattern); a level-1 tile holds the value at its minimum
//                 corner, a level-2 tile likewise. One layer of tiles past the domain's maximum
//                 faces stores the last corners. Metadata "levelforge:adf" etc. (see below).
//   error         what is exact: type-1 samples (double, stored as float). What is
//                 approximate: type-2/3 samples (bounds above) and the trilinear reconstruction
//                 between samples. The builder states a bound per level, and proves it: for
//                 every cell it evaluates the reconstruction rec at the 27 points of the cell's
//                 half-size grid (corners + Frisken's 19 test points: centre, face and edge
//                 midpoints, Frisken et al., SIGGRAPH 2000) against the level's sample function
//                 f (type-2 rule inside leaves, type-3 rule in tiles), adds f's own bound, and
//                 adds (1 + max|∇rec|)·(√3/4)·size for the points in between (every point of the
//                 cell is within (√3/4)·size of one of the 27; d is 1-Lipschitz and the gradient
//                 of a trilinear function is bounded by its edge differences). The bound is
//                 loose for big cells (a 128³ cell cannot do better than ~55 voxels), tight near
//                 the surface; measured errors are reported next to it (docs/adf.md).
//                 Refinement mode (toleranceVoxels > 0): tiles failing Frisken's criterion
//                 (|rec − f| > tolerance at one of the 19 test points) are subdivided (level-2 →
//                 level-1 tiles → a leaf of finest cells) until every tile passes.
// Distances are signed world units, negative inside. The sign is exact for closed,
// consistently oriented meshes (as in MeshToLevelSet.h). Queries outside the domain return the
// value at the nearest domain point plus the distance to it (an upper bound of |d|).
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <cstdint>
#include <string>

namespace levelforge {

struct AdaptiveDistanceFieldOptions
{
    /// Finest voxel edge length h, world units. If <= 0 (default) it is derived from voxelCount.
    double voxelSize = 0.0;
    /// Finest voxels along the longest axis of the mesh bounding box (the paper's "resolution"),
    /// used when voxelSize <= 0.
    int voxelCount = 0;
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
    std::string gridName = "adf";
    /// Refuse domains with more finest voxels than this (dense equivalent); 0 = no limit.
    uint64_t maxVoxels = 64ull << 30;
    openvdb::util::NullInterrupter* interrupter = nullptr;
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
    /// Wraps a grid written by this class (e.g. read from a .vdb). Throws InvalidArgumentError
    /// if the grid is not an ADF (isAdaptiveDistanceField) or its metadata is inconsistent.
    explicit AdaptiveDistanceField(openvdb::FloatGrid::ConstPtr grid);

    bool valid() const { return bool(mGrid); }
    openvdb::FloatGrid::ConstPtr grid() const { return mGrid; }
    double voxelSize() const { return mH; }
    /// Domain of the reconstruction, index space (sample lattice, inclusive) and world.
    const openvdb::CoordBBox& indexDomain() const { return mDomain; }
    openvdb::BBoxd worldDomain() const;

    /// Signed distance at a world point, world units (C0 trilinear reconstruction).
    double distance(const Vec3d& worldPoint) const;
    /// Gradient of the reconstruction (world units per world unit) in the cell holding the point.
    Vec3d gradient(const Vec3d& worldPoint) const;
    /// Level (index into kAdfCellSize) of the cell holding the point; -1 outside the domain.
    int level(const Vec3d& worldPoint) const;
    /// Stated bound per level (metadata "levelforge:adf_bound_level<k>_voxels"), -1 if unknown.
    double levelBoundVoxels(int level) const { return mBounds[size_t(level)]; }

    /// Value of the lattice point (index space), hanging points resolved. Inside the domain.
    double latticeValue(const openvdb::Coord& ijk) const;

private:
    friend struct AdfAccess;
    openvdb::FloatGrid::ConstPtr mGrid;
    double mH = 1.0;
    openvdb::CoordBBox mDomain;
    std::array<double, kAdfLevels> mBounds{{-1, -1, -1, -1, -1}};
};

/// Builds the ADF of a mesh (see the file comment). Throws InvalidArgumentError,
/// InvalidMeshError, ResourceLimitError, InterruptedError.
AdaptiveDistanceField meshToAdaptiveDistanceField(const TriangleMesh& mesh,
                                                  const AdaptiveDistanceFieldOptions& options = {},
                                                  AdaptiveDistanceFieldStats* stats = nullptr);

/// True if the grid carries the "levelforge:adf" metadata (written by this header's builders).
bool isAdaptiveDistanceField(const openvdb::GridBase& grid);

/// An ordinary narrow-band level set (GRID_LEVEL_SET, background = halfWidth·h, signed flood
/// filled) sampled from the ADF at the voxel centres i·h, band |d| < halfWidthVoxels·h.
openvdb::FloatGrid::Ptr adaptiveDistanceFieldToLevelSet(const AdaptiveDistanceField& adf,
                                                        double halfWidthVoxels = 3.0);

enum class CsgOperation { Union, Intersection, Difference };
/// "union", "intersection", "difference"; throws InvalidArgumentError for other names.
CsgOperation csgOperationFromString(const std::string& name);

/// CSG of two ADFs with the same voxel size (and lattice: the transforms must agree), as in
/// the paper's Figure 10 (Frisken & Perry): min(a, b), max(a, b), max(a, −b). The result's
/// cells are the finer of the two at every place, its samples are op(a, b) at the result's
/// lattice points, hanging points resolved again (C0). Its stated bounds are the larger of the
/// inputs'. Throws InvalidArgumentError for mismatched transforms.
AdaptiveDistanceField csgAdaptiveDistanceFields(const AdaptiveDistanceField& a,
                                                const AdaptiveDistanceField& b, CsgOperation op);

/// CSG of two level sets (same transform) with openvdb::tools::csg*Copy; the inputs are not
/// modified. Throws InvalidArgumentError for mismatched transforms or non-level-set grids.
openvdb::FloatGrid::Ptr csgLevelSets(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b,
                                     CsgOperation op);

namespace adf_internal {

/// Whether the builder's per-leaf sample pass runs its AVX2 build on this CPU (x86-64 with
/// AVX2). It is the same code in VEX encoding (no FMA, nothing contracted), so every value is
/// bit-identical to the baseline build's; only the speed differs.
bool avx2LeafPassAvailable();

/// Testing hook: false forces the baseline build of the leaf pass (process-wide; not for use
/// while a build runs on another thread).
void setAvx2LeafPassEnabled(bool enabled);

} // namespace adf_internal
} // namespace levelforge
