// SPDX-License-Identifier: Apache-2.0
// The closest-triangle hierarchy of the exact band. See TriangleHierarchy.h.
#include "mesh/TriangleHierarchy.h"

#include "detail/ProgressCheck.h"
#include "mesh/LazyPseudoNormals.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <cstdlib>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace levelforge::mesh_internal {

namespace {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LEVELFORGE_CLUSTER_AVX2 1
/// clusterBounds() for AVX2: the same operations in the same order as the SSE2 build, 8 lanes per
/// instruction, no FMA, so every bound has the same bits (only the speed differs). With
/// `kDirections`, also the vector to q from each lane's closest point (clusterBoundsDirections()):
/// the argmin of the edge segments, pd·n inside; the bounds are the same operations either way.
#define LF_ROW(f) _mm256_loadu_ps(c.F[f])
template<bool kDirections>
__attribute__((target("avx2"))) inline uint32_t clusterBoundsAvx2Impl(const TriangleCluster& c, float qx, float qy, float qz,
                                                                    float bm2, float* lb2, float* gx, float* gy, float* gz)
{
    const __m256 Q[3] = {_mm256_set1_ps(qx), _mm256_set1_ps(qy), _mm256_set1_ps(qz)};
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f), B = _mm256_set1_ps(bm2);
    const __m256 n[3] = {LF_ROW(0), LF_ROW(1), LF_ROW(2)};
    const __m256 pd = _mm256_sub_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(n[0], Q[0]), _mm256_mul_ps(n[1], Q[1])), _mm256_mul_ps(n[2], Q[2])), LF_ROW(3));
    const __m256 pd2 = _mm256_mul_ps(pd, pd);
    const int near = _mm256_movemask_ps(_mm256_cmp_ps(pd2, B, _CMP_LT_OQ));
    if (near == 0) {
        _mm256_storeu_ps(lb2, pd2);
        return 0;
    }
    __m256 outside = zero;
    __m256 seg = _mm256_set1_ps(3.0e38f);
    __m256 sx = zero, sy = zero, sz = zero;
    for (int k = 0; k < 3; ++k) {
        const int a = 4 + 3 * k, b = 4 + 3 * ((k + 1) % 3);
        const __m256 e[3] = {_mm256_sub_ps(LF_ROW(b), LF_ROW(a)), _mm256_sub_ps(LF_ROW(b + 1), LF_ROW(a + 1)), _mm256_sub_ps(LF_ROW(b + 2), LF_ROW(a + 2))};
        const __m256 d[3] = {_mm256_sub_ps(Q[0], LF_ROW(a)), _mm256_sub_ps(Q[1], LF_ROW(a + 1)), _mm256_sub_ps(Q[2], LF_ROW(a + 2))};
        const __m256 mx = _mm256_sub_ps(_mm256_mul_ps(e[1], n[2]), _mm256_mul_ps(e[2], n[1]));
        const __m256 my = _mm256_sub_ps(_mm256_mul_ps(e[2], n[0]), _mm256_mul_ps(e[0], n[2]));
        const __m256 mz = _mm256_sub_ps(_mm256_mul_ps(e[0], n[1]), _mm256_mul_ps(e[1], n[0]));
        const __m256 side = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(mx, d[0]), _mm256_mul_ps(my, d[1])), _mm256_mul_ps(mz, d[2]));
        outside = _mm256_or_ps(outside, _mm256_cmp_ps(side, zero, _CMP_GT_OQ));
        __m256 t = _mm256_mul_ps(_mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(d[0], e[0]), _mm256_mul_ps(d[1], e[1])), _mm256_mul_ps(d[2], e[2])), LF_ROW(13 + k));
        t = _mm256_min_ps(_mm256_max_ps(t, zero), one);
        const __m256 rx = _mm256_sub_ps(d[0], _mm256_mul_ps(t, e[0])), ry = _mm256_sub_ps(d[1], _mm256_mul_ps(t, e[1])),
                     rz = _mm256_sub_ps(d[2], _mm256_mul_ps(t, e[2]));
        const __m256 r2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(rx, rx), _mm256_mul_ps(ry, ry)), _mm256_mul_ps(rz, rz));
        if constexpr (kDirections) {
            const __m256 closer = _mm256_cmp_ps(r2, seg, _CMP_LT_OQ);
            sx = _mm256_blendv_ps(sx, rx, closer);
            sy = _mm256_blendv_ps(sy, ry, closer);
            sz = _mm256_blendv_ps(sz, rz, closer);
        }
        seg = _mm256_min_ps(seg, r2);
    }
    __m256 l = _mm256_or_ps(_mm256_andnot_ps(outside, pd2), _mm256_and_ps(outside, seg));
    // the baseline keeps the plane distance of a group of 4 lanes that it rules out entirely
    if ((near & 0x0F) == 0) l = _mm256_blend_ps(l, pd2, 0x0F);
    if ((near & 0xF0) == 0) l = _mm256_blend_ps(l, pd2, 0xF0);
    _mm256_storeu_ps(lb2, l);
    if constexpr (kDirections) {
        _mm256_storeu_ps(gx, _mm256_blendv_ps(_mm256_mul_ps(pd, n[0]), sx, outside));
        _mm256_storeu_ps(gy, _mm256_blendv_ps(_mm256_mul_ps(pd, n[1]), sy, outside));
        _mm256_storeu_ps(gz, _mm256_blendv_ps(_mm256_mul_ps(pd, n[2]), sz, outside));
    }
    return uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(l, B, _CMP_LT_OQ)));
}

