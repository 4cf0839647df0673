// SPDX-License-Identifier: Apache-2.0
#include "detail/VoxelBudget.h"

#include "detail/ProgressCheck.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/mesh/MicrotriangleVoxelizer.h> // triangleBoxOverlap

#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace levelforge {
namespace detail {

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

/// Leaf-coordinate range (leaf origin / 8) of the cell-space box [lo, hi] dilated by r: the
/// leaves holding a voxel centre (at cell ijk + 0.5) within r of the box.
CoordBBox leafRange(const Vec3d& lo, const Vec3d& hi, double r)
{
    Coord a, b;
    for (int k = 0; k < 3; ++k) {
        a[k] = int(std::ceil((lo[k] - r - 7.5) / 8.0));
        b[k] = int(std::floor((hi[k] + r - 0.5) / 8.0));
    }
    return CoordBBox(a, b);
}

/// Marks the leaves of @p block that come within r of the triangle: whole when the block is at
/// most @p wide leaves across, else halved along its longest axis after a conservative test.
void rasterize(const Vec3d& a, const Vec3d& b, const Vec3d& c, const CoordBBox& block, double r, int wide,
               openvdb::MaskTree& mask)
{
    const Vec3d lo(block.min().x() * 8.0 + 0.5 - r, block.min().y() * 8.0 + 0.5 - r, block.min().z() * 8.0 + 0.5 - r);
    const Vec3d hi(block.max().x() * 8.0 + 7.5 + r, block.max().y() * 8.0 + 7.5 + r, block.max().z() * 8.0 + 7.5 + r);
    if (!triangleBoxOverlap((lo + hi) * 0.5, (hi - lo) * 0.5, a, b, c, 1e-6)) return;
    const Coord dim = block.dim();
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (dim[k] > dim[axis]) axis = k;
    if (dim[axis] <= wide) {
        mask.fill(block, true, true);
        return;
    }
    CoordBBox l = block, h = block;
    const int mid = block.min()[axis] + dim[axis] / 2;
    l.max()[axis] = mid - 1;
    h.min()[axis] = mid;
    rasterize(a, b, c, l, r, wide, mask);
    rasterize(a, b, c, h, r, wide, mask);
}

std::string mib(double bytes)
{
    std::ostringstream os;
    os << uint64_t(std::ceil(bytes / (1024.0 * 1024.0))) << " MiB";
    return os.str();
}

} // namespace

uint64_t bandLeafCount(const std::vector<Vec3d>& cellPts, const std::vector<Vec3I>& tris,
                       const std::vector<uint32_t>& use, double reach, openvdb::util::NullInterrupter* interrupter)
{
    const size_t n = use.empty() ? tris.size() : use.size();
    if (n == 0) return 0;
    const double r = reach + 1e-4;
    const int wide = std::max(1, int(std::floor(reach / 8.0)));
    tbb::enumerable_thread_specific<openvdb::MaskTree> tls;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 8192), [&](const tbb::blocked_range<size_t>& range) {
        progress_internal::check(interrupter);
        openvdb::MaskTree& mask = tls.local();
        CoordBBox last; // the last block marked whole: neighbouring triangles often fall inside it
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const Vec3I& t = tris[use.empty() ? i : use[i]];
            const Vec3d &a = cellPts[t[0]], &b = cellPts[t[1]], &c = cellPts[t[2]];
            Vec3d lo, hi;
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min({a[k], b[k], c[k]});
                hi[k] = std::max({a[k], b[k], c[k]});
            }
            const CoordBBox block = leafRange(lo, hi, r);
            if (!last.empty() && last.isInside(block)) continue;
            const Coord dim = block.dim();
            if (std::max({dim.x(), dim.y(), dim.z()}) <= wide) {
                mask.fill(block, true, true);
                last = block;
                continue;
            }
            rasterize(a, b, c, block, r, wide, mask);
        }
    });
    openvdb::MaskTree all;
    for (openvdb::MaskTree& m : tls) all.topologyUnion(m);
    return all.activeVoxelCount();
}

int budgetThreads()
{
    return std::max(1, tbb::this_task_arena::max_concurrency());
}

void checkBandLeafBudget(const std::string& operation, uint64_t leaves, double width, double scratchBytes,
                         uint64_t maxVoxels)
{
    VoxelBudgetRequest req;
    req.operation = operation;
    req.what = "the band";
    std::ostringstream d;
    d << leaves << " leaf nodes within " << width << " voxels of the surface";
    req.detail = d.str();
    req.voxels = double(leaves) * 512.0;
    req.scratchBytes = scratchBytes;
    req.maxVoxels = maxVoxels;
    checkVoxelBudget(req);
}

void checkMeshBandBudget(const std::string& operation, const std::vector<Vec3d>& cellPts,
                         const std::vector<Vec3I>& tris, double reach, double scratchBytes, uint64_t maxVoxels,
                         openvdb::util::NullInterrupter* interrupter)
{
    if (maxVoxels == 0 || tris.empty()) return;
    Vec3d lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const Vec3I& t : tris)
        for (int k = 0; k < 3; ++k) {
            lo = minComponent(lo, cellPts[t[k]]);
            hi = maxComponent(hi, cellPts[t[k]]);
        }
    const double r = reach + 1e-4;
    const CoordBBox box = leafRange(lo, hi, r);
    const double upperLeaves = double(box.dim().x()) * double(box.dim().y()) * double(box.dim().z());
    const double budget = double(maxVoxels) - std::max(0.0, scratchBytes) / 4.0;
    if (upperLeaves * 512.0 <= budget) return; // the whole dilated box fits
    constexpr double kPi = 3.14159265358979323846;
    const double inner = std::max(0.0, reach - 8.0 * std::sqrt(3.0)); // leaves wholly inside the ball
    if (4.0 / 3.0 * kPi * inner * inner * inner > budget) {
        checkBandLeafBudget(operation, uint64_t(std::min(upperLeaves, 1.8e19 / 512.0)), reach, scratchBytes, maxVoxels);
        return; // (not reached: the upper bound exceeds the budget too)
    }
    checkBandLeafBudget(operation, bandLeafCount(cellPts, tris, {}, reach, interrupter), reach, scratchBytes,
                        maxVoxels);
}

double budgetVoxels(const VoxelBudgetRequest& r)
{
    return r.voxels + std::max(0.0, r.scratchBytes) / 4.0;
}

void checkVoxelBudget(const VoxelBudgetRequest& r)
{
    if (r.maxVoxels == 0) return;
    const double total = budgetVoxels(r);
    if (!(total > double(r.maxVoxels))) return;
    std::ostringstream os;
    os << r.operation << ": " << r.what << " would hold up to " << uint64_t(std::min(r.voxels, 1.8e19)) << " voxels";
    if (!r.detail.empty()) os << " (" << r.detail << ")";
    if (r.scratchBytes >= 1024.0 * 1024.0) os << " plus " << mib(r.scratchBytes) << " of working memory";
    os << ", more than the limit of " << r.maxVoxels << " voxels";
    if (!r.remedy.empty()) os << "; " << r.remedy;
    throw ResourceLimitError(os.str());
}

} // namespace detail
} // namespace levelforge
