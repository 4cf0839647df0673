// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The closest-triangle hierarchy of the exact band (private to mesh/): a binary tree of
///        boxes over the mesh's triangles, built once per conversion, whose leaves are
///        *clusters* of up to 8 triangles stored with their lower-bound planes in
///        single-precision structure-of-arrays form, relative to the cluster's centre.
///
/// Why: the paper's per-cell triangle lists (Chang et al. 2008 §3.2) make the cost of a voxel
/// grow with the number of triangles near it — coarse voxels over dense meshes, a stray vertex
/// that squeezes the whole mesh into a few cells, or a wide band gather thousands of triangles
/// per voxel. The hierarchy makes it logarithmic: a voxel visits the boxes near it,
/// nearest child first, and only the clusters whose box is closer than its best distance so far.
///
/// Exactness: nothing here decides a distance. Boxes are built from the double-precision
/// cell-space vertices, so a box distance never exceeds the distance to any triangle inside;
/// a cluster's bounds are lower bounds up to single-precision rounding, which the caller covers
/// with its margin (margin()). Exact distances are always evaluated in double precision.
///
/// Triangles longer than 8 cells are split (recursive halving of the polygon at the middle of
/// its longest box axis) into pieces no longer than that; each piece is an item of its own with
/// its own box and a lane holding the whole triangle, so slivers, needles and large CAD faces
/// do not make boxes that overlap everything around them. A triangle can then appear in several
/// clusters; the search skips a triangle it already holds as its best.
///
/// Construction is deterministic (median splits on the longest axis of the centroid box, ties
/// broken by triangle id; the tree shape depends only on the triangle count), parallel over
/// subtrees with TBB, so the tree is identical for any thread count.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include "detail/UninitialisedAllocator.h"

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace levelforge::mesh_internal {

constexpr uint32_t kNoTriangle = 0xffffffffu;
constexpr uint32_t kClusterSize = 8;

/// Up to 8 triangles, in single precision relative to `origin`, per lane i: F[0..3] the
/// triangle's plane (unit normal, offset), F[4..12] its corners (x0 y0 z0 x1 ...), F[13..15]
/// 1/|edge k|² (0 for a zero-length edge). clusterBounds() turns them into the point–triangle
/// distance evaluated in single precision: the plane distance where the point projects inside
/// the three edges, the nearest edge segment otherwise. (A cheaper plane-and-edge-lines bound,
/// loose in vertex regions, was tried on 2026-12-02: armadillo_100k at 1024³ distance stage
/// 2.30 s against 2.54 s, within the machine's noise, but 19.3 exact evaluations per voxel against
/// 3.9 at band 20 and 256³, and slower at 256³ band 3; dropped.) Unused lanes have F[3] = 1e30 and far corners (never survive).
constexpr int kClusterRows = 16;
struct alignas(16) TriangleCluster
{
    float F[kClusterRows][kClusterSize];
    Vec3d origin;                  ///< centre of the cluster's box, cell space
    uint32_t ids[kClusterSize];    ///< triangle indices (kNoTriangle in unused lanes)
    uint32_t count;                ///< triangles in use
    uint32_t node;                 ///< the hierarchy leaf holding it (its box)
};

/// The clusters, written in parallel right after they are allocated (no zeroing on one thread).
using detail::UninitialisedAllocator;
using ClusterVector = std::vector<TriangleCluster, UninitialisedAllocator<TriangleCluster>>;

/// A node of the hierarchy: its box (cell space, double) and either two children or a cluster.
struct HierarchyNode
{
    double lo[3], hi[3];
    uint32_t left;      ///< inner: left child; leaf: cluster index
    uint32_t right;     ///< inner: right child; leaf: kLeaf
    uint32_t triangles; ///< triangles in the subtree
    static constexpr uint32_t kLeaf = 0xffffffffu;
    bool isLeaf() const { return right == kLeaf; }
};

/// Squared distance from p to the box of n (0 inside).
inline double boxDistanceSqr(const HierarchyNode& n, const Vec3d& p)
{
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double e = p[k] < n.lo[k] ? n.lo[k] - p[k] : (p[k] > n.hi[k] ? p[k] - n.hi[k] : 0.0);
        d2 += e * e;
    }
    return d2;
}

/// Squared distance between the box of n and the box [lo, hi] (0 when they overlap).
inline double boxBoxDistanceSqr(const HierarchyNode& n, const Vec3d& lo, const Vec3d& hi)
{
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double e = hi[k] < n.lo[k] ? n.lo[k] - hi[k] : (lo[k] > n.hi[k] ? lo[k] - n.hi[k] : 0.0);
        d2 += e * e;
    }
    return d2;
}

/// Squared distances, in single precision, from q (relative to the cluster origin) to the 8 lanes
/// of a cluster: lb2[i], and the mask of lanes with lb2 < bm2 as the return value. The rounding
/// error of each distance is a few ulps of (|q| + the cluster radius), which the caller's margin
/// covers, so lb2 serves as a lower bound. SSE2 on x86-64, scalar elsewhere.
/// On x86-64 CPUs with AVX2 an AVX2 build runs (the same operations, 8 lanes at once, no FMA:
/// bit-identical bounds).
uint32_t clusterBounds(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2);
/// clusterBounds() that also gives, per lane, the vector from the closest point of the lane's
/// triangle, as the single-precision arithmetic finds it, to q: pd·n (n the unit normal, pd the
/// signed plane distance) where q projects inside the triangle, q − the nearest edge point
/// otherwise, so that g / sqrt(lb2) is the unit normal of a plane separating q from the triangle.
/// The same lb2 and mask as clusterBounds(); g only for the lanes of the mask. AVX2 where the
/// CPU has it, scalar otherwise (g may then differ in the last bits; lb2 does not).
uint32_t clusterBoundsDirections(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2,
                                 float* gx, float* gy, float* gz);
/// The SSE2 (or scalar) build of clusterBounds(), for the twin test.
uint32_t clusterBoundsBaseline(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2);
/// Whether clusterBounds() can use its AVX2 build on this CPU.
bool clusterBoundsAvx2Available();

class TriangleHierarchy
{
public:
    /// Builds the hierarchy over the triangles `use` (indices into mesh.triangles,
    /// non-degenerate) with cell-space vertices `cellPts`; the bound planes take the unit face
    /// normals of the world-space mesh (faceNormalOf(), as the pseudonormals do). Polls the
    /// interrupter after the partition (throws InterruptedError).
    TriangleHierarchy(const TriangleMesh& mesh, const std::vector<Vec3d>& cellPts, const std::vector<uint32_t>& use,
                      openvdb::util::NullInterrupter* interrupter = nullptr);

    const std::vector<HierarchyNode>& nodes() const { return mNodes; }
    const ClusterVector& clusters() const { return mClusters; }
    /// The largest distance from a cluster's origin to a corner of its box (cell units): bounds
    /// the magnitude of the coordinates the single-precision planes are evaluated at.
    double maxClusterRadius() const { return mMaxRadius; }
    /// Pieces made by splitting triangles longer than 8 cells (0 when none was).
    size_t pieces() const { return mPieces; }
    /// Bytes held (nodes and clusters).
    size_t memoryBytes() const
    {
        return mNodes.capacity() * sizeof(HierarchyNode) + mClusters.capacity() * sizeof(TriangleCluster);
    }

private:
    std::vector<HierarchyNode> mNodes;       // pre-order; node 0 is the root
    ClusterVector mClusters;                 // in leaf order
    double mMaxRadius = 0.0;
    size_t mPieces = 0;
};

} // namespace levelforge::mesh_internal
