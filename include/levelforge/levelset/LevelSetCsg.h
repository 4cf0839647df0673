// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief CSG of two narrow-band level sets on the same transform, with OpenVDB's
///        openvdb::tools::csgUnionCopy / csgIntersectionCopy / csgDifferenceCopy (Museth,
///        "VDB: High-Resolution Sparse Volumes with Dynamic Topology", ACM TOG 2013); the
///        inputs are not modified.
#pragma once

#include <levelforge/core/CsgOperation.h>

#include <openvdb/openvdb.h>

namespace levelforge {

/// @brief Union, intersection or difference of two level sets.
/// @param[in] a   the first level set (GRID_LEVEL_SET); its name is the result's
/// @param[in] b   the second level set, on the same transform as @p a
/// @param[in] op  the operation: min(a, b), max(a, b) or max(a, -b)
/// @return a new level set (GRID_LEVEL_SET) on the inputs' transform
/// @throws InvalidArgumentError if the transforms differ or either grid is not a level set
openvdb::FloatGrid::Ptr csgLevelSets(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, CsgOperation op);

} // namespace levelforge
