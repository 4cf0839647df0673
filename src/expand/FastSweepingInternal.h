// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the expansion: what the front door (ExpandLevelSet.cc) calls of the fast
///        sweeping method (FastSweeping.cc) and of the candidate topology (ExpansionTopology.cc).
#pragma once

#include <levelforge/expand/ExpandLevelSet.h>
#include "expand/FastSweeping.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge::fast_sweeping_internal {

/// "Not yet reached" / "not part of the domain" (world units).
inline constexpr float kBig = 1e30f;

/// Leaf-granular candidate domain of the sweep: every leaf node that may hold a voxel closer than
/// `radius` voxels to an active voxel of `band` (the gap between the leaf's box and the box of
/// a band leaf's active voxels is below the radius), fully active. One pass over a dense grid
/// of leaf cells instead of `radius` voxel dilation steps; it contains the Euclidean dilation.
/// Returns null (the caller dilates voxel by voxel) when that grid would be too large; else
/// `leafCount` receives the number of leaves.
openvdb::MaskTree::Ptr leafDomain(const openvdb::MaskTree& band, double radius, uint64_t& leafCount);

/// The sweeps (FastSweeping.h) on `tree`: the dilated topology with flood-filled signs, whose
/// active voxels that are not active in `frozen` get the Godunov solution (world units, voxel
/// size h). tol: changes of at most this (world units) are not passed on. capPos / capNeg:
/// voxels whose value would not be below the cap (world units) on their side are left
/// unreached (±kBig). Sets stats.candidateVoxels, iterations, maxChange, converged,
/// leafUpdates and voxelUpdates. Throws InterruptedError.
void sweepLeaves(openvdb::FloatTree& tree, const openvdb::FloatTree& frozen, float h, float tol, float capPos,
                 float capNeg, int maxIterations, openvdb::util::NullInterrupter* interrupter,
                 ExpandLevelSetStats& stats);

} // namespace levelforge::fast_sweeping_internal
