// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one bounding-volume hierarchy of the library: a binary tree over axis-aligned
///        boxes, built top-down by median splits, queried for the nearest primitive by a
///        nearest-child-first depth-first traversal that prunes by the squared distance to the
///        node boxes.
///
/// Its users keep their own tree shape and tie rule through the callbacks of build() and the
/// template argument of nearest():
///  - reference/ExactReference.cc: triangles, leaves of up to 4, split on the longest axis of
///    the range's centroid box; boxes at exactly the best distance are still visited, so equally
///    near triangles can go to the lowest id;
///  - adf/AdfCentreBvh.h: the 4³ quarters of the boundary-cell tree, one per leaf, split on the
///    longest axis of the node box; boxes at the best distance are pruned (only the distance is
///    asked for).
#pragma once

#include <levelforge/core/TriangleDistance.h>
#include <levelforge/core/TriangleMesh.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace levelforge::detail {

class Bvh
{
public:
    struct Node
    {
        Vec3d lo{0.0}, hi{0.0};           ///< box of the node's primitives
        uint32_t first = 0, count = 0;    ///< leaf: primitives order()[first, first + count); inner: count = 0
        uint32_t left = 0, right = 0;     ///< inner node: its children
    };

    /// @brief Builds the tree (nodes in depth-first pre-order).
    /// @param[in] ids       the primitives (their ids), in any order; kept, permuted into leaf
    ///                      order, as order()
    /// @param[in] boxes     boxes[id]: the box of primitive id
    /// @param[in] leafSize  a range of at most this many primitives becomes a leaf (>= 1)
    /// @param[in] axisOf    axisOf(const uint32_t* ids, size_t n, const Node& node) -> int: the
    ///                      split axis of an inner node (node.lo / node.hi are set)
    /// @param[in] less      less(a, b, axis) -> bool: a strict total order of the primitives
    ///                      along the axis; the range is split at its median by nth_element
    template<typename AxisOf, typename Less>
    void build(std::vector<uint32_t> ids, const std::vector<BBoxd>& boxes, size_t leafSize, AxisOf&& axisOf,
               Less&& less)
    {
        mOrder = std::move(ids);
        mNodes.clear();
        if (!mOrder.empty()) buildRange(0, mOrder.size(), boxes, leafSize, axisOf, less);
    }

    bool empty() const { return mNodes.empty(); }
    /// @brief The primitive ids in leaf order.
    const std::vector<uint32_t>& order() const { return mOrder; }

    /// @brief Visits the leaves that may hold a primitive nearer to @p p than @p best2, nearer
    ///        child first.
    /// @param[in]     p          the query point
    /// @param[in,out] best2      squared distance of the best primitive so far; the visitor
    ///                           lowers it
    /// @param[in]     visitLeaf  visitLeaf(const uint32_t* ids, uint32_t n): the primitives of a
    ///                           leaf whose box is nearer than best2 (kVisitTies: not farther)
    /// @tparam kVisitTies  also visit boxes at exactly best2 (for a tie rule among equally near
    ///                     primitives)
    template<bool kVisitTies, typename VisitLeaf>
#if defined(__GNUC__)
    // inlined into the caller, so that best2 and the visitor's state can live in registers
    __attribute__((always_inline))
#endif
    inline void nearest(const Vec3d& p, double& best2, VisitLeaf&& visitLeaf) const
    {
        if (mNodes.empty()) return;
        const double* q = p.asPointer();
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const Node& n = mNodes[stack[--sp]];
            const double d2 = boxDist2(q, n);
            if (kVisitTies ? d2 > best2 : d2 >= best2) continue;
            if (n.count > 0) {
                visitLeaf(mOrder.data() + n.first, n.count);
                continue;
            }
            const Node& l = mNodes[n.left];
            const Node& r = mNodes[n.right];
            const double dl = boxDist2(q, l), dr = boxDist2(q, r);
            // push the farther child first, so that the nearer one is visited first
            if (dl < dr) { stack[sp++] = n.right; stack[sp++] = n.left; }
            else { stack[sp++] = n.left; stack[sp++] = n.right; }
        }
    }

private:
    /// boxDistanceSqr(p, n.lo, n.hi), the same operations in the same order, on raw pointers:
    /// Vec3d's operator[] is not inlined in the instrumented (ASan, fuzzing) builds, where it made
    /// the ADF's type-3 samples 16x slower than in Release.
    static inline double boxDist2(const double* p, const Node& n)
    {
        const double* lo = n.lo.asPointer();
        const double* hi = n.hi.asPointer();
        double d2 = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double e = p[k] < lo[k] ? lo[k] - p[k] : (p[k] > hi[k] ? p[k] - hi[k] : 0.0);
            d2 += e * e;
        }
        return d2;
    }

    template<typename AxisOf, typename Less>
    uint32_t buildRange(size_t b, size_t e, const std::vector<BBoxd>& boxes, size_t leafSize, AxisOf& axisOf,
                        Less& less)
    {
        const uint32_t me = uint32_t(mNodes.size());
        mNodes.emplace_back();
        Node n;
        for (int k = 0; k < 3; ++k) {
            n.lo[k] = std::numeric_limits<double>::max();
            n.hi[k] = -std::numeric_limits<double>::max();
        }
        for (size_t i = b; i < e; ++i) {
            const BBoxd& bb = boxes[mOrder[i]];
            for (int k = 0; k < 3; ++k) {
                n.lo[k] = std::min(n.lo[k], bb.min()[k]);
                n.hi[k] = std::max(n.hi[k], bb.max()[k]);
            }
        }
        if (e - b <= leafSize) {
            n.first = uint32_t(b);
            n.count = uint32_t(e - b);
        } else {
            const int axis = axisOf(mOrder.data() + b, e - b, static_cast<const Node&>(n));
            const size_t mid = (b + e) / 2;
            std::nth_element(mOrder.begin() + long(b), mOrder.begin() + long(mid), mOrder.begin() + long(e),
                             [&](uint32_t x, uint32_t y) { return less(x, y, axis); });
            n.left = buildRange(b, mid, boxes, leafSize, axisOf, less);
            n.right = buildRange(mid, e, boxes, leafSize, axisOf, less);
        }
        mNodes[me] = n;
        return me;
    }

    std::vector<uint32_t> mOrder;
    std::vector<Node> mNodes;
};

} // namespace levelforge::detail