__attribute__((target("avx2"))) uint32_t clusterBoundsAvx2(const TriangleCluster& c, float qx, float qy, float qz, float bm2,
                                                         float* lb2)
{
    return clusterBoundsAvx2Impl<false>(c, qx, qy, qz, bm2, lb2, nullptr, nullptr, nullptr);
}

__attribute__((target("avx2"))) uint32_t clusterBoundsDirectionsAvx2(const TriangleCluster& c, float qx, float qy, float qz,
                                                                   float bm2, float* lb2, float* gx, float* gy, float* gz)
{
    return clusterBoundsAvx2Impl<true>(c, qx, qy, qz, bm2, lb2, gx, gy, gz);
}
#undef LF_ROW
#endif
/// One lane of the scalar kernel (the SSE2 build's operations, one lane at a time): its squared
/// distance bound, and where g is given, the vector to q from the closest point (pd·n inside).
inline float scalarLaneBound(const TriangleCluster& c, uint32_t i, const float q[3], float* g)
{
    const float n[3] = {c.F[0][i], c.F[1][i], c.F[2][i]};
    const float pd = n[0] * q[0] + n[1] * q[1] + n[2] * q[2] - c.F[3][i];
    bool outside = false;
    float seg = 3.0e38f, s[3] = {0.0f, 0.0f, 0.0f};
    for (int k = 0; k < 3; ++k) {
        const int a = 4 + 3 * k, b = 4 + 3 * ((k + 1) % 3);
        float e[3], d[3];
        for (int j = 0; j < 3; ++j) { e[j] = c.F[b + j][i] - c.F[a + j][i]; d[j] = q[j] - c.F[a + j][i]; }
        const float side = (e[1] * n[2] - e[2] * n[1]) * d[0] + (e[2] * n[0] - e[0] * n[2]) * d[1] + (e[0] * n[1] - e[1] * n[0]) * d[2];
        if (side > 0.0f) outside = true;
        const float t = std::min(std::max((d[0] * e[0] + d[1] * e[1] + d[2] * e[2]) * c.F[13 + k][i], 0.0f), 1.0f);
        float r[3], r2 = 0.0f;
        for (int j = 0; j < 3; ++j) { r[j] = d[j] - t * e[j]; r2 += r[j] * r[j]; }
        if (r2 < seg) { seg = r2; s[0] = r[0]; s[1] = r[1]; s[2] = r[2]; }
    }
    if (g)
        for (int j = 0; j < 3; ++j) g[j] = outside ? s[j] : pd * n[j];
    return outside ? seg : pd * pd;
}

} // namespace

uint32_t clusterBoundsDirections(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2, float* gx,
                                 float* gy, float* gz)
{
#if defined(LEVELFORGE_CLUSTER_AVX2)
    static const bool avx2 = clusterBoundsAvx2Available();
    if (avx2) return clusterBoundsDirectionsAvx2(c, qx, qy, qz, bm2, lb2, gx, gy, gz);
#endif
    const uint32_t mask = clusterBoundsBaseline(c, qx, qy, qz, bm2, lb2);
    const float q[3] = {qx, qy, qz};
    for (uint32_t m = mask; m; m &= m - 1) {
        const uint32_t i = uint32_t(__builtin_ctz(m));
        float g[3];
        scalarLaneBound(c, i, q, g);
        gx[i] = g[0];
        gy[i] = g[1];
        gz[i] = g[2];
    }
    return mask;
}

