// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The voxel budget every operator checks before it allocates a band: one estimate from the
///        band's real volume (the leaves the dilated surface touches, not area × width), one
///        message.
///
/// An operation computes how many voxels its output may hold and how much working memory it
/// needs beyond the output (per-thread scratch, dense slabs, pass buffers), then calls
/// checkVoxelBudget(). The working memory counts at 4 bytes a voxel (one float), so
/// `maxVoxels` bounds output and scratch together. The message names the operation, what was
/// estimated, both numbers, and what to change:
///
///   "mesh to level set: the band would hold up to 268435456 voxels (within 1000 voxels of the
///    surface) plus 12 MiB of working memory, more than the limit of 2147483648 voxels; use a
///    larger voxel size or a narrower band"
#pragma once
#include <levelforge/core/TriangleMesh.h>
#include <openvdb/util/NullInterrupter.h>
#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {
namespace detail {

/// @brief Leaves (8³ voxels) holding a voxel centre within @p reach voxels of a triangle.
///
/// Each triangle's box, dilated by the reach, is marked at leaf resolution; a triangle whose
/// dilated box spans more than ~2 reaches (or 2 leaves) is halved recursively with a conservative
/// triangle–box test, so a long sliver costs the leaves along it, not its bounding box. A superset
/// of the band's leaves (boxes stand for balls), at most a few percent above it for closed
/// surfaces. Cost: the leaves touched; parallel; the count is the same for any thread count.
/// @param cellPts  vertices in cell space (voxel ijk's centre at ijk + 0.5, i.e. world / h + 0.5)
/// @param tris     triangles (indices into cellPts)
/// @param use      the triangles to count; empty: all
/// @param reach    band limit in voxels (> 0)
/// @param interrupter  polled once per ~64k triangles; may be null
/// @throws InterruptedError the interrupter asked to stop
uint64_t bandLeafCount(const std::vector<Vec3d>& cellPts, const std::vector<Vec3I>& tris,
                       const std::vector<uint32_t>& use, double reach,
                       openvdb::util::NullInterrupter* interrupter = nullptr);

/// @brief Threads the TBB scheduler may use here (for per-thread scratch estimates).
int budgetThreads();

/// @brief What an operation is about to allocate, for checkVoxelBudget().
struct VoxelBudgetRequest
{
    std::string operation;   ///< e.g. "mesh to level set" (starts the message)
    std::string what;        ///< e.g. "the band" (the subject: "<what> would hold up to N voxels")
    std::string detail;      ///< optional, in parentheses after the count, e.g. "within 3 voxels of the surface"
    double voxels = 0.0;     ///< output voxels (upper estimate)
    double scratchBytes = 0; ///< working memory beyond the output, all threads together
    uint64_t maxVoxels = 0;  ///< the limit; 0: no limit
    std::string remedy = "use a larger voxel size or a narrower band";
};

/// @brief checkVoxelBudget() for a band counted in leaves by bandLeafCount(): "<operation>: the
/// band would hold up to N voxels (L leaf nodes within W voxels of the surface) ...".
void checkBandLeafBudget(const std::string& operation, uint64_t leaves, double width, double scratchBytes,
                         uint64_t maxVoxels);

/// @brief checkBandLeafBudget() for the band of width @p reach around a mesh, counting its leaves
///        (bandLeafCount()) only when the answer needs it.
///
/// Accepted at once when the leaves of the mesh's box dilated by the reach (an upper bound of the
/// band's) fit; refused at once when the voxels of a ball of radius reach − 8√3 around a vertex
/// (a lower bound: the band holds the leaves inside the ball around any surface point) do not,
/// the message quoting the upper bound. Otherwise the leaves are counted. An absurd band is then
/// refused in microseconds instead of after marking tens of millions of leaves.
/// @param cellPts, tris, reach, interrupter  as for bandLeafCount()
/// @param operation, scratchBytes, maxVoxels   as for checkBandLeafBudget() (0: no limit, no count)
void checkMeshBandBudget(const std::string& operation, const std::vector<Vec3d>& cellPts,
                         const std::vector<Vec3I>& tris, double reach, double scratchBytes, uint64_t maxVoxels,
                         openvdb::util::NullInterrupter* interrupter = nullptr);

/// @brief Voxels' worth (4 bytes each) of output plus scratch: what is compared with maxVoxels.
double budgetVoxels(const VoxelBudgetRequest& r);

/// @brief Throws ResourceLimitError with the shared message when budgetVoxels(r) > r.maxVoxels.
void checkVoxelBudget(const VoxelBudgetRequest& r);

} // namespace detail
} // namespace levelforge
