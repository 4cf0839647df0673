// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The Voronoi region of a triangle that holds a closest point: the face, one of its
///        three vertices or one of its three edges. closestPointOnTriangle() (TriangleDistance.h)
///        returns it; PseudoNormals.h maps it to the pseudonormal that decides the sign.
#pragma once

#include <cstdint>

namespace levelforge {

/// Which feature of a triangle holds the closest point (see TriangleDistance.h).
enum class TriangleFeature : uint8_t { Face = 0, Vertex0, Vertex1, Vertex2, Edge01, Edge12, Edge20 };

} // namespace levelforge