bool clusterBoundsAvx2Available()
{
#if defined(LEVELFORGE_CLUSTER_AVX2)
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
#else
    return false;
#endif
}

uint32_t clusterBounds(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2)
{
#if defined(LEVELFORGE_CLUSTER_AVX2)
    static const bool avx2 = clusterBoundsAvx2Available();
    if (avx2) return clusterBoundsAvx2(c, qx, qy, qz, bm2, lb2);
#endif
    return clusterBoundsBaseline(c, qx, qy, qz, bm2, lb2);
}

uint32_t clusterBoundsBaseline(const TriangleCluster& c, float qx, float qy, float qz, float bm2, float* lb2)
{
    uint32_t mask = 0;
#if defined(__SSE2__)
    const __m128 Q[3] = {_mm_set1_ps(qx), _mm_set1_ps(qy), _mm_set1_ps(qz)};
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f), B = _mm_set1_ps(bm2);
    for (int i = 0; i < int(kClusterSize); i += 4) {
        auto row = [&](int f) { return _mm_load_ps(c.F[f] + i); };
        const __m128 n[3] = {row(0), row(1), row(2)};
        const __m128 pd = _mm_sub_ps(
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(n[0], Q[0]), _mm_mul_ps(n[1], Q[1])), _mm_mul_ps(n[2], Q[2])), row(3));
        // the plane distance alone is a lower bound: lanes it already puts beyond the search
        // radius need no more (often all four, for clusters facing another way)
        const __m128 pd2 = _mm_mul_ps(pd, pd);
        if (_mm_movemask_ps(_mm_cmplt_ps(pd2, B)) == 0) {
            _mm_storeu_ps(lb2 + i, pd2);
            continue;
        }
        __m128 outside = zero; // all bits set where q projects outside an edge
        __m128 seg = _mm_set1_ps(3.0e38f);
        for (int k = 0; k < 3; ++k) {
            const int a = 4 + 3 * k, b = 4 + 3 * ((k + 1) % 3);
            const __m128 e[3] = {_mm_sub_ps(row(b), row(a)), _mm_sub_ps(row(b + 1), row(a + 1)), _mm_sub_ps(row(b + 2), row(a + 2))};
            const __m128 d[3] = {_mm_sub_ps(Q[0], row(a)), _mm_sub_ps(Q[1], row(a + 1)), _mm_sub_ps(Q[2], row(a + 2))};
            // side of the edge line: (e × n) · d > 0 is outside (counter-clockwise corners)
            const __m128 mx = _mm_sub_ps(_mm_mul_ps(e[1], n[2]), _mm_mul_ps(e[2], n[1]));
            const __m128 my = _mm_sub_ps(_mm_mul_ps(e[2], n[0]), _mm_mul_ps(e[0], n[2]));
            const __m128 mz = _mm_sub_ps(_mm_mul_ps(e[0], n[1]), _mm_mul_ps(e[1], n[0]));
            const __m128 side = _mm_add_ps(_mm_add_ps(_mm_mul_ps(mx, d[0]), _mm_mul_ps(my, d[1])), _mm_mul_ps(mz, d[2]));
            outside = _mm_or_ps(outside, _mm_cmpgt_ps(side, zero));
            __m128 t = _mm_mul_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(d[0], e[0]), _mm_mul_ps(d[1], e[1])), _mm_mul_ps(d[2], e[2])), row(13 + k));
            t = _mm_min_ps(_mm_max_ps(t, zero), one);
            const __m128 rx = _mm_sub_ps(d[0], _mm_mul_ps(t, e[0])), ry = _mm_sub_ps(d[1], _mm_mul_ps(t, e[1])),
                         rz = _mm_sub_ps(d[2], _mm_mul_ps(t, e[2]));
            seg = _mm_min_ps(seg, _mm_add_ps(_mm_add_ps(_mm_mul_ps(rx, rx), _mm_mul_ps(ry, ry)), _mm_mul_ps(rz, rz)));
        }
        const __m128 l = _mm_or_ps(_mm_andnot_ps(outside, pd2), _mm_and_ps(outside, seg));
        _mm_storeu_ps(lb2 + i, l);
        mask |= uint32_t(_mm_movemask_ps(_mm_cmplt_ps(l, B))) << i;
    }
