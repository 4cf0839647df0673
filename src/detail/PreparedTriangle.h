// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The triangle record the exact-distance kernels copy next to the leaf (or block) that
///        uses it: vertices in cell space (index units, double precision) and the triangle's
///        index in the mesh, so the hot loop reads one contiguous array instead of chasing
///        vertex indices. Used by the exact band (mesh/) and the ADF's mesh provider (adf/).
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <cstdint>

namespace levelforge::detail {

/// A triangle copied next to the leaf that uses it (cell-space vertices, double precision).
struct PreparedTri
{
    Vec3d a, b, c;
    uint32_t id; ///< index in TriangleMesh::triangles
};

} // namespace levelforge::detail
