// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The lists the exact band's search works from (private to mesh/, used by
///        MeshToLevelSet.cc): a leaf's frontier of hierarchy nodes with single-precision copies of
///        their boxes, and a 2×2×2 block's triangles with their separating planes (or, for blocks
///        too dense to list, its clusters with their boxes), with the vectorised passes a voxel
///        makes over them. Nothing here decides a distance: every bound is a lower bound up to the
///        rounding the search's margin covers, and the search evaluates exactly what they leave
///        (docs/algorithm.md, step 5).
#pragma once

#include "mesh/MeshToLevelSetInternal.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace levelforge::meshtols_internal {

/// A block lists its triangles up to this many (beyond, only its clusters: its voxels then bound
/// the clusters' triangles at the voxel itself, as the search does, instead of a pass over
/// thousands of listed planes; see computeLeaf()).
constexpr size_t kMaxListed = 512;

/// Appends to a block's list (Scratch::bt*) the lanes `mask` of a cluster, from their
/// single-precision distances² lb2 at the block centre c and the vectors g from their closest
/// points to c (clusterBoundsDirections()): the two lower-bound terms (see computeLeaf()), the
/// separating plane's unit normal, the triangle.
inline void listTriangles(const TriangleCluster& c, uint32_t ci, uint32_t mask, const float* lb2, const float (*g)[kClusterSize],
                          float tauK, float tauR, Scratch& s)
{
    if (!mask) return;
    size_t k = s.btCount;
    if (k + kClusterSize > s.btId.size()) s.growBlockTriangles(k + kClusterSize);
    alignas(16) float plane[kClusterSize], ball[kClusterSize], ux[kClusterSize], uy[kClusterSize], uz[kClusterSize];
#if defined(__SSE2__)
    const __m128 tiny = _mm_set1_ps(1e-20f), one = _mm_set1_ps(1.0f), K = _mm_set1_ps(tauK), R = _mm_set1_ps(tauR),
                 r = _mm_set1_ps(0.8660255f), far = _mm_set1_ps(-1e30f);
    for (uint32_t i = 0; i < kClusterSize; i += 4) {
        const __m128 d = _mm_sqrt_ps(_mm_loadu_ps(lb2 + i));
        const __m128 ok = _mm_cmpgt_ps(d, tiny);
        const __m128 inv = _mm_and_ps(ok, _mm_div_ps(one, d));
        const __m128 p = _mm_sub_ps(d, _mm_mul_ps(K, _mm_add_ps(one, _mm_mul_ps(R, inv))));
        _mm_store_ps(plane + i, _mm_or_ps(_mm_and_ps(ok, p), _mm_andnot_ps(ok, far)));
        _mm_store_ps(ball + i, _mm_sub_ps(d, r));
        _mm_store_ps(ux + i, _mm_mul_ps(_mm_loadu_ps(g[0] + i), inv));
        _mm_store_ps(uy + i, _mm_mul_ps(_mm_loadu_ps(g[1] + i), inv));
        _mm_store_ps(uz + i, _mm_mul_ps(_mm_loadu_ps(g[2] + i), inv));
    }
#else
    for (uint32_t i = 0; i < kClusterSize; ++i) {
        const float d = std::sqrt(lb2[i]);
        const bool ok = d > 1e-20f;
        const float inv = ok ? 1.0f / d : 0.0f;
        plane[i] = ok ? d - tauK * (1.0f + tauR * inv) : -1e30f;
        ball[i] = d - 0.8660255f;
        ux[i] = g[0][i] * inv;
        uy[i] = g[1][i] * inv;
        uz[i] = g[2][i] * inv;
    }
#endif
    for (uint32_t m = mask; m; m &= m - 1, ++k) {
        const uint32_t lane = uint32_t(__builtin_ctz(m));
        if (!s.btSeen.empty()) { // a piece of a triangle listed already
            uint32_t& seen = s.btSeen[c.ids[lane]];
            if (seen == s.btBlock) { --k; continue; }
            seen = s.btBlock;
        }
        s.btPlane[k] = plane[lane];
        s.btBall[k] = ball[lane]; // d(c, T) - r: the Lipschitz bound at a voxel of the block
        s.btX[k] = ux[lane];
        s.btY[k] = uy[lane];
        s.btZ[k] = uz[lane];
        s.btId[k] = c.ids[lane];
        s.btCluster[k] = ci;
    }
    s.btCount = k;
}

