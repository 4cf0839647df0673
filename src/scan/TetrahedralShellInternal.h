// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the tetrahedral shells (and their white-box tests): convex hull, hull
///        tetrahedra, thin-shell extrusion limit, OBB and eps-prism decompositions.
#pragma once

#include <levelforge/scan/TetrahedralShell.h>

namespace levelforge {

namespace shell_internal {

/// Triangles of the convex hull of `points` (n <= 64; intended for n <= 12), as index triples.
/// Coplanar facets are fan-triangulated once. Duplicate points are tolerated. Empty result if the
/// points are (nearly) coplanar.
std::vector<std::array<int, 3>> convexHull(const std::vector<Vec3d>& points);

/// Tetrahedra from the centre of the hull of `points` to each hull triangle (appended to out).
void hullTetrahedra(const std::vector<Vec3d>& points, uint32_t triangle, std::vector<Tetrahedron>& out);

/// Smallest positive root of the system Eq. 11 for the prism q_i = p_i + sigma * eps * n_i
/// (sigma = -1: inward, +1: outward); +infinity if there is none.
double thinShellExtrusionLimit(const std::array<Vec3d, 3>& p, const std::array<Vec3d, 3>& n, double sigma);

/// The eight corners of the Obb shell (bit 0: along the longest edge, bit 1: along the height,
/// bit 2: along the normal) and its 5-tetrahedron decomposition.
std::array<Vec3d, 8> obbCorners(const Vec3d& a, const Vec3d& b, const Vec3d& c, double eps);
void obbTetrahedra(const std::array<Vec3d, 8>& corners, uint32_t triangle, std::vector<Tetrahedron>& out);

/// The 12 corners of the eps-prism of triangle (a, b, c) (see the file comment): corners 0–5 are
/// the hexagon at -eps along the face normal, in order around it, 6–11 the same at +eps.
std::array<Vec3d, 12> epsilonPrism(const Vec3d& a, const Vec3d& b, const Vec3d& c, double eps);
/// 12 tetrahedra whose union is the prism (4 triangular prisms of a fan, 3 tetrahedra each);
/// zero-volume ones are dropped.
void prismTetrahedra(const std::array<Vec3d, 12>& corners, uint32_t triangle, std::vector<Tetrahedron>& out);

/// Unsigned volume of a tetrahedron.
double volume(const Tetrahedron& t);

} // namespace shell_internal

} // namespace levelforge
