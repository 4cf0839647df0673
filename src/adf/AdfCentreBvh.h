// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: the nearest centre of a boundary cell (the type-3 estimator,
///        Yin et al. 2011 §7.2), by the library's BVH (detail/Bvh.h) over the 4³ quarters of
///        the triangle-list tree's leaves.
#pragma once

#include "adf/AdfInternal.h"
#include "detail/Bvh.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace levelforge {
namespace adf_internal {

/// Nearest centre of a boundary cell (type-3 estimator, §7.2): a BVH over the list tree's leaves.
/// The tree: one non-empty 4³ quarter of a leaf per BVH leaf (tight boxes prune well), split at
/// the median of the box minima along the node box's longest axis; boxes at the best distance
/// are pruned (only the distance is returned, and it is the minimum over all centres whatever
/// the tree: the box bounds and the row bounds of scanLeaf never exceed a centre's distance).
class CentreBvh
{
public:
    using ListLeaf = openvdb::UInt32Tree::LeafNodeType;
    explicit CentreBvh(const openvdb::UInt32Tree& tree);

    /// Squared index-space distance from p to the nearest cell centre; `hint` is a centre
    /// (updated) used as the starting bound. Out of line: the leaf pass calls it on its rare
    /// paths only (wide type-2 certificates, leaves far from the surface).
    double nearest2(const Vec3d& p, Vec3d& hint) const;

private:
    void scanLeaf(uint32_t li, const Vec3d& p, double& best2, Vec3d& hint) const;

    std::vector<const ListLeaf*> mLeaves; ///< per primitive: its list-tree leaf
    std::vector<uint8_t> mQuarter;        ///< and which 4³ quarter of it
    detail::Bvh mBvh;
};

} // namespace adf_internal
} // namespace levelforge