/// The frontier of a leaf: hierarchy nodes whose boxes come closer than the band limit to the
/// box of the leaf's voxel centres, so that every triangle within the limit of a voxel of the
/// leaf lies in one of their subtrees. Where at most kMaxFlat clusters qualify, the frontier is
/// those clusters (flat: one vectorised pass over their boxes per voxel); otherwise at most
/// kMaxFrontier nodes, as deep as that allows, searched as subtrees. Sorted by distance to the
/// leaf centre (ties by node index).
inline void leafFrontier(const Context& ctx, const Coord& origin, Scratch& s)
{
    const auto& nodes = ctx.hierarchy.nodes();
    const Vec3d lo(origin.x() + 0.5, origin.y() + 0.5, origin.z() + 0.5), hi = lo + Vec3d(7.0);
    const double reach = ctx.limit + ctx.margin, reach2 = reach * reach;
    s.front.clear();
    s.flat = false;
    if (nodes.empty() || boxBoxDistanceSqr(nodes[0], lo, hi) >= reach2) { s.order.clear(); return; }
    // flat: every cluster within reach, unless there are too many
    bool flat = true;
    s.next.clear();
    s.next.push_back(0);
    while (!s.next.empty()) {
        const uint32_t ni = s.next.back();
        s.next.pop_back();
        const HierarchyNode& n = nodes[ni];
        if (n.isLeaf()) {
            s.front.push_back(ni);
            if (s.front.size() > kMaxFlat) { flat = false; break; }
            continue;
        }
        if (boxBoxDistanceSqr(nodes[n.right], lo, hi) < reach2) s.next.push_back(n.right);
        if (boxBoxDistanceSqr(nodes[n.left], lo, hi) < reach2) s.next.push_back(n.left);
    }
    if (!flat) {
        s.front.clear();
        s.front.push_back(0);
        for (bool changed = true; changed;) {
            changed = false;
            s.next.clear();
            for (size_t i = 0; i < s.front.size(); ++i) {
                const HierarchyNode& n = nodes[s.front[i]];
                if (n.isLeaf()) { s.next.push_back(s.front[i]); continue; }
                const bool l = boxBoxDistanceSqr(nodes[n.left], lo, hi) < reach2;
                const bool r = boxBoxDistanceSqr(nodes[n.right], lo, hi) < reach2;
                const size_t remaining = s.front.size() - i - 1;
                if (s.next.size() + size_t(l) + size_t(r) + remaining > kMaxFrontier) { s.next.push_back(s.front[i]); continue; }
                if (l) s.next.push_back(n.left);
                if (r) s.next.push_back(n.right);
                changed = true;
            }
            s.front.swap(s.next);
        }
    }
    s.flat = flat;
    const Vec3d centre = (lo + hi) * 0.5;
    s.order.clear();
    for (uint32_t ni : s.front) s.order.emplace_back(boxDistanceSqr(nodes[ni], centre), ni);
    // flat clusters stay in the hierarchy's depth-first order, so that groups of 8 consecutive
    // ones are compact; subtrees go nearest first
    if (!flat) std::sort(s.order.begin(), s.order.end());
    // Single-precision copies of the boxes, relative to the leaf centre and widened by more than
    // their rounding, so that the vectorised box distance never exceeds the true one.
    if (s.levels.empty()) s.levels.resize(8);
    {
        Scratch::Level& L = s.levels[0];
        L.count = s.order.size();
        L.stride = (L.count + 7) & ~size_t(7);
        L.box.assign(6 * L.stride, 1e30f);
        for (size_t i = 0; i < L.count; ++i) {
            const HierarchyNode& n = nodes[s.order[i].second];
            for (int k = 0; k < 3; ++k) {
                const double lo = n.lo[k] - centre[k], hi = n.hi[k] - centre[k];
                const double pad = 1e-6 * (std::abs(lo) + std::abs(hi)) + 1e-6;
                L.box[k * L.stride + i] = float(lo - pad);
                L.box[(3 + k) * L.stride + i] = float(hi + pad);
            }
        }
    }
    s.nLevels = 1;
    while (s.levels[s.nLevels - 1].count > 8) {
        const Scratch::Level& below = s.levels[s.nLevels - 1];
        if (s.nLevels == s.levels.size()) s.levels.resize(s.nLevels + 1);
        Scratch::Level& L = s.levels[s.nLevels];
        const Scratch::Level& B = s.levels[s.nLevels - 1];
        L.count = (below.count + 7) / 8;
        L.stride = (L.count + 7) & ~size_t(7);
        L.box.assign(6 * L.stride, 1e30f);
        for (size_t g = 0; g < L.count; ++g)
            for (int k = 0; k < 3; ++k) {
                float lo = std::numeric_limits<float>::max(), hi = -lo;
                for (size_t i = 8 * g; i < 8 * g + 8 && i < B.count; ++i) {
                    lo = std::min(lo, B.box[k * B.stride + i]);
                    hi = std::max(hi, B.box[(3 + k) * B.stride + i]);
                }
                L.box[k * L.stride + g] = lo;
                L.box[(3 + k) * L.stride + g] = hi;
            }
        ++s.nLevels;
    }
}

