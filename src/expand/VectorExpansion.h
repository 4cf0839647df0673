// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The vector method of expandLevelSet() (ExpansionMethod::Vector): closest-point
///        vectors propagated over sparse VDB topology by the 8-pass vector-city vector distance
///        transform of Satherley & Jones, run on VDB leaves.
///
/// Paper: R. Satherley, M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001), §3 (VCVDT, full vector grid, Leymarie–Levine storage of the
/// minimal distance) and §4.3 (a shell of exact closest-point vectors around a mesh, propagated
/// by the 8-pass VCVDT).
///
/// Use it through expandLevelSet() (ExpandLevelSet.h) with ExpandLevelSetOptions::method =
/// ExpansionMethod::Vector; this header documents the method and exposes the propagation step.
///
/// Shell: every voxel of the input band holds the offset from its centre to its closest surface
/// point (voxel units). With meshToLevelSetWithClosestPoints() these offsets are exact (the point
/// of the closest triangle that decided the exact distance). Without them they are estimated from
/// the band: p = x - φ(x) ∇φ/|∇φ| with central differences (one-sided at the band's edge), which
/// is exact for planes and first-order accurate elsewhere.
///
/// Propagation: two sweeps over the z-slices (z+ then z-); every slice gets four in-slice raster
/// passes, one from each corner — P1 (y+, x+) reads the (x-1), (y-1) neighbours and the vertical
/// neighbour of the previous slice (read only here), P2 (y+, x-) reads (x+1), (y-1), P3 (y-, x-)
/// reads (x+1), (y+1), P4 (y-, x+) reads (x-1), (y+1). A candidate for voxel x from neighbour
/// n = x + o is o + V(n) (the neighbour's closest point seen from x); the one with the smallest
/// squared length wins, and that length is kept with the vector, so the centre's distance is
/// never recomputed. The passes visit exactly the voxels of the dilated VDB topology in the same
/// order as the dense 8-pass VCVDT visits a full grid (leaves are walked row by row across each
/// slice), never a dense box. Input band voxels are frozen (their exact values are kept bit for
/// bit). The passes are sequential by nature (each voxel reads voxels of the same pass), so this
/// step runs on one thread; the result is independent of the thread count.
///
/// What is exact and what is approximate: every new value is the distance from the voxel centre
/// to a point of the surface (when the shell vectors are exact), so it never underestimates the
/// exact distance; it is exact when the closest point of the voxel is the closest point of one of
/// the shell voxels and the raster passes carry it there. With the closest triangles (mesh road)
/// the triangle of the winning vector travels with it; each new voxel then takes the exact
/// distance to it, and where its neighbours disagree on the triangle it also tries their 26
/// triangles and walks over the mesh to strictly closer ones (edges, vertex fans), followed by
/// Jacobi rounds over the neighbours' refined triangles: the value is the exact distance to a
/// local minimum of the distance over the mesh (exact unless another side of the mesh, e.g.
/// across a thin part near the medial axis, is closer). Errors are local (corners of Voronoi
/// regions, §3.2 of the paper): with points only, mean 0.02 / max 0.25 voxel on a sphere at 64
/// voxels; with the triangle refinement, mean < 1e-4 / max 0.04 voxel on the Armadillo at 256
/// for 3 → 20 and 3 → 60 (docs/benchmarks.md, tests/expand/TestVectorExpansion.cc).
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <vector>

namespace levelforge {

namespace vector_expansion_internal {

/// The mesh adjacency the triangle refinement walks over.
/// @param[in]  mesh      the triangles (indices in range)
/// @param[out] fanBegin  per vertex + 1: offsets into `fan`
/// @param[out] fan       the triangles around each vertex, in increasing order (a triangle that
///                       holds the vertex twice is listed twice)
/// @param[out] edge      3 per triangle: the triangle across edge e (corners e, e + 1), -1 for a
///                       boundary edge. The triangles of a non-manifold edge form a ring in the
///                       order of their edge slots 3 t + e: each slot names the next slot's
///                       triangle, the last the first's. Linear in the triangles plus the fans
///                       scanned (at most 64 triangles per edge; edges between two larger fans
///                       are sorted instead).
void meshAdjacency(const TriangleMesh& mesh, std::vector<uint32_t>& fanBegin, std::vector<int32_t>& fan,
                   std::vector<int32_t>& edge);

/// What propagateClosestVectors() did.
struct PropagationStats
{
    uint64_t shellVoxels = 0;      ///< frozen voxels that seed the propagation
    uint64_t estimatedVectors = 0; ///< shell vectors estimated from φ and ∇φ (no closest points given)
    uint64_t updatedVoxels = 0;    ///< voxels that received a vector
    uint64_t unreachedVoxels = 0;  ///< active voxels no vector reached (left at ±infinity)
    uint64_t refinedVoxels = 0;    ///< new voxels given the exact distance to their triangle
    uint64_t walkSteps = 0;        ///< steps of the greedy walk to closer edge-adjacent triangles
    uint64_t improvedByNeighbours = 0; ///< refinements found through a neighbour's triangle
    int refineRounds = 0;          ///< Jacobi rounds until no voxel improved
    uint64_t refineEvaluations = 0; ///< exact point–triangle distances of the refinement
    double secondsSetup = 0, secondsPasses = 0, secondsFinish = 0;
};

/// The seed vectors of the input band (all optional, not owned).
struct ShellVectors
{
    const openvdb::Vec3fTree* points = nullptr;   ///< offset to the closest point, voxel units
    const openvdb::Int32Tree* triangles = nullptr; ///< closest triangle (index into mesh->triangles)
    const TriangleMesh* mesh = nullptr;            ///< with `triangles`: enables the exact refinement
};

/// @brief The propagation step of the vector method: fills the non-frozen active voxels of
///        `tree` with sign(value) × |V| × h, where V is the closest-point vector propagated from
///        the frozen voxels (the active voxels of `frozen`) by the sparse 8-pass VCVDT.
///
/// Frozen voxels keep their values. `shell.points` gives, for frozen voxels, the offset from
/// the voxel centre to the closest surface point in voxel units (else estimated from φ and
/// ∇φ); with `shell.triangles` and `shell.mesh` the triangle travels with the vector and each
/// new voxel finally gets min(|V|, exact distance to the refined triangle) (see the file
/// comment).
/// @param[in,out] tree         the dilated topology with flood-filled signs; the new values
/// @param[in]     frozen       the input band (its active voxels are frozen)
/// @param[in]     shell        optional seed vectors, triangles and mesh
/// @param[in]     transform    index to world space (uniform voxels)
/// @param[in]     unreached    the magnitude unreached voxels get (±unreached)
/// @param[in]     interrupter  optional; not owned
/// @param[out]    stats        optional: counts and stage times
/// @throws InterruptedError.
void propagateClosestVectors(openvdb::FloatTree& tree, const openvdb::FloatTree& frozen,
                             const ShellVectors& shell, const openvdb::math::Transform& transform,
                             float unreached, openvdb::util::NullInterrupter* interrupter,
                             PropagationStats* stats);

} // namespace vector_expansion_internal
} // namespace levelforge
