// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The front door of level-set expansion: widen (or narrow) the band of a narrow-band
///        level set on sparse VDB topology, by fast sweeping or by closest-point vectors.
///
/// Two methods give the new voxels their values (ExpandLevelSetOptions::method):
///  - ExpansionMethod::Sweep: H. Zhao, "A fast sweeping method for Eikonal equations" (2005),
///    the first-order Godunov solution of |∇φ| = 1 from the frozen input band (src/expand/FastSweeping.h);
///  - ExpansionMethod::Vector: closest-point vectors propagated by the 8-pass vector-city vector
///    distance transform of R. Satherley and M. W. Jones, "Vector-City Vector Distance
///    Transform" (2001), over the VDB leaves, optionally refined to exact distances to the
///    closest triangles (docs/expansion.md).
/// Both keep the voxels of the input band bit for bit, work only on the active voxels of the
/// candidate topology (never a dense box), and give results that do not depend on the thread
/// count.
///
/// Topology (Euclidean-complete): a voxel whose exact distance d is below the target width w
/// lies within Euclidean distance R = w - w0 + √3 (voxels) of a voxel of the input band of
/// half-width w0. The Sweep method's candidates are whole leaf nodes near the band
/// (src/expand/FastSweeping.h); the Vector method, and the Sweep method on inputs whose grid of leaf cells
/// would exceed 2^24 cells (about 2048^3 voxels), instead dilate the band by a sequence of a
/// 26-neighbour and b 6-neighbour steps whose lattice Minkowski sum (cube of half-side a +
/// octahedron of radius b) contains the Euclidean ball of radius R — much tighter than a cube
/// (a = R), never missing a diagonal voxel (fast_sweeping_internal::dilationPattern()).
///
/// Coverage: after the expansion a voxel stays active iff |φ| < w + margin (coverageMargin
/// voxels, plus for Sweep coverageMarginPerVoxel times the swept distance; by default 1 voxel +
/// 2.5 %): the first-order solution overestimates the distance where characteristics spread
/// (outside convex parts), and the margin keeps every voxel with d < w active (checked against
/// the exact reference in tests and benchmarks; it is an empirical bound, not a proof).
///
/// Each method is described in its private header (src/expand/FastSweeping.h, src/expand/VectorExpansion.h); its accuracy is measured in docs/expansion.md.
#pragma once

#include <levelforge/core/GridSpec.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge {

/// How the new voxels get their values.
enum class ExpansionMethod
{
    Sweep, ///< fast sweeping: first-order Godunov solution of |∇φ| = 1 (src/expand/FastSweeping.h)
    Vector ///< closest-point vectors propagated by the sparse 8-pass VCVDT (docs/expansion.md)
};

/// What the expanded level set covers.
enum class ExpansionDomain
{
    Band,        ///< a band of exteriorWidth / interiorWidth around the surface
    BoundingBox  ///< every voxel of the input's active bounding box grown by boundingBoxMargin
};

/// Options of expandLevelSet().
///
/// From GridSpec: exteriorWidth / interiorWidth (the TARGET widths, in `units`; 20 voxels by
/// default), units (also of boundingBoxMargin), maxVoxels (limit on the active voxels of the
/// result and of the candidate topology) and interrupter. Not used: the result keeps the input
/// grid's voxel size and name, so voxelSize and voxelCount must stay 0 (InvalidArgumentError
/// otherwise) and gridName is ignored.
struct ExpandLevelSetOptions : GridSpec
{
    /// The expansion defaults: target widths of 20 voxels on each side.
    ExpandLevelSetOptions()
    {
        exteriorWidth = 20.0;
        interiorWidth = 20.0;
    }

