// SPDX-License-Identifier: Apache-2.0
// levelforge — exact signed distance reference, for tests, benchmarks and accuracy reports.
//
// A bounding-volume hierarchy over the triangles answers closest-point queries exactly (double
// precision, exhaustive pruning by box distance); the sign follows the same angle-weighted
// pseudonormal rule as meshToLevelSet (Bærentzen & Aanæs 2005), so the two agree bit-for-bit in
// sign on every voxel whose closest feature is unambiguous. A brute-force O(F) query is
// provided too, to test the BVH itself.
#pragma once

#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>

#include <cstdint>
#include <memory>
#include <vector>

namespace levelforge {

namespace detail {
class Bvh;
}

class ExactReference
{
public:
    struct Result
    {
        double distance = 0.0;      ///< signed, world units (negative inside)
        uint32_t triangle = ~0u;    ///< closest triangle (index into mesh.triangles)
        Vec3d closestPoint{0.0};    ///< world units
    };

    /// Keeps a reference to `mesh`, which must outlive this object. Degenerate triangles are
    /// ignored exactly as meshToLevelSet ignores them.
    explicit ExactReference(const TriangleMesh& mesh);
    ~ExactReference();

    /// Exact closest point and signed distance (BVH).
    Result query(const Vec3d& worldPoint) const;
    double signedDistance(const Vec3d& worldPoint) const { return query(worldPoint).distance; }
    /// The same, by testing every triangle (slow; for testing the BVH).
    Result bruteForce(const Vec3d& worldPoint) const;

    const PseudoNormals& pseudoNormals() const { return *mNormals; }

private:
    const TriangleMesh& mMesh;
    std::unique_ptr<PseudoNormals> mNormals;
    /// BVH over the non-degenerate triangles; its order() holds their ids in leaf order.
    std::unique_ptr<detail::Bvh> mBvh;
};

/// Accuracy of a level set against the exact reference, in voxel units.
struct BandErrorReport
{
    uint64_t checkedVoxels = 0;   ///< active voxels compared
    double maxError = 0.0;        ///< max |φ - d_exact| / voxelSize
    double meanError = 0.0;       ///< mean |φ - d_exact| / voxelSize
    uint64_t signErrors = 0;      ///< active voxels whose sign differs from the reference (|d| > 1e-6 voxel)
    uint64_t missingVoxels = 0;   ///< inactive face-neighbours of the band whose exact distance is inside the band
    uint64_t extraVoxels = 0;     ///< active voxels whose exact distance lies outside the requested band
};

/// Compares every active voxel of `grid` (or every `stride`-th one, in a fixed order) with the
/// reference, and checks the inactive face-neighbours of the band for voxels that should have
/// been active given the band widths (in voxels). Parallel; deterministic.
BandErrorReport compareToReference(const openvdb::FloatGrid& grid, const ExactReference& reference,
                                   double exteriorWidth, double interiorWidth, uint64_t stride = 1);

} // namespace levelforge
