// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Tetrahedral shells around the faces of a triangle mesh (T4 scan conversion).
///
/// Paper: K. Erleben, H. Dohlmann, "Scan Conversion of Signed Distance Fields".
/// Every triangle is enclosed in a bounded volume made only of
/// tetrahedra, each tagged with its source triangle; TetScanConversion.h slices them with z-planes
/// and evaluates the exact distance to the source triangle at every covered voxel centre.
///
/// Four shell generators, for a narrow-band width eps (same units as the mesh points):
///   PseudoNormal (§3.3) the 6 points p_i ± eps * n_i (n_i: unit angle-weighted vertex
///                pseudonormals) → convex hull → one tetrahedron from the hull centre to each hull
///                triangle.
///   Thin (§3.4)  as PseudoNormal, but the inward and outward extrusion lengths are limited to the
///                smallest positive root of the constraint system Eq. 6–11 (no swallow tail):
///                length = min(eps, root).
///   Offset (§3.4, "face-offsetting") the 12 points p_i ± eps * n_i and p_i ± eps * n_face.
///   Obb (§3.5)   rectangle on the longest edge and the height, enlarged by eps in the face plane,
///                extruded ± eps along the face normal → 5 tetrahedra.
///
/// Coverage (what is exact, what is not). Call N_eps(T) the set of points within eps of triangle T.
///   * Obb contains N_eps(T) completely (T lies in the rectangle R, so a point within eps of T is
///     within eps of R in each frame coordinate).
///   * The paper's PseudoNormal, Thin and Offset hulls do NOT contain N_eps(T) in general: near
///     vertices and edges the eps-ball bulges beyond the chords of the hull, and Thin shortens the
///     extrusion below eps wherever the root system demands it. On the other hand every one of
///     their points is p_i + s * n with |s| <= eps and |n| = 1, i.e. within eps of T, and N_eps(T)
///     is convex, so each of these hulls lies INSIDE N_eps(T).
///   * ShellCoverage::Complete (the default) therefore completes them to the eps-prism of the face
///     (epsilonPrism() in src/scan/TetrahedralShell.cc): the hexagon bounded by the three edge lines
///     offset by eps in the face plane and by three bevel lines at distance eps from the vertices,
///     perpendicular to the bisector of the vertex's two outward edge normals, extruded +-eps along
///     the face normal. Each of the 6 half-planes (x) the slab contains N_eps(T) (the support of T +
///     disc(eps) in an edge normal is that edge's offset; in a direction of a vertex's normal cone,
///     the vertex's), so the prism contains N_eps(T), and it contains the paper hull because N_eps(T)
///     does: the completion hull(paper points + prism) IS the prism, and the three completed shells
///     coincide. The prism is the ball's circumscribed cylinder swept along T: for an equilateral
///     face of edge 1 voxel at eps = 3 voxels it holds 244 voxel volumes (N_eps(T): 158, Obb: 288),
///     for edge 10 voxels 987 (N_eps(T): 797, Obb: 1407). With Complete every voxel centre of the eps
///     band is covered by the shell of its closest triangle whatever the shell, so the scan-converted
///     band is exact; aliasing does not arise because coverage is a property of the voxel centres
///     themselves (the rasterizer tests centres, with a 1e-7-voxel tolerance for round-off).
///   * ShellCoverage::Paper keeps the paper's hulls as they are (for comparison with its Figures
///     20–28): voxels they miss are either absent or hold the distance to another (farther)
///     triangle that covers them. tests/scan/TestTetScanConversion.cc measures both;
///     docs/scan-conversion.md reports the numbers.
///
/// Convex hulls of <= 12 points are computed here by hand (exhaustive facet test, O(n^4) with
/// n <= 12, exact up to a relative tolerance), coplanar facets fan-triangulated once, so no
/// external hull library is needed; tests/scan/TestTetrahedralShell.cc checks the hull against
/// brute force containment tests.
#pragma once

#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleMesh.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

