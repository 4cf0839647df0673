// SPDX-License-Identifier: Apache-2.0
// The candidate topology of the expansion: the voxel dilation that contains a Euclidean ball
// (dilationPattern, FastSweeping.h) and the leaf-granular domain of the sweep (leafDomain,
// FastSweepingInternal.h).
#include "expand/FastSweepingInternal.h"

#include <openvdb/tree/ValueAccessor.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace levelforge::fast_sweeping_internal {

namespace {
/// Largest Σ max(|x_i| - a, 0) over lattice points x with |x| < radius: the face steps needed
/// after `a` cube steps (the lattice Minkowski sum of the cube and the octahedron contains x
/// iff that sum is <= b).
int faceStepsNeeded(double radius, int a)
{
    const int n = int(std::floor(radius));
    const double r2 = radius * radius;
    int b = 0;
    for (int x = 0; x <= n; ++x) {
        for (int y = 0; y <= n; ++y) {
            const double rest = r2 - double(x) * x - double(y) * y;
            if (rest <= 0) break;
            int z = int(std::floor(std::sqrt(rest)));
            while (z > 0 && double(x) * x + double(y) * y + double(z) * z >= r2) --z;
            if (double(x) * x + double(y) * y + double(z) * z >= r2) continue;
            b = std::max(b, std::max(x - a, 0) + std::max(y - a, 0) + std::max(z - a, 0));
        }
    }
    return b;
}
} // namespace

void dilationPattern(double radius, int& cubeSteps, int& faceSteps)
{
    cubeSteps = faceSteps = 0;
    if (!(radius > 0)) return;
    const int n = int(std::ceil(radius));
    int bestA = n, bestB = 0;
    // a + b is minimal (= ceil(radius) or so) from about 0.41 R on; search a small window.
    const int lo = std::max(0, int(std::floor(0.33 * radius)) - 1);
    for (int a = lo; a <= n; ++a) {
        const int b = faceStepsNeeded(radius, a);
        if (a + b < bestA + bestB) { bestA = a; bestB = b; }
        if (a > int(0.5 * radius) + 2) break;
    }
    cubeSteps = bestA;
    faceSteps = bestB;
}

namespace {

using openvdb::Coord;

/// floor(a / b) for b > 0
inline int64_t floorDiv(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

} // namespace

openvdb::MaskTree::Ptr leafDomain(const openvdb::MaskTree& band, double radius, uint64_t& leafCount)
{
    using MaskLeaf = openvdb::MaskTree::LeafNodeType;
    std::vector<const MaskLeaf*> leaves;
    band.getNodes(leaves);
    leafCount = 0;
    if (leaves.empty() || !(radius >= 0)) return nullptr;
    const size_t n = leaves.size();
    std::vector<openvdb::CoordBBox> boxes(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            openvdb::CoordBBox b;
            for (auto it = leaves[i]->cbeginValueOn(); it; ++it) b.expand(it.getCoord());
            boxes[i] = b;
        }
    });
    const int64_t rc = int64_t(std::ceil(radius));
    const double r2 = radius * radius;
    int64_t lo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, hi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
    for (const auto& b : boxes) {
        if (b.empty()) continue;
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], floorDiv(int64_t(b.min()[k]) - 7 - rc, 8));
            hi[k] = std::max(hi[k], floorDiv(int64_t(b.max()[k]) + rc, 8));
        }
    }
    if (lo[0] > hi[0]) return nullptr;
    const int64_t dim[3] = {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    const double cells = double(dim[0]) * double(dim[1]) * double(dim[2]);
    if (cells > double(1 << 24)) return nullptr; // about 2048^3 voxels: dilate instead
    std::unique_ptr<std::atomic<uint8_t>[]> grid(new std::atomic<uint8_t>[size_t(cells)]());
    // the gap between leaf cell I (voxels 8I .. 8I+7) and the voxel range [a, b] along one axis
    auto gap = [](int64_t I, int64_t a, int64_t b) {
        return double(std::max<int64_t>({0, a - (8 * I + 7), 8 * I - b}));
    };
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const openvdb::CoordBBox& b = boxes[i];
            if (b.empty()) continue;
            const int64_t a0 = b.min()[0], b0 = b.max()[0], a1 = b.min()[1], b1 = b.max()[1];
            const int64_t a2 = b.min()[2], b2 = b.max()[2];
            for (int64_t I = floorDiv(a0 - 7 - rc, 8); I <= floorDiv(b0 + rc, 8); ++I) {
                const double g0 = gap(I, a0, b0);
                const double rem0 = r2 - g0 * g0;
                if (rem0 <= 0) continue;
                for (int64_t J = floorDiv(a1 - 7 - rc, 8); J <= floorDiv(b1 + rc, 8); ++J) {
                    const double g1 = gap(J, a1, b1);
                    const double rem1 = rem0 - g1 * g1;
                    if (rem1 <= 0) continue;
                    const int64_t s = int64_t(std::ceil(std::sqrt(rem1)));
                    const int64_t row = ((I - lo[0]) * dim[1] + (J - lo[1])) * dim[2] - lo[2];
                    for (int64_t K = floorDiv(a2 - 7 - s, 8); K <= floorDiv(b2 + s, 8); ++K) {
                        const double g2 = gap(K, a2, b2);
                        if (g2 * g2 < rem1) grid[size_t(row + K)].store(1, std::memory_order_relaxed);
                    }
                }
            }
        }
    });
    openvdb::MaskTree::Ptr dom(new openvdb::MaskTree(false));
    openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(*dom);
    size_t c = 0;
    for (int64_t I = lo[0]; I <= hi[0]; ++I)
        for (int64_t J = lo[1]; J <= hi[1]; ++J)
            for (int64_t K = lo[2]; K <= hi[2]; ++K, ++c) {
                if (!grid[c].load(std::memory_order_relaxed)) continue;
                acc.touchLeaf(Coord(int(8 * I), int(8 * J), int(8 * K)))->setValuesOn();
                ++leafCount;
            }
    return dom;
}

} // namespace levelforge::fast_sweeping_internal
