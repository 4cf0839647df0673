// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief T4 scan conversion: triangle mesh → narrow-band signed distance FloatGrid by
/// slicing tetrahedral shells with the z-planes of the grid.
///
/// Paper: K. Erleben, H. Dohlmann, "Scan Conversion of Signed Distance Fields", Figures 8–9:
///   1. shell: tetrahedra around every face, tagged with the face (TetrahedralShell.h, §3.3–3.5),
///      built in index space with eps = max(exteriorWidth, interiorWidth) voxels;
///   2. sweep: tetrahedra sorted by min z; for each z-slab of the grid (slabDepth planes) the
///      active set comes from a sweep line (add by min z, drop by max z); each active tetrahedron
///      is cut by each plane of the slab into a convex polygon (cases A, B, C of §3.1), and the
///      polygons of one face's tetrahedra are merged into their convex hull — exactly the slice
///      of the face's shell, which is convex — so each (face, plane) is rasterized once;
///   3. the polygons are binned into dense slabs (slabDepth x slabWidth x slabWidth voxels, leaf
///      aligned) and a SlabBackend (DenseSlab.h; CpuSlabBackend by default) fills each slab with the
///      exact distance to the polygon's source triangle at every covered voxel centre, signed by
///      the angle-weighted pseudonormal of the closest feature (the triangle-frame case analysis
///      of §3.2 is closestPointOnTriangle's Voronoi classification), min-combined;
///   4. slabs are scattered into the sparse tree; voxels with -interiorWidth < d/h < exteriorWidth
///      become active; signed flood fill.
///
/// What is exact: every active voxel holds the exact distance (double, stored as float) to a
/// triangle whose shell covers it, and the min over those triangles. Where the voxel is covered
/// by the shell of its true closest triangle — always with ShellCoverage::Complete (the default),
/// where every shell contains the whole eps-neighbourhood of its face — the value and sign equal
/// ExactReference and meshToLevelSet (Chang), and no voxel of the band is missing. With
/// ShellCoverage::Paper the pseudonormal-family shells (PseudoNormal, Thin, Offset) are the paper's
/// hulls, and voxels near |d| = eps outside the shell of their closest triangle may be missing or
/// hold a larger distance — and then the sign — of a neighbour (see TetrahedralShell.h and
/// docs/scan-conversion.md). Sign: pseudonormal rule of the closest feature, so with Obb there are
/// no plane-test or construction leaks (§2) on closed, consistently oriented meshes; a fold
/// (flipped triangle) is wrong by construction of its pseudonormals — there is no fix in the paper.
/// Results do not depend on the number of threads.
#pragma once

#include <levelforge/core/GridSpec.h>
#include <levelforge/scan/DenseSlab.h>
#include <levelforge/scan/TetrahedralShell.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <string>

