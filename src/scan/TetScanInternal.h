// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the scan conversion (and its white-box tests): slicing a tetrahedron with a z-plane
///        and its conservative footprint.
#pragma once

#include <levelforge/scan/TetScanConversion.h>

namespace levelforge {

namespace scan_internal {
/// Cross-section of a tetrahedron with the plane z (§3.1, cases A, B, C). Returns the number of
/// polygon vertices written to (x, y): 0 if the plane misses, 3 or 4 otherwise (some may
/// coincide when the plane passes through a corner).
int sliceTetrahedron(const Tetrahedron& tet, double z, double* x, double* y);
/// Conservative footprint of a tetrahedron on plane z (see TetScanOptions::conservative):
/// convex polygon (up to 16 vertices) written to cs.x/cs.y/cs.count; false if empty.
bool conservativeFootprint(const Tetrahedron& tet, int z, CrossSection& cs);
} // namespace scan_internal

} // namespace levelforge