#else
    const float q[3] = {qx, qy, qz};
    for (uint32_t i = 0; i < kClusterSize; ++i) {
        lb2[i] = scalarLaneBound(c, i, q, nullptr);
        if (lb2[i] < bm2) mask |= 1u << i;
    }
#endif
    return mask;
}

namespace {

constexpr uint32_t kWhole = 0xffffffffu;
/// Triangles longer than this (cells) are split into pieces no longer, each with its own box.
constexpr double kSplitSize = 8.0;

struct Item
{
    float c[3];     // centroid of the triangle or of the piece's box, cell space
    uint32_t t;     // triangle index
    uint32_t piece; // kWhole, or the index of the piece's box
};

struct PieceBox
{
    double lo[3], hi[3];
};

/// Splits the convex polygon poly[0, n) (a triangle or a piece of one) at the middle of its
/// longest box axis until no piece's box is longer than kSplitSize; appends the pieces' boxes
/// (widened by more than the rounding of the clipped corners).
void splitPolygon(const Vec3d* poly, int n, std::vector<PieceBox>& out, int depth)
{
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) { lo[k] = hi[k] = poly[0][k]; }
    for (int i = 1; i < n; ++i)
        for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], poly[i][k]); hi[k] = std::max(hi[k], poly[i][k]); }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    if (hi[axis] - lo[axis] <= kSplitSize || depth >= 60) {
        PieceBox b;
        for (int k = 0; k < 3; ++k) {
            const double pad = 1e-9 * (1.0 + std::abs(lo[k]) + std::abs(hi[k]));
            b.lo[k] = lo[k] - pad;
            b.hi[k] = hi[k] + pad;
        }
        out.push_back(b);
        return;
    }
    const double cut = 0.5 * (lo[axis] + hi[axis]);
    Vec3d below[16], above[16];
    int nb = 0, na = 0;
    for (int i = 0; i < n; ++i) {
        const Vec3d& a = poly[i];
        const Vec3d& b = poly[(i + 1) % n];
        const double da = a[axis] - cut, db = b[axis] - cut;
        if (da <= 0.0 && nb < 16) below[nb++] = a;
        if (da >= 0.0 && na < 16) above[na++] = a;
        if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
            Vec3d x = a + (b - a) * (da / (da - db));
            x[axis] = cut;
            if (nb < 16) below[nb++] = x;
            if (na < 16) above[na++] = x;
        }
    }
    if (nb >= 1) splitPolygon(below, nb, out, depth + 1);
    if (na >= 1) splitPolygon(above, na, out, depth + 1);
}

/// Orders the items of [b, e) so that the median splits of the hierarchy (mid = b + n/2, longest
/// axis of the centroid box, ties by triangle id) leave every subtree's triangles contiguous.
/// Polls the interrupter at every range of more than 65536 items (a few dozen polls for a
/// million triangles); a stop sets `stop` and every range returns at once (nothing throws inside
/// the task tree: two halves throwing at once would end in std::terminate); the caller throws.
void partition(Item* items, size_t b, size_t e, int depth, openvdb::util::NullInterrupter* interrupter,
               std::atomic<bool>& stop)
{
    const size_t n = e - b;
    if (n <= kClusterSize || stop.load(std::memory_order_relaxed)) return;
    if (interrupter && n > 65536 && interrupter->wasInterrupted()) {
        stop.store(true, std::memory_order_relaxed);
        return;
    }
    float lo[3], hi[3];
    for (int k = 0; k < 3; ++k) { lo[k] = std::numeric_limits<float>::max(); hi[k] = -lo[k]; }
    for (size_t i = b; i < e; ++i)
        for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], items[i].c[k]); hi[k] = std::max(hi[k], items[i].c[k]); }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    const size_t mid = b + n / 2;
    std::nth_element(items + b, items + mid, items + e, [axis](const Item& x, const Item& y) {
        if (x.c[axis] != y.c[axis]) return x.c[axis] < y.c[axis];
        return x.t < y.t || (x.t == y.t && x.piece < y.piece);
    });
    if (n > 16384 && depth < 24) {
        tbb::task_group g;
        g.run([=, &stop] { partition(items, b, mid, depth + 1, interrupter, stop); });
        partition(items, mid, e, depth + 1, interrupter, stop);
        g.wait();
    } else {
        partition(items, b, mid, depth + 1, interrupter, stop);
        partition(items, mid, e, depth + 1, interrupter, stop);
    }
}

} // namespace