/// @brief How the shell of a face is built (see the file comment): the paper's PseudoNormal
///        (§3.3), Thin and Offset (§3.4) hulls, or the Obb prism (§3.5).
enum class ShellMethod : uint8_t { PseudoNormal = 0, Thin, Offset, Obb };

/// @brief Complete: every shell contains the eps-neighbourhood of its face (the pseudonormal
///        family is completed to the eps-prism, see the file comment); Paper: the hulls exactly
///        as the paper builds them.
enum class ShellCoverage : uint8_t { Complete = 0, Paper };

/// @brief The name of a shell method: "pseudonormal", "thin", "offset", "obb".
/// @param[in] method  the method
/// @return a static string ("?" for a value outside the enumeration)
const char* toString(ShellMethod method);
/// @brief Inverse of toString; throws InvalidArgumentError on an unknown name.
/// @param[in] name  "pseudonormal", "thin", "offset" or "obb" (exact, lower case)
/// @return the method
/// @throws InvalidArgumentError on an unknown name (the message lists the valid ones)
ShellMethod shellMethodFromString(const std::string& name);
/// @brief The name of a shell coverage: "complete", "paper".
/// @param[in] coverage  the coverage
/// @return a static string
const char* toString(ShellCoverage coverage);
/// @brief Inverse of toString; throws InvalidArgumentError on an unknown name.
/// @param[in] name  "complete" or "paper" (exact, lower case)
/// @return the coverage
/// @throws InvalidArgumentError on an unknown name (the message lists the valid ones)
ShellCoverage shellCoverageFromString(const std::string& name);

/// @brief One tetrahedron of a shell, tagged with the triangle it bounds.
struct Tetrahedron
{
    std::array<Vec3d, 4> p; ///< corners (units of the mesh points)
    uint32_t triangle = 0;  ///< source face (index into mesh.triangles)
};

/// @brief Options of buildTetrahedralShell().
struct TetrahedralShellOptions
{
    ShellMethod method = ShellMethod::Obb;
    /// Narrow-band width eps, in the units of the mesh points (> 0).
    double epsilon = 1.0;
    ShellCoverage coverage = ShellCoverage::Complete;
};

/// @brief What buildTetrahedralShell() built.
struct TetrahedralShellStats
{
    uint64_t faces = 0;             ///< non-degenerate faces given a shell
    uint64_t skippedDegenerate = 0; ///< zero-area faces (no shell)
    uint64_t tetrahedra = 0;
    uint64_t limitedExtrusions = 0; ///< Thin: faces whose extrusion was shortened below eps
    uint64_t completedFaces = 0;    ///< faces whose paper hull was completed to the eps-prism
    /// @brief Tetrahedra per face given a shell.
    /// @return tetrahedra / faces, or 0 when no face got a shell
    double tetrahedraPerFace() const { return faces ? double(tetrahedra) / double(faces) : 0.0; }
};

/// @brief Builds the shell of every non-degenerate face of `mesh`.
///
/// `normals` must be the pseudonormals of a mesh with the same connectivity (directions only are
/// used, so a uniformly scaled copy of the mesh may share them). Parallel (TBB); the output order
/// is by face, independent of the number of threads. Throws InvalidArgumentError if epsilon is not
/// positive and finite.
/// @param[in]  mesh     the mesh; its point units (TetScanConversion: index space, voxels) are the
///                      units of epsilon and of the tetrahedra
/// @param[in]  normals  pseudonormals of a mesh with the same connectivity; faces it marks
///                      degenerate get no shell
/// @param[in]  options  shell method, width eps (> 0, units of the mesh points) and coverage
/// @param[out] stats    optional: faces, skipped degenerate faces, tetrahedra, limited extrusions
///                      (Thin), completed faces
/// @return the tetrahedra of all shells, grouped by face in ascending face order
/// @throws InvalidArgumentError if epsilon is not positive and finite
std::vector<Tetrahedron> buildTetrahedralShell(const TriangleMesh& mesh, const PseudoNormals& normals,
                                               const TetrahedralShellOptions& options,
                                               TetrahedralShellStats* stats = nullptr);

} // namespace levelforge
