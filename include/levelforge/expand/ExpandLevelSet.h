// levelforge — widen a narrow-band level set by fast sweeping on sparse VDB topology.
//
// Algorithm: Zhao, "A fast sweeping method for Eikonal equations", Math. Comp. 74 (2005), used
// as Chang, Cha & Ihm (CGF 2008, §5.3) use it: the exact narrow band of meshToLevelSet() is the
// boundary condition, every new voxel gets its sign first (signed flood fill of the input), then
// Gauss–Seidel sweeps in the 2^3 = 8 alternating orderings solve |∇φ| = 1 with the first-order
// Godunov upwind discretisation
//     [(φ - a_x)^+]^2 + [(φ - a_y)^+]^2 + [(φ - a_z)^+]^2 = h^2,  a_k = min(φ(x - e_k), φ(x + e_k))
// (magnitudes, on each side of the surface), taking φ_new = min(φ_old, solution).
//
// Sparse: the sweeps visit only the active voxels of the candidate VDB tree, never a dense box.
// Schedule (leaf-level marching, in the spirit of Chacon & Vladimirsky's heap-cell method): a
// leaf node (8^3 voxels) is processed when it has pending input — new values on a neighbouring
// face, or its own fixed values at the start — and processing it means Gauss–Seidel sweeps of
// its voxels until none of them is dirty (below). The first ordering runs along each axis away
// from the halo face with the smaller minimum; each next one reverses the axes along which a
// change marked an already visited voxel. Leaves are taken roughly in order of their smallest
// pending input value (the key): each step processes the leaves whose key is below the
// smallest key + 8 voxels, skipping a leaf while a face neighbour has a smaller key, until none
// is left. Within a step the leaves go in two phases by the parity of I + J + K (I, J, K: leaf
// coordinates); two leaves of one parity never share a face and the Godunov stencil only reads
// face neighbours, so each phase processes its leaves in parallel (TBB), every leaf seeing the
// same values whatever the thread count, and the phases, steps and keys are computed serially:
// the result is bit-identical for any number of threads. Any such order of Gauss–Seidel
// min-updates converges to the same discrete fixed point (up to the tolerance below).
//
// Work saved (none of it changes what a voxel's update computes):
// - per-voxel dirty bits: a voxel is re-evaluated only when a face neighbour changed since its
//   last evaluation in a way its update can see: a change to value u marks a neighbour q only
//   when u is below |φ_q| and below q's other neighbour on the same axis (q's upwind value on
//   that axis is the smaller of the two, so otherwise it stays the same bit for bit); leaves with
//   both signs mark every neighbour. Changes of at most the tolerance are not passed on
//   (rounding creep would otherwise ripple through the band; measured effect on the error
//   columns: none at 4 decimals).
// - capped values: a voxel whose solution is not below the kept width on its side (see below)
//   stays unreached — it would be trimmed anyway, and no voxel below the cap depends on it (the
//   Godunov solution only reads neighbour values below itself).
// - single-precision update with the discriminants written as sums of squared differences
//   (2h² − (a1 − a0)², 3h² − Σ (ai − aj)²), so nothing cancels.
// The sweeps stop when no leaf has pending input (converged), or when only leaves already
// processed maxIterations times have.
//
// Topology (Euclidean-complete): a voxel whose exact distance d is below the target width w
// lies within Euclidean distance R = w - w0 + √3 (voxels) of a voxel of the input band of
// half-width w0. The sweep's candidates are whole leaf nodes: every leaf whose box comes closer
// than R to the bounding box of some input leaf's active voxels (one pass over a dense grid of
// leaf cells; a superset of the Euclidean dilation, the cap keeps the extra voxels unreached).
// The Vector method, and inputs whose grid of leaf cells would exceed 2^24 cells (about 2048^3
// voxels), instead dilate the band
// by a sequence of a 26-neighbour and b 6-neighbour steps whose lattice Minkowski sum (cube of
// half-side a + octahedron of radius b) contains the Euclidean ball of radius R — much tighter
// than a cube (a = R), never missing a diagonal voxel. After the sweeps a voxel stays active
// iff |φ| < w + margin (1 voxel + 2.5 % of the swept distance by default): the first-order
// solution overestimates the distance where characteristics spread (outside convex parts), and
// the margin keeps every voxel with d < w active (checked against the exact reference in tests
// and benchmarks; it is an empirical bound, not a proof).
//
// What is exact and what is approximate: the voxels of the input band keep their (exact) values
// bit for bit. The new voxels hold the first-order Godunov solution, which satisfies |∇φ| ≈ 1 but
// is not the Euclidean distance: it is exact for planes, and elsewhere its error grows slowly
// with the distance from the frozen band (measured in docs/expansion.md against the exact
// reference: mean 0.05–0.15 voxel and max ≈ 1 voxel when sweeping 3 → 20 voxels, mean
// 0.15–0.43 and max ≈ 1.5 voxels for 3 → 60; equal to openvdb::tools::dilateSdf on the voxels
// both produce). For exact distances in a wide band, call
// meshToLevelSet() with the wide band directly (`--expansion exact`).
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge {

/// How the new voxels get their values.
enum class ExpansionMethod
{
    Sweep, ///< fast sweeping: first-order Godunov solution of |∇φ| = 1 (this header)
    Vector ///< closest-point vectors propagated by the sparse 8-pass VCVDT (VectorExpansion.h)
};

/// What the expanded level set covers.
enum class ExpansionDomain
{
    Band,        ///< a band of exteriorWidth / interiorWidth around the surface
    BoundingBox  ///< every voxel of the input's active bounding box grown by boundingBoxMargin
};

/// Units of ExpandLevelSetOptions::exteriorWidth / interiorWidth / boundingBoxMargin.
enum class WidthUnits
{
    Voxels,
    World
};

struct ExpandLevelSetOptions
{
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
    const TriangleMesh* mesh = nullptr;
    /// Target half-width of the band outside the surface (units: `units`); Houdini's
    /// VDB Activate SDF "Exterior Band". Must be finite and > 0.
    double exteriorWidth = 20.0;
    /// Target half-width of the band inside the surface (units: `units`). Finite and > 0.
    double interiorWidth = 20.0;
    WidthUnits units = WidthUnits::Voxels;
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
    /// "levelforge:exterior_band_voxels" / "levelforge:interior_band_voxels" metadata, else
    /// background / voxel size.
    double inputExteriorWidth = 0.0;
    double inputInteriorWidth = 0.0;
    /// Changes of at most this (voxels, > 0) are not passed on to the neighbours; the sweeps
    /// stop when no change above it is pending.
    double tolerance = 1e-4;
    /// Sweep: each leaf node is processed (swept until it has no dirty voxel) at most this many
    /// times (>= 1); typically up to 4–6 times.
    int maxIterations = 50;
    /// Refuse (ResourceLimitError) to build grids with more active voxels than this; 0 = no limit.
    uint64_t maxVoxels = 2'000'000'000ull;
    /// Optional progress / interruption (OpenVDB convention). Not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

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

/// Returns a new level set: `input`'s band widened (or narrowed) as `options` say; see the file
/// comment. `input` must be a level set (GRID_LEVEL_SET or unknown class, uniform voxels,
/// background > 0, at least one active voxel, inactive values signed like a flood-filled level
/// set). The result has the same transform, name and metadata, class GRID_LEVEL_SET, and
/// background = the larger kept width (world units); inactive values are ±background.
/// Throws InvalidArgumentError (bad options or input), ResourceLimitError (more than
/// maxVoxels), InterruptedError.
openvdb::FloatGrid::Ptr expandLevelSet(const openvdb::FloatGrid& input,
                                       const ExpandLevelSetOptions& options = {},
                                       ExpandLevelSetStats* stats = nullptr);

namespace fast_sweeping_internal {
/// Smallest (cube steps a, face steps b) with a + b minimal such that every lattice point at
/// Euclidean distance < radius (voxels) from the origin is reached by a 26-neighbour steps
/// followed by b 6-neighbour steps; among those, the smallest a (fewest extra voxels).
void dilationPattern(double radius, int& cubeSteps, int& faceSteps);
} // namespace fast_sweeping_internal

} // namespace levelforge