TriangleHierarchy::TriangleHierarchy(const TriangleMesh& mesh, const std::vector<Vec3d>& cellPts,
                                     const std::vector<uint32_t>& use, openvdb::util::NullInterrupter* interrupter)
{
    const std::vector<Vec3I>& triangles = mesh.triangles;
    if (use.empty()) return;
    // Items: whole triangles, or the pieces of triangles longer than kSplitSize (slivers,
    // needles, CAD faces), so that no box of the hierarchy is much larger than what it holds.
    // Chunks in triangle order keep the item order independent of the thread count.
    const size_t chunk = 4096, nChunks = (use.size() + chunk - 1) / chunk;
    std::vector<std::vector<Item>> chunkItems(nChunks);
    std::vector<std::vector<PieceBox>> chunkPieces(nChunks);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nChunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t ch = r.begin(); ch != r.end(); ++ch) {
            auto& out = chunkItems[ch];
            auto& pieces = chunkPieces[ch];
            for (size_t i = ch * chunk; i < std::min(use.size(), (ch + 1) * chunk); ++i) {
                const Vec3I& tri = triangles[use[i]];
                const Vec3d v[3] = {cellPts[tri[0]], cellPts[tri[1]], cellPts[tri[2]]};
                double ext = 0.0;
                for (int k = 0; k < 3; ++k)
                    ext = std::max(ext, std::max({v[0][k], v[1][k], v[2][k]}) - std::min({v[0][k], v[1][k], v[2][k]}));
                if (!(ext > kSplitSize)) {
                    const Vec3d c = (v[0] + v[1] + v[2]) * (1.0 / 3.0);
                    out.push_back(Item{{float(c[0]), float(c[1]), float(c[2])}, use[i], kWhole});
                    continue;
                }
                const size_t first = pieces.size();
                splitPolygon(v, 3, pieces, 0);
                for (size_t pc = first; pc < pieces.size(); ++pc) {
                    const PieceBox& b = pieces[pc];
                    out.push_back(Item{{float(0.5 * (b.lo[0] + b.hi[0])), float(0.5 * (b.lo[1] + b.hi[1])),
                                        float(0.5 * (b.lo[2] + b.hi[2]))},
                                       use[i], uint32_t(pc)}); // local index, rebased below
                }
            }
        }
    });
    std::vector<Item> items;
    std::vector<PieceBox> pieceBoxes;
    {
        size_t ni = 0, np = 0;
        for (size_t ch = 0; ch < nChunks; ++ch) { ni += chunkItems[ch].size(); np += chunkPieces[ch].size(); }
        items.reserve(ni);
        pieceBoxes.reserve(np);
        for (size_t ch = 0; ch < nChunks; ++ch) {
            const uint32_t base = uint32_t(pieceBoxes.size());
            for (Item it : chunkItems[ch]) {
                if (it.piece != kWhole) it.piece += base;
                items.push_back(it);
            }
            pieceBoxes.insert(pieceBoxes.end(), chunkPieces[ch].begin(), chunkPieces[ch].end());
            std::vector<Item>().swap(chunkItems[ch]);
            std::vector<PieceBox>().swap(chunkPieces[ch]);
        }
    }
    mPieces = pieceBoxes.size();
    std::atomic<bool> stop{false};
    partition(items.data(), 0, items.size(), 0, interrupter, stop);
    if (stop) throw InterruptedError("interrupted while building the triangle hierarchy");
    progress_internal::check(interrupter);

    // The tree's shape depends only on the count: pre-order nodes, leaves numbered in order.
    struct Range { size_t b, e; };
    std::vector<Range> clusterRange;
    mNodes.reserve(2 * (items.size() / kClusterSize + 1));
    clusterRange.reserve(items.size() / (kClusterSize / 2) + 1);
    auto make = [&](auto&& self, size_t b, size_t e) -> uint32_t {
        const uint32_t me = uint32_t(mNodes.size());
        mNodes.emplace_back();
        mNodes[me].triangles = uint32_t(e - b);
        if (e - b <= kClusterSize) {
            mNodes[me].left = uint32_t(clusterRange.size());
            mNodes[me].right = HierarchyNode::kLeaf;
            clusterRange.push_back({b, e});
            return me;
        }
        const size_t mid = b + (e - b) / 2;
        const uint32_t l = self(self, b, mid);
        const uint32_t r = self(self, mid, e);
        mNodes[me].left = l;
        mNodes[me].right = r;
        return me;
    };
    make(make, 0, items.size());

    mClusters.resize(clusterRange.size());
    std::vector<uint32_t> leafNode(clusterRange.size());
    for (uint32_t i = 0; i < mNodes.size(); ++i)
        if (mNodes[i].isLeaf()) leafNode[mNodes[i].left] = i;
    std::vector<double> radius(clusterRange.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, clusterRange.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t ci = r.begin(); ci != r.end(); ++ci) {
            TriangleCluster& c = mClusters[ci];
            HierarchyNode& node = mNodes[leafNode[ci]];
            const Range rg = clusterRange[ci];
            Vec3d lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
            for (size_t i = rg.b; i < rg.e; ++i) {
                if (items[i].piece != kWhole) {
                    const PieceBox& b = pieceBoxes[items[i].piece];
                    for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], b.lo[k]); hi[k] = std::max(hi[k], b.hi[k]); }
                    continue;
                }
                const Vec3I& tri = triangles[items[i].t];
                for (int v = 0; v < 3; ++v)
                    for (int k = 0; k < 3; ++k) {
                        lo[k] = std::min(lo[k], cellPts[tri[v]][k]);
                        hi[k] = std::max(hi[k], cellPts[tri[v]][k]);
                    }
            }
            for (int k = 0; k < 3; ++k) { node.lo[k] = lo[k]; node.hi[k] = hi[k]; }
            c.origin = (lo + hi) * 0.5;
            c.node = leafNode[ci];
            // the single-precision kernels see the whole triangles, whose corners may lie outside
            // the box of their pieces: the radius that bounds their coordinates
            double r2 = ((hi - lo) * 0.5).lengthSqr();
            for (size_t i = rg.b; i < rg.e; ++i) {
                const Vec3I& tri = triangles[items[i].t];
                for (int v = 0; v < 3; ++v) r2 = std::max(r2, (cellPts[tri[v]] - c.origin).lengthSqr());
            }
            radius[ci] = std::sqrt(r2);
            c.count = uint32_t(rg.e - rg.b);
            for (uint32_t lane = 0; lane < kClusterSize; ++lane) {
                if (lane >= c.count) {
                    c.ids[lane] = kNoTriangle;
                    for (int f = 0; f < kClusterRows; ++f) c.F[f][lane] = 0.0f;
                    c.F[3][lane] = 1e30f; // plane distance 1e30: never survives
                    for (int f = 4; f < 13; ++f) c.F[f][lane] = 1e30f; // a far point: edge distances overflow to inf
                    continue;
                }
                const uint32_t t = items[rg.b + lane].t;
                c.ids[lane] = t;
                const Vec3I& tri = triangles[t];
                const Vec3d n = faceNormalOf(mesh, t);
                const Vec3d v[3] = {cellPts[tri[0]] - c.origin, cellPts[tri[1]] - c.origin, cellPts[tri[2]] - c.origin};
                c.F[0][lane] = float(n[0]); c.F[1][lane] = float(n[1]); c.F[2][lane] = float(n[2]);
                c.F[3][lane] = float(n.dot(v[0]));
                // corners and inverse squared edge lengths, from the rounded corners so that the
                // segments are those the single-precision arithmetic sees
                float fv[3][3];
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) { fv[k][j] = float(v[k][j]); c.F[4 + 3 * k + j][lane] = fv[k][j]; }
                for (int k = 0; k < 3; ++k) {
                    double len2 = 0.0;
                    for (int j = 0; j < 3; ++j) {
                        const double d = double(fv[(k + 1) % 3][j]) - double(fv[k][j]);
                        len2 += d * d;
                    }
                    c.F[13 + k][lane] = len2 > 0.0 ? float(1.0 / len2) : 0.0f;
                }
            }
        }
    });
    for (double r : radius) mMaxRadius = std::max(mMaxRadius, r);
    // Inner boxes: children come after their parent in pre-order.
    for (size_t i = mNodes.size(); i-- > 0;) {
        HierarchyNode& n = mNodes[i];
        if (n.isLeaf()) continue;
        const HierarchyNode& a = mNodes[n.left];
        const HierarchyNode& b = mNodes[n.right];
        for (int k = 0; k < 3; ++k) {
            n.lo[k] = std::min(a.lo[k], b.lo[k]);
            n.hi[k] = std::max(a.hi[k], b.hi[k]);
        }
    }
}

} // namespace levelforge::mesh_internal