/// Squared distances from q (relative to the leaf centre) to the boxes [begin, end) of the SoA
/// box arrays F (6 arrays of `n` floats), into d2[0, end - begin); begin and end multiples of 4.
/// SSE2 on x86-64.
inline void boxDistances(const float* F, size_t n, size_t begin, size_t end, float qx, float qy, float qz, float* d2)
{
#if defined(__SSE2__)
    const __m128 Q[3] = {_mm_set1_ps(qx), _mm_set1_ps(qy), _mm_set1_ps(qz)};
    const __m128 zero = _mm_setzero_ps();
    for (size_t i = begin; i < end; i += 4) {
        __m128 acc = zero;
        for (int k = 0; k < 3; ++k) {
            const __m128 lo = _mm_loadu_ps(F + k * n + i), hi = _mm_loadu_ps(F + (3 + k) * n + i);
            const __m128 e = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, Q[k]), _mm_sub_ps(Q[k], hi)), zero);
            acc = _mm_add_ps(acc, _mm_mul_ps(e, e));
        }
        _mm_storeu_ps(d2 + (i - begin), acc);
    }
#else
    const float q[3] = {qx, qy, qz};
    for (size_t i = begin; i < end; ++i) {
        float acc = 0.0f;
        for (int k = 0; k < 3; ++k) {
            const float e = std::max(std::max(F[k * n + i] - q[k], q[k] - F[(3 + k) * n + i]), 0.0f);
            acc += e * e;
        }
        d2[i - begin] = acc;
    }
#endif
}

/// The long-list branch of sortNearestFirst(), out of line: inlined into callers with 8-entry
/// arrays, GCC 12 warns (-Warray-bounds) about a branch those callers never take.
__attribute__((noinline)) inline void sortNearestFirstLong(uint32_t* idx, uint32_t n, const float* d2)
{
    std::sort(idx, idx + n, [d2](uint32_t a, uint32_t b) { return d2[a] < d2[b] || (d2[a] == d2[b] && a < b); });
}

/// Sorts the indices idx[0, n) by d2[idx] (ties by index): insertion sort for short lists.
inline void sortNearestFirst(uint32_t* idx, uint32_t n, const float* d2)
{
    auto nearer = [d2](uint32_t a, uint32_t b) { return d2[a] < d2[b] || (d2[a] == d2[b] && a < b); };
    if (n > 16) {
        sortNearestFirstLong(idx, n, d2);
        return;
    }
    for (uint32_t k = 1; k < n; ++k) {
        const uint32_t x = idx[k];
        uint32_t j = k;
        for (; j > 0 && nearer(x, idx[j - 1]); --j) idx[j] = idx[j - 1];
        idx[j] = x;
    }
}