    /// Sweep (Zhao's fast sweeping) or Vector (Satherley–Jones VCVDT over VDB leaves).
    ExpansionMethod method = ExpansionMethod::Sweep;
    /// Vector method only (optional, not owned): for the voxels of the input band, the offset
    /// from the voxel centre to the closest surface point, in voxels — as made by
    /// meshToLevelSetWithClosestPoints(). Without it the offsets are estimated from φ and ∇φ.
    const openvdb::Vec3fTree* closestPoints = nullptr;
    /// Vector method only (optional, with closestPoints and mesh; not owned): the closest
    /// triangle of every input band voxel (meshToLevelSetWithClosestPoints()). The triangle is
    /// carried with the vector, and each new voxel finally gets its exact distance to that
    /// triangle (never more than the propagated distance, never less than the true one).
    const openvdb::Int32Tree* closestTriangles = nullptr;
    /// Vector method only (with closestTriangles; not owned): the mesh the triangle indices
    /// refer to.
    const TriangleMesh* mesh = nullptr;
    // exteriorWidth (GridSpec): target half-width of the band outside the surface (units:
    // `units`); Houdini's VDB Activate SDF "Exterior Band". Must be finite and > 0.
    // interiorWidth (GridSpec): target half-width of the band inside the surface. Finite and > 0.
    /// Activate every interior voxel (Houdini's "Fill Interior"); interiorWidth is then ignored.
    bool fillInterior = false;
    ExpansionDomain domain = ExpansionDomain::Band;
    /// Margin around the input's active bounding box for ExpansionDomain::BoundingBox (units).
    double boundingBoxMargin = 10.0;
    /// Extra width kept beyond each target width so that no voxel whose exact distance is below
    /// the target is lost to first-order overestimation: coverageMargin voxels plus
    /// coverageMarginPerVoxel times the swept distance (target - input width, voxels). The
    /// overestimation grows with the distance swept (measured: up to 1.5 voxels after sweeping
    /// 57 voxels on the Armadillo); both >= 0. The Vector method's error does not grow with the
    /// distance, so it uses coverageMargin only.
    double coverageMargin = 1.0;
    double coverageMarginPerVoxel = 0.025;
    /// Half-widths of the input band, in voxels, where it is exact and complete; 0 = read the
    /// meta::kExteriorBandVoxels / meta::kInteriorBandVoxels metadata (core/Metadata.h), else
    /// background / voxel size.
    double inputExteriorWidth = 0.0;
    double inputInteriorWidth = 0.0;
    /// Changes of at most this (voxels, > 0) are not passed on to the neighbours; the sweeps
    /// stop when no change above it is pending.
    double tolerance = 1e-4;
    /// Sweep: each leaf node is processed (swept until it has no dirty voxel) at most this many
    /// times (>= 1); typically up to 4–6 times.
    int maxIterations = 50;
};

/// What expandLevelSet() did.
struct ExpandLevelSetStats
{
    double voxelSize = 0.0;          ///< world units
    double inputExteriorWidth = 0.0; ///< voxels (as resolved)
    double inputInteriorWidth = 0.0; ///< voxels
    int dilationCubeSteps = 0;       ///< 26-neighbour dilation steps (larger side; 0 with leaf candidates)
    int dilationFaceSteps = 0;       ///< 6-neighbour dilation steps (larger side; 0 with leaf candidates)
    uint64_t frozenVoxels = 0;       ///< input band voxels kept as the boundary condition
    uint64_t candidateVoxels = 0;    ///< active voxels of the swept domain (whole leaves for Sweep)
    uint64_t activeVoxels = 0;       ///< active voxels of the result
    uint64_t leafUpdates = 0;        ///< leaf-node passes performed (each sweeps the leaf until it has no dirty voxel)
    uint64_t voxelUpdates = 0;       ///< Godunov updates evaluated (voxels re-evaluated only when a neighbour changed)
    int iterations = 0;              ///< the most passes over any one leaf node
    double maxChange = 0.0;          ///< converged: the largest change not passed on to the neighbours (<= tolerance), voxels; else infinity
    bool converged = false;          ///< no change above the tolerance is left pending
    double secondsTopology = 0, secondsSweep = 0, secondsFinish = 0;
    ExpansionMethod method = ExpansionMethod::Sweep;
    uint64_t estimatedVectors = 0;   ///< Vector: shell vectors estimated from φ and ∇φ
    uint64_t unreachedVoxels = 0;    ///< Vector: candidates no vector reached (dropped)
    uint64_t refinedVoxels = 0;      ///< Vector: new voxels given the exact distance to their triangle
    uint64_t walkSteps = 0;          ///< Vector: greedy steps to closer edge-adjacent triangles
    uint64_t refineEvaluations = 0;  ///< Vector: exact point–triangle distances of the refinement
    int refineRounds = 0;            ///< Vector: neighbour rounds of the refinement
    /// Vector: set-up (shell vectors), the 8 raster passes (one thread), write-back + refinement.
    double secondsVectorSetup = 0, secondsVectorPasses = 0, secondsVectorFinish = 0;
};

/// @brief A new level set: the band of @p input widened (or narrowed) as @p options say (see the
///        file comment).
///
/// The result has the transform, name and metadata of @p input (the band-width metadata, where
/// present, updated to the new widths), class GRID_LEVEL_SET, and background = the larger kept
/// width (world units); inactive values are ±background.
/// @param[in]  input    a level set: GRID_LEVEL_SET or unknown class, uniform voxels,
///                      background > 0, at least one active voxel, inactive values signed like
///                      a flood-filled level set
/// @param[in]  options  method, target widths, domain, margins, limits (ExpandLevelSetOptions)
/// @param[out] stats    optional: topology, sweep and finish statistics
/// @return the expanded level set.
/// @throws InvalidArgumentError (bad options or input; voxelSize or voxelCount set);
/// @throws ResourceLimitError (a width beyond 1e5 voxels, or more active voxels than maxVoxels);
/// @throws InterruptedError.
openvdb::FloatGrid::Ptr expandLevelSet(const openvdb::FloatGrid& input,
                                       const ExpandLevelSetOptions& options = {},
                                       ExpandLevelSetStats* stats = nullptr);

} // namespace levelforge
