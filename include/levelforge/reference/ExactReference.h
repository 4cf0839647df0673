// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Exact signed distance reference, for tests, benchmarks and accuracy reports: the test
///        oracle every converter is measured against.
///
/// A bounding-volume hierarchy over the triangles answers closest-point queries exactly (double
/// precision, exhaustive pruning by box distance); the sign follows the same angle-weighted
/// pseudonormal rule as meshToLevelSet (Bærentzen & Aanæs 2005), so the two agree bit-for-bit in
/// sign on every voxel whose closest feature is unambiguous. A brute-force O(F) query is
/// provided too, to test the BVH itself. compareToReference() measures a level set against it
/// and reports the band's errors (BandErrorReport).
///
/// windingNumber() is the exact generalized winding number (Jacobson et al. 2013): the sum of
/// the triangles' signed solid angles over 4π, every triangle evaluated (O(F), no tree, no
/// expansion), each by Van Oosterom and Strackee's formula written out here independently of
/// mesh/FastWindingNumber.h, so that it can be the fast winding number's oracle.
/// compareSignsToWindingNumber() counts a grid's sign errors against it.
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

/// @brief Exact closest point and signed distance to a triangle mesh (BVH or brute force), signed
///        by the angle-weighted pseudonormal rule.
///
/// Ties between triangles at the same distance go to the lowest triangle id, so query() and
/// bruteForce() give the same answer. Queries are const and may run concurrently.
class ExactReference
{
public:
    /// @brief The answer of a query.
    struct Result
    {
        double distance = 0.0;      ///< signed, world units (negative inside)
        uint32_t triangle = ~0u;    ///< closest triangle (index into mesh.triangles)
        Vec3d closestPoint{0.0};    ///< world units
    };

    /// @brief Computes the pseudonormals and builds the BVH over the non-degenerate triangles.
    ///
    /// Keeps a reference to `mesh`, which must outlive this object. Degenerate triangles are
    /// ignored exactly as meshToLevelSet ignores them.
    /// @param[in] mesh  the surface, world units, counter-clockwise seen from outside (a usable
    ///                  mesh: indices in range, finite coordinates)
    explicit ExactReference(const TriangleMesh& mesh);
    /// @brief Frees the BVH and the pseudonormals.
    ~ExactReference();

    /// @brief Exact closest point and signed distance (BVH).
    /// @param[in] worldPoint  the query point, world units
    /// @return the signed distance (negative inside), the closest triangle and point; a default
    ///         Result (distance 0, triangle ~0u) when the mesh has no non-degenerate triangle
    Result query(const Vec3d& worldPoint) const;
    /// @brief The signed distance of query().
    /// @param[in] worldPoint  the query point, world units
    /// @return the signed distance, world units, negative inside
    double signedDistance(const Vec3d& worldPoint) const { return query(worldPoint).distance; }
    /// @brief The same, by testing every triangle (slow; for testing the BVH).
    /// @param[in] worldPoint  the query point, world units
    /// @return the same Result as query() (ties go to the lowest triangle id in both)
    Result bruteForce(const Vec3d& worldPoint) const;

    /// @brief The exact generalized winding number at @p worldPoint: Σ Ω_t / 4π over the
    ///        non-degenerate triangles (Van Oosterom–Strackee solid angles, ascending triangle
    ///        order, double precision). 1 inside and 0 outside a closed, consistently oriented
    ///        mesh; on a triangle's plane its solid angle counts 0.
    /// @param[in] worldPoint  the query point, world units
    /// @return w (O(F) work)
    double windingNumber(const Vec3d& worldPoint) const;

    /// @brief The pseudonormals used for the sign.
    const PseudoNormals& pseudoNormals() const { return *mNormals; }

private:
    const TriangleMesh& mMesh;
    std::unique_ptr<PseudoNormals> mNormals;
    /// BVH over the non-degenerate triangles; its order() holds their ids in leaf order.
    std::unique_ptr<detail::Bvh> mBvh;
};

/// @brief Accuracy of a level set against the exact reference, in voxel units.
struct BandErrorReport
{
    uint64_t checkedVoxels = 0;   ///< active voxels compared
    double maxError = 0.0;        ///< max |φ - d_exact| / voxelSize
    double meanError = 0.0;       ///< mean |φ - d_exact| / voxelSize
    uint64_t signErrors = 0;      ///< active voxels whose sign differs from the reference (|d| > 1e-6 voxel)
    uint64_t missingVoxels = 0;   ///< inactive face-neighbours of the band whose exact distance is inside the band
    uint64_t extraVoxels = 0;     ///< active voxels whose exact distance lies outside the requested band
};

/// @brief Compares every active voxel of `grid` (or about one in `stride`, chosen by a fixed hash
///        of the voxel coordinates) with the reference.
///
/// Also checks the inactive face-neighbours of the band for voxels that should have been active
/// given the band widths (in voxels). Band membership and sign use a tolerance of 1e-6 voxel.
/// Parallel; deterministic.
/// @param[in] grid           the level set to check (world-unit values; its voxel size is taken
///                           from the transform's x axis)
/// @param[in] reference      the exact reference of the mesh the grid was made from
/// @param[in] exteriorWidth  the requested exterior band half-width, voxels
/// @param[in] interiorWidth  the requested interior band half-width, voxels
/// @param[in] stride         1 (or 0): every active voxel; n > 1: about one voxel in n (the
///                           neighbour check then covers only the sampled voxels)
/// @return the error statistics (maximum and mean error, sign errors, missing and extra voxels)
BandErrorReport compareToReference(const openvdb::FloatGrid& grid, const ExactReference& reference,
                                   double exteriorWidth, double interiorWidth, uint64_t stride = 1);

/// @brief Signs of a grid against the exact winding number (inside where |w| > 1/2).
struct WindingSignReport
{
    uint64_t checked = 0;        ///< values compared
    uint64_t decisive = 0;       ///< of them, where ||w| − 1/2| > margin
    uint64_t signErrors = 0;     ///< decisive values whose sign disagrees (negative ⇔ inside)
    uint64_t undecisive = 0;     ///< values with ||w| − 1/2| <= margin (not judged)
    double maxAbsW = 0.0;        ///< largest |w| seen
};

/// @brief Compares the sign of every active voxel of @p grid (or about one in @p stride, by the
///        same coordinate hash as compareToReference()), and with @p inactive also of its inactive
///        leaf voxels and of one point per tile (its centre; about one tile in @p stride, by the
///        hash of its first voxel), with the exact winding number:
///        a value counts as inside when it is negative. Voxels exactly on the surface (|φ| = 0)
///        are skipped. Parallel; deterministic.
/// @param[in] grid       the signed grid (world-unit values; its transform maps voxels to world)
/// @param[in] reference  the exact reference of the mesh the grid was made from
/// @param[in] margin     values with ||w| − 1/2| <= margin are not judged (the 0.25)
/// @param[in] stride     1: every voxel; n > 1: about one in n
/// @param[in] inactive   also the inactive voxels of leaves and the tiles
/// @return the counts
WindingSignReport compareSignsToWindingNumber(const openvdb::FloatGrid& grid, const ExactReference& reference,
                                              double margin = 0.25, uint64_t stride = 1, bool inactive = false);

} // namespace levelforge