/// The boxes of a block's listed clusters, in single precision relative to the block centre c
/// and widened by more than their rounding (as the frontier's levels), 6 SoA arrays of
/// s.blockStride floats (a multiple of 8, padded with far boxes).
inline void blockBoxes(const Context& ctx, const Vec3d& c, Scratch& s)
{
    const auto& nodes = ctx.hierarchy.nodes();
    const auto& clusters = ctx.hierarchy.clusters();
    const size_t n = s.blockList.size();
    s.blockStride = (n + 7) & ~size_t(7);
    s.blockBox.assign(6 * s.blockStride, 1e30f);
    if (s.blockD2.size() < s.blockStride) s.blockD2.resize(s.blockStride);
    for (size_t i = 0; i < n; ++i) {
        const HierarchyNode& b = nodes[clusters[s.blockList[i].second].node];
        for (int k = 0; k < 3; ++k) {
            const double lo = b.lo[k] - c[k], hi = b.hi[k] - c[k];
            const double pad = 1e-6 * (std::abs(lo) + std::abs(hi)) + 1e-6;
            s.blockBox[k * s.blockStride + i] = float(lo - pad);
            s.blockBox[(3 + k) * s.blockStride + i] = float(hi + pad);
        }
    }
}

/// A voxel's bounds of a block's listed triangles (Scratch::bt*, n a multiple of 4), offset
/// (dx, dy, dz) from the block centre: lb[i] = max(ball[i], plane[i] + g[i]·(dx, dy, dz)).
/// Returns the index of the smallest (the first of equals).
inline size_t blockTriangleBounds(const Scratch& s, size_t n, float dx, float dy, float dz, float* lb)
{
    const float *P = s.btPlane.data(), *Bl = s.btBall.data(), *X = s.btX.data(), *Y = s.btY.data(), *Z = s.btZ.data();
#if defined(__SSE2__)
    const __m128 DX = _mm_set1_ps(dx), DY = _mm_set1_ps(dy), DZ = _mm_set1_ps(dz);
    __m128 lo = _mm_set1_ps(3.0e38f);
    for (size_t i = 0; i < n; i += 4) {
        const __m128 plane = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_loadu_ps(P + i), _mm_mul_ps(_mm_loadu_ps(X + i), DX)),
                                                   _mm_mul_ps(_mm_loadu_ps(Y + i), DY)),
                                        _mm_mul_ps(_mm_loadu_ps(Z + i), DZ));
        const __m128 b = _mm_max_ps(_mm_loadu_ps(Bl + i), plane);
        _mm_storeu_ps(lb + i, b);
        lo = _mm_min_ps(lo, b);
    }
    lo = _mm_min_ps(lo, _mm_shuffle_ps(lo, lo, _MM_SHUFFLE(1, 0, 3, 2)));
    lo = _mm_min_ps(lo, _mm_shuffle_ps(lo, lo, _MM_SHUFFLE(2, 3, 0, 1)));
    const __m128 L = lo;
    for (size_t i = 0; i < n; i += 4) {
        const int m = _mm_movemask_ps(_mm_cmpeq_ps(_mm_loadu_ps(lb + i), L));
        if (m) return i + size_t(__builtin_ctz(unsigned(m)));
    }
    return 0;
#else
    size_t first = 0;
    for (size_t i = 0; i < n; ++i) {
        lb[i] = std::max(Bl[i], P[i] + X[i] * dx + Y[i] * dy + Z[i] * dz);
        if (lb[i] < lb[first]) first = i;
    }
    return first;
#endif
}

/// Appends (lb[i], i) for every i < n with lb[i] < thr (n a multiple of 4; padding never passes).
inline void selectBelow(const float* lb, size_t n, float thr, std::vector<std::pair<float, uint32_t>>& out)
{
    out.clear();
#if defined(__SSE2__)
    const __m128 T = _mm_set1_ps(thr);
    for (size_t i = 0; i < n; i += 4)
        for (unsigned m = unsigned(_mm_movemask_ps(_mm_cmplt_ps(_mm_loadu_ps(lb + i), T))); m; m &= m - 1) {
            const size_t k = i + size_t(__builtin_ctz(m));
            out.emplace_back(lb[k], uint32_t(k));
        }
#else
    for (size_t i = 0; i < n; ++i)
        if (lb[i] < thr) out.emplace_back(lb[i], uint32_t(i));
#endif
}

} // namespace levelforge::meshtols_internal
