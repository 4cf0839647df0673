// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The fast sweeping method of expandLevelSet() (ExpansionMethod::Sweep): Zhao's
///        Gauss–Seidel sweeps of the Eikonal equation, scheduled leaf by leaf on sparse VDB
///        topology. Use it through expandLevelSet() (ExpandLevelSet.h).
///
/// Algorithm: H. Zhao, "A fast sweeping method for Eikonal equations", Mathematics of
/// Computation 74 (2005), used as Chang, Cha and Ihm, "Computing Local Signed Distance Fields for
/// Large Polygonal Models", Computer Graphics Forum (2008), §5.3, use it:
/// the exact narrow band of meshToLevelSet() is the boundary condition, every new voxel gets its
/// sign first (signed flood fill of the input), then Gauss–Seidel sweeps in the 2^3 = 8
/// alternating orderings solve |∇φ| = 1 with the first-order Godunov upwind discretisation
///     [(φ - a_x)^+]^2 + [(φ - a_y)^+]^2 + [(φ - a_z)^+]^2 = h^2,  a_k = min(φ(x - e_k), φ(x + e_k))
/// (magnitudes, on each side of the surface), taking φ_new = min(φ_old, solution).
///
/// Sparse: the sweeps visit only the active voxels of the candidate VDB tree, never a dense box.
/// Schedule (leaf-level marching, in the spirit of the heap-cell method of A. Chacon and
/// A. Vladimirsky, "Fast two-scale methods for Eikonal equations", SIAM J. Sci. Comput. 2012): a
/// leaf node (8^3 voxels) is processed when it has pending input — new values on a neighbouring
/// face, or its own fixed values at the start — and processing it means Gauss–Seidel sweeps of
/// its voxels until none of them is dirty (below). The first ordering runs along each axis away
/// from the halo face with the smaller minimum; each next one reverses the axes along which a
/// change marked an already visited voxel. Leaves are taken roughly in order of their smallest
/// pending input value (the key): each step processes the leaves whose key is below the
/// smallest key + 8 voxels, skipping a leaf while a face neighbour has a smaller key, until none
/// is left. Within a step the leaves go in two phases by the parity of I + J + K (I, J, K: leaf
/// coordinates); two leaves of one parity never share a face and the Godunov stencil only reads
/// face neighbours, so each phase processes its leaves in parallel (TBB), every leaf seeing the
/// same values whatever the thread count, and the phases, steps and keys are computed serially:
/// the result is bit-identical for any number of threads. Any such order of Gauss–Seidel
/// min-updates converges to the same discrete fixed point (up to the tolerance below).
///
/// Work saved (none of it changes what a voxel's update computes):
/// - per-voxel dirty bits: a voxel is re-evaluated only when a face neighbour changed since its
///   last evaluation in a way its update can see: a change to value u marks a neighbour q only
///   when u is below |φ_q| and below q's other neighbour on the same axis (q's upwind value on
///   that axis is the smaller of the two, so otherwise it stays the same bit for bit); leaves with
///   both signs mark every neighbour. Changes of at most the tolerance are not passed on
///   (rounding creep would otherwise ripple through the band; measured effect on the error
///   columns: none at 4 decimals).
/// - capped values: a voxel whose solution is not below the kept width on its side (see
///   ExpandLevelSet.h) stays unreached — it would be trimmed anyway, and no voxel below the cap
///   depends on it (the Godunov solution only reads neighbour values below itself).
/// - single-precision update with the discriminants written as sums of squared differences
///   (2h² − (a1 − a0)², 3h² − Σ (ai − aj)²), so nothing cancels.
/// The sweeps stop when no leaf has pending input (converged), or when only leaves already
/// processed maxIterations times have.
///
/// Candidates: whole leaf nodes, every leaf whose box comes closer than R (ExpandLevelSet.h,
/// "Topology") to the bounding box of some input leaf's active voxels (one pass over a dense
/// grid of leaf cells; a superset of the Euclidean dilation, the cap keeps the extra voxels
/// unreached). Inputs whose grid of leaf cells would exceed 2^24 cells (about 2048^3 voxels)
/// take the voxel dilation of dilationPattern() instead, as the Vector method always does.
///
/// What is exact and what is approximate: the voxels of the input band keep their (exact) values
/// bit for bit. The new voxels hold the first-order Godunov solution, which satisfies |∇φ| ≈ 1 but
/// is not the Euclidean distance: it is exact for planes, and elsewhere its error grows slowly
/// with the distance from the frozen band (measured in docs/expansion.md against the exact
/// reference: mean 0.05–0.15 voxel and max ≈ 1 voxel when sweeping 3 → 20 voxels, mean
/// 0.15–0.43 and max ≈ 1.5 voxels for 3 → 60; equal to openvdb::tools::dilateSdf on the voxels
/// both produce). For exact distances in a wide band, call meshToLevelSet() with the wide band
/// directly (`--expansion exact`).
#pragma once

namespace levelforge::fast_sweeping_internal {

/// @brief The voxel dilation that reaches a Euclidean ball: a 26-neighbour steps followed by
///        b 6-neighbour steps, whose lattice Minkowski sum (cube of half-side a + octahedron of
///        radius b) contains every lattice point at Euclidean distance < radius.
///
/// Among the (a, b) with a + b minimal, the smallest a (fewest extra voxels). The Vector method,
/// and the Sweep method on very large inputs, dilate the input band with it.
/// @param[in]  radius     the ball radius, voxels (<= 0 or NaN: no steps)
/// @param[out] cubeSteps  a, the 26-neighbour steps
/// @param[out] faceSteps  b, the 6-neighbour steps
void dilationPattern(double radius, int& cubeSteps, int& faceSteps);

} // namespace levelforge::fast_sweeping_internal
