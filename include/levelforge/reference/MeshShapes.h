// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Procedural meshes for tests, benchmarks and the demo.
///
/// Every closed shape here is watertight with shared vertices (each edge used by exactly two
/// triangles, once in each direction), consistently wound counter-clockwise seen from outside
/// (so its divergence-theorem signed volume is positive), free of degenerate triangles and of
/// self-intersections; validateMesh(shape).closed() holds. Each sets mesh.source to a short
/// description such as "<icosphere r=1 s=3>". Invalid parameters throw InvalidArgumentError.
///
/// Analytic references for tests (the meshes are inscribed polyhedra, so their volume and area
/// converge to these from below as the resolution grows):
///   icosphere    V = 4/3 pi r^3,       A = 4 pi r^2
///   box          V = dx dy dz,         A = 2 (dx dy + dy dz + dz dx)   (exact)
///   torus        V = 2 pi^2 R r^2,     A = 4 pi^2 R r
///   torus knot   V = pi t^2 L,         A = 2 pi t L   (L = centre-line length, Pappus/Weyl tube
///                formulas, exact for a tube thinner than the curve's radius of curvature and
///                without self-contact)
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <string>

#include <cstdint>
#include <vector>

namespace levelforge {

/// @brief Sphere from a subdivided icosahedron: 10*4^s + 2 vertices, 20*4^s triangles, every
///        vertex on the sphere.
///
/// s = subdivisions, in [0, 10].
/// @param[in] center        sphere centre (finite)
/// @param[in] radius        sphere radius (> 0, finite)
/// @param[in] subdivisions  s, the number of 1-to-4 subdivisions of the icosahedron, in [0, 10]
/// @return the closed mesh
/// @throws InvalidArgumentError a non-finite centre, radius <= 0, subdivisions outside [0, 10]
TriangleMesh makeIcosphere(const Vec3d& center, double radius, int subdivisions);

/// @brief Axis-aligned box [min, max] with each edge split into @a segments (>= 1) equal parts:
///        12 * segments^2 triangles (12 for segments = 1).
/// @param[in] min       minimum corner (finite)
/// @param[in] max       maximum corner (finite, above @p min on every axis)
/// @param[in] segments  parts per edge, in [1, 4096]
/// @return the closed mesh
/// @throws InvalidArgumentError non-finite corners, min not below max on some axis, segments
///         outside [1, 4096]
TriangleMesh makeBox(const Vec3d& min, const Vec3d& max, int segments = 1);

/// @brief Torus around the z axis through @a center: major radius R (centre of the tube), minor
///        radius r (tube), 0 < r < R.
///
/// Vertex i * minorSegments + j lies at major angle 2 pi i / majorSegments, minor angle
/// 2 pi j / minorSegments. Segments >= 3.
/// @param[in] center         torus centre (finite)
/// @param[in] majorRadius    R, distance from @p center to the centre of the tube
/// @param[in] minorRadius    r, radius of the tube, 0 < r < R
/// @param[in] majorSegments  vertices around the z axis (>= 3)
/// @param[in] minorSegments  vertices around the tube (>= 3)
/// @return the closed mesh, majorSegments * minorSegments vertices, twice as many triangles
/// @throws InvalidArgumentError a non-finite centre, radii not 0 < r < R, segments < 3
TriangleMesh makeTorus(const Vec3d& center, double majorRadius, double minorRadius,
                       int majorSegments, int minorSegments);

/// @brief The (p, q) torus knot tube, centred at the origin, the project's default demo mesh.
///
/// The centre line is C(t) = ((R + R/2 cos qt) cos pt, (R + R/2 cos qt) sin pt, R/2 sin qt),
/// t in [0, 2 pi), R = radius, i.e. it winds p times around the z axis and q times through the
/// hole of a torus with radii R and R/2. The tube has radius tubeRadius; vertex
/// i * tubeSegments + j is ring i (t = 2 pi i / segments), angle 2 pi j / tubeSegments, and ring
/// i is centred on C(t_i).
/// Requirements: p, q >= 1 and coprime (otherwise it is a link, not a knot); 0 < tubeRadius;
/// segments >= 3; tubeSegments >= 3. The defaults (trefoil, tube 0.25) are free of
/// self-intersections: strands stay more than 0.8 apart, the curvature radius exceeds 0.7.
/// @param[in] p             windings around the z axis (>= 1, coprime with @p q)
/// @param[in] q             windings through the hole of the torus (>= 1)
/// @param[in] radius        R, the major radius of the torus the knot winds on (> 0)
/// @param[in] tubeRadius    radius of the tube (> 0)
/// @param[in] segments      rings along the centre line (>= 3)
/// @param[in] tubeSegments  vertices per ring (>= 3)
/// @return the closed mesh, segments * tubeSegments vertices, twice as many triangles
/// @throws InvalidArgumentError p, q not >= 1 and coprime, a radius not > 0, segments < 3
TriangleMesh makeTorusKnot(int p = 2, int q = 3, double radius = 1.0, double tubeRadius = 0.25,
                           int segments = 256, int tubeSegments = 24);

/// @brief Centre line point of makeTorusKnot() at parameter t (same p, q, radius).
/// @param[in] p       windings around the z axis
/// @param[in] q       windings through the hole of the torus
/// @param[in] radius  R, the major radius
/// @param[in] t       curve parameter, radians (period 2 pi)
/// @return C(t), see makeTorusKnot()
Vec3d torusKnotPoint(int p, int q, double radius, double t);

/// @brief A soup of @a count independent triangles (3 * count vertices, nothing shared), for
///        voxelization tests.
///
/// Deterministic for a given seed on every platform (std::mt19937_64 and an explicit conversion
/// to doubles). Every vertex lies inside @a box and every edge is at most @a maxEdge long
/// (vertices are drawn in a ball of radius maxEdge / 2 around a centre drawn uniformly in the
/// box, then clamped into the box). Orientation is random; triangles may be
/// arbitrarily thin but are never degenerate (resampled if they are).
/// @param[in] count    number of triangles
/// @param[in] seed     seed of the std::mt19937_64 generator
/// @param[in] box      the box every vertex lies in (finite, positive extent on every axis)
/// @param[in] maxEdge  the longest possible edge (> 0)
/// @return the soup (not closed)
/// @throws InvalidArgumentError a box that is not finite with positive extent, maxEdge <= 0
TriangleMesh makeRandomTriangles(uint32_t count, uint64_t seed, const BBoxd& box, double maxEdge);

/// @brief Signed volume enclosed by @a mesh by the divergence theorem (positive for a closed mesh
///        wound counter-clockwise seen from outside).
///
/// Meaningful for closed meshes only.
/// @param[in] mesh  the mesh, world units
/// @return the signed volume, world units cubed; 0 for a mesh without triangles
double signedVolume(const TriangleMesh& mesh);

/// @brief Total area of the triangles of @a mesh.
/// @param[in] mesh  the mesh, world units
/// @return the area, world units squared
double surfaceArea(const TriangleMesh& mesh);

/// @brief The built-in meshes the command-line tools accept as an input name.
/// @param[in] name  "builtin:torus-knot" (makeTorusKnot()), "builtin:sphere" (unit icosphere,
///                  4 subdivisions), "builtin:box" (the cube [-1, 1]³)
/// @return the mesh, with its `source` set by its generator
/// @throws InvalidArgumentError for another "builtin:" name (the message lists the valid ones)
TriangleMesh makeBuiltinMesh(const std::string& name);

/// @brief True when @p name starts with "builtin:" (a name for makeBuiltinMesh(), not a path).
/// @param[in] name  an input name given to a command-line tool
/// @return true for a "builtin:" name (valid or not)
bool isBuiltinMeshName(const std::string& name);

} // namespace levelforge