namespace levelforge {

/// @brief Options of meshToLevelSetScan().
///
/// GridSpec gives the voxel size or count, the band widths (voxels or world units; rounded to
/// float after conversion to voxels), the grid name, the voxel budget (estimate: surface area in
/// voxels² × band width, as meshToLevelSet; it also bounds the rasterization work) and the
/// interrupter.
struct TetScanOptions : GridSpec
{
    ShellMethod shell = ShellMethod::Obb;
    /// Complete (default): every shell covers the eps band (exact result); Paper: the paper's hulls.
    ShellCoverage coverage = ShellCoverage::Complete;
    /// Slab size in voxels: z planes per slab and xy edge, multiples of 8 (VDB leaf aligned).
    int slabDepth = 8;
    int slabWidth = 32;
    /// Conservative rasterization (Hasselgren et al., cited in §3.3): a voxel is covered when its
    /// cell (the unit cube around its centre) intersects the tetrahedron, instead of when its
    /// centre lies inside. The slice polygon becomes the projection of the tetrahedron clipped to
    /// [z - 1/2, z + 1/2], Minkowski-summed with the unit square. A grid-fixed enlargement (no
    /// tuning parameter); it closes sub-voxel gaps of the pseudonormal-family shells at the cost
    /// of more rasterized voxels. It cannot change a value that is exact already (values are
    /// min-combined exact distances). Default off: centres are tested exactly.
    bool conservative = false;
    /// Backend that fills the slabs; nullptr: a CpuSlabBackend. Not owned.
    const SlabBackend* backend = nullptr;
};

/// @brief Counters in the spirit of the paper's Figures 20–28.
struct TetScanStats
{
    double voxelSize = 0.0;
    ShellMethod shell = ShellMethod::Obb;
    ShellCoverage coverage = ShellCoverage::Complete;
    uint64_t triangles = 0, skippedDegenerate = 0;
    uint64_t tetrahedra = 0;
    uint64_t limitedExtrusions = 0; ///< Thin shell: faces shortened below eps
    uint64_t crossSections = 0;     ///< (face, plane) polygons: the merged cuts of a face's tetrahedra
    uint64_t slabItems = 0;         ///< polygons handed to slabs (a polygon may touch several)
    uint64_t slabs = 0;
    uint64_t voxelsRasterized = 0;  ///< (voxel, polygon) evaluations
    uint64_t activeVoxels = 0;
    double secondsShell = 0, secondsSort = 0, secondsSweep = 0, secondsFill = 0, secondsFinish = 0;
    /// The slab backend (set by the pipeline, meshToSdf()): "cpu" or "vulkan: <device>"; why
    /// the CPU when `auto` fell back.
    std::string device = "cpu";
    std::string deviceNote;
    /// @brief Tetrahedra per non-degenerate face.
    /// @return tetrahedra / triangles, or 0 when there are no triangles
    double tetrahedraPerFace() const { return triangles ? double(tetrahedra) / double(triangles) : 0.0; }
    /// @brief Voxels rasterized per output voxel (the overlap the paper's Figure 20 pays for).
    /// @return voxelsRasterized / activeVoxels, or 0 when there are no active voxels
    double overlapFactor() const { return activeVoxels ? double(voxelsRasterized) / double(activeVoxels) : 0.0; }
};

/// @brief The class behind meshToLevelSetScan(): holds the mesh (by reference) and the options;
///        each run() builds the shell, sweeps and fills anew.
class TetScanConverter
{
public:
    /// @brief Stores the inputs; nothing is checked or computed until run().
    /// @param[in] mesh     the surface, world units; kept by reference, it must outlive the converter
    /// @param[in] options  the options (copied)
    TetScanConverter(const TriangleMesh& mesh, const TetScanOptions& options);
    /// @brief Builds the shell, sweeps, fills slabs, returns the grid (see the file comment).
    /// @param[out] stats  optional: counters and stage times of this run
    /// @return a GRID_LEVEL_SET FloatGrid named options.gridName, with a linear transform of the
    ///         resolved voxel size; values in world units, negative inside
    /// @throws InvalidArgumentError bad options (voxel size, band widths, slab sizes not
    ///         multiples of 8 in [8, 512])
    /// @throws InvalidMeshError empty mesh, NaN/Inf coordinate, bad index
    /// @throws ResourceLimitError index coordinates out of range, band larger than maxVoxels
    /// @throws InterruptedError the interrupter asked to stop
    openvdb::FloatGrid::Ptr run(TetScanStats* stats = nullptr);

private:
    const TriangleMesh& mMesh;
    TetScanOptions mOptions;
};

/// @brief Converts a triangle mesh to a narrow-band level set by T4 scan conversion.
///
/// Throws InvalidArgumentError (bad options), InvalidMeshError (empty mesh, NaN, bad index),
/// ResourceLimitError (index coordinates out of range, band larger than maxVoxels),
/// InterruptedError (polled per slab, from inside the parallel loops).
/// @param[in]  mesh     the surface, world units, counter-clockwise seen from outside; degenerate
///                      (zero-area) triangles get no shell
/// @param[in]  options  grid spec, shell method and coverage, slab sizes, conservative
///                      rasterization, backend (see TetScanOptions)
/// @param[out] stats    optional: counters and stage times of this run
/// @return a GRID_LEVEL_SET FloatGrid named options.gridName, with a linear transform of the
///         resolved voxel size; values in world units, negative inside, background
///         exteriorWidth * voxelSize
/// @throws InvalidArgumentError bad options (voxel size, band widths, slab sizes)
/// @throws InvalidMeshError empty mesh, NaN/Inf coordinate, bad index
/// @throws ResourceLimitError index coordinates out of range, band larger than maxVoxels
/// @throws InterruptedError polled per slab, from inside the parallel loops
openvdb::FloatGrid::Ptr meshToLevelSetScan(const TriangleMesh& mesh, const TetScanOptions& options = {},
                                           TetScanStats* stats = nullptr);

} // namespace levelforge
